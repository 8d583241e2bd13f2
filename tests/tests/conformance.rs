//! The conformance vectors of `shared/conformance/`, through derive-generated code
//! with run-time parameters, under the accuracy test of the conformance README.

use std::path::PathBuf;

use joint_tests::conformance::{self, TOLERANCE};

fn shared(file: &str) -> serde_json::Value {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/conformance").join(file);
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
    serde_json::from_str(&text).expect("valid JSON")
}

fn check(file: &str, min_cases: usize) {
    let summary = conformance::run(&shared(file), None, false).expect("well-formed cases");
    for ((joint, form), (worst, n)) in &summary.worst {
        println!("{file}: {joint}/{form}: worst {worst:.3} eps*scale over {n} cases");
    }
    assert!(summary.missing.is_empty(), "{file}: no generated code for {:?}", summary.missing);
    assert!(summary.failures.is_empty(), "{file}: failures:\n{}", summary.failures.join("\n"));
    let worst = summary.worst.values().map(|(w, _)| *w).fold(0.0, f64::max);
    assert!(worst <= TOLERANCE, "{file}: worst error {worst}");
    assert!(summary.outputs.len() >= min_cases, "{file}: only {} cases ran", summary.outputs.len());
}

#[test]
fn vectors_json() {
    check("vectors.json", 450);
}

#[test]
fn hard_json() {
    check("hard.json", 630);
}

/// The runner's test can fail: a perturbed expectation is caught, and so is a
/// nonzero value where the scale says the entry is identically zero.
#[test]
fn a_wrong_value_fails() {
    let mut doc = shared("vectors.json");
    let cases = doc["cases"].as_array_mut().expect("cases");
    cases.retain(|c| c["joint"] == "universal" && c["formulation"] == "omega_body");
    let gamma = &mut cases[0]["expected"]["gamma"][3];
    let v = gamma.as_f64().expect("number");
    *gamma = serde_json::json!(v * (1.0 + 1e-9));
    cases[1]["expected"]["jacobian"][0][1] = serde_json::json!(1e-300);
    let summary = conformance::run(&doc, None, false).expect("well-formed cases");
    assert_eq!(summary.failures.len(), 2, "{:?}", summary.failures);
}
