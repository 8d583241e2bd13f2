//! Bricard's mechanism, IFToMM multibody benchmark A04: an over-constrained
//! closed loop that moves.
//!
//! Five identical bars (1 m, 1 kg, square section 0.1 m) and the ground, as the
//! sixth link, are joined in a loop by six revolute joints. The joints sit at the
//! corners of a unit cube, `P0 = (0, 0, 0)`, `P1 = (1, 0, 0)`, `P2 = (1, −1, 0)`,
//! `P3 = (1, −1, 1)`, `P4 = (0, −1, 1)`, `P5 = (0, 0, 1)`, and their axes are
//! `y, z, x, y, z, x`: consecutive axes are perpendicular, and each bar is
//! perpendicular to both of its axes. Gravity is 9.81 m/s² along −y and the
//! mechanism starts from rest (as in the benchmark's public re-implementations).
//!
//! Grübler–Kutzbach counts `6·5 − 5·6 = 0` degrees of freedom, yet the special axis
//! arrangement leaves one: of the 30 constraint rows one is redundant at every
//! configuration. The analyses find it (the rank-revealing factorisation drops one
//! row and names its joint), and dynamics, projection and assembly work with the
//! remaining 29.
//!
//! Bodies: `bar1 … bar5` with frames at their centres of mass and the local `x`
//! axis along the bar (from `P(i−1)` to `Pi`); the ground closes the loop from
//! `P5` back to `P0`.

// `AnalysisError` is returned by value, as in `joint_runtime` (it carries the
// worst rows; the runtime has no allocator to box it).

use joint_runtime::analysis::{AnalysisError, Assembly, AssemblyOptions, RowList, assemble};
use joint_runtime::dynamics::{AbsoluteSimulation, Integrator, NoLoads, SimulationOptions};
use joint_runtime::linalg::{DEFAULT_RANK_TOLERANCE, PivotedCholesky};
use joint_runtime::nalgebra::{UnitQuaternion, Vector3};
use joint_runtime::record::Trajectory;
use joint_runtime::{BodyInertia, OmegaBody, Scene, SparseJacobian, SystemState};

/// Number of moving bars.
pub const BODIES: usize = 5;
/// Velocity columns (`6 × BODIES`).
pub const COLUMNS: usize = 6 * BODIES;
/// Constraint rows: six revolute joints of five rows.
pub const ROWS: usize = 30;
/// Gravity, m/s², along −y.
pub const GRAVITY: f64 = 9.81;

/// Bar inertia (body components), as declared in [`Bricard`]: a 1 m × 0.1 m ×
/// 0.1 m block of 1 kg, `(0.1² + 0.1²)/12` about its axis (`x`) and
/// `(1² + 0.1²)/12` across it.
pub fn bar_inertia() -> BodyInertia {
    BodyInertia::principal(1.0, Vector3::new((0.01 + 0.01) / 12.0, (1.0 + 0.01) / 12.0, (1.0 + 0.01) / 12.0))
}

