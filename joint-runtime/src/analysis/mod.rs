//! Kinematic analyses of any [`Scene`]: assembly (position analysis), velocity
//! analysis and acceleration analysis.
//!
//! All three solve underdetermined or redundant linear systems `J x = b` in the
//! minimum-norm sense, `x = Jᵀ y` with `(J Jᵀ) y = b`, factorising the Gram
//! matrix on the scene's block pattern ([`BlockFactor`](crate::absolute::BlockFactor):
//! the derive's elimination order, each diagonal block by a rank-revealing
//! pivoted Cholesky), in time and memory proportional to the scene. Rows it
//! drops as dependent are *redundant* and are reported by joint name (via
//! [`Scene::BLOCKS`]) in a [`RowList`]; they receive no correction of their
//! own, which is right when the redundant rows are consistent with the others
//! (a duplicated joint) and shows up as a residual otherwise.
//!
//! [`Analyses`] holds the factor, made once (boxed with `alloc`, inline
//! without); its analyses then allocate nothing and cannot panic
//! (`no-panic-check`), and bad input (NaN, infinities, zero quaternions,
//! impossible configurations) returns an [`AnalysisError`]. The functions
//! [`assemble`], [`velocities`] and [`accelerations`] make one for a single
//! call.
//!
//! Assembly is damped Newton on the rotation group (`α = 1, ½, ¼, …` until
//! `‖Φ‖` decreases), written once over the linear solver that gives its
//! directions (the block factor here, the dense reference in the tests); the
//! dynamics' projection runs the same iteration. At convergence it
//! factorises once more and takes no step, so the redundant rows it reports
//! are the converged state's.
//!
//! Orientation updates stay on the rotation group: a velocity-level increment
//! `Δθ'` (body components, the `ω'` columns of `J`) moves `p ← p ⊗ q(Δθ')` with
//! `q(θ) = [cos(|θ|/2), sin(|θ|/2) θ/|θ|]` (scalar first), then `p` is renormalised.
//! Because `A(p ⊗ q) = A(p) A(q)`, this is the increment whose first-order effect
//! the `omega_body` Jacobian describes.

mod analyses;
#[cfg(feature = "__dense_reference")]
#[doc(hidden)]
pub mod dense;
mod diagnostics;
mod error;
mod motion;
mod newton;
mod solve;

use nalgebra::SVector;

pub use analyses::Analyses;
pub use diagnostics::{RowInfo, RowList, RowResidual, WorstRows};
pub(crate) use diagnostics::{check_dims, check_output, check_state, check_values};
pub use error::{Analysis, AnalysisError};
pub(crate) use motion::{
    apply_increment, normalise_orientations, quat_mul, rotate_body, set_velocities, velocity_vector,
    velocity_vector_into,
};
pub(crate) use newton::{Directions, NewtonWork, damped_newton};
pub use solve::InverseMass;
#[cfg(feature = "__dense_reference")]
pub(crate) use solve::Metric;
pub(crate) use solve::apply_metric;
pub(crate) use solve::{apply_metric_in_place, apply_metric_into};

use crate::linalg::DEFAULT_RANK_TOLERANCE;
use crate::scene::{Scene, SparseJacobian, SystemState};

/// Options of [`assemble`] (and of the projection step of [`crate::dynamics`]).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[non_exhaustive]
#[cfg_attr(feature = "serde", serde(default))]
pub struct AssemblyOptions {
    /// Converged when ‖Φ‖₂ ≤ `tolerance`.
    pub tolerance: f64,
    /// Newton iterations allowed.
    pub max_iterations: usize,
    /// Relative pivot tolerance of the rank-revealing factorisation.
    pub rank_tolerance: f64,
    /// Smallest step fraction the backtracking line search tries before
    /// reporting [`AnalysisError::NoProgress`].
    pub min_step: f64,
}

impl Default for AssemblyOptions {
    fn default() -> Self {
        AssemblyOptions { tolerance: 1e-12, max_iterations: 25, rank_tolerance: DEFAULT_RANK_TOLERANCE, min_step: 1e-4 }
    }
}

/// Options are `#[non_exhaustive]` (more will come); set them from the defaults:
/// `AssemblyOptions::default().with_tolerance(1e-10)`.
impl AssemblyOptions {
    /// Sets [`tolerance`](Self::tolerance).
    pub const fn with_tolerance(mut self, tolerance: f64) -> Self {
        self.tolerance = tolerance;
        self
    }
    /// Sets [`max_iterations`](Self::max_iterations).
    pub const fn with_max_iterations(mut self, max_iterations: usize) -> Self {
        self.max_iterations = max_iterations;
        self
    }
    /// Sets [`rank_tolerance`](Self::rank_tolerance).
    pub const fn with_rank_tolerance(mut self, rank_tolerance: f64) -> Self {
        self.rank_tolerance = rank_tolerance;
        self
    }
    /// Sets [`min_step`](Self::min_step).
    pub const fn with_min_step(mut self, min_step: f64) -> Self {
        self.min_step = min_step;
        self
    }
}

