//! The spatial pendulum chain: energy conserved over 10 s by each integrator;
//! the same motion in relative coordinates.

use joint_examples::coordinates;
use joint_examples::pendulum_chain as chain;
use joint_runtime::Scene;
use joint_runtime::dynamics::Integrator;

/// The chain in both coordinate choices from the one declaration: the same
/// start, RK4 at h = 1e-4 for 1 s (the motion is chaotic, so a longer run
/// would compare round-off, not coordinates).
#[test]
fn both_coordinate_choices_give_the_same_motion() {
    let start = chain::initial_state();
    let both = coordinates::both(&chain::scene(), &start, &[], 1e-4, 10_000, |_, _| {}).expect("runs");
    assert!(both.worst < 1e-10, "the coordinate choices differ by {:e}", both.worst);
    assert!((chain::tip(&both.relative) - chain::tip(&start)).norm() > 1.0, "the tip travels");
    // Energy in the tree's coordinates, against the absolute scene's.
    let (e_tree, e_abs) = both.energies;
    assert!((e_tree - e_abs).abs() < 1e-10 * e_abs.abs(), "{e_tree} against {e_abs}");
}

#[test]
fn the_start_is_consistent() {
    let scene = chain::scene();
    let s = chain::initial_state();
    assert!(scene.phi(&s).norm() < 1e-15);
    let mut v = joint_runtime::nalgebra::SVector::<f64, { chain::COLUMNS }>::zeros();
    for (i, b) in s.bodies.iter().enumerate() {
        v.fixed_rows_mut::<3>(6 * i).copy_from(&b.rdot);
        v.fixed_rows_mut::<3>(6 * i + 3).copy_from(&b.omega);
    }
    assert!((scene.jacobian(&s) * v).norm() < 1e-14, "joint velocities match");
    // The whirl moves the tip out of the chain's plane.
    let tip_velocity = s.bodies[4].rdot.y;
    assert!(tip_velocity > 1.0, "{tip_velocity}");
}

#[test]
fn rk4_conserves_energy() {
    let projected = chain::simulate(Integrator::Rk4, true, 1e-3, 10.0, 100).expect("runs");
    assert!(projected.max_relative_energy_error < 1e-10, "{:e}", projected.max_relative_energy_error); // 6.0e-12
    assert!(projected.max_constraint <= 1e-10);
    let free = chain::simulate(Integrator::Rk4, false, 1e-3, 10.0, 100).expect("runs");
    assert!(free.max_relative_energy_error < 1e-8, "{:e}", free.max_relative_energy_error); // 4.0e-10
    assert!(free.max_constraint < 1e-8, "Φ drifts without projection: {:e}", free.max_constraint); // 9.9e-10
    // The chain really swings: the tip travels.
    let tip = chain::tip(&projected.end);
    assert!((tip - chain::tip(&chain::initial_state())).norm() > 1.0);
}

#[test]
fn implicit_midpoint_keeps_energy_bounded() {
    let projected = chain::simulate(Integrator::ImplicitMidpoint, true, 1e-3, 10.0, 100).expect("runs");
    assert!(projected.max_relative_energy_error < 5e-6, "{:e}", projected.max_relative_energy_error); // 5.2e-7
    assert!(projected.final_relative_energy_error.abs() < 1e-6, "{:e}", projected.final_relative_energy_error);
    assert!(projected.max_constraint <= 1e-10);
    assert!(projected.newton_iterations >= 10_000, "at least one Newton iteration per step");
    let free = chain::simulate(Integrator::ImplicitMidpoint, false, 1e-3, 10.0, 100).expect("runs");
    assert!(free.max_relative_energy_error < 1e-5, "{:e}", free.max_relative_energy_error); // 1.3e-6
    assert!(free.max_constraint < 1e-4, "{:e}", free.max_constraint); // 2.7e-5 (index-1 drift)
    // Both integrators agree on where the tip ends.
    let rk4 = chain::simulate(Integrator::Rk4, true, 1e-3, 10.0, 1000).expect("runs");
    assert!((chain::tip(&rk4.end) - chain::tip(&projected.end)).norm() < 1e-3);
}
