//! The implicit rules in relative coordinates (`Integrator::ImplicitMidpoint`
//! and `Integrator::GeneralisedAlpha` in a `TreeSimulation`'s options):
//! their closed forms on a stiff linear spring, their second order on a
//! floating tree, a loop and a quadruped on its feet against fine RK4 runs,
//! and the exact Newton matrix's iteration counts against the differenced
//! one's.

use joint_runtime::Scene;
use joint_runtime::dynamics::{Integrator, NewtonMatrix, SimulationOptions};
use joint_runtime::nalgebra::SVector;
use joint_runtime::relative::{TreeScene, TreeSimulation, TreeState};

use crate::floating::{Drone, drone_state};

/// A joint spring of 1e4 N·m/rad on a rotor of 0.01 kg·m² (no gravity):
/// `ω = 1000 rad/s`.
#[derive(Scene)]
#[scene(gravity = [0, 0, 0], coordinates = relative)]
#[body(rotor, mass = 1.0, inertia = [0.01, 0.01, 0.01])]
#[joint(pin = revolute(ground, rotor), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0, 0, 0], rho2 = [0, 0, 0], stiffness = 1e4, spring_rest = 0.1)]
pub(crate) struct Rotor;

fn midpoint(matrix: NewtonMatrix) -> SimulationOptions {
    implicit(Integrator::ImplicitMidpoint, matrix)
}

fn implicit(integrator: Integrator, matrix: NewtonMatrix) -> SimulationOptions {
    SimulationOptions::default().with_integrator(integrator).with_newton_matrix(matrix)
}

/// On `ë = −ω² e` the midpoint rule turns `(e, ė/ω)` by exactly
/// `2 atan(h ω / 2)` a step (its map is the Cayley transform of the
/// rotation's generator), keeps the energy, and stays bounded at
/// `h ω = 4`, where RK4 diverges. Both Newton matrices: the exact one in two
/// iterations (the second only confirms), one matrix for the whole run.
#[test]
fn a_stiff_spring_turns_by_the_rules_closed_form_angle() {
    let (omega, h, n) = (1000.0_f64, 4e-3, 250);
    let turn = 2.0 * (0.5 * h * omega).atan();
    for matrix in [NewtonMatrix::Generated, NewtonMatrix::FiniteDifferences] {
        let mut sim = TreeSimulation::new(&Rotor).unwrap().with_options(midpoint(matrix)).unwrap();
        let mut state = TreeState { q: SVector::from([0.3]), v: SVector::zeros(), t: 0.0 };
        let (mut iterations, mut matrices) = (0, 0);
        for _ in 0..n {
            let report = sim.step(&mut state, h).unwrap();
            matrices += report.newton_matrices;
            iterations = iterations.max(report.newton_iterations);
        }
        // Linear: the first step's matrix serves every step.
        assert_eq!(matrices, 1, "{matrix:?}");
        let angle = n as f64 * turn;
        let (e, rate) = (0.2 * angle.cos(), -0.2 * omega * angle.sin());
        assert!((state.q[0] - 0.1 - e).abs() < 1e-11, "{matrix:?}: {} against {e}", state.q[0] - 0.1);
        assert!((state.v[0] - rate).abs() < 1e-8, "{matrix:?}: {} against {rate}", state.v[0]);
        let energy = sim.energy(&state).total();
        assert!((energy - 200.0).abs() < 1e-9, "{matrix:?}: {energy}");
        let most = if matrix == NewtonMatrix::Generated { 2 } else { 3 };
        assert!(iterations <= most, "{matrix:?}: {iterations} iterations");
    }
}

