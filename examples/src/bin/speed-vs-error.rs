//! The speed-against-error report: `cargo run --release -p joint-examples --bin
//! speed-vs-error` from the repository root.
//!
//! Measures the generated Φ, J and γ beside a hand-written implementation,
//! num-dual and central differences on the conformance vectors
//! ([`joint_examples::report::variants`]), runs the simulations' work–precision
//! diagrams ([`joint_examples::report::simulation`]), times the robots'
//! dynamics' derivatives exact and by differences
//! ([`joint_examples::report::derivatives`]), prints the summary tables
//! and writes `report/README.md` with the SVG figures.
//!
//! Options (`--help`): `--vectors DIR` (default: the repository's
//! `conformance/`, found from any directory), `--out DIR` (default `report`),
//! `--no-simulation` (the evaluation level only).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use clap::Parser;
use joint_examples::report::simulation::{self, Series};
use joint_examples::report::variants::{self, GroupResult};
use joint_tests::conformance::{self, VectorFile};

/// The command the README gives to reproduce the report.
const COMMAND: &str = "cargo run --release -p joint-examples --bin speed-vs-error";

/// Times the generated Φ, J and γ against a hand-written implementation,
/// num-dual and central differences on the conformance vectors, runs the
/// simulations' work–precision diagrams, and writes the report with its figures.
#[derive(Parser)]
#[command(name = "speed-vs-error")]
struct Options {
    /// Folder holding vectors.json and hard.json; the default is the repository's copy, found from any working directory
    #[arg(long, value_name = "DIR", default_value_os_t = conformance::vectors_dir())]
    vectors: PathBuf,
    /// Folder to write README.md and the SVG figures into
    #[arg(long, value_name = "DIR", default_value = "report")]
    out: PathBuf,
    /// Measure the evaluation level only, skipping the simulations' work–precision diagrams
    #[arg(long)]
    no_simulation: bool,
}

/// The CPU model and the number of logical cores, from `/proc/cpuinfo`.
fn machine() -> String {
    let info = std::fs::read_to_string("/proc/cpuinfo").unwrap_or_default();
    let model = info
        .lines()
        .find_map(|l| l.strip_prefix("model name").and_then(|r| r.split_once(':')).map(|(_, m)| m.trim().to_string()))
        .unwrap_or_else(|| "unknown CPU".into());
    let cores = info.lines().filter(|l| l.starts_with("processor")).count();
    let cores = if cores > 0 { cores } else { std::thread::available_parallelism().map(usize::from).unwrap_or(0) };
    format!("{model}, {cores} logical cores ({} {})", std::env::consts::OS, std::env::consts::ARCH)
}

fn read_vectors(dir: &Path) -> Result<Vec<VectorFile>, String> {
    ["vectors.json", "hard.json"].iter().map(|f| conformance::load(&dir.join(f))).collect()
}

/// The vectors folder as the README names it: relative to the repository when
/// inside it, so that the committed report names no machine's path.
fn shown(vectors: &Path) -> String {
    let ours = conformance::vectors_dir();
    let repository = ours.parent().unwrap_or(&ours);
    match vectors.strip_prefix(repository) {
        Ok(inside) => format!("`{}/` in the repository", inside.display()),
        Err(_) => format!("`{}`", vectors.display()),
    }
}

/// The figures of the evaluation level: file name, formulations, caption.
const FIGURES: [(&str, &[&str], &str); 3] = [
    ("speed-error-euler.svg", &["euler"], "euler: time against error of Φ, J, γ"),
    ("speed-error-omega.svg", &["omega_inertial", "omega_body"], "ω formulations: time against error of Φ, J, γ"),
    (
        "speed-error-relative.svg",
        &["relative_b1", "relative_b2"],
        "relative formulations: time against error of Φ, J, γ",
    ),
];

