//! The dense path's exact Newton matrices from the generated second-order terms.

use nalgebra::{Matrix3, SMatrix, SVector};

use super::{DenseSimulation, Factored, StepRule};
use crate::analysis::dense::jacobian_times_metric;
use crate::analysis::{AnalysisError, InverseMass, velocity_vector};
use crate::dynamics::newton_matrix::*;
use crate::dynamics::{AppliedLoads, Dynamics, midpoint_state};
use crate::linalg::PivotedCholesky;
use crate::scene::{Scene, SystemState};

impl<S, L, const NB: usize, const NV: usize, const M: usize> DenseSimulation<'_, S, L, NB, NV, M>
where
    S: Scene<NB, NV, M>,
    L: AppliedLoads<NB>,
{
    /// The linearised equations of motion at `state` (the rule's redundant
    /// rows dropped, as the accelerations drop them); `None` when the scene
    /// has no generated second-order terms.
    pub(super) fn tangent(
        &mut self,
        state: &SystemState<NB>,
        rule: &mut StepRule<M>,
    ) -> Result<Option<Tangent<NB, NV, M>>, AnalysisError> {
        let f = self.solve_factored(state, Some(rule))?;
        self.tangent_on(state, f)
    }

    /// [`tangent`](Self::tangent) on the accelerations `f` already solved at `state`.
    pub(super) fn tangent_on(
        &mut self,
        state: &SystemState<NB>,
        f: Factored<NV, M>,
    ) -> Result<Option<Tangent<NB, NV, M>>, AnalysisError> {
        let d = f.dynamics;
        let (alpha, beta) = self.options.stabilisation.coefficients();
        let v = velocity_vector::<NB, NV>(state);
        // ∂(J a)/∂q + 2α ∂(J v)/∂q in one: J u is linear in u.
        let u = d.vdot + v * (2.0 * alpha);
        let Some(second) = self.scene.second_order(state, &d.lambda, &u) else { return Ok(None) };
        let (j, jw, chol) = (f.jacobian, f.jw, f.chol);
        let (force_q, force_v) = self.force_derivatives(state);
        let r2q = second.gamma_q - second.jacobian_q - second.phi_t_q * (2.0 * alpha) - j * (beta * beta);
        Ok(Some(Tangent {
            r1q: force_q - second.stiffness,
            r1v: force_v,
            r2q,
            r2v: second.gamma_v - j * (2.0 * alpha),
            j,
            jw,
            chol,
            inverse: self.inverse,
            dynamics: d,
        }))
    }

    /// `∂R/∂w` of the midpoint residual at `w`, exact; `None` when the scene
    /// has no generated second-order terms.
    /// `∂R/∂w` of the midpoint residual at `w`, exact, and the linearised
    /// equations at the midpoint it was built from (on `at`, the
    /// accelerations already solved there, if given); `None` when the scene
    /// has no generated second-order terms.
    #[allow(clippy::type_complexity)]
    pub(super) fn midpoint_tangent(
        &mut self,
        y0: &SystemState<NB>,
        w: &SVector<f64, NV>,
        h: f64,
        rule: &mut StepRule<M>,
        at: Option<&Factored<NV, M>>,
    ) -> Result<Option<(SMatrix<f64, NV, NV>, Tangent<NB, NV, M>)>, AnalysisError> {
        let mid = midpoint_state(y0, w, h);
        let tangent = match at {
            Some(f) => self.tangent_on(&mid, *f)?,
            None => self.tangent(&mid, rule)?,
        };
        let Some(t) = tangent else { return Ok(None) };
        // δq = (h/2) T δw, δv = δw.
        let p = update_blocks::<NB, NV>(w, 0.5 * h);
        let r1 = times_update(&t.r1q, &p, 0.5 * h) + t.r1v;
        let r2 = times_update(&t.r2q, &p, 0.5 * h) + t.r2v;
        let matrix = SMatrix::<f64, NV, NV>::identity() - t.accelerations(&r1, &r2) * (0.5 * h);
        if !matrix.iter().all(|x| x.is_finite()) {
            return Err(AnalysisError::NonFiniteOutput { quantity: "Newton matrix", row: None });
        }
        Ok(Some((matrix, t)))
    }
}
/// The linearised equations of motion at one state: `δa` for any direction
/// `(δq, δv)` is [`Tangent::accelerations`] of `R1 = R1q δq + R1v δv` and
/// `R2 = R2q δq + R2v δv`.
pub(super) struct Tangent<const NB: usize, const NV: usize, const M: usize> {
    /// `Q_q − K`.
    pub(super) r1q: SMatrix<f64, NV, NV>,
    /// `Q_v`.
    pub(super) r1v: SMatrix<f64, NV, NV>,
    /// `∂(γ̂ − J a)/∂q`, `γ̂` the stabilised right-hand side.
    pub(super) r2q: SMatrix<f64, M, NV>,
    /// `∂γ̂/∂v`.
    pub(super) r2v: SMatrix<f64, M, NV>,
    /// `J`, and `J M⁻¹`.
    pub(super) j: SMatrix<f64, M, NV>,
    jw: SMatrix<f64, M, NV>,
    /// `J M⁻¹ Jᵀ` under the step's rule for redundant rows.
    chol: PivotedCholesky<M>,
    inverse: [InverseMass; NB],
    /// The accelerations and multipliers at the state (the linearisation's λ).
    #[cfg_attr(not(feature = "alloc"), allow(dead_code))]
    pub(super) dynamics: Dynamics<NV, M>,
}

