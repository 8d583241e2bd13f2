//! Work–precision diagrams of the simulations: the error of a run against its
//! run time over a range of step sizes, for each integrator (RK4, implicit
//! midpoint) and each way of holding the constraints (none, Baumgarte,
//! projection).
//!
//! # The problems
//!
//! - **`cardan`**: the Cardan shaft of [`crate::cardan`], bent by 30°, its input
//!   driven at 10 rad/s, simulated by *forward dynamics with the driver*
//!   ([`AbsoluteSimulation::step`](joint_runtime::dynamics::AbsoluteSimulation::step) on [`CardanShaft`], motor included) from the
//!   reference configuration with the velocities of the driven motion. With the
//!   motor the mechanism has no freedom left, so the constrained accelerations
//!   are those of the kinematics (the masses only set λ and the metric of the
//!   projection); the integrator must follow the output's non-uniform rotation
//!   while keeping 15 rows, 3 of them redundant, on Φ = 0. Two input turns
//!   (1.26 s). The error is the largest `|φ₂ − φ₂,closed(ω₁ t)|` over the steps,
//!   with `tan φ₂ = tan φ₁ / cos β` ([`output_angle`]) at the *prescribed* input
//!   angle, so a drift of the input off its driver counts too.
//! - **`bricard`**: Bricard's mechanism of [`crate::bricard`] (IFToMM A04, five
//!   bars, 30 rows, one redundant), free motion under gravity from rest for 2 s.
//!   The error is `|P3 − P3,ref|` at the end, the reference being RK4 with
//!   projection at a step 16 times smaller than the smallest of the diagram.
//!
//! # The variants
//!
//! Each integrator runs three ways: *none* (plain `J v̇ = γ`, no projection: the
//! index-1 equations drift off Φ = 0), *Baumgarte* (`α = β = 10 /s`, no
//! projection) and *projection* (no Baumgarte; positions and velocities
//! projected after every step with the default [`SimulationOptions`]
//! projection). A run that fails (a step's dynamics or Newton iteration gives
//! up) leaves its point out of the series, and the progress line says so.
//!
//! # Timing
//!
//! A point's time is the wall-clock time of the whole run (building the
//! [`Simulation`], the steps and the cheap error measurement along the way), the
//! fastest of repeated runs until 20 ms were spent on that point. One thread;
//! the whole computation takes about 10 s in a release build.
//!
//! # What the diagrams show
//!
//! - Cardan shaft: RK4 converges at fourth order (error ÷16 per halving of h),
//!   the implicit midpoint rule at second order; Baumgarte lowers the error by a
//!   factor (4–10 for RK4, 16 for the midpoint rule). With projection
//!   the error sits at round-off for every step: a driven mechanism has no
//!   freedom, so projecting onto Φ(q, t) = 0 and `J v = −Φ_t` *is* the exact
//!   kinematic solution at `t`, and the integrator only supplies the starting
//!   guess. What projection costs is visible on the time axis.
//! - Bricard: *every* variant converges at second order, RK4 included (error ÷4
//!   per halving). The redundant row is to blame: the same mechanism with the
//!   closing revolute replaced by a cylindrical joint (29 rows, none redundant)
//!   gives RK4 its fourth order back (error ÷16 per halving, 2·10⁻⁸ at h = 0.02 s
//!   over 0.5 s where the redundant scene has 5·10⁻⁷). The likely mechanism: off
//!   the constraint manifold (RK4's stage states sit O(h²) off it) the redundant
//!   rows' acceleration equations disagree by O(h²), and the row the pivoted
//!   factorisation drops flips between `j5[0]` and `j0[0]` from one stage state to
//!   the next (a third of the second stages drop `j0[0]`, at every h tried), so
//!   the stage accelerations jump by O(h²): a local error of O(h³).
//!   At the largest steps several variants stop with "redundant constraints are
//!   inconsistent" (the disagreement exceeds
//!   [`REDUNDANT_TOLERANCE`](joint_runtime::dynamics::REDUNDANT_TOLERANCE)), and
//!   RK4 with projection at h = 0.05 s completes but lands 0.19 m away.

