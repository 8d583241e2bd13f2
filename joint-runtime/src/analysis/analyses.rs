//! [`Analyses`]: assembly, velocity and acceleration analysis of one scene on
//! its block factor (the derive's pattern and elimination order), reading
//! only Φ, Φ_t, γ and the Jacobian's nonzero entries: no `M × NV` matrix.

use super::{
    AccelerationAnalysis, Analysis, AnalysisError, Assembly, AssemblyOptions, InverseMass, NewtonWork,
    VelocityAnalysis, check_output, check_state, check_values, set_velocities,
};
use crate::absolute::solver::{Solver, unit_metric};
use crate::linalg::DEFAULT_RANK_TOLERANCE;
use crate::scene::{Scene, SparseJacobian, SystemState};

/// The kinematic analyses of one scene: assembly, velocity and acceleration
/// analysis on the scene's block factor, whose storage the derive sized
/// (made once, in [`Analyses::new`]; boxed with `alloc`, inline without).
/// The functions [`assemble`](super::assemble), [`velocities`](super::velocities)
/// and [`accelerations`](super::accelerations) make one for a single call;
/// keep one to analyse repeatedly without making it again (and without
/// allocating after `new`).
///
/// ```
/// use joint_runtime::analysis::{Analyses, AssemblyOptions};
/// use joint_runtime::nalgebra::{UnitQuaternion, Vector3};
/// use joint_runtime::{OmegaBody, Scene, SystemState};
///
/// /// A link hinged at the origin about y, its centre of mass 0.5 m along x.
/// #[derive(Scene)]
/// #[scene(coordinates = absolute)]
/// #[body(link, mass = 1.0, inertia = [0.01, 0.1, 0.1])]
/// #[joint(hinge = revolute(ground, link), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0, 0, 0], rho2 = [-0.5, 0, 0])]
/// struct Pendulum;
///
/// let tilt = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), 0.3);
/// let rough = OmegaBody::from_rotation(Vector3::new(0.4, 0.1, -0.2), &tilt, Vector3::zeros(), Vector3::zeros());
/// let mut state = SystemState { bodies: [rough], t: 0.0 };
/// let mut analyses = Analyses::new(&Pendulum)?;
/// let assembly = analyses.assemble(&mut state, &AssemblyOptions::default())?;
/// assert!(assembly.residual < 1e-12);
/// // The hinge holds the link's far end 0.5 m from the origin.
/// assert!((state.bodies[0].r.norm() - 0.5).abs() < 1e-12);
/// let a = analyses.accelerations(&state)?;
/// assert!(a.residual < 1e-12);
/// # Ok::<(), joint_runtime::analysis::AnalysisError>(())
/// ```
pub struct Analyses<'a, S: SparseJacobian<NB, NNZ>, const NB: usize, const NV: usize, const M: usize, const NNZ: usize>
{
    scene: &'a S,
    solver: Solver<S, NB, NV, M, NNZ>,
    unit: [InverseMass; NB],
    /// Relative rank tolerance of the velocity and acceleration solves.
    pub rank_tolerance: f64,
}

impl<S: SparseJacobian<NB, NNZ>, const NB: usize, const NV: usize, const M: usize, const NNZ: usize> core::fmt::Debug
    for Analyses<'_, S, NB, NV, M, NNZ>
{
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Analyses")
            .field("scene", &core::any::type_name::<S>())
            .field("factor_blocks", &self.solver.factor.factor_blocks())
            .finish_non_exhaustive()
    }
}

