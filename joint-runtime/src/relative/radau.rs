//! Radau IIA of order 5 in the tree's own coordinates
//! ([`Integrator::RadauIIA`] and [`Adaptive::RadauIIA`]), loops, contacts and
//! floating bases included: the absolute engine's driver
//! (`dynamics/radau.rs`: three stages, simplified Newton on RADAU5's
//! transformed real and complex systems, its error estimate and step-size
//! rule) over the tree's group and the tree's dynamics.
//!
//! # The group
//!
//! A stage's position increment `U` is velocity-shaped, `q = q_n ⊕ U`
//! ([`Tree::displace`]): an angle or a slide added, a quaternion turned in
//! its own frame, `p_n ⊗ exp(U_θ/2)`, a free joint's offset moved along its
//! child's axes at the start, `r_n + R(p_n) U_r`. Its rate is then exact:
//! `U̇ = v` for the first, `J_r(U_θ)⁻¹ ω'` for a turn, and
//! `exp(U_θ) u` for the offset (`ṙ = R(p) u`, `R(p) = R(p_n) exp(U_θ)`).
//! The Jacobian Newton uses is that of the first-order system at `U = 0`,
//! where both rates are the velocities: `[[0, I], [A_q, A_v]]` with
//! `A_q = ∂q̈/∂q` along `⊕` and `A_v = ∂q̈/∂v`, the exact derivatives of
//! [`forward_dynamics_derivatives`](super::TreeSimulation::forward_dynamics_derivatives)
//! (loops' constrained dynamics included), or forward differences of the
//! dynamics with springs, user loads or
//! [`NewtonMatrix::FiniteDifferences`] (`2 NV` evaluations).
//!
//! # The index
//!
//! As the absolute engine's Radau IIA and the tree's other integrators: the
//! index-1 equations (a loop's constrained dynamics, the rows the start
//! dropped dropped at every stage), the end projected onto the loops.
//!
//! # The error norm
//!
//! RADAU5's over the position increments (a turn scaled by one radian, an
//! angle, a slide or an offset by its coordinate's size) and the
//! velocities, the root mean square over the tree's freedoms.

use nalgebra::{SMatrix, SVector, UnitQuaternion};

use super::tangent::{get, put_three, set, three};
use super::topology::Tree;
use super::{ForwardDerivatives, InverseDerivatives};
use super::{TreeError, TreeJointKind, TreeScene, TreeSimulation, TreeState};
use crate::analysis::AnalysisError;
use crate::dynamics::adaptive::Tolerance;
use crate::dynamics::radau::{
    DenseFactors, RadauGroup, RadauHistory, RadauHost, RadauWork, inverse_right_jacobian_times, step_radau_in,
};
use crate::dynamics::{AppliedLoads, NewtonMatrix, StepReport};
use crate::linalg::PivotedCholesky;

#[cfg(doc)]
use crate::dynamics::{Adaptive, Integrator};

/// `A_q` and `A_v` at a step's start.
pub(super) type TreeJacobian<const NV: usize> = (SMatrix<f64, NV, NV>, SMatrix<f64, NV, NV>);

/// What a tree's Radau steps carry from one to the next.
pub(super) type TreeRadauHistory<const NQ: usize, const NV: usize> =
    RadauHistory<TreeState<NQ, NV>, NV, TreeJacobian<NV>>;

impl<const NB: usize, const NQ: usize, const NV: usize> RadauGroup<NV> for Tree<NB, NQ, NV> {
    type State = TreeState<NQ, NV>;

    fn displaced_into(
        &self,
        y0: &TreeState<NQ, NV>,
        u: &SVector<f64, NV>,
        v: &SVector<f64, NV>,
        t: f64,
        out: &mut TreeState<NQ, NV>,
    ) {
        out.q = y0.q;
        self.displace(&mut out.q, u);
        out.v = *v;
        out.t = t;
    }

    fn velocity_into(&self, y: &TreeState<NQ, NV>, out: &mut SVector<f64, NV>) {
        *out = y.v;
    }

    fn position_rates_into(&self, u: &SVector<f64, NV>, v: &SVector<f64, NV>, out: &mut SVector<f64, NV>) {
        *out = *v;
        for (k, j) in self.joints.iter().enumerate() {
            let va = self.v_at[k];
            let turn_at = match j.kind {
                TreeJointKind::Spherical => va,
                TreeJointKind::Free => {
                    // ṙ = R(p_n) exp(U_θ) u, in the start's child axes.
                    let turned = UnitQuaternion::from_scaled_axis(three(u, va + 3)) * three(v, va);
                    put_three(out, va, &turned);
                    va + 3
                }
                _ => continue,
            };
            put_three(out, turn_at, &inverse_right_jacobian_times(&three(u, turn_at), &three(v, turn_at)));
        }
    }

