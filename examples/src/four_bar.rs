//! The N-four-bar mechanism, IFToMM multibody benchmark A02, with `N = 4`: a
//! mechanism that passes through singular configurations again and again.
//!
//! Five vertical cranks, pivoted on the ground at `x = 0, 1, 2, 3, 4` (y = 0), and
//! four horizontal couplers joining their tops form four parallelograms in a row
//! (`2N + 1 = 9` bars of 1 m and 1 kg, slender: `m L²/12` across the bar). Every
//! joint is a revolute about `z`, and the model is spatial, so each planar loop
//! carries three redundant rows: `13 × 5 = 65` rows for `54` columns, rank 53,
//! mobility 1 and `3N = 12` redundant rows at a regular configuration. Gravity is
//! 9.81 m/s² along −y. The mechanism starts upright with the top of the first
//! crank, `B0`, moving at 1 m/s along +x, and turns over and over.
//!
//! When the cranks are horizontal every bar lies on the x axis: the Jacobian loses
//! `N` more ranks (mobility `N + 1`, `4N = 16` dependent rows) and the
//! parallelogram motion may continue or bifurcate. The simulation must pass
//! through it without failing and stay on the parallelogram branch.
//!
//! State order: `crank0, coupler0, crank1, coupler1, …, crank4`. Frames at the
//! centres of mass, identity orientation when upright: a crank's local `y` and a
//! coupler's local `x` run along the bar.

// `AnalysisError` is returned by value, as in `joint_runtime` (it carries the
// worst rows; the runtime has no allocator to box it).

use joint_runtime::analysis::AnalysisError;
use joint_runtime::dynamics::{AbsoluteSimulation, Integrator, NoLoads, SimulationOptions};
use joint_runtime::linalg::{DEFAULT_RANK_TOLERANCE, PivotedCholesky};
use joint_runtime::nalgebra::{DMatrix, UnitQuaternion, Vector3};
use joint_runtime::record::Trajectory;
use joint_runtime::{BodyInertia, OmegaBody, Scene, SparseJacobian, SystemState};

/// Number of four-bar loops.
pub const LOOPS: usize = 4;
/// Bodies: `N + 1` cranks and `N` couplers.
pub const BODIES: usize = 2 * LOOPS + 1;
/// Velocity columns.
pub const COLUMNS: usize = 6 * BODIES;
/// Constraint rows: `3N + 1` revolute joints of five rows.
pub const ROWS: usize = 5 * (3 * LOOPS + 1);
/// Gravity, m/s², along −y.
pub const GRAVITY: f64 = 9.81;
/// Initial speed of `B0`, m/s, along +x.
pub const B0_SPEED: f64 = 1.0;

/// Index of crank `i` in the state.
pub const fn crank(i: usize) -> usize {
    2 * i
}

/// Index of coupler `i` in the state.
pub const fn coupler(i: usize) -> usize {
    2 * i + 1
}

/// The mechanism (redundant rows included): `ground{i}` pins crank `i` to the
/// ground, `left{i}` and `right{i}` pin coupler `i` to cranks `i` and `i + 1`;
/// every axis is `z`. Bar inertia as [`bar_inertia`].
#[derive(joint_runtime::Scene)]
#[scene(gravity = [0, -9.81, 0], second_order, coordinates = both)]
#[body(crank0, mass = 1.0, inertia = [0.08333333333333333, 0.08333333333333333, 0.08333333333333333])]
#[body(coupler0, mass = 1.0, inertia = [0.08333333333333333, 0.08333333333333333, 0.08333333333333333])]
#[body(crank1, mass = 1.0, inertia = [0.08333333333333333, 0.08333333333333333, 0.08333333333333333])]
#[body(coupler1, mass = 1.0, inertia = [0.08333333333333333, 0.08333333333333333, 0.08333333333333333])]
#[body(crank2, mass = 1.0, inertia = [0.08333333333333333, 0.08333333333333333, 0.08333333333333333])]
#[body(coupler2, mass = 1.0, inertia = [0.08333333333333333, 0.08333333333333333, 0.08333333333333333])]
#[body(crank3, mass = 1.0, inertia = [0.08333333333333333, 0.08333333333333333, 0.08333333333333333])]
#[body(coupler3, mass = 1.0, inertia = [0.08333333333333333, 0.08333333333333333, 0.08333333333333333])]
#[body(crank4, mass = 1.0, inertia = [0.08333333333333333, 0.08333333333333333, 0.08333333333333333])]
#[joint(ground0 = revolute(ground, crank0), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0, 0, 0], rho2 = [0, -0.5, 0])]
#[joint(ground1 = revolute(ground, crank1), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [1, 0, 0], rho2 = [0, -0.5, 0])]
#[joint(ground2 = revolute(ground, crank2), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [2, 0, 0], rho2 = [0, -0.5, 0])]
#[joint(ground3 = revolute(ground, crank3), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [3, 0, 0], rho2 = [0, -0.5, 0])]
#[joint(ground4 = revolute(ground, crank4), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [4, 0, 0], rho2 = [0, -0.5, 0])]
#[joint(left0 = revolute(crank0, coupler0), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0, 0.5, 0], rho2 = [-0.5, 0, 0])]
#[joint(left1 = revolute(crank1, coupler1), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0, 0.5, 0], rho2 = [-0.5, 0, 0])]
#[joint(left2 = revolute(crank2, coupler2), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0, 0.5, 0], rho2 = [-0.5, 0, 0])]
#[joint(left3 = revolute(crank3, coupler3), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0, 0.5, 0], rho2 = [-0.5, 0, 0])]
#[joint(right0 = revolute(crank1, coupler0), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0, 0.5, 0], rho2 = [0.5, 0, 0])]
#[joint(right1 = revolute(crank2, coupler1), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0, 0.5, 0], rho2 = [0.5, 0, 0])]
#[joint(right2 = revolute(crank3, coupler2), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0, 0.5, 0], rho2 = [0.5, 0, 0])]
#[joint(right3 = revolute(crank4, coupler3), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0, 0.5, 0], rho2 = [0.5, 0, 0])]
#[derive(Clone, Copy, Debug, Default)]
pub struct FourBar;