use std::time::Instant;

use joint_runtime::SystemState;
use joint_runtime::analysis::{AnalysisError, velocities};
use joint_runtime::dynamics::{Integrator, NoLoads, Simulation, SimulationOptions, Stabilisation};
use joint_runtime::nalgebra::{UnitQuaternion, Vector3};

use crate::bricard;
use crate::cardan::{CardanShaft, output_angle, shaft_angle, wrap};

/// One line of a work–precision diagram.
#[derive(Clone, Debug, PartialEq)]
pub struct Series {
    /// Integrator and stabilisation, e.g. `"RK4, projection"`.
    pub name: String,
    /// The problem: `"cardan"` or `"bricard"`.
    pub group: String,
    /// `(run time in seconds, error)`, from the largest step to the smallest.
    /// The error is in radians for `cardan`, metres for `bricard` (module documentation).
    pub points: Vec<(f64, f64)>,
}

/// The Cardan shaft's bend, degrees.
const BEND_DEGREES: f64 = 30.0;
/// The Cardan shaft's input speed, rad/s.
const INPUT_SPEED: f64 = 10.0;
/// Baumgarte's parameters, 1/s.
const BAUMGARTE: Stabilisation = Stabilisation::Baumgarte { alpha: 10.0, beta: 10.0 };
/// Repetitions of one run stop once this much time (s) was spent on it...
const MIN_TIME: f64 = 0.02;
/// ...or after this many runs.
const MAX_REPEATS: usize = 50;

/// How the constraints are held.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Method {
    /// Plain `J v̇ = γ`.
    None,
    /// Baumgarte stabilisation, no projection.
    Baumgarte,
    /// Projection after every step, no Baumgarte.
    Projection,
}

impl Method {
    const ALL: [Method; 3] = [Method::None, Method::Baumgarte, Method::Projection];

    fn name(self) -> &'static str {
        match self {
            Method::None => "no stabilisation",
            Method::Baumgarte => "Baumgarte",
            Method::Projection => "projection",
        }
    }
}

fn integrator_name(integrator: Integrator) -> &'static str {
    match integrator {
        Integrator::Rk4 => "RK4",
        Integrator::ImplicitMidpoint => "implicit midpoint",
        _ => "another integrator",
    }
}

/// The simulation options of one variant.
fn options(integrator: Integrator, method: Method) -> SimulationOptions {
    let defaults = SimulationOptions::default();
    defaults
        .with_integrator(integrator)
        .with_stabilisation(if method == Method::Baumgarte { BAUMGARTE } else { Stabilisation::None })
        .with_projection(if method == Method::Projection { defaults.projection } else { None })
}

/// The ranges of one computation of the diagrams.
#[derive(Clone, Debug)]
struct Config {
    /// The integrators.
    integrators: Vec<Integrator>,
    /// Cardan shaft: steps per input turn, one point each.
    cardan_steps: Vec<usize>,
    /// Cardan shaft: input turns simulated.
    cardan_turns: usize,
    /// Bricard: steps over `bricard_end`, one point each.
    bricard_steps: Vec<usize>,
    /// Bricard: simulated time, s.
    bricard_end: f64,
    /// Bricard: steps of the reference run.
    bricard_reference_steps: usize,
    /// Repeat each run until this much time (s) was spent on it.
    min_time: f64,
}

impl Config {
    /// The report's ranges: about 10 s in a release build.
    fn report() -> Self {
        Config {
            integrators: vec![Integrator::Rk4, Integrator::ImplicitMidpoint],
            cardan_steps: vec![16, 32, 64, 128, 256, 512, 1024],
            cardan_turns: 2,
            bricard_steps: vec![40, 80, 160, 320, 640, 1280, 2560],
            bricard_end: 2.0,
            bricard_reference_steps: 16 * 2560,
            min_time: MIN_TIME,
        }
    }
}

