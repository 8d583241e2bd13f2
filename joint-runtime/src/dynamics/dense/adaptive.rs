//! [`DenseSimulation::integrate`]: the shared error-controlled driver on the dense path.

use super::DenseSimulation;
use crate::analysis::{AnalysisError, check_state};
use crate::dynamics::adaptive::{AdaptiveSteps, alpha_estimate, dormand_prince, integrate};
use crate::dynamics::radau::{RadauWork, step_radau};
use crate::dynamics::{Adaptive, AppliedLoads, IntegrationReport, Integrator, Tolerance};
use crate::scene::{Scene, SystemState};

impl<S, L, const NB: usize, const NV: usize, const M: usize> DenseSimulation<'_, S, L, NB, NV, M>
where
    S: Scene<NB, NV, M>,
    L: AppliedLoads<NB>,
{
    /// Advances `state` to time `t_end` with error-controlled steps of
    /// `method`, projecting after every accepted step if the options say so.
    ///
    /// # Errors
    /// As [`AbsoluteSimulation::integrate`](super::AbsoluteSimulation::integrate).
    pub fn integrate(
        &mut self,
        state: &mut SystemState<NB>,
        t_end: f64,
        method: Adaptive,
        tolerance: Tolerance,
    ) -> Result<IntegrationReport, AnalysisError> {
        let saved = self.options.integrator;
        if method == Adaptive::GeneralisedAlpha {
            self.options.integrator = Integrator::GeneralisedAlpha;
        }
        let result = integrate(self, state, t_end, method, tolerance);
        self.options.integrator = saved;
        result
    }
}

impl<S, L, const NB: usize, const NV: usize, const M: usize> AdaptiveSteps for DenseSimulation<'_, S, L, NB, NV, M>
where
    S: Scene<NB, NV, M>,
    L: AppliedLoads<NB>,
{
    type State = SystemState<NB>;
    type Error = AnalysisError;

    fn check_start(&self, state: &SystemState<NB>) -> Result<(), AnalysisError> {
        check_state::<S, NB, NV, M>(state, true)
    }

    fn trial(
        &mut self,
        y0: &SystemState<NB>,
        h: f64,
        method: Adaptive,
        tolerance: Tolerance,
        report: &mut IntegrationReport,
    ) -> Result<(SystemState<NB>, f64), AnalysisError> {
        match method {
            Adaptive::DormandPrince => {
                let (y, mut rule) = self.step_start(y0, h)?;
                let first = self.rate(&y, &mut rule)?;
                dormand_prince(&y, first, h, tolerance, report, |stage| self.rate(stage, &mut rule))
            }
            Adaptive::GeneralisedAlpha => {
                let continuing = self.history.is_some_and(|past| past.state == *y0);
                let (mut y, mut rule) = self.step_start(y0, h)?;
                let saved = self.history;
                // The history the step starts from (fresh from the dynamics
                // unless it goes on from the last step), kept for the estimate.
                let past = self.alpha_history(&y, continuing, &mut rule)?;
                let before = past.a;
                self.history = Some(past);
                let (iterations, matrices) = self.step_alpha(&mut y, h, true, &mut rule).inspect_err(|_| {
                    self.history = saved;
                })?;
                let after = self.history.map_or(before, |past| past.a);
                let rho = self.options.spectral_radius;
                let err = alpha_estimate(y0, &y, &(after - before), h, rho, tolerance, report, (iterations, matrices));
                if err > 1.0 {
                    self.history = saved;
                }
                Ok((y, err))
            }
            Adaptive::RadauIIA => {
                let (mut y, mut rule) = self.step_start(y0, h)?;
                let mut host = super::radau::DenseRadau::new(self, &mut rule);
                let step = step_radau(&mut host, &mut RadauWork::new(), &mut y, h, Some(tolerance))?;
                report.newton_iterations += step.iterations;
                report.newton_matrices += step.matrices;
                report.evaluations += step.evaluations;
                Ok((y, step.error))
            }
        }
    }

    fn accept(&mut self, next: SystemState<NB>, method: Adaptive) -> Result<SystemState<NB>, AnalysisError> {
        let mut next = next;
        if let Some(options) = self.options.projection {
            self.project(&mut next, &options)?;
        }
        self.follow(next, method.integrator());
        Ok(next)
    }
}
