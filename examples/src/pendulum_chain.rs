//! A spatial pendulum chain: five bars hanging from the ground by spherical
//! joints, swinging and whirling in three dimensions; a test of energy
//! conservation by each integrator.
//!
//! Bars of 1 m and 1 kg (cylinders of radius 0.05 m), frames at their centres with
//! local `x` along the bar; the first hangs from the origin, each next one from the
//! lower end of the previous. Gravity is 9.81 m/s² along −z. The chain starts
//! straight, 60° from the vertical in the xz-plane, whirling about the vertical at
//! 2 rad/s (out of its plane) and bending in its plane at `0.4 i` rad/s for bar
//! `i`. Fifteen rows (five spherical joints), thirty columns, no redundancy: the
//! motion has fifteen degrees of freedom and is chaotic, but its energy is
//! conserved exactly.

// `AnalysisError` is returned by value, as in `joint_runtime` (it carries the
// worst rows; the runtime has no allocator to box it).

use joint_runtime::analysis::AnalysisError;
use joint_runtime::dynamics::{Integrator, NoLoads, Simulation, SimulationOptions};
use joint_runtime::nalgebra::{Rotation3, UnitQuaternion, Vector3};
use joint_runtime::record::Trajectory;
use joint_runtime::{BodyInertia, OmegaBody, Scene, SystemState};

/// Number of bars.
pub const BODIES: usize = 5;
/// Velocity columns.
pub const COLUMNS: usize = 6 * BODIES;
/// Constraint rows: five spherical joints of three rows.
pub const ROWS: usize = 3 * BODIES;
/// Gravity, m/s², along −z.
pub const GRAVITY: f64 = 9.81;
/// Initial angle of the chain from the vertical, rad.
pub const INITIAL_ANGLE: f64 = core::f64::consts::FRAC_PI_3;
/// Initial whirl about the vertical, rad/s.
pub const WHIRL: f64 = 2.0;

/// The chain: `pivot` hangs `bar1` from the ground, `ball{i}` hangs `bar{i+1}`
/// from `bar{i}`. Bar inertia as [`bar_inertia`]. In both coordinate choices:
/// absolute (`Simulation`) and relative (`joint_runtime::relative::TreeSimulation`,
/// fifteen coordinates of five quaternions, fifteen velocities, no rows).
#[derive(joint_runtime::Scene)]
#[scene(gravity = [0, 0, -9.81], coordinates = both)]
#[body(bar1, mass = 1.0, inertia = [0.00125, 0.08395833333333333, 0.08395833333333333])]
#[body(bar2, mass = 1.0, inertia = [0.00125, 0.08395833333333333, 0.08395833333333333])]
#[body(bar3, mass = 1.0, inertia = [0.00125, 0.08395833333333333, 0.08395833333333333])]
#[body(bar4, mass = 1.0, inertia = [0.00125, 0.08395833333333333, 0.08395833333333333])]
#[body(bar5, mass = 1.0, inertia = [0.00125, 0.08395833333333333, 0.08395833333333333])]
#[joint(pivot = spherical(ground, bar1), rho1 = [0, 0, 0], rho2 = [-0.5, 0, 0])]
#[joint(ball1 = spherical(bar1, bar2), rho1 = [0.5, 0, 0], rho2 = [-0.5, 0, 0])]
#[joint(ball2 = spherical(bar2, bar3), rho1 = [0.5, 0, 0], rho2 = [-0.5, 0, 0])]
#[joint(ball3 = spherical(bar3, bar4), rho1 = [0.5, 0, 0], rho2 = [-0.5, 0, 0])]
#[joint(ball4 = spherical(bar4, bar5), rho1 = [0.5, 0, 0], rho2 = [-0.5, 0, 0])]
#[derive(Clone, Copy, Debug, Default)]
pub struct Chain;

/// A bar's inertia, as declared in [`Chain`]: a solid cylinder of 1 kg, length
/// 1 m, radius 0.05 m, axis `x`.
pub fn bar_inertia() -> BodyInertia {
    let (m, l, r) = (1.0, 1.0, 0.05);
    let across = m * (3.0 * r * r + l * l) / 12.0;
    BodyInertia::principal(m, Vector3::new(0.5 * m * r * r, across, across))
}

/// The scene (a unit struct: everything is constant).
pub fn scene() -> Chain {
    Chain
}

/// Angular velocity of bar `i` at the start (inertial components): the whirl
/// `WHIRL` about +z plus an in-plane bend of `0.4 i` rad/s about +y.
pub fn initial_omega(i: usize) -> Vector3<f64> {
    Vector3::new(0.0, 0.4 * i as f64, WHIRL)
}

