//! The Panda from its URDF file holding a pose under a PD controller with
//! gravity compensation (`joint_examples::panda`): the tracking error as
//! it settles, a CSV and a plot of the error, and the run in 3D (the arm's
//! own meshes) as `target/plots/panda_pd.glb` with a page that plays it,
//! whose path it prints last.
//!
//! ```text
//! cargo run --release -p joint-examples --example panda_pd
//! ```

use std::error::Error;
use std::path::Path;

use joint_examples::bricard::plot_lines;
use joint_examples::panda;

fn main() -> Result<(), Box<dyn Error>> {
    let timer = std::time::Instant::now();
    let run = panda::simulate(3.0, 1e-3).map_err(|e| format!("{e:?}"))?;
    let elapsed = timer.elapsed();
    println!("Panda (URDF, 9 joints) from the ready pose to a target, PD + gravity compensation at 1 kHz:");
    for t in [0.0, 0.1, 0.25, 0.5, 1.0, 2.0, 3.0] {
        let s = run.samples.iter().min_by(|a, b| (a.t - t).abs().total_cmp(&(b.t - t).abs())).ok_or("no samples")?;
        println!("  t = {:4.2} s: largest joint error {:.2e}, V = {:.3e} J", s.t, s.error, s.lyapunov);
    }
    let clamped = run.samples.iter().filter(|s| s.clamped).count();
    println!(
        "  {} steps in {:.1} ms ({:.2} µs a step with the controller); {clamped} steps with a torque at its effort limit",
        run.samples.len() - 1,
        elapsed.as_secs_f64() * 1e3,
        elapsed.as_secs_f64() * 1e6 / (run.samples.len() - 1) as f64
    );
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/plots");
    std::fs::create_dir_all(&dir)?;
    let csv = dir.join("panda_pd.csv");
    panda::write_csv(&run, std::fs::File::create(&csv)?)?;
    let tracking = dir.join("panda_pd_error.svg");
    let error = ("largest |q* − q|".to_string(), run.samples.iter().map(|s| (s.t, s.error)).collect());
    plot_lines(&tracking, "Panda: PD + gravity compensation, tracking error", ("t (s)", "rad or m"), &[error])?;
    println!("CSV: {}\nplot: {}", csv.display(), tracking.display());
    let timer = std::time::Instant::now();
    let run3d =
        joint_examples::write_animation(&dir.join("panda_pd"), &run.trajectory, "Panda: PD + gravity compensation")?;
    println!(
        "  (.glb and page written in {:.0} ms, the mesh files read included)",
        timer.elapsed().as_secs_f64() * 1e3
    );
    println!("{}", run3d.page.canonicalize().unwrap_or(run3d.page).display());
    Ok(())
}