/// The result of [`assemble`].
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
#[non_exhaustive]
pub struct Assembly<const M: usize> {
    /// Newton iterations taken (0 if the configuration was already assembled).
    pub iterations: usize,
    /// Final ‖Φ‖₂.
    pub residual: f64,
    /// Rows found redundant at the final configuration.
    pub redundant: RowList<M>,
}

/// The result of [`velocities`].
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
#[non_exhaustive]
pub struct VelocityAnalysis<const M: usize> {
    /// ‖J v + Φ_t‖₂ after the solve.
    pub residual: f64,
    /// Redundant rows.
    pub redundant: RowList<M>,
}

/// The result of [`accelerations`].
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
#[non_exhaustive]
pub struct AccelerationAnalysis<const NV: usize, const M: usize> {
    /// `v̇ = [r̈_0, ω̇'_0, r̈_1, ...]`: the minimum-norm solution of `J v̇ = γ`.
    pub vdot: SVector<f64, NV>,
    /// ‖J v̇ − γ‖₂.
    pub residual: f64,
    /// Redundant rows.
    pub redundant: RowList<M>,
}

// ---------------------------------------------------------------------------
// Public analyses.

/// Assembles `scene` from `state`'s rough configuration:
/// [`Analyses::assemble`] on analyses made for this one call.
///
/// # Errors
/// As [`Analyses::new`] and [`Analyses::assemble`].
pub fn assemble<S, const NB: usize, const NV: usize, const M: usize, const NNZ: usize>(
    scene: &S,
    state: &mut SystemState<NB>,
    options: &AssemblyOptions,
) -> Result<Assembly<M>, AnalysisError>
where
    S: Scene<NB, NV, M> + SparseJacobian<NB, NNZ>,
{
    Analyses::new(scene)?.assemble(state, options)
}

/// Velocity analysis of `scene` at `state`: [`Analyses::velocities`] on
/// analyses made for this one call.
///
/// # Errors
/// As [`Analyses::new`] and [`Analyses::velocities`].
pub fn velocities<S, const NB: usize, const NV: usize, const M: usize, const NNZ: usize>(
    scene: &S,
    state: &mut SystemState<NB>,
) -> Result<VelocityAnalysis<M>, AnalysisError>
where
    S: Scene<NB, NV, M> + SparseJacobian<NB, NNZ>,
{
    velocities_with(scene, state, DEFAULT_RANK_TOLERANCE)
}

/// [`velocities`] with a chosen relative rank tolerance.
///
/// # Errors
/// As [`velocities`].
pub fn velocities_with<S, const NB: usize, const NV: usize, const M: usize, const NNZ: usize>(
    scene: &S,
    state: &mut SystemState<NB>,
    rank_tolerance: f64,
) -> Result<VelocityAnalysis<M>, AnalysisError>
where
    S: Scene<NB, NV, M> + SparseJacobian<NB, NNZ>,
{
    let mut analyses = Analyses::new(scene)?;
    analyses.rank_tolerance = rank_tolerance;
    analyses.velocities(state)
}

/// Acceleration analysis of `scene` at `state`: [`Analyses::accelerations`]
/// on analyses made for this one call.
///
/// # Errors
/// As [`Analyses::new`] and [`Analyses::accelerations`].
pub fn accelerations<S, const NB: usize, const NV: usize, const M: usize, const NNZ: usize>(
    scene: &S,
    state: &SystemState<NB>,
) -> Result<AccelerationAnalysis<NV, M>, AnalysisError>
where
    S: Scene<NB, NV, M> + SparseJacobian<NB, NNZ>,
{
    accelerations_with(scene, state, DEFAULT_RANK_TOLERANCE)
}

/// [`accelerations`] with a chosen relative rank tolerance.
///
/// # Errors
/// As [`accelerations`].
pub fn accelerations_with<S, const NB: usize, const NV: usize, const M: usize, const NNZ: usize>(
    scene: &S,
    state: &SystemState<NB>,
    rank_tolerance: f64,
) -> Result<AccelerationAnalysis<NV, M>, AnalysisError>
where
    S: Scene<NB, NV, M> + SparseJacobian<NB, NNZ>,
{
    let mut analyses = Analyses::new(scene)?;
    analyses.rank_tolerance = rank_tolerance;
    analyses.accelerations(state)
}
