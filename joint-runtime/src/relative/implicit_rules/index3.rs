//! Generalised-α at index 3 on a tree's loops: `Φ(q_{n+1}, t_{n+1}) = 0`
//! held inside Newton's iteration, as the absolute engine's generalised-α
//! holds it (`dynamics/generalised_alpha.rs`), instead of the index-1 rule's
//! acceleration rows and end projection. On the report's stiff press the
//! index-1 rule's error at one step was 33 to 3 500 times the absolute
//! engine's; this is the rule that closes that gap.
//!
//! The unknowns are `x = v̇_{n+1}` (the index-1 rule's, with its
//! pseudo-acceleration, `q(x)` and `v(x)`) and the loops' forces `λ`:
//!
//! ```text
//! R₁ = ID(q(x), v(x), x) − τ − Q(q(x), v(x)) − J(q(x))ᵀ λ = 0
//! R₂ = Φ(q(x), t_{n+1}) / s_q = 0,          ∂q/∂x = T s_q,  ∂v/∂x = s_v
//! ```
//!
//! `ID` the inverse dynamics, `Q` springs and user loads. The Newton matrix
//!
//! ```text
//! [ A     −Jᵀ ]   A = M + ∂ID/∂v s_v + (∂ID/∂q − K) T s_q,   K = ∂(Jᵀλ)/∂q
//! [ J T    0  ]
//! ```
//!
//! is exact from the tree's inverse-dynamics derivatives and the closures'
//! second-order terms (`A` by forward differences of `R₁` with springs,
//! loads or `FiniteDifferences`), and solved by its Schur complement
//! `J T A⁻¹ Jᵀ` (`NV + NC` is not a stable const generic), the rows the
//! step's start drops (redundant, by the pivoted factor of `J M⁻¹ Jᵀ`) held
//! at `λ = 0`. The iteration is modified Newton, the matrix kept across
//! steps of one length as the index-1 rules keep theirs and rebuilt when a
//! correction contracts by less than a factor 10. The end is `q(x)` itself, so `Φ` holds there to
//! Newton's tolerance, and the projection that follows moves the positions
//! by round-off. The velocities are the method's own at a fixed step:
//! projecting them onto `J v + Φ_t = 0`, as the other integrators' ends
//! are, raised the press's error fiftyfold. A step of another length than
//! the last starts from projected velocities instead, its memory's
//! pseudo-acceleration moved by `Δv/(hγ)` (a misfit `d` would enter the
//! step's acceleration as `d/(hβ)`), and an error-controlled step's end is
//! projected, with the same move (so the step after it, of a new length
//! again, starts from those velocities as they are): left unprojected unless the misfit
//! reached a tenth of the error budget, the press's runs at tolerances
//! 1e-9 and 1e-10 shrank their steps to 1e-15 s. Also tried and
//! reverted: Géradin and Cardona's estimate from the method's own change of
//! the pseudo-acceleration, the projection's `Δv/(hγ)` left out. It was
//! faster to an error of 1e-8 (the double Cardan shaft's time 1.20 of the
//! absolute engine's, against 1.42; the press's 1.84 against 1.95), but the
//! press's runs at 1e-9 and 1e-10 again shrank their steps to 4e-15 s.
//!
//! Used for generalised-α on a tree whose rows are all loops or couplings
//! (positions to hold); contacts (rows at the velocity level, no `Φ`) and
//! MuJoCo's soft equalities keep the index-1 rule.

use nalgebra::{SMatrix, SVector};

use super::{AlphaMemory, KeptMatrix, Rule, Start, afresh_on_failure, forward_differences, tree_error};
use crate::dynamics::{AppliedLoads, Coefficients, ModifiedNewton, NewtonMatrix, StepReport};
use crate::linalg::{Lu, PivotedCholesky};
use crate::relative::constrained::mask_rows;
use crate::relative::{InverseDerivatives, TreeError, TreeScene, TreeSimulation, TreeState};

