//! Impacts: the velocity just after contacts are made (or loops snap
//! shut), and the impulses, with their exact derivatives (Pinocchio's
//! `impulseDynamics`). With restitution `e` on the active rows,
//! `M (v⁺ − v) = Jᵀ Λ` and `J v⁺ = −e J v`, so `Λ = −(1 + e) S⁻¹ J v` and
//! `v⁺ = v + M⁻¹ Jᵀ Λ` (`S = J M⁻¹ Jᵀ`, dependent rows dropped as the
//! dynamics drop them).
//!
//! Differentiating the same two equations: with `w = v⁺ − v` held,
//! `∂(M w)/∂q` is the inverse dynamics' `∂τ/∂q` at zero velocity and
//! accelerations `w` less the same at zero accelerations (gravity
//! cancels), `K = ∂(JᵀΛ)/∂q` and `∂(J u)/∂q` at `u = v⁺ + e v` are the
//! closures' second-order terms. Then `∂v⁺/∂v = I − (1 + e) M⁻¹ Jᵀ S⁻¹ J`:
//! the identity Pinocchio's `computeImpulseDynamicsDerivatives` leaves out.

use nalgebra::{SMatrix, SVector};

use super::constrained::{Kkt, mask_rows};
use super::simulation::finite_inputs;
use super::{ActiveRows, InverseDerivatives, TreeError, TreeScene, TreeSimulation, TreeState};
use crate::linalg::{finite, gemm};

/// An impact's outcome at one state: the velocity after it, the impulses,
/// and their first derivatives (`∂/∂q` in tangent columns).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImpulseDerivatives<const NV: usize, const NC: usize> {
    /// `v⁺`.
    pub v_after: SVector<f64, NV>,
    /// `Λ`, in the closures' row order and axes (zero on inactive rows).
    pub impulse: SVector<f64, NC>,
    /// `∂v⁺/∂q`.
    pub v_after_q: SMatrix<f64, NV, NV>,
    /// `∂v⁺/∂v`.
    pub v_after_v: SMatrix<f64, NV, NV>,
    /// `∂Λ/∂q`.
    pub impulse_q: SMatrix<f64, NC, NV>,
    /// `∂Λ/∂v`.
    pub impulse_v: SMatrix<f64, NC, NV>,
}

impl<const NV: usize, const NC: usize> ImpulseDerivatives<NV, NC> {
    /// All zero.
    pub fn zeros() -> Self {
        ImpulseDerivatives {
            v_after: SVector::zeros(),
            impulse: SVector::zeros(),
            v_after_q: SMatrix::zeros(),
            v_after_v: SMatrix::zeros(),
            impulse_q: SMatrix::zeros(),
            impulse_v: SMatrix::zeros(),
        }
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
    /// The impact of the rows of `active` at `state` with restitution
    /// `restitution` (0: the rows' velocity stops; 1: it turns back):
    /// `out.v_after` and `out.impulse` (the derivatives untouched).
    /// [`TreeError::NonFinite`] for a state that is not finite or a
    /// restitution outside `0 ..= 1`. Allocation-free.
    pub fn impact(
        &self,
        state: &TreeState<NQ, NV>,
        active: ActiveRows,
        restitution: f64,
        out: &mut ImpulseDerivatives<NV, NC>,
    ) -> Result<(), TreeError> {
        let mut kkt = Kkt::forward(&self.tree().freedoms);
        self.impulses(state, active, restitution, out, &mut kkt)
    }

    /// The impact and its exact first derivatives (the module's method);
    /// `work` holds the inverse dynamics' derivatives on the way. Errors as
    /// [`impact`](Self::impact), and [`TreeError::NotDerived`] where the
    /// derive did not write the closures' second-order terms.
    /// Allocation-free.
    pub fn impact_derivatives(
        &self,
        state: &TreeState<NQ, NV>,
        active: ActiveRows,
        restitution: f64,
        work: &mut InverseDerivatives<NV>,
        out: &mut ImpulseDerivatives<NV, NC>,
    ) -> Result<(), TreeError> {
        let mut kkt = Kkt::new(&self.tree().freedoms);
        self.impulses(state, active, restitution, out, &mut kkt)?;
        // ∂(M w)/∂q: the tree's pass without gravity or springs; the
        // derive's written derivatives hold gravity, so there it is Newton–
        // Euler's ∂τ/∂q at rest with accelerations w, less at rest alone.
        let jump = out.v_after - state.v;
        let m_w_q = if S::DERIVATIVES {
            let rest = TreeState { v: SVector::zeros(), ..*state };
            self.derivatives_at(&rest, &jump, work)?;
            let moved = work.d_q;
            self.derivatives_at(&rest, &SVector::zeros(), work)?;
            moved - work.d_q
        } else {
            self.tree().mass_product_derivative(&state.q, &jump, work);
            work.d_q
        };
        let u = out.v_after + state.v * restitution;
        let second = self.second_order_at(state, &out.impulse, &u)?;
        let r1_q = second.stiffness - m_w_q;
        let mut r2_q = -second.jacobian_q;
        mask_rows(&kkt.mask, &mut r2_q);
        let mut minv = SMatrix::<f64, NV, NV>::zeros();
        kkt.mass.inverse_into(&mut minv);
        let sinv = kkt.factor.inverse();
        let mut rows = r2_q;
        gemm(&mut rows, -1.0, &kkt.y.transpose(), &r1_q, 1.0);
        gemm(&mut out.impulse_q, 1.0, &sinv, &rows, 0.0);
        gemm(&mut out.v_after_q, 1.0, &minv, &r1_q, 0.0);
        gemm(&mut out.v_after_q, 1.0, &kkt.y, &out.impulse_q, 1.0);
        // ∂Λ/∂v = −(1 + e) S⁻¹ J, ∂v⁺/∂v = I + Y ∂Λ/∂v.
        gemm(&mut out.impulse_v, -(1.0 + restitution), &sinv, &kkt.jacobian, 0.0);
        out.v_after_v = SMatrix::identity();
        gemm(&mut out.v_after_v, 1.0, &kkt.y, &out.impulse_v, 1.0);
        let all = [out.v_after_q.as_slice(), out.impulse_q.as_slice(), out.v_after_v.as_slice()];
        if !all.iter().all(|m| finite(m)) {
            return Err(TreeError::NonFinite);
        }
        Ok(())
    }

    /// `v⁺` and `Λ` into `out`; the factors for the derivatives.
    fn impulses(
        &self,
        state: &TreeState<NQ, NV>,
        active: ActiveRows,
        restitution: f64,
        out: &mut ImpulseDerivatives<NV, NC>,
        kkt: &mut Kkt<'_, NV, NC>,
    ) -> Result<(), TreeError> {
        finite_inputs(state, &[])?;
        if !(0.0..=1.0).contains(&restitution) {
            return Err(TreeError::NonFinite);
        }
        let rows = self.closure_rows(state);
        self.delassus(state, &rows.jacobian, active, kkt)?;
        out.impulse = kkt.factor.solve(&(kkt.jacobian * state.v * -(1.0 + restitution)));
        out.v_after = state.v + kkt.velocity_jump(&out.impulse);
        if !out.v_after.iter().chain(out.impulse.iter()).all(|x| x.is_finite()) {
            return Err(TreeError::NonFinite);
        }
        Ok(())
    }
}
