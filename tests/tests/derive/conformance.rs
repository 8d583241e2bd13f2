//! The conformance vectors of the repository's `conformance/`, through
//! derive-generated code with run-time parameters, under the accuracy test of
//! the conformance README; and the check that those copies are still the
//! originals they were taken from.

use joint_tests::conformance::{self, TOLERANCE};

fn check(file: &str, min_cases: usize) {
    let summary = conformance::run(&conformance::vectors(file), None, false).expect("well-formed cases");
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
    let mut doc = conformance::vectors("vectors.json");
    doc.cases.retain(|c| c.joint == "universal" && c.formulation == "omega_body");
    doc.cases[0].expected.gamma[3] *= 1.0 + 1e-9;
    doc.cases[1].expected.jacobian[0][1] = 1e-300;
    let summary = conformance::run(&doc, None, false).expect("well-formed cases");
    assert_eq!(summary.failures.len(), 2, "{:?}", summary.failures);
}

/// The repository's vectors are copies: where the originals sit beside the
/// repository (the `shared` folder next to it, as on the developers' machines
/// and in CI), they must be the same bytes, so that the references are never
/// edited here by mistake nor left behind when the originals change. Where a
/// `shared` folder sits beside the repository its vectors must be there; a bare
/// clone has none and skips the check.
#[test]
fn in_repo_copies_match_the_originals() {
    let ours = conformance::vectors_dir();
    let repository = ours.parent().expect("the vectors folder is inside the repository");
    // Its `conformance` folder inside the `shared` folder beside the repository.
    let shared = repository.join("..").join("shared");
    if !shared.is_dir() {
        println!("skipped: no folder {}", shared.display());
        return;
    }
    let originals = shared.join("conformance");
    for file in ["vectors.json", "hard.json"] {
        let read = |dir: &std::path::Path| {
            let path = dir.join(file);
            std::fs::read(&path).unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()))
        };
        assert!(
            read(&ours) == read(&originals),
            "{} differs from {}: copy the original again",
            ours.join(file).display(),
            originals.join(file).display()
        );
    }
}