/// Generalised-α on `ë = −ω² e` follows its own recurrence, written here
/// from the method's definition (one linear equation for `v̇_{n+1}` a step,
/// `a` and `v̇` carried), over 50 steps at `h ω = 4`; and at `h ω = 1000`,
/// far past every step a stiff mode would be resolved at, it damps the
/// mode out (ρ∞ = 0.5 a step) where the midpoint rule keeps its energy.
#[test]
fn generalised_alpha_follows_its_recurrence_and_damps_a_stiff_spring() {
    let (omega, rho) = (1000.0_f64, 0.5);
    let (alpha_m, alpha_f) = ((2.0 * rho - 1.0) / (rho + 1.0), rho / (rho + 1.0));
    let gamma = 0.5 + alpha_f - alpha_m;
    let beta = 0.25 * (gamma + 0.5) * (gamma + 0.5);
    let options = implicit(Integrator::GeneralisedAlpha, NewtonMatrix::Generated).with_spectral_radius(rho);
    for h in [4e-3, 1.0] {
        let mut sim = TreeSimulation::new(&Rotor).unwrap().with_options(options).unwrap();
        let mut state = TreeState { q: SVector::from([0.3]), v: SVector::zeros(), t: 0.0 };
        // The recurrence: e = θ − 0.1, its rate, v̇ and the pseudo-acceleration.
        let (mut e, mut rate) = (0.2, 0.0);
        let (mut vdot, mut a) = (-omega * omega * e, -omega * omega * e);
        for _ in 0..50 {
            sim.step(&mut state, h).unwrap();
            let known = e
                + h * rate
                + h * h * (0.5 - beta) * a
                + h * h * beta * (alpha_f * vdot - alpha_m * a) / (1.0 - alpha_m);
            let next =
                -omega * omega * known / (1.0 + omega * omega * h * h * beta * (1.0 - alpha_f) / (1.0 - alpha_m));
            let pseudo = ((1.0 - alpha_f) * next + alpha_f * vdot - alpha_m * a) / (1.0 - alpha_m);
            e += h * rate + h * h * (0.5 - beta) * a + h * h * beta * pseudo;
            rate += h * (1.0 - gamma) * a + h * gamma * pseudo;
            (vdot, a) = (next, pseudo);
        }
        assert!((state.q[0] - 0.1 - e).abs() < 1e-11, "h = {h}: {} against {e}", state.q[0] - 0.1);
        assert!((state.v[0] - rate).abs() < 1e-8, "h = {h}: {} against {rate}", state.v[0]);
    }
    // At h ω = 1000 the mode is gone after 50 steps; the midpoint rule keeps it.
    let damped = |integrator| {
        let options = implicit(integrator, NewtonMatrix::Generated).with_spectral_radius(rho);
        let mut sim = TreeSimulation::new(&Rotor).unwrap().with_options(options).unwrap();
        let mut state = TreeState { q: SVector::from([0.3]), v: SVector::zeros(), t: 0.0 };
        for _ in 0..50 {
            sim.step(&mut state, 1.0).unwrap();
        }
        sim.energy(&state).total()
    };
    let (alpha, midpoint) = (damped(Integrator::GeneralisedAlpha), damped(Integrator::ImplicitMidpoint));
    assert!(alpha < 1e-9 && (midpoint - 200.0).abs() < 1e-6, "{alpha} J and {midpoint} J left of 200");
}

/// The end of `steps` steps of `h` from `start` with `options`, and the
/// Newton iterations they took.
pub(crate) fn run<S, const NB: usize, const NQ: usize, const NV: usize, const NC: usize>(
    scene: &S,
    options: SimulationOptions,
    start: TreeState<NQ, NV>,
    (h, steps): (f64, usize),
) -> (TreeState<NQ, NV>, usize)
where
    S: TreeScene<NB, NQ, NV, NC>,
{
    let mut sim = TreeSimulation::new(scene).unwrap().with_options(options).unwrap();
    let (mut state, mut iterations, mut matrices) = (start, 0, 0);
    for _ in 0..steps {
        let report = sim.step(&mut state, h).unwrap();
        iterations += report.newton_iterations;
        matrices += report.newton_matrices;
    }
    // At most two matrices a step: a kept one rebuilt once.
    assert!(matrices <= 2 * steps, "{matrices} matrices in {steps} steps");
    (state, iterations)
}

/// Second order against a fine RK4 run (halving the step divides the
/// error by 3.5–4.5), and the same end from both Newton matrices, the exact
/// one in no more iterations than the differenced one but one in ten steps.
fn second_order<S, const NB: usize, const NQ: usize, const NV: usize, const NC: usize>(
    scene: &S,
    start: TreeState<NQ, NV>,
    (t, h): (f64, f64),
) where
    S: TreeScene<NB, NQ, NV, NC>,
{
    let fine = run(scene, SimulationOptions::default(), start, (t / 1000.0, 1000)).0;
    let mut errors = [[0.0; 2]; 2];
    for (k, error) in errors.iter_mut().enumerate() {
        let coarse = h / f64::from(1 << k);
        let steps = (t / coarse).round() as usize;
        for (integrator, error) in [Integrator::ImplicitMidpoint, Integrator::GeneralisedAlpha].into_iter().zip(error) {
            let (end, iterations) = run(scene, implicit(integrator, NewtonMatrix::Generated), start, (coarse, steps));
            let differenced = implicit(integrator, NewtonMatrix::FiniteDifferences);
            let (other, more) = run(scene, differenced, start, (coarse, steps));
            assert!((end.q - other.q).amax() < 1e-9 && (end.v - other.v).amax() < 1e-8, "{integrator:?}");
            // The exact matrix converges as fast as the differenced one: kept
            // across steps, the two are rebuilt at different steps, which
            // moves a count by an iteration now and then.
            assert!(
                iterations <= more + steps / 10,
                "{integrator:?}: {iterations} iterations against {more} at h = {coarse}"
            );
            *error = (end.q - fine.q).amax().max((end.v - fine.v).amax() * coarse);
        }
    }
    for (k, integrator) in ["midpoint", "generalised-α"].into_iter().enumerate() {
        let ratio = errors[0][k] / errors[1][k];
        assert!((3.5..4.5).contains(&ratio), "{integrator}: errors {errors:?}: ratio {ratio}");
    }
}