/// A bar's inertia, as declared in [`FourBar`]: `m L²/12` across it. The
/// benchmark's bars are slender (no moment about their own axis), but the motion
/// is planar so that moment never enters it; `m L²/12` is used about all three
/// axes, which keeps the mass metric of the dynamics and projections well
/// conditioned.
pub fn bar_inertia() -> BodyInertia {
    BodyInertia::principal(1.0, Vector3::repeat(1.0 / 12.0))
}

/// The scene (a unit struct: everything is constant).
pub fn scene() -> FourBar {
    FourBar
}

/// The configuration with every crank at `angle` from +x (π/2: upright), turning
/// at `rate` (rad/s, about +z), couplers translating.
pub fn state_at(angle: f64, rate: f64) -> SystemState<BODIES> {
    let turn = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), angle - core::f64::consts::FRAC_PI_2);
    let dir = Vector3::new(angle.cos(), angle.sin(), 0.0);
    let tip_velocity = Vector3::new(-angle.sin(), angle.cos(), 0.0) * rate;
    let bodies = core::array::from_fn(|b| {
        let i = (b / 2) as f64;
        if b % 2 == 0 {
            let r = Vector3::new(i, 0.0, 0.0) + dir * 0.5;
            OmegaBody::from_rotation(r, &turn, tip_velocity * 0.5, Vector3::new(0.0, 0.0, rate))
        } else {
            let r = Vector3::new(i + 0.5, 0.0, 0.0) + dir;
            OmegaBody::from_rotation(r, &UnitQuaternion::identity(), tip_velocity, Vector3::zeros())
        }
    });
    SystemState { bodies, t: 0.0 }
}

/// The benchmark's initial state: upright, `B0` moving at [`B0_SPEED`] along +x.
pub fn initial_state() -> SystemState<BODIES> {
    state_at(core::f64::consts::FRAC_PI_2, -B0_SPEED)
}

/// Angle of crank `i` from +x (rad, in (−π, π]).
pub fn crank_angle(state: &SystemState<BODIES>, i: usize) -> f64 {
    let a = state.bodies[crank(i)].rotation_matrix() * Vector3::y();
    a.y.atan2(a.x)
}

/// The tip `B0` of the first crank.
pub fn b0(state: &SystemState<BODIES>) -> Vector3<f64> {
    let b = &state.bodies[crank(0)];
    b.point(&Vector3::new(0.0, 0.5, 0.0))
}

/// Largest angle (rad) between crank 0 and any other crank, or any coupler and
/// the x axis: zero on the parallelogram branch.
pub fn branch_deviation(state: &SystemState<BODIES>) -> f64 {
    let a0 = crank_angle(state, 0);
    let mut worst: f64 = 0.0;
    for i in 1..=LOOPS {
        let d = crank_angle(state, i) - a0;
        worst = worst.max(d.sin().abs().max(1.0 - d.cos()));
    }
    for i in 0..LOOPS {
        let x = state.bodies[coupler(i)].rotation_matrix() * Vector3::x();
        worst = worst.max(x.y.atan2(x.x).abs());
    }
    worst
}

/// Singular values of the system Jacobian, largest first.
pub fn singular_values(scene: &FourBar, state: &SystemState<BODIES>) -> Vec<f64> {
    let j = scene.jacobian(state);
    let d = DMatrix::from_column_slice(ROWS, COLUMNS, j.as_slice());
    let mut s: Vec<f64> = d.singular_values().iter().copied().collect();
    s.sort_by(|a, b| b.total_cmp(a));
    s
}

/// The smallest singular value of J that is nonzero at a regular configuration
/// (the `rank`-th, `rank = COLUMNS − 1`): it vanishes at the singular position.
pub fn critical_singular_value(scene: &FourBar, state: &SystemState<BODIES>) -> f64 {
    singular_values(scene, state).get(COLUMNS - 2).copied().unwrap_or(0.0)
}

