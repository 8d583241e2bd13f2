//! The implicit midpoint rule and generalised-α in the tree's own
//! coordinates, loops, contacts and floating bases included, each solved by
//! modified Newton with its matrix from the exact derivatives of the
//! dynamics.
//!
//! Both rules have one unknown `x` of the tree's size; each evaluation of
//! their residual `R(x) = x − b − k q̈(q(x), v(x))` runs the dynamics once:
//!
//! - **Implicit midpoint** ([`Integrator::ImplicitMidpoint`]): `x = w`, the
//!   midpoint velocity; `q(w) = q_n ⊕ (h/2) w`, `v(w) = w`, at `t_n + h/2`,
//!   `b = v_n`, `k = h/2`. Then `q_{n+1} = q_n ⊕ h w`, `v_{n+1} = 2 w − v_n`.
//! - **Generalised-α** ([`Integrator::GeneralisedAlpha`]; Chung and Hulbert,
//!   Arnold and Brüls on the group): `x = v̇_{n+1}`; with the
//!   pseudo-acceleration `a_{n+1} = ((1 − α_f) v̇_{n+1} + α_f v̇_n −
//!   α_m a_n)/(1 − α_m)`, `Δ = h v_n + h² (½ − β) a_n + h² β a_{n+1}`,
//!   `q(x) = q_n ⊕ Δ`, `v(x) = v_n + h (1 − γ) a_n + h γ a_{n+1}`, at
//!   `t_n + h`, `b = 0`, `k = 1`; the coefficients from the options'
//!   spectral radius ρ∞, as on the absolute engine. `(v̇, a)` carry to the
//!   next step when it starts where this one ended (otherwise the method
//!   starts afresh, `a_n = v̇_n` at the start). On a tree whose rows are
//!   all loops or couplings it runs at index 3 (`implicit_rules/index3.rs`:
//!   `Φ = 0` at the step's end is one of Newton's equations, as on the
//!   absolute engine); with contacts or soft rows, on the index-1 equations
//!   as the midpoint rule, the loops' constrained dynamics, the end
//!   projected.
//!
//! `q̈` is the tree's dynamics, on a loop the constrained ones (Baumgarte's
//! terms as the options say, the rows the start dropped dropped at every
//! evaluation, as RK4's stages do), and the end is projected as RK4's is. A
//! floating base's offset moves by the rotation halfway along the step's
//! turn (`r_{n+1} = r_n + R_½ δ`; by the start's rotation, as `q ⊕ δ`
//! turns it, both rules were first order).
//!
//! `∂R/∂x = I − k (∂q̈/∂v s_v + ∂q̈/∂q T s_q)`, `T` the right Jacobian of
//! the displacement (the identity but for a ball's or a floating base's
//! turn), `s_v = ∂v/∂x` and `s_q` with `∂q/∂x = T s_q`: the exact `∂q̈/∂(q,
//! v)` of [`forward_dynamics_derivatives`](super::TreeSimulation::forward_dynamics_derivatives),
//! loops included. A tree with springs or user loads, whose exact
//! derivatives cover only its own dynamics, or options that ask for
//! [`NewtonMatrix::FiniteDifferences`], take forward differences of `R`
//! (`NV` evaluations). Newton is modified as on the absolute engine, the
//! matrix rebuilt only when a correction shrinks by less than a factor 4
//! (`dynamics::ModifiedNewton`), and more so: a step of the same length
//! starts from the last step's matrix (as RADAU5 keeps its Jacobian), so
//! that a smooth run builds one now and then and a step costs its
//! residuals' evaluations, rebuilt when a correction contracts by less than
//! a factor 10. A step that fails from a kept matrix is taken again from a
//! fresh one.

pub(super) mod index3;

use nalgebra::{SMatrix, SVector};

use super::{ForwardDerivatives, InverseDerivatives, TreeError, TreeScene, TreeSimulation, TreeState};
use crate::dynamics::adaptive::{IntegrationReport, Tolerance, alpha_error_increments};
use crate::dynamics::radau::RadauGroup;
use crate::dynamics::{AppliedLoads, Coefficients, Integrator, ModifiedNewton, NewtonMatrix, StepReport};
use crate::linalg::{Lu, PivotedCholesky};