/// Runs `run` until `min_time` seconds were spent (at least once, at most
/// [`MAX_REPEATS`] times); the fastest time and the (deterministic) result.
fn timed<R>(min_time: f64, mut run: impl FnMut() -> Result<R, AnalysisError>) -> Result<(f64, R), AnalysisError> {
    let (mut best, mut spent) = (f64::INFINITY, 0.0);
    let mut repeats = 0;
    loop {
        let clock = Instant::now();
        let result = run()?;
        let seconds = clock.elapsed().as_secs_f64();
        best = best.min(seconds);
        spent += seconds;
        repeats += 1;
        if spent >= min_time || repeats >= MAX_REPEATS {
            return Ok((best, result));
        }
    }
}

/// The Cardan shaft driven at [`INPUT_SPEED`] for `turns` input turns of
/// `steps_per_turn` steps: max |φ₂ − φ₂,closed| over the steps, rad.
fn cardan_error(
    integrator: Integrator,
    method: Method,
    steps_per_turn: usize,
    turns: usize,
) -> Result<f64, AnalysisError> {
    let bend = BEND_DEGREES.to_radians();
    let scene = CardanShaft::new(bend, INPUT_SPEED).ok_or(AnalysisError::BadOption { name: "bend" })?;
    let mut state = scene.reference_state();
    velocities(&scene, &mut state)?;
    let mut sim = Simulation::new(&scene, NoLoads, &[], options(integrator, method))?;
    let h = 2.0 * core::f64::consts::PI / INPUT_SPEED / steps_per_turn as f64;
    let reference = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), bend);
    let (mut phi2, mut worst) = (0.0f64, 0.0f64);
    for _ in 0..steps_per_turn * turns {
        sim.step(&mut state, h)?;
        // Unwrap: a step turns the output by well under π.
        phi2 += wrap(shaft_angle(&state.bodies[1], &reference) - phi2);
        worst = worst.max((phi2 - output_angle(INPUT_SPEED * state.t, bend)).abs());
    }
    Ok(worst)
}

/// Bricard's mechanism from rest for `end` seconds in `steps` steps: the final P3.
fn bricard_end(integrator: Integrator, method: Method, steps: usize, end: f64) -> Result<Vector3<f64>, AnalysisError> {
    let scene = bricard::scene();
    let mut state: SystemState<{ bricard::BODIES }> = bricard::initial_state();
    let mut sim = Simulation::new(&scene, NoLoads, &[], options(integrator, method))?;
    let h = end / steps as f64;
    for _ in 0..steps {
        sim.step(&mut state, h)?;
    }
    Ok(bricard::p3(&state))
}

/// One series: a point per entry of `steps` (`run` gives the error), and a
/// progress line.
fn series(
    group: &str,
    integrator: Integrator,
    method: Method,
    steps: &[usize],
    min_time: f64,
    progress: &mut dyn FnMut(&str),
    mut run: impl FnMut(usize) -> Result<f64, AnalysisError>,
) -> Series {
    let name = format!("{}, {}", integrator_name(integrator), method.name());
    let mut points = Vec::with_capacity(steps.len());
    let mut failed = Vec::new();
    for &n in steps {
        match timed(min_time, || run(n)) {
            Ok((seconds, error)) if error.is_finite() => points.push((seconds, error)),
            Ok(_) => failed.push(format!("{n} steps: non-finite error")),
            Err(e) => failed.push(format!("{n} steps: {e}")),
        }
    }
    let mut line = format!("{group:<8} {name:<38}");
    match (points.first(), points.last()) {
        (Some(&(t0, e0)), Some(&(t1, e1))) => {
            line +=
                &format!("{} points, error {e0:.2e} … {e1:.2e} in {:.2} … {:.2} ms", points.len(), t0 * 1e3, t1 * 1e3)
        }
        _ => line += "no points",
    }
    if !failed.is_empty() {
        line += &format!("; failed: {}", failed.join("; "));
    }
    progress(&line);
    Series { name, group: group.into(), points }
}

