//! The double Cardan shaft: constant velocity with the intermediate yokes in
//! phase, the product of two single-joint fluctuations a quarter turn out of
//! phase, in the Z and W arrangements; one redundant row (the intermediate
//! shaft's length).

use joint_examples::double_cardan::{self, Arrangement, Phasing};

const SPEED: f64 = 2.0 * std::f64::consts::PI;

#[test]
fn in_phase_yokes_give_constant_output_speed() {
    for arrangement in [Arrangement::Z, Arrangement::W] {
        for degrees in [10.0f64, 30.0, 60.0] {
            let s = double_cardan::sweep(degrees.to_radians(), arrangement, Phasing::InPhase, SPEED, 360)
                .expect("the sweep runs");
            assert!(
                s.max_output_fluctuation <= 1e-10,
                "{arrangement:?} {degrees}°: |ω_o − ω₁| up to {:e}",
                s.max_output_fluctuation
            );
            assert!(s.max_angle_error <= 1e-10, "{arrangement:?} {degrees}°: angle error {:e}", s.max_angle_error);
            assert!(s.max_speed_error <= 1e-10, "{arrangement:?} {degrees}°: speed error {:e}", s.max_speed_error);
            assert!((s.min_ratio - 1.0).abs() <= 1e-10 && (s.max_ratio - 1.0).abs() <= 1e-10);
        }
    }
}

#[test]
fn quarter_phase_fluctuation_is_the_product_of_both_joints() {
    for arrangement in [Arrangement::Z, Arrangement::W] {
        for degrees in [10.0f64, 30.0, 60.0] {
            let bend = degrees.to_radians();
            let s = double_cardan::sweep(bend, arrangement, Phasing::Quarter, SPEED, 360).expect("the sweep runs");
            assert!(s.max_angle_error <= 1e-10, "{arrangement:?} {degrees}°: angle error {:e}", s.max_angle_error);
            assert!(s.max_speed_error <= 1e-10, "{arrangement:?} {degrees}°: speed error {:e}", s.max_speed_error);
            assert!(s.max_formula_difference <= 1e-12, "the two closed forms differ by {:e}", s.max_formula_difference);
            let c2 = bend.cos().powi(2);
            assert!((s.min_ratio - c2).abs() <= 1e-10, "min ratio {} vs cos²β {c2}", s.min_ratio);
            assert!((s.max_ratio - 1.0 / c2).abs() <= 1e-10, "max ratio {} vs 1/cos²β", s.max_ratio);
        }
    }
}

#[test]
fn the_intermediate_shaft_length_is_imposed_twice() {
    for arrangement in [Arrangement::Z, Arrangement::W] {
        for phasing in [Phasing::InPhase, Phasing::Quarter] {
            let s = double_cardan::sweep(30f64.to_radians(), arrangement, phasing, SPEED, 72).expect("the sweep runs");
            assert_eq!(s.redundant.len(), 1, "{arrangement:?} {phasing:?}: {:?}", s.redundant);
            assert!(s.redundant_variants.iter().all(|v| v.len() == 1), "{:?}", s.redundant_variants);
            for r in s.redundant_variants.iter().flatten() {
                assert!(
                    matches!((r.joint, r.joint_row), ("input_bearing" | "output_bearing" | "first" | "second", 0..=2)),
                    "unexpected redundant row {r}"
                );
            }
        }
    }
}

/// The one declaration in relative coordinates (the bearing angles and the
/// first Cardan joint's two angles: a `universal` tree joint; the second
/// Cardan joint and the motor close the loop) against the absolute scene:
/// RK4 at h = 1e-4 for 0.4 s at 30°, yokes in phase: the output turns with
/// the input, and the free shaft (no motor) moves alike in both too.
#[test]
fn both_coordinate_choices_agree() {
    use joint_examples::cardan::shaft_angle;
    use joint_examples::coordinates;
    use joint_examples::double_cardan::{DoubleCardan, FreeDoubleCardan, Geometry};
    let geometry = Geometry::new(30f64.to_radians(), Arrangement::Z, Phasing::InPhase).expect("a geometry");
    let shaft = DoubleCardan::new(geometry, SPEED);
    let start = shaft.initial_state().expect("assembled");
    let both = coordinates::both(&shaft, &start, &[], 1e-4, 4_000, |_, _| {}).expect("both run");
    assert!(both.worst < 1e-10, "the coordinate choices differ by {:e}", both.worst);
    let [qi, _, qo] = geometry.references();
    let (phi_i, phi_o) = (shaft_angle(&both.relative.bodies[0], &qi), shaft_angle(&both.relative.bodies[2], &qo));
    assert!((phi_i - SPEED * 0.4).abs() < 1e-10, "input at {phi_i}");
    assert!((phi_o - phi_i).abs() < 1e-10, "output at {phi_o}, input at {phi_i}");
    let free = FreeDoubleCardan::new(&geometry);
    let both = coordinates::both(&free, &start, &[], 1e-4, 4_000, |_, _| {}).expect("both run");
    assert!(both.worst < 1e-10, "the free shaft's coordinate choices differ by {:e}", both.worst);
}
