//! MuJoCo's soft equalities, read as MuJoCo makes them (an MJCF file
//! without `equality = hard`): a `connect` and a `joint` equality are
//! spring-dampers in the constraint space, `(J M⁻¹ Jᵀ + R) f = a_ref − J q̈₀`,
//! with MuJoCo's impedance, inverse weights and reference acceleration.
//! Checked against MuJoCo 4.0's `mj_forward` (`tests/data/mjcf/soft_reference.py`)
//! and the derivatives against central differences of the accelerations.

use joint_runtime::Scene;
use joint_runtime::dynamics::{SimulationOptions, Stabilisation};
use joint_runtime::nalgebra::SVector;
use joint_runtime::relative::{
    ForwardDerivatives, InverseDerivatives, StepJacobian, StepWork, TreeError, TreeScene, TreeSimulation, TreeState,
};

/// A four-bar closed by a `connect` with MuJoCo's default `solref`, `solimp`.
#[derive(Scene)]
#[scene(mjcf = "data/mjcf/four_bar.xml")]
struct SoftFourBar;

/// A double pendulum whose elbow follows its shoulder by a `joint`
/// equality (`joint2 = 0.1 − 0.5 joint1`), soft.
#[derive(Scene)]
#[scene(mjcf = "data/mjcf/coupled_pendulum.xml")]
struct SoftCoupled;

/// Fingers coupled softly, a `connect` from a class with MuJoCo's direct
/// `solref` and a cubic impedance, a `connect` to the world whose time
/// constant MuJoCo raises to twice the step.
#[derive(Scene)]
#[scene(mjcf = "data/mjcf/soft_gripper.xml")]
struct SoftGripper;

/// The Panda with its fingers coupled as MuJoCo Menagerie ships it.
#[derive(Scene)]
#[scene(mjcf = "data/mjcf/panda_fingers.xml")]
struct PandaFingers;

/// A double pendulum whose elbow is welded, with MuJoCo's defaults.
#[derive(Scene)]
#[scene(mjcf = "data/mjcf/welded_pendulum.xml")]
struct SoftWelded;

/// A weld with half its torque between a ball joint's body and a turned
/// hinge's, and a slider welded to the world.
#[derive(Scene)]
#[scene(mjcf = "data/mjcf/soft_weld.xml")]
pub(crate) struct SoftWeld;

/// `soft_reference.json`'s entry `key`.
fn reference(key: &str) -> serde_json::Value {
    let path = format!("{}/data/mjcf/soft_reference.json", env!("CARGO_MANIFEST_DIR"));
    let mut data: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    data[key].take()
}

fn numbers(v: &serde_json::Value) -> Vec<f64> {
    v.as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect()
}

/// The samples of `key` in the scene's terms (through its `MUJOCO`
/// layout): each state, joint forces and MuJoCo's `qacc`.
type Sample<const NQ: usize, const NV: usize> = (TreeState<NQ, NV>, SVector<f64, NV>, Vec<f64>);
fn samples<S, const NB: usize, const NQ: usize, const NV: usize, const NC: usize>(key: &str) -> Vec<Sample<NQ, NV>>
where
    S: TreeScene<NB, NQ, NV, NC>,
{
    let layout = S::STATE_LAYOUT.unwrap();
    let sample = |s: &serde_json::Value| {
        let state = layout.state_from(&numbers(&s["q"]), &numbers(&s["v"])).unwrap();
        let tau = layout.forces_from(&state, &numbers(&s["tau"])).unwrap();
        (state, tau, numbers(&s["qacc"]))
    };
    reference(key).as_array().unwrap().iter().map(sample).collect()
}

