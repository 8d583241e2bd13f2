//! The steering column against its closed form (two Cardan relations composed)
//! over a full steering turn, and against the same column with the intermediate
//! shaft's lower half as a body of its own.

use core::f64::consts::{PI, TAU};

use joint_examples::steering::{
    INTERMEDIATE_LOWER_X, SteeringColumn, cardan, cardan_ratio, cardan_ratio_derivative, column_direction,
    compare_split, sweep,
};
use joint_runtime::Constant;

const TOLERANCE: f64 = 1e-10;

#[test]
fn pinion_follows_two_cardan_relations_over_a_full_turn() {
    let s = sweep(0.0, 1.0, 360).expect("every step assembles");
    assert_eq!(s.samples.len(), 361);
    assert!(s.max_error() < TOLERANCE, "angle error {:e}", s.max_error());
    assert!(s.max_rate_error() < TOLERANCE, "rate error {:e}", s.max_rate_error());
    assert!(s.max_accel_error() < TOLERANCE, "acceleration error {:e}", s.max_accel_error());
    assert!(s.max_length_error() < 1e-12, "length error {:e}", s.max_length_error());
    assert!(s.samples.iter().all(|x| x.residual <= 1e-14), "assembly left a residual");
    assert!(s.redundant.is_empty(), "unexpected redundant rows: {}", s.redundant);
    // The geometry is what the module documents: two bends of about 26° and 29°
    // in different planes, an intermediate shaft about 0.44 m long.
    assert!((s.geometry.bend_upper.to_degrees() - 25.88).abs() < 0.01, "{}", s.geometry.bend_upper.to_degrees());
    assert!((s.geometry.bend_lower.to_degrees() - 29.39).abs() < 0.01, "{}", s.geometry.bend_lower.to_degrees());
    assert!((s.geometry.length - 0.4409).abs() < 1e-4);
    // One turn of the wheel is one turn of the pinion...
    let (first, last) = (s.samples[0], s.samples[360]);
    assert!((last.input - TAU).abs() < 1e-12);
    assert!((last.output - first.output - TAU).abs() < TOLERANCE);
    // ... but not a uniform one: the pinion leads and lags the wheel by degrees,
    // so the check is not a trivial one.
    let lag = |x: &joint_examples::steering::Sample| x.output - first.output - x.input;
    let (lo, hi) = s.samples.iter().map(lag).fold((f64::MAX, f64::MIN), |(a, b), x| (a.min(x), b.max(x)));
    assert!(hi - lo > 5f64.to_radians(), "fluctuation {}°", (hi - lo).to_degrees());
    let (rmin, rmax) = s.samples.iter().fold((f64::MAX, f64::MIN), |(a, b), x| (a.min(x.rate), b.max(x.rate)));
    assert!(rmin < 0.9 && rmax > 1.1, "speed ratio {rmin}..{rmax}");
    // The length is constant while steering (both joint centres are fixed points).
    assert!(s.samples.iter().all(|x| (x.length - first.length).abs() < 1e-12));
}

#[test]
fn reach_adjustment_is_taken_up_by_the_telescoping_shaft() {
    let a = column_direction();
    for reach in [-0.05, -0.02, 0.0, 0.03, 0.06] {
        let s = sweep(reach, 2.0, 72).expect("every step assembles");
        assert!(s.max_error() < TOLERANCE, "reach {reach}: angle error {:e}", s.max_error());
        assert!(s.max_rate_error() < TOLERANCE, "reach {reach}: rate error {:e}", s.max_rate_error());
        assert!(s.max_accel_error() < TOLERANCE, "reach {reach}: acceleration error {:e}", s.max_accel_error());
        assert!(s.max_length_error() < 1e-12, "reach {reach}: length error {:e}", s.max_length_error());
        // The length is the distance between the joint centres, the upper one moved along the column.
        let column = SteeringColumn::new(Constant(0.0), reach);
        let length = (column.lower_joint() - a * reach).norm();
        for x in &s.samples {
            assert!((x.length - length).abs() < 1e-12);
            assert!(
                (x.slide - (length + joint_examples::steering::INTERMEDIATE_UPPER_X - INTERMEDIATE_LOWER_X)).abs()
                    < 1e-12
            );
        }
    }
}