/// What generalised-α carries from a step to the next: the state it ended
/// at, its acceleration and pseudo-acceleration.
#[derive(Clone, Copy, Debug)]
pub(super) struct AlphaMemory<const NQ: usize, const NV: usize, const NC: usize> {
    end: TreeState<NQ, NV>,
    vdot: SVector<f64, NV>,
    a: SVector<f64, NV>,
    /// The pseudo-acceleration the step started from: the error estimate's.
    a_start: SVector<f64, NV>,
    /// The loops' forces at index 3 (`index3.rs`), zero at index 1.
    lambda: SVector<f64, NC>,
    /// The step's length.
    h: f64,
    /// Whether the end's velocities were projected onto `J v + Φ_t = 0`
    /// (every end but a fixed-step index-3 one): a step of another length
    /// then starts from them as they are (`index3.rs`).
    projected: bool,
}

/// The implicit rules' last Newton matrix, factorised: the index-1 rules'
/// `∂R/∂x`, or index-3 generalised-α's saddle-point matrix (`index3.rs`).
#[derive(Clone, Copy, Debug)]
pub(super) enum KeptMatrix<const NV: usize, const NC: usize> {
    Rule(Lu<NV>),
    Index3(index3::Matrix<NV, NC>),
}

/// Which rule, with what it reads of the past.
#[derive(Clone, Copy)]
enum Rule<const NV: usize> {
    Midpoint,
    Alpha { c: Coefficients, vdot: SVector<f64, NV>, a: SVector<f64, NV> },
}

/// The step's start, its length, the joint forces, the rows the start
/// dropped and the rule: what every evaluation of the residual reads.
struct Start<'s, const NQ: usize, const NV: usize, const NC: usize> {
    state: &'s TreeState<NQ, NV>,
    h: f64,
    tau: &'s SVector<f64, NV>,
    order: Option<&'s PivotedCholesky<NC>>,
    rule: Rule<NV>,
}

