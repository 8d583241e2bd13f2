//! A steering column turned through a full turn of the wheel: the pinion angle
//! from the assembled mechanism against two Cardan relations composed, the
//! intermediate shaft's length, and the same with the column's reach adjusted.
//! Writes `target/plots/steering.svg`.
//!
//! ```text
//! cargo run --release -p joint-examples --example steering
//! ```

use std::error::Error;
use std::path::Path;

use joint_examples::steering::{SteeringColumn, compare_split, sweep};
use joint_runtime::Ramp;
use plotters::prelude::*;

fn main() -> Result<(), Box<dyn Error>> {
    let rate = 1.0;
    let s = sweep(0.0, rate, 360)?;
    let g = s.geometry;
    println!("Steering column: wheel shaft —Cardan— intermediate shaft —Cardan with sliding (UT)— pinion shaft");
    println!(
        "bends {:.2}° (upper) and {:.2}° (lower), intermediate shaft {:.6} m between the joint centres",
        g.bend_upper.to_degrees(),
        g.bend_lower.to_degrees(),
        g.length
    );
    let blocks: Vec<String> = SteeringColumn::<Ramp>::BLOCKS
        .iter()
        .map(|b| format!("{} ({} {})", b.name, b.rows, if b.rows == 1 { "row" } else { "rows" }))
        .collect();
    println!("joints: {}", blocks.join(", "));
    println!(
        "closed-form branch: {} (the assembled pinion is {} the closed form's yoke)",
        s.branch,
        if s.branch == 0 { "on" } else { "half a turn from" }
    );
    println!();
    println!(
        "{:>9} {:>12} {:>14} {:>11} {:>11} {:>12} {:>9}",
        "input °", "output °", "closed form °", "error rad", "rate ratio", "length m", "slide m"
    );
    for x in s.samples.iter().step_by(15) {
        println!(
            "{:>9.1} {:>12.6} {:>14.6} {:>11.2e} {:>11.6} {:>12.9} {:>9.6}",
            x.input.to_degrees(),
            x.output.to_degrees(),
            x.closed.to_degrees(),
            x.error,
            x.rate / rate,
            x.length,
            x.slide
        );
    }
    println!();
    println!("over 360 steps of 1°:");
    println!("  max |pinion angle − closed form|        = {:.3e} rad", s.max_error());
    println!("  max |pinion rate − closed form|         = {:.3e} rad/s", s.max_rate_error());
    println!("  max |pinion acceleration − closed form| = {:.3e} rad/s²", s.max_accel_error());
    println!("  max |length − joint-centre distance|    = {:.3e} m", s.max_length_error());
    println!("  redundant rows: {}", if s.redundant.is_empty() { "none".to_string() } else { s.redundant.to_string() });

    println!();
    println!("reach adjustment (the column moved along its axis; the intermediate shaft telescopes):");
    println!(
        "{:>8} {:>12} {:>10} {:>10} {:>11} {:>11}",
        "reach m", "length m", "bend 1 °", "bend 2 °", "max error", "rate error"
    );
    for reach in [-0.05, -0.02, 0.0, 0.03, 0.06] {
        let r = sweep(reach, rate, 72)?;
        println!(
            "{:>8.3} {:>12.9} {:>10.3} {:>10.3} {:>11.2e} {:>11.2e}",
            reach,
            r.geometry.length,
            r.geometry.bend_upper.to_degrees(),
            r.geometry.bend_lower.to_degrees(),
            r.max_error(),
            r.max_rate_error()
        );
    }
    let c = compare_split(0.0, rate, 360)?;
    println!();
    println!("against the split model (lower half a body: translational spline + universal joint, 4 bodies, 24 rows):");
    println!(
        "  max differences: angle {:.3e} rad, rate {:.3e} rad/s, acceleration {:.3e} rad/s², length {:.3e} m",
        c.angle, c.rate, c.accel, c.length
    );

    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/plots/steering.svg");
    plot(&s, &path)?;
    // The wheel turned once: the shafts' axes bend, the intermediate shaft telescopes.
    joint_examples::write_animation(
        &path.with_file_name("steering"),
        &s.trajectory,
        "Steering column, one turn of the wheel",
    )?;
    Ok(())
}

/// The pinion's lead over the wheel (degrees) and the speed ratio, mechanism
/// (points) against the closed form (line).
fn plot(s: &joint_examples::steering::Sweep, path: &Path) -> Result<(), Box<dyn Error>> {
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir)?;
    }
    let first = s.samples.first().ok_or("no samples")?;
    let lead = |output: f64, input: f64| (output - first.output - input).to_degrees();
    let root = SVGBackend::new(path, (900, 520)).into_drawing_area();
    root.fill(&WHITE)?;
    let (lo, hi) = s.samples.iter().fold((f64::MAX, f64::MIN), |(a, b), x| {
        let y = lead(x.output, x.input);
        (a.min(y), b.max(y))
    });
    let pad = 0.1 * (hi - lo);
    let mut chart = ChartBuilder::on(&root)
        .caption("Steering column: pinion lead over the wheel", ("sans-serif", 20))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(55)
        .build_cartesian_2d(0.0..360.0, (lo - pad)..(hi + pad))?;
    chart.configure_mesh().x_desc("steering angle (°)").y_desc("pinion − wheel angle (°)").draw()?;
    chart
        .draw_series(LineSeries::new(
            s.samples.iter().map(|x| (x.input.to_degrees(), lead(x.closed, x.input))),
            BLUE.stroke_width(2),
        ))?
        .label("two Cardan relations composed (closed form)")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLUE));
    chart
        .draw_series(
            s.samples
                .iter()
                .step_by(6)
                .map(|x| Circle::new((x.input.to_degrees(), lead(x.output, x.input)), 3, RED.filled())),
        )?
        .label("assembled mechanism")
        .legend(|(x, y)| Circle::new((x + 10, y), 3, RED.filled()));
    chart.configure_series_labels().background_style(WHITE.mix(0.8)).border_style(BLACK).draw()?;
    root.present()?;
    println!("plot: {}", path.display());
    Ok(())
}
