//! The kinematic analyses on dense matrices (feature `__dense_reference`, not
//! part of the API): `J` as an `M × NV` nalgebra matrix and the Gram matrix
//! `J Jᵀ` factorised whole, the tests' independent reference for
//! [`Analyses`](super::Analyses) on the block factor.

use nalgebra::{SMatrix, SVector};

use super::newton::{Directions, NewtonWork, damped_newton};
use super::{
    AccelerationAnalysis, Analysis, AnalysisError, Assembly, AssemblyOptions, Metric, RowList, VelocityAnalysis,
    WorstRows, check_output, check_state, set_velocities,
};
use crate::linalg::{DEFAULT_RANK_TOLERANCE, PivotedCholesky};
use crate::scene::{Scene, SystemState};

/// Assembles the mechanism: moves `state`'s positions and orientations onto
/// Φ = 0 by damped Newton from a rough configuration.
///
/// Each iteration solves `J Δ = −Φ` in the minimum-norm least-squares sense
/// (`Δ = Jᵀ y`, `(J Jᵀ) y = −Φ` by [`PivotedCholesky`](crate::linalg::PivotedCholesky)), then tries `r += α Δr`,
/// `p ← p ⊗ q(α Δθ')` for `α = 1, ½, ¼, …` until ‖Φ‖₂ decreases (Armijo). The
/// Euler parameters are normalised first (a rough `p` need not be unit).
/// Velocities and time are not touched.
///
/// # Errors
/// [`AnalysisError::NonFinite`] names the body and field of a NaN/infinite
/// position input; [`AnalysisError::NotConverged`] after `max_iterations`;
/// [`AnalysisError::NoProgress`] when no step reduces ‖Φ‖ (singular or
/// impossible). Both name the rows with the largest residuals. On error `state`
/// holds the last accepted iterate.
pub fn assemble<S, const NB: usize, const NV: usize, const M: usize>(
    scene: &S,
    state: &mut SystemState<NB>,
    options: &AssemblyOptions,
) -> Result<Assembly<M>, AnalysisError>
where
    S: Scene<NB, NV, M>,
{
    newton(scene, state, options, None)
}

/// Velocity analysis: solves `J v = −Φ_t` (minimum norm) at `state`'s
/// configuration and writes every body's `ṙ` and `ω'`. Degrees of freedom not
/// fixed by the constraints (or drivers) get zero velocity; use this on a fully
/// driven mechanism, or to start from rest.
///
/// # Errors
/// Non-finite inputs or outputs; [`AnalysisError::Inconsistent`] when redundant
/// rows contradict the others. Redundant but consistent rows are reported in the
/// result.
pub fn velocities<S, const NB: usize, const NV: usize, const M: usize>(
    scene: &S,
    state: &mut SystemState<NB>,
) -> Result<VelocityAnalysis<M>, AnalysisError>
where
    S: Scene<NB, NV, M>,
{
    velocities_with(scene, state, DEFAULT_RANK_TOLERANCE)
}

/// [`velocities`] with a chosen relative rank tolerance.
pub fn velocities_with<S, const NB: usize, const NV: usize, const M: usize>(
    scene: &S,
    state: &mut SystemState<NB>,
    rank_tolerance: f64,
) -> Result<VelocityAnalysis<M>, AnalysisError>
where
    S: Scene<NB, NV, M>,
{
    check_state::<S, NB, NV, M>(state, false)?;
    let j = scene.jacobian(state);
    check_output::<S, NB, NV, M, NV>("J", &j)?;
    let phi_t = scene.phi_t(state);
    check_output::<S, NB, NV, M, 1>("Φ_t", &phi_t)?;
    let solution = solve_linear::<S, NB, NV, M>(Analysis::Velocity, &j, &(-phi_t), None, rank_tolerance)?;
    set_velocities(state, &solution.x);
    Ok(VelocityAnalysis { residual: solution.residual, redundant: solution.redundant })
}

/// Acceleration analysis: the minimum-norm solution of `J v̇ = γ` at `state`.
///
/// # Errors
/// As [`velocities`].
pub fn accelerations<S, const NB: usize, const NV: usize, const M: usize>(
    scene: &S,
    state: &SystemState<NB>,
) -> Result<AccelerationAnalysis<NV, M>, AnalysisError>
where
    S: Scene<NB, NV, M>,
{
    accelerations_with(scene, state, DEFAULT_RANK_TOLERANCE)
}

/// [`accelerations`] with a chosen relative rank tolerance.
pub fn accelerations_with<S, const NB: usize, const NV: usize, const M: usize>(
    scene: &S,
    state: &SystemState<NB>,
    rank_tolerance: f64,
) -> Result<AccelerationAnalysis<NV, M>, AnalysisError>
where
    S: Scene<NB, NV, M>,
{
    check_state::<S, NB, NV, M>(state, true)?;
    let e = scene.evaluate(state);
    check_output::<S, NB, NV, M, NV>("J", &e.jacobian)?;
    check_output::<S, NB, NV, M, 1>("γ", &e.gamma)?;
    let solution = solve_linear::<S, NB, NV, M>(Analysis::Acceleration, &e.jacobian, &e.gamma, None, rank_tolerance)?;
    Ok(AccelerationAnalysis { vdot: solution.x, residual: solution.residual, redundant: solution.redundant })
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
/// Damped Newton on Φ = 0 with minimum-norm steps in the metric.
pub(crate) fn newton<S, const NB: usize, const NV: usize, const M: usize>(
    scene: &S,
    state: &mut SystemState<NB>,
    options: &AssemblyOptions,
    metric: Metric<'_, NB>,
) -> Result<Assembly<M>, AnalysisError>
where
    S: Scene<NB, NV, M>,
{
    let mut dense = Dense { scene, metric, rank_tolerance: options.rank_tolerance, redundant: RowList::default() };
    let (iterations, residual) = damped_newton(scene, state, options, &mut dense, &mut NewtonWork::new())?;
    Ok(Assembly { iterations, residual, redundant: dense.redundant })
}

/// The dense solver's directions, and the rows its last factorisation dropped.
struct Dense<'s, S, const NB: usize, const M: usize> {
    scene: &'s S,
    metric: Metric<'s, NB>,
    rank_tolerance: f64,
    redundant: RowList<M>,
}

impl<S: Scene<NB, NV, M>, const NB: usize, const NV: usize, const M: usize> Directions<NB, NV, M>
    for Dense<'_, S, NB, M>
{
    fn step(
        &mut self,
        state: &SystemState<NB>,
        b: &mut SVector<f64, M>,
        delta: &mut SVector<f64, NV>,
    ) -> Result<(), AnalysisError> {
        let j = self.scene.jacobian(state);
        check_output::<S, NB, NV, M, NV>("J", &j)?;
        *delta = min_norm(&j, b, self.metric, self.rank_tolerance)?.x;
        Ok(())
    }

    fn factor_at(&mut self, state: &SystemState<NB>) -> Result<(), AnalysisError> {
        let j = self.scene.jacobian(state);
        check_output::<S, NB, NV, M, NV>("J", &j)?;
        let step = min_norm(&j, &SVector::<f64, M>::zeros(), self.metric, self.rank_tolerance)?;
        self.redundant = RowList::from_rows::<S, NB, NV>(step.factor.dropped());
        Ok(())
    }
}