/// The Newton matrix, factorised: `A`, `Y = A⁻¹ Jᵀ`, `J T` and the Schur
/// complement `S = J T Y` (the identity on the rows held at `λ = 0`, which
/// `held` marks).
#[derive(Clone, Copy, Debug)]
pub(in crate::relative) struct Matrix<const NV: usize, const NC: usize> {
    a: Lu<NV>,
    y: SMatrix<f64, NV, NC>,
    jt: SMatrix<f64, NC, NV>,
    s: Lu<NC>,
    held: [bool; NC],
}

impl<const NV: usize, const NC: usize> Matrix<NV, NC> {
    /// The correction `(δx, δλ)` for the residuals `(r₁, r₂)`:
    /// `S δλ = J T A⁻¹ r₁ − r₂`, `δx = −A⁻¹ r₁ + Y δλ`.
    fn solve(&self, r1: &SVector<f64, NV>, r2: &SVector<f64, NC>) -> (SVector<f64, NV>, SVector<f64, NC>) {
        let ar1 = self.a.solve(r1);
        let dl = self.s.solve(&(self.jt * ar1 - r2));
        (self.y * dl - ar1, dl)
    }
}

/// The rows a step holds: those the start's pivoted factor kept.
fn kept_rows<const NC: usize>(order: Option<&PivotedCholesky<NC>>) -> [bool; NC] {
    let mut mask = [order.is_none(); NC];
    if let Some(f) = order {
        for &row in f.permutation().iter().take(f.rank()) {
            if let Some(slot) = mask.get_mut(row) {
                *slot = true;
            }
        }
    }
    mask
}

impl<
    S: TreeScene<NB, NQ, NV, NC>,
    L: AppliedLoads<NB>,
    const NB: usize,
    const NQ: usize,
    const NV: usize,
    const NC: usize,
