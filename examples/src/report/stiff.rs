//! Work–precision of every integrator on three mechanisms (`report/stiff.md`,
//! `cargo run --release -p joint-examples --bin stiff`):
//!
//! - **press**: the stiff press of [`crate::press`] (five bodies, closed loop,
//!   three redundant rows, a 20 rad/s motor, two rams on spring-dampers with a
//!   7 071 rad/s mode), 0.5 s from the assembled start;
//! - **bricard**: Bricard's mechanism (five bars, one redundant row), free
//!   under gravity from rest, 1 s;
//! - **double-cardan**: the free double Cardan shaft (β = 30°, Z, in phase),
//!   spinning at 10 rad/s under gravity, 1 s.
//!
//! Integrators: fixed steps of RK4, the implicit midpoint rule,
//! generalised-α (ρ∞ = 0.8) and Radau IIA, the implicit ones with the
//! generated iteration matrix; and the error-controlled Dormand–Prince
//! 5(4), generalised-α and Radau IIA over a range of tolerances (`rtol =
//! atol`). Each in both coordinate choices of the one declaration
//! (`coordinates = both`): the absolute `AbsoluteSimulation` and the relative
//! `TreeSimulation`, the series named by their engine. Every
//! run projects after each step (the default options). The error is the
//! largest `|r − r_ref| + |p − p_ref|` of a body at the end (metres and
//! Euler parameters, `p` up to its sign; a relative run's end as bodies),
//! the reference being the absolute Dormand–Prince at `rtol = atol =
//! 1e-12`; the time is the fastest of repeated runs until 20 ms were spent.

use std::time::Instant;

use joint_runtime::dynamics::{
    AbsoluteSimulation, Adaptive, Integrator, NoLoads, SimulationOptions, SpringDamper, Tolerance,
};
use joint_runtime::relative::{TreeScene, TreeSimulation};
use joint_runtime::{Scene, SparseJacobian, SystemState};

use super::simulation::Series;

/// Repetitions of one run stop once this much time (s) was spent on it.
const MIN_TIME: f64 = 0.02;
/// The error at which the summary compares the integrators' times.
pub const TARGET_ERROR: f64 = 1e-8;

/// The coordinate choice a run is in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Engine {
    /// Bodies' absolute coordinates (`AbsoluteSimulation`).
    Absolute,
    /// The tree's joint coordinates (`TreeSimulation`).
    Relative,
}

impl Engine {
    /// The word the series' names end with.
    pub fn word(self) -> &'static str {
        match self {
            Engine::Absolute => "absolute",
            Engine::Relative => "relative",
        }
    }
}

/// How a run advances.
#[derive(Clone, Copy, Debug)]
enum Run {
    /// Fixed steps.
    Fixed(Integrator, usize),
    /// Error-controlled steps to a tolerance.
    Adaptive(Adaptive, f64),
}

/// One mechanism of the benchmark.
struct Problem<'a, S, const NB: usize> {
    group: &'static str,
    scene: &'a S,
    springs: &'a [SpringDamper],
    start: SystemState<NB>,
    t_end: f64,
}