#[test]
fn two_angle_joint_with_sliding_equals_spline_and_cardan() {
    for reach in [-0.03, 0.0, 0.04] {
        let c = compare_split(reach, 1.0, 180).expect("both models assemble");
        assert!(c.angle < TOLERANCE && c.rate < TOLERANCE && c.accel < TOLERANCE, "{c:?}");
        assert!(c.length < 1e-12, "{c:?}");
        assert!(c.redundant.is_empty(), "unexpected redundant rows: {}", c.redundant);
    }
}

#[test]
fn cardan_relation_and_its_derivatives() {
    for cos_bend in [1.0, 0.9, 0.6, 0.2] {
        for k in -40..=40 {
            let phi = f64::from(k) * PI / 17.0 + 0.01;
            let psi = cardan(phi, cos_bend);
            // tan ψ = cos β tan φ, on the branch within a quarter turn of φ.
            assert!((psi.sin() * phi.cos() - cos_bend * phi.sin() * psi.cos()).abs() < 1e-14);
            assert!((psi - phi).abs() < PI / 2.0);
            // The ratio and its derivative, against central differences.
            let h = 1e-5;
            let ratio = (cardan(phi + h, cos_bend) - cardan(phi - h, cos_bend)) / (2.0 * h);
            assert!((ratio - cardan_ratio(phi, cos_bend)).abs() < 1e-8);
            let slope = (cardan_ratio(phi + h, cos_bend) - cardan_ratio(phi - h, cos_bend)) / (2.0 * h);
            assert!((slope - cardan_ratio_derivative(phi, cos_bend)).abs() < 1e-7);
        }
    }
    // A half turn in is a half turn out.
    assert!((cardan(PI, 0.7) - PI).abs() < 1e-15);
}

/// Both declarations in relative coordinates (column, intermediate shaft on
/// the upper Cardan joint: a `universal` tree joint, pinion; the spline
/// variant's lower half on a `translational` one; the lower Cardan joint and
/// the steering driver close the loop) against the absolute scenes: RK4 at
/// h = 1e-4 for 0.3 s of steering at 2 rad/s from an assembled start, and the
/// pinion against the closed form.
#[test]
fn both_coordinate_choices_agree_with_the_closed_form() {
    use joint_examples::coordinates;
    use joint_runtime::Ramp;
    use joint_runtime::analysis::{AssemblyOptions, assemble, velocities};
    let column = SteeringColumn::new(Ramp { start: 0.0, rate: 2.0 }, 0.02);
    let mut start = column.rough_state(0.0);
    assemble(&column, &mut start, &AssemblyOptions::default().with_tolerance(1e-14)).expect("assembles");
    velocities(&column, &mut start).expect("driven velocities");
    let both = coordinates::both(&column, &start, &[], 1e-4, 3_000, |_, _| {}).expect("both run");
    assert!(both.worst < 1e-10, "the coordinate choices differ by {:e}", both.worst);
    let closed = column.closed_form(joint_runtime::TimeFunction::eval(&column.steer, 0.3));
    let angle = column.output_angle(&both.relative);
    assert!(
        joint_examples::steering::wrap(angle - closed.output_angle).abs() < 1e-9,
        "{angle} against {}",
        closed.output_angle
    );
    let split = column.split();
    let mut start = split.rough_state(0.0);
    assemble(&split, &mut start, &AssemblyOptions::default().with_tolerance(1e-14)).expect("assembles");
    velocities(&split, &mut start).expect("driven velocities");
    let both = coordinates::both(&split, &start, &[], 1e-4, 3_000, |_, _| {}).expect("both run");
    assert!(both.worst < 1e-10, "the split column's coordinate choices differ by {:e}", both.worst);
}
