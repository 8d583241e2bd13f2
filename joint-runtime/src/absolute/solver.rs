//! What the sparse analyses and the sparse simulation share: the block factor
//! of one scene, minimum-norm solves of `J x = b` in a metric, and damped Newton
//! on Φ = 0, reading only the Jacobian's nonzero entries.

use core::marker::PhantomData;

use nalgebra::{Matrix3, SVector};

use super::BlockFactor;
use crate::analysis::{
    Analysis, AnalysisError, AssemblyOptions, Directions, InverseMass, NewtonWork, RowList, WorstRows, apply_metric,
    apply_metric_in_place, damped_newton,
};
use crate::scene::{Scene, SparseJacobian, SystemState};

/// The identity metric: minimum-norm solves in the Euclidean sense.
pub(crate) fn unit_metric<const NB: usize>() -> [InverseMass; NB] {
    [InverseMass { inv_mass: 1.0, inv_inertia: Matrix3::identity() }; NB]
}

/// `J x`: the scene's generated product, or a walk of the CSR entries.
pub(crate) fn j_mul<S: SparseJacobian<NB, NNZ>, const NB: usize, const NNZ: usize, const NV: usize, const M: usize>(
    values: &[f64; NNZ],
    x: &SVector<f64, NV>,
) -> SVector<f64, M> {
    let mut out = SVector::<f64, M>::zeros();
    j_mul_into::<S, NB, NNZ>(values, x.as_slice(), out.as_mut_slice());
    out
}

/// `Jᵀ y`: the scene's generated product, or a walk of the CSR entries.
pub(crate) fn jt_mul<S: SparseJacobian<NB, NNZ>, const NB: usize, const NNZ: usize, const NV: usize, const M: usize>(
    values: &[f64; NNZ],
    y: &SVector<f64, M>,
) -> SVector<f64, NV> {
    let mut out = SVector::<f64, NV>::zeros();
    jt_mul_into::<S, NB, NNZ>(values, y.as_slice(), out.as_mut_slice());
    out
}

/// `out = J x` into a vector of the scene's rows.
pub(crate) fn j_mul_into<S: SparseJacobian<NB, NNZ>, const NB: usize, const NNZ: usize>(
    values: &[f64; NNZ],
    x: &[f64],
    out: &mut [f64],
) {
    if S::j_mul_into(values, x, out) {
        return;
    }
    out.fill(0.0);
    for (o, (row, columns)) in out.iter_mut().zip(rows::<S, NB, NNZ>(values)) {
        let mut sum = 0.0;
        for (v, &c) in row.iter().zip(columns) {
            sum += v * x.get(c).copied().unwrap_or(0.0);
        }
        *o = sum;
    }
}

/// `out = Jᵀ y` into a vector of the scene's columns.
pub(crate) fn jt_mul_into<S: SparseJacobian<NB, NNZ>, const NB: usize, const NNZ: usize>(
    values: &[f64; NNZ],
    y: &[f64],
    out: &mut [f64],
) {
    if S::jt_mul_into(values, y, out) {
        return;
    }
    out.fill(0.0);
    for (&yr, (row, columns)) in y.iter().zip(rows::<S, NB, NNZ>(values)) {
        for (v, &c) in row.iter().zip(columns) {
            if let Some(o) = out.get_mut(c) {
                *o += v * yr;
            }
        }
    }
}

/// Each row's entries and their columns, in row order.
// Slices of the rows, walked once: per-row look-ups and `skip(start)` over all
// entries cost a 10-bar chain's RK4 step an eighth of its instructions.
fn rows<S: SparseJacobian<NB, NNZ>, const NB: usize, const NNZ: usize>(
    values: &[f64; NNZ],
) -> impl Iterator<Item = (&[f64], &'static [usize])> {
    S::ROW_STARTS.windows(2).map(move |w| match *w {
        [a, b] => (values.get(a..b).unwrap_or(&[]), S::COLUMNS.get(a..b).unwrap_or(&[])),
        _ => (&[][..], &[][..]),
    })
}

