//! A stiff robot at its own step: the UR5 from its URDF file held by a PD
//! law of 1e4 N·m/rad and 1e2 N·m·s/rad on every joint, stepped at h = 2 ms.
//! RK4 with the law's forces held over each step blows up there; the
//! linearly implicit Euler step (`TreeSimulation::implicit_step_with`)
//! settles, and converges to a fine RK4 run at first order.

use joint_runtime::Scene;
use joint_runtime::nalgebra::SVector;
use joint_runtime::relative::{DIVERGED, ForceGains, StepWork, TreeError, TreeSimulation, TreeState};

#[derive(Scene)]
#[scene(urdf = "data/robots/ur5.urdf")]
struct Ur5;

const KP: f64 = 1e4;
const KD: f64 = 1e2;

/// The target pose, and the PD law's forces at `state`.
fn target() -> SVector<f64, 6> {
    SVector::from([0.3, -1.2, 1.4, -0.8, 0.5, 0.2])
}

fn pd(state: &TreeState<6, 6>) -> SVector<f64, 6> {
    (target() - state.q) * KP - state.v * KD
}

/// The start: 0.2 rad off the target on every joint, at rest.
fn start() -> TreeState<6, 6> {
    TreeState { q: target().add_scalar(0.2), v: SVector::zeros(), t: 0.0 }
}

/// `t_end` of implicit steps of `h`.
fn implicit(sim: &TreeSimulation<'_, Ur5, 6, 6, 6>, h: f64, t_end: f64) -> TreeState<6, 6> {
    let gains = ForceGains::pd(&SVector::repeat(KP), &SVector::repeat(KD));
    let (mut state, mut work) = (start(), StepWork::new());
    for _ in 0..(t_end / h).round() as usize {
        let tau = pd(&state);
        sim.implicit_step_with(&mut state, h, &tau, &gains, &mut work).unwrap();
    }
    state
}

#[test]
fn a_stiff_arm_settles_at_its_own_step() {
    let mut sim = TreeSimulation::new(&Ur5).unwrap();
    let t_end: f64 = 0.5;
    // RK4 at 2 ms, the law's forces held over each step: the wrist's damping
    // alone (1e2 over its ~0.01 kg m²) is far past its stability limit.
    // The step says so by name once the state leaves a robot's range.
    let mut rk4 = start();
    let error = (0..1000).find_map(|_| {
        let tau = pd(&rk4);
        sim.step_with(&mut rk4, 2e-3, &tau).err()
    });
    let Some(TreeError::Diverged { t }) = error else { panic!("RK4 at 2 ms: {error:?}, not a divergence") };
    eprintln!("stiff UR5: RK4 at 2 ms diverges at t = {t} s: {}", error.unwrap());
    assert!(t < 0.5 && rk4.q.amax() <= DIVERGED && rk4.q.amax() > 1.0, "{t}, {}", rk4.q.amax());
    // A fine reference: RK4 at 20 µs, the forces held over each (tiny) step.
    let mut fine = start();
    for _ in 0..(t_end / 2e-5).round() as usize {
        let tau = pd(&fine);
        sim.step_with(&mut fine, 2e-5, &tau).unwrap();
    }
    let coarse = implicit(&sim, 2e-3, t_end);
    let half = implicit(&sim, 1e-3, t_end);
    let (e_coarse, e_half) = ((coarse.q - fine.q).amax(), (half.q - fine.q).amax());
    eprintln!(
        "stiff UR5, 0.5 s: implicit Euler off a 20 µs RK4 run by {e_coarse:.1e} rad (h = 2 ms), {e_half:.1e} rad (1 ms); \
         off its target by {:.1e} rad",
        (coarse.q - target()).amax()
    );
    assert!(e_coarse < 2e-2 && e_half < e_coarse, "{e_coarse:e}, {e_half:e}");
    // First order: halving the step about halves the error.
    let order = (e_coarse / e_half).log2();
    assert!((0.7..1.5).contains(&order), "order {order}");
    // Settled: at rest near the target (gravity's pull over Kp leaves an offset).
    assert!(coarse.v.amax() < 0.1 && (coarse.q - target()).amax() < 5e-3, "{coarse:?}");
}

/// A joint spring of 1e4 N·m/rad on a rotor of 0.01 kg·m² (no gravity),
/// stretched 0.2 rad from its rest at 0.1: `θ = 0.1 + 0.2 cos(ω t)`,
/// `ω = √(k / I) = 1000 rad/s`, and its energy `½ I θ̇² + ½ k (θ − 0.1)²`
/// stays 200 J.
#[derive(Scene)]
#[scene(gravity = [0, 0, 0], coordinates = relative)]
#[body(rotor, mass = 1.0, inertia = [0.01, 0.01, 0.01])]
#[joint(pin = revolute(ground, rotor), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0, 0, 0], rho2 = [0, 0, 0], stiffness = 1e4, spring_rest = 0.1)]
struct Rotor;

