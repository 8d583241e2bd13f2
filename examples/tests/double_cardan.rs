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