/// Every sample's `qacc` to 1e-12 of its largest entry; the worst returned.
fn against_mujoco<S, const NB: usize, const NQ: usize, const NV: usize, const NC: usize>(scene: &S, key: &str) -> f64
where
    S: TreeScene<NB, NQ, NV, NC>,
{
    let layout = S::STATE_LAYOUT.unwrap();
    let mut sim = TreeSimulation::new(scene).unwrap();
    let mut worst = 0.0_f64;
    for (state, tau, qacc) in samples::<S, NB, NQ, NV, NC>(key) {
        let mut ours = [0.0; NV];
        layout.write_accelerations(&state, &sim.forward_dynamics(&state, &tau).unwrap(), &mut ours).unwrap();
        let (ours, theirs) = (SVector::<f64, NV>::from(ours), SVector::<f64, NV>::from_iterator(qacc));
        worst = worst.max((ours - theirs).amax() / theirs.amax());
    }
    eprintln!("{key}, soft equalities against MuJoCo: qacc to {worst:.1e} of the largest entry");
    assert!(worst < 1e-12, "{key}: off by {worst:e}");
    worst
}

#[test]
fn soft_equalities_equal_mujoco() {
    against_mujoco(&SoftFourBar, "four_bar");
    against_mujoco(&SoftCoupled, "coupled_pendulum");
    against_mujoco(&SoftGripper, "soft_gripper");
    against_mujoco(&PandaFingers, "panda_fingers");
    against_mujoco(&SoftWelded, "welded_pendulum");
    against_mujoco(&SoftWeld, "soft_weld");
}

/// The exact derivatives of the soft accelerations (through `J`, `R(imp(Φ))`
/// and `a_ref`) against differences of the accelerations, at every sample:
/// residuals on each piece of the impedance curve, to 1e-6 of the column.
fn derivatives_against_differences<S, const NB: usize, const NQ: usize, const NV: usize, const NC: usize>(
    scene: &S,
    key: &str,
) -> f64
where
    S: TreeScene<NB, NQ, NV, NC>,
{
    let mut sim = TreeSimulation::new(scene).unwrap();
    let (mut work, mut exact) = (Box::new(InverseDerivatives::zeros()), Box::new(ForwardDerivatives::zeros()));
    let mut worst = 0.0_f64;
    let tree = sim.tree().clone();
    for (state, tau, _) in samples::<S, NB, NQ, NV, NC>(key) {
        sim.forward_dynamics_derivatives(&state, &tau, &mut work, &mut exact).unwrap();
        for i in 0..NV {
            let unit = SVector::<f64, NV>::from_fn(|r, _| if r == i { 1.0 } else { 0.0 });
            let mut at = |state: TreeState<NQ, NV>, tau: SVector<f64, NV>| sim.forward_dynamics(&state, &tau).unwrap();
            let moved = |h: f64| TreeState { q: tree.displaced(&state.q, &(unit * h)), ..state };
            let central = |h: f64, at: &mut dyn FnMut(TreeState<NQ, NV>, SVector<f64, NV>) -> SVector<f64, NV>| {
                (at(moved(h), tau) - at(moved(-h), tau)) / (2.0 * h)
            };
            // q: Richardson on central differences (the impedance curves
            // sharply within a millimetre); v: `q̈` is quadratic in `v`, so
            // one central difference is exact; τ: affine, a unit step exact.
            let d_q = (central(1e-6, &mut at) * 4.0 - central(2e-6, &mut at)) / 3.0;
            let (faster, slower) =
                (TreeState { v: state.v + unit * 1e-3, ..state }, TreeState { v: state.v - unit * 1e-3, ..state });
            let d_v = (at(faster, tau) - at(slower, tau)) / 2e-3;
            let d_tau = (at(state, tau + unit) - at(state, tau - unit)) / 2.0;
            for (column, exact) in
                [(d_q, exact.d_q.column(i)), (d_v, exact.d_v.column(i)), (d_tau, exact.d_tau.column(i))]
            {
                let scale = exact.amax().max(1.0);
                worst = worst.max((column - exact).amax() / scale);
            }
        }
    }
    eprintln!("{key}, soft equalities: derivatives to {worst:.1e} of central differences");
    assert!(worst < 1e-6, "{key}: derivatives off by {worst:e}");
    worst
}

#[test]
fn soft_derivatives_equal_differences() {
    derivatives_against_differences(&SoftFourBar, "four_bar");
    derivatives_against_differences(&SoftCoupled, "coupled_pendulum");
    derivatives_against_differences(&SoftGripper, "soft_gripper");
    derivatives_against_differences(&PandaFingers, "panda_fingers");
    derivatives_against_differences(&SoftWelded, "welded_pendulum");
    derivatives_against_differences(&SoftWeld, "soft_weld");
}

