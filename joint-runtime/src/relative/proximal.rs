//! The proximal solve of the constrained dynamics (Carpentier, Budhiraja
//! and Mansard, RSS 2021): for rows that depend on one another (a contact
//! declared twice, a weld beside a point of the same frame, a loop closed
//! by more rows than it has), `λ` is not unique; the proximal iterations
//! `(S + μ I) λₖ₊₁ = r + μ λₖ` from `λ₀ = 0` converge to the one of least
//! norm (the error along each eigenvector of `S` shrinks by `μ / (σ + μ)`
//! an iteration, and nothing ever enters `S`'s null space), and `q̈` to the
//! exact one. The pivoted solve of
//! [`constrained_dynamics`](super::TreeSimulation::constrained_dynamics)
//! gives the same `q̈` and a basic `λ` (dropped rows carry nothing).

use nalgebra::SVector;

use super::{ActiveRows, ConstrainedDerivatives, TreeError, TreeScene, TreeSimulation, TreeState};
use crate::linalg::PivotedCholesky;

/// The proximal iterations' settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Proximal {
    /// The proximal weight `μ`, relative to the largest diagonal entry of
    /// `S` (scale-free, where Pinocchio's `mu` is absolute), positive. The
    /// least-norm `λ` is reached to about `ε / μ` (rounding in the shifted
    /// factor enters `S`'s null space and stays), each iteration shrinking
    /// the rest by `μ / (σ + μ)`: 1e-6 balances the two.
    pub mu: f64,
    /// Stop when no force moved by more than this times the largest one (or
    /// 1). Above the rounding that enters `S`'s null space each iteration
    /// (about `ε / μ`), or the iterations may not stop.
    pub tolerance: f64,
    /// At most this many iterations.
    pub max_iterations: usize,
}

impl Default for Proximal {
    /// `μ = 1e-6` of `S`'s largest diagonal entry, tolerance `1e-9`, at
    /// most 50 iterations.
    fn default() -> Self {
        Proximal { mu: 1e-6, tolerance: 1e-9, max_iterations: 50 }
    }
}

impl<
    S: TreeScene<NB, NQ, NV, NC>,
    L: crate::dynamics::AppliedLoads<NB>,
    const NB: usize,
    const NQ: usize,
    const NV: usize,
    const NC: usize,
> TreeSimulation<'_, S, NB, NQ, NV, NC, L>
{
    /// `q̈` and the least-norm `λ` at `state` under `tau` with the rows of
    /// `active` holding, by the proximal iterations (the module), into
    /// `out.qdd`, `out.lambda` (`out.d_tau`: `M⁻¹`); the number of
    /// iterations. [`TreeError::NonFinite`] for a `μ` that is not positive
    /// and finite, or iterations that did not converge. Allocation-free.
    pub fn constrained_dynamics_proximal(
        &self,
        state: &TreeState<NQ, NV>,
        tau: &SVector<f64, NV>,
        active: ActiveRows,
        proximal: &Proximal,
        out: &mut ConstrainedDerivatives<NV, NC>,
    ) -> Result<usize, TreeError> {
        if !(proximal.mu > 0.0 && proximal.mu.is_finite()) {
            return Err(TreeError::NonFinite);
        }
        let mut kkt = super::constrained::Kkt::new(&self.tree().freedoms);
        let (free, r) = self.kkt_system(state, tau, active, &mut kkt)?;
        let mut shifted = kkt.delassus;
        let scale = (0..NC).map(|i| shifted[(i, i)]).fold(0.0, f64::max);
        let mu = proximal.mu * if scale > 0.0 { scale } else { 1.0 };
        for i in 0..NC {
            shifted[(i, i)] += mu;
        }
        // Positive definite: no row is dropped.
        let factor = PivotedCholesky::new(&shifted, 0.0).map_err(|_| TreeError::NonFinite)?;
        let mut lambda = SVector::<f64, NC>::zeros();
        for k in 1..=proximal.max_iterations {
            let next = factor.solve(&(r + lambda * mu));
            let moved = (next - lambda).amax();
            lambda = next;
            if moved <= proximal.tolerance * lambda.amax().max(1.0) {
                out.lambda = lambda;
                out.qdd = free + kkt.y * lambda;
                out.rank = kkt.rank();
                if !out.qdd.iter().chain(out.lambda.iter()).all(|x| x.is_finite()) {
                    return Err(TreeError::NonFinite);
                }
                return Ok(k);
            }
        }
        Err(TreeError::NonFinite)
    }
}
