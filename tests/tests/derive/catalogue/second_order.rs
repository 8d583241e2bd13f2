//! The generated second-order terms (`#[joint(.., second_order)]`) of every
//! catalogue joint in every formulation against num-dual over the generated J
//! and γ: each column is the `Dual64` derivative of `Jᵀλ`, `J u` or γ along the
//! exact group curve `q ⊕ τ e_k`, or along `v + τ e_k` for `∂γ/∂v`
//! ([`joint_by_duals`]). Tolerance 256 ε times the monomial scale of `CONVENTIONS.md`
//! (bounded below by [`magnitude`] of the generated terms at flipped signs).

use super::*;
use joint_tests::second_order::{joint_by_duals, joint_generated};

/// λ and u of a case: deterministic functions of its numbers.
fn weights<const R: usize, const C: usize>(k: &Case) -> (SVector<f64, R>, SVector<f64, C>) {
    let lambda = SVector::from_fn(|i, _| 1.0 + k.p.0[(7 * i + 2) % 25]);
    let u = SVector::from_fn(|i, _| k.c.0[(5 * i + 3) % 34]);
    (lambda, u)
}

/// Every generated entry, `K`, `∂(J u)/∂q`, `∂γ/∂q`, `∂γ/∂v` column-major.
fn generated<Fa: Family<R, C>, const R: usize, const C: usize>(k: &Case) -> Vec<f64> {
    let (lambda, u) = weights::<R, C>(k);
    joint_generated(&joint::<Fa, R, C>(&k.p, k.poly_tf()), &state::<Fa, R, C, f64>(&k.c, k.t0), &lambda, &u)
}

/// The same entries by num-dual over the generated `jacobian` and `gamma`.
fn by_duals<Fa: Family<R, C>, const R: usize, const C: usize>(k: &Case) -> Vec<f64> {
    let (lambda, u) = weights::<R, C>(k);
    let jd = Fa::make::<Dual64>(&k.p.map(lift::<Dual64>), k.poly_tf());
    joint_by_duals::<Fa::F, _, R, C>(&jd, &k.c, k.t0, &lambda, &u)
}

/// The check; returns the largest entry compared.
pub(super) fn check_second_order<Fa: Family<R, C>, const R: usize, const C: usize>(
    k: &Case,
) -> Result<f64, TestCaseError> {
    let got = generated::<Fa, R, C>(k);
    let want = by_duals::<Fa, R, C>(k);
    let mag = magnitude(k, generated::<Fa, R, C>);
    close(&format!("{} second-order terms vs num-dual", Fa::NAME), &got, &want, 256.0 * f64::EPSILON, &mag)?;
    Ok(max_abs(&want))
}
