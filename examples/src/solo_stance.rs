//! The floating Solo12, read from its URDF file, standing on its four feet
//! (`#[contact]` points), shifting its weight over three of them, lifting
//! the front left foot, putting it back down (an impact) and shifting back:
//! the active set changes twice in the run.
//!
//! The controller asks, at every tick, for the torques that give the base
//! and the lifted leg the accelerations of a PD law: the constrained
//! dynamics are affine in `τ` for the tick's state and contacts, so
//! `q̈(τ) = q̈(τ₀) + (∂q̈/∂τ)(τ − τ₀)` is exact, with `∂q̈/∂τ` from
//! `constrained_dynamics_derivatives`, and one least-squares solve (the
//! smallest torques among those that reach the targets) gives them. The
//! contact forces `λ` come with it; a stance foot must be pushed, never
//! pulled (`λ_z > 0`), which the tests check. The run steps by the
//! semi-implicit Euler rule on the active contacts (Baumgarte's velocity
//! gain keeps them from drifting apart), at 1 kHz; at touchdown the
//! velocity jumps by `impact` (restitution 0).

use joint_runtime::Scene;
use joint_runtime::dynamics::{SimulationOptions, Stabilisation};
use joint_runtime::nalgebra::{DMatrix, DVector, SVector, UnitQuaternion, Vector3};
use joint_runtime::record::Trajectory;
use joint_runtime::relative::{
    ActiveRows, ConstrainedDerivatives, ImpulseDerivatives, InverseDerivatives, TreeError, TreeSimulation, TreeState,
};

/// ODRI's Solo12 on a floating base, its four feet held as points in the
/// world's axes.
#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], urdf = "../tests/data/robots/solo12.urdf", floating_base, coordinates = both)]
#[contact(fl = point(FL_FOOT); fr = point(FR_FOOT); hl = point(HL_FOOT); hr = point(HR_FOOT))]
pub struct Solo;

/// Solo's state in relative coordinates.
pub type State = TreeState<19, 18>;

/// The legs' joint angles standing (HAA, HFE, KFE per leg: FL, FR, HL, HR).
pub const STANDING: [f64; 12] = [0.0, 0.8, -1.6, 0.0, 0.8, -1.6, 0.0, -0.8, 1.6, 0.0, -0.8, 1.6];

/// The front left leg lifted: hip and knee folded further.
pub const LIFTED: [f64; 3] = [0.0, 1.3, -2.4];

/// The run's phases (s): standing, the weight shifted, the foot up, down, the weight back.
pub const PHASES: [f64; 5] = [0.3, 1.0, 1.6, 2.2, 3.0];

/// One recorded instant.
#[derive(Clone, Copy, Debug)]
pub struct Sample {
    /// Time (s).
    pub t: f64,
    /// Each foot's force from the ground, world axes (N); zero when lifted.
    pub forces: [Vector3<f64>; 4],
    /// Each foot's position (m).
    pub feet: [Vector3<f64>; 4],
    /// The base's centre (m).
    pub base: Vector3<f64>,
    /// Whether the front left foot is held.
    pub front_left_down: bool,
}

/// A run: samples every step, the bodies every 10 ms, the velocity jump
/// at touchdown.
pub struct Run {
    /// One sample per step.
    pub samples: Vec<Sample>,
    /// The bodies, for the 3D run.
    pub trajectory: Trajectory<13>,
    /// `|v⁺ − v|` at touchdown.
    pub touchdown_jump: f64,
}

/// The standing state: the base at rest 0.24 m up, level.
pub fn standing(sim: &TreeSimulation<'_, Solo, 13, 19, 18, 12>) -> State {
    let mut state = sim.tree().zero_state();
    state.q[2] = 0.24;
    state.q.fixed_rows_mut::<12>(7).copy_from_slice(&STANDING);
    state
}

/// A smooth step from 0 to 1 over `[a, b]`.
fn ramp(t: f64, a: f64, b: f64) -> f64 {
    let s = ((t - a) / (b - a)).clamp(0.0, 1.0);
    0.5 - 0.5 * (std::f64::consts::PI * s).cos()
}

/// Where the base's centre should be at `t`: shifted 3 cm towards the
/// three other feet while the front left one is up.
fn base_target(t: f64, home: &Vector3<f64>) -> Vector3<f64> {
    let shift = ramp(t, PHASES[0], PHASES[1]) - ramp(t, PHASES[3], PHASES[4]);
    home + Vector3::new(-0.03, -0.03, 0.0) * shift
}

/// The front left leg's joint targets at `t`.
fn leg_target(t: f64) -> [f64; 3] {
    let up = ramp(t, PHASES[1], 0.5 * (PHASES[1] + PHASES[2])) - ramp(t, PHASES[2], PHASES[3]);
    [0, 1, 2].map(|i| STANDING[i] + (LIFTED[i] - STANDING[i]) * up)
}