/// Rows the rank-revealing factorisation of `J Jᵀ` drops at `state` (default
/// tolerance): `3N` at a regular configuration, `4N` at the singular one.
pub fn dropped_rows(scene: &FourBar, state: &SystemState<BODIES>) -> usize {
    let j = scene.jacobian(state);
    PivotedCholesky::new(&(j * j.transpose()), DEFAULT_RANK_TOLERANCE).map_or(ROWS, |c| ROWS - c.rank())
}

/// One sample of a run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// Time, s.
    pub t: f64,
    /// `B0`.
    pub b0: Vector3<f64>,
    /// Total energy minus the initial one, J.
    pub energy_error: f64,
    /// ‖Φ‖₂ after the step.
    pub constraint: f64,
}

/// What [`simulate`] measured.
#[derive(Clone, Debug, PartialEq)]
pub struct Run {
    /// Initial total energy (datum `y = 0`), J.
    pub initial_energy: f64,
    /// max |E(t) − E(0)| / |E(0)|.
    pub max_relative_energy_error: f64,
    /// max ‖Φ‖₂ after each step.
    pub max_constraint: f64,
    /// max ‖J v‖₂ after each step.
    pub max_velocity_constraint: f64,
    /// Passages of the cranks through the horizontal (singular) position.
    pub singular_passages: usize,
    /// Smallest [`critical_singular_value`] seen at a step end.
    pub min_singular_value: f64,
    /// Crank angle (rad from the nearest horizontal) where it was seen.
    pub min_singular_angle: f64,
    /// Most rows dropped by the factorisation of `J Jᵀ` at a step end.
    pub max_dropped_rows: usize,
    /// Largest [`branch_deviation`] (rad).
    pub max_branch_deviation: f64,
    /// Largest projection iteration count in one step.
    pub max_projection_iterations: usize,
    /// The final state.
    pub end: SystemState<BODIES>,
    /// Samples every `sample_every` steps (and the last).
    pub samples: Vec<Sample>,
    /// The states at the samples, to write as CSV or an animated SVG.
    pub trajectory: Trajectory<BODIES>,
}

/// Runs `t_end` seconds from `start` (e.g. [`initial_state`]) with step `h` and projection
/// after every step, on `scene` ([`scene`]`()`). Singular values are computed only near the horizontal
/// (`|sin θ| < 0.02`), where the minimum occurs.
///
/// # Errors
/// Any failure of a step.
pub fn simulate<S: Scene<BODIES, COLUMNS, ROWS> + SparseJacobian<BODIES, NNZ>, const NNZ: usize>(
    scene: &S,
    start: &SystemState<BODIES>,
    integrator: Integrator,
    h: f64,
    t_end: f64,
    sample_every: usize,
) -> Result<Run, AnalysisError> {
    let plain = self::scene();
    let options = SimulationOptions::default().with_integrator(integrator);
    let mut sim = AbsoluteSimulation::new(scene, NoLoads, &[], options)?;
    let mut state = *start;
    let e0 = sim.energy(&state).total();
    let steps = (t_end / h).round() as usize;
    let mut run = Run {
        initial_energy: e0,
        max_relative_energy_error: 0.0,
        max_constraint: 0.0,
        max_velocity_constraint: 0.0,
        singular_passages: 0,
        min_singular_value: f64::INFINITY,
        min_singular_angle: 0.0,
        max_dropped_rows: dropped_rows(&plain, &state),
        max_branch_deviation: 0.0,
        max_projection_iterations: 0,
        end: state,
        samples: vec![Sample { t: 0.0, b0: b0(&state), energy_error: 0.0, constraint: plain.phi(&state).norm() }],
        trajectory: Trajectory::new(scene),
    };
    run.trajectory.record(&state);
    let mut last_sin = crank_angle(&state, 0).sin();
    for n in 1..=steps {
        let report = sim.step(&mut state, h)?;
        let de = sim.energy(&state).total() - e0;
        let phi = plain.phi(&state).norm();
        run.max_relative_energy_error = run.max_relative_energy_error.max(de.abs() / e0.abs());
        run.max_constraint = run.max_constraint.max(phi);
        run.max_velocity_constraint = run.max_velocity_constraint.max(report.velocity_residual);
        run.max_projection_iterations = run.max_projection_iterations.max(report.projection_iterations);
        run.max_branch_deviation = run.max_branch_deviation.max(branch_deviation(&state));
        let angle = crank_angle(&state, 0);
        if last_sin != 0.0 && angle.sin() * last_sin <= 0.0 {
            run.singular_passages += 1;
        }
        last_sin = angle.sin();
        if angle.sin().abs() < 0.02 {
            let s = critical_singular_value(&plain, &state);
            if s < run.min_singular_value {
                run.min_singular_value = s;
                run.min_singular_angle = angle.sin().asin();
            }
            run.max_dropped_rows = run.max_dropped_rows.max(dropped_rows(&plain, &state));
        }
        if n % sample_every.max(1) == 0 || n == steps {
            run.samples.push(Sample { t: state.t, b0: b0(&state), energy_error: de, constraint: phi });
            run.trajectory.record(&state);
        }
    }
    run.end = state;
    Ok(run)
}