/// Both problems' diagrams for `config`.
fn compute(config: &Config, progress: &mut dyn FnMut(&str)) -> Vec<Series> {
    let mut out = Vec::new();
    for &integrator in &config.integrators {
        for method in Method::ALL {
            out.push(series("cardan", integrator, method, &config.cardan_steps, config.min_time, progress, |n| {
                cardan_error(integrator, method, n, config.cardan_turns)
            }));
        }
    }
    let clock = Instant::now();
    let reference =
        bricard_end(Integrator::Rk4, Method::Projection, config.bricard_reference_steps, config.bricard_end);
    let reference = match reference {
        Ok(p) => {
            progress(&format!(
                "bricard  reference: RK4 + projection, {} steps ({:.2} s)",
                config.bricard_reference_steps,
                clock.elapsed().as_secs_f64()
            ));
            p
        }
        Err(e) => {
            progress(&format!("bricard  reference run failed ({e}): no bricard diagram"));
            return out;
        }
    };
    for &integrator in &config.integrators {
        for method in Method::ALL {
            out.push(series("bricard", integrator, method, &config.bricard_steps, config.min_time, progress, |n| {
                Ok((bricard_end(integrator, method, n, config.bricard_end)? - reference).norm())
            }));
        }
    }
    out
}

/// The work–precision diagrams of both problems (module documentation): one
/// [`Series`] per problem × integrator × stabilisation (12), seven step sizes
/// each, the Cardan shaft first. Calls `progress` with one line per series (and
/// one for the Bricard reference run). About 10 s in a release build.
pub fn work_precision(progress: &mut dyn FnMut(&str)) -> Vec<Series> {
    compute(&Config::report(), progress)
}