/// The initial state: straight at [`INITIAL_ANGLE`] from the vertical, each bar
/// turning at [`initial_omega`], the velocities propagated down the chain so that
/// every joint's velocity constraint holds exactly.
pub fn initial_state() -> SystemState<BODIES> {
    let dir = Vector3::new(INITIAL_ANGLE.sin(), 0.0, -INITIAL_ANGLE.cos());
    // The rotation taking local x onto `dir`.
    let rotation = Rotation3::rotation_between(&Vector3::x(), &dir).unwrap_or_else(Rotation3::identity);
    let q = UnitQuaternion::from_rotation_matrix(&rotation);
    let mut joint_velocity = Vector3::zeros();
    let bodies = core::array::from_fn(|i| {
        let w = initial_omega(i);
        let centre = dir * (i as f64 + 0.5);
        let v = joint_velocity + w.cross(&(dir * 0.5));
        joint_velocity += w.cross(&dir);
        OmegaBody::from_rotation(centre, &q, v, q.inverse() * w)
    });
    SystemState { bodies, t: 0.0 }
}

/// The lower end of the last bar.
pub fn tip(state: &SystemState<BODIES>) -> Vector3<f64> {
    let b = &state.bodies[BODIES - 1];
    b.point(&Vector3::new(0.5, 0.0, 0.0))
}

/// One sample of a run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// Time, s.
    pub t: f64,
    /// Total energy minus the initial one, J.
    pub energy_error: f64,
    /// ‖Φ‖₂ after the step.
    pub constraint: f64,
    /// The chain's tip.
    pub tip: Vector3<f64>,
}

/// What [`simulate`] measured.
#[derive(Clone, Debug, PartialEq)]
pub struct Run {
    /// Initial total energy (datum `z = 0`), J.
    pub initial_energy: f64,
    /// Initial kinetic energy, J: the scale of the relative energy errors (the
    /// total depends on the potential's datum; this does not).
    pub initial_kinetic: f64,
    /// max |E(t) − E(0)| / T(0).
    pub max_relative_energy_error: f64,
    /// (E(t_end) − E(0)) / T(0): the drift at the end.
    pub final_relative_energy_error: f64,
    /// max ‖Φ‖₂ after each step.
    pub max_constraint: f64,
    /// max ‖J v‖₂ after each step.
    pub max_velocity_constraint: f64,
    /// Newton iterations of the implicit integrator, total.
    pub newton_iterations: usize,
    /// The final state.
    pub end: SystemState<BODIES>,
    /// Samples every `sample_every` steps (and the last).
    pub samples: Vec<Sample>,
    /// The bars at the same samples, for the 3D run.
    pub trajectory: Trajectory<BODIES>,
}

/// Runs `t_end` seconds from [`initial_state`] with step `h`, the chosen
/// integrator, and projection after every step or none.
///
/// # Errors
/// Any failure of a step.
pub fn simulate(
    integrator: Integrator,
    projection: bool,
    h: f64,
    t_end: f64,
    sample_every: usize,
) -> Result<Run, AnalysisError> {
    let scene = scene();
    let defaults = SimulationOptions::default();
    let options =
        defaults.with_integrator(integrator).with_projection(if projection { defaults.projection } else { None });
    let mut sim = Simulation::new(&scene, NoLoads, &[], options)?;
    let mut state = initial_state();
    let e = sim.energy(&state);
    let e0 = e.total();
    let steps = (t_end / h).round() as usize;
    let mut run = Run {
        initial_energy: e0,
        initial_kinetic: e.kinetic,
        max_relative_energy_error: 0.0,
        final_relative_energy_error: 0.0,
        max_constraint: scene.phi(&state).norm(),
        max_velocity_constraint: 0.0,
        newton_iterations: 0,
        end: state,
        samples: vec![Sample { t: 0.0, energy_error: 0.0, constraint: scene.phi(&state).norm(), tip: tip(&state) }],
        trajectory: Trajectory::new(&scene),
    };
    run.trajectory.record(&state);
    for n in 1..=steps {
        let report = sim.step(&mut state, h)?;
        let de = sim.energy(&state).total() - e0;
        let phi = scene.phi(&state).norm();
        run.max_relative_energy_error = run.max_relative_energy_error.max(de.abs() / e.kinetic);
        run.final_relative_energy_error = de / e.kinetic;
        run.max_constraint = run.max_constraint.max(phi);
        run.max_velocity_constraint = run.max_velocity_constraint.max(report.velocity_residual);
        run.newton_iterations += report.newton_iterations;
        if n % sample_every.max(1) == 0 || n == steps {
            run.samples.push(Sample { t: state.t, energy_error: de, constraint: phi, tip: tip(&state) });
            run.trajectory.record(&state);
        }
    }
    run.end = state;
    Ok(run)
}
