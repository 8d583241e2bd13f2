//! iLQR on exact derivatives (`joint_examples::ilqr`): the Panda from its
//! URDF file reaching a target, and an acrobot swinging up on its elbow
//! alone. Prints the cost per iteration and the time per iteration with
//! exact step Jacobians and with central differences; writes the cost
//! against iteration (`target/plots/ilqr_cost.svg`) and both motions as
//! animations (`target/plots/ilqr_panda.svg`, `ilqr_acrobot.svg`).
//!
//! ```text
//! cargo run --release -p joint-examples --example ilqr
//! ```

use std::error::Error;
use std::path::Path;

use joint_examples::ilqr::{self, Acrobot, Derivatives, PandaArm, Solution};
use joint_runtime::record::Trajectory;
use joint_runtime::relative::TreeSimulation;

fn report<const NV: usize>(name: &str, exact: &Solution<NV>, differenced: &Solution<NV>) {
    println!("{name}: cost {:.4e} at the first guess", exact.initial_cost);
    for (k, i) in exact.iterations.iter().enumerate() {
        println!("  iteration {:3}: cost {:.6e} (step {:.4})", k + 1, i.cost, i.alpha);
    }
    let mean = |s: &Solution<NV>, f: &dyn Fn(&ilqr::Iteration) -> f64| {
        s.iterations.iter().map(f).sum::<f64>() / s.iterations.len().max(1) as f64 * 1e3
    };
    println!(
        "  per iteration: {:.2} ms with exact step Jacobians ({:.2} ms of it the Jacobians), {:.2} ms with central \
         differences ({:.2} ms of it the differences); cost after {} iterations: {:.6e} exact, {:.6e} differenced",
        mean(exact, &|i| i.seconds),
        mean(exact, &|i| i.derivative_seconds),
        mean(differenced, &|i| i.seconds),
        mean(differenced, &|i| i.derivative_seconds),
        differenced.iterations.len(),
        exact.iterations.get(differenced.iterations.len().saturating_sub(1)).map_or(f64::NAN, |i| i.cost),
        differenced.cost(),
    );
}

fn plot(path: &Path, runs: &[(&str, Vec<f64>)]) -> Result<(), Box<dyn Error>> {
    use plotters::prelude::*;
    let root = SVGBackend::new(path, (900, 520)).into_drawing_area();
    root.fill(&WHITE)?;
    let most = runs.iter().map(|(_, c)| c.len()).max().unwrap_or(1);
    let (lo, hi) =
        runs.iter().flat_map(|(_, c)| c.iter()).fold((f64::INFINITY, 0.0_f64), |(a, b), &c| (a.min(c), b.max(c)));
    let mut chart = ChartBuilder::on(&root)
        .caption("iLQR on exact step Jacobians: cost against iteration", ("sans-serif", 20))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d(0..most, (lo * 0.5..hi * 2.0).log_scale())?;
    chart.configure_mesh().x_desc("iteration").y_desc("cost (relative to the first guess)").draw()?;
    for (k, (name, costs)) in runs.iter().enumerate() {
        let color = Palette99::pick(k).to_rgba();
        chart
            .draw_series(LineSeries::new(costs.iter().enumerate().map(|(i, c)| (i, *c)), color.stroke_width(2)))?
            .label(*name)
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], color.stroke_width(2)));
    }
    chart.configure_series_labels().border_style(BLACK).background_style(WHITE).draw()?;
    root.present()?;
    Ok(())
}

fn main() -> Result<(), Box<dyn Error>> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/plots");
    std::fs::create_dir_all(&dir)?;
    let err = |e: joint_runtime::relative::TreeError| e.to_string();

    let mut sim = TreeSimulation::new(&PandaArm)?;
    let problem = ilqr::panda_problem(&sim);
    let panda = ilqr::solve(&mut sim, &problem, 30, Derivatives::Exact).map_err(err)?;
    let panda_fd = ilqr::solve(&mut sim, &problem, 5, Derivatives::Differences).map_err(err)?;
    report("Panda (URDF, 9 joints), READY to TARGET in 1 s", &panda, &panda_fd);
    let end = panda.states.last().ok_or("no states")?;
    println!(
        "  at 1 s: largest joint error {:.2e} rad, largest rate {:.2e} rad/s",
        (end.q - problem.target.0).amax(),
        end.v.amax()
    );

    let mut sim = TreeSimulation::new(&Acrobot)?;
    let problem = ilqr::acrobot_problem();
    let acrobot = ilqr::solve(&mut sim, &problem, 150, Derivatives::Exact).map_err(err)?;
    let acrobot_fd = ilqr::solve(&mut sim, &problem, 5, Derivatives::Differences).map_err(err)?;
    report("Acrobot (elbow driven), hanging to upright in 4 s", &acrobot, &acrobot_fd);
    let end = acrobot.states.last().ok_or("no states")?;
    println!(
        "  at 4 s: angles off upright by {:.2e} rad, rates {:.2e} rad/s; largest elbow torque {:.1} N m",
        (end.q - problem.target.0).amax(),
        end.v.amax(),
        acrobot.controls.iter().map(|u| u[0].abs()).fold(0.0, f64::max)
    );

    let relative = |s: &Solution<9>| s.iterations.iter().map(|i| i.cost / s.initial_cost).collect::<Vec<_>>();
    let relative2 = |s: &Solution<2>| s.iterations.iter().map(|i| i.cost / s.initial_cost).collect::<Vec<_>>();
    let cost_svg = dir.join("ilqr_cost.svg");
    plot(&cost_svg, &[("Panda", relative(&panda)), ("acrobot", relative2(&acrobot))])?;

    // The optimised motions, drawn through the scenes' absolute coordinates.
    let recorder = TreeSimulation::new(&joint_examples::panda::Panda)?;
    let mut movie = Trajectory::new(&joint_examples::panda::Panda);
    for s in &panda.states {
        movie.record(&recorder.system_state(s));
    }
    joint_examples::write_animation(&dir.join("ilqr_panda"), &movie, "Panda: iLQR reach")?;
    let mut movie = Trajectory::new(&Acrobot);
    for s in acrobot.states.iter().step_by(2) {
        movie.record(&sim.system_state(s));
    }
    joint_examples::write_animation(&dir.join("ilqr_acrobot"), &movie, "Acrobot: iLQR swing-up")?;
    println!("cost plot: {}", cost_svg.display());
    Ok(())
}
