//! The robot level's stiff run: the UR5 from its URDF file under a PD law
//! of 1e4 N·m/rad and 1e2 N·m·s/rad on every joint (the test's,
//! `tests/tests/runtime/tree_implicit.rs`), 0.5 s from 0.2 rad off its
//! target, at several steps: RK4 with the law's forces held over each step
//! (a controller's zero-order hold) and the linearly implicit Euler step
//! (`implicit_step_with`, the law's gains in its Newton matrix), each's
//! error against an RK4 run at 20 µs and its time per step.

use std::fmt::Write as _;
use std::time::Instant;

use joint_runtime::nalgebra::SVector;
use joint_runtime::relative::{ForceGains, StepWork, TreeSimulation, TreeState};

use super::derivatives::Ur5;

const KP: f64 = 1e4;
const KD: f64 = 1e2;
const T_END: f64 = 0.5;

/// The steps compared (s).
pub const STEPS: [f64; 5] = [2.5e-4, 5e-4, 1e-3, 2e-3, 4e-3];

/// One integrator at one step: its error (rad, the largest joint's at
/// `T_END`) or the time it diverged, and its median time per step.
#[derive(Clone, Copy, Debug)]
pub struct Outcome {
    /// `Ok(error)`, or `Err(t)`: the run diverged at `t` (`TreeError::Diverged`).
    pub error: Result<f64, f64>,
    /// Median ns per step over 5 runs (up to the divergence).
    pub ns_per_step: f64,
}

/// One step size's row.
#[derive(Clone, Copy, Debug)]
pub struct Row {
    /// The step (s).
    pub h: f64,
    /// RK4, the law's forces held.
    pub rk4: Outcome,
    /// The linearly implicit Euler step.
    pub implicit: Outcome,
}

type State = TreeState<6, 6>;

fn target() -> SVector<f64, 6> {
    SVector::from([0.3, -1.2, 1.4, -0.8, 0.5, 0.2])
}

fn pd(state: &State) -> SVector<f64, 6> {
    (target() - state.q) * KP - state.v * KD
}

fn start() -> State {
    TreeState { q: target().add_scalar(0.2), v: SVector::zeros(), t: 0.0 }
}

/// `T_END` of steps of `h` by `step` (which returns false on divergence):
/// the end state or the time it diverged, and the ns per step taken.
fn run(h: f64, step: &mut dyn FnMut(&mut State, f64) -> bool) -> (Result<State, f64>, f64) {
    let (mut state, steps) = (start(), (T_END / h).round() as usize);
    let clock = Instant::now();
    for k in 0..steps {
        if !step(&mut state, h) {
            let taken = (k + 1) as f64;
            return (Err(state.t + h), clock.elapsed().as_nanos() as f64 / taken);
        }
    }
    (Ok(state), clock.elapsed().as_nanos() as f64 / steps as f64)
}

/// Five runs: the last's end against `fine`, the median time per step.
fn outcome(h: f64, fine: &State, step: &mut dyn FnMut(&mut State, f64) -> bool) -> Outcome {
    let mut times = Vec::new();
    let mut end = Err(0.0);
    for _ in 0..5 {
        let (e, ns) = run(h, step);
        times.push(ns);
        end = e;
    }
    times.sort_by(f64::total_cmp);
    Outcome { error: end.map(|s| (s.q - fine.q).amax()), ns_per_step: times[2] }
}

/// Every step's row.
pub fn measure() -> Vec<Row> {
    let mut sim = TreeSimulation::new(&Ur5).expect("the UR5's tree");
    let mut fine = start();
    for _ in 0..(T_END / 2e-5).round() as usize {
        let tau = pd(&fine);
        sim.step_with(&mut fine, 2e-5, &tau).expect("the fine reference");
    }
    let gains = ForceGains::pd(&SVector::repeat(KP), &SVector::repeat(KD));
    let mut work = StepWork::new();
    STEPS
        .iter()
        .map(|&h| {
            let rk4 = outcome(h, &fine, &mut |s, h| {
                let tau = pd(s);
                sim.step_with(s, h, &tau).is_ok()
            });
            let implicit = outcome(h, &fine, &mut |s, h| {
                let tau = pd(s);
                sim.implicit_step_with(s, h, &tau, &gains, &mut work).is_ok()
            });
            Row { h, rk4, implicit }
        })
        .collect()
}

/// The report's section.
pub fn section(rows: &[Row]) -> String {
    let mut s = String::from(
        "### A stiff robot at its own step\n\nThe UR5 from its URDF file under a PD law of 1e4 N·m/rad and \
         1e2 N·m·s/rad on every joint, 0.5 s from 0.2 rad off its target (`report::stiff_robot`, the test \
         `tree_implicit.rs`'s run): RK4 with the law's forces held over each step, and the linearly implicit \
         Euler step with the law's gains in its Newton matrix (`implicit_step_with`). **Error**: the largest \
         joint's, rad, at 0.5 s against an RK4 run at 20 µs; *diverged at t*: the step's \
         `TreeError::Diverged`. **Time**: median ns per step over 5 runs.\n\n\
         | h | RK4 | implicit Euler |\n|---|---|---|\n",
    );
    let cell = |o: &Outcome| match o.error {
        Ok(e) => format!("{e:.1e} rad · {:.0} ns", o.ns_per_step),
        Err(t) => format!("diverged at t = {t:.3} s · {:.0} ns", o.ns_per_step),
    };
    for r in rows {
        let _ = writeln!(s, "| {} ms | {} | {} |", r.h * 1e3, cell(&r.rk4), cell(&r.implicit));
    }
    s.push('\n');
    s
}
