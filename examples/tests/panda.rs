//! The Panda under PD control with gravity compensation
//! (`joint_examples::panda`): what the theory says of it.

use joint_examples::panda::{self, Joints, TARGET};

/// `V = ½ vᵀ M v + ½ eᵀ Kp e` never grows while no torque is clamped
/// (`V̇ = −vᵀ Kd v`; the zero-order hold's gravity term is `O(h)` off, so a
/// step may gain `O(h²)` of it: bounded by 1e-9 of `V(0)`; none does), and the arm
/// settles on the target.
#[test]
fn the_controller_settles_as_lyapunov_says() {
    let run = panda::simulate(3.0, 1e-3).unwrap();
    let v0 = run.samples[0].lyapunov;
    let mut worst = f64::NEG_INFINITY;
    for pair in run.samples.windows(2) {
        if !pair[0].clamped {
            worst = worst.max((pair[1].lyapunov - pair[0].lyapunov) / v0);
        }
    }
    let clamped = run.samples.iter().filter(|s| s.clamped).count();
    let end = run.samples.last().unwrap();
    eprintln!(
        "Panda PD: V(0) = {v0:.3} J, largest rise of V in an unclamped step {worst:.1e} of V(0); {clamped} steps \
         clamped; error at 3 s {:.1e}",
        end.error
    );
    assert!(worst < 1e-9, "V rose by {worst:e} of V(0)");
    assert!(clamped > 0 && clamped < 200, "the effort limits bite at the start only: {clamped}");
    assert!(end.error < 1e-8 && run.end.v.amax() < 1e-7, "{} {}", end.error, run.end.v.amax());
    assert!((run.end.q - Joints::from(TARGET)).amax() < 1e-8);
}

/// The CSV's tracking error, computed back from the bodies' state, is the
/// run's own at the recorded instants.
#[test]
fn the_csv_holds_the_tracking_error() {
    let run = panda::simulate(0.2, 1e-3).unwrap();
    let mut out = Vec::new();
    panda::write_csv(&run, &mut out).unwrap();
    let text = String::from_utf8(out).unwrap();
    let rows: Vec<&str> = text.lines().collect();
    assert_eq!(rows.len(), 1 + 21, "a header and a row every 10 ms");
    assert!(rows[0].ends_with(",tracking_error") && rows[0].starts_with("t,panda_link1.x"));
    for (row, k) in rows[1..].iter().zip((0..).step_by(10)) {
        let csv: f64 = row.rsplit(',').next().unwrap().parse().unwrap();
        let ours = run.samples[k].error;
        assert!((csv - ours).abs() < 1e-9 * ours.max(1.0), "{k}: {csv} against {ours}");
    }
}
