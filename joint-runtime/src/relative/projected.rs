//! The derivative of a step's projection: the step's end closed onto its
//! loops as [`step_with`](super::TreeSimulation::step_with) closes it
//! (simplified Newton on `Φ(q) = 0` in the mass metric of the end it starts
//! from, then `v` onto `J v + Φ_t = 0` with the same factor), differentiated
//! along the same iterations, so that a projected RK4 step has its exact
//! Jacobian.
//!
//! With `G r = M⁻¹ Jᵀ S⁺ r` at the unprojected end `q₀` (`S = J M⁻¹ Jᵀ`,
//! `S⁺` its pivoted factor's solve), `μ = S⁺ r` and `y = G r`, the
//! derivative of `G r` along `δq₀` for a fixed `r` is `a + M⁻¹ Jᵀ dμ`, with
//! `a = M⁻¹ (K(μ) − ∂(M y)/∂q) δq₀` and `dμ = −S⁺ (∂(J y)/∂q δq₀ + J a)`
//! (from `J y = r` on the kept rows). `K` and `∂(J y)/∂q` are the derive's
//! second-order terms, `∂(M y)/∂q` the tree's derivative pass. Each Newton
//! iteration `q ← q ⊕ (−G Φ(q))` and each velocity correction
//! `v ← v − G (J v + Φ_t)` is then a product of known derivatives. The
//! iterations are the projection's own (its count replayed, and at least
//! one): the Jacobian is the derivative of the projection onto the closed
//! loop, which the step's iterations reach to their tolerance (an end
//! already within it is not moved, while its neighbours off the loop are).

use nalgebra::{SMatrix, SVector};

use super::constrained::mask_rows;
use super::simulation::Saddle;
use super::{InverseDerivatives, StepJacobian, TreeError, TreeScene, TreeSimulation, TreeState};

type Block<const NV: usize> = SMatrix<f64, NV, NV>;