/// A run: 100 RK4 steps at the file's timestep from a sample's state, its
/// forces held, equal to MuJoCo's own RK4 (`integrator="RK4"`) to 1e-12
/// of the largest coordinate and velocity: the soft rows step as MuJoCo
/// steps them, never projected.
fn run_against_mujoco<S, const NB: usize, const NQ: usize, const NV: usize, const NC: usize>(
    scene: &S,
    key: &str,
) -> f64
where
    S: TreeScene<NB, NQ, NV, NC>,
{
    let layout = S::STATE_LAYOUT.unwrap();
    let run = reference(&format!("{key}_rk4"));
    let (mut state, tau, _) = samples::<S, NB, NQ, NV, NC>(key).swap_remove(run["start"].as_u64().unwrap() as usize);
    let mut sim = TreeSimulation::new(scene).unwrap();
    let h = run["h"].as_f64().unwrap();
    for _ in 0..run["steps"].as_u64().unwrap() {
        sim.step_with(&mut state, h, &tau).unwrap();
    }
    let (mut q, mut v) = (vec![0.0; layout.nq()], vec![0.0; layout.nv()]);
    layout.write_state(&state, &mut q, &mut v).unwrap();
    let (theirs_q, theirs_v) = (numbers(&run["q"]), numbers(&run["v"]));
    let off = |ours: &[f64], theirs: &[f64]| {
        let scale = theirs.iter().fold(1.0_f64, |m, x| m.max(x.abs()));
        ours.iter().zip(theirs).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max) / scale
    };
    let worst = off(&q, &theirs_q).max(off(&v, &theirs_v));
    eprintln!("{key}: 100 RK4 steps against MuJoCo's, to {worst:.1e}");
    assert!(worst < 1e-12, "{key}: the run is off by {worst:e}");
    worst
}

#[test]
fn soft_runs_equal_mujoco() {
    run_against_mujoco(&SoftFourBar, "four_bar");
    run_against_mujoco(&SoftCoupled, "coupled_pendulum");
    run_against_mujoco(&SoftGripper, "soft_gripper");
    run_against_mujoco(&PandaFingers, "panda_fingers");
    run_against_mujoco(&SoftWelded, "welded_pendulum");
    run_against_mujoco(&SoftWeld, "soft_weld");
}

