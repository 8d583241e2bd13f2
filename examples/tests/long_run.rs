//! A long run: 10⁶ dynamics steps of the driven Cardan shaft (β = 30°, the
//! motor at one turn per second, RK4 with `h = 1 ms` and projection), 1000 s and
//! 1000 input turns. Checked throughout: ‖Φ‖ after each step's projection
//! (below 1e-10), the velocity constraint `J v + Φ_t`, the Euler parameters'
//! norm error (no growth: the last tenth of the run is no worse than round-off),
//! and, every 1000 steps, the output angle against the closed form
//! `tan φ₂ = tan φ₁ / cos β` — the projection holds positions on Φ = 0, so the
//! output must follow the kinematics however long the run.
//!
//! About 15 s in the test profile (the numeric crates are optimised there).

use joint_examples::cardan::{CardanShaft, output_angle, shaft_angle, wrap};
use joint_runtime::analysis::velocities;
use joint_runtime::dynamics::{NoLoads, Simulation, SimulationOptions};
use joint_runtime::nalgebra::{UnitQuaternion, Vector3};

const STEPS: usize = 1_000_000;
const H: f64 = 1e-3;

#[test]
fn a_million_steps_of_a_driven_cardan_shaft() {
    let bend = 30f64.to_radians();
    let speed = 2.0 * std::f64::consts::PI;
    let scene = CardanShaft::new(bend, speed).expect("a valid bend");
    let mut state = scene.reference_state();
    velocities(&scene, &mut state).expect("the driven shaft's velocities");
    let mut sim = Simulation::new(&scene, NoLoads, &[], SimulationOptions::default()).expect("valid options");
    let output_reference = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), bend);

    let (mut max_phi, mut max_velocity, mut max_angle) = (0.0f64, 0.0f64, 0.0f64);
    // The Euler parameters' norm error over the first and the last tenth of the run.
    let (mut norm_first, mut norm_last) = (0.0f64, 0.0f64);
    let mut max_projection_iterations = 0;
    for k in 1..=STEPS {
        let report = sim.step(&mut state, H).unwrap_or_else(|e| panic!("step {k}: {e}"));
        max_phi = max_phi.max(report.constraint_residual);
        max_velocity = max_velocity.max(report.velocity_residual);
        max_projection_iterations = max_projection_iterations.max(report.projection_iterations);
        let norm_error = state.bodies.iter().map(|b| (b.p.norm() - 1.0).abs()).fold(0.0, f64::max);
        if k <= STEPS / 10 {
            norm_first = norm_first.max(norm_error);
        } else if k > STEPS - STEPS / 10 {
            norm_last = norm_last.max(norm_error);
        }
        if k % 1000 == 0 {
            let input = speed * state.t;
            let got = shaft_angle(&state.bodies[1], &output_reference);
            max_angle = max_angle.max(wrap(got - output_angle(input, bend)).abs());
        }
    }
    println!(
        "{STEPS} steps, t = {:.1} s: max |Φ| {max_phi:.2e}, max |J v + Φ_t| {max_velocity:.2e}, \
         output angle vs closed form {max_angle:.2e} rad, | |p| − 1 | first tenth {norm_first:.2e}, \
         last tenth {norm_last:.2e}; projection iterations ≤ {max_projection_iterations}",
        state.t
    );
    assert!((state.t - STEPS as f64 * H).abs() < 1e-6, "time {}", state.t);
    assert!(max_phi < 1e-10, "constraint drift {max_phi:e}");
    assert!(max_velocity < 1e-9, "velocity constraint {max_velocity:e}");
    assert!(max_angle < 1e-9, "output angle error {max_angle:e}");
    // Renormalised every step: the norm error is round-off, and stays so.
    assert!(norm_first <= 8.0 * f64::EPSILON, "first tenth {norm_first:e}");
    assert!(norm_last <= 8.0 * f64::EPSILON, "last tenth {norm_last:e}");
}
