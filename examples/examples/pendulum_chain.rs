//! A spatial chain of five bars on spherical joints, whirling and swinging for
//! 10 s: energy and constraint drift of each integrator, with and without
//! projection; plots go to `target/plots/pendulum_chain_*.svg`, the RK4 run
//! with projection in 3D to `target/plots/pendulum_chain.html`.
//!
//! ```text
//! cargo run --release -p joint-examples --example pendulum_chain
//! ```

use std::error::Error;
use std::path::Path;

use joint_examples::bricard::{Curve, plot_lines};
use joint_examples::pendulum_chain as chain;
use joint_runtime::dynamics::Integrator;

fn main() -> Result<(), Box<dyn Error>> {
    let start = chain::initial_state();
    let tip = chain::tip(&start);
    println!(
        "pendulum chain: {} bars on spherical joints, 15 rows, 30 columns; tip starts at ({:.3}, {:.3}, {:.3}) m",
        chain::BODIES,
        tip.x,
        tip.y,
        tip.z
    );
    let mut curves: Vec<Curve> = Vec::new();
    let mut shown = None;
    for (integrator, projection, h) in [
        (Integrator::Rk4, true, 1e-3),
        (Integrator::Rk4, false, 1e-3),
        (Integrator::ImplicitMidpoint, true, 1e-3),
        (Integrator::ImplicitMidpoint, false, 1e-3),
        (Integrator::Rk4, true, 1e-2),
        (Integrator::ImplicitMidpoint, true, 1e-2),
    ] {
        let timer = std::time::Instant::now();
        let run = chain::simulate(integrator, projection, h, 10.0, 10)?;
        let tip = chain::tip(&run.end);
        println!(
            "{integrator:?}, h = {h}, projection {}: energy error max {:.2e}, at 10 s {:+.2e} (of T0 = {:.2} J); \
             max |Φ| = {:.2e}, max |J v| = {:.2e}; tip(10 s) = ({:.4}, {:.4}, {:.4}) [{:.1} s]",
            if projection { "on " } else { "off" },
            run.max_relative_energy_error,
            run.final_relative_energy_error,
            run.initial_kinetic,
            run.max_constraint,
            run.max_velocity_constraint,
            tip.x,
            tip.y,
            tip.z,
            timer.elapsed().as_secs_f64()
        );
        if (integrator, projection, h) == (Integrator::Rk4, true, 1e-3) {
            shown = Some(run.trajectory.clone());
        }
        if h == 1e-3 {
            let name = format!("{integrator:?}{}", if projection { " + projection" } else { "" });
            curves.push((name, run.samples.iter().map(|s| (s.t, s.energy_error / run.initial_kinetic)).collect()));
        }
    }
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/plots/pendulum_chain_energy.svg");
    plot_lines(&path, "Pendulum chain: (E − E0)/T0, h = 1e-3", ("t (s)", "relative energy error"), &curves)?;
    println!("plot: {}", path.display());
    if let Some(run) = shown {
        let title = "Pendulum chain: five bars on spherical joints, RK4 + projection, h = 1e-3";
        joint_examples::write_animation(&path.with_file_name("pendulum_chain"), &run, title)?;
    }
    Ok(())
}
