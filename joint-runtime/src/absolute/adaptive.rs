//! [`AbsoluteSimulation::integrate`]: the error-controlled driver of
//! `dynamics/adaptive.rs` (written once for both paths) over the block path's
//! stages, generalised-α and Radau steps and projection.

use super::AbsoluteSimulation;
use super::simulation::with_taken;
use crate::analysis::{AnalysisError, check_state};
use crate::dynamics::adaptive::{AdaptiveSteps, alpha_estimate, dormand_prince, integrate};
use crate::dynamics::radau::step_radau;
use crate::dynamics::{Adaptive, AppliedLoads, IntegrationReport, Rate, Tolerance};
use crate::scene::{Scene, SparseJacobian, SystemState};

impl<S, L, const NB: usize, const NV: usize, const M: usize, const NNZ: usize>
    AbsoluteSimulation<'_, S, L, NB, NV, M, NNZ>
where
    S: Scene<NB, NV, M> + SparseJacobian<NB, NNZ>,
    L: AppliedLoads<NB>,
{
    /// Advances `state` to time `t_end` with error-controlled steps of
    /// `method`, projecting after every accepted step if the options say so,
    /// in time and memory proportional to the scene. An implicit method
    /// steps in the workspace [`AbsoluteSimulation::new`] made for it (that integrator
    /// in the options) or [`AbsoluteSimulation::prepare`]: `integrate` never builds
    /// one, so it never allocates.
    ///
    /// # Errors
    /// [`AnalysisError::BadOption`] for tolerances that are not positive and
    /// finite or a `t_end` before the state's time;
    /// [`AnalysisError::NotPrepared`] for an implicit method whose workspace
    /// was not made; failures of the dynamics or
    /// of the projection; [`AnalysisError::StepTooSmall`] when the step size
    /// falls below `1e-14 (1 + |t|)` or past ten million steps. On error
    /// `state` holds the last accepted step.
    ///
    /// # Examples
    /// ```
    /// use joint_runtime::dynamics::{Adaptive, NoLoads, Simulation, SimulationOptions, Tolerance};
    /// use joint_runtime::{OmegaBody, Scene, SystemState};
    /// use joint_runtime::nalgebra::{UnitQuaternion, Vector3};
    ///
    /// /// A bar hanging from a spherical joint at the origin.
    /// #[derive(Scene)]
    /// #[scene(coordinates = absolute, gravity = [0, 0, -9.81])]
    /// #[body(bar, mass = 1.0, inertia = [0.001, 0.08, 0.08])]
    /// #[joint(pivot = spherical(ground, bar), rho1 = [0, 0, 0], rho2 = [-0.5, 0, 0])]
    /// struct Pendulum;
    ///
    /// let level = UnitQuaternion::identity();
    /// let bar = OmegaBody::from_rotation(Vector3::new(0.5, 0.0, 0.0), &level, Vector3::zeros(), Vector3::zeros());
    /// let mut state = SystemState { bodies: [bar], t: 0.0 };
    /// let mut sim = Simulation::new(&Pendulum, NoLoads, &[], SimulationOptions::default())?;
    /// let tolerance = Tolerance { rtol: 1e-8, atol: 1e-8 };
    /// let report = sim.integrate(&mut state, 0.5, Adaptive::DormandPrince, tolerance)?;
    /// assert_eq!(state.t, 0.5);
    /// assert!(report.accepted > 0);
    /// // The bar's end is still at the origin.
    /// let end = state.bodies[0].r - state.bodies[0].rotation() * Vector3::new(0.5, 0.0, 0.0);
    /// assert!(end.norm() < 1e-9);
    /// # Ok::<(), joint_runtime::analysis::AnalysisError>(())
    /// ```
    pub fn integrate(
        &mut self,
        state: &mut SystemState<NB>,
        t_end: f64,
        method: Adaptive,
        tolerance: Tolerance,
    ) -> Result<IntegrationReport, AnalysisError> {
        match method {
            Adaptive::GeneralisedAlpha => self.ready(crate::dynamics::Integrator::GeneralisedAlpha)?,
            Adaptive::RadauIIA => self.ready(crate::dynamics::Integrator::RadauIIA)?,
            Adaptive::DormandPrince => {}
        }
        integrate(self, state, t_end, method, tolerance)
    }
}

impl<S, L, const NB: usize, const NV: usize, const M: usize, const NNZ: usize> AdaptiveSteps
    for AbsoluteSimulation<'_, S, L, NB, NV, M, NNZ>
where
    S: Scene<NB, NV, M> + SparseJacobian<NB, NNZ>,
    L: AppliedLoads<NB>,
{
    type State = SystemState<NB>;
    type Error = AnalysisError;

    fn check_start(&self, state: &SystemState<NB>) -> Result<(), AnalysisError> {
        check_state::<S, NB, NV, M>(state, true)?;
        self.check_assembled(state)
    }

    fn trial(
        &mut self,
        y0: &SystemState<NB>,
        h: f64,
        method: Adaptive,
        tolerance: Tolerance,
        report: &mut IntegrationReport,
    ) -> Result<(SystemState<NB>, f64), AnalysisError> {
        let continuing = self.alpha.as_deref().and_then(|w| w.history.as_ref()).is_some_and(|past| past.state == *y0);
        let (y, d) = self.step_start(y0)?;
        match method {
            Adaptive::DormandPrince => {
                dormand_prince(&y, Rate::new(&y, d.vdot), h, tolerance, report, |stage| self.rate(stage))
            }
            Adaptive::GeneralisedAlpha => {
                let saved = self.alpha.as_deref().and_then(|w| w.history);
                let before = match (continuing, saved) {
                    (true, Some(past)) => past.a,
                    _ => d.vdot,
                };
                let restore = |sim: &mut Self| {
                    if let Some(w) = sim.alpha.as_deref_mut() {
                        w.history = saved;
                    }
                };
                let (y1, iterations, matrices) =
                    self.step_alpha(&y, h, continuing, (d.vdot, d.lambda)).inspect_err(|_| restore(self))?;
                let after = self.alpha.as_deref().and_then(|w| w.history.as_ref()).map_or(before, |past| past.a);
                let rho = self.options.spectral_radius;
                let err = alpha_estimate(y0, &y1, &(after - before), h, rho, tolerance, report, (iterations, matrices));
                if err > 1.0 {
                    restore(self);
                }
                Ok((y1, err))
            }
            Adaptive::RadauIIA => {
                let mut y1 = y;
                // `step_start` left its solve at `y` in the workspace.
                self.remember_radau_start(&y);
                let step =
                    with_taken(self, |s| &mut s.radau_work, |sim, w| step_radau(sim, w, &mut y1, h, Some(tolerance)))?;
                report.newton_iterations += step.iterations;
                report.newton_matrices += step.matrices;
                report.evaluations += step.evaluations;
                Ok((y1, step.error))
            }
        }
    }

    fn accept(&mut self, next: SystemState<NB>, method: Adaptive) -> Result<SystemState<NB>, AnalysisError> {
        let mut next = next;
        if let Some(options) = self.options.projection {
            self.project(&mut next, &options)?;
        }
        self.follow(&next, method.integrator());
        Ok(next)
    }
}
