//! Error-controlled steps on relative coordinates (`TreeSimulation::
//! integrate`, the absolute path's driver: Dormand–Prince, Radau IIA and
//! generalised-α): against fine RK4 steps, against the absolute scene's own
//! `integrate`, through a loop, and its options refused.

use joint_runtime::Scene;
use joint_runtime::dynamics::{Adaptive, Integrator, NoLoads, Simulation, SimulationOptions, Tolerance};
use joint_runtime::nalgebra::SVector;
use joint_runtime::relative::{TreeError, TreeSimulation, TreeState};

use crate::tree::same_bodies;

/// A double pendulum swinging out of its plane: a spherical shoulder and a
/// revolute elbow.
#[derive(Scene, Clone, Copy, Debug, Default)]
#[scene(gravity = [0, 0, -9.81], coordinates = both)]
#[body(upper, mass = 1.0, inertia = [0.08, 0.08, 0.002])]
#[body(lower, mass = 0.7, inertia = [0.05, 0.05, 0.001])]
#[joint(shoulder = spherical(ground, upper), rho1 = [0, 0, 0], rho2 = [0, 0, 0.5])]
#[joint(elbow = revolute(upper, lower), axis1 = [1, 0, 0], axis2 = [1, 0, 0], rho1 = [0, 0, -0.5], rho2 = [0, 0, 0.4])]
struct Swing;

/// The swing's bodies after 1 s of fine RK4 steps (1e-4 s).
fn swing_reference() -> joint_runtime::SystemState<2> {
    let mut sim = TreeSimulation::new(&Swing).unwrap();
    let mut reference = swing_state();
    for _ in 0..10_000 {
        sim.step(&mut reference, 1e-4).unwrap();
    }
    sim.tree().system_state(&reference)
}

fn swing_state() -> SwingTreeState {
    let n = (0.9f64 * 0.9 + 0.3 * 0.3 + 0.2 * 0.2).sqrt();
    TreeState {
        q: SVector::from_column_slice(&[0.9 / n, 0.3 / n, 0.2 / n, 0.0, 0.8]),
        v: SVector::from_column_slice(&[0.5, -1.0, 2.0, -1.5]),
        t: 0.0,
    }
}

/// Against fine RK4 steps, at three tolerances: the error falls with the
/// tolerance, with more steps, and is at most 1.5 times the absolute
/// scene's own `integrate` at the same tolerance (both about 100 times the
/// tolerance after this swing's second: a global error, of a motion that
/// spreads nearby starts apart).
#[test]
fn adaptive_steps_follow_the_tolerance() {
    let mut sim = TreeSimulation::new(&Swing).unwrap();
    let reference = swing_reference();
    let (mut errors, mut steps) = (Vec::new(), Vec::new());
    for tol in [1e-6, 1e-8, 1e-10] {
        let tolerance = Tolerance { rtol: tol, atol: tol };
        let mut state = swing_state();
        let report = sim.integrate(&mut state, 1.0, Adaptive::DormandPrince, tolerance).unwrap();
        assert_eq!(state.t, 1.0);
        assert_eq!(report.evaluations, 7 * (report.accepted + report.rejected));
        let mut absolute = Simulation::new(&Swing, NoLoads, &[], SimulationOptions::default()).unwrap();
        let mut system = sim.tree().system_state(&swing_state());
        absolute.integrate(&mut system, 1.0, Adaptive::DormandPrince, tolerance).unwrap();
        let (mine, theirs) =
            (same_bodies(&sim.tree().system_state(&state), &reference), same_bodies(&system, &reference));
        assert!(mine <= 1.5 * theirs, "at {tol:e}: {mine:e} against the absolute path's {theirs:e}");
        errors.push(mine);
        steps.push(report.accepted);
    }
    assert!(errors.windows(2).all(|w| w[1] < 0.1 * w[0]) && errors[2] < 1e-8, "{errors:?}");
    assert!(steps.windows(2).all(|w| w[0] < w[1]), "{steps:?}");
}

/// The same declaration integrated in both coordinate choices at a tight
/// tolerance ends in the same bodies' state.
#[test]
fn adaptive_steps_agree_with_the_absolute_scene() {
    let tolerance = Tolerance { rtol: 1e-11, atol: 1e-11 };
    let mut relative = TreeSimulation::new(&Swing).unwrap();
    let mut state = swing_state();
    relative.integrate(&mut state, 1.0, Adaptive::DormandPrince, tolerance).unwrap();
    let mut absolute = Simulation::new(&Swing, NoLoads, &[], SimulationOptions::default()).unwrap();
    let mut system = relative.tree().system_state(&swing_state());
    absolute.integrate(&mut system, 1.0, Adaptive::DormandPrince, tolerance).unwrap();
    let worst = same_bodies(&relative.tree().system_state(&state), &system);
    assert!(worst < 1e-8, "{worst:e}");
}

