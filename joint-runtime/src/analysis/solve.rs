//! Minimum-norm solves of `J x = b` in the Euclidean or the kinetic-energy
//! metric, through the rank-revealing factorisation of the Gram matrix.

use nalgebra::{Matrix3, SMatrix, SVector};

use super::{Analysis, AnalysisError, RowList, WorstRows};
use crate::linalg::PivotedCholesky;
use crate::scene::Scene;

/// Inverse mass of one body: `1/m` and `J'⁻¹` (public only for the code the
/// derive writes: [`SparseJacobian::normal_blocks_into`](crate::SparseJacobian)).
#[derive(Clone, Copy, Debug, PartialEq)]
#[doc(hidden)]
pub struct InverseMass {
    pub(crate) inv_mass: f64,
    pub(crate) inv_inertia: Matrix3<f64>,
}

impl InverseMass {
    /// `1/m`, then `J'⁻¹` row by row: the numbers generated code reads (by
    /// constant index, so without a bounds check).
    #[doc(hidden)]
    #[inline(always)]
    pub fn entries(&self) -> [f64; 10] {
        let w = &self.inv_inertia;
        [self.inv_mass, w.m11, w.m12, w.m13, w.m21, w.m22, w.m23, w.m31, w.m32, w.m33]
    }
}

/// The metric of a minimum-norm solve: Euclidean, or the inverse mass matrix
/// (`x = W Jᵀ y`, `(J W Jᵀ) y = b`: the solution closest in kinetic energy).
pub(crate) type Metric<'a, const NB: usize> = Option<&'a [InverseMass; NB]>;

/// `W x` for the block-diagonal metric (identity when `None`).
pub(crate) fn apply_metric<const NB: usize, const NV: usize>(
    metric: Metric<'_, NB>,
    x: &SVector<f64, NV>,
) -> SVector<f64, NV> {
    let Some(w) = metric else { return *x };
    let mut y = *x;
    apply_metric_into(w, x, &mut y);
    y
}

/// `y = W x` in place of the caller's vector (no `NV`-sized temporary).
pub(crate) fn apply_metric_into<const NB: usize, const NV: usize>(
    w: &[InverseMass; NB],
    x: &SVector<f64, NV>,
    y: &mut SVector<f64, NV>,
) {
    y.copy_from(x);
    apply_metric_in_place(w, y);
}

/// `x = W x` in place, body by body (the same operations as
/// [`apply_metric_into`]).
pub(crate) fn apply_metric_in_place<const NB: usize, const NV: usize>(w: &[InverseMass; NB], x: &mut SVector<f64, NV>) {
    for (i, m) in w.iter().enumerate() {
        if 6 * i + 6 > NV {
            break;
        }
        let f = x.fixed_rows::<3>(6 * i) * m.inv_mass;
        let t = m.inv_inertia * x.fixed_rows::<3>(6 * i + 3);
        x.fixed_rows_mut::<3>(6 * i).copy_from(&f);
        x.fixed_rows_mut::<3>(6 * i + 3).copy_from(&t);
    }
}

/// `J W` for the block-diagonal metric.
pub(crate) fn jacobian_times_metric<const NB: usize, const NV: usize, const M: usize>(
    metric: Metric<'_, NB>,
    j: &SMatrix<f64, M, NV>,
) -> SMatrix<f64, M, NV> {
    let Some(w) = metric else { return *j };
    let mut out = *j;
    for (i, m) in w.iter().enumerate() {
        if 6 * i + 6 > NV {
            break;
        }
        for r in 0..M {
            for c in 0..3 {
                out[(r, 6 * i + c)] = j[(r, 6 * i + c)] * m.inv_mass;
            }
            // Row block times the symmetric J'⁻¹.
            for c in 0..3 {
                let mut s = 0.0;
                for k in 0..3 {
                    s += j[(r, 6 * i + 3 + k)] * m.inv_inertia[(k, c)];
                }
                out[(r, 6 * i + 3 + c)] = s;
            }
        }
    }
    out
}

/// A minimum-norm solution of `J x = b`, from [`min_norm`].
pub(crate) struct MinNorm<const NV: usize, const M: usize> {
    /// `x = W Jᵀ y`.
    pub(crate) x: SVector<f64, NV>,
    /// The factorisation of `J W Jᵀ`; its dropped rows are the redundant ones.
    pub(crate) factor: PivotedCholesky<M>,
}

/// Minimum-norm solution (in the metric) of `J x = b`: `x = W Jᵀ y`,
/// `(J W Jᵀ) y = b`.
pub(crate) fn min_norm<const NB: usize, const NV: usize, const M: usize>(
    j: &SMatrix<f64, M, NV>,
    b: &SVector<f64, M>,
    metric: Metric<'_, NB>,
    rank_tolerance: f64,
) -> Result<MinNorm<NV, M>, AnalysisError> {
    let jw = jacobian_times_metric(metric, j);
    let gram = jw * j.transpose();
    let factor = PivotedCholesky::new(&gram, rank_tolerance)?;
    let x = jw.transpose() * factor.solve(b);
    Ok(MinNorm { x, factor })
}

/// A consistent solution of `J x = b`, from [`solve_linear`].
pub(crate) struct LinearSolution<const NV: usize, const M: usize> {
    /// The minimum-norm solution.
    pub(crate) x: SVector<f64, NV>,
    /// ‖J x − b‖₂.
    pub(crate) residual: f64,
    /// The rows dropped as redundant.
    pub(crate) redundant: RowList<M>,
}

/// Solves `J x = b` (minimum norm), checks consistency, lists redundant rows.
pub(crate) fn solve_linear<S, const NB: usize, const NV: usize, const M: usize>(
    analysis: Analysis,
    j: &SMatrix<f64, M, NV>,
    b: &SVector<f64, M>,
    metric: Metric<'_, NB>,
    rank_tolerance: f64,
) -> Result<LinearSolution<NV, M>, AnalysisError>
where
    S: Scene<NB, NV, M>,
{
    let MinNorm { x, factor } = min_norm(j, b, metric, rank_tolerance)?;
    let r = j * x - b;
    let residual = r.norm();
    if !residual.is_finite() {
        return Err(AnalysisError::NonFiniteOutput { quantity: "accelerations", row: None });
    }
    // Consistent up to round-off: relative to the sizes of b and of J x.
    let scale = 1.0 + b.norm() + j.norm() * x.norm();
    if residual > 1e-9 * scale {
        return Err(AnalysisError::Inconsistent { analysis, residual, worst: WorstRows::of::<S, NB, NV, M>(&r) });
    }
    Ok(LinearSolution { x, residual, redundant: RowList::from_rows::<S, NB, NV>(factor.dropped()) })
}
