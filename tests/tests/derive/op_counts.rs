//! A ratchet on the size of the generated code: the operation counts
//! ([`Joint::OPS`]) of every catalogue joint in every formulation may not grow.
//!
//! `tests/op_counts.txt` records one line per joint × formulation (75), written
//! `joint formulation phi phi_t jacobian gamma evaluate`. The test computes the
//! counts of the structs of [`joint_tests::joints`] (every parameter a run-time
//! field), checks that the file and the structs cover exactly the same 75 pairs,
//! and fails if any count is larger than the recorded one. Smaller counts pass
//! and are printed (run with `--nocapture` to see them); record them with
//!
//! ```text
//! UPDATE_OP_COUNTS=1 cargo test -p joint-tests --test derive op_counts
//! ```
//!
//! which rewrites the file from the current code (and then passes). An
//! intentional increase is recorded the same way, in the commit that explains it.

use std::collections::{BTreeMap, BTreeSet};
use std::fmt::Write as _;
use std::path::PathBuf;

use joint_runtime::{Joint, Ops};
use joint_tests::joints::*;

/// Joints × formulations in the catalogue.
const ENTRIES: usize = 75;
/// The environment variable that makes the test rewrite the file.
const UPDATE: &str = "UPDATE_OP_COUNTS";

/// One struct's kind, formulation and counts, read off its `Joint` impl (`R` and
/// `C` are inferred from the struct's single impl).
fn entry<J: Joint<f64, R, C>, const R: usize, const C: usize>(_: core::marker::PhantomData<J>) -> (String, Ops) {
    (format!("{} {}", J::KIND, J::FORMULATION.name()), J::OPS)
}

/// Every struct of the catalogue, keyed `"joint formulation"`.
fn current() -> Vec<(String, Ops)> {
    macro_rules! all {
        ($($t:ident),* $(,)?) => { vec![$(entry(core::marker::PhantomData::<$t<f64>>)),*] };
    }
    all![
        SphericalEuler,
        SphericalOmegaInertial,
        SphericalOmegaBody,
        SphericalRelativeB1,
        SphericalRelativeB2,
        UniversalEuler,
        UniversalOmegaInertial,
        UniversalOmegaBody,
        UniversalRelativeB1,
        UniversalRelativeB2,
        UniversalTranslationalEuler,
        UniversalTranslationalOmegaInertial,
        UniversalTranslationalOmegaBody,
        UniversalTranslationalRelativeB1,
        UniversalTranslationalRelativeB2,
        RevoluteEuler,
        RevoluteOmegaInertial,
        RevoluteOmegaBody,
        RevoluteRelativeB1,
        RevoluteRelativeB2,
        CylindricalEuler,
        CylindricalOmegaInertial,
        CylindricalOmegaBody,
        CylindricalRelativeB1,
        CylindricalRelativeB2,
        TranslationalEuler,
        TranslationalOmegaInertial,
        TranslationalOmegaBody,
        TranslationalRelativeB1,
        TranslationalRelativeB2,
        FixedEuler,
        FixedOmegaInertial,
        FixedOmegaBody,
        FixedRelativeB1,
        FixedRelativeB2,
        PlanarEuler,
        PlanarOmegaInertial,
        PlanarOmegaBody,
        PlanarRelativeB1,
        PlanarRelativeB2,
        PointOnLineEuler,
        PointOnLineOmegaInertial,
        PointOnLineOmegaBody,
        PointOnLineRelativeB1,
        PointOnLineRelativeB2,
        PointInPlaneEuler,
        PointInPlaneOmegaInertial,
        PointInPlaneOmegaBody,
        PointInPlaneRelativeB1,
        PointInPlaneRelativeB2,
        ParallelEuler,
        ParallelOmegaInertial,
        ParallelOmegaBody,
        ParallelRelativeB1,
        ParallelRelativeB2,
        PerpendicularEuler,
        PerpendicularOmegaInertial,
        PerpendicularOmegaBody,
        PerpendicularRelativeB1,
        PerpendicularRelativeB2,
        DistanceEuler,
        DistanceOmegaInertial,
        DistanceOmegaBody,
        DistanceRelativeB1,
        DistanceRelativeB2,
        RotationalDriverEuler,
        RotationalDriverOmegaInertial,
        RotationalDriverOmegaBody,
        RotationalDriverRelativeB1,
        RotationalDriverRelativeB2,
        TranslationalDriverEuler,
        TranslationalDriverOmegaInertial,
        TranslationalDriverOmegaBody,
        TranslationalDriverRelativeB1,
        TranslationalDriverRelativeB2,
    ]
}

