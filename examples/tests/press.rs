//! The press in both coordinate choices: a tree of revolute and
//! translational (prismatic) joints, the rocker's ground pivot and the motor
//! closing the loop, the rams on their stiff spring-dampers.

use joint_examples::{coordinates, press};

/// The one declaration in relative coordinates (crank, coupler and rocker
/// angles, the two rams' slides; the rocker's pivot `d` and the `motor`
/// close the loop; the springs' forces enter as joint forces through their
/// ends' Jacobians) against the absolute scene: RK4 at h = 1e-4 (inside the
/// 4e-4 the 7 071 rad/s ram mode allows) for 0.1 s, the crank turning 2 rad;
/// and without the springs, where the rams slide freely, for 0.2 s.
#[test]
fn both_coordinate_choices_agree() {
    let start = press::initial_state().expect("assembled press");
    let springs = press::springs();
    let both = coordinates::both(&press::scene(), &start, &springs, 1e-4, 1_000, |_, _| {}).expect("both run");
    assert!(both.worst < 1e-10, "the coordinate choices differ by {:e}", both.worst);
    let held = (both.relative.bodies[3].r - start.bodies[3].r).norm();
    assert!(held > 0.05, "the rocker's ram moved {held} m only");
    let both = coordinates::both(&press::scene(), &start, &[], 1e-4, 2_000, |_, _| {}).expect("both run");
    assert!(both.worst < 1e-10, "without springs, the coordinate choices differ by {:e}", both.worst);
    let travel = (both.relative.bodies[3].r - start.bodies[3].r).norm();
    assert!(travel > 0.1, "the rocker's ram moved {travel} m only");
}

/// The implicit rules on the press in relative coordinates: a loop with
/// redundant rows and two stiff spring-dampers, whose forces the tree's
/// exact derivatives do not cover, so the Newton matrix is the residual's
/// differences. The implicit midpoint rule and generalised-α, each at least
/// second order against a fine RK4 run, the loop closed at the end.
#[test]
fn the_relative_implicit_rules_are_second_order_on_the_press() {
    use joint_runtime::dynamics::{Integrator, SimulationOptions};
    use joint_runtime::relative::TreeSimulation;
    let scene = press::scene();
    let springs = press::springs();
    let mut fine = TreeSimulation::new(&scene).and_then(|s| s.with_springs(&springs)).expect("the press");
    let start = fine.state_of(&press::initial_state().expect("assembled press")).expect("on its joints");
    let t = 0.05;
    let mut reference = start;
    for _ in 0..5_000 {
        fine.step(&mut reference, t / 5_000.0).expect("RK4 runs");
    }
    for integrator in [Integrator::ImplicitMidpoint, Integrator::GeneralisedAlpha] {
        let options = SimulationOptions::default().with_integrator(integrator);
        let made = TreeSimulation::new(&scene).and_then(|s| s.with_springs(&springs));
        let mut implicit = made.and_then(|s| s.with_options(options)).expect("offered");
        let mut errors = [0.0; 2];
        for (k, error) in errors.iter_mut().enumerate() {
            // h = 0.25 ms and 0.125 ms: h ω = 1.8 and 0.9 on the rams' mode.
            let steps = 200 << k;
            let mut state = start;
            for _ in 0..steps {
                implicit.step(&mut state, t / steps as f64).expect("the rule runs");
            }
            let closed = implicit.closure_rows(&state).phi.amax();
            assert!(closed < 1e-10, "{integrator:?}: the loop is open by {closed:e}");
            *error = (state.q - reference.q).amax();
        }
        // At least second order. The ratio is above 4 and falling toward it
        // (midpoint 7.0, 6.4, 5.8 from 0.5 ms down; generalised-α 7.5,
        // 7.0, 6.5): a third-order term with the stiff mode's large
        // coefficient still weighs at these steps.
        let ratio = errors[0] / errors[1];
        assert!((3.5..8.5).contains(&ratio), "{integrator:?}: errors {errors:?}: ratio {ratio}");
    }
}