impl<'a, S, const NB: usize, const NV: usize, const M: usize, const NNZ: usize> Analyses<'a, S, NB, NV, M, NNZ>
where
    S: Scene<NB, NV, M> + SparseJacobian<NB, NNZ>,
{
    /// The analyses of `scene`.
    ///
    /// # Errors
    /// [`AnalysisError::Dimensions`] if `NV ≠ 6 NB`; a structure that
    /// contradicts itself (a hand-written impl) is reported as a non-finite `J`.
    pub fn new(scene: &'a S) -> Result<Self, AnalysisError> {
        let solver = Solver::new()?;
        Ok(Analyses { scene, solver, unit: unit_metric(), rank_tolerance: DEFAULT_RANK_TOLERANCE })
    }

    /// The scene.
    pub fn scene(&self) -> &'a S {
        self.scene
    }

    /// Assembles the mechanism: moves `state`'s positions and orientations
    /// onto Φ = 0 by damped Newton from a rough configuration.
    ///
    /// Each iteration solves `J Δ = −Φ` in the minimum-norm least-squares
    /// sense (`Δ = Jᵀ y`, `(J Jᵀ) y = −Φ` on the block factor, pivoted within
    /// each diagonal block), then tries `r += α Δr`, `p ← p ⊗ q(α Δθ')` for
    /// `α = 1, ½, ¼, …` until ‖Φ‖₂ decreases (Armijo). The Euler parameters
    /// are normalised first (a rough `p` need not be unit). Velocities and
    /// time are not touched.
    ///
    /// # Errors
    /// [`AnalysisError::NonFinite`] names the body and field of a NaN/infinite
    /// position input; [`AnalysisError::NotConverged`] after `max_iterations`;
    /// [`AnalysisError::NoProgress`] when no step reduces ‖Φ‖ (singular or
    /// impossible). Both name the rows with the largest residuals. On error
    /// `state` holds the last accepted iterate.
    pub fn assemble(
        &mut self,
        state: &mut SystemState<NB>,
        options: &AssemblyOptions,
    ) -> Result<Assembly<M>, AnalysisError> {
        let unit = self.unit;
        let (iterations, residual) =
            self.solver.newton(self.scene, state, options, &unit, &mut [0.0; NNZ], &mut NewtonWork::new())?;
        Ok(Assembly { iterations, residual, redundant: self.solver.redundant() })
    }

    /// Velocity analysis: solves `J v = −Φ_t` (minimum norm, rank tolerance
    /// [`rank_tolerance`](Self::rank_tolerance)) at `state`'s configuration
    /// and writes every body's `ṙ` and `ω'`. Degrees of freedom not fixed by
    /// the constraints (or drivers) get zero velocity; use this on a fully
    /// driven mechanism, or to start from rest.
    ///
    /// # Errors
    /// Non-finite inputs or outputs (by body and field, or by row and joint);
    /// [`AnalysisError::Inconsistent`] when redundant rows contradict the
    /// others. Redundant but consistent rows are reported in the result.
    pub fn velocities(&mut self, state: &mut SystemState<NB>) -> Result<VelocityAnalysis<M>, AnalysisError> {
        check_state::<S, NB, NV, M>(state, false)?;
        let values = self.scene.jacobian_values(state);
        check_values::<S, NB, NV, M, NNZ>(&values)?;
        let phi_t = self.scene.phi_t(state);
        check_output::<S, NB, NV, M, 1>("Φ_t", &phi_t)?;
        let unit = self.unit;
        let (v, residual) =
            self.solver.solve_linear(Analysis::Velocity, &values, -phi_t, &unit, self.rank_tolerance)?;
        set_velocities(state, &v);
        Ok(VelocityAnalysis { residual, redundant: self.solver.redundant() })
    }

    /// Acceleration analysis: the minimum-norm solution of `J v̇ = γ` at
    /// `state`.
    ///
    /// # Errors
    /// As [`velocities`](Self::velocities).
    pub fn accelerations(&mut self, state: &SystemState<NB>) -> Result<AccelerationAnalysis<NV, M>, AnalysisError> {
        check_state::<S, NB, NV, M>(state, true)?;
        let values = self.scene.jacobian_values(state);
        check_values::<S, NB, NV, M, NNZ>(&values)?;
        let gamma = self.scene.gamma(state);
        check_output::<S, NB, NV, M, 1>("γ", &gamma)?;
        let unit = self.unit;
        let (vdot, residual) =
            self.solver.solve_linear(Analysis::Acceleration, &values, gamma, &unit, self.rank_tolerance)?;
        Ok(AccelerationAnalysis { vdot, residual, redundant: self.solver.redundant() })
    }
}
