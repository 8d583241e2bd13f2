//! Generated second-order terms of scenes (`#[scene(second_order)]`) against
//! Richardson-extrapolated central differences of the generated J and γ on
//! the rotation group, at random states: a chain with a closed loop and a
//! driver, so every kind of row (spherical, revolute, distance, a time
//! function) meets bodies that move.

#![allow(missing_docs)]

use joint_runtime::nalgebra::SVector;
use joint_runtime::{Constant, Scene, Sinusoid, SystemState};
use joint_tests::random::Rng;
use joint_tests::second_order::worst_error;

/// A driven four-bar with a pendulum hung from the coupler: revolute, spherical,
/// distance and a rotational driver, a closed loop.
#[derive(Scene)]
#[scene(coordinates = absolute, gravity = [0, 0, -9.81], second_order)]
#[body(crank, mass = 1.0, inertia = [0.1, 0.2, 0.3])]
#[body(coupler, mass = 2.0, inertia = [0.2, 0.3, 0.4])]
#[body(rocker, mass = 1.5, inertia = [0.3, 0.2, 0.1])]
#[body(bob, mass = 0.5, inertia = [0.01, 0.02, 0.03])]
#[joint(a = revolute(ground, crank), rho1 = [0, 0, 0], rho2 = [-0.5, 0, 0], axis1 = [0, 0, 1], axis2 = [0, 0, 1])]
#[joint(b = spherical(crank, coupler), rho1 = [0.5, 0, 0], rho2 = [-1, 0, 0])]
#[joint(c = distance(coupler, rocker), rho1 = [1, 0, 0], rho2 = [0, 0.7, 0], length = 0.3)]
#[joint(d = revolute(rocker, ground), rho1 = [0, -0.7, 0.1], rho2 = [2, 0, 0], axis1 = [0.6, 0, 0.8], axis2 = [0, 0, 1])]
#[joint(e = spherical(coupler, bob), rho1 = [0, 0.2, 0], rho2 = [0, 0, 0.4])]
#[joint(drive = rotational_driver(ground, crank), axis1 = [0, 0, 1], axis2 = [0, 0, 1], theta = theta)]
struct Rig {
    theta: Sinusoid,
}

#[test]
fn scene_second_order_terms_match_differences_of_j_and_gamma() {
    let rig = Rig { theta: Sinusoid { amplitude: 0.7, frequency: 1.3, phase: 0.2, offset: 0.1 } };
    let mut rng = Rng(7);
    let mut worst = (0.0f64, "");
    for _ in 0..20 {
        let state = SystemState { bodies: [(); 4].map(|_| rng.omega_body()), t: rng.next() };
        let lambda = SVector::<f64, { Rig::ROWS }>::from_fn(|_, _| rng.next() * 10.0);
        let u = SVector::<f64, 24>::from_fn(|_, _| rng.next() * 5.0);
        let e = worst_error(&rig, &state, &lambda, &u);
        if e.0 > worst.0 {
            worst = e;
        }
    }
    assert!(worst.0 < 1e-8, "worst {} error {:e}", worst.1, worst.0);
}

/// A scene derived without `second_order` returns `None`.
#[test]
fn scenes_without_the_option_give_none() {
    #[derive(Scene)]
    #[scene(coordinates = absolute)]
    #[body(bob, mass = 1.0, inertia = [1, 1, 1])]
    #[joint(pivot = spherical(ground, bob), rho1 = [0, 0, 0], rho2 = [0, 0, 1])]
    struct Plain;
    let state = SystemState { bodies: [Rng(1).omega_body()], t: 0.0 };
    assert!(Plain.second_order(&state, &SVector::zeros(), &SVector::zeros()).is_none());
    let _ = Constant(1.0);
}

/// The sparse path's terms by differences (`DifferenceTerms`, for scenes
/// derived without `second_order`) against the generated ones, every entry of
/// the sparse layout, at random states of the rig: its bodies in two colours
/// (no joint between two of one colour), so one evaluation moves several.
#[test]
fn difference_terms_match_the_generated_ones() {
    use joint_runtime::SparseJacobian;
    use joint_runtime::absolute::{DifferenceTerms, SecondOrderLayout};
    let rig = Rig { theta: Sinusoid { amplitude: 0.7, frequency: 1.3, phase: 0.2, offset: 0.1 } };
    let layout = SecondOrderLayout::new(Rig::BLOCKS, Rig::BLOCK_BODIES);
    let terms = DifferenceTerms::<4>::new(Rig::BLOCK_BODIES);
    assert_eq!(terms.colours(), 2);
    let mut rng = Rng(11);
    let mut worst = 0.0f64;
    for _ in 0..20 {
        let state = SystemState { bodies: [(); 4].map(|_| rng.omega_body()), t: rng.next() };
        let lambda = SVector::<f64, { Rig::ROWS }>::from_fn(|_, _| rng.next() * 10.0);
        let u = SVector::<f64, 24>::from_fn(|_, _| rng.next() * 5.0);
        let (mut exact, mut differences) = (vec![0.0; layout.len()], vec![0.0; layout.len()]);
        assert!(rig.second_order_values(&state, &lambda, &u, &mut exact));
        assert!(terms.values(&rig, &state, &lambda, &u, &mut differences));
        let scale = exact.iter().fold(1.0f64, |m, x| m.max(x.abs()));
        for (x, y) in exact.iter().zip(&differences) {
            worst = worst.max((x - y).abs() / scale);
        }
        // A buffer of the wrong length is refused, untouched.
        let mut short = vec![7.0; layout.len() - 1];
        assert!(!terms.values(&rig, &state, &lambda, &u, &mut short) && short.iter().all(|&x| x == 7.0));
    }
    println!("terms by differences against the generated ones: worst {worst:e} of the largest");
    assert!(worst < 1e-8, "{worst:e}");
}
