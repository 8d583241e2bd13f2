//! The implicit midpoint rule in the tree's own coordinates, loops
//! included, with its Newton matrix from the exact derivatives of the
//! dynamics.
//!
//! With the unknown midpoint velocity `w`, `q_½ = q_n ⊕ (h/2) w` and
//! `w = v_n + (h/2) q̈(q_½, w)`, then `q_{n+1} = q_n ⊕ h w` and
//! `v_{n+1} = 2 w − v_n` (a floating base's offset turned by the midpoint's
//! rotation, `r_{n+1} = r_n + R_½ h w`: by the start's, the rule would be
//! first order): the absolute engine's rule
//! ([`Integrator::ImplicitMidpoint`](crate::dynamics::Integrator)) on the
//! joints' coordinates, a floating base or ball joint turned through `exp`.
//! `q̈` is the tree's dynamics, on a loop the constrained ones (Baumgarte's
//! terms as the options say, the rows the start dropped dropped at every
//! evaluation, as RK4's stages do), and the end is projected as RK4's is.
//!
//! The residual `R(w) = w − v_n − (h/2) q̈(q_½, w)` has the Jacobian
//! `I − (h/2) (∂q̈/∂v + (h/2) ∂q̈/∂q T)`, `T` the right Jacobian of
//! `q_n ⊕ (h/2) w` (the identity but for a ball's or a floating base's
//! turn): the exact `∂q̈/∂(q, v)` of
//! [`forward_dynamics_derivatives`](super::TreeSimulation::forward_dynamics_derivatives),
//! loops included. A tree with springs or user loads, whose exact
//! derivatives cover only its own dynamics, or options that ask for
//! [`NewtonMatrix::FiniteDifferences`], take forward differences of `R`
//! (`NV` evaluations). Newton is modified as on the absolute engine, the
//! matrix rebuilt only when a correction shrinks by less than a factor 4
//! (`dynamics::ModifiedNewton`), and more so: a step of the same length
//! starts from the last step's matrix (as RADAU5 keeps its Jacobian), so
//! that a smooth run builds one now and then, and a step costs its
//! residuals' evaluations. A step that fails from a kept matrix is taken
//! again from a fresh one.

use nalgebra::{SMatrix, SVector};

use super::{ForwardDerivatives, InverseDerivatives, TreeError, TreeScene, TreeSimulation, TreeState};
use crate::dynamics::{AppliedLoads, ModifiedNewton, NewtonMatrix, StepReport};
use crate::linalg::{Lu, PivotedCholesky};