/// The mechanism. Body frames: origin at the bar's centre, `x` along the bar; joint
/// `ji` sits at `Pi` with the axis `y, z, x, y, z, x` (`i = 0 … 5`), given in each
/// body's components. Bar inertia as [`bar_inertia`].
#[derive(joint_runtime::Scene)]
#[scene(gravity = [0, -9.81, 0], second_order, coordinates = both)]
#[body(bar1, mass = 1.0, inertia = [0.0016666666666666668, 0.08416666666666667, 0.08416666666666667])]
#[body(bar2, mass = 1.0, inertia = [0.0016666666666666668, 0.08416666666666667, 0.08416666666666667])]
#[body(bar3, mass = 1.0, inertia = [0.0016666666666666668, 0.08416666666666667, 0.08416666666666667])]
#[body(bar4, mass = 1.0, inertia = [0.0016666666666666668, 0.08416666666666667, 0.08416666666666667])]
#[body(bar5, mass = 1.0, inertia = [0.0016666666666666668, 0.08416666666666667, 0.08416666666666667])]
#[joint(j0 = revolute(ground, bar1), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0, 0, 0], rho2 = [-0.5, 0, 0])]
#[joint(j1 = revolute(bar1, bar2), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0.5, 0, 0], rho2 = [-0.5, 0, 0])]
#[joint(j2 = revolute(bar2, bar3), axis1 = [0, 1, 0], axis2 = [0, 0, -1], rho1 = [0.5, 0, 0], rho2 = [-0.5, 0, 0])]
#[joint(j3 = revolute(bar3, bar4), axis1 = [0, 1, 0], axis2 = [0, -1, 0], rho1 = [0.5, 0, 0], rho2 = [-0.5, 0, 0])]
#[joint(j4 = revolute(bar4, bar5), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0.5, 0, 0], rho2 = [-0.5, 0, 0])]
#[joint(j5 = revolute(bar5, ground), axis1 = [0, -1, 0], axis2 = [1, 0, 0], rho1 = [0.5, 0, 0], rho2 = [0, 0, 1])]
#[derive(Clone, Copy, Debug, Default)]
pub struct Bricard;

/// The scene (a unit struct: everything is constant).
pub fn scene() -> Bricard {
    Bricard
}

/// The joint points `P0 … P5` of the initial configuration (inertial, m).
pub const JOINT_POINTS: [[f64; 3]; 6] =
    [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, -1.0, 0.0], [1.0, -1.0, 1.0], [0.0, -1.0, 1.0], [0.0, 0.0, 1.0]];

/// Each bar's orientation in the initial configuration: its local `x` axis along
/// `P(i−1) → Pi`.
pub fn initial_rotations() -> [UnitQuaternion<f64>; BODIES] {
    use core::f64::consts::{FRAC_PI_2, PI};
    [
        UnitQuaternion::identity(),
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), -FRAC_PI_2),
        UnitQuaternion::from_axis_angle(&Vector3::y_axis(), -FRAC_PI_2),
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), PI),
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), FRAC_PI_2),
    ]
}

/// The benchmark's initial state: the bars along the cube's edges, at rest, `t = 0`.
pub fn initial_state() -> SystemState<BODIES> {
    let q = initial_rotations();
    let bodies = core::array::from_fn(|i| {
        let [a, b] = [JOINT_POINTS[i], JOINT_POINTS[i + 1]];
        let centre = (Vector3::from(a) + Vector3::from(b)) * 0.5;
        OmegaBody::from_rotation(centre, &q[i], Vector3::zeros(), Vector3::zeros())
    });
    SystemState { bodies, t: 0.0 }
}

/// The initial configuration with every bar turned by `degrees` about a tilted
/// axis of its own (different for each bar) and shifted by `degrees/100` m: a
/// rough guess for [`assemble`].
pub fn perturbed_state(degrees: f64) -> SystemState<BODIES> {
    let mut s = initial_state();
    let angle = degrees.to_radians();
    for (i, b) in s.bodies.iter_mut().enumerate() {
        let k = i as f64;
        let axis = joint_runtime::nalgebra::Unit::new_normalize(Vector3::new(1.0 + k, 2.0 - k, 0.5 + 0.3 * k));
        let turn = UnitQuaternion::from_axis_angle(&axis, angle);
        b.set_rotation(&(turn * b.rotation()));
        b.r += Vector3::new(0.3 - 0.1 * k, 0.1 * k - 0.2, 0.25) * (degrees / 100.0);
    }
    s
}

/// Position of the body-fixed point `local` of bar `body` (inertial components).
pub fn point(state: &SystemState<BODIES>, body: usize, local: &Vector3<f64>) -> Vector3<f64> {
    state.bodies[body].point(local)
}