impl<const NQ: usize, const NV: usize, const NC: usize> Start<'_, NQ, NV, NC> {
    /// `(b, k)` of the residual, `(s_v, s_q)` of the point's derivatives.
    fn scales(&self) -> (f64, f64, f64) {
        let h = self.h;
        match self.rule {
            Rule::Midpoint => (0.5 * h, 1.0, 0.5 * h),
            Rule::Alpha { c, .. } => {
                let rate = (1.0 - c.alpha_f) / (1.0 - c.alpha_m);
                (1.0, h * c.gamma * rate, h * h * c.beta * rate)
            }
        }
    }

    /// Generalised-α's `a_{n+1}` at `x = v̇_{n+1}` (the midpoint rule has none).
    fn pseudo(&self, x: &SVector<f64, NV>) -> SVector<f64, NV> {
        match self.rule {
            Rule::Midpoint => SVector::zeros(),
            Rule::Alpha { c, vdot, a } => {
                (x * (1.0 - c.alpha_f) + vdot * c.alpha_f - a * c.alpha_m) / (1.0 - c.alpha_m)
            }
        }
    }

    /// The displacement from `q_n` to the point at `x`, the velocity there
    /// and its time.
    fn point(&self, x: &SVector<f64, NV>) -> (SVector<f64, NV>, SVector<f64, NV>, f64) {
        let (h, v, t) = (self.h, &self.state.v, self.state.t);
        match self.rule {
            Rule::Midpoint => (x * (0.5 * h), *x, t + 0.5 * h),
            Rule::Alpha { c, a, .. } => {
                let next = self.pseudo(x);
                let delta = v * h + a * (h * h * (0.5 - c.beta)) + next * (h * h * c.beta);
                (delta, v + a * (h * (1.0 - c.gamma)) + next * (h * c.gamma), t + h)
            }
        }
    }
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
    /// One step of length `h` from `state` under joint forces `tau` by the
    /// options' implicit rule (the module), into `state` only on success.
    /// [`TreeError::NotConverged`] when Newton does not converge within the
    /// options' iterations; the other errors as RK4's step. The last step's
    /// Newton matrix is kept while the step length is: a step that fails
    /// from it is taken again from a fresh one.
    // Inlined into `step_with`, as are the helpers below that evaluate the
    // dynamics: out of line, LTO left each without `nounwind` (nothing in
    // it unwinds), a landing pad in every caller the no-panic proof counts.
    #[inline(always)]
    pub(super) fn implicit_rule_step(
        &mut self,
        state: &mut TreeState<NQ, NV>,
        h: f64,
        tau: &SVector<f64, NV>,
    ) -> Result<StepReport, TreeError> {
        let alpha = self.options().integrator == Integrator::GeneralisedAlpha;
        self.rule_step(state, h, tau, (alpha, false))
    }

    /// [`implicit_rule_step`](Self::implicit_rule_step) by generalised-α
    /// (`alpha`) or the midpoint rule, whatever the options' integrator;
    /// `controlled`: a step of error control.
    #[inline(always)]
    fn rule_step(
        &mut self,
        state: &mut TreeState<NQ, NV>,
        h: f64,
        tau: &SVector<f64, NV>,
        (alpha, controlled): (bool, bool),
    ) -> Result<StepReport, TreeError> {
        if alpha && self.index3() {
            return self.index3_step(state, h, tau, controlled);
        }
        let kept = match self.newton.take() {
            Some((length, KeptMatrix::Rule(lu))) if length == h => Some(lu),
            _ => None,
        };
        afresh_on_failure(kept, |kept| self.rule_newton(state, (h, alpha), tau, kept))
    }

    /// The step by modified Newton from `kept` (or a matrix built at the
    /// predictor), the matrix kept for the next step on success.
    #[inline(always)]
    fn rule_newton(
        &mut self,
        state: &mut TreeState<NQ, NV>,
        (h, alpha): (f64, bool),
        tau: &SVector<f64, NV>,
        kept: Option<Lu<NV>>,
    ) -> Result<StepReport, TreeError> {
        // The start's dynamics: the midpoint's predictor, a fresh
        // generalised-α start, and the rows a loop drops. A continuing
        // generalised-α step on a tree without rows needs none of them.
        let memory = self.alpha.filter(|m| alpha && m.end == *state);
        let (a0, first) = match memory {
            Some(m) if NC == 0 => (m.vdot, None),
            _ => self.constrained(state, tau, None)?,
        };
        // Predictors: the explicit midpoint velocity; the last acceleration.
        let (rule, mut x) = match alpha {
            true => {
                let c = Coefficients::checked(self.options().spectral_radius)
                    .map_err(|_| TreeError::BadOption { name: "spectral_radius" })?;
                let (vdot, a) = match memory {
                    Some(m) => (m.vdot, m.a),
                    None => (a0, a0),
                };
                (Rule::Alpha { c, vdot, a }, vdot)
            }
            false => (Rule::Midpoint, state.v + a0 * (0.5 * h)),
        };
        let start = Start { state, h, tau, order: first.as_ref(), rule };
        let mut r = self.rule_residual(&start, &x)?;
        let mut newton = ModifiedNewton::new(self.options());
        let mut factor = kept;
        if factor.is_some() {
            newton.kept();
        }
        let (_, s_v, _) = start.scales();
        loop {
            newton.next().map_err(tree_error)?;
            let lu = match factor {
                Some(lu) if !newton.stale() => lu,
                _ => {
                    let lu = self.rule_matrix(&start, &x, &r)?;
                    newton.built();
                    factor = Some(lu);
                    lu
                }
            };
            let dx = lu.solve(&(-r));
            x += dx;
            r = self.rule_residual(&start, &x)?;
            // Measured as the velocity it moves, against the velocity's size.
            let (_, v, _) = start.point(&x);
            if newton.converged(dx.norm() * s_v, 1.0 + v.norm()).map_err(tree_error)? {
                break;
            }
        }
        let (next, (projection_iterations, constraint_residual, velocity_residual)) = self.rule_end(&start, &x)?;
        if let Rule::Alpha { a: a_start, .. } = start.rule {
            let lambda = SVector::zeros();
            let a = start.pseudo(&x);
            self.alpha = Some(AlphaMemory { end: next, vdot: x, a, a_start, lambda, h, projected: true });
        }
        *state = next;
        self.newton = factor.map(|lu| (h, KeptMatrix::Rule(lu)));
        let (newton_iterations, newton_matrices) = newton.counts();
        Ok(StepReport {
            newton_iterations,
            newton_matrices,
            projection_iterations,
            constraint_residual,
            velocity_residual,
        })
    }

    /// One generalised-α step of `h` from `y0` with no joint forces, its
    /// end projected, and its error norm: Géradin and Cardona's estimate of
    /// the absolute engine's error control (`dynamics/adaptive.rs`),
    /// `(β − 1/6) h² Δa` for the positions and `(γ − ½) h Δa` for the
    /// velocities, `Δa` the step's change of pseudo-acceleration, in the
    /// norm of Radau IIA's (`radau.rs`). A step the control refuses, or one
    /// that fails, leaves the memory the next step starts from as it was.
    pub(super) fn alpha_trial(
        &mut self,
        y0: &TreeState<NQ, NV>,
        h: f64,
        tolerance: Tolerance,
        report: &mut IntegrationReport,
    ) -> Result<(TreeState<NQ, NV>, f64), TreeError> {
        let saved = self.alpha;
        let mut end = *y0;
        let step = self.rule_step(&mut end, h, &SVector::zeros(), (true, true)).inspect_err(|_| self.alpha = saved)?;
        report.newton_iterations += step.newton_iterations;
        report.newton_matrices += step.newton_matrices;
        report.evaluations += step.newton_iterations + 1;
        let change = self.alpha.map_or(SVector::zeros(), |m| m.a - m.a_start);
        let (e, ev) = alpha_error_increments(&change, h, self.options().spectral_radius);
        let err = RadauGroup::increment_error(self.tree(), y0, &end, &e, &ev, tolerance);
        if err.is_nan() || err > 1.0 {
            self.alpha = saved;
        }
        Ok((end, err))
    }

    /// The step's end at the converged `x`, projected, and what the
    /// projection did.
    fn rule_end(
        &self,
        start: &Start<'_, NQ, NV, NC>,
        x: &SVector<f64, NV>,
    ) -> Result<(TreeState<NQ, NV>, (usize, f64, f64)), TreeError> {
        let (mut next, _) = self.end_state(start, x);
        let closed = self.finish(&mut next)?;
        Ok((next, closed))
    }

    /// The step's end at `x` before any projection, `q_n ⊕ Δ` with a
    /// floating base's offset turned halfway along the step, and `Δ`.
    fn end_state(&self, start: &Start<'_, NQ, NV, NC>, x: &SVector<f64, NV>) -> (TreeState<NQ, NV>, SVector<f64, NV>) {
        let (h, from) = (start.h, start.state);
        let (delta, v) = match start.rule {
            Rule::Midpoint => (x * h, x * 2.0 - from.v),
            Rule::Alpha { .. } => {
                let (delta, v, _) = start.point(x);
                (delta, v)
            }
        };
        let mut half = from.q;
        self.tree().displace(&mut half, &(delta * 0.5));
        let mut next = TreeState { q: from.q, v, t: from.t + h };
        self.tree().displace_through(&mut next.q, &delta, &half);
        (next, delta)
    }

    /// The state the rule evaluates the dynamics at, for `x`.
    fn rule_point(&self, start: &Start<'_, NQ, NV, NC>, x: &SVector<f64, NV>) -> (TreeState<NQ, NV>, SVector<f64, NV>) {
        let (delta, v, t) = start.point(x);
        let mut q = start.state.q;
        self.tree().displace(&mut q, &delta);
        (TreeState { q, v, t }, delta)
    }

    /// `R(x) = x − b − k q̈(q(x), v(x))`; a failing evaluation is the
    /// step's divergence at the point's time.
    #[inline(always)]
    fn rule_residual(
        &mut self,
        start: &Start<'_, NQ, NV, NC>,
        x: &SVector<f64, NV>,
    ) -> Result<SVector<f64, NV>, TreeError> {
        let (at, _) = self.rule_point(start, x);
        let (a, _) = self.constrained(&at, start.tau, start.order).map_err(|e| e.at_stage(at.t))?;
        let (k, _, _) = start.scales();
        let base = match start.rule {
            Rule::Midpoint => start.state.v,
            Rule::Alpha { .. } => SVector::zeros(),
        };
        Ok(x - base - a * k)
    }

    /// `∂R/∂x` at `x` (residual `r`), factorised: exact where the tree's
    /// derivatives are, forward differences of `R` otherwise.
    #[inline(always)]
    fn rule_matrix(
        &mut self,
        start: &Start<'_, NQ, NV, NC>,
        x: &SVector<f64, NV>,
        r: &SVector<f64, NV>,
    ) -> Result<Lu<NV>, TreeError> {
        let exact = self.options().newton_matrix == NewtonMatrix::Generated;
        let (at, delta) = self.rule_point(start, x);
        let (mut work, mut d) = (InverseDerivatives::zeros(), ForwardDerivatives::zeros());
        let matrix = match exact.then(|| self.forward_dynamics_derivatives(&at, start.tau, &mut work, &mut d)) {
            Some(Ok(())) => {
                let (k, s_v, s_q) = start.scales();
                let (_, right) = self.displace_derivative(&delta);
                let rate = d.d_v * s_v + d.d_q * right * s_q;
                SMatrix::<f64, NV, NV>::identity() - rate * k
            }
            // Springs, loads or no derivatives: the residual's differences.
            Some(Err(TreeError::Loaded | TreeError::NotDerived)) | None => self.residual_differences(start, x, r)?,
            Some(Err(e)) => return Err(e.at_stage(at.t)),
        };
        let joint = self.tree().joints().first().map_or("", |j| j.name);
        Lu::new(&matrix).map_err(|_| TreeError::Singular { joint })
    }

    /// `∂R/∂x` by forward differences.
    #[inline(always)]
    fn residual_differences(
        &mut self,
        start: &Start<'_, NQ, NV, NC>,
        x: &SVector<f64, NV>,
        r: &SVector<f64, NV>,
    ) -> Result<SMatrix<f64, NV, NV>, TreeError> {
        forward_differences(x, r, |moved| self.rule_residual(start, moved))
    }
}

