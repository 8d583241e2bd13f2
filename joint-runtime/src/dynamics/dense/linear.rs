//! The dense path's linearisation and state-transition Jacobian.

use nalgebra::{DMatrix, SMatrix, SVector};

use super::DenseSimulation;
use crate::analysis::{AnalysisError, velocity_vector};
use crate::dynamics::AppliedLoads;
use crate::dynamics::linear::*;
use crate::scene::{Scene, SystemState};

impl<S, L, const NB: usize, const NV: usize, const M: usize> DenseSimulation<'_, S, L, NB, NV, M>
where
    S: Scene<NB, NV, M>,
    L: AppliedLoads<NB>,
{
    /// The linearised dynamics about `state` (which should satisfy the
    /// constraints: assemble it first), with `inputs` the generalised-force
    /// direction of each input (`NV × k`, columns laid out as `Q`: forces
    /// inertial, torques in body components; `k = 0` for none).
    ///
    /// # Errors
    /// [`AnalysisError::NoSecondOrder`] for a scene derived without
    /// `second_order`; [`AnalysisError::BadOption`] if `inputs` does not have
    /// `NV` rows; non-finite inputs; failures of the dynamics;
    /// [`AnalysisError::NoConvergence`] if the SVD of J fails.
    pub fn linearise(
        &mut self,
        state: &SystemState<NB>,
        inputs: &DMatrix<f64>,
    ) -> Result<Linearisation, AnalysisError> {
        check_inputs::<S, NB, NV, M>(state, inputs)?;
        let mut rule = self.step_rule(state)?;
        let needed = AnalysisError::NoSecondOrder { needed_by: "the linearisation" };
        let t = self.tangent(state, &mut rule)?.ok_or(needed)?;
        let v = velocity_vector::<NB, NV>(state);
        let lambda = t.dynamics.lambda;
        let second = self.scene.second_order(state, &lambda, &v).ok_or(needed)?;
        let (a_q, a_v) = (t.accelerations(&t.r1q, &t.r2q), t.accelerations(&t.r1v, &t.r2v));
        let mut forced = DMatrix::zeros(NV, inputs.ncols());
        for (k, column) in inputs.column_iter().enumerate() {
            let g = SVector::<f64, NV>::from_iterator(column.iter().copied());
            forced.set_column(k, &t.accelerations(&g, &SVector::<f64, M>::zeros()));
        }
        let dense = |m: &[f64], rows: usize| DMatrix::from_column_slice(rows, NV, m);
        let moved = second.jacobian_q + second.phi_t_q;
        minimal::<NB>(
            v.as_slice(),
            &dense(a_q.as_slice(), NV),
            &dense(a_v.as_slice(), NV),
            &dense(t.j.as_slice(), M),
            &dense(moved.as_slice(), M),
            forced,
        )
    }
}

impl<S, L, const NB: usize, const NV: usize, const M: usize> DenseSimulation<'_, S, L, NB, NV, M>
where
    S: Scene<NB, NV, M>,
    L: AppliedLoads<NB>,
{
    /// One step of the implicit midpoint rule from `state` (without
    /// projection, whatever the options say) and its state-transition
    /// Jacobian, exact: `(δq₁, δv₁) = Φ (δq₀, δv₀)` in the increments of
    /// [`Linearisation`] (`2 NV × 2 NV`), what an extended Kalman filter or an
    /// MPC propagates. By the implicit function theorem on the midpoint
    /// residual `R(w; q₀, v₀) = 0`: `∂w/∂(q₀, v₀) = −R_w⁻¹ R_{(q₀, v₀)}`, with
    /// `R_w` the exact Newton matrix; then `δq₁ = Ad δq₀ + h J_r(h ω') δw`
    /// (`Ad = R(h ω')ᵀ` carries a body increment across the step's turn) and
    /// `δv₁ = 2 δw − δv₀`.
    ///
    /// # Errors
    /// [`AnalysisError::NoSecondOrder`] for a scene derived without
    /// `second_order`; as [`DenseSimulation::step`] otherwise. On error `state` is
    /// unchanged.
    pub fn transition(&mut self, state: &mut SystemState<NB>, h: f64) -> Result<DMatrix<f64>, AnalysisError> {
        let (y0, mut rule) = self.step_start(state, h)?;
        let mut y1 = y0;
        self.step_midpoint(&mut y1, h, &mut rule)?;
        let (v0, v1) = (velocity_vector::<NB, NV>(&y0), velocity_vector::<NB, NV>(&y1));
        let w = (v0 + v1) * 0.5;
        let needed = AnalysisError::NoSecondOrder { needed_by: "the state-transition Jacobian" };
        let (r_w, t) = self.midpoint_tangent(&y0, &w, h, &mut rule, None)?.ok_or(needed)?;
        let a_q = t.accelerations(&t.r1q, &t.r2q);
        let dense = |m: &SMatrix<f64, NV, NV>| DMatrix::from_column_slice(NV, NV, m.as_slice());
        let phi = transition_matrix::<NB, NV>(&w, h, dense(&r_w), &dense(&a_q))?;
        *state = y1;
        self.history = None;
        Ok(phi)
    }
}
