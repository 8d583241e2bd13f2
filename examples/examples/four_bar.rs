//! The N-four-bar mechanism (IFToMM benchmark A02, N = 4): nine bars in four
//! parallelograms, passing again and again through the horizontal position where
//! all bars align and the Jacobian loses rank. The program prints the rank drop
//! at the singular position, then runs 10 s and prints energy and constraint
//! drift, the passages through the singular position and how close they came;
//! plots go to `target/plots/four_bar_*.svg`, an animation to `four_bar.svg`.
//!
//! ```text
//! cargo run --release -p joint-examples --example four_bar
//! ```

use std::error::Error;
use std::path::Path;

use joint_examples::bricard::plot_lines;
use joint_examples::four_bar::{self, ROWS};
use joint_examples::write_animation;
use joint_runtime::dynamics::Integrator;

fn main() -> Result<(), Box<dyn Error>> {
    let scene = four_bar::scene();
    let upright = four_bar::initial_state();
    let flat = four_bar::state_at(0.0, -1.0);
    println!("N-four-bar (IFToMM A02), N = {}: {} bars, {ROWS} rows, {} columns", four_bar::LOOPS, 9, 54);
    let sv = |s| four_bar::singular_values(&scene, s);
    let (up, fl) = (sv(&upright), sv(&flat));
    println!(
        "  upright:    rows dropped by the pivoted Cholesky of J Jᵀ = {}, smallest singular values {:.3e}, {:.3e}",
        four_bar::dropped_rows(&scene, &upright),
        up[52],
        up[53]
    );
    println!(
        "  horizontal: rows dropped = {}, smallest nonzero singular value {:.3e}, {} zero ones: the mobility jumps from 1 to {}",
        four_bar::dropped_rows(&scene, &flat),
        fl[48],
        fl.iter().filter(|&&s| s < 1e-10).count(),
        fl.iter().filter(|&&s| s < 1e-10).count()
    );
    for (integrator, h) in [(Integrator::Rk4, 1e-3), (Integrator::Rk4, 2e-3)] {
        let timer = std::time::Instant::now();
        let run = four_bar::simulate(&scene, &upright, integrator, h, 10.0, 10)?;
        println!("{integrator:?}, h = {h}, 10 s ({:.1} s):", timer.elapsed().as_secs_f64());
        println!(
            "  max |ΔE|/E0 = {:.2e} (E0 = {:.3} J), max |Φ| = {:.2e}, max |J v| = {:.2e}",
            run.max_relative_energy_error, run.initial_energy, run.max_constraint, run.max_velocity_constraint
        );
        println!(
            "  {} passages through the horizontal; closest at {:.2e} rad, where σ = {:.2e} (σ = {:.3} upright); \
             at most {} rows dropped at a step end; largest departure from the parallelogram branch {:.1e} rad",
            run.singular_passages,
            run.min_singular_angle,
            run.min_singular_value,
            up[52],
            run.max_dropped_rows,
            run.max_branch_deviation
        );
        let b0 = four_bar::b0(&run.end);
        println!("  B0(10 s) = ({:.6}, {:.6}) m", b0.x, b0.y);
        if h == 1e-3 {
            let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/plots");
            let x = ("B0 x".to_string(), run.samples.iter().map(|s| (s.t, s.b0.x)).collect());
            let y = ("B0 y".to_string(), run.samples.iter().map(|s| (s.t, s.b0.y)).collect());
            plot_lines(&dir.join("four_bar_b0.svg"), "N-four-bar (N = 4): point B0", ("t (s)", "m"), &[x, y])?;
            let e = (
                "(E − E0)/E0".to_string(),
                run.samples.iter().map(|s| (s.t, s.energy_error / run.initial_energy)).collect(),
            );
            plot_lines(&dir.join("four_bar_energy.svg"), "N-four-bar: energy error", ("t (s)", "relative"), &[e])?;
            println!("  plots: {}", dir.join("four_bar_{b0,energy}.svg").display());
            write_animation(&dir.join("four_bar"), &run.trajectory, "N-four-bar (N = 4), RK4 h = 1e-3")?;
        }
    }
    // A step that starts exactly on the singular position (16 rows dropped there).
    let run = four_bar::simulate(&scene, &flat, Integrator::Rk4, 1e-3, 2.0, 100)?;
    println!(
        "from exactly horizontal, turning at 1 rad/s, RK4 h = 1e-3, 2 s: {} passages, max |ΔE|/E0 = {:.2e}, \
         max |Φ| = {:.2e}, branch departure {:.1e} rad, at most {} rows dropped",
        run.singular_passages,
        run.max_relative_energy_error,
        run.max_constraint,
        run.max_branch_deviation,
        run.max_dropped_rows
    );
    Ok(())
}
