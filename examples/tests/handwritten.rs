//! The hand-written nalgebra joints of `report::handwritten` under the project's
//! conformance test (the repository's `conformance/vectors.json` and
//! `hard.json`, the runner's `case_error` at 256 ε·scale), and their operation
//! counts with `report::counting::Counted`.

use joint_examples::report::counting::{Counted, ToCounted, count};
use joint_examples::report::handwritten::*;
use joint_runtime::Joint;
use joint_tests::conformance::{self, Case, FromCase, Output, TOLERANCE, VectorFile, case_error};

fn cases<'a>(doc: &'a VectorFile, joint: &str, formulation: &str) -> Vec<&'a Case> {
    doc.cases.iter().filter(|c| c.joint == joint && c.formulation == formulation).collect()
}

/// Each case's id and its error in ε·scale (`Err` for an exact-zero miss or a
/// wrong shape), evaluating `J` on the cases of `joint`/`formulation` in `doc`.
fn errors<J, const R: usize, const C: usize>(
    doc: &VectorFile,
    joint: &str,
    formulation: &str,
) -> Vec<(String, Result<f64, String>)>
where
    J: Joint<f64, R, C> + FromCase,
    J::State: FromCase,
{
    cases(doc, joint, formulation)
        .into_iter()
        .map(|case| {
            let id = case.id.clone();
            let j = J::from_case(case).unwrap_or_else(|e| panic!("{id}: params: {e}"));
            let state = J::State::from_case(case).unwrap_or_else(|e| panic!("{id}: state: {e}"));
            let e = j.evaluate(&state);
            // The separate functions give the fused evaluation's numbers.
            assert_eq!((j.phi(&state), j.jacobian(&state), j.gamma(&state)), (e.phi, e.jacobian, e.gamma), "{id}");
            let out = Output {
                id: id.clone(),
                phi: e.phi.iter().copied().collect(),
                jacobian: (0..R).map(|r| (0..C).map(|c| e.jacobian[(r, c)]).collect()).collect(),
                gamma: e.gamma.iter().copied().collect(),
            };
            (id, case_error(case, &out))
        })
        .collect()
}

/// The worst error in ε·scale over the cases of `joint`/`formulation` in `doc`,
/// its case, and how many cases there were; panics on an exact-zero miss.
fn worst<J, const R: usize, const C: usize>(doc: &VectorFile, joint: &str, formulation: &str) -> (f64, String, usize)
where
    J: Joint<f64, R, C> + FromCase,
    J::State: FromCase,
{
    let errors = errors::<J, R, C>(doc, joint, formulation);
    let mut worst = (0.0, String::new());
    for (id, err) in &errors {
        let err = *err.as_ref().unwrap_or_else(|msg| panic!("{id}: {msg}"));
        if err > worst.0 || worst.1.is_empty() {
            worst = (err, id.clone());
        }
    }
    (worst.0, worst.1, errors.len())
}

/// The test can fail: the right formulas against another formulation's
/// expectations (ω in the other body's components, ω inertial instead of body)
/// land far outside the tolerance.
#[test]
fn a_wrong_convention_fails() {
    let doc = conformance::vectors("vectors.json");
    let failed = |errors: Vec<(String, Result<f64, String>)>| {
        assert!(!errors.is_empty());
        errors.iter().filter(|(_, e)| e.as_ref().map_or(true, |e| *e > TOLERANCE)).count() * 2 > errors.len()
    };
    assert!(failed(errors::<UniversalRelativeB1<f64>, 4, 6>(&doc, "universal", "relative_b2")));
    assert!(failed(errors::<UniversalOmegaBody<f64>, 4, 12>(&doc, "universal", "omega_inertial")));
    assert!(failed(errors::<UniversalTranslationalOmegaInertial<f64>, 3, 12>(
        &doc,
        "universal_translational",
        "omega_body"
    )));
}

