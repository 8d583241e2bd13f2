//! The integrator benchmark: `cargo run --release -p joint-examples --bin
//! stiff` from the repository root writes `report/stiff.md` and one
//! work–precision diagram per mechanism (`report/stiff-*.svg`); see
//! [`joint_examples::report::stiff`].

use std::fmt::Write as _;
use std::path::Path;
use std::process::ExitCode;

use joint_examples::report::simulation::{Series, plot_work_precision};
use joint_examples::report::stiff::{self, TARGET_ERROR, time_for};

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("stiff: {e}");
            ExitCode::FAILURE
        }
    }
}

fn run() -> Result<(), String> {
    let series = stiff::work_precision(&mut |line| eprintln!("{line}"))?;
    let out = Path::new("report");
    let mut md = String::from(
        "# Integrators on stiff and closed-loop mechanisms\n\n\
         `cargo run --release -p joint-examples --bin stiff` (one core; the module documentation of \
         `examples/src/report/stiff.rs` says what is run). Error: the largest `|r − r_ref| + |p − p_ref|` \
         of a body at the end, against Dormand–Prince at `rtol = atol = 1e-12`; time: the fastest of \
         repeated runs. Every run projects onto the constraints after each step. \"Time for error\" is the \
         cheapest run whose error is at most that.\n",
    );
    for group in ["press", "bricard", "double-cardan"] {
        let file = format!("stiff-{group}.svg");
        plot_work_precision(&series, group, &out.join(&file))?;
        let chosen: Vec<&Series> = series.iter().filter(|s| s.group == group).collect();
        let _ = write!(md, "\n## {group}\n\n![work–precision, {group}]({file})\n\n");
        let _ = writeln!(md, "| integrator | points (run time s, error) | time for error {TARGET_ERROR:.0e} |");
        let _ = writeln!(md, "|---|---|---|");
        for s in &chosen {
            let points: Vec<String> = s.points.iter().map(|(t, e)| format!("({t:.1e}, {e:.1e})")).collect();
            let at = time_for(s, TARGET_ERROR).map_or("not reached".to_string(), |t| format!("{t:.2e} s"));
            let _ = writeln!(md, "| {} | {} | {at} |", s.name, points.join(" "));
        }
        engines_table(&mut md, &chosen);
        // RK4's best time.
        let rk4 = chosen
            .iter()
            .filter(|s| s.name.starts_with("RK4"))
            .filter_map(|s| time_for(s, TARGET_ERROR))
            .min_by(f64::total_cmp);
        let best = chosen
            .iter()
            .filter(|s| !s.name.starts_with("RK4"))
            .filter_map(|s| time_for(s, TARGET_ERROR).map(|t| (t, s.name.as_str())))
            .min_by(|a, b| a.0.total_cmp(&b.0));
        if let (Some(r), Some((b, name))) = (rk4, best) {
            let _ = writeln!(
                md,
                "\nAt error {TARGET_ERROR:.0e}: RK4 with projection (its faster engine) {r:.2e} s, \
                 the fastest other ({name}) {b:.2e} s: {:.2} times RK4's time.",
                b / r
            );
        }
    }
    std::fs::write(out.join("stiff.md"), md).map_err(|e| format!("writing report/stiff.md: {e}"))?;
    eprintln!("wrote report/stiff.md");
    Ok(())
}

/// Each integrator's time for the target error in both coordinate
/// choices, and their ratio.
fn engines_table(md: &mut String, chosen: &[&Series]) {
    let _ = writeln!(md, "\n| integrator | absolute, time for {TARGET_ERROR:.0e} | relative | relative / absolute |");
    let _ = writeln!(md, "|---|---|---|---|");
    for s in chosen.iter().filter(|s| s.name.ends_with(", absolute")) {
        let base = s.name.trim_end_matches(", absolute");
        let other = chosen.iter().find(|r| r.name == format!("{base}, relative"));
        let (a, r) = (time_for(s, TARGET_ERROR), other.and_then(|r| time_for(r, TARGET_ERROR)));
        let show = |t: Option<f64>| t.map_or("not reached".to_string(), |t| format!("{t:.2e} s"));
        let ratio = match (a, r, other) {
            (_, _, None) => "not offered".to_string(),
            (Some(a), Some(r), _) => format!("{:.2}", r / a),
            _ => "–".to_string(),
        };
        let relative = if other.is_some() { show(r) } else { "not offered".to_string() };
        let _ = writeln!(md, "| {base} | {} | {relative} | {ratio} |", show(a));
    }
}
