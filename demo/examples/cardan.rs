//! The Cardan shaft, the project's main example: an input shaft driven at
//! constant speed in its bearing, a universal joint, and an output shaft in a
//! bearing bent by β. Kinematic analysis over one turn for β = 10°, 30°, 60°, 85°
//! against the closed form `tan φ₂ = tan φ₁ / cos β`, the redundant rows the
//! analysis finds, a plot of the output speed and an animation of the 60° shaft
//! (`target/plots/cardan.svg`).
//!
//! ```text
//! cargo run --release --example cardan
//! ```

use joint_demo::cardan::{self, Curve, Sweep, plot_speed_ratios};
use joint_demo::write_animation;

const STEPS: usize = 360;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let speed = 2.0 * std::f64::consts::PI; // one turn per second
    let bends = [10.0f64, 30.0, 60.0, 85.0];
    let mut sweeps: Vec<Sweep> = Vec::new();
    for d in bends {
        sweeps.push(cardan::sweep(d.to_radians(), speed, STEPS)?);
    }

    println!("Cardan shaft: input at 1 turn/s ({speed:.4} rad/s), {STEPS} input angles per turn;");
    println!("at each: set t, predict, assemble (Newton), velocity analysis; compare with");
    println!("tan φ₂ = tan φ₁ / cos β and ω₂/ω₁ = cos β / (1 − sin²β cos²φ₁).\n");
    println!(
        "{:>5}  {:>13}  {:>15}  {:>10}  {:>10}  {:>10}  {:>10}  {:>10}",
        "β", "max |Δφ₂| rad", "max |Δω₂| rad/s", "min ω₂/ω₁", "cos β", "max ω₂/ω₁", "1/cos β", "Newton it"
    );
    for (d, s) in bends.iter().zip(&sweeps) {
        let iterations: usize = s.samples.iter().map(|x| x.iterations).sum();
        println!(
            "{:>4}°  {:>13.2e}  {:>15.2e}  {:>10.6}  {:>10.6}  {:>10.6}  {:>10.6}  {:>10.2}",
            d,
            s.max_angle_error,
            s.max_speed_error,
            s.min_ratio,
            s.bend.cos(),
            s.max_ratio,
            1.0 / s.bend.cos(),
            iterations as f64 / s.samples.len() as f64
        );
    }

    println!("\nJoint rows: {}", describe_blocks());
    for s in &sweeps {
        let first: Vec<String> = s.redundant.iter().map(|r| format!("{}#{}", r.joint, r.joint_row)).collect();
        let sizes: std::collections::BTreeSet<usize> = s.redundant_variants.iter().map(Vec::len).collect();
        println!(
            "Redundant rows, β = {:>2.0}°: {} at φ₁ = 0; {} different choices over the turn, of sizes {:?}",
            s.bend.to_degrees(),
            first.join(", "),
            s.redundant_variants.len(),
            sizes
        );
    }
    println!(
        "(joint#row counts from 0; rows 0-2 of a revolute or universal joint are its spherical rows.)\n\
         15 rows, 12 columns and no freedom left: rank 12, so 3 rows are redundant. Both bearing\n\
         axes pass through the joint centre, so the bearings already keep each shaft's end at\n\
         the centre, and the cross's three spherical rows repeat them (its fourth row, the\n\
         yokes' perpendicularity, is what couples the shafts). The pivoted Cholesky keeps the\n\
         cross's rows and drops three of the bearings' spherical rows, which three depending on\n\
         the pivoting at each configuration; they are consistent, so every analysis succeeds."
    );

    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/plots/cardan-speed.svg");
    let curves: Vec<Curve> = sweeps
        .iter()
        .map(|s| Curve {
            label: format!("β = {:.0}°", s.bend.to_degrees()),
            points: s.samples.iter().map(|x| (x.input_angle.to_degrees(), x.output_speed / s.input_speed)).collect(),
            markers: false,
        })
        .collect();
    plot_speed_ratios(&path, "Cardan shaft: output speed over one input turn", &curves)?;
    println!("\nplot: {}", path.canonicalize().unwrap_or_else(|_| path.clone()).display());
    // The 60° shaft turning, its yokes marked (points on the axes alone would not show the spin).
    let shown = sweeps.iter().find(|s| (s.bend.to_degrees() - 60.0).abs() < 1e-9).ok_or("no 60° sweep")?;
    let mut run = shown.trajectory.clone();
    cardan::mark_yokes(&mut run, 0, &[1]);
    write_animation(&path.with_file_name("cardan"), &run, "Cardan shaft bent by 60°, one input turn per second")?;
    Ok(())
}

fn describe_blocks() -> String {
    cardan::blocks()
        .iter()
        .map(|b| format!("{} {}..{}", b.name, b.start, b.start + b.rows))
        .collect::<Vec<_>>()
        .join(", ")
}