#[test]
fn a_stiff_joint_spring_in_closed_form_and_at_its_own_step() {
    let mut sim = TreeSimulation::new(&Rotor).unwrap();
    let start = TreeState { q: SVector::from([0.3]), v: SVector::zeros(), t: 0.0 };
    let mut fine = start;
    for _ in 0..1000 {
        sim.step(&mut fine, 1e-5).unwrap();
    }
    let exact = 0.1 + 0.2 * (1000.0_f64 * 0.01).cos();
    assert!((fine.q[0] - exact).abs() < 1e-9, "{} against {exact}", fine.q[0]);
    let energy = sim.energy(&fine);
    assert!((energy.total() - 200.0).abs() < 1e-6 && energy.kinetic > 1.0, "{energy:?}");
    // At h = 4 ms (h ω = 4, past RK4's 2.8) RK4 diverges; the implicit
    // step, its Newton matrix from the spring's exact derivative, decays.
    let mut rk4 = start;
    let error = (0..200).find_map(|_| sim.step(&mut rk4, 4e-3).err());
    assert!(matches!(error, Some(TreeError::Diverged { .. })), "{error:?}");
    let (mut implicit, mut work) = (start, StepWork::new());
    let none = ForceGains::pd(&SVector::zeros(), &SVector::zeros());
    for _ in 0..250 {
        sim.implicit_step_with(&mut implicit, 4e-3, &SVector::zeros(), &none, &mut work).unwrap();
    }
    assert!((implicit.q[0] - 0.1).abs() < 1e-3 && implicit.v[0].abs() < 1.0, "{implicit:?}");
}

/// The Panda as its URDF says: the second finger follows the first (a
/// coupling row, `NC = 1`).
#[derive(Scene)]
#[scene(urdf = "data/robots/panda.urdf")]
struct PandaCoupled;

/// A coupled tree at its own step: the Panda's fingers held together by
/// their row while a stiff PD law drives every joint (the second finger's
/// own law fights the row, whose force takes it). The row holds exactly
/// at every step's end, and the implicit step converges to a fine RK4 run
/// (which projects onto the row after each step) at first order.
#[test]
fn a_coupled_arm_keeps_its_row_and_converges_at_first_order() {
    const GAINS: (f64, f64) = (2e3, 40.0);
    let target = SVector::<f64, 9>::from([0.3, -0.6, 0.2, -2.0, 0.1, 1.6, 0.7, 0.03, 0.01]);
    let pd = |s: &TreeState<9, 9>| (target - s.q) * GAINS.0 - s.v * GAINS.1;
    let mut sim = TreeSimulation::new(&PandaCoupled).unwrap();
    let names: Vec<&str> = sim.tree().joints().iter().map(|j| j.name).collect();
    assert_eq!(&names[7..], ["panda_finger_joint1", "panda_finger_joint2"]);
    let start = {
        let mut q = target.add_scalar(0.15);
        (q[7], q[8]) = (0.02, 0.02);
        TreeState { q, v: SVector::zeros(), t: 0.0 }
    };
    let t_end = 0.2;
    let implicit = |h: f64, sim: &TreeSimulation<'_, PandaCoupled, _, 9, 9, 1>| {
        let gains = ForceGains::pd(&SVector::repeat(GAINS.0), &SVector::repeat(GAINS.1));
        let (mut state, mut work, mut row) = (start, StepWork::new(), 0.0_f64);
        for _ in 0..(t_end / h).round() as usize {
            let tau = pd(&state);
            sim.implicit_step_with(&mut state, h, &tau, &gains, &mut work).unwrap();
            row = row.max(sim.closure_rows(&state).phi.amax());
        }
        (state, row)
    };
    let mut fine = start;
    for _ in 0..(t_end / 1e-5).round() as usize {
        let tau = pd(&fine);
        sim.step_with(&mut fine, 1e-5, &tau).unwrap();
    }
    let ((coarse, row_coarse), (half, row_half)) = (implicit(2e-3, &sim), implicit(1e-3, &sim));
    let (e1, e2) = ((coarse.q - fine.q).amax(), (half.q - fine.q).amax());
    eprintln!(
        "coupled Panda: implicit at 2 ms {e1:.2e} rad off RK4 at 10 µs, at 1 ms {e2:.2e} (ratio {:.2}); rows {row_coarse:.1e}, {row_half:.1e}",
        e1 / e2
    );
    assert!(row_coarse < 1e-13 && row_half < 1e-13, "the row: {row_coarse:e}, {row_half:e}");
    assert!((1.6..2.5).contains(&(e1 / e2)) && e2 < 1e-2, "first order: {e1:e} then {e2:e}");
    assert!((half.q[7] - half.q[8]).abs() < 1e-13, "the fingers: {} and {}", half.q[7], half.q[8]);
}
