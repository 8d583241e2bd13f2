//! The dense reference path (feature `__dense_reference`, not part of the
//! API): [`Simulation`](super::Simulation)'s equations written again with the
//! full `J` and `J M⁻¹ Jᵀ` as nalgebra matrices, so that the tests can check
//! the block path against an independent implementation (the same equations,
//! none of the block pattern, elimination order, saddle-point factor or
//! generated products). Its stack grows with the square of the scene.

mod adaptive;
mod alpha;
mod force_derivatives;
#[cfg(feature = "alloc")]
mod linear;
mod newton_matrix;
mod radau;

use nalgebra::{SMatrix, SVector};

use self::radau::{DenseJacobian, DenseRadau};
use crate::dynamics::radau::{RadauHistory, RadauWork, step_radau};

use super::*;
use crate::analysis::dense::{jacobian_times_metric, min_norm, newton};
use crate::analysis::{
    AnalysisError, AssemblyOptions, RowList, apply_metric, check_output, check_state, normalise_orientations,
    set_velocities, velocity_vector,
};
use crate::linalg::{Lu, PivotedCholesky};
use crate::scene::{RowBlock, Scene, SystemState};

/// The dense reference: [`Simulation`]'s equations with the full `J`
/// (`M × NV`) and `J M⁻¹ Jᵀ` (`M × M`) on the stack, the same methods. For
/// the tests only (a 40-body chain overflows a 2 MiB thread).
pub struct DenseSimulation<'a, S, L, const NB: usize, const NV: usize, const M: usize> {
    pub(super) scene: &'a S,
    pub(super) loads: L,
    pub(super) springs: &'a [SpringDamper],
    pub(super) inertias: [BodyInertia; NB],
    pub(super) inverse: [InverseMass; NB],
    pub(super) gravity: Vector3<f64>,
    /// What generalised-α's last step left for the next.
    pub(super) history: Option<generalised_alpha::AlphaHistory<NB, NV, M>>,
    /// Radau IIA's last stages (the next step's starting values).
    pub(super) radau: Option<RadauHistory<SystemState<NB>, NV, DenseJacobian<NV>>>,
    /// The options (may be changed between steps).
    pub options: SimulationOptions,
}

/// The accelerations at a state with `J`, `J M⁻¹` and the factorisation of
/// `J M⁻¹ Jᵀ` they were solved with.
#[derive(Clone, Copy)]
pub(super) struct Factored<const NV: usize, const M: usize> {
    pub(super) dynamics: Dynamics<NV, M>,
    pub(super) jacobian: SMatrix<f64, M, NV>,
    pub(super) jw: SMatrix<f64, M, NV>,
    pub(super) chol: PivotedCholesky<M>,
}

/// What the stages of one step share, decided at the step's start: which rows
/// of `J M⁻¹ Jᵀ` to drop as redundant (its pivot order and rank), so that every
/// stage drops the same ones, and whether the start was checked for
/// contradictory redundant rows.
pub(super) struct StepRule<const M: usize> {
    pub(super) order: [usize; M],
    pub(super) rank: usize,
    pub(super) checked: bool,
}

/// Shows the options and the mechanical data; the scene and the loads are shown
/// by type (neither needs to be `Debug`).
impl<S, L, const NB: usize, const NV: usize, const M: usize> core::fmt::Debug for DenseSimulation<'_, S, L, NB, NV, M> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("DenseSimulation")
            .field("scene", &core::any::type_name::<S>())
            .field("loads", &core::any::type_name::<L>())
            .field("springs", &self.springs)
            .field("inertias", &self.inertias)
            .field("gravity", &self.gravity)
            .field("options", &self.options)
            .finish_non_exhaustive()
    }
}