/// The torques for `state` under `active`: the base's and the lifted leg's
/// accelerations from PD laws, reached through the exact `∂q̈/∂τ`.
fn control(
    sim: &TreeSimulation<'_, Solo, 13, 19, 18, 12>,
    state: &State,
    active: ActiveRows,
    home: &Vector3<f64>,
    work: &mut InverseDerivatives<18>,
    out: &mut ConstrainedDerivatives<18, 12>,
) -> Result<SVector<f64, 18>, TreeError> {
    let zero = SVector::<f64, 18>::zeros();
    sim.constrained_dynamics_derivatives(state, &zero, active, work, out)?;
    let turn = UnitQuaternion::from_quaternion(joint_runtime::nalgebra::Quaternion::new(
        state.q[3], state.q[4], state.q[5], state.q[6],
    ));
    let (p, v, w) = (state.q.fixed_rows::<3>(0).into_owned(), state.v.fixed_rows::<3>(0), state.v.fixed_rows::<3>(3));
    // Base: p̈* from a PD law in the world, ω̇* from the turn's error, in the
    // tree's velocities (the centre's velocity in the base's axes).
    let accel = 400.0 * (base_target(state.t, home) - p) - 40.0 * (turn * v.into_owned());
    let mut wanted: Vec<(usize, f64)> = Vec::new();
    let linear = turn.inverse() * accel - w.cross(&v);
    let angular = -400.0 * turn.scaled_axis() - 40.0 * w;
    wanted.extend((0..3).map(|i| (i, linear[i])));
    wanted.extend((0..3).map(|i| (3 + i, angular[i])));
    if !active.holds(0) {
        let target = leg_target(state.t);
        wanted.extend((0..3).map(|i| (6 + i, 900.0 * (target[i] - state.q[7 + i]) - 60.0 * state.v[6 + i])));
    }
    // min |τ|² subject to q̈(τ)_k = wanted_k: the rows of ∂q̈/∂τ on the
    // actuated columns, the smallest torques by the pseudo-inverse.
    let a = DMatrix::from_fn(wanted.len(), 12, |r, c| out.d_tau[(wanted[r].0, 6 + c)]);
    let b = DVector::from_fn(wanted.len(), |r, _| wanted[r].1 - out.qdd[wanted[r].0]);
    let tau = a.pseudo_inverse(1e-9).map_err(|_| TreeError::NonFinite)? * b;
    Ok(SVector::from_fn(|r, _| if r < 6 { 0.0 } else { tau[r - 6] }))
}

/// The feet's positions at `state`.
fn feet(sim: &TreeSimulation<'_, Solo, 13, 19, 18, 12>, state: &State) -> [Vector3<f64>; 4] {
    let bodies = sim.system_state(state);
    ["FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT"].map(|name| {
        let link = joint_runtime::robot::LinkFrame::find(&Solo::LINKS, name).expect("a foot");
        let body = link.body.unwrap_or(0);
        bodies.bodies[body].point(&link.point(&Vector3::zeros()))
    })
}

/// `seconds` of the run, steps of `h`.
///
/// # Errors
/// What the dynamics return (none for this robot and these gains).
pub fn simulate(seconds: f64, h: f64) -> Result<Run, TreeError> {
    let options = SimulationOptions::default().with_stabilisation(Stabilisation::Baumgarte { alpha: 20.0, beta: 0.0 });
    let sim = TreeSimulation::new(&Solo)?.with_options(options)?;
    let mut state = standing(&sim);
    let home = state.q.fixed_rows::<3>(0).into_owned();
    let mut trajectory = Trajectory::new(&Solo);
    for link in &Solo::LINKS {
        if let Some(body) = link.body {
            trajectory.add_segment(body, Vector3::zeros(), Vector3::from(link.origin));
        }
    }
    let (mut work, mut out) = (InverseDerivatives::zeros(), ConstrainedDerivatives::zeros());
    let (mut samples, mut touchdown_jump) = (Vec::new(), 0.0);
    let every = ((0.01 / h).round() as usize).max(1);
    let steps = (seconds / h).round() as usize;
    for k in 0..=steps {
        let up = (PHASES[1]..PHASES[3]).contains(&state.t);
        let active = if up { ActiveRows::all().without(0) } else { ActiveRows::all() };
        let tau = control(&sim, &state, active, &home, &mut work, &mut out)?;
        sim.constrained_dynamics(&state, &tau, active, &mut out)?;
        let forces = [0, 1, 2, 3].map(|f| Vector3::from(out.lambda.fixed_rows::<3>(3 * f).into_owned()));
        let base = state.q.fixed_rows::<3>(0).into_owned();
        samples.push(Sample { t: state.t, forces, feet: feet(&sim, &state), base, front_left_down: !up });
        if k % every == 0 {
            trajectory.record(&sim.system_state(&state));
        }
        if k == steps {
            break;
        }
        // Semi-implicit Euler on the active contacts.
        state.v += out.qdd * h;
        let step = state.v * h;
        sim.tree().displace(&mut state.q, &step);
        state.t += h;
        if up && state.t >= PHASES[3] {
            // Touchdown: every foot held again, the velocity jumps.
            let mut hit = ImpulseDerivatives::zeros();
            sim.impact(&state, ActiveRows::all(), 0.0, &mut hit)?;
            touchdown_jump = (hit.v_after - state.v).amax();
            state.v = hit.v_after;
        }
    }
    Ok(Run { samples, trajectory, touchdown_jump })
}

/// The run's forces as CSV: `t`, each foot's force (x, y, z), the base's centre.
///
/// # Errors
/// The writer's.
pub fn write_csv<W: std::io::Write>(run: &Run, mut out: W) -> std::io::Result<()> {
    writeln!(out, "t,fl_x,fl_y,fl_z,fr_x,fr_y,fr_z,hl_x,hl_y,hl_z,hr_x,hr_y,hr_z,base_x,base_y,base_z")?;
    for s in &run.samples {
        write!(out, "{}", s.t)?;
        for f in &s.forces {
            write!(out, ",{},{},{}", f.x, f.y, f.z)?;
        }
        writeln!(out, ",{},{},{}", s.base.x, s.base.y, s.base.z)?;
    }
    Ok(())
}
