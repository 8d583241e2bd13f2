//! Radau IIA on the dense path: `A_q`, `A_v` dense, the stage systems by [`Lu`].

use nalgebra::{SMatrix, SVector};

use super::displaced;
use super::{DenseSimulation, Factored, StepRule};
use crate::analysis::{AnalysisError, velocity_vector};
use crate::dynamics::radau::*;
use crate::dynamics::{AppliedLoads, NewtonMatrix};
use crate::scene::{Scene, SystemState};

/// `A_q` and `A_v`, dense.
pub(crate) type DenseJacobian<const NV: usize> = (SMatrix<f64, NV, NV>, SMatrix<f64, NV, NV>);

/// The dense [`DenseSimulation`] under the rule of a step, as a [`RadauHost`]:
/// `A_q`, `A_v` dense and the stage systems factorised by [`Lu`].
pub(super) struct DenseRadau<'r, 'a, S, L, const NB: usize, const NV: usize, const M: usize> {
    pub(super) sim: &'r mut DenseSimulation<'a, S, L, NB, NV, M>,
    pub(super) rule: &'r mut StepRule<M>,
    /// The start's factorisation, for the generated Jacobian.
    start: Option<Factored<NV, M>>,
}

impl<'r, 'a, S, L, const NB: usize, const NV: usize, const M: usize> DenseRadau<'r, 'a, S, L, NB, NV, M> {
    /// The host of one step of `sim` under `rule`.
    pub(super) fn new(sim: &'r mut DenseSimulation<'a, S, L, NB, NV, M>, rule: &'r mut StepRule<M>) -> Self {
        DenseRadau { sim, rule, start: None }
    }
}

impl<S, L, const NB: usize, const NV: usize, const M: usize> RadauHost<NV> for DenseRadau<'_, '_, S, L, NB, NV, M>
where
    S: Scene<NB, NV, M>,
    L: AppliedLoads<NB>,
{
    type Group = Bodies<NB>;
    type Error = AnalysisError;
    type Jacobian = DenseJacobian<NV>;
    type Factors = DenseFactors<NV>;

    fn error(e: AnalysisError) -> AnalysisError {
        e
    }

    fn group(&self) -> &Bodies<NB> {
        &Bodies
    }

    fn newton_limits(&self) -> (usize, f64) {
        (self.sim.options.newton_max_iterations, self.sim.options.newton_tolerance)
    }

    fn history(&mut self) -> &mut Option<RadauHistory<SystemState<NB>, NV, Self::Jacobian>> {
        &mut self.sim.radau
    }

    fn start(&mut self, y0: &SystemState<NB>, out: &mut SVector<f64, NV>) -> Result<(), AnalysisError> {
        let start = self.sim.solve_factored(y0, Some(self.rule))?;
        self.start = Some(start);
        *out = start.dynamics.vdot;
        Ok(())
    }

    fn accelerations(&mut self, state: &SystemState<NB>, out: &mut SVector<f64, NV>) -> Result<(), AnalysisError> {
        *out = self.sim.solve(state, Some(self.rule))?.vdot;
        Ok(())
    }

    fn jacobian(&mut self, y0: &SystemState<NB>) -> Result<(Self::Jacobian, usize), AnalysisError> {
        let start = match self.start {
            Some(start) => start,
            None => self.sim.solve_factored(y0, Some(self.rule))?,
        };
        let (aq, av, evaluations) = self.sim.radau_jacobian(y0, start, self.rule)?;
        Ok(((aq, av), evaluations))
    }

    fn factor(&mut self, jacobian: &Self::Jacobian, h: f64) -> Result<Self::Factors, AnalysisError> {
        DenseFactors::new(&jacobian.0, &jacobian.1, h)
    }

    fn solve_real(
        &mut self,
        factors: &Self::Factors,
        (r, s): (&SVector<f64, NV>, &SVector<f64, NV>),
        (x, y): (&mut SVector<f64, NV>, &mut SVector<f64, NV>),
    ) {
        factors.solve_real_into((r, s), (x, y));
    }

    fn solve_complex(
        &mut self,
        factors: &Self::Factors,
        r: (&SVector<f64, NV>, &SVector<f64, NV>),
        s: (&SVector<f64, NV>, &SVector<f64, NV>),
        x: (&mut SVector<f64, NV>, &mut SVector<f64, NV>),
        y: (&mut SVector<f64, NV>, &mut SVector<f64, NV>),
    ) {
        factors.solve_complex_into(r, s, x, y);
    }
}

impl<S, L, const NB: usize, const NV: usize, const M: usize> DenseSimulation<'_, S, L, NB, NV, M>
where
    S: Scene<NB, NV, M>,
    L: AppliedLoads<NB>,
{
    /// `A_q = ∂a/∂q` (increments at the state) and `A_v = ∂a/∂v` at `y0`,
    /// whose accelerations `start` solved, and the dynamics evaluations spent.
    #[allow(clippy::type_complexity)]
    fn radau_jacobian(
        &mut self,
        y0: &SystemState<NB>,
        start: Factored<NV, M>,
        rule: &mut StepRule<M>,
    ) -> Result<(SMatrix<f64, NV, NV>, SMatrix<f64, NV, NV>, usize), AnalysisError> {
        let a0 = start.dynamics.vdot;
        if self.options.newton_matrix == NewtonMatrix::Generated
            && let Some(t) = self.tangent_on(y0, start)?
        {
            return Ok((t.accelerations(&t.r1q, &t.r2q), t.accelerations(&t.r1v, &t.r2v), 0));
        }
        let v0 = velocity_vector::<NB, NV>(y0);
        let (mut aq, mut av) = (SMatrix::<f64, NV, NV>::zeros(), SMatrix::<f64, NV, NV>::zeros());
        for (c, (mut q, mut v)) in aq.column_iter_mut().zip(av.column_iter_mut()).enumerate() {
            let unit = |size: f64| SVector::<f64, NV>::from_fn(|i, _| if i == c { size } else { 0.0 });
            let a = self.solve(&displaced(y0, &unit(1e-7), 1.0, &v0, y0.t), Some(rule))?.vdot;
            q.copy_from(&((a - a0) / 1e-7));
            let eps = 1e-7 * (1.0 + libm::fabs(v0.get(c).copied().unwrap_or(0.0)));
            let a = self.solve(&displaced(y0, &SVector::zeros(), 1.0, &(v0 + unit(eps)), y0.t), Some(rule))?.vdot;
            v.copy_from(&((a - a0) / eps));
        }
        Ok((aq, av, 2 * NV))
    }
}