impl<'a, S, L, const NB: usize, const NV: usize, const M: usize> DenseSimulation<'a, S, L, NB, NV, M>
where
    S: Scene<NB, NV, M>,
    L: AppliedLoads<NB>,
{
    /// A simulation of `scene` with user `loads` (a closure or [`NoLoads`]) and
    /// `springs`.
    ///
    /// # Errors
    /// [`AnalysisError::BadInertia`] for a non-positive or non-finite mass or a
    /// singular inertia tensor, [`AnalysisError::BadOption`] for a spring attached
    /// to a body that does not exist or with non-finite coefficients,
    /// [`AnalysisError::Dimensions`] if `NV ≠ 6 NB`.
    pub fn new(
        scene: &'a S,
        loads: L,
        springs: &'a [SpringDamper],
        options: SimulationOptions,
    ) -> Result<Self, AnalysisError> {
        let Mechanics { inertias, inverse, gravity } = Mechanics::new(scene, springs)?;
        let (inertias, inverse) = (*inertias, *inverse);
        Ok(DenseSimulation { scene, loads, springs, inertias, inverse, gravity, history: None, radau: None, options })
    }

    /// The scene.
    pub fn scene(&self) -> &'a S {
        self.scene
    }

    /// The generalised forces `Q` (gravity, user loads, gyroscopic terms, springs).
    pub fn forces(&mut self, state: &SystemState<NB>) -> SVector<f64, NV> {
        generalised_forces(&mut self.loads, self.springs, &self.inertias, &self.gravity, state)
    }

    /// The rule of a step starting at `state`: the pivot order and rank of
    /// `J M⁻¹ Jᵀ` there.
    pub(super) fn step_rule(&self, state: &SystemState<NB>) -> Result<StepRule<M>, AnalysisError> {
        let j = self.scene.jacobian(state);
        check_output::<S, NB, NV, M, NV>("J", &j)?;
        let jw = jacobian_times_metric(Some(&self.inverse), &j);
        let chol = PivotedCholesky::new(&(jw * j.transpose()), self.options.rank_tolerance)?;
        Ok(StepRule { order: *chol.permutation(), rank: chol.rank(), checked: false })
    }

    /// The start of a step `h` from `state`: `h` and `state` checked, the
    /// normalised copy the step advances, and its rule for redundant rows.
    /// The rule is decided once, here: off the constraint manifold (at the
    /// stages) redundant rows disagree by O(h²), and a choice that switched
    /// between stages would cost the method its order.
    pub(super) fn step_start(
        &self,
        state: &SystemState<NB>,
        h: f64,
    ) -> Result<(SystemState<NB>, StepRule<M>), AnalysisError> {
        if !(h > 0.0 && h.is_finite()) {
            return Err(AnalysisError::BadOption { name: "step size" });
        }
        check_state::<S, NB, NV, M>(state, true)?;
        let mut y = *state;
        normalise_orientations::<S, NB, NV, M>(&mut y)?;
        let rule = self.step_rule(&y)?;
        Ok((y, rule))
    }

    /// Constrained accelerations and Lagrange multipliers at `state` (with the
    /// configured stabilisation). Redundant rows get zero multipliers; they must
    /// agree with the others to [`REDUNDANT_TOLERANCE`] (relative).
    ///
    /// # Errors
    /// Non-finite inputs or outputs; [`AnalysisError::Inconsistent`] when
    /// redundant constraints contradict each other.
    pub fn dynamics(&mut self, state: &SystemState<NB>) -> Result<Dynamics<NV, M>, AnalysisError> {
        self.solve(state, None)
    }

    /// [`dynamics`](Self::dynamics) on its own (`rule` `None`: the rows to drop
    /// chosen here, all checked), or at a stage of a step under its rule.
    pub(super) fn solve(
        &mut self,
        state: &SystemState<NB>,
        rule: Option<&mut StepRule<M>>,
    ) -> Result<Dynamics<NV, M>, AnalysisError> {
        self.solve_factored(state, rule).map(|f| f.dynamics)
    }

    /// [`solve`](Self::solve), with the factorisation it used (what the exact
    /// Newton matrices are built on).
    pub(super) fn solve_factored(
        &mut self,
        state: &SystemState<NB>,
        rule: Option<&mut StepRule<M>>,
    ) -> Result<Factored<NV, M>, AnalysisError> {
        check_state::<S, NB, NV, M>(state, true)?;
        let e = self.scene.evaluate(state);
        check_output::<S, NB, NV, M, NV>("J", &e.jacobian)?;
        check_output::<S, NB, NV, M, 1>("γ", &e.gamma)?;
        let mut gamma = e.gamma;
        if let Stabilisation::Baumgarte { alpha, beta } = self.options.stabilisation {
            check_output::<S, NB, NV, M, 1>("Φ", &e.phi)?;
            let phi_t = self.scene.phi_t(state);
            check_output::<S, NB, NV, M, 1>("Φ_t", &phi_t)?;
            let phi_dot = e.jacobian * velocity_vector::<NB, NV>(state) + phi_t;
            gamma -= phi_dot * (2.0 * alpha) + e.phi * (beta * beta);
        }
        let forces = self.forces(state);
        if !forces.iter().all(|x| x.is_finite()) {
            return Err(AnalysisError::NonFiniteOutput { quantity: "forces", row: None });
        }
        let metric = Some(&self.inverse);
        let minv_q = apply_metric::<NB, NV>(metric, &forces);
        let jw = jacobian_times_metric(metric, &e.jacobian);
        let gram = jw * e.jacobian.transpose();
        let chol = match &rule {
            Some(r) => PivotedCholesky::with_order(&gram, &r.order, r.rank, self.options.rank_tolerance)?,
            None => PivotedCholesky::new(&gram, self.options.rank_tolerance)?,
        };
        let lambda = chol.solve(&(e.jacobian * minv_q - gamma));
        let vdot = minv_q - jw.transpose() * lambda;
        let r = e.jacobian * vdot - gamma;
        let residual = r.norm();
        if !residual.is_finite() || !vdot.iter().all(|x| x.is_finite()) {
            return Err(AnalysisError::NonFiniteOutput { quantity: "accelerations", row: None });
        }
        // The rows the factorisation kept hold to round-off by construction. A
        // dropped (redundant) row holds only as far as the redundancy is exact:
        // on the constraint manifold, but an integrator's stage states sit
        // O(h²) off it, where redundant rows disagree by as much. Contradictory
        // constraints (two drivers of one freedom, say) disagree at O(1), so the
        // dropped rows are held to a looser tolerance that still tells the two
        // apart; projection removes the drift at the end of the step.
        let scale = 1.0 + gamma.norm() + e.jacobian.norm() * vdot.norm();
        // Within a step only the first stage (the step's own start) is checked:
        // contradiction is a property of the configuration, while later stages
        // sit O(h²) off the manifold by construction.
        let check_dropped = match rule {
            Some(r) => !core::mem::replace(&mut r.checked, true),
            None => true,
        };
        check_redundant::<S, NB, NV, M>(&r, chol.dropped(), scale, check_dropped)?;
        let dynamics = Dynamics { vdot, lambda, forces, redundant: RowList::from_rows::<S, NB, NV>(chol.dropped()) };
        Ok(Factored { dynamics, jacobian: e.jacobian, jw, chol })
    }

    /// The reaction of the joint `block` (one of [`Scene::BLOCKS`]) on every body,
    /// from the multipliers `lambda` of [`DenseSimulation::dynamics`] at `state`:
    /// `−J_kᵀ λ_k` split by body. Rows outside `0..M` are ignored.
    pub fn reactions(&self, state: &SystemState<NB>, lambda: &SVector<f64, M>, block: &RowBlock) -> [Reaction; NB] {
        let j = self.scene.jacobian(state);
        let mut out = [Reaction::default(); NB];
        let end = block.start.saturating_add(block.rows).min(M);
        for (i, reaction) in out.iter_mut().enumerate() {
            if 6 * i + 6 > NV {
                break;
            }
            for row in block.start.min(end)..end {
                for c in 0..3 {
                    reaction.force[c] -= j[(row, 6 * i + c)] * lambda[row];
                    reaction.torque[c] -= j[(row, 6 * i + 3 + c)] * lambda[row];
                }
            }
        }
        out
    }

    /// Kinetic, gravitational and elastic energy at `state`.
    pub fn energy(&self, state: &SystemState<NB>) -> Energy {
        energy(&self.inertias, &self.gravity, self.springs, state)
    }

    /// Projects `state` onto the constraints: positions onto Φ = 0 by minimum-norm
    /// (mass-metric) Newton steps with `options`, then velocities onto
    /// `J v = −Φ_t` (mass-metric, the least change of kinetic energy). Returns the
    /// Newton iterations, ‖Φ‖ and ‖J v + Φ_t‖ after the projection.
    ///
    /// # Errors
    /// As [`crate::analysis::assemble`], except that stopping short of the
    /// tolerance by less than a factor 1000 (round-off floor) is accepted.
    pub fn project(
        &self,
        state: &mut SystemState<NB>,
        options: &AssemblyOptions,
    ) -> Result<(usize, f64, f64), AnalysisError> {
        let (iterations, residual) = near_enough(
            newton(self.scene, state, options, Some(&self.inverse)).map(|a| (a.iterations, a.residual)),
            options,
        )?;
        let j = self.scene.jacobian(state);
        let phi_t = self.scene.phi_t(state);
        check_output::<S, NB, NV, M, 1>("Φ_t", &phi_t)?;
        let v = velocity_vector::<NB, NV>(state);
        let dv = min_norm(&j, &(-(j * v + phi_t)), Some(&self.inverse), options.rank_tolerance)?.x;
        let v = v + dv;
        set_velocities(state, &v);
        let velocity_residual = (j * v + phi_t).norm();
        Ok((iterations, residual, velocity_residual))
    }

    pub(super) fn rate(
        &mut self,
        state: &SystemState<NB>,
        rule: &mut StepRule<M>,
    ) -> Result<Rate<NB, NV>, AnalysisError> {
        Ok(Rate::new(state, self.solve(state, Some(rule))?.vdot))
    }

    pub(super) fn step_rk4(
        &mut self,
        state: &mut SystemState<NB>,
        h: f64,
        rule: &mut StepRule<M>,
    ) -> Result<usize, AnalysisError> {
        let y0 = *state;
        let t0 = y0.t;
        let k1 = self.rate(&y0, rule)?;
        let k2 = self.rate(&advance(&y0, [(&k1, 0.5)], h, t0 + 0.5 * h), rule)?;
        let k3 = self.rate(&advance(&y0, [(&k2, 0.5)], h, t0 + 0.5 * h), rule)?;
        let k4 = self.rate(&advance(&y0, [(&k3, 1.0)], h, t0 + h), rule)?;
        *state = advance(&y0, rk4_weights(&k1, &k2, &k3, &k4), h, t0 + h);
        Ok(0)
    }

    /// `w − v_n − (h/2) a(q_n ⊕ (h/2) w, w, t_n + h/2)`, with the
    /// factorisation the accelerations were solved with (the generated Newton
    /// matrix at this `w` is built on it).
    pub(super) fn midpoint_residual(
        &mut self,
        y0: &SystemState<NB>,
        v0: &SVector<f64, NV>,
        w: &SVector<f64, NV>,
        h: f64,
        rule: &mut StepRule<M>,
    ) -> Result<(SVector<f64, NV>, Factored<NV, M>), AnalysisError> {
        let mid = midpoint_state(y0, w, h);
        let f = self.solve_factored(&mid, Some(rule))?;
        Ok((w - v0 - f.dynamics.vdot * (0.5 * h), f))
    }

    /// The iteration matrix `∂R/∂w` at `w`: generated (from `at`, the
    /// residual's factorisation there), or forward differences of the
    /// residual `r` at `w`.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn midpoint_matrix(
        &mut self,
        y0: &SystemState<NB>,
        v0: &SVector<f64, NV>,
        w: &SVector<f64, NV>,
        (r, at): &(SVector<f64, NV>, Factored<NV, M>),
        h: f64,
        rule: &mut StepRule<M>,
    ) -> Result<SMatrix<f64, NV, NV>, AnalysisError> {
        if self.options.newton_matrix == NewtonMatrix::Generated
            && let Some((m, _)) = self.midpoint_tangent(y0, w, h, rule, Some(at))?
        {
            return Ok(m);
        }
        let mut jac = SMatrix::<f64, NV, NV>::zeros();
        for c in 0..NV {
            let eps = 1e-7 * (1.0 + libm::fabs(w[c]));
            let mut wc = *w;
            wc[c] += eps;
            let (rc, _) = self.midpoint_residual(y0, v0, &wc, h, rule)?;
            jac.set_column(c, &((rc - r) / eps));
        }
        Ok(jac)
    }

    /// One step of the implicit midpoint rule; returns the Newton iterations
    /// and the iteration matrices built.
    pub(super) fn step_midpoint(
        &mut self,
        state: &mut SystemState<NB>,
        h: f64,
        rule: &mut StepRule<M>,
    ) -> Result<(usize, usize), AnalysisError> {
        let y0 = *state;
        let v0 = velocity_vector::<NB, NV>(&y0);
        // Explicit predictor.
        let mut w = v0 + self.solve(&y0, Some(rule))?.vdot * (0.5 * h);
        let mut r = self.midpoint_residual(&y0, &v0, &w, h, rule)?;
        let mut lu: Option<Lu<NV>> = None;
        let mut newton = ModifiedNewton::new(&self.options);
        loop {
            newton.next()?;
            let factor = match lu {
                Some(f) if !newton.stale() => f,
                _ => {
                    let f = Lu::new(&self.midpoint_matrix(&y0, &v0, &w, &r, h, rule)?)?;
                    newton.built();
                    lu = Some(f);
                    f
                }
            };
            let dw = factor.solve(&(-r.0));
            w += dw;
            r = self.midpoint_residual(&y0, &v0, &w, h, rule)?;
            if newton.converged(dw.norm(), 1.0 + w.norm())? {
                break;
            }
        }
        let end = midpoint_end(&y0, &v0, &w, h);
        let mid = midpoint_state(&y0, &w, h);
        let constraint_power = -r.1.dynamics.lambda.dot(&(r.1.jacobian * w));
        let work = midpoint_work::<L, NB, NV>(&mut self.loads, &self.inertias, &mid, constraint_power, h);
        energy_balance(&self.energy(&y0), &self.energy(&end), work)?;
        *state = end;
        Ok(newton.counts())
    }

    /// Advances `state` by one step `h` with the configured integrator, then
    /// projects onto the constraints if configured.
    ///
    /// # Errors
    /// [`AnalysisError::BadOption`] for a step that is not positive and finite;
    /// non-finite inputs; failures of the dynamics, of the implicit iteration or
    /// of the projection. On error `state` is unchanged.
    pub fn step(&mut self, state: &mut SystemState<NB>, h: f64) -> Result<StepReport, AnalysisError> {
        let (mut y, mut rule) = self.step_start(state, h)?;
        // Generalised-α goes on from its last step only if handed back its state.
        let continuing = self.history.is_some_and(|h| h.state == *state);
        let (newton_iterations, newton_matrices) = match self.options.integrator {
            Integrator::Rk4 => (self.step_rk4(&mut y, h, &mut rule)?, 0),
            Integrator::ImplicitMidpoint => self.step_midpoint(&mut y, h, &mut rule)?,
            Integrator::GeneralisedAlpha => self.step_alpha(&mut y, h, continuing, &mut rule)?,
            Integrator::RadauIIA => {
                let (mut host, mut work) = (DenseRadau::new(self, &mut rule), RadauWork::new());
                let step = step_radau(&mut host, &mut work, &mut y, h, None)?;
                (step.iterations, step.matrices)
            }
        };
        let mut report = StepReport { newton_iterations, newton_matrices, ..StepReport::default() };
        if let Some(options) = self.options.projection {
            // Projected on the copy: a failed projection (a NaN parameter seen
            // only by Φ, say) leaves the caller's state as it was.
            let (it, c, v) = self.project(&mut y, &options)?;
            *state = y;
            report.projection_iterations = it;
            report.constraint_residual = c;
            report.velocity_residual = v;
        } else {
            *state = y;
            report.constraint_residual = self.scene.phi(state).norm();
            let phi_dot = self.scene.jacobian(state) * velocity_vector::<NB, NV>(state) + self.scene.phi_t(state);
            report.velocity_residual = phi_dot.norm();
        }
        self.follow(*state, self.options.integrator);
        Ok(report)
    }
}