    fn increment_error(
        &self,
        y0: &TreeState<NQ, NV>,
        y1: &TreeState<NQ, NV>,
        e: &SVector<f64, NV>,
        ev: &SVector<f64, NV>,
        tolerance: Tolerance,
    ) -> f64 {
        let scaled = |x: f64, size: f64| {
            let r = x / (tolerance.atol + tolerance.rtol * size);
            r * r
        };
        let size = |q: usize| libm::fabs(get(&y0.q, q)).max(libm::fabs(get(&y1.q, q)));
        let mut sum = 0.0;
        for (k, j) in self.joints.iter().enumerate() {
            let (qa, va) = (self.q_at[k], self.v_at[k]);
            for i in 0..j.kind.freedoms() {
                // A quaternion's turn by one radian; an offset, angle or slide by its size.
                let position = match (j.kind, i) {
                    (TreeJointKind::Spherical, _) | (TreeJointKind::Free, 3..) => 1.0,
                    _ => size(qa + i),
                };
                let speed = libm::fabs(get(&y0.v, va + i)).max(libm::fabs(get(&y1.v, va + i)));
                sum += scaled(get(e, va + i), position) + scaled(get(ev, va + i), speed);
            }
        }
        libm::sqrt(sum / (2 * NV).max(1) as f64)
    }
}

/// A tree simulation under joint forces `tau` as a [`RadauHost`], with the
/// rows its step's start dropped.
pub(super) struct TreeRadau<'r, 'a, S, L, const NB: usize, const NQ: usize, const NV: usize, const NC: usize> {
    sim: &'r mut TreeSimulation<'a, S, NB, NQ, NV, NC, L>,
    tau: SVector<f64, NV>,
    order: Option<PivotedCholesky<NC>>,
    /// The start's accelerations, which a differenced Jacobian at the
    /// start reads rather than evaluates again.
    a0: SVector<f64, NV>,
}

// The methods that evaluate the dynamics are inlined into the step, as the
// implicit rules' are: out of line, LTO left them without `nounwind`
// (nothing in them unwinds), a landing pad in every caller the no-panic
// proof counts.
impl<S, L, const NB: usize, const NQ: usize, const NV: usize, const NC: usize> RadauHost<NV>
    for TreeRadau<'_, '_, S, L, NB, NQ, NV, NC>
where
    S: TreeScene<NB, NQ, NV, NC>,
    L: AppliedLoads<NB>,
{
    type Group = Tree<NB, NQ, NV>;
    type Jacobian = TreeJacobian<NV>;
    type Factors = DenseFactors<NV>;
    type Error = TreeError;

    fn error(e: AnalysisError) -> TreeError {
        super::implicit_rules::tree_error(e)
    }

    fn group(&self) -> &Tree<NB, NQ, NV> {
        self.sim.tree()
    }

    fn newton_limits(&self) -> (usize, f64) {
        (self.sim.options().newton_max_iterations, self.sim.options().newton_tolerance)
    }

    /// Newton to the options' tolerance at every step: RADAU5's `κ` in the
    /// error norm left a swinging double pendulum's global error at 30–100
    /// times the tolerance asked (the iteration stopping where its
    /// contraction predicted less than it left); converged, 0.7–3 times.
    fn scaled_stop(&self) -> bool {
        false
    }

    fn history(&mut self) -> &mut Option<TreeRadauHistory<NQ, NV>> {
        &mut self.sim.radau
    }

    #[inline(always)]
    fn start(&mut self, y0: &TreeState<NQ, NV>, out: &mut SVector<f64, NV>) -> Result<(), TreeError> {
        let (a, first) = self.sim.constrained(y0, &self.tau, None)?;
        (*out, self.order, self.a0) = (a, first, a);
        Ok(())
    }

    #[inline(always)]
    fn accelerations(&mut self, state: &TreeState<NQ, NV>, out: &mut SVector<f64, NV>) -> Result<(), TreeError> {
        let (a, _) = self.sim.constrained(state, &self.tau, self.order.as_ref()).map_err(|e| e.at_stage(state.t))?;
        *out = a;
        Ok(())
    }

    #[inline(always)]
    fn jacobian(&mut self, y0: &TreeState<NQ, NV>) -> Result<(TreeJacobian<NV>, usize), TreeError> {
        if self.sim.options().newton_matrix == NewtonMatrix::Generated {
            let (mut work, mut d) = (InverseDerivatives::zeros(), ForwardDerivatives::zeros());
            match self.sim.forward_dynamics_derivatives(y0, &self.tau, &mut work, &mut d) {
                Ok(()) => return Ok(((d.d_q, d.d_v), 0)),
                // Springs, loads or no derivatives: differences below.
                Err(TreeError::Loaded | TreeError::NotDerived) => {}
                Err(e) => return Err(e),
            }
        }
        self.jacobian_differences(y0)
    }

    fn factor(&mut self, jacobian: &TreeJacobian<NV>, h: f64) -> Result<DenseFactors<NV>, TreeError> {
        let joint = self.sim.tree().joints().first().map_or("", |j| j.name);
        DenseFactors::new(&jacobian.0, &jacobian.1, h).map_err(|_| TreeError::Singular { joint })
    }

    fn solve_real(
        &mut self,
        factors: &DenseFactors<NV>,
        (r, s): (&SVector<f64, NV>, &SVector<f64, NV>),
        (x, y): (&mut SVector<f64, NV>, &mut SVector<f64, NV>),
    ) {
        factors.solve_real_into((r, s), (x, y));
    }

    fn solve_complex(
        &mut self,
        factors: &DenseFactors<NV>,
        r: (&SVector<f64, NV>, &SVector<f64, NV>),
        s: (&SVector<f64, NV>, &SVector<f64, NV>),
        x: (&mut SVector<f64, NV>, &mut SVector<f64, NV>),
        y: (&mut SVector<f64, NV>, &mut SVector<f64, NV>),
    ) {
        factors.solve_complex_into(r, s, x, y);
    }
}

