//! The Solo12 from its URDF file standing on its four feet, shifting its
//! weight, lifting and putting down its front left foot under a controller
//! that uses the constrained dynamics' exact derivatives
//! (`joint_examples::solo_stance`): the feet's forces as CSV and a plot, and
//! the run in 3D as `target/plots/solo_stance.glb` with a page that plays
//! it, whose path it prints last.
//!
//! ```text
//! cargo run --release -p joint-examples --example solo_stance
//! ```

use std::error::Error;
use std::path::Path;

use joint_examples::bricard::plot_lines;
use joint_examples::solo_stance;

fn main() -> Result<(), Box<dyn Error>> {
    let timer = std::time::Instant::now();
    let run = solo_stance::simulate(3.0, 1e-3).map_err(|e| format!("{e:?}"))?;
    let elapsed = timer.elapsed();
    println!(
        "Solo12 (URDF, floating, 4 point contacts) at 1 kHz: stand, shift, lift the front left foot, put it down:"
    );
    for t in [0.0, 0.3, 1.0, 1.3, 1.6, 2.2, 3.0] {
        let s = run.samples.iter().min_by(|a, b| (a.t - t).abs().total_cmp(&(b.t - t).abs())).ok_or("no samples")?;
        let z: Vec<String> = s.forces.iter().map(|f| format!("{:6.2}", f.z)).collect();
        println!(
            "  t = {:4.2} s: feet's vertical forces [{}] N, front left foot at z = {:+.3} m",
            s.t,
            z.join(", "),
            s.feet[0].z
        );
    }
    println!(
        "  {} steps in {:.1} ms ({:.1} µs a step: the controller's exact derivatives, the dynamics, the step); \
         touchdown jump {:.3}",
        run.samples.len() - 1,
        elapsed.as_secs_f64() * 1e3,
        elapsed.as_secs_f64() * 1e6 / (run.samples.len() - 1) as f64,
        run.touchdown_jump
    );
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/plots");
    std::fs::create_dir_all(&dir)?;
    let csv = dir.join("solo_stance.csv");
    solo_stance::write_csv(&run, std::fs::File::create(&csv)?)?;
    let plot = dir.join("solo_stance_forces.svg");
    let curves: Vec<_> = ["front left", "front right", "hind left", "hind right"]
        .iter()
        .enumerate()
        .map(|(f, name)| (format!("{name} foot, z"), run.samples.iter().map(|s| (s.t, s.forces[f].z)).collect()))
        .collect();
    plot_lines(&plot, "Solo12: the ground's vertical force on each foot", ("t (s)", "N"), &curves)?;
    println!("CSV: {}\nplot: {}", csv.display(), plot.display());
    let run3d = joint_examples::write_animation(&dir.join("solo_stance"), &run.trajectory, "Solo12: a foot lifted")?;
    println!("{}", run3d.page.canonicalize().unwrap_or(run3d.page).display());
    Ok(())
}
