//! The conformance runner (see `shared/conformance/README.md`).
//!
//! ```text
//! cargo run --release -p joint-tests --bin conformance -- [FILE] [--joints a,b] [--emit OUT] [--time]
//! ```
//! FILE defaults to `../shared/conformance/vectors.json` (run from the repository root).

use std::process::ExitCode;

use joint_tests::conformance::{self, TOLERANCE};

fn main() -> ExitCode {
    let mut file = "../shared/conformance/vectors.json".to_string();
    let (mut joints, mut emit, mut time) = (None, None, false);
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--joints" => joints = args.next().map(|s| s.split(',').map(str::to_string).collect::<Vec<_>>()),
            "--emit" => emit = args.next(),
            "--time" => time = true,
            "-h" | "--help" => {
                println!("usage: conformance [FILE] [--joints a,b,c] [--emit OUT.json] [--time]");
                return ExitCode::SUCCESS;
            }
            _ if a.starts_with("--") => {
                eprintln!("conformance: unknown option `{a}` (try --help)");
                return ExitCode::from(2);
            }
            _ => file = a,
        }
    }
    let doc = match std::fs::read_to_string(&file)
        .map_err(|e| e.to_string())
        .and_then(|s| serde_json::from_str(&s).map_err(|e| e.to_string()))
    {
        Ok(d) => d,
        Err(e) => {
            eprintln!("conformance: cannot read `{file}`: {e}");
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
    println!("{file}: worst error per joint and formulation, in units of eps*scale (pass: <= {TOLERANCE})");
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
            eprintln!("conformance: cannot write `{path}`: {e}");
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