> TreeSimulation<'_, S, NB, NQ, NV, NC, L>
{
    /// Whether generalised-α runs at index 3 here: loops or couplings,
    /// every row a position to hold, none soft.
    pub(super) fn index3(&self) -> bool {
        NC > 0 && Self::POSITIONED.iter().all(|&p| p) && !self.soft.any()
    }

    /// One generalised-α step at index 3 (the module) from `state` under
    /// joint forces `tau`, into `state` only on success; `controlled`: an
    /// error-controlled step, whose end's velocities are projected too.
    ///
    /// The last step's matrix is kept while the step length is (and the
    /// rows held are): a step that fails from it is taken again from a
    /// fresh one, as the index-1 rules' are.
    #[inline(always)]
    pub(super) fn index3_step(
        &mut self,
        state: &mut TreeState<NQ, NV>,
        h: f64,
        tau: &SVector<f64, NV>,
        controlled: bool,
    ) -> Result<StepReport, TreeError> {
        let kept = match self.newton.take() {
            Some((length, KeptMatrix::Index3(m))) if length == h => Some(m),
            _ => None,
        };
        afresh_on_failure(kept, |kept| self.index3_newton(state, (h, controlled), tau, kept))
    }

    /// [`index3_step`](Self::index3_step) from `kept` (or a matrix built at
    /// the predictor), the matrix kept for the next step on success.
    #[inline(always)]
    fn index3_newton(
        &mut self,
        state: &mut TreeState<NQ, NV>,
        (h, controlled): (f64, bool),
        tau: &SVector<f64, NV>,
        kept: Option<Matrix<NV, NC>>,
    ) -> Result<StepReport, TreeError> {
        let memory = self.alpha.filter(|m| m.end == *state);
        let c = Coefficients::checked(self.options().spectral_radius)
            .map_err(|_| TreeError::BadOption { name: "spectral_radius" })?;
        // A step of the last one's length starts from the method's own
        // velocities; any other start from velocities on `J v + Φ_t = 0`, the
        // memory's pseudo-acceleration moved with them (below), unless the
        // last step's end was projected already (error control's).
        let mut from = *state;
        let shift = match memory {
            Some(m) if m.h == h || m.projected => SVector::zeros(),
            _ => self.onto_velocity_rows(&mut from)? / (memory.map_or(h, |m| m.h) * c.gamma),
        };
        // The start's dynamics: a fresh start's acceleration, and the rows it drops.
        let (a0, first) = self.constrained(&from, tau, None)?;
        let (vdot, a, mut lambda) = match memory {
            Some(m) => (m.vdot, m.a + shift, m.lambda),
            None => (a0, a0, SVector::zeros()),
        };
        let mask = kept_rows(first.as_ref());
        for (l, &on) in lambda.iter_mut().zip(&mask) {
            if !on {
                *l = 0.0;
            }
        }
        let start = Start { state: &from, h, tau, order: first.as_ref(), rule: Rule::Alpha { c, vdot, a } };
        let mut x = vdot;
        let (mut r1, mut r2) = self.index3_residual(&start, &x, &lambda, &mask)?;
        let mut newton = ModifiedNewton::new(self.options());
        let mut factor = kept.filter(|m| m.held == mask);
        if factor.is_some() {
            newton.kept();
        }
        let (_, s_v, _) = start.scales();
        loop {
            newton.next().map_err(tree_error)?;
            let m = match factor.take() {
                Some(m) if !newton.stale() => m,
                _ => {
                    let m = self.index3_matrix(&start, (&x, &lambda), &mask, &r1)?;
                    newton.built();
                    m
                }
            };
            let (dx, dl) = m.solve(&r1, &r2);
            factor = Some(m);
            x += dx;
            lambda += dl;
            (r1, r2) = self.index3_residual(&start, &x, &lambda, &mask)?;
            let (_, v, _) = start.point(&x);
            if newton.converged(dx.norm() * s_v, 1.0 + v.norm()).map_err(tree_error)? {
                break;
            }
        }
        let (mut next, _) = self.end_state(&start, &x);
        let unprojected = next.v;
        let closed = self.finish_with(&mut next, controlled)?;
        let (projection_iterations, constraint_residual, velocity_residual) = closed;
        let a_next = start.pseudo(&x) + (next.v - unprojected) / (h * c.gamma);
        let projected = controlled;
        self.alpha = Some(AlphaMemory { end: next, vdot: x, a: a_next, a_start: a, lambda, h, projected });
        self.newton = factor.map(|m| (h, KeptMatrix::Index3(m)));
        *state = next;
        let (newton_iterations, newton_matrices) = newton.counts();
        Ok(StepReport {
            newton_iterations,
            newton_matrices,
            projection_iterations,
            constraint_residual,
            velocity_residual,
        })
    }

    /// `state`'s velocities projected onto `J v + Φ_t = 0` (as every
    /// step's end is projected, options permitting), and how far they moved.
    fn onto_velocity_rows(&self, state: &mut TreeState<NQ, NV>) -> Result<SVector<f64, NV>, TreeError> {
        let before = state.v;
        if self.options().projection.is_some() {
            self.close(state, self.projection(), (false, true))?;
        }
        Ok(state.v - before)
    }

    /// `(R₁, R₂)` at `(x, λ)`, the rows not held left out.
    #[inline(always)]
    fn index3_residual(
        &mut self,
        start: &Start<'_, NQ, NV, NC>,
        x: &SVector<f64, NV>,
        lambda: &SVector<f64, NC>,
        mask: &[bool; NC],
    ) -> Result<(SVector<f64, NV>, SVector<f64, NC>), TreeError> {
        let (at, _) = self.end_state(start, x);
        let applied = start.tau + self.applied_forces(&at);
        let rows = self.closure_rows(&at);
        let mut jacobian = rows.jacobian;
        mask_rows(mask, &mut jacobian);
        let r1 = self.inverse_dynamics(&at, x) - applied - jacobian.tr_mul(lambda);
        let (_, _, s_q) = start.scales();
        let mut r2 = rows.phi / s_q;
        for (r, &on) in r2.iter_mut().zip(mask) {
            if !on {
                *r = 0.0;
            }
        }
        if !(crate::linalg::finite(r1.as_slice()) && crate::linalg::finite(r2.as_slice())) {
            return Err(TreeError::NonFinite.at_stage(at.t));
        }
        Ok((r1, r2))
    }

    /// The Newton matrix at `(x, λ)` (residual `r1`), factorised.
    #[inline(always)]
    fn index3_matrix(
        &mut self,
        start: &Start<'_, NQ, NV, NC>,
        (x, lambda): (&SVector<f64, NV>, &SVector<f64, NC>),
        mask: &[bool; NC],
        r1: &SVector<f64, NV>,
    ) -> Result<Matrix<NV, NC>, TreeError> {
        let (at, delta) = self.end_state(start, x);
        let (_, right) = self.displace_derivative(&delta);
        let mut jacobian = self.closure_rows(&at).jacobian;
        mask_rows(mask, &mut jacobian);
        let a = match self.index3_exact(&at, x, lambda, (start, &right)) {
            Some(a) => a?,
            None => self.index3_differences(start, x, lambda, mask, r1)?,
        };
        let joint = self.tree().joints().first().map_or("", |j| j.name);
        let a = Lu::new(&a).map_err(|_| TreeError::Singular { joint })?;
        let mut y = SMatrix::<f64, NV, NC>::zeros();
        for (row, mut column) in jacobian.row_iter().zip(y.column_iter_mut()) {
            column.copy_from(&a.solve(&row.transpose()));
        }
        let jt = jacobian * right;
        let mut s = jt * y;
        for (r, &on) in mask.iter().enumerate() {
            if !on {
                s.row_mut(r).fill(0.0);
                s.column_mut(r).fill(0.0);
                if let Some(d) = s.get_mut((r, r)) {
                    *d = 1.0;
                }
            }
        }
        let s = Lu::new(&s).map_err(|_| TreeError::Singular { joint })?;
        Ok(Matrix { a, y, jt, s, held: *mask })
    }

    /// `A` exact, or `None` where the tree's derivatives do not cover the
    /// residual (springs, loads, `FiniteDifferences`, none derived).
    #[inline(always)]
    fn index3_exact(
        &self,
        at: &TreeState<NQ, NV>,
        x: &SVector<f64, NV>,
        lambda: &SVector<f64, NC>,
        (start, right): (&Start<'_, NQ, NV, NC>, &SMatrix<f64, NV, NV>),
    ) -> Option<Result<SMatrix<f64, NV, NV>, TreeError>> {
        if self.options().newton_matrix != NewtonMatrix::Generated || self.loaded() {
            return None;
        }
        let mut work = InverseDerivatives::zeros();
        match self.derivatives_at(at, x, &mut work) {
            Ok(()) => {}
            Err(TreeError::NotDerived) => return None,
            Err(e) => return Some(Err(e)),
        }
        let stiffness = match self.second_order_at(at, lambda, x) {
            Ok(second) => second.stiffness,
            Err(TreeError::NotDerived) => return None,
            Err(e) => return Some(Err(e)),
        };
        let mut m = SMatrix::<f64, NV, NV>::zeros();
        self.mass_matrix_into(&at.q, &mut m);
        let (_, s_v, s_q) = start.scales();
        Some(Ok(m + work.d_v * s_v + (work.d_q - stiffness) * right * s_q))
    }

    /// `A = ∂R₁/∂x` by forward differences.
    #[inline(always)]
    fn index3_differences(
        &mut self,
        start: &Start<'_, NQ, NV, NC>,
        x: &SVector<f64, NV>,
        lambda: &SVector<f64, NC>,
        mask: &[bool; NC],
        r1: &SVector<f64, NV>,
    ) -> Result<SMatrix<f64, NV, NV>, TreeError> {
        forward_differences(x, r1, |moved| Ok(self.index3_residual(start, moved, lambda, mask)?.0))
    }
}
