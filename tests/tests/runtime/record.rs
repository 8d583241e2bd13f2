//! The `record` feature: the derive's joint points, the CSV a trajectory writes
//! (read back with the `csv` crate, every number exact), and the animated SVG's
//! structure (one animated path per body, its frames in the layout of the stills).

#![allow(missing_docs)]

use joint_runtime::nalgebra::Vector3;
use joint_runtime::record::{Column, SvgOptions, Trajectory, View};
use joint_runtime::{JointPoint, Scene, SystemState};
use joint_tests::scenes::hanging_rods;

/// Two rods hanging from the origin; the lower rod's point is a field.
#[derive(Scene)]
#[scene(coordinates = absolute, gravity = [0, 0, -9.81])]
#[body(upper, mass = 1.0, inertia = [0.1, 0.1, 0.01])]
#[body(lower, mass = 1.0, inertia = [0.1, 0.1, 0.01])]
#[joint(shoulder = spherical(ground, upper), rho1 = [0, 0, 0], rho2 = [0, 0, 0.5])]
#[joint(elbow = spherical(upper, lower), rho1 = [0, 0, -0.5], rho2 = top)]
#[joint(keep = perpendicular(upper, lower), s = [1, 0, 0], h = [0, 1, 0])]
pub(super) struct Rods {
    top: Vector3<f64>,
}

pub(super) fn rods() -> Rods {
    Rods { top: Vector3::new(0.0, 0.0, 0.5) }
}

#[test]
fn joint_points_follow_the_declaration() {
    let mut points = Vec::new();
    rods().joint_points(&mut |p| points.push(p));
    let point = |joint, body, x: [f64; 3]| JointPoint { joint, body, point: Vector3::from(x) };
    assert_eq!(
        points,
        [
            point("shoulder", None, [0.0, 0.0, 0.0]),
            point("shoulder", Some(0), [0.0, 0.0, 0.5]),
            point("elbow", Some(0), [0.0, 0.0, -0.5]),
            point("elbow", Some(1), [0.0, 0.0, 0.5]),
        ]
    );
}

fn swinging(samples: usize) -> Trajectory<2> {
    let mut run = Trajectory::new(&rods());
    for k in 0..samples {
        let t = 0.01 * k as f64;
        let mut state = hanging_rods([0.5 * t.sin(), 0.8 * (2.0 * t).sin()]);
        state.t = t;
        run.record(&state);
    }
    run
}

#[test]
fn csv_holds_every_sample_exactly() {
    let run = swinging(50);
    let mut bytes = Vec::new();
    let lower_tip = |s: &SystemState<2>| s.bodies[1].point(&Vector3::new(0.0, 0.0, -0.5)).y;
    run.write_csv(&mut bytes, &[Column::new("tip_y", &lower_tip)]).expect("written");
    let mut reader = csv::Reader::from_reader(bytes.as_slice());
    let header: Vec<String> = reader.headers().expect("a header").iter().map(String::from).collect();
    assert_eq!(header.len(), 1 + 2 * 7 + 1);
    assert_eq!(
        &header[..9],
        ["t", "upper.x", "upper.y", "upper.z", "upper.e0", "upper.e1", "upper.e2", "upper.e3", "lower.x"]
    );
    assert_eq!(header[15], "tip_y");
    let rows: Vec<Vec<f64>> =
        reader.records().map(|r| r.expect("a row").iter().map(|x| x.parse().expect("a number")).collect()).collect();
    assert_eq!(rows.len(), 50);
    for (row, s) in rows.iter().zip(run.samples()) {
        let b = &s.bodies[1];
        assert_eq!(row[0], s.t);
        assert_eq!(&row[8..15], [b.r.x, b.r.y, b.r.z, b.p[0], b.p[1], b.p[2], b.p[3]]);
        assert_eq!(row[15], lower_tip(s));
    }
}

#[test]
fn svg_animates_each_body_over_its_frames() {
    let run = swinging(400);
    let options = SvgOptions::default().with_view(View::yz()).with_max_frames(100).with_title("two <rods>");
    let svg = run.svg(&options);
    assert_eq!(svg.matches("<animate attributeName=\"d\"").count(), 2);
    assert_eq!(svg.matches("attributeName=\"visibility\"").count(), 100, "one time label per frame");
    assert!(svg.contains("two &lt;rods&gt;") && svg.contains("t = 3.990 s"));
    // 100 frames of a 3.99 s run, played in real time, looping.
    assert!(svg.contains(r#"dur="3.9900s" repeatCount="indefinite""#));
    let values = |svg: &str| -> Vec<String> {
        svg.split("values=\"").skip(1).map(|v| v.split('"').next().unwrap_or("").to_string()).collect()
    };
    let values = values(&svg);
    let upper: Vec<&str> = values[0].split(';').collect();
    assert_eq!(upper.len(), 100);
    // Each frame is drawn as its still is (same layout), the first as the base path.
    for k in [0, 37, 99] {
        let still = run.svg_frame(k, &options).expect("a frame");
        assert!(still.contains(&format!(r#"<path d="{}""#, upper[k])), "frame {k}");
    }
    assert!(svg.contains(&format!(r#"<path d="{}""#, upper[0])));
    assert!(run.svg_frame(100, &options).is_none());
    assert_ne!(upper[0], upper[50], "the upper rod moves");
    // One sample: a still picture, no animation.
    let one = swinging(1).svg(&options);
    assert!(!one.contains("<animate"));
}

#[test]
fn a_body_is_a_polyline_through_its_joint_points_and_its_marks() {
    let mut run = swinging(3);
    run.add_segment(1, Vector3::new(-0.1, 0.0, 0.0), Vector3::new(0.1, 0.0, 0.0));
    run.add_segment(7, Vector3::zeros(), Vector3::x()); // no such body: ignored
    let still = run.svg_frame(0, &SvgOptions::default()).expect("a frame");
    let paths: Vec<&str> = still.split("<path d=\"").skip(1).map(|p| p.split('"').next().unwrap_or("")).collect();
    // The upper rod through its two joint points; the lower rod through its one
    // joint point from its centre, then the mark.
    let commands = |d: &str| d.chars().filter(|c| c.is_ascii_uppercase()).collect::<String>();
    assert_eq!(paths.iter().map(|d| commands(d)).collect::<Vec<_>>(), ["ML", "MLML"]);
}
