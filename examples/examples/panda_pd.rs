//! The Panda from its URDF file holding a pose under a PD controller with
//! gravity compensation (`joint_examples::panda`): the tracking error as
//! it settles, an animation and a CSV in `target/plots/`.
//!
//! ```text
//! cargo run --release --example panda_pd
//! ```

use std::error::Error;
use std::path::Path;

use joint_examples::panda;
use joint_runtime::record::{SvgOptions, View};

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
    let options = SvgOptions::default()
        .with_view(View::isometric())
        .with_size(1000, 640)
        .with_title("Panda: PD + gravity compensation");
    let svg = dir.join("panda_pd.svg");
    joint_examples::write_animation(&svg, &run.trajectory, &options)?;
    let csv = dir.join("panda_pd.csv");
    panda::write_csv(&run, std::fs::File::create(&csv)?)?;
    for (name, index) in [("start", 0), ("end", run.trajectory.samples().len().saturating_sub(1))] {
        if let Some(still) = run.trajectory.svg_frame(index, &options) {
            std::fs::write(dir.join(format!("panda_pd_{name}.svg")), still)?;
        }
    }
    println!("animation: {}\nCSV: {}", svg.display(), csv.display());
    Ok(())
}