impl<S, const NB: usize> Problem<'_, S, NB> {
    /// The state at `t_end` by `run` in `engine`'s coordinates (as bodies),
    /// or why it failed.
    fn run<const NV6: usize, const M: usize, const NNZ: usize, const NQ: usize, const NV: usize, const NC: usize>(
        &self,
        engine: Engine,
        run: Run,
    ) -> Result<SystemState<NB>, String>
    where
        S: Scene<NB, NV6, M> + SparseJacobian<NB, NNZ> + TreeScene<NB, NQ, NV, NC>,
    {
        // The simulation is made for the integrator it runs (for
        // error-controlled steps, the one they are made of), so that `new`
        // makes that integrator's workspace.
        let integrator = match run {
            Run::Fixed(i, _) => i,
            Run::Adaptive(Adaptive::GeneralisedAlpha, _) => Integrator::GeneralisedAlpha,
            Run::Adaptive(Adaptive::RadauIIA, _) => Integrator::RadauIIA,
            Run::Adaptive(..) => Integrator::Rk4,
        };
        let options = SimulationOptions::default().with_integrator(integrator).with_spectral_radius(0.8);
        let text = |e: joint_runtime::analysis::AnalysisError| e.to_string();
        if engine == Engine::Relative {
            return self.run_relative(options, run);
        }
        let mut state = self.start;
        match run {
            Run::Fixed(_, steps) => {
                let mut sim = AbsoluteSimulation::new(self.scene, NoLoads, self.springs, options).map_err(text)?;
                let h = self.t_end / steps as f64;
                for _ in 0..steps {
                    sim.step(&mut state, h).map_err(text)?;
                }
            }
            Run::Adaptive(method, tol) => {
                let mut sim = AbsoluteSimulation::new(self.scene, NoLoads, self.springs, options).map_err(text)?;
                sim.integrate(&mut state, self.t_end, method, Tolerance { rtol: tol, atol: tol }).map_err(text)?;
            }
        }
        Ok(state)
    }

    /// [`run`](Self::run) in the tree's coordinates with `options`.
    fn run_relative<const NQ: usize, const NV: usize, const NC: usize>(
        &self,
        options: SimulationOptions,
        run: Run,
    ) -> Result<SystemState<NB>, String>
    where
        S: TreeScene<NB, NQ, NV, NC>,
    {
        let text = |e: joint_runtime::relative::TreeError| e.to_string();
        let made = TreeSimulation::new(self.scene).and_then(|s| s.with_springs(self.springs));
        let mut sim = made.and_then(|s| s.with_options(options)).map_err(text)?;
        let mut state = sim.state_of(&self.start).map_err(text)?;
        match run {
            Run::Fixed(_, steps) => {
                let h = self.t_end / steps as f64;
                for _ in 0..steps {
                    sim.step(&mut state, h).map_err(text)?;
                }
            }
            Run::Adaptive(method, tol) => {
                sim.integrate(&mut state, self.t_end, method, Tolerance { rtol: tol, atol: tol }).map_err(text)?;
            }
        }
        Ok(sim.tree().system_state(&state))
    }

    /// The fastest time of `run` (s) and its end state.
    fn timed<const NV6: usize, const M: usize, const NNZ: usize, const NQ: usize, const NV: usize, const NC: usize>(
        &self,
        engine: Engine,
        run: Run,
    ) -> Result<(f64, SystemState<NB>), String>
    where
        S: Scene<NB, NV6, M> + SparseJacobian<NB, NNZ> + TreeScene<NB, NQ, NV, NC>,
    {
        let (mut best, mut spent, mut end) = (f64::INFINITY, 0.0, self.start);
        while spent < MIN_TIME {
            let clock = Instant::now();
            end = self.run(engine, run)?;
            let t = clock.elapsed().as_secs_f64();
            best = best.min(t);
            spent += t;
        }
        Ok((best, end))
    }

    /// Every series of the problem.
    fn series<const NV6: usize, const M: usize, const NNZ: usize, const NQ: usize, const NV: usize, const NC: usize>(
        &self,
        progress: &mut dyn FnMut(&str),
    ) -> Vec<Series>
    where
        S: Scene<NB, NV6, M> + SparseJacobian<NB, NNZ> + TreeScene<NB, NQ, NV, NC>,
    {
        let reference = match self.run(Engine::Absolute, Run::Adaptive(Adaptive::DormandPrince, 1e-12)) {
            Ok(r) => r,
            Err(e) => {
                progress(&format!("{}: the reference run failed: {e}", self.group));
                return Vec::new();
            }
        };
        // Position and orientation: |Δr| + |Δp| (p up to its sign) of the worst body.
        let error = |s: &SystemState<NB>| {
            s.bodies
                .iter()
                .zip(&reference.bodies)
                .map(|(a, b)| (a.r - b.r).norm() + (a.p - b.p).norm().min((a.p + b.p).norm()))
                .fold(0.0, f64::max)
        };
        let steps = [50usize, 100, 200, 400, 800, 1600, 3200, 6400];
        let tolerances = [1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10];
        let mut lines: Vec<(String, Engine, Vec<Run>)> = Vec::new();
        for engine in [Engine::Absolute, Engine::Relative] {
            for (name, i) in [
                ("RK4", Integrator::Rk4),
                ("implicit midpoint", Integrator::ImplicitMidpoint),
                ("generalised-α", Integrator::GeneralisedAlpha),
                ("Radau IIA", Integrator::RadauIIA),
            ] {
                let runs = steps.iter().map(|&n| Run::Fixed(i, n)).collect();
                lines.push((format!("{name}, fixed h, {}", engine.word()), engine, runs));
            }
            for (name, method) in [
                ("Dormand–Prince 5(4)", Adaptive::DormandPrince),
                ("generalised-α", Adaptive::GeneralisedAlpha),
                ("Radau IIA 5(3)", Adaptive::RadauIIA),
            ] {
                let runs = tolerances.iter().map(|&t| Run::Adaptive(method, t)).collect();
                lines.push((format!("{name}, tolerance, {}", engine.word()), engine, runs));
            }
        }
        let mut out = Vec::new();
        for (name, engine, runs) in lines {
            let mut points = Vec::new();
            let mut failed = Vec::new();
            for run in runs {
                match self.timed(engine, run) {
                    Ok((time, end)) => points.push((time, error(&end))),
                    Err(e) => failed.push(format!("{run:?}: {e}")),
                }
            }
            let why = failed.first().map_or(String::new(), |e| format!(" (first: {e})"));
            progress(&format!("{}: {name}: {} points, {} runs failed{why}", self.group, points.len(), failed.len()));
            out.push(Series { name, group: self.group.to_string(), points });
        }
        out
    }
}

/// The series of the three problems, the press first.
///
/// # Errors
/// A failed start (assembly or velocity analysis of a mechanism).
pub fn work_precision(progress: &mut dyn FnMut(&str)) -> Result<Vec<Series>, String> {
    use crate::double_cardan::{Arrangement, DoubleCardan, FreeDoubleCardan, Geometry, Phasing};
    let press = crate::press::scene();
    let springs = crate::press::springs();
    let start = crate::press::initial_state().map_err(|e| e.to_string())?;
    let mut out = Problem { group: "press", scene: &press, springs: &springs, start, t_end: 0.5 }.series(progress);
    let bricard = crate::bricard::scene();
    let start = crate::bricard::initial_state();
    out.extend(Problem { group: "bricard", scene: &bricard, springs: &[], start, t_end: 1.0 }.series(progress));
    let geometry = Geometry::new(30f64.to_radians(), Arrangement::Z, Phasing::InPhase).ok_or("geometry")?;
    let start = DoubleCardan::new(geometry, 10.0).initial_state().map_err(|e| e.to_string())?;
    let shaft = FreeDoubleCardan::new(&geometry);
    out.extend(Problem { group: "double-cardan", scene: &shaft, springs: &[], start, t_end: 1.0 }.series(progress));
    Ok(out)
}

/// The time (s) of the cheapest run of a series whose error is at most
/// `error`; `None` if none is.
pub fn time_for(series: &Series, error: f64) -> Option<f64> {
    series.points.iter().filter(|&&(t, e)| t > 0.0 && e <= error).map(|&(t, _)| t).min_by(f64::total_cmp)
}