impl<S, L, const NB: usize, const NV: usize, const M: usize> DenseSimulation<'_, S, L, NB, NV, M> {
    /// The histories after a step of `integrator` was accepted at `state`:
    /// its own follows the state, the others are dropped.
    pub(super) fn follow(&mut self, state: SystemState<NB>, integrator: Integrator) {
        match (&mut self.history, integrator) {
            (Some(history), Integrator::GeneralisedAlpha) => history.state = state,
            _ => self.history = None,
        }
        match (&mut self.radau, integrator) {
            (Some(radau), Integrator::RadauIIA) => radau.accept(&state),
            _ => self.radau = None,
        }
    }
}

/// `q_n ⊕ s u` with velocities `v`, at time `t`: what the implicit
/// integrators' stages and ends are made of.
pub(crate) fn displaced<const NB: usize, const NV: usize>(
    y0: &SystemState<NB>,
    u: &SVector<f64, NV>,
    s: f64,
    v: &SVector<f64, NV>,
    t: f64,
) -> SystemState<NB> {
    let mut y = *y0;
    displaced_into(y0, u, s, v, t, &mut y);
    y
}

/// The implicit midpoint rule's end of step from `y0` (velocities `v0`)
/// with the midpoint velocity `w`: `q_n ⊕ h w`, `v_{n+1} = 2w − v_n`, at
/// `t_n + h`.
pub(crate) fn midpoint_end<const NB: usize, const NV: usize>(
    y0: &SystemState<NB>,
    v0: &SVector<f64, NV>,
    w: &SVector<f64, NV>,
    h: f64,
) -> SystemState<NB> {
    let (mut end, mut v) = (*y0, *v0);
    midpoint_end_into(y0, v0, w, h, &mut v, &mut end);
    end
}

/// The work done over an implicit midpoint step by the forces that the
/// energy of [`DenseSimulation::energy`] does not hold: the user's loads and the
/// constraint forces (`constraint_power = −λᵀ J w`, nonzero where drivers
/// move the mechanism), both at the midpoint with its velocity `w`. Gravity
/// and the springs are in the energy; the dampers and the gyroscopic terms only
/// take energy out (or none).
pub(crate) fn midpoint_work<L: AppliedLoads<NB>, const NB: usize, const NV: usize>(
    loads: &mut L,
    inertias: &[BodyInertia; NB],
    mid: &SystemState<NB>,
    constraint_power: f64,
    h: f64,
) -> f64 {
    let user: SVector<f64, NV> = generalised_forces(loads, &[], inertias, &Vector3::zeros(), mid);
    h * (user.dot(&velocity_vector::<NB, NV>(mid)) + constraint_power)
}