/// `∂R/∂x` at `x` by forward differences, column by column, from the
/// residual `r` there: what both rules' matrices fall back to.
#[inline(always)]
fn forward_differences<const NV: usize>(
    x: &SVector<f64, NV>,
    r: &SVector<f64, NV>,
    mut residual: impl FnMut(&SVector<f64, NV>) -> Result<SVector<f64, NV>, TreeError>,
) -> Result<SMatrix<f64, NV, NV>, TreeError> {
    let mut out = SMatrix::<f64, NV, NV>::zeros();
    for k in 0..NV {
        // √ε relative to the unknown: the forward difference's best step.
        let eps = 1.4901161193847656e-8 * (1.0 + x[k].abs());
        let mut moved = *x;
        moved[k] += eps;
        out.set_column(k, &((residual(&moved)? - r) / eps));
    }
    Ok(out)
}

/// A step from `kept`, the last step's Newton matrix (one call site for
/// the iteration): taken again from a fresh matrix when it fails from a
/// kept one (not converged, or an iterate the dynamics refused).
#[inline(always)]
fn afresh_on_failure<K>(
    mut kept: Option<K>,
    mut step: impl FnMut(Option<K>) -> Result<StepReport, TreeError>,
) -> Result<StepReport, TreeError> {
    loop {
        let reused = kept.is_some();
        match step(kept.take()) {
            Err(_) if reused => continue,
            result => return result,
        }
    }
}

/// Newton's failure (or the Radau driver's) in the engine's terms.
pub(super) fn tree_error(e: crate::analysis::AnalysisError) -> TreeError {
    use crate::analysis::AnalysisError;
    match e {
        AnalysisError::ImplicitNotConverged { iterations, correction } => {
            TreeError::NotConverged { iterations, correction }
        }
        AnalysisError::BadOption { name } => TreeError::BadOption { name },
        _ => TreeError::NonFinite,
    }
}