/// The RK4 and semi-implicit Euler steps' exact Jacobians on soft rows
/// (never projected, so the chain rule through the stages is the step's)
/// against central differences of the same steps, at samples on each piece
/// of the impedance curve; the RK4 step is `step_with`'s.
fn step_jacobians_against_differences<S, const NB: usize, const NQ: usize, const NV: usize, const NC: usize>(
    scene: &S,
    key: &str,
    options: SimulationOptions,
) -> [f64; 2]
where
    S: TreeScene<NB, NQ, NV, NC>,
{
    let mut sim = TreeSimulation::new(scene).unwrap().with_options(options).unwrap();
    let h = reference(&format!("{key}_rk4"))["h"].as_f64().unwrap();
    let (mut work, mut out, mut scratch) = (Box::new(StepWork::new()), StepJacobian::zeros(), StepJacobian::zeros());
    let mut worst = [0.0_f64; 2];
    for (start, tau, _) in samples::<S, NB, NQ, NV, NC>(key).into_iter().step_by(3) {
        for (k, worst) in worst.iter_mut().enumerate() {
            let mut step = |s: &mut TreeState<NQ, NV>, t: &SVector<f64, NV>, out: &mut StepJacobian<NV>| match k {
                0 => sim.rk4_step_jacobian(s, h, t, &mut work, out).unwrap(),
                _ => sim.euler_step_jacobian(s, h, t, &mut work, out).unwrap(),
            };
            let mut end = start;
            step(&mut end, &tau, &mut out);
            let tree = sim.tree().clone();
            let eps = 1e-6;
            let (mut diff, mut scale) = (0.0_f64, 0.0_f64);
            for c in 0..3 * NV {
                let moved = |by: f64| {
                    let (mut s, mut t) = (start, tau);
                    let e = SVector::<f64, NV>::from_fn(|r, _| if r == c % NV { by } else { 0.0 });
                    match c / NV {
                        0 => s.q = tree.displaced(&start.q, &e),
                        1 => s.v += e,
                        _ => t += e,
                    }
                    (s, t)
                };
                // Richardson on central differences: the impedance curves
                // sharply within a millimetre.
                let mut central = |h: f64| {
                    let ((mut a, ta), (mut b, tb)) = (moved(h), moved(-h));
                    step(&mut a, &ta, &mut scratch);
                    step(&mut b, &tb, &mut scratch);
                    let dq = (tree.difference(&end.q, &a.q) - tree.difference(&end.q, &b.q)) / (2.0 * h);
                    (dq, (a.v - b.v) / (2.0 * h))
                };
                let ((dq1, dv1), (dq2, dv2)) = (central(eps), central(2.0 * eps));
                let (dq, dv) = ((dq1 * 4.0 - dq2) / 3.0, (dv1 * 4.0 - dv2) / 3.0);
                for r in 0..NV {
                    diff = diff.max((dq[r] - out.entry(r, c)).abs()).max((dv[r] - out.entry(NV + r, c)).abs());
                    scale = scale.max(out.entry(r, c).abs()).max(out.entry(NV + r, c).abs());
                }
            }
            *worst = worst.max(diff / scale);
            if k == 0 {
                let mut stepped = start;
                sim.step_with(&mut stepped, h, &tau).unwrap();
                assert!((stepped.q - end.q).amax() < 1e-14 && (stepped.v - end.v).amax() < 1e-12);
            }
        }
    }
    eprintln!("{key}: step Jacobians off differences by {:.1e} (RK4), {:.1e} (Euler)", worst[0], worst[1]);
    assert!(worst[0] < 1e-6 && worst[1] < 1e-6, "{key}: {worst:?}");
    worst
}

#[test]
fn soft_step_jacobians_equal_differences() {
    let options = SimulationOptions::default();
    step_jacobians_against_differences(&SoftGripper, "soft_gripper", options);
    step_jacobians_against_differences(&PandaFingers, "panda_fingers", options);
    step_jacobians_against_differences(&SoftWeld, "soft_weld", options);
}

/// The four-bar with ideal rows (`equality = hard`).
#[derive(Scene)]
#[scene(mjcf = "data/mjcf/four_bar.xml", equality = hard)]
struct HardFourBar;

/// A scene whose rows hold is projected after each step by default: the
/// semi-implicit Euler step (no stepping function projects it) is refused
/// then. Without projection the stages hold the rows at the acceleration
/// level, and both steps' Jacobians run the chain rule through the
/// constrained dynamics' exact derivatives: against central differences
/// (the hard four-bar from the soft one's states, slightly open, Baumgarte's
/// gains pulling them in; its planar loop closed by a point has a redundant
/// row, dropped at every stage).
#[test]
fn an_unprojected_step_has_both_step_jacobians() {
    let sim = TreeSimulation::new(&HardFourBar).unwrap();
    let (mut state, mut work, mut out) = (sim.tree().zero_state(), Box::new(StepWork::new()), StepJacobian::zeros());
    let error = sim.euler_step_jacobian(&mut state, 1e-3, &SVector::zeros(), &mut work, &mut out).unwrap_err();
    assert!(matches!(error, TreeError::NotOffered { .. }), "{error}");
    let options = SimulationOptions::default()
        .with_projection(None)
        .with_stabilisation(Stabilisation::Baumgarte { alpha: 5.0, beta: 5.0 });
    let worst = step_jacobians_against_differences(&HardFourBar, "four_bar", options);
    assert!(worst[0] > 0.0 && worst[1] > 0.0);
}