/// A floating drone with a ball-jointed gripper: both turns go through
/// `exp`, and the Newton matrix through their right Jacobians.
#[test]
fn a_floating_tree_converges_at_second_order() {
    second_order(&Drone, drone_state(), (0.4, 0.02));
}

/// The four-bar from its MJCF file with its loop held exactly: the
/// constrained dynamics at the midpoint, the end projected.
#[derive(Scene)]
#[scene(mjcf = "data/mjcf/four_bar.xml", equality = hard)]
pub(crate) struct HardFourBar;

/// The four-bar off its upright balance: the crank turned 0.3 rad, the
/// loop closed.
pub(crate) fn four_bar_start() -> TreeState<3, 3> {
    let sim = TreeSimulation::new(&HardFourBar).unwrap();
    let mut guess = sim.tree().zero_state();
    guess.q[0] = 0.3;
    sim.assemble(&guess).unwrap()
}

#[test]
fn a_loop_converges_at_second_order() {
    second_order(&HardFourBar, four_bar_start(), (0.5, 0.025));
}

/// The floating Solo12 from its URDF file on its four feet.
#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], urdf = "data/robots/solo12.urdf", floating_base)]
#[contact(fl = point(FL_FOOT); fr = point(FR_FOOT); hl = point(HL_FOOT); hr = point(HR_FOOT))]
pub(crate) struct SoloFeet;

/// A quadruped on its four feet (a floating base, twelve contact rows, the
/// feet's velocities projected out after each step): the constrained
/// dynamics' exact derivatives make the Newton matrix.
#[test]
fn a_robot_on_its_feet_converges_at_second_order() {
    second_order(&SoloFeet, solo_start(), (0.1, 0.01));
}

/// The Solo12 30 cm up, its feet on the ground and its joints moving.
pub(crate) fn solo_start() -> TreeState<19, 18> {
    let sim = TreeSimulation::new(&SoloFeet).unwrap();
    let mut guess = sim.tree().zero_state();
    guess.q[2] = 0.3;
    for (k, x) in guess.v.iter_mut().enumerate() {
        *x = 0.5 * (k as f64).sin();
    }
    sim.assemble(&guess).unwrap()
}

/// Generalised-α on a loop is index 3: `Φ(q_{n+1}) = 0` is one of its
/// Newton equations, so with the projection switched off the hard
/// four-bar's loop stays closed to Newton's tolerance over 200 steps of
/// 10 ms (the midpoint rule, at index 1, drifts off it), with both Newton
/// matrices, and the forces it carries between steps are the constrained
/// dynamics' (the run ends where the projected run ends, to 1e-9).
#[test]
fn generalised_alpha_holds_a_loop_closed_at_index_3() {
    let unprojected = |integrator, matrix| {
        let mut options = implicit(integrator, matrix);
        options.projection = None;
        options
    };
    let sim = TreeSimulation::new(&HardFourBar).unwrap();
    let loop_error = |end: &TreeState<3, 3>| sim.closure_rows(end).phi.amax();
    for matrix in [NewtonMatrix::Generated, NewtonMatrix::FiniteDifferences] {
        let (end, _) =
            run(&HardFourBar, unprojected(Integrator::GeneralisedAlpha, matrix), four_bar_start(), (0.01, 200));
        assert!(loop_error(&end) < 1e-9, "{matrix:?}: |Φ| = {:e}", loop_error(&end));
        let projected =
            run(&HardFourBar, implicit(Integrator::GeneralisedAlpha, matrix), four_bar_start(), (0.01, 200)).0;
        assert!((end.q - projected.q).amax() < 1e-9, "{matrix:?}: {} {}", end.q, projected.q);
    }
    let (drifted, _) = run(
        &HardFourBar,
        unprojected(Integrator::ImplicitMidpoint, NewtonMatrix::Generated),
        four_bar_start(),
        (0.01, 200),
    );
    assert!(loop_error(&drifted) > 1e-7, "the index-1 rule drifts: |Φ| = {:e}", loop_error(&drifted));
}