impl<S, L, const NB: usize, const NQ: usize, const NV: usize, const NC: usize> TreeRadau<'_, '_, S, L, NB, NQ, NV, NC>
where
    S: TreeScene<NB, NQ, NV, NC>,
    L: AppliedLoads<NB>,
{
    /// `A_q`, `A_v` at the step's start `y0` by forward differences of the
    /// dynamics under its rule (from its accelerations, which `start`
    /// kept), and the `2 NV` evaluations spent.
    #[inline(always)]
    fn jacobian_differences(&mut self, y0: &TreeState<NQ, NV>) -> Result<(TreeJacobian<NV>, usize), TreeError> {
        let a0 = self.a0;
        let (mut aq, mut av) = (SMatrix::<f64, NV, NV>::zeros(), SMatrix::<f64, NV, NV>::zeros());
        let mut a = SVector::<f64, NV>::zeros();
        // √ε steps: the forward difference's best.
        let root = 1.4901161193847656e-8;
        for ((c, mut q), mut v) in aq.column_iter_mut().enumerate().zip(av.column_iter_mut()) {
            let mut unit = SVector::<f64, NV>::zeros();
            set(&mut unit, c, root);
            let mut moved = *y0;
            self.sim.tree().displace(&mut moved.q, &unit);
            self.accelerations(&moved, &mut a)?;
            q.copy_from(&((a - a0) / root));
            let eps = root * (1.0 + libm::fabs(get(&y0.v, c)));
            let mut moved = *y0;
            set(&mut moved.v, c, get(&y0.v, c) + eps);
            self.accelerations(&moved, &mut a)?;
            v.copy_from(&((a - a0) / eps));
        }
        Ok(((aq, av), 2 * NV))
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
    /// One Radau IIA step of length `h` from `state` under joint forces
    /// `tau`; with a `tolerance`, Newton stops as the error control needs
    /// and the step's error norm is estimated. The end is not projected
    /// (the caller finishes it) and `state` is not changed: the end, what
    /// Newton did and the error norm (0 at fixed steps).
    pub(super) fn radau_trial(
        &mut self,
        state: &TreeState<NQ, NV>,
        h: f64,
        tau: &SVector<f64, NV>,
        tolerance: Option<Tolerance>,
    ) -> Result<(TreeState<NQ, NV>, crate::dynamics::radau::RadauStep), TreeError> {
        let mut work = RadauWork::at(*state);
        let mut host = TreeRadau { sim: self, tau: *tau, order: None, a0: SVector::zeros() };
        let step = step_radau_in(&mut host, &mut work, h, tolerance)?;
        Ok((*work.end_mut(), step))
    }

    /// One fixed Radau IIA step (`step_with` under [`Integrator::RadauIIA`]),
    /// projected, into `state` only on success.
    pub(super) fn radau_step(
        &mut self,
        state: &mut TreeState<NQ, NV>,
        h: f64,
        tau: &SVector<f64, NV>,
    ) -> Result<StepReport, TreeError> {
        let (mut next, step) = self.radau_trial(state, h, tau, None)?;
        let (projection_iterations, constraint_residual, velocity_residual) = self.finish(&mut next)?;
        self.radau_accepted(&next);
        *state = next;
        Ok(StepReport {
            newton_iterations: step.iterations,
            newton_matrices: step.matrices,
            projection_iterations,
            constraint_residual,
            velocity_residual,
        })
    }

    /// A Radau step accepted at `end` (projected): the next step starts from
    /// its stages if it starts there.
    pub(super) fn radau_accepted(&mut self, end: &TreeState<NQ, NV>) {
        if let Some(history) = &mut self.radau {
            history.accept(end);
        }
    }
}