/// The same code runs at `f32` and agrees with `f64` to `f32` precision.
#[test]
fn runs_at_f32() {
    use joint_runtime::{EulerBody, TwoBodies};
    let doc = conformance::vectors("vectors.json");
    let case = cases(&doc, "universal", "euler")[0];
    let j = UniversalEuler::<f64>::from_case(case).expect("params");
    let state = TwoBodies::<EulerBody<f64>>::from_case(case).expect("state");
    let body = |b: &EulerBody<f64>| EulerBody {
        r: b.r.map(|x| x as f32),
        p: b.p.map(|x| x as f32),
        rdot: b.rdot.map(|x| x as f32),
        pdot: b.pdot.map(|x| x as f32),
    };
    let state32 = TwoBodies::new(body(&state.body1), body(&state.body2));
    let (e, e32) = (j.evaluate(&state), j.map(|x| x as f32).evaluate(&state32));
    let close = |a: f64, b: f32, scale: f64| (a - b as f64).abs() <= 1e-4 * scale.max(1.0);
    let scale = e.jacobian.amax().max(e.gamma.amax()).max(e.phi.amax());
    assert!(e.phi.iter().zip(e32.phi.iter()).all(|(&a, &b)| close(a, b, scale)));
    assert!(e.jacobian.iter().zip(e32.jacobian.iter()).all(|(&a, &b)| close(a, b, scale)));
    assert!(e.gamma.iter().zip(e32.gamma.iter()).all(|(&a, &b)| close(a, b, scale)));
}

macro_rules! conformance {
    ($($test:ident: $ty:ident, $joint:literal, $form:literal, $r:literal, $c:literal;)*) => {$(
        #[test]
        fn $test() {
            for (file, min_cases) in [("vectors.json", 4), ("hard.json", 4)] {
                let doc = conformance::vectors(file);
                let (err, id, n) = worst::<$ty<f64>, $r, $c>(&doc, $joint, $form);
                println!("{file}: {}/{}: worst {err:.2} ε·scale over {n} cases ({id})", $joint, $form);
                assert!(n >= min_cases, "{file}: only {n} cases of {}/{}", $joint, $form);
                assert!(err <= TOLERANCE, "{file}: {id}: {err:.1} ε·scale > {TOLERANCE}");
            }
        }
    )*};
}

conformance! {
    universal_omega_inertial: UniversalOmegaInertial, "universal", "omega_inertial", 4, 12;
    universal_omega_body: UniversalOmegaBody, "universal", "omega_body", 4, 12;
    universal_euler: UniversalEuler, "universal", "euler", 4, 14;
    universal_relative_b1: UniversalRelativeB1, "universal", "relative_b1", 4, 6;
    universal_relative_b2: UniversalRelativeB2, "universal", "relative_b2", 4, 6;
    universal_translational_omega_inertial: UniversalTranslationalOmegaInertial, "universal_translational", "omega_inertial", 3, 12;
    universal_translational_omega_body: UniversalTranslationalOmegaBody, "universal_translational", "omega_body", 3, 12;
    universal_translational_euler: UniversalTranslationalEuler, "universal_translational", "euler", 3, 14;
    universal_translational_relative_b1: UniversalTranslationalRelativeB1, "universal_translational", "relative_b1", 3, 6;
    universal_translational_relative_b2: UniversalTranslationalRelativeB2, "universal_translational", "relative_b2", 3, 6;
    spherical_omega_body: SphericalOmegaBody, "spherical", "omega_body", 3, 12;
    spherical_euler: SphericalEuler, "spherical", "euler", 3, 14;
    revolute_omega_body: RevoluteOmegaBody, "revolute", "omega_body", 5, 12;
    revolute_euler: RevoluteEuler, "revolute", "euler", 5, 14;
    translational_omega_body: TranslationalOmegaBody, "translational", "omega_body", 5, 12;
    translational_euler: TranslationalEuler, "translational", "euler", 5, 14;
}

