//! The double Cardan shaft: input, intermediate and output shafts, two universal
//! joints, in the Z arrangement (input and output parallel, offset) and the W
//! arrangement (input and output meeting at 2β). With the intermediate shaft's
//! yokes in phase the output turns at exactly the input speed; a quarter turn out
//! of phase, the two joints' fluctuations multiply:
//! `ω_o/ω₁ = cos²β / (1 − (1 − cos⁴β) cos²φ₁)`. A plot of the output speeds and
//! an animation of the Z shaft (`target/plots/double-cardan.svg`).
//!
//! ```text
//! cargo run --release -p joint-examples --example double_cardan
//! ```

use joint_examples::cardan::{Curve, plot_speed_ratios};
use joint_examples::double_cardan::{self, Arrangement, Phasing, Sweep};
use joint_examples::write_animation;

const STEPS: usize = 360;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let speed = 2.0 * std::f64::consts::PI;
    let bends = [10.0f64, 30.0, 60.0];
    let mut sweeps: Vec<Sweep> = Vec::new();
    for arrangement in [Arrangement::Z, Arrangement::W] {
        for phasing in [Phasing::InPhase, Phasing::Quarter] {
            for d in bends {
                sweeps.push(double_cardan::sweep(d.to_radians(), arrangement, phasing, speed, STEPS)?);
            }
        }
    }

    println!("Double Cardan shaft: input at 1 turn/s, {STEPS} input angles; assemble + velocity analysis at each.");
    println!("Closed forms: in phase φ_o = φ₁, ω_o = ω₁; a quarter turn out of phase");
    println!("ω_o/ω₁ = [cos β/(1 − sin²β cos²φ₁)]·[cos β/(1 − sin²β cos²φ_m)] = cos²β/(1 − (1 − cos⁴β) cos²φ₁).");
    println!("Errors cover both the intermediate and the output shaft.\n");
    print_table(&sweeps);
    let worst_formula = sweeps.iter().map(|s| s.max_formula_difference).fold(0.0, f64::max);
    println!("\nProduct of the two single-joint ratios vs the one-line formula: max difference {worst_formula:.1e}.");
    let sizes: std::collections::BTreeSet<usize> =
        sweeps.iter().flat_map(|s| s.redundant_variants.iter().map(Vec::len)).collect();
    println!(
        "Redundant rows: 19 rows, 18 columns, no freedom: one redundant row in every sweep (sizes seen: {sizes:?}).\n\
         The bearings fix both joint centres, and the crosses' spherical rows pin the intermediate\n\
         shaft's ends to them: its length |AB| is imposed twice. The pivoted Cholesky drops one\n\
         translational (spherical) row (joint#row above; which one depends on the pivoting).\n\
         A real double Cardan shaft has a sliding spline in its intermediate shaft for this reason."
    );

    // The plot: Z arrangement as lines, W as markers on top (the kinematics is the same).
    let curves = speed_curves(&sweeps);
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/plots/double-cardan-speed.svg");
    plot_speed_ratios(&path, "Double Cardan shaft: output speed over one input turn", &curves)?;
    println!("\nplot: {}", path.canonicalize().unwrap_or_else(|_| path.clone()).display());
    // The Z arrangement bent by 30°, yokes in phase, its yokes marked.
    let shown = sweeps
        .iter()
        .find(|s| {
            let g = s.geometry;
            (g.arrangement, g.phasing) == (Arrangement::Z, Phasing::InPhase)
                && (g.bend.to_degrees() - 30.0).abs() < 1e-9
        })
        .ok_or("no Z, in-phase, 30° sweep")?;
    let mut run = shown.trajectory.clone();
    joint_examples::cardan::mark_yokes(&mut run, 0, &[1, 2]);
    let title = "Double Cardan shaft (Z, in phase, 30°), one input turn per second";
    write_animation(&path.with_file_name("double-cardan"), &run, title)?;
    Ok(())
}

/// One row per sweep: the errors against the closed forms, the extreme speed
/// ratios beside theirs, and the redundant rows.
fn print_table(sweeps: &[Sweep]) {
    println!(
        "{:>3} {:>8} {:>4}  {:>11}  {:>11}  {:>11}  {:>10}  {:>10}  {:>10}  {:>10}  {:>9}",
        "arr",
        "yokes",
        "β",
        "max |Δφ|",
        "max |Δω|",
        "max|ω_o−ω₁|",
        "min ω_o/ω₁",
        "closed",
        "max ω_o/ω₁",
        "closed",
        "redundant"
    );
    for s in sweeps {
        let g = &s.geometry;
        let c2 = g.bend.cos().powi(2);
        let (lo, hi) = match g.phasing {
            Phasing::InPhase => (1.0, 1.0),
            Phasing::Quarter => (c2, 1.0 / c2),
        };
        println!(
            "{:>3} {:>8} {:>3.0}°  {:>11.2e}  {:>11.2e}  {:>11.2e}  {:>10.6}  {:>10.6}  {:>10.6}  {:>10.6}  {:>9}",
            format!("{:?}", g.arrangement),
            match g.phasing {
                Phasing::InPhase => "in phase",
                Phasing::Quarter => "90°",
            },
            g.bend.to_degrees(),
            s.max_angle_error,
            s.max_speed_error,
            s.max_output_fluctuation,
            s.min_ratio,
            lo,
            s.max_ratio,
            hi,
            s.redundant.iter().map(|r| format!("{}#{}", r.joint, r.joint_row)).collect::<Vec<_>>().join(",")
        );
    }
}

/// The speed ratio over one input turn: one in-phase curve of each
/// arrangement (they are all ω_o/ω₁ = 1), every out-of-phase one.
fn speed_curves(sweeps: &[Sweep]) -> Vec<Curve> {
    let mut curves = Vec::new();
    for s in sweeps {
        let g = &s.geometry;
        let label = format!(
            "{:?}, {}, β = {:.0}°",
            g.arrangement,
            match g.phasing {
                Phasing::InPhase => "in phase",
                Phasing::Quarter => "90° out of phase",
            },
            g.bend.to_degrees()
        );
        // The in-phase curves are all the line ω_o/ω₁ = 1: draw one of each arrangement.
        if g.phasing == Phasing::InPhase && g.bend.to_degrees().round() != 30.0 {
            continue;
        }
        curves.push(Curve {
            label,
            points: s.samples.iter().map(|x| (x.input_angle.to_degrees(), x.output_speed / s.input_speed)).collect(),
            markers: g.arrangement == Arrangement::W,
        });
    }
    curves
}
