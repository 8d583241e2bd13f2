//! Radau IIA in relative coordinates (`Integrator::RadauIIA` in a
//! `TreeSimulation`'s options, `Adaptive::RadauIIA` in its `integrate`):
//! its stability function on a stiff linear spring, its fifth order on a
//! floating tree, a loop and a quadruped on its feet against fine RK4 runs,
//! and its error control against Dormand–Prince's.

use joint_runtime::dynamics::{Adaptive, Integrator, NewtonMatrix, SimulationOptions, Tolerance};
use joint_runtime::nalgebra::{Matrix2, SVector, Vector2};
use joint_runtime::relative::{TreeScene, TreeSimulation, TreeState};

use crate::floating::{Drone, drone_state};
use crate::tree_implicit_rules::{HardFourBar, Rotor, SoloFeet, four_bar_start, run, solo_start};

fn radau(matrix: NewtonMatrix) -> SimulationOptions {
    SimulationOptions::default().with_integrator(Integrator::RadauIIA).with_newton_matrix(matrix)
}

/// On `ë = −ω² e` a step is `R(h A)`, `R(z) = (1 + 2z/5 + z²/20) / (1 −
/// 3z/5 + 3z²/20 − z³/60)`, Radau IIA(5)'s stability function (the (2, 3)
/// Padé approximant of `exp`; Hairer & Wanner IV.5), written here as a
/// matrix function of the oscillator's `A = [[0, 1], [−ω², 0]]`. At `h ω =
/// 4` the run follows it over 50 steps, both Newton matrices; at `h ω =
/// 1000` (L-stability, `|R| ≈ 3/(h ω)` a step) the mode is gone in ten.
#[test]
fn a_stiff_spring_follows_the_stability_function() {
    let omega = 1000.0_f64;
    for (h, n) in [(4e-3, 50), (1.0, 10)] {
        let z = Matrix2::new(0.0, 1.0, -omega * omega, 0.0) * h;
        let id = Matrix2::identity();
        let p = id + z * 0.4 + z * z / 20.0;
        let q = id - z * 0.6 + z * z * 0.15 - z * z * z / 60.0;
        let step = q.try_inverse().unwrap() * p;
        let mut want = Vector2::new(0.2, 0.0);
        for _ in 0..n {
            want = step * want;
        }
        for matrix in [NewtonMatrix::Generated, NewtonMatrix::FiniteDifferences] {
            let mut sim = TreeSimulation::new(&Rotor).unwrap().with_options(radau(matrix)).unwrap();
            let mut state = TreeState { q: SVector::from([0.3]), v: SVector::zeros(), t: 0.0 };
            for _ in 0..n {
                sim.step(&mut state, h).unwrap();
            }
            let (e, rate) = (state.q[0] - 0.1, state.v[0]);
            assert!((e - want[0]).abs() < 1e-10, "h = {h}, {matrix:?}: {e} against {}", want[0]);
            assert!((rate - want[1]).abs() < 1e-10 * omega, "h = {h}, {matrix:?}: {rate} against {}", want[1]);
            if h == 1.0 {
                let energy = sim.energy(&state).total();
                assert!(energy < 1e-9, "{matrix:?}: {energy} J left of 200");
            }
        }
    }
}

/// At least fifth order against a fine RK4 run (halving the step divides
/// the error by 24–70: 32 in the limit, fourth order's 16 refused; the
/// four-bar measures 49 and 59 from 50 ms down, its fifth-order term
/// small against the next), and the same end from both Newton matrices.
fn fifth_order<S, const NB: usize, const NQ: usize, const NV: usize, const NC: usize>(
    scene: &S,
    start: TreeState<NQ, NV>,
    (t, h): (f64, f64),
) where
    S: TreeScene<NB, NQ, NV, NC>,
{
    let fine = run(scene, SimulationOptions::default(), start, (t / 4000.0, 4000)).0;
    let mut errors = [0.0; 2];
    for (k, error) in errors.iter_mut().enumerate() {
        let coarse = h / f64::from(1 << k);
        let steps = (t / coarse).round() as usize;
        let (end, _) = run(scene, radau(NewtonMatrix::Generated), start, (coarse, steps));
        let (other, _) = run(scene, radau(NewtonMatrix::FiniteDifferences), start, (coarse, steps));
        assert!((end.q - other.q).amax() < 1e-9 && (end.v - other.v).amax() < 1e-8, "h = {coarse}");
        *error = (end.q - fine.q).amax().max((end.v - fine.v).amax() * coarse);
    }
    let ratio = errors[0] / errors[1];
    assert!((24.0..70.0).contains(&ratio), "errors {errors:?}: ratio {ratio}");
}

/// A floating drone with a ball-jointed gripper: the stages' turns through
/// `exp` and their rates through the inverse right Jacobian, the offset
/// turned along the stage.
#[test]
fn a_floating_tree_converges_at_fifth_order() {
    fifth_order(&Drone, drone_state(), (0.4, 0.04));
}

/// The four-bar from its MJCF file with its loop held exactly: the
/// constrained dynamics at every stage, the end projected.
#[test]
fn a_loop_converges_at_fifth_order() {
    fifth_order(&HardFourBar, four_bar_start(), (0.5, 0.05));
}

/// The floating Solo12 on its four feet.
#[test]
fn a_robot_on_its_feet_converges_at_fifth_order() {
    fifth_order(&SoloFeet, solo_start(), (0.1, 0.02));
}

/// Error control: the drone's end at two tolerances against a fine RK4
/// run, within a small multiple of the tolerance and smaller at the
/// tighter one; the loop closed after every accepted step.
#[test]
fn error_control_follows_the_tolerance() {
    let fine = run(&Drone, SimulationOptions::default(), drone_state(), (0.5 / 4000.0, 4000)).0;
    let mut last = f64::INFINITY;
    for tol in [1e-5, 1e-8] {
        let mut sim = TreeSimulation::new(&Drone).unwrap();
        let mut state = drone_state();
        let report = sim.integrate(&mut state, 0.5, Adaptive::RadauIIA, Tolerance { rtol: tol, atol: tol }).unwrap();
        let error = (state.q - fine.q).amax().max((state.v - fine.v).amax());
        assert!(state.t == 0.5 && error < 30.0 * tol && error < last, "tol {tol}: error {error:e}, {report:?}");
        assert!(report.newton_matrices >= 1 && report.accepted > 2, "{report:?}");
        last = error;
    }
    let mut sim = TreeSimulation::new(&HardFourBar).unwrap();
    let mut state = four_bar_start();
    sim.integrate(&mut state, 0.5, Adaptive::RadauIIA, Tolerance { rtol: 1e-8, atol: 1e-8 }).unwrap();
    let rows = sim.closure_rows(&state);
    assert!(rows.phi.amax() < 1e-12 && (rows.jacobian * state.v).amax() < 1e-12, "{}", rows.phi.amax());
}