/// Operations of `phi`, `jacobian`, `gamma` and `evaluate` at the first case of
/// `vectors.json`, counted with `Counted`; the counted values must be the `f64` ones.
macro_rules! op_counts {
    ($($ty:ident, $gen:ident, $joint:literal, $form:literal, $r:literal, $c:literal;)*) => {{
        let doc = conformance::vectors("vectors.json");
        let mut rows = Vec::new();
        $({
            let case = cases(&doc, $joint, $form)[0];
            let j = <$ty<f64> as FromCase>::from_case(case).expect("params");
            let state = <<$ty<f64> as Joint<f64, $r, $c>>::State as FromCase>::from_case(case).expect("state");
            let (jc, sc) = (j.map(Counted::new), state.to_counted());
            let (e, evaluate) = count(|| jc.evaluate(&sc));
            let (_, phi) = count(|| jc.phi(&sc));
            let (_, jacobian) = count(|| jc.jacobian(&sc));
            let (_, gamma) = count(|| jc.gamma(&sc));
            let plain = j.evaluate(&state);
            assert_eq!(e.phi.map(Counted::value), plain.phi);
            assert_eq!(e.jacobian.map(Counted::value), plain.jacobian);
            assert_eq!(e.gamma.map(Counted::value), plain.gamma);
            let generated = <joint_tests::joints::$gen<f64> as Joint<f64, $r, $c>>::OPS.evaluate;
            rows.push((concat!($joint, "/", $form), phi, jacobian, gamma, evaluate, generated));
        })*
        rows
    }};
}

#[test]
fn operation_counts() {
    let rows = op_counts! {
        UniversalOmegaInertial, UniversalOmegaInertial, "universal", "omega_inertial", 4, 12;
        UniversalOmegaBody, UniversalOmegaBody, "universal", "omega_body", 4, 12;
        UniversalEuler, UniversalEuler, "universal", "euler", 4, 14;
        UniversalRelativeB1, UniversalRelativeB1, "universal", "relative_b1", 4, 6;
        UniversalRelativeB2, UniversalRelativeB2, "universal", "relative_b2", 4, 6;
        UniversalTranslationalOmegaInertial, UniversalTranslationalOmegaInertial, "universal_translational", "omega_inertial", 3, 12;
        UniversalTranslationalOmegaBody, UniversalTranslationalOmegaBody, "universal_translational", "omega_body", 3, 12;
        UniversalTranslationalEuler, UniversalTranslationalEuler, "universal_translational", "euler", 3, 14;
        UniversalTranslationalRelativeB1, UniversalTranslationalRelativeB1, "universal_translational", "relative_b1", 3, 6;
        UniversalTranslationalRelativeB2, UniversalTranslationalRelativeB2, "universal_translational", "relative_b2", 3, 6;
        SphericalOmegaBody, SphericalOmegaBody, "spherical", "omega_body", 3, 12;
        SphericalEuler, SphericalEuler, "spherical", "euler", 3, 14;
        RevoluteOmegaBody, RevoluteOmegaBody, "revolute", "omega_body", 5, 12;
        RevoluteEuler, RevoluteEuler, "revolute", "euler", 5, 14;
        TranslationalOmegaBody, TranslationalOmegaBody, "translational", "omega_body", 5, 12;
        TranslationalEuler, TranslationalEuler, "translational", "euler", 5, 14;
    };
    println!(
        "{:<40} {:>6} {:>8} {:>6} {:>8} {:>10}",
        "joint/formulation", "phi", "jacobian", "gamma", "evaluate", "generated"
    );
    for &(name, phi, jacobian, gamma, evaluate, generated) in &rows {
        println!("{name:<40} {phi:>6} {jacobian:>8} {gamma:>6} {evaluate:>8} {generated:>10}");
        // Every function does work; the fused evaluation shares, so it costs no more
        // than the three separately and at least the dearest of them.
        assert!(phi > 0 && jacobian > 0 && gamma > 0, "{name}");
        assert!(evaluate <= phi + jacobian + gamma, "{name}: evaluate {evaluate}");
        assert!(evaluate >= phi.max(jacobian).max(gamma), "{name}: evaluate {evaluate}");
        assert!(evaluate < 5000, "{name}: evaluate {evaluate}");
    }
}
