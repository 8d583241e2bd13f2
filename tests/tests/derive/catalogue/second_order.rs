//! The generated second-order terms (`#[joint(.., second_order)]`) of every
//! catalogue joint in every formulation against num-dual over the generated J
//! and γ: each column is the `Dual64` derivative of `Jᵀλ`, `J u` or γ along the
//! exact group curve `q ⊕ τ e_k`, or along `v + τ e_k` for `∂γ/∂v`
//! ([`joint_by_duals`]). Tolerance 256 ε times the monomial scale of `CONVENTIONS.md`
//! (bounded below by [`magnitude`] of the generated terms at flipped signs).

use super::*;
use joint_tests::conformance;
use joint_tests::second_order::{joint_by_duals, joint_generated};
use joint_tests::trajectory::Flat;

/// λ and u of a case: deterministic functions of its numbers.
fn weights<const R: usize, const C: usize>(k: &Case) -> (SVector<f64, R>, SVector<f64, C>) {
    let lambda = SVector::from_fn(|i, _| 1.0 + k.p.0[(7 * i + 2) % 25]);
    let u = SVector::from_fn(|i, _| k.c.0[(5 * i + 3) % 34]);
    (lambda, u)
}

/// Every generated entry, `K`, `∂(J u)/∂q`, `∂γ/∂q`, `∂γ/∂v`, `∂Φ_t/∂q`
/// column-major, with the time function `tf`.
fn generated<Fa: Family<R, C>, const R: usize, const C: usize>(k: &Case, tf: Tf) -> Vec<f64> {
    let (lambda, u) = weights::<R, C>(k);
    joint_generated(&joint::<Fa, R, C>(&k.p, tf), &state::<Fa, R, C, f64>(&k.c, k.t0), &lambda, &u)
}

/// The same entries by num-dual over the generated `jacobian` and `gamma`.
fn by_duals<Fa: Family<R, C>, const R: usize, const C: usize>(k: &Case, tf: Tf) -> Vec<f64> {
    let (lambda, u) = weights::<R, C>(k);
    let jd = Fa::make::<Dual64>(&k.p.map(lift::<Dual64>), tf);
    joint_by_duals::<Fa::F, _, R, C>(&jd, &k.c, k.t0, &lambda, &u)
}

/// The check with the case's polynomial time function; returns the largest
/// entry compared.
pub(super) fn check_second_order<Fa: Family<R, C>, const R: usize, const C: usize>(
    k: &Case,
) -> Result<f64, TestCaseError> {
    check_with::<Fa, R, C>(k, k.poly_tf())
}

fn check_with<Fa: Family<R, C>, const R: usize, const C: usize>(k: &Case, tf: Tf) -> Result<f64, TestCaseError> {
    let got = generated::<Fa, R, C>(k, tf);
    let want = by_duals::<Fa, R, C>(k, tf);
    let mag = magnitude(k, |k| generated::<Fa, R, C>(k, tf));
    close(&format!("{} second-order terms vs num-dual", Fa::NAME), &got, &want, 256.0 * f64::EPSILON, &mag)?;
    Ok(max_abs(&want))
}

/// A conformance case as the catalogue's: its coordinates, its parameters in
/// the catalogue's slots, and its drive frozen at the state's values.
fn from_conformance(case: &conformance::Case) -> Result<(Case, Tf), String> {
    let c = case.state.coords()?;
    let q = &case.params;
    let mut p = Flat([0.0; 25]);
    let slots = [(0, q.f), (3, q.g), (6, q.h), (9, q.k), (12, q.n), (15, q.s), (18, q.rho1), (21, q.rho2)];
    for (o, x) in slots {
        p.set(o, &x.unwrap_or([0.0; 3]));
    }
    p.0[24] = q.length.unwrap_or(0.0);
    let tf = case.state.drive.map_or(frozen(0.0), |d| Tf::Frozen(d.into()));
    let sine = Sinusoid { offset: 0.0, amplitude: 0.0, frequency: 1.0, phase: 0.0 };
    Ok((Case { c, p, t0: 0.0, poly: [0.0; 3], sine }, tf))
}

/// The check of a conformance case of a catalogue joint; `None` for the
/// joints of `derivatives.rs`.
fn check_conformance(case: &conformance::Case) -> Option<Result<f64, String>> {
    macro_rules! dispatch {
        ($($module:ident: $r:literal),*) => {
            match (case.joint.as_str(), case.formulation.as_str()) {
                $(
                    (stringify!($module), "euler") => Some(check_case::<$module::E, $r, 14>(case)),
                    (stringify!($module), "omega_inertial") => Some(check_case::<$module::Oi, $r, 12>(case)),
                    (stringify!($module), "omega_body") => Some(check_case::<$module::Ob, $r, 12>(case)),
                    (stringify!($module), "relative_b1") => Some(check_case::<$module::R1, $r, 6>(case)),
                    (stringify!($module), "relative_b2") => Some(check_case::<$module::R2, $r, 6>(case)),
                )*
                _ => None,
            }
        };
    }
    dispatch!(
        revolute: 5, cylindrical: 4, translational: 5, fixed: 6, planar: 3, point_on_line: 2, point_in_plane: 1,
        parallel: 2, perpendicular: 1, distance: 1, rotational_driver: 1, translational_driver: 1
    )
}

fn check_case<Fa: Family<R, C>, const R: usize, const C: usize>(case: &conformance::Case) -> Result<f64, String> {
    let (k, tf) = from_conformance(case)?;
    check_with::<Fa, R, C>(&k, tf).map_err(|e| e.to_string())
}

/// Every conformance state of every catalogue joint (`vectors.json` and
/// `hard.json`, the repository's copies).
#[test]
fn second_order_on_the_conformance_states() {
    let mut checked = 0;
    for file in ["vectors.json", "hard.json"] {
        for case in joint_tests::conformance::vectors(file).cases {
            if let Some(result) = check_conformance(&case) {
                result.unwrap_or_else(|e| panic!("{}: {e}", case.id));
                checked += 1;
            }
        }
    }
    println!("second-order terms checked on {checked} conformance states");
    assert!(checked >= 60, "{checked} cases");
}