/// The summary section: the tables and what they say.
fn evaluation_section(results: &[GroupResult], cases: usize) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "## Evaluation level: Φ, J and γ of one joint\n\n\
         Every variant evaluates the same states — the {cases} cases of `vectors.json` and \
         `hard.json` for these joints and formulations, all parameters at run time — and is \
         checked against their 60-digit expected values. **Time**: median ns per evaluation of Φ, \
         J and γ together over those states (repetitions calibrated to 3 ms a sample, median of 15). \
         **Error**: worst `|error| / (ε · scale)` over the cases and over Φ, J and γ \
         (the conformance test's unit, tolerance 256); f32 in units of `ε₃₂ · scale`, `ε₃₂ = 2⁻²³`.\n\n\
         - *generated f64 / f32*: the derive's fused `evaluate` at `f64` and at `f32` (inputs rounded to f32).\n\
         - *hand-written*: `report::handwritten`, careful nalgebra code written from `CONVENTIONS.md`; \
           its samples alternate with the generated f64 code's, so that both see the same machine load.\n\
         - *num-dual*: forward-mode AD of the generated generic `phi`: one `DualSVec64<C>` pass (one \
           dual direction per velocity column: `∂Φ/∂q` for `euler`, the tangent of the exact \
           trajectory `r + ṙt`, `q(ωt) ⊗ p0` / `p0 ⊗ q(ω't)` for the others) gives Φ and J, one \
           `Dual2_64` pass along the exact trajectory with the state's velocities gives γ = −Φ̈.\n\
         - *central differences*: `2C + 3` evaluations of the generated `phi` (f64): \
           `J = (Φ(+h) − Φ(−h)) / 2h` per column along the same directions (exact rotations by ±h), \
           `γ = −(Φ(h) − 2Φ(0) + Φ(−h)) / h²` along the trajectory; steps 1e-2 … 1e-10, \
           the table shows the step with the smallest worst error (chosen after the fact, in favour \
           of the differences).\n"
    );
    let _ = writeln!(s, "### Time and error per variant\n\n{}", variants::main_table(results));
    let _ = writeln!(
        s,
        "![euler](speed-error-euler.svg)\n\n![ω](speed-error-omega.svg)\n\n![relative](speed-error-relative.svg)\n"
    );
    let _ = writeln!(
        s,
        "### Targets\n\nRatios against the generated f64 code (times: other ÷ generated; errors: \
         central differences at their best step ÷ generated, both the worst of Φ, J, γ). The \
         column *J alone* compares the Jacobian only, with the step that is best for J; it is \
         information, not a target: \
         a central difference balances truncation (∝ h²) against rounding (∝ ε/h), so even at its \
         best step J keeps an error of order ε^(2/3) ≈ 10⁵ ε relative to its scale, and this ratio \
         falls below 10⁶ wherever the generated J is accurate to a few ε.\n\n{}",
        variants::targets_table(results)
    );
    let misses = variants::misses(results);
    if misses.is_empty() {
        let _ = writeln!(s, "Every target is met.\n");
    } else {
        let _ = writeln!(s, "**Missed targets:**\n");
        for m in &misses {
            let _ = writeln!(s, "- {m}");
        }
        s.push('\n');
    }
    let _ = writeln!(
        s,
        "### Operation counts\n\nBinary + − × ÷ per call (negation free), generated (`Joint::OPS`) and hand-written (counted by running it on `report::counting::Counted`).\n\n{}",
        variants::ops_table(results)
    );
    let _ = writeln!(
        s,
        "### Errors of Φ, J and γ separately\n\nIn `ε · scale` (f32: `ε₃₂ · scale`). *Inexact zeros*: \
         entries that are zero for every input (scale 0) but came out nonzero — the conformance \
         test fails such a case outright; here they are measured against 1/64 of the largest \
         scale of their row and counted.\n\n{}",
        variants::error_table(results)
    );
    let _ = writeln!(
        s,
        "### Central differences: the error–step trade-off\n\nWorst J / γ error (ε·scale) at each \
         step: truncation (∝ h² for both) against rounding (∝ ε/h for J, ε/h² for γ).\n\n{}\n\
         ![central differences](fd-steps.svg)\n",
        variants::fd_table(results)
    );
    s
}