impl<const NB: usize, const NV: usize, const M: usize> Tangent<NB, NV, M> {
    /// `δa` for the right-hand sides `r1` (`NV × K`) and `r2` (`M × K`):
    /// `δa = X − M⁻¹ Jᵀ δλ` with `X = M⁻¹ r1` and `(J M⁻¹ Jᵀ) δλ = J X − r2`.
    pub(super) fn accelerations<const K: usize>(
        &self,
        r1: &SMatrix<f64, NV, K>,
        r2: &SMatrix<f64, M, K>,
    ) -> SMatrix<f64, NV, K> {
        let x = jacobian_times_metric::<NB, NV, K>(Some(&self.inverse), &r1.transpose()).transpose();
        let mut b = sparse_times(&self.j, &x) - r2;
        for mut column in b.column_iter_mut() {
            let solved = self.chol.solve(&column.clone_owned());
            column.copy_from(&solved);
        }
        x - sparse_transpose_times(&self.jw, &b)
    }
}

/// `A · s blockdiag(I, J_r,0, I, J_r,1, ...)`: `O(R · NV)` where a dense product
/// would cost `O(R · NV²)`.
pub(super) fn times_update<const R: usize, const NB: usize, const NV: usize>(
    a: &SMatrix<f64, R, NV>,
    rotations: &[Matrix3<f64>; NB],
    s: f64,
) -> SMatrix<f64, R, NV> {
    let mut out = a * s;
    for (b, jr) in rotations.iter().enumerate() {
        let jr = jr * s;
        for i in 0..R {
            let row = [0, 1, 2].map(|l| a.get((i, 6 * b + 3 + l)).copied().unwrap_or(0.0));
            for k in 0..3 {
                if let Some(o) = out.get_mut((i, 6 * b + 3 + k)) {
                    *o = row[0] * jr[(0, k)] + row[1] * jr[(1, k)] + row[2] * jr[(2, k)];
                }
            }
        }
    }
    out
}

/// `J X`, skipping `J`'s structural zeros (most of a scene's `J`).
fn sparse_times<const M: usize, const NV: usize, const K: usize>(
    j: &SMatrix<f64, M, NV>,
    x: &SMatrix<f64, NV, K>,
) -> SMatrix<f64, M, K> {
    let mut out = SMatrix::<f64, M, K>::zeros();
    for (c, jc) in j.column_iter().enumerate() {
        for (r, &v) in jc.iter().enumerate().filter(|(_, v)| **v != 0.0) {
            for (mut ok, xk) in out.column_iter_mut().zip(x.column_iter()) {
                if let (Some(o), Some(&xv)) = (ok.get_mut(r), xk.get(c)) {
                    *o += v * xv;
                }
            }
        }
    }
    out
}

/// `Jᵀ Y`, skipping `J`'s structural zeros.
fn sparse_transpose_times<const M: usize, const NV: usize, const K: usize>(
    j: &SMatrix<f64, M, NV>,
    y: &SMatrix<f64, M, K>,
) -> SMatrix<f64, NV, K> {
    let mut out = SMatrix::<f64, NV, K>::zeros();
    for (c, jc) in j.column_iter().enumerate() {
        for (r, &v) in jc.iter().enumerate().filter(|(_, v)| **v != 0.0) {
            for (mut ok, yk) in out.column_iter_mut().zip(y.column_iter()) {
                if let (Some(o), Some(&yv)) = (ok.get_mut(c), yk.get(r)) {
                    *o += v * yv;
                }
            }
        }
    }
    out
}