/// The projected RK4 step (the default options: simplified Newton on the
/// loop's rows, then the velocities) has its exact Jacobian, projection
/// included: against central differences of the same step from starts off
/// the loop by the differences' steps, at closed starts (the soft four-bar's
/// states assembled onto the hard loop); its end is `step_with`'s.
#[test]
fn the_projected_rk4_step_has_its_exact_jacobian() {
    let mut sim = TreeSimulation::new(&HardFourBar).unwrap();
    let h = 1e-2;
    let (mut work, mut out, mut scratch) = (Box::new(StepWork::new()), StepJacobian::zeros(), StepJacobian::zeros());
    let mut worst = 0.0_f64;
    let mut iterations = 0;
    for (guess, tau, _) in samples::<HardFourBar, 3, 3, 3, 2>("four_bar").into_iter().step_by(3) {
        let start = sim.assemble(&guess).unwrap();
        let mut end = start;
        sim.rk4_step_jacobian(&mut end, h, &tau, &mut work, &mut out).unwrap();
        let mut stepped = start;
        iterations += sim.step_with(&mut stepped, h, &tau).unwrap().projection_iterations;
        assert!((stepped.q - end.q).amax() < 1e-15 && (stepped.v - end.v).amax() < 1e-14);
        let tree = sim.tree().clone();
        let (mut diff, mut scale) = (0.0_f64, 0.0_f64);
        for c in 0..3 * 3 {
            let central = |by: f64, scratch: &mut StepJacobian<3>, work: &mut StepWork<3, 3>| {
                let mut ends = [start; 2];
                for (sign, e) in [1.0, -1.0].into_iter().zip(ends.iter_mut()) {
                    let mut t = tau;
                    let d = SVector::<f64, 3>::from_fn(|r, _| if r == c % 3 { sign * by } else { 0.0 });
                    match c / 3 {
                        0 => e.q = tree.displaced(&start.q, &d),
                        1 => e.v += d,
                        _ => t += d,
                    }
                    sim.rk4_step_jacobian(e, h, &t, work, scratch).unwrap();
                }
                let dq = tree.difference(&end.q, &ends[0].q) - tree.difference(&end.q, &ends[1].q);
                (dq / (2.0 * by), (ends[0].v - ends[1].v) / (2.0 * by))
            };
            // Steps of 1e-4: the projection's tolerance (1e-12) decides its
            // iteration count, so a difference over 2ε carries 1e-12/ε of it.
            let ((dq1, dv1), (dq2, dv2)) =
                (central(1e-4, &mut scratch, &mut work), central(2e-4, &mut scratch, &mut work));
            let (dq, dv) = ((dq1 * 4.0 - dq2) / 3.0, (dv1 * 4.0 - dv2) / 3.0);
            for r in 0..3 {
                diff = diff.max((dq[r] - out.entry(r, c)).abs()).max((dv[r] - out.entry(3 + r, c)).abs());
                scale = scale.max(out.entry(r, c).abs()).max(out.entry(3 + r, c).abs());
            }
        }
        worst = worst.max(diff / scale);
    }
    eprintln!(
        "hard four-bar: the projected RK4 step's Jacobian off differences by {worst:.1e} ({iterations} Newton iterations)"
    );
    assert!(iterations > 0, "the projection never iterated: its derivative went untested");
    assert!(worst < 1e-7, "{worst:e}");
}

/// A soft loop is not projected: a start off it steps, and the rows'
/// spring pulls the residual in (the four-bar opened by 5 mrad at its crank, one
/// second of RK4 under gravity, MuJoCo's time constant 0.02 s).
#[test]
fn a_soft_loop_pulls_itself_closed() {
    let mut sim = TreeSimulation::new(&SoftFourBar).unwrap();
    let mut state = sim.tree().zero_state();
    state.q[0] = 0.005;
    let open = sim.closure_rows(&state).phi.norm();
    for _ in 0..500 {
        sim.step(&mut state, 0.002).unwrap();
    }
    let closed = sim.closure_rows(&state).phi.norm();
    eprintln!("soft four-bar: residual {open:.1e} → {closed:.1e} after 1 s");
    assert!(open > 1e-3 && closed < 0.05 * open, "{open} → {closed}");
}