/// The simulation section and its figures.
fn simulation_section(series: &[Series], out: &Path) -> Result<String, String> {
    let mut s = String::from(
        "## Simulation level: work–precision\n\nRun time of a whole simulation against its error over a \
         range of step sizes, per integrator and stabilisation (`report::simulation`: the Cardan \
         shaft bent by 30° with its input driven at 10 rad/s, error in rad against the closed form; Bricard's \
         mechanism in free motion, error in m against a fine reference).\n\n",
    );
    let mut groups: Vec<&str> = Vec::new();
    for x in series {
        if !groups.contains(&x.group.as_str()) {
            groups.push(&x.group);
        }
    }
    for group in groups {
        let file = format!("work-precision-{group}.svg");
        simulation::plot_work_precision(series, group, &out.join(&file))?;
        let _ = writeln!(s, "### `{group}`\n\n![{group}]({file})\n");
        let _ =
            writeln!(s, "| series | points | fastest: time, error | most accurate: time, error |\n|---|---|---|---|");
        for x in series.iter().filter(|x| x.group == group) {
            let fastest = x.points.iter().min_by(|a, b| a.0.total_cmp(&b.0));
            let best = x.points.iter().min_by(|a, b| a.1.total_cmp(&b.1));
            let cell = |p: Option<&(f64, f64)>| p.map_or("—".into(), |(t, e)| format!("{:.3} ms, {e:.2e}", t * 1e3));
            let _ = writeln!(s, "| {} | {} | {} | {} |", x.name, x.points.len(), cell(fastest), cell(best));
        }
        s.push('\n');
    }
    Ok(s)
}

fn run(o: &Options) -> Result<(), String> {
    let start = Instant::now();
    let mut progress = |what: &str| eprintln!("[{:6.1} s] {what}", start.elapsed().as_secs_f64());
    progress(&format!("reading {}", o.vectors.display()));
    let docs = read_vectors(&o.vectors)?;
    let results = variants::measure_all(&docs, &mut progress)?;
    let cases: usize = results.iter().map(|g| g.cases).sum();
    std::fs::create_dir_all(&o.out).map_err(|e| format!("creating {}: {e}", o.out.display()))?;
    for (file, forms, caption) in FIGURES {
        variants::plot_speed_error(&results, forms, caption, &o.out.join(file))?;
    }
    variants::plot_fd_steps(&results, &o.out.join("fd-steps.svg"))?;
    let evaluation = evaluation_section(&results, cases);
    let evaluation_time = start.elapsed().as_secs_f64();
    progress("robot level: the dynamics' derivatives");
    let robots = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/data/robots");
    let derivative_rows = joint_examples::report::derivatives::measure(&robots)?;
    let mut derivatives = joint_examples::report::derivatives::section(&derivative_rows);
    progress("robot level: a stiff arm at its own step");
    derivatives += &joint_examples::report::stiff_robot::section(&joint_examples::report::stiff_robot::measure());

    let simulation = if !o.no_simulation {
        progress("simulation level: work–precision diagrams");
        let series = simulation::work_precision(&mut progress);
        Some(simulation_section(&series, &o.out)?)
    } else {
        None
    };
    let total = start.elapsed().as_secs_f64();

    let mut readme = format!(
        "# Speed against error: generated code and the alternatives\n\n\
         Written by `{COMMAND}` (from the repository root; the conformance vectors are read from \
         {}).\n\n\
         - Machine: {}, one thread.\n\
         - Build: release (`[profile.release]` of the workspace).\n\
         - Run time: {total:.0} s ({evaluation_time:.0} s for the evaluation level).\n\n",
        shown(&o.vectors),
        machine(),
    );
    readme += &evaluation;
    readme += &derivatives;
    if let Some(sim) = &simulation {
        readme += sim;
    }
    let path = o.out.join("README.md");
    std::fs::write(&path, &readme).map_err(|e| format!("writing {}: {e}", path.display()))?;

    println!("{}", variants::main_table(&results));
    println!("{}", variants::targets_table(&results));
    println!("{}", variants::ops_table(&results));
    println!("{derivatives}");
    let misses = variants::misses(&results);
    if misses.is_empty() {
        println!("Every target is met.");
    } else {
        println!("Missed targets:");
        for m in &misses {
            println!("- {m}");
        }
    }
    println!("\nwrote {} and its figures in {total:.0} s", path.display());
    Ok(())
}

fn main() -> ExitCode {
    // clap exits by itself: 0 for --help, 2 for a bad command line.
    let options = Options::parse();
    match run(&options) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("speed-vs-error: {e}");
            ExitCode::FAILURE
        }
    }
}