pub(crate) fn non_finite(quantity: &'static str) -> AnalysisError {
    AnalysisError::NonFiniteOutput { quantity, row: None }
}

/// The block factor of one scene type and the solves on it.
pub(crate) struct Solver<S: SparseJacobian<NB, NNZ>, const NB: usize, const NV: usize, const M: usize, const NNZ: usize>
{
    pub(crate) factor: BlockFactor<S::Factor>,
    scene: PhantomData<fn() -> S>,
}

impl<S, const NB: usize, const NV: usize, const M: usize, const NNZ: usize> Solver<S, NB, NV, M, NNZ>
where
    S: Scene<NB, NV, M> + SparseJacobian<NB, NNZ>,
{
    /// The factor's schedule, from the scene's compile-time structure.
    pub(crate) fn new() -> Result<Self, AnalysisError> {
        crate::analysis::check_dims::<NB, NV>()?;
        let factor = BlockFactor::new(
            S::BLOCKS,
            S::BLOCK_BODIES,
            S::ROW_STARTS,
            &S::COLUMNS,
            S::ELIMINATION,
            S::FACTOR_STARTS,
            S::FACTOR_BELOW,
        )?;
        Ok(Solver { factor, scene: PhantomData })
    }

    /// `x = W Jᵀ y` with `(J W Jᵀ) y = b`: the solution of `J x = b` closest
    /// to zero in the metric `W` (its dropped rows: [`BlockFactor::dropped`]).
    pub(crate) fn min_norm(
        &mut self,
        values: &[f64; NNZ],
        b: SVector<f64, M>,
        w: &[InverseMass; NB],
        tolerance: f64,
    ) -> Result<SVector<f64, NV>, AnalysisError> {
        self.factorise(values, w, tolerance)?;
        Ok(self.min_norm_factored(values, b, w))
    }

    /// `J W Jᵀ` factorised afresh (no pivot rule) for the values `values`.
    pub(crate) fn factorise(
        &mut self,
        values: &[f64; NNZ],
        w: &[InverseMass; NB],
        tolerance: f64,
    ) -> Result<(), AnalysisError> {
        self.factorise_by(values, w, tolerance, false)
    }

    /// `J W Jᵀ` factorised for the values `values`, under the kept pivot
    /// rule with `keep`: by the scene's generated blocks and program where
    /// it has them.
    pub(crate) fn factorise_by(
        &mut self,
        values: &[f64; NNZ],
        w: &[InverseMass; NB],
        tolerance: f64,
        keep: bool,
    ) -> Result<(), AnalysisError> {
        self.factor
            .factor(values, w, tolerance, keep, |f| S::normal_blocks_into(values, w, f), S::factor_program)
            .map_err(|_| non_finite("J"))
    }

    /// Solves `J W Jᵀ λ = b` in place on the last factorisation.
    pub(crate) fn solve(&mut self, b: &mut [f64]) {
        self.factor.solve_by(b, S::solve_program);
    }

    /// [`Solver::min_norm`] on the factor as it stands: `values` and `w` must
    /// be those it was last factorised with.
    pub(crate) fn min_norm_factored(
        &mut self,
        values: &[f64; NNZ],
        b: SVector<f64, M>,
        w: &[InverseMass; NB],
    ) -> SVector<f64, NV> {
        let mut y = b;
        self.solve(y.as_mut_slice());
        apply_metric::<NB, NV>(Some(w), &jt_mul::<S, NB, NNZ, NV, M>(values, &y))
    }

    /// [`Solver::min_norm_factored`] with `b` solved in place (it becomes
    /// `y`) and `x` written into `out`: no vector in this frame.
    pub(crate) fn min_norm_factored_in_place(
        &mut self,
        values: &[f64; NNZ],
        b: &mut SVector<f64, M>,
        w: &[InverseMass; NB],
        out: &mut SVector<f64, NV>,
    ) {
        self.solve(b.as_mut_slice());
        jt_mul_into::<S, NB, NNZ>(values, b.as_slice(), out.as_mut_slice());
        apply_metric_in_place(w, out);
    }

    /// [`Solver::min_norm`] in place, as [`Solver::min_norm_factored_in_place`].
    pub(crate) fn min_norm_in_place(
        &mut self,
        values: &[f64; NNZ],
        b: &mut SVector<f64, M>,
        w: &[InverseMass; NB],
        tolerance: f64,
        out: &mut SVector<f64, NV>,
    ) -> Result<(), AnalysisError> {
        self.factorise(values, w, tolerance)?;
        self.min_norm_factored_in_place(values, b, w, out);
        Ok(())
    }

    /// [`Solver::min_norm`], then the consistency check of the dense
    /// `solve_linear`: the residual within round-off of `b` and `J x`.
    pub(crate) fn solve_linear(
        &mut self,
        analysis: Analysis,
        values: &[f64; NNZ],
        b: SVector<f64, M>,
        w: &[InverseMass; NB],
        tolerance: f64,
    ) -> Result<(SVector<f64, NV>, f64), AnalysisError> {
        let x = self.min_norm(values, b, w, tolerance)?;
        let r = j_mul::<S, NB, NNZ, NV, M>(values, &x) - b;
        let residual = r.norm();
        if !residual.is_finite() {
            return Err(non_finite("solution"));
        }
        let j_norm = libm::sqrt(values.iter().map(|v| v * v).sum::<f64>());
        if residual > 1e-9 * (1.0 + b.norm() + j_norm * x.norm()) {
            return Err(AnalysisError::Inconsistent { analysis, residual, worst: WorstRows::of::<S, NB, NV, M>(&r) });
        }
        Ok((x, residual))
    }

    /// The rows the last factorisation dropped, by joint.
    pub(crate) fn redundant(&self) -> RowList<M> {
        RowList::from_rows::<S, NB, NV>(self.factor.dropped())
    }

    /// Damped Newton on Φ = 0 with minimum-norm steps in the metric `w`, as
    /// the dense assembly (the same iteration, with this factor's steps).
    pub(crate) fn newton(
        &mut self,
        scene: &S,
        state: &mut SystemState<NB>,
        options: &AssemblyOptions,
        w: &[InverseMass; NB],
        values: &mut [f64; NNZ],
        work: &mut NewtonWork<NB, NV, M>,
    ) -> Result<(usize, f64), AnalysisError> {
        damped_newton(
            scene,
            state,
            options,
            &mut Sparse { solver: self, scene, w, values, rank_tolerance: options.rank_tolerance },
            work,
        )
    }
}