/// Writes the log–log work–precision diagram (run time against error, one line
/// with markers per series) of the series of `group` to the SVG file `path`,
/// creating its directory. Points that are not positive are left out (a log
/// scale cannot show them).
///
/// # Errors
/// No plottable point in `group`; any I/O or drawing error, as text.
pub fn plot_work_precision(series: &[Series], group: &str, path: &std::path::Path) -> Result<(), String> {
    use plotters::prelude::*;
    let positive = |&(x, y): &(f64, f64)| x > 0.0 && y > 0.0 && x.is_finite() && y.is_finite();
    let chosen: Vec<(&str, Vec<(f64, f64)>)> = series
        .iter()
        .filter(|s| s.group == group)
        .map(|s| (s.name.as_str(), s.points.iter().copied().filter(positive).collect()))
        .collect();
    let (mut x0, mut x1, mut y0, mut y1) = (f64::INFINITY, 0.0f64, f64::INFINITY, 0.0f64);
    for &(x, y) in chosen.iter().flat_map(|c| c.1.iter()) {
        (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
    }
    if !(x0.is_finite() && y0.is_finite()) {
        return Err(format!("no positive points in group `{group}`"));
    }
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).map_err(|e| format!("creating {}: {e}", dir.display()))?;
    }
    let (title, error) = match group {
        "cardan" => ("Cardan shaft, driven (β = 30°, 2 turns)", "max |φ₂ − φ₂,closed| (rad)"),
        "bricard" if series.iter().any(|s| s.name.ends_with("tolerance")) => {
            ("Bricard mechanism, free under gravity (1 s)", "max |Δr| + |Δp| at the end")
        }
        "bricard" => ("Bricard mechanism, free under gravity (2 s)", "|P3 − P3,ref| at the end (m)"),
        "pendulum" => ("double pendulum", "error"),
        "press" => ("stiff press (k = 1e7 N/m, motor 20 rad/s, 0.5 s)", "max |Δr| + |Δp| at the end"),
        "double-cardan" => ("double Cardan shaft, free (β = 30°, 1 s)", "max |Δr| + |Δp| at the end"),
        _ => (group, "error"),
    };
    let err = |e: &dyn std::fmt::Display| e.to_string();
    let root = SVGBackend::new(path, (960, 640)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(format!("Work–precision: {title}"), ("sans-serif", 24))
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(80)
        // Three decades of headroom above the data for the legend.
        .build_cartesian_2d((x0 / 1.5..x1 * 1.5).log_scale(), (y0 / 3.0..y1 * 1e3).log_scale())
        .map_err(|e| err(&e))?;
    chart
        .configure_mesh()
        .x_desc("run time (s)")
        .y_desc(error)
        .label_style(("sans-serif", 15))
        .axis_desc_style(("sans-serif", 16))
        .x_label_formatter(&|x| format!("{x:.0e}"))
        .y_label_formatter(&|y| format!("{y:.0e}"))
        .draw()
        .map_err(|e| err(&e))?;
    for (i, (name, points)) in chosen.iter().enumerate() {
        let color = Palette99::pick(i).to_rgba();
        chart
            .draw_series(LineSeries::new(points.iter().copied(), color.stroke_width(2)).point_size(3))
            .map_err(|e| err(&e))?
            .label(*name)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2)));
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 15))
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(|e| err(&e))?;
    root.present().map_err(|e| err(&e))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// On a reduced range (a debug build is slow), RK4's error falls with the
    /// step size in every variant of both problems, and the diagram is drawn.
    #[test]
    fn rk4_errors_decrease_with_the_step_size() {
        let config = Config {
            integrators: vec![Integrator::Rk4],
            cardan_steps: vec![32, 64, 128],
            cardan_turns: 1,
            bricard_steps: vec![20, 40, 80],
            bricard_end: 0.5,
            bricard_reference_steps: 1280,
            min_time: 0.0,
        };
        let mut lines = Vec::new();
        let series = compute(&config, &mut |l| lines.push(l.to_string()));
        assert_eq!(series.len(), 6);
        assert_eq!(lines.len(), 7, "one line per series and one for the reference: {lines:#?}");
        for line in &lines {
            println!("{line}");
        }
        for s in &series {
            assert_eq!(s.points.len(), 3, "{} {}: a run failed: {lines:#?}", s.group, s.name);
            if s.group == "cardan" && s.name.ends_with("projection") {
                // No freedom left: the projection is an exact assembly at t.
                for &(_, error) in &s.points {
                    assert!(error < 1e-12, "{}: {error:e}", s.name);
                }
                continue;
            }
            for pair in s.points.windows(2) {
                let ((_, coarse), (_, fine)) = (pair[0], pair[1]);
                assert!(fine < 0.5 * coarse, "{} {}: error {coarse:e} → {fine:e} when halving h", s.group, s.name);
            }
        }
        let dir = std::env::temp_dir().join(format!("work-precision-{}", std::process::id()));
        for group in ["cardan", "bricard"] {
            let path = dir.join(format!("{group}.svg"));
            plot_work_precision(&series, group, &path).expect("plotted");
            let svg = std::fs::read_to_string(&path).expect("written");
            assert!(svg.contains("<svg") && svg.contains("RK4, projection"));
        }
        assert!(plot_work_precision(&series, "nothing", &dir.join("none.svg")).is_err());
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// The report's diagrams, printed (slow unless optimised):
    /// `cargo test --release -p joint-examples --lib report::simulation -- --ignored --nocapture`.
    #[test]
    #[ignore = "the full diagrams take about 10 s in a release build, minutes in a debug one"]
    fn print_work_precision() {
        let clock = Instant::now();
        for s in work_precision(&mut |l| println!("{l}")) {
            println!("{} / {}:", s.group, s.name);
            for (t, e) in &s.points {
                println!("    {:>10.3} ms  {e:.3e}", t * 1e3);
            }
        }
        println!("total {:.1} s", clock.elapsed().as_secs_f64());
    }
}
