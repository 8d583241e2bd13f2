//! The implicit midpoint rule in relative coordinates
//! (`SimulationOptions::with_integrator(Integrator::ImplicitMidpoint)` on a
//! `TreeSimulation`): its closed form on a stiff linear spring, its second
//! order on a floating tree and on a loop against fine RK4 runs, and the
//! exact Newton matrix's iteration counts against the differenced one's.

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
struct Rotor;

fn midpoint(matrix: NewtonMatrix) -> SimulationOptions {
    SimulationOptions::default().with_integrator(Integrator::ImplicitMidpoint).with_newton_matrix(matrix)
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

/// The end of `steps` steps of `h` from `start` with `options`.
fn run<S, const NB: usize, const NQ: usize, const NV: usize, const NC: usize>(
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
/// one in no more iterations than the differenced one.
fn second_order<S, const NB: usize, const NQ: usize, const NV: usize, const NC: usize>(
    scene: &S,
    start: TreeState<NQ, NV>,
    (t, h): (f64, f64),
) where
    S: TreeScene<NB, NQ, NV, NC>,
{
    let fine = run(scene, SimulationOptions::default(), start, (t / 1000.0, 1000)).0;
    let mut errors = [0.0; 2];
    for (k, error) in errors.iter_mut().enumerate() {
        let coarse = h / f64::from(1 << k);
        let steps = (t / coarse).round() as usize;
        let (end, iterations) = run(scene, midpoint(NewtonMatrix::Generated), start, (coarse, steps));
        let (differenced, more) = run(scene, midpoint(NewtonMatrix::FiniteDifferences), start, (coarse, steps));
        assert!((end.q - differenced.q).amax() < 1e-9 && (end.v - differenced.v).amax() < 1e-8);
        // The exact matrix converges at least as fast as the differenced one.
        assert!(iterations <= more, "{iterations} iterations against {more} at h = {coarse}");
        *error = (end.q - fine.q).amax().max((end.v - fine.v).amax() * coarse);
    }
    let ratio = errors[0] / errors[1];
    assert!((3.5..4.5).contains(&ratio), "errors {errors:?}: ratio {ratio}");
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
struct HardFourBar;

#[test]
fn a_loop_converges_at_second_order() {
    // Off its upright balance: the crank turned 0.3 rad, the loop closed.
    let sim = TreeSimulation::new(&HardFourBar).unwrap();
    let mut guess = sim.tree().zero_state();
    guess.q[0] = 0.3;
    let start = sim.assemble(&guess).unwrap();
    second_order(&HardFourBar, start, (0.5, 0.025));
}

/// The floating Solo12 from its URDF file on its four feet.
#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], urdf = "data/robots/solo12.urdf", floating_base)]
#[contact(fl = point(FL_FOOT); fr = point(FR_FOOT); hl = point(HL_FOOT); hr = point(HR_FOOT))]
struct SoloFeet;

/// A quadruped on its four feet (a floating base, twelve contact rows, the
/// feet's velocities projected out after each step): the constrained
/// dynamics' exact derivatives make the Newton matrix.
#[test]
fn a_robot_on_its_feet_converges_at_second_order() {
    let sim = TreeSimulation::new(&SoloFeet).unwrap();
    let mut guess = sim.tree().zero_state();
    guess.q[2] = 0.3;
    for (k, x) in guess.v.iter_mut().enumerate() {
        *x = 0.5 * (k as f64).sin();
    }
    let start = sim.assemble(&guess).unwrap();
    second_order(&SoloFeet, start, (0.1, 0.01));
}
