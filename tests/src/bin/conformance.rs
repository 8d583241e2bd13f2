//! The conformance runner (see the conformance README, `conformance/` in the
//! repository).
//!
//! ```text
//! cargo run --release -p joint-tests --bin conformance -- [FILE] [--joints a,b] [--emit OUT] [--time]
//! ```
//! FILE defaults to the repository's `conformance/vectors.json`, found from the
//! package's manifest directory, so the runner works from any directory.

use std::path::PathBuf;
use std::process::ExitCode;

use joint_tests::conformance::{self, TOLERANCE};

fn main() -> ExitCode {
    let mut file = conformance::vectors_dir().join("vectors.json");
    let (mut joints, mut emit, mut time) = (None, None, false);
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--joints" => joints = args.next().map(|s| s.split(',').map(str::to_string).collect::<Vec<_>>()),
            "--emit" => emit = args.next().map(PathBuf::from),
            "--time" => time = true,
            "-h" | "--help" => {
                println!("usage: conformance [FILE] [--joints a,b,c] [--emit OUT.json] [--time]");
                return ExitCode::SUCCESS;
            }
            _ if a.starts_with("--") => {
                eprintln!("conformance: unknown option `{a}` (try --help)");
                return ExitCode::from(2);
            }
            _ => file = a.into(),
        }
    }
    let doc = match conformance::load(&file) {
        Ok(d) => d,
        Err(e) => {
            eprintln!("conformance: {e}");
            return ExitCode::from(2);
        }
    };
    let summary = match conformance::run(&doc, joints.as_deref(), time) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("conformance: {e}");
            return ExitCode::from(2);
        }
    };
    println!("{}: worst error per joint and formulation, in units of eps*scale (pass: <= {TOLERANCE})", file.display());
    for ((joint, form), (worst, n)) in &summary.worst {
        println!("{joint:<26} {form:<15} {worst:>8.3}  ({n} cases)");
    }
    for (joint, form, ns, ops) in &summary.timings {
        println!("TIME {joint} {form} {ns:.1}");
        println!("OPS {joint} {form} {ops}");
    }
    if let Some(path) = emit {
        let text = serde_json::to_string_pretty(&conformance::emit_json(&summary.outputs)).unwrap_or_default();
        if let Err(e) = std::fs::write(&path, text) {
            eprintln!("conformance: cannot write `{}`: {e}", path.display());
            return ExitCode::from(2);
        }
    }
    for m in &summary.missing {
        println!("MISSING {m}: no generated code");
    }
    for f in &summary.failures {
        println!("FAIL {f}");
    }
    let total: usize = summary.worst.values().map(|(_, n)| n).sum();
    println!("{} cases, {} failed, {} groups without code", total, summary.failures.len(), summary.missing.len());
    if summary.failures.is_empty() && summary.missing.is_empty() { ExitCode::SUCCESS } else { ExitCode::FAILURE }
}
