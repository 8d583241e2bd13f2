//! The Cardan shaft against its closed form: output angle and speed to 1e-10 over
//! one turn for β = 10°, 30°, 60°, 85°, the extreme speed ratios `cos β` and
//! `1/cos β`, and the three redundant rows (the cross's spherical rows repeat the
//! bearings').

use joint_examples::cardan::{self, CardanShaft, output_angle, speed_ratio};
use joint_examples::coordinates;

const SPEED: f64 = 2.0 * std::f64::consts::PI;

#[test]
fn output_angle_and_speed_match_the_closed_form() {
    for degrees in [10.0f64, 30.0, 60.0, 85.0] {
        let bend = degrees.to_radians();
        let s = cardan::sweep(bend, SPEED, 360).expect("the sweep runs");
        assert_eq!(s.samples.len(), 360);
        assert!(s.max_angle_error <= 1e-10, "β = {degrees}°: angle error {:e}", s.max_angle_error);
        assert!(s.max_speed_error <= 1e-10, "β = {degrees}°: speed error {:e}", s.max_speed_error);
        assert!(s.max_input_error <= 1e-10, "β = {degrees}°: the driver is off by {:e}", s.max_input_error);
        // 1° steps hit φ₁ = 0 (largest ratio) and 90° (smallest) exactly.
        assert!((s.min_ratio - bend.cos()).abs() <= 1e-10, "β = {degrees}°: min ratio {}", s.min_ratio);
        assert!((s.max_ratio - 1.0 / bend.cos()).abs() <= 1e-10, "β = {degrees}°: max ratio {}", s.max_ratio);
        // One whole output turn per input turn: the unwrapped output angle ends near 2π.
        let last = s.samples.last().expect("samples");
        assert!((last.output_angle - output_angle(last.input_angle, bend)).abs() <= 1e-10);
        assert!(last.output_angle > 6.0 && last.output_angle < 2.0 * std::f64::consts::PI);
    }
}

#[test]
fn the_cross_repeats_the_bearings_three_rows() {
    for degrees in [10.0f64, 60.0] {
        let s = cardan::sweep(degrees.to_radians(), SPEED, 72).expect("the sweep runs");
        assert_eq!(s.redundant.len(), 3, "β = {degrees}°: {:?}", s.redundant);
        // Always three, wherever the pivoting puts them: each a translational
        // (spherical) row of a bearing or of the cross.
        assert!(s.redundant_variants.iter().all(|v| v.len() == 3), "{:?}", s.redundant_variants);
        for r in s.redundant_variants.iter().flatten() {
            assert!(
                matches!((r.joint, r.joint_row), ("input_bearing" | "output_bearing" | "cross", 0..=2)),
                "unexpected redundant row {r}"
            );
        }
    }
    let blocks = CardanShaft::BLOCKS;
    assert_eq!(blocks.iter().map(|b| b.rows).sum::<usize>(), 15);
}

#[test]
fn closed_form_is_its_own_derivative() {
    // The speed ratio is dφ₂/dφ₁ (central differences), and tan φ₂ = tan φ₁ / cos β.
    for degrees in [10.0f64, 30.0, 60.0, 85.0] {
        let bend = degrees.to_radians();
        for k in 0..50 {
            let x = -7.0 + 0.29 * k as f64;
            let h = 1e-5;
            let d = (output_angle(x + h, bend) - output_angle(x - h, bend)) / (2.0 * h);
            assert!((d - speed_ratio(x, bend)).abs() < 1e-7 * speed_ratio(x, bend).max(1.0));
            let y = output_angle(x, bend);
            assert!((y.sin() * x.cos() * bend.cos() - x.sin() * y.cos()).abs() < 1e-14);
        }
    }
    assert!(CardanShaft::new(90f64.to_radians(), 1.0).is_none());
}

/// The one declaration in relative coordinates (the two bearing angles; the
/// cross and the motor close the loop, the output bearing's axis and centre
/// read from its fields at run time) against the absolute scene and the
/// closed form: RK4 at h = 1e-4 for 0.4 of a turn at β = 30°.
#[test]
fn both_coordinate_choices_agree_with_the_closed_form() {
    let bend = 30f64.to_radians();
    let shaft = CardanShaft::new(bend, SPEED).expect("a shaft");
    let mut start = shaft.reference_state();
    joint_runtime::analysis::velocities(&shaft, &mut start).expect("the driven velocities");
    let both = coordinates::both(&shaft, &start, &[], 1e-4, 4_000, |_, _| {}).expect("both run");
    assert!(both.worst < 1e-10, "the coordinate choices differ by {:e}", both.worst);
    let reference = shaft.reference_state();
    let phi1 = cardan::shaft_angle(&both.relative.bodies[0], &reference.bodies[0].rotation());
    let phi2 = cardan::shaft_angle(&both.relative.bodies[1], &reference.bodies[1].rotation());
    assert!((phi1 - SPEED * 0.4).abs() < 1e-10, "input at {phi1}");
    assert!((cardan::wrap(phi2 - output_angle(phi1, bend))).abs() < 1e-10, "output at {phi2}");
}
