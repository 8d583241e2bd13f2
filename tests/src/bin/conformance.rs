//! The conformance runner (see the conformance README, `conformance/` in the
//! repository).
//!
//! ```text
//! cargo run --release -p joint-tests --bin conformance -- [FILE] [--joints a,b] [--emit OUT] [--time]
//! ```
//! FILE defaults to the repository's `conformance/vectors.json`, found from the
//! package's manifest directory, so the runner works from any directory.
//! Exit codes: 0 when every case passes, 1 when one fails or a joint has no
//! generated code, 2 for a bad command line or an unreadable or malformed file.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::Parser;
use joint_tests::conformance::{self, TOLERANCE};

/// Evaluates conformance vectors through the derive-generated code and applies
/// the accuracy test (worst error per joint and formulation, in ε·scale).
#[derive(Parser)]
#[command(name = "conformance")]
struct Args {
    /// Vectors file to run; the default is the repository's copy, found from any working directory
    #[arg(value_name = "FILE", default_value_os_t = conformance::vectors_dir().join("vectors.json"))]
    file: PathBuf,
    /// Run only these joints (comma-separated, e.g. universal,revolute)
    #[arg(long, value_name = "a,b,c", value_delimiter = ',')]
    joints: Option<Vec<String>>,
    /// Write the computed Φ, J and γ of every case to OUT as JSON
    #[arg(long, value_name = "OUT")]
    emit: Option<PathBuf>,
    /// Also time the fused evaluation per joint and formulation (TIME and OPS lines)
    #[arg(long)]
    time: bool,
}

fn main() -> ExitCode {
    // clap exits by itself: 0 for --help, 2 for a bad command line.
    let args = Args::parse();
    let file = args.file;
    let doc = match conformance::load(&file) {
        Ok(d) => d,
        Err(e) => {
            eprintln!("conformance: {e}");
            return ExitCode::from(2);
        }
    };
    let summary = match conformance::run(&doc, args.joints.as_deref(), args.time) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("conformance: {e}");
            return ExitCode::from(2);
        }
    };
    print_summary(&file, &summary);
    if let Some(path) = args.emit {
        let text = serde_json::to_string_pretty(&conformance::Emitted { cases: &summary.outputs }).unwrap_or_default();
        if let Err(e) = std::fs::write(&path, text) {
            eprintln!("conformance: cannot write `{}`: {e}", path.display());
            return ExitCode::from(2);
        }
    }
    print_problems(&summary);
    if summary.failures.is_empty() && summary.missing.is_empty() { ExitCode::SUCCESS } else { ExitCode::FAILURE }
}

/// The worst error per group, and the timings.
fn print_summary(file: &std::path::Path, summary: &conformance::Summary) {
    println!("{}: worst error per joint and formulation, in units of eps*scale (pass: <= {TOLERANCE})", file.display());
    for ((joint, form), (worst, n)) in &summary.worst {
        println!("{joint:<26} {form:<15} {worst:>8.3}  ({n} cases)");
    }
    for (joint, form, ns, ops) in &summary.timings {
        println!("TIME {joint} {form} {ns:.1}");
        println!("OPS {joint} {form} {ops}");
    }
}

/// Groups without code, failed cases, and the totals.
fn print_problems(summary: &conformance::Summary) {
    for m in &summary.missing {
        println!("MISSING {m}: no generated code");
    }
    for f in &summary.failures {
        println!("FAIL {f}");
    }
    let total: usize = summary.worst.values().map(|(_, n)| n).sum();
    println!("{} cases, {} failed, {} groups without code", total, summary.failures.len(), summary.missing.len());
}
