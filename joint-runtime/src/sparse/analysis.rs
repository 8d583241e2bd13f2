//! The kinematic analyses of [`crate::analysis`] on the block factor: assembly,
//! velocity and acceleration analysis of large scenes, with the same results
//! and errors, a workspace allocated once and no `M × NV` matrix.

use crate::analysis::{
    AccelerationAnalysis, Analysis, AnalysisError, Assembly, AssemblyOptions, InverseMass, NewtonWork,
    VelocityAnalysis, check_state, set_velocities,
};
use crate::linalg::DEFAULT_RANK_TOLERANCE;
use crate::scene::{Scene, SparseJacobian, SystemState};

use super::solver::{Solver, non_finite, unit_metric};

/// Assembly, velocity and acceleration analysis of one scene type on its
/// sparse block factor (built once, in [`SparseAnalysis::new`]).
pub struct SparseAnalysis<
    S: SparseJacobian<NB, NNZ>,
    const NB: usize,
    const NV: usize,
    const M: usize,
    const NNZ: usize,
> {
    solver: Solver<S, NB, NV, M, NNZ>,
    unit: [InverseMass; NB],
    /// Relative rank tolerance of the velocity and acceleration solves.
    pub rank_tolerance: f64,
}

impl<S: SparseJacobian<NB, NNZ>, const NB: usize, const NV: usize, const M: usize, const NNZ: usize> core::fmt::Debug
    for SparseAnalysis<S, NB, NV, M, NNZ>
{
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("SparseAnalysis")
            .field("scene", &core::any::type_name::<S>())
            .field("factor_blocks", &self.solver.factor.factor_blocks())
            .finish_non_exhaustive()
    }
}

impl<S, const NB: usize, const NV: usize, const M: usize, const NNZ: usize> SparseAnalysis<S, NB, NV, M, NNZ>
where
    S: Scene<NB, NV, M> + SparseJacobian<NB, NNZ>,
{
    /// The analyses of scenes of type `S`.
    ///
    /// # Errors
    /// [`AnalysisError::Dimensions`] if `NV ≠ 6 NB`; a structure that
    /// contradicts itself (a hand-written impl) is reported as a non-finite `J`.
    pub fn new(_scene: &S) -> Result<Self, AnalysisError> {
        let solver = Solver::new()?;
        Ok(SparseAnalysis { solver, unit: unit_metric(), rank_tolerance: DEFAULT_RANK_TOLERANCE })
    }

    /// [`crate::analysis::assemble`] on the block factor: damped minimum-norm
    /// Newton onto Φ = 0 from a rough configuration.
    ///
    /// # Errors
    /// As [`crate::analysis::assemble`].
    pub fn assemble(
        &mut self,
        scene: &S,
        state: &mut SystemState<NB>,
        options: &AssemblyOptions,
    ) -> Result<Assembly<M>, AnalysisError> {
        let unit = self.unit;
        let (iterations, residual) =
            self.solver.newton(scene, state, options, &unit, &mut [0.0; NNZ], &mut NewtonWork::new())?;
        Ok(Assembly { iterations, residual, redundant: self.solver.redundant() })
    }

    /// [`crate::analysis::velocities`] on the block factor: `J v = −Φ_t`,
    /// minimum norm, written into `state`.
    ///
    /// # Errors
    /// As [`crate::analysis::velocities`].
    pub fn velocities(&mut self, scene: &S, state: &mut SystemState<NB>) -> Result<VelocityAnalysis<M>, AnalysisError> {
        check_state::<S, NB, NV, M>(state, false)?;
        let values = scene.jacobian_values(state);
        let phi_t = scene.phi_t(state);
        if !phi_t.iter().all(|x| x.is_finite()) {
            return Err(non_finite("Φ_t"));
        }
        let unit = self.unit;
        let (v, residual) =
            self.solver.solve_linear(Analysis::Velocity, &values, -phi_t, &unit, self.rank_tolerance)?;
        set_velocities(state, &v);
        Ok(VelocityAnalysis { residual, redundant: self.solver.redundant() })
    }

    /// [`crate::analysis::accelerations`] on the block factor: `J v̇ = γ`,
    /// minimum norm.
    ///
    /// # Errors
    /// As [`crate::analysis::accelerations`].
    pub fn accelerations(
        &mut self,
        scene: &S,
        state: &SystemState<NB>,
    ) -> Result<AccelerationAnalysis<NV, M>, AnalysisError> {
        check_state::<S, NB, NV, M>(state, true)?;
        let values = scene.jacobian_values(state);
        let gamma = scene.gamma(state);
        if !gamma.iter().all(|x| x.is_finite()) {
            return Err(non_finite("γ"));
        }
        let unit = self.unit;
        let (vdot, residual) =
            self.solver.solve_linear(Analysis::Acceleration, &values, gamma, &unit, self.rank_tolerance)?;
        Ok(AccelerationAnalysis { vdot, residual, redundant: self.solver.redundant() })
    }
}