fn path() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests").join("op_counts.txt")
}

fn counts(ops: &Ops) -> [usize; 5] {
    [ops.phi, ops.phi_t, ops.jacobian, ops.gamma, ops.evaluate]
}

const NAMES: [&str; 5] = ["phi", "phi_t", "jacobian", "gamma", "evaluate"];

/// The file's text for `entries`, in catalogue order.
fn render(entries: &[(String, Ops)]) -> String {
    let mut out = String::new();
    for (key, ops) in entries {
        let [a, b, c, d, e] = counts(ops);
        let _ = writeln!(out, "{key} {a} {b} {c} {d} {e}");
    }
    out
}

/// Parses the recorded file: `"joint formulation"` → counts, with the line number
/// of any malformed or repeated line as the error.
fn parse(text: &str) -> Result<BTreeMap<String, [usize; 5]>, String> {
    let mut out = BTreeMap::new();
    for (n, line) in text.lines().enumerate() {
        let words: Vec<&str> = line.split_whitespace().collect();
        let [joint, formulation, rest @ ..] = words.as_slice() else {
            return Err(format!("line {}: expected `joint formulation phi phi_t jacobian gamma evaluate`", n + 1));
        };
        let numbers: Vec<usize> = rest
            .iter()
            .map(|w| w.parse::<usize>())
            .collect::<Result<_, _>>()
            .map_err(|e| format!("line {}: {e}", n + 1))?;
        let numbers: [usize; 5] =
            numbers.try_into().map_err(|_| format!("line {}: expected five counts after the names", n + 1))?;
        if out.insert(format!("{joint} {formulation}"), numbers).is_some() {
            return Err(format!("line {}: `{joint} {formulation}` appears twice", n + 1));
        }
    }
    Ok(out)
}

#[test]
fn generated_operation_counts_do_not_grow() {
    let now = current();

    // The struct list is the whole catalogue: 75 distinct pairs, each of them a
    // pair the conformance runner knows.
    assert_eq!(now.len(), ENTRIES);
    let keys: BTreeSet<&str> = now.iter().map(|(k, _)| k.as_str()).collect();
    assert_eq!(keys.len(), ENTRIES, "a joint × formulation pair is listed twice");
    for key in &keys {
        let (joint, formulation) = key.split_once(' ').expect("two words");
        assert!(
            joint_tests::joints::group(joint, formulation, &[]).is_some(),
            "`{key}` is not in the conformance runner's table"
        );
    }

    let file = path();
    if std::env::var_os(UPDATE).is_some_and(|v| !v.is_empty() && v != "0") {
        std::fs::write(&file, render(&now)).unwrap_or_else(|e| panic!("writing {}: {e}", file.display()));
        println!("{UPDATE}: rewrote {} ({} lines)", file.display(), now.len());
    }
    let text = std::fs::read_to_string(&file).unwrap_or_else(|e| panic!("reading {}: {e}", file.display()));
    let recorded = parse(&text).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
    assert_eq!(text.lines().count(), ENTRIES, "{} must have one line per joint × formulation", file.display());
    let recorded_keys: BTreeSet<&str> = recorded.keys().map(String::as_str).collect();
    assert_eq!(recorded_keys, keys, "{} does not cover exactly the catalogue's structs", file.display());

    let (mut worse, mut better) = (Vec::new(), Vec::new());
    for (key, ops) in &now {
        let old = recorded[key.as_str()];
        for ((name, new), old) in NAMES.iter().zip(counts(ops)).zip(old) {
            let line = format!("{key} {name}: {old} → {new}");
            if new > old {
                worse.push(line);
            } else if new < old {
                better.push(line);
            }
        }
    }
    if !better.is_empty() {
        println!(
            "{} operation counts went down (record them with {UPDATE}=1 cargo test -p joint-tests --test derive op_counts):",
            better.len()
        );
        for line in &better {
            println!("  {line}");
        }
    }
    assert!(
        worse.is_empty(),
        "{} operation counts grew:\n  {}\n(if intended, record them with {UPDATE}=1 cargo test -p joint-tests --test derive op_counts)",
        worse.len(),
        worse.join("\n  ")
    );
}