/// What every correction's derivative reads at the unprojected end.
struct At<'s, const NQ: usize, const NV: usize, const NC: usize> {
    state: &'s TreeState<NQ, NV>,
    saddle: &'s Saddle<NV, NC>,
    minv: Block<NV>,
    jacobian: SMatrix<f64, NC, NV>,
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
    /// Projects `end` (the step's unprojected, renormalised end) as the
    /// step does and takes `out` (the Jacobian of that end) through the
    /// projection's derivative. Errors as the step's projection.
    pub(super) fn project_chain(
        &self,
        end: &mut TreeState<NQ, NV>,
        work: &mut InverseDerivatives<NV>,
        out: &mut StepJacobian<NV>,
    ) -> Result<(), TreeError> {
        let raw = *end;
        let (done, _, _) = self.close(end, self.projection(), (false, true))?;
        let rows = self.held_rows(&raw);
        let saddle = self.saddle(&raw.q, &rows.jacobian, None, None)?;
        let mut m = Block::<NV>::zeros();
        self.mass_matrix_into(&raw.q, &mut m);
        let mut minv = Block::<NV>::zeros();
        let joint = self.tree().joints.first().map_or("", |j| j.name);
        super::derivatives::spd_inverse(&m, &mut minv).ok_or(TreeError::Singular { joint })?;
        let at = At { state: &raw, saddle: &saddle, minv, jacobian: rows.jacobian };
        // The Newton iterations: δq_{i+1} = T δq_i + R δΔ_i, Δ_i = −G Φ(q_i).
        // At least one: an end already within the tolerance is not moved,
        // but a neighbour off the loop is, so the derivative is the closed
        // loop's (`I − G J` on the first), not the identity.
        // `∂Φ/∂q` is `J` on a loop's rows and zero on a contact's (it has
        // no position: its zero residual holds the foot where it is).
        let positioned = Self::POSITIONED;
        let (mut q, mut rows, mut d) = (raw, rows, Block::<NV>::identity());
        for i in 0..done.max(1) {
            let delta = -saddle.correction(&rows.phi);
            let mut phi_q = rows.jacobian * d;
            mask_rows(&positioned, &mut phi_q);
            let d_delta = -(self.correction_derivative(&at, &rows.phi, work)? + through(&saddle, &phi_q));
            let (transport, right) = self.displace_derivative(&delta);
            d = transport * d + right * d_delta;
            if i < done {
                self.tree().displace(&mut q.q, &delta);
                rows = self.held_rows(&q);
            }
        }
        // The velocity corrections, against δq₀ (`v_q`) and δv₀ (`v_v`).
        let moved = TreeState { v: raw.v, ..q };
        let rate = self.held_terms(&moved, &raw.v, true)?;
        let mut drift = rows.jacobian * raw.v + rows.phi_t;
        let (mut drift_q, mut drift_v) = (rate * d, rows.jacobian);
        let (mut v_q, mut v_v) = (Block::<NV>::zeros(), Block::<NV>::identity());
        for _ in 0..if done > 0 { 2 } else { 1 } {
            let correction = saddle.correction(&drift);
            let dc_q = self.correction_derivative(&at, &drift, work)? + through(&saddle, &drift_q);
            let dc_v = through(&saddle, &drift_v);
            v_q -= dc_q;
            v_v -= dc_v;
            let turned = self.held_terms(&moved, &correction, false)? * d;
            drift -= rows.jacobian * correction;
            drift_q -= turned + rows.jacobian * dc_q;
            drift_v -= rows.jacobian * dc_v;
        }
        let raw_out = *out;
        let pairs = [(&mut out.q_q, &mut out.v_q), (&mut out.q_v, &mut out.v_v), (&mut out.q_tau, &mut out.v_tau)];
        for ((q_block, v_block), (rq, rv)) in pairs.into_iter().zip([
            (&raw_out.q_q, &raw_out.v_q),
            (&raw_out.q_v, &raw_out.v_v),
            (&raw_out.q_tau, &raw_out.v_tau),
        ]) {
            *q_block = d * rq;
            *v_block = v_q * rq + v_v * rv;
        }
        Ok(())
    }

    /// `∂(G r)/∂q₀` for a fixed `r` (the module's formula), `NV × NV`.
    fn correction_derivative(
        &self,
        at: &At<'_, NQ, NV, NC>,
        r: &SVector<f64, NC>,
        work: &mut InverseDerivatives<NV>,
    ) -> Result<Block<NV>, TreeError> {
        let mu = at.saddle.factor.solve(r);
        let y = at.saddle.minv_jt * mu;
        let second = self.second_order_at(at.state, &mu, &y)?;
        let mut turned = second.jacobian_q;
        mask_rows(&self.held_mask(), &mut turned);
        self.tree().mass_product_derivative(&at.state.q, &y, work);
        let a = at.minv * (second.stiffness - work.d_q);
        Ok(a - through(at.saddle, &(turned + at.jacobian * a)))
    }

    /// `∂(J u)/∂q` on the rows that hold at `state`, and `∂Φ_t/∂q` with
    /// it when `rate` (the rows' velocity `J v + Φ_t`).
    fn held_terms(
        &self,
        state: &TreeState<NQ, NV>,
        u: &SVector<f64, NV>,
        rate: bool,
    ) -> Result<SMatrix<f64, NC, NV>, TreeError> {
        let second = self.second_order_at(state, &SVector::zeros(), u)?;
        let mut out = if rate { second.jacobian_q + second.phi_t_q } else { second.jacobian_q };
        mask_rows(&self.held_mask(), &mut out);
        Ok(out)
    }

    /// The rows the projection holds: all but MuJoCo's soft ones.
    fn held_mask(&self) -> [bool; NC] {
        self.soft.soft.map(|soft| !soft)
    }

    /// The rows with a position `Φ`: all but the contacts'. A constant of
    /// the scene, evaluated when it compiles (no run-time loop to prove).
    pub(super) const POSITIONED: [bool; NC] = positioned(S::CLOSURES, S::CONTACTS);
}

/// `[true; NC]` with the contacts' blocks of `closures` set to `false`.
const fn positioned<const NC: usize>(closures: &[crate::RowBlock], contacts: &[super::Contact]) -> [bool; NC] {
    let mut out = [true; NC];
    let mut c = 0;
    while c < contacts.len() {
        if contacts[c].block < closures.len() {
            let block = &closures[contacts[c].block];
            let mut r = block.start;
            while r < block.start + block.rows && r < NC {
                out[r] = false;
                r += 1;
            }
        }
        c += 1;
    }
    out
}

/// `G X = M⁻¹ Jᵀ S⁺ X`, column by column.
fn through<const NV: usize, const NC: usize>(saddle: &Saddle<NV, NC>, x: &SMatrix<f64, NC, NV>) -> Block<NV> {
    let mut out = Block::<NV>::zeros();
    for (mut target, column) in out.column_iter_mut().zip(x.column_iter()) {
        target.copy_from(&saddle.correction(&column.into_owned()));
    }
    out
}
