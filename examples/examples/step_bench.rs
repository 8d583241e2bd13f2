//! Time per `Simulation::step` on the double Cardan shaft (Z arrangement, yokes
//! in phase, β = 30°) as a dynamics problem: no motor, gravity along −z, the
//! shafts spinning freely from an initial 10 rad/s (velocities from the driven
//! shaft's velocity analysis, so the start is consistent). Each integrator (RK4,
//! implicit midpoint, generalised-α, Radau IIA) with and without projection, `h = 1 ms`, `STEPS` steps ×
//! `REPS` repetitions from the same start; the median of the individually timed
//! steps. `tests/tests/alloc.rs` proves that a step allocates nothing.
//!
//! ```text
//! cargo run --release -p joint-examples --features bench --example step_bench
//! ```

use std::time::Instant;

use joint_examples::double_cardan::{Arrangement, DoubleCardan, FreeDoubleCardan, Geometry, Phasing};
use joint_runtime::dynamics::{Integrator, NoLoads, Simulation, SimulationOptions};

const STEPS: usize = 20_000;
const REPS: usize = 5;
const H: f64 = 1e-3;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let geometry = Geometry::new(30f64.to_radians(), Arrangement::Z, Phasing::InPhase).ok_or("geometry")?;
    let spin = 10.0;
    let start = DoubleCardan::new(geometry, spin).initial_state()?;
    let scene = FreeDoubleCardan::new(&geometry);

    println!(
        "Double Cardan shaft (Z, in phase, β = 30°), free, gravity −z, initial spin {spin} rad/s; \
         h = {} ms, {STEPS} steps × {REPS} repetitions per row (release build).\n",
        H * 1e3
    );
    println!(
        "{:<17} {:>10}  {:>11}  {:>11}  {:>11}  {:>11}  {:>12}",
        "integrator", "projection", "median ns", "mean ns", "|ΔE|/E", "max |Φ|", "ω_out − ω_in"
    );
    let mut times = Vec::with_capacity(STEPS * REPS);
    for integrator in
        [Integrator::Rk4, Integrator::ImplicitMidpoint, Integrator::GeneralisedAlpha, Integrator::RadauIIA]
    {
        for projection in [true, false] {
            let mut options = SimulationOptions::default().with_integrator(integrator);
            if !projection {
                options.projection = None;
            }
            let mut sim = Simulation::new(&scene, NoLoads, &[], options)?;
            let e0 = sim.energy(&start).total();
            times.clear();
            let (mut drift, mut residual, mut mismatch) = (0.0f64, 0.0f64, 0.0f64);
            let mut total = 0.0;
            for _ in 0..REPS {
                let mut state = start;
                let clock = Instant::now();
                for _ in 0..STEPS {
                    let t = Instant::now();
                    let report = sim.step(&mut state, H)?;
                    times.push(t.elapsed().as_nanos() as u64);
                    residual = residual.max(report.constraint_residual);
                }
                total += clock.elapsed().as_secs_f64();
                drift = drift.max(((sim.energy(&state).total() - e0) / e0).abs());
                mismatch = mismatch.max((state.bodies[2].omega.x - state.bodies[0].omega.x).abs());
            }
            times.sort_unstable();
            let median = times[times.len() / 2];
            println!(
                "{:<17} {:>10}  {:>11}  {:>11.0}  {:>11.2e}  {:>11.2e}  {:>12.2e}",
                format!("{integrator:?}"),
                if projection { "on" } else { "off" },
                median,
                total * 1e9 / (STEPS * REPS) as f64,
                drift,
                residual,
                mismatch
            );
        }
    }
    println!(
        "\n|ΔE|/E: energy error after {} s (kinetic only: every centre of mass stays put); \
         ω_out − ω_in: the in-phase shaft's output minus input spin at the end (0 exactly).\n\
         A step allocates nothing: tests/tests/alloc.rs counts allocations around scene steps \
         of every integrator (0).",
        STEPS as f64 * H
    );
    Ok(())
}