/// Through a loop: each accepted step closed, the parallelogram's coupler
/// level and its crank and rocker turned alike.
#[test]
fn adaptive_steps_keep_loops_closed() {
    let mut sim = TreeSimulation::new(&crate::loops::FourBar).unwrap();
    let mut state = TreeState { q: SVector::from([0.3, -0.3, 0.3]), v: SVector::from([1.0, -1.0, 1.0]), t: 0.0 };
    sim.integrate(&mut state, 1.0, Adaptive::DormandPrince, Tolerance { rtol: 1e-9, atol: 1e-9 }).unwrap();
    let rows = sim.closure_rows(&state);
    assert!(rows.phi.amax() < 1e-12 && (rows.jacobian * state.v).amax() < 1e-12);
    assert!((state.q[0] + state.q[1]).abs() < 1e-12 && (state.q[0] - state.q[2]).abs() < 1e-12, "{}", state.q);
}

#[test]
fn adaptive_options_out_of_range_are_refused() {
    let mut sim = TreeSimulation::new(&Swing).unwrap();
    let mut state = swing_state();
    let bad = Tolerance { rtol: 0.0, atol: 1e-9 };
    let fine = Tolerance { rtol: 1e-9, atol: 1e-9 };
    assert_eq!(
        sim.integrate(&mut state, 1.0, Adaptive::DormandPrince, bad),
        Err(TreeError::BadOption { name: "tolerance" })
    );
    assert_eq!(
        sim.integrate(&mut state, -1.0, Adaptive::DormandPrince, fine),
        Err(TreeError::BadOption { name: "t_end" })
    );
    let alpha = sim.integrate(&mut state, 1.0, Adaptive::GeneralisedAlpha, Tolerance { rtol: -1.0, atol: 1e-9 });
    assert_eq!(alpha, Err(TreeError::BadOption { name: "tolerance" }));
    assert_eq!(state, swing_state());
}

/// The implicit methods with error control, Radau IIA 5(3) and
/// generalised-α, against fine RK4 steps at three tolerances: the error
/// falls at least tenfold with each hundredfold tighter tolerance and is at
/// most 3 times the absolute scene's own run by the same method at the same
/// tolerance. Measured: Radau IIA 3.1e-4, 6.4e-6, 7.4e-8 (absolute 1.3e-4,
/// 1.7e-5, 2.0e-7); generalised-α 3.6e-2, 3.5e-4, 3.5e-6 (absolute 1.9e-1,
/// 1.8e-3, 1.8e-5: its estimate is local, the error global).
#[test]
fn implicit_error_control_follows_the_tolerance() {
    let mut sim = TreeSimulation::new(&Swing).unwrap();
    let reference = swing_reference();
    for (method, integrator) in
        [(Adaptive::RadauIIA, Integrator::RadauIIA), (Adaptive::GeneralisedAlpha, Integrator::GeneralisedAlpha)]
    {
        let mut errors = Vec::new();
        for tol in [1e-4, 1e-6, 1e-8] {
            let tolerance = Tolerance { rtol: tol, atol: tol };
            let mut state = swing_state();
            let report = sim.integrate(&mut state, 1.0, method, tolerance).unwrap();
            assert!(state.t == 1.0 && report.newton_iterations >= report.accepted, "{report:?}");
            let options = SimulationOptions::default().with_integrator(integrator);
            let mut absolute = Simulation::new(&Swing, NoLoads, &[], options).unwrap();
            let mut system = sim.tree().system_state(&swing_state());
            absolute.integrate(&mut system, 1.0, method, tolerance).unwrap();
            let (mine, theirs) =
                (same_bodies(&sim.tree().system_state(&state), &reference), same_bodies(&system, &reference));
            assert!(mine <= 3.0 * theirs, "{method:?} at {tol:e}: {mine:e} against the absolute path's {theirs:e}");
            errors.push(mine);
        }
        assert!(errors.windows(2).all(|w| w[1] < 0.1 * w[0]), "{method:?}: {errors:?}");
    }
}