/// The block factor's Newton directions; at the end, a factorisation and no
/// solve.
struct Sparse<'s, S: SparseJacobian<NB, NNZ>, const NB: usize, const NV: usize, const M: usize, const NNZ: usize> {
    solver: &'s mut Solver<S, NB, NV, M, NNZ>,
    scene: &'s S,
    w: &'s [InverseMass; NB],
    /// `J`'s values, written in place (the caller's buffer).
    values: &'s mut [f64; NNZ],
    rank_tolerance: f64,
}

impl<S, const NB: usize, const NV: usize, const M: usize, const NNZ: usize> Directions<NB, NV, M>
    for Sparse<'_, S, NB, NV, M, NNZ>
where
    S: Scene<NB, NV, M> + SparseJacobian<NB, NNZ>,
{
    fn step(
        &mut self,
        state: &SystemState<NB>,
        b: &mut SVector<f64, M>,
        delta: &mut SVector<f64, NV>,
    ) -> Result<(), AnalysisError> {
        self.scene.jacobian_values_into(state, self.values);
        self.solver.min_norm_in_place(self.values, b, self.w, self.rank_tolerance, delta)
    }

    fn factor_at(&mut self, state: &SystemState<NB>) -> Result<(), AnalysisError> {
        self.scene.jacobian_values_into(state, self.values);
        self.solver.factorise(self.values, self.w, self.rank_tolerance)
    }
}
