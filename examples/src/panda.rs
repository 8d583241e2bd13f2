//! The Franka Emika Panda, read from its URDF file, holding a pose under a
//! PD controller with gravity compensation:
//! `τ = g(q) + Kp (q* − q) − Kd v`, each torque clamped to the file's
//! effort limit (`Panda::LIMITS`), at 1 kHz (a zero-order hold over each
//! RK4 step). `g(q)` is the scene's inverse dynamics at rest, checked
//! against Pinocchio (`tests/tests/runtime/urdf.rs`).
//!
//! Without clamping the controller makes `V = ½ vᵀ M v + ½ eᵀ Kp e`
//! (`e = q* − q`) a Lyapunov function: `V̇ = −vᵀ Kd v ≤ 0` (Takegaki and
//! Arimoto, 1981), so the arm settles on the target with the torques `g(q*)`.
//! The tests check both; the run is drawn as an animated SVG and written as
//! CSV through `record::Trajectory`, which the scene's absolute coordinates
//! (`coordinates = both`) give.

use joint_runtime::Scene;
use joint_runtime::nalgebra::{SMatrix, SVector, Vector3};
use joint_runtime::record::{Column, Trajectory};
use joint_runtime::relative::{TreeError, TreeSimulation, TreeState};

/// The Panda: seven revolute joints and the two fingers' slides, each
/// finger its own joint (`mimic = independent`: the controller holds both;
/// the file's coupling would be a row of relative coordinates alone, and
/// the animation wants the absolute ones too).
#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], urdf = "../tests/data/robots/panda.urdf", coordinates = both, mimic = independent)]
pub struct Panda;

/// Joint coordinates, rates or torques, in the file's joint order.
pub type Joints = SVector<f64, 9>;

/// The arm's tree simulation.
pub type PandaSimulation<'a> = TreeSimulation<'a, Panda, 9, 9, 9>;

/// Franka's "ready" pose, fingers half open: the start.
pub const READY: [f64; 9] = [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785, 0.02, 0.02];

/// The pose to hold: every joint moved from `READY`, fingers opened.
pub const TARGET: [f64; 9] = [0.4, -0.5, -0.3, -2.0, 0.4, 1.9, 1.2, 0.03, 0.03];

/// Stiffness per joint (N m/rad, N/m): the wrist and fingers softer, so
/// that `h · ω` stays well inside RK4's stability region at 1 kHz (the
/// wrist's largest entry of `M⁻¹` is about 150 at `READY`).
pub const KP: [f64; 9] = [400.0, 400.0, 400.0, 400.0, 100.0, 100.0, 20.0, 50.0, 50.0];

/// Damping per joint (N m s/rad, N s/m).
pub const KD: [f64; 9] = [40.0, 40.0, 40.0, 40.0, 5.0, 5.0, 2.0, 2.0, 2.0];

/// One recorded instant.
#[derive(Clone, Copy, Debug)]
pub struct Sample {
    /// Time (s).
    pub t: f64,
    /// The largest `|q* − q|` (rad or m).
    pub error: f64,
    /// `V = ½ vᵀ M v + ½ eᵀ Kp e` (J).
    pub lyapunov: f64,
    /// Whether a torque was clamped to its effort limit in the step after.
    pub clamped: bool,
}

/// A run: every step's sample, the animation's samples, the last state.
pub struct Run {
    /// One sample per step, the start first.
    pub samples: Vec<Sample>,
    /// The bodies every 10 ms, for the animation and the CSV.
    pub trajectory: Trajectory<9>,
    /// Where the arm ends.
    pub end: TreeState<9, 9>,
}

/// The controller's torques at `state` for `target`, and whether one was
/// clamped to the file's effort limit.
pub fn control(sim: &PandaSimulation<'_>, state: &TreeState<9, 9>, target: &Joints) -> (Joints, bool) {
    let at_rest = TreeState { v: Joints::zeros(), ..*state };
    let gravity = sim.inverse_dynamics(&at_rest, &Joints::zeros());
    let mut clamped = false;
    let tau = Joints::from_fn(|i, _| {
        let wanted = gravity[i] + KP[i] * (target[i] - state.q[i]) - KD[i] * state.v[i];
        let limit = Panda::LIMITS[i].effort.unwrap_or(f64::INFINITY);
        clamped |= wanted.abs() > limit;
        wanted.clamp(-limit, limit)
    });
    (tau, clamped)
}

/// `V = ½ vᵀ M v + ½ eᵀ Kp e`.
pub fn lyapunov(sim: &PandaSimulation<'_>, state: &TreeState<9, 9>, target: &Joints) -> f64 {
    let mut m = SMatrix::<f64, 9, 9>::zeros();
    sim.mass_matrix_into(&state.q, &mut m);
    let e = target - state.q;
    0.5 * state.v.dot(&(m * state.v)) + 0.5 * (0..9).map(|i| KP[i] * e[i] * e[i]).sum::<f64>()
}

/// `seconds` of the arm from `READY` at rest towards `TARGET`, steps of `h`.
///
/// # Errors
/// What a step returns (none for this arm and these gains).
pub fn simulate(seconds: f64, h: f64) -> Result<Run, TreeError> {
    let mut sim = TreeSimulation::new(&Panda)?;
    let target = Joints::from(TARGET);
    let mut state = TreeState { q: Joints::from(READY), v: Joints::zeros(), t: 0.0 };
    let mut trajectory = Trajectory::new(&Panda);
    // Each link drawn from its body's centre to its frames' origins: a
    // robot's joint points alone are few (two of the Panda's share a point).
    for link in &Panda::LINKS {
        if let Some(body) = link.body {
            trajectory.add_segment(body, Vector3::zeros(), Vector3::from(link.origin));
        }
    }
    let mut samples = Vec::new();
    let steps = (seconds / h).round() as usize;
    let every = ((0.01 / h).round() as usize).max(1);
    for k in 0..=steps {
        let (tau, clamped) = control(&sim, &state, &target);
        let error = (target - state.q).amax();
        samples.push(Sample { t: state.t, error, lyapunov: lyapunov(&sim, &state, &target), clamped });
        if k % every == 0 {
            trajectory.record(&sim.system_state(&state));
        }
        if k < steps {
            sim.step_with(&mut state, h, &tau)?;
        }
    }
    Ok(Run { samples, trajectory, end: state })
}

/// The run as CSV: `Trajectory`'s columns (each body's centre and Euler
/// parameters) and the tracking error, computed back from the bodies'
/// state to joint coordinates (`state_of`).
///
/// # Errors
/// What writing to `out` returns.
pub fn write_csv<W: std::io::Write>(run: &Run, out: W) -> std::io::Result<()> {
    let sim = TreeSimulation::new(&Panda).map_err(|e| std::io::Error::other(format!("{e:?}")))?;
    let target = Joints::from(TARGET);
    let error = |s: &joint_runtime::SystemState<9>| sim.state_of(s).map_or(f64::NAN, |t| (target - t.q).amax());
    run.trajectory.write_csv(out, &[Column::new("tracking_error", &error)])
}