/// The joint point `P3` (between `bar3` and `bar4`), the benchmark's reference point.
pub fn p3(state: &SystemState<BODIES>) -> Vector3<f64> {
    point(state, 2, &Vector3::new(0.5, 0.0, 0.0))
}

/// Assembles the mechanism from [`perturbed_state`]`(degrees)` with the default
/// Newton options; returns the assembled state and the analysis' report (Newton
/// iterations, ‖Φ‖, redundant rows).
///
/// # Errors
/// Those of [`assemble`].
pub fn assemble_perturbed(degrees: f64) -> Result<(SystemState<BODIES>, Assembly<ROWS>), AnalysisError> {
    let mut state = perturbed_state(degrees);
    let report = assemble(&scene(), &mut state, &AssemblyOptions::default())?;
    Ok((state, report))
}

/// Numerical rank of the system Jacobian at `state` (rank-revealing Cholesky of
/// `J Jᵀ`, default tolerance): 29 on the Bricard mechanism's configuration curve,
/// so its mobility is `30 − 29 = 1` where Grübler–Kutzbach counts 0.
pub fn jacobian_rank(state: &SystemState<BODIES>) -> usize {
    let j = scene().jacobian(state);
    PivotedCholesky::new(&(j * j.transpose()), DEFAULT_RANK_TOLERANCE).map_or(0, |c| c.rank())
}

/// Names of the redundant rows, `joint[row]`, for printing.
pub fn describe(rows: &RowList<ROWS>) -> String {
    let names: Vec<String> = rows.as_slice().iter().map(|r| format!("{}[{}]", r.joint, r.joint_row)).collect();
    names.join(", ")
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
    /// The point `P3`.
    pub p3: Vector3<f64>,
}

/// What [`simulate`] measured.
#[derive(Clone, Debug, PartialEq)]
pub struct Run {
    /// Initial total energy (potential datum `y = 0`), J.
    pub initial_energy: f64,
    /// max |E(t) − E(0)| / |E(0)| over the run.
    pub max_relative_energy_error: f64,
    /// max ‖Φ‖₂ after each step.
    pub max_constraint: f64,
    /// max ‖J v‖₂ after each step.
    pub max_velocity_constraint: f64,
    /// Largest number of projection iterations in one step.
    pub max_projection_iterations: usize,
    /// Rows dropped as redundant by the dynamics at `t = 0`.
    pub redundant: RowList<ROWS>,
    /// The final state.
    pub end: SystemState<BODIES>,
    /// Samples every `sample_every` steps (and the last).
    pub samples: Vec<Sample>,
    /// The states at the samples, to write as CSV or an animated SVG.
    pub trajectory: Trajectory<BODIES>,
}

/// A run that stopped: the time of the state the failing step started from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Failure {
    /// Time, s.
    pub t: f64,
    /// What failed.
    pub error: AnalysisError,
}

impl core::fmt::Display for Failure {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "at t = {:.4} s: {}", self.t, self.error)
    }
}

impl core::error::Error for Failure {}