/// The step's start, its length, the joint forces and the rows the start
/// dropped: what every evaluation of the residual reads.
struct Start<'s, const NQ: usize, const NV: usize, const NC: usize> {
    state: &'s TreeState<NQ, NV>,
    h: f64,
    tau: &'s SVector<f64, NV>,
    order: Option<&'s PivotedCholesky<NC>>,
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
    /// One implicit midpoint step of length `h` from `state` under joint
    /// forces `tau` (the module's rule), into `state` only on success.
    /// [`TreeError::NotConverged`] when Newton does not converge within the
    /// options' iterations; the other errors as RK4's step. The last step's
    /// Newton matrix is kept while the step length is: a step that fails
    /// from it is taken again from a fresh one.
    // Inlined into `step_with`, as are the helpers below that evaluate the
    // dynamics: out of line, LTO left each without `nounwind` (nothing in
    // it unwinds), a landing pad in every caller the no-panic proof counts.
    #[inline(always)]
    pub(super) fn midpoint_step(
        &mut self,
        state: &mut TreeState<NQ, NV>,
        h: f64,
        tau: &SVector<f64, NV>,
    ) -> Result<StepReport, TreeError> {
        let mut kept = self.newton.take().filter(|&(length, _)| length == h).map(|(_, lu)| lu);
        // One call site for the Newton iteration: a second try only after a kept matrix failed.
        loop {
            let reused = kept.is_some();
            match self.midpoint_newton(state, h, tau, kept.take()) {
                // Not converged, or an iterate the dynamics refused: afresh.
                Err(_) if reused => continue,
                result => return result,
            }
        }
    }

    /// The step by modified Newton from `kept` (or a matrix built at the
    /// predictor), the matrix kept for the next step on success.
    #[inline(always)]
    fn midpoint_newton(
        &mut self,
        state: &mut TreeState<NQ, NV>,
        h: f64,
        tau: &SVector<f64, NV>,
        kept: Option<Lu<NV>>,
    ) -> Result<StepReport, TreeError> {
        let (a0, first) = self.constrained(state, tau, None)?;
        let start = Start { state, h, tau, order: first.as_ref() };
        // The explicit predictor, then modified Newton on `R(w) = 0`.
        let mut w = state.v + a0 * (0.5 * h);
        let mut r = self.midpoint_residual(&start, &w)?;
        let mut newton = ModifiedNewton::new(self.options());
        let mut factor = kept;
        if factor.is_some() {
            newton.kept();
        }
        loop {
            newton.next().map_err(not_converged)?;
            let lu = match factor {
                Some(lu) if !newton.stale() => lu,
                _ => {
                    let lu = self.midpoint_matrix(&start, &w, &r)?;
                    newton.built();
                    factor = Some(lu);
                    lu
                }
            };
            let dw = lu.solve(&(-r));
            w += dw;
            r = self.midpoint_residual(&start, &w)?;
            if newton.converged(dw.norm(), 1.0 + w.norm()).map_err(not_converged)? {
                break;
            }
        }
        let mut next = TreeState { q: state.q, v: w * 2.0 - state.v, t: state.t + h };
        let mid = self.midpoint_at(&start, &w);
        self.tree().displace_through(&mut next.q, &(w * h), &mid.q);
        let (projection_iterations, constraint_residual, velocity_residual) = self.finish(&mut next)?;
        *state = next;
        self.newton = factor.map(|lu| (h, lu));
        let (newton_iterations, newton_matrices) = newton.counts();
        Ok(StepReport {
            newton_iterations,
            newton_matrices,
            projection_iterations,
            constraint_residual,
            velocity_residual,
        })
    }

    /// The midpoint's state at the midpoint velocity `w`.
    fn midpoint_at(&self, start: &Start<'_, NQ, NV, NC>, w: &SVector<f64, NV>) -> TreeState<NQ, NV> {
        let mut q = start.state.q;
        self.tree().displace(&mut q, &(w * (0.5 * start.h)));
        TreeState { q, v: *w, t: start.state.t + 0.5 * start.h }
    }

    /// `R(w) = w − v_n − (h/2) q̈(q_½, w)`; a failing evaluation is the
    /// step's divergence at the midpoint's time.
    #[inline(always)]
    fn midpoint_residual(
        &mut self,
        start: &Start<'_, NQ, NV, NC>,
        w: &SVector<f64, NV>,
    ) -> Result<SVector<f64, NV>, TreeError> {
        let mid = self.midpoint_at(start, w);
        let (a, _) = self.constrained(&mid, start.tau, start.order).map_err(|e| e.at_stage(mid.t))?;
        Ok(w - start.state.v - a * (0.5 * start.h))
    }

    /// `∂R/∂w` at `w` (residual `r`), factorised: exact where the tree's
    /// derivatives are, forward differences of `R` otherwise.
    #[inline(always)]
    fn midpoint_matrix(
        &mut self,
        start: &Start<'_, NQ, NV, NC>,
        w: &SVector<f64, NV>,
        r: &SVector<f64, NV>,
    ) -> Result<Lu<NV>, TreeError> {
        let h = start.h;
        let exact = self.options().newton_matrix == NewtonMatrix::Generated;
        let mid = self.midpoint_at(start, w);
        let (mut work, mut d) = (InverseDerivatives::zeros(), ForwardDerivatives::zeros());
        let matrix = match exact.then(|| self.forward_dynamics_derivatives(&mid, start.tau, &mut work, &mut d)) {
            Some(Ok(())) => {
                let (_, right) = self.displace_derivative(&(w * (0.5 * h)));
                let rate = d.d_v + d.d_q * right * (0.5 * h);
                SMatrix::<f64, NV, NV>::identity() - rate * (0.5 * h)
            }
            // Springs, loads or no derivatives: the residual's differences.
            Some(Err(TreeError::Loaded | TreeError::NotDerived)) | None => self.residual_differences(start, w, r)?,
            Some(Err(e)) => return Err(e.at_stage(mid.t)),
        };
        let joint = self.tree().joints().first().map_or("", |j| j.name);
        Lu::new(&matrix).map_err(|_| TreeError::Singular { joint })
    }

    /// `∂R/∂w` by forward differences, column by column.
    #[inline(always)]
    fn residual_differences(
        &mut self,
        start: &Start<'_, NQ, NV, NC>,
        w: &SVector<f64, NV>,
        r: &SVector<f64, NV>,
    ) -> Result<SMatrix<f64, NV, NV>, TreeError> {
        let mut out = SMatrix::<f64, NV, NV>::zeros();
        for k in 0..NV {
            // √ε relative to the velocity: the forward difference's best step.
            let eps = 1.4901161193847656e-8 * (1.0 + w[k].abs());
            let mut moved = *w;
            moved[k] += eps;
            let column = (self.midpoint_residual(start, &moved)? - r) / eps;
            out.set_column(k, &column);
        }
        Ok(out)
    }
}

/// Newton's failure in the engine's terms.
fn not_converged(e: crate::analysis::AnalysisError) -> TreeError {
    match e {
        crate::analysis::AnalysisError::ImplicitNotConverged { iterations, correction } => {
            TreeError::NotConverged { iterations, correction }
        }
        _ => TreeError::NonFinite,
    }
}