/// Runs `t_end` seconds of free motion from [`initial_state`] with step `h`,
/// projection onto Φ = 0 after every step (tolerance 1e-13, so the accepted
/// round-off floor stays below 1e-10) and the chosen integrator.
///
/// # Errors
/// The first failure of a step, with the time it was reached.
// The error is the runtime's (120 bytes) plus the time it happened: one word
// over clippy's threshold, on a path taken once per run.
#[allow(clippy::result_large_err)]
pub fn simulate<S: Scene<BODIES, COLUMNS, ROWS> + SparseJacobian<BODIES, NNZ>, const NNZ: usize>(
    scene: &S,
    integrator: Integrator,
    h: f64,
    t_end: f64,
    sample_every: usize,
) -> Result<Run, Failure> {
    let at = |t: f64| move |error| Failure { t, error };
    let options = SimulationOptions::default()
        .with_integrator(integrator)
        .with_projection(Some(AssemblyOptions::default().with_tolerance(1e-13).with_max_iterations(8)));
    let mut sim = AbsoluteSimulation::new(scene, NoLoads, &[], options).map_err(at(0.0))?;
    let mut state = initial_state();
    let redundant = sim.dynamics(&state).map_err(at(0.0))?.redundant;
    let e0 = sim.energy(&state).total();
    let steps = (t_end / h).round() as usize;
    let mut run = Run {
        initial_energy: e0,
        max_relative_energy_error: 0.0,
        max_constraint: scene.phi(&state).norm(),
        max_velocity_constraint: 0.0,
        max_projection_iterations: 0,
        redundant,
        end: state,
        samples: vec![Sample { t: 0.0, energy_error: 0.0, constraint: scene.phi(&state).norm(), p3: p3(&state) }],
        trajectory: Trajectory::new(scene),
    };
    run.trajectory.record(&state);
    for n in 1..=steps {
        let report = sim.step(&mut state, h).map_err(at(state.t))?;
        let de = sim.energy(&state).total() - e0;
        let phi = scene.phi(&state).norm();
        run.max_relative_energy_error = run.max_relative_energy_error.max(de.abs() / e0.abs());
        run.max_constraint = run.max_constraint.max(phi);
        run.max_velocity_constraint = run.max_velocity_constraint.max(report.velocity_residual);
        run.max_projection_iterations = run.max_projection_iterations.max(report.projection_iterations);
        if n % sample_every.max(1) == 0 || n == steps {
            run.samples.push(Sample { t: state.t, energy_error: de, constraint: phi, p3: p3(&state) });
            run.trajectory.record(&state);
        }
    }
    run.end = state;
    Ok(run)
}

/// One curve of [`plot_lines`]: a legend and its points.
pub type Curve = (String, Vec<(f64, f64)>);

/// Writes an SVG line plot (one line per curve, linear axes fitted to the data)
/// and creates the file's directory. Used by the example programs of this
/// module, of [`crate::four_bar`] and of [`crate::pendulum_chain`].
///
/// # Errors
/// Any I/O or drawing error, as text.
pub fn plot_lines(path: &std::path::Path, caption: &str, axes: (&str, &str), curves: &[Curve]) -> Result<(), String> {
    use plotters::prelude::*;
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).map_err(|e| format!("creating {}: {e}", dir.display()))?;
    }
    let points = curves.iter().flat_map(|c| c.1.iter());
    let (mut x0, mut x1, mut y0, mut y1) = (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
    for &(x, y) in points {
        (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
    }
    if !(x0.is_finite() && x1.is_finite() && y0.is_finite() && y1.is_finite()) {
        return Err("nothing to plot".into());
    }
    let pad = if y1 > y0 { 0.08 * (y1 - y0) } else { (y0.abs() * 0.1).max(1e-12) };
    let err = |e: &dyn std::fmt::Display| e.to_string();
    let root = SVGBackend::new(path, (960, 560)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(caption, ("sans-serif", 22))
        .margin(14)
        .x_label_area_size(42)
        .y_label_area_size(80)
        .build_cartesian_2d(x0..x1.max(x0 + 1e-12), (y0 - pad)..(y1 + pad))
        .map_err(|e| err(&e))?;
    chart
        .configure_mesh()
        .x_desc(axes.0)
        .y_desc(axes.1)
        .y_label_formatter(&|y| format!("{y:.3e}"))
        .draw()
        .map_err(|e| err(&e))?;
    for (i, (label, pts)) in curves.iter().enumerate() {
        let color = Palette99::pick(i).to_rgba();
        chart
            .draw_series(LineSeries::new(pts.iter().copied(), color.stroke_width(2)))
            .map_err(|e| err(&e))?
            .label(label.clone())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2)));
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(|e| err(&e))?;
    root.present().map_err(|e| err(&e))
}
