//! The one simulation: the equations of [`dynamics`](crate::dynamics) on the
//! scene's block factor, in time and memory proportional to the scene.

use nalgebra::{SVector, Vector3};

use super::BlockFactor;
use super::alpha::{AlphaWork, AlphaWorkspace};
use super::buf::{Boxed, at_rest, boxed_with, zero_state, zeros};
use super::midpoint::MidpointWork;
use super::radau::{RadauScratch, RadauWorkspace};
use super::solver::{Solver, j_mul, j_mul_into, jt_mul_into, non_finite};
use crate::analysis::{
    AnalysisError, AssemblyOptions, InverseMass, NewtonWork, RowList, apply_increment, apply_metric_into, check_output,
    check_state, normalise_orientations, set_velocities, velocity_vector, velocity_vector_into,
};
use crate::dynamics::radau::{RadauHistory, RadauWork, step_radau_in};
use crate::dynamics::{
    AppliedLoads, Dynamics, Energy, Integrator, Loads, Mechanics, Rate, Reaction, SimulationOptions, SpringDamper,
    Stabilisation, StepReport, advance_into, check_redundant, generalised_forces, generalised_forces_into, near_enough,
    rk4_weights,
};
use crate::scene::{BodyInertia, RowBlock, Scene, SparseJacobian, SystemState};

/// Constrained accelerations and multipliers at one state: what the
/// integrators read of a solve ([`Dynamics`] without its copies of `Q` and
/// the dropped rows).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Accelerations<const NV: usize, const M: usize> {
    /// `v̇ = [r̈_0, ω̇'_0, ...]`.
    pub vdot: SVector<f64, NV>,
    /// Lagrange multipliers (`M v̇ + Jᵀ λ = Q`); zero on redundant rows.
    pub lambda: SVector<f64, M>,
}

/// A scene with loads, springs and options: constrained dynamics, reactions,
/// energy and fixed or error-controlled steps; the one simulation for every
/// scene ([`dynamics`](crate::dynamics) gives the equations, integrators and
/// signs). It solves on the scene's compile-time block pattern: the block
/// factor of `J M⁻¹ Jᵀ` (see [`sparse`](super)) and, for the implicit
/// integrators, their exact Newton matrices in saddle-point form over bodies
/// and joints. The workspaces of the configured integrator are made in
/// [`AbsoluteSimulation::new`]; a step allocates nothing. Every array has a size
/// the derive computed for the scene (`SparseJacobian::Factor`, `Kkt`,
/// `Terms`); with feature `alloc` the workspaces are boxed, without it they
/// live inline and every integrator still runs (springs between bodies no
/// joint joins excepted under an implicit integrator: their pattern is found
/// at run time, with `alloc`).
pub struct AbsoluteSimulation<
    'a,
    S: SparseJacobian<NB, NNZ>,
    L,
    const NB: usize,
    const NV: usize,
    const M: usize,
    const NNZ: usize,
> {
    pub(super) scene: &'a S,
    pub(super) loads: L,
    pub(super) springs: &'a [SpringDamper],
    /// The bodies' inertias and inverse masses: boxed with `alloc`, like
    /// every array of the scene's size here, so that the simulation itself
    /// is a few hundred bytes whatever the scene (a 500-body chain is made
    /// and stepped in a 256 KiB thread).
    pub(super) inertias: Boxed<[BodyInertia; NB]>,
    pub(super) inverse: Boxed<[InverseMass; NB]>,
    pub(super) gravity: Vector3<f64>,
    pub(super) solver: Solver<S, NB, NV, M, NNZ>,
    /// The state the last projection ended at, and the count and rank
    /// tolerance of the factorisation of `J W Jᵀ` it made there, which the
    /// dynamics at that state reuse while the factor holds it.
    projected: Boxed<(SystemState<NB>, Option<(u64, f64)>)>,
    /// Generalised-α's pattern, factor and history (the implicit
    /// integrators only).
    pub(super) alpha: Option<Boxed<SceneAlpha<S, NB, NV, M, NNZ>>>,
    /// Radau IIA's matrices on that pattern, and its history.
    pub(super) radau: Option<Boxed<SceneRadau<S, NB, NV, M, NNZ>>>,
    pub(super) radau_history: Boxed<Option<RadauHistory<SystemState<NB>, NV, ()>>>,
    /// The dynamics a Radau step's start solved, and where (its stages
    /// start from them rather than solving the start again), and its host's
    /// vectors.
    pub(super) radau_scratch: Option<Boxed<RadauScratch<NB, NV, M>>>,
    /// A Radau step's states and stages.
    pub(super) radau_work: Option<Boxed<RadauWork<SystemState<NB>, NV>>>,
    /// The implicit midpoint rule's iterate (with `alpha`).
    pub(super) midpoint: Option<Boxed<MidpointWork<NB, NV, M, NNZ>>>,
    /// Generalised-α's iterate and Newton vectors (with `alpha`).
    pub(super) alpha_work: Option<Boxed<AlphaWork<NB, NV, M, NNZ>>>,
    /// The vectors of a solve and the stages of an RK4 step, kept here
    /// rather than in a step's frames (allocated once, in `new`).
    work: Boxed<SolveWork<NB, NV, M, NNZ>>,
    rk4: Option<Boxed<Rk4Work<NB, NV>>>,
    /// The options (may be changed between steps; an implicit integrator
    /// steps in the workspace [`AbsoluteSimulation::new`] or [`AbsoluteSimulation::prepare`]
    /// built for it: a step never builds one).
    pub options: SimulationOptions,
}

/// The implicit integrators' workspace in the scene's arrays.
type SceneAlpha<S, const NB: usize, const NV: usize, const M: usize, const NNZ: usize> =
    AlphaWorkspace<<S as SparseJacobian<NB, NNZ>>::Kkt<f64>, <S as SparseJacobian<NB, NNZ>>::Terms, NB, NV, M, NNZ>;

/// Radau's workspace in the scene's saddle-point arrays.
type SceneRadau<S, const NB: usize, const NV: usize, const M: usize, const NNZ: usize> = RadauWorkspace<
    <S as SparseJacobian<NB, NNZ>>::Kkt<f64>,
    <S as SparseJacobian<NB, NNZ>>::Kkt<nalgebra::Complex<f64>>,
    NV,
    M,
    NNZ,
>;

/// Runs `f` on the workspace in `slot` (made by `new` or
/// [`AbsoluteSimulation::prepare`]), taken out while `f` borrows the simulation and
/// always put back. Held without drop glue: a box dropped on unwinding, or
/// the `None` the slot holds meanwhile dropped on putting back, would keep a
/// call to `free` or a cleanup path that `no-panic-check` counts as a panic,
/// and nothing here unwinds.
pub(super) fn with_taken<T, W, R>(
    sim: &mut T,
    slot: impl Fn(&mut T) -> &mut Option<W>,
    f: impl FnOnce(&mut T, &mut W) -> Result<R, AnalysisError>,
) -> Result<R, AnalysisError> {
    let Some(w) = slot(sim).take() else {
        return Err(AnalysisError::BadOption { name: "workspace" });
    };
    let mut held = core::mem::ManuallyDrop::new(w);
    let out = f(sim, &mut held);
    // The slot is empty (taken above): forgetting what it held drops nothing.
    core::mem::forget(slot(sim).replace(core::mem::ManuallyDrop::into_inner(held)));
    out
}

/// A solve's vectors: `J`'s values, `γ`, the loads and `Q`, `W Q`, `λ`,
/// `Jᵀ λ`, `v̇` and the residual `J v̇ − γ`.
struct SolveWork<const NB: usize, const NV: usize, const M: usize, const NNZ: usize> {
    values: [f64; NNZ],
    loads: Loads<NB>,
    /// The projection's vectors and trial state.
    newton: NewtonWork<NB, NV, M>,
    gamma: SVector<f64, M>,
    forces: SVector<f64, NV>,
    minv_q: SVector<f64, NV>,
    lambda: SVector<f64, M>,
    jt_lambda: SVector<f64, NV>,
    vdot: SVector<f64, NV>,
    r: SVector<f64, M>,
}

impl<const NB: usize, const NV: usize, const M: usize, const NNZ: usize> SolveWork<NB, NV, M, NNZ> {
    /// Zeros, the projection's trial state at rest; written in the heap
    /// (`buf`).
    fn new() -> Boxed<Self> {
        let mut w = boxed_with(|| {
            const {
                SolveWork {
                    values: [0.0; NNZ],
                    loads: Loads::zeros(),
                    newton: NewtonWork::zeros(),
                    gamma: zeros(),
                    forces: zeros(),
                    minv_q: zeros(),
                    lambda: zeros(),
                    jt_lambda: zeros(),
                    vdot: zeros(),
                    r: zeros(),
                }
            }
        });
        at_rest(&mut w.newton.trial);
        w
    }
}

/// An RK4 step's start, stage rates, stage state and end.
struct Rk4Work<const NB: usize, const NV: usize> {
    y0: SystemState<NB>,
    k: [Rate<NB, NV>; 4],
    stage: SystemState<NB>,
    end: SystemState<NB>,
}

impl<const NB: usize, const NV: usize> Rk4Work<NB, NV> {
    /// States at rest and their rates (zero); written in the heap (`buf`).
    fn new() -> Boxed<Self> {
        let mut w = boxed_with(|| {
            const { Rk4Work { y0: zero_state(), k: [Rate::zeros(); 4], stage: zero_state(), end: zero_state() } }
        });
        let Rk4Work { y0, stage, end, .. } = &mut *w;
        for state in [y0, stage, end] {
            at_rest(state);
        }
        w
    }
}

/// Baumgarte's `γ − 2α (J v + Φ_t) − β² Φ` into the workspace's `γ` (its
/// `J` values at `state` already there). In a frame of its own: its vectors
/// sit on the stack only with the stabilisation on.
#[inline(never)]
fn baumgarte<S, const NB: usize, const NV: usize, const M: usize, const NNZ: usize>(
    scene: &S,
    state: &SystemState<NB>,
    w: &mut SolveWork<NB, NV, M, NNZ>,
    (alpha, beta): (f64, f64),
) -> Result<(), AnalysisError>
where
    S: Scene<NB, NV, M> + SparseJacobian<NB, NNZ>,
{
    let (phi, phi_t) = (scene.phi(state), scene.phi_t(state));
    check_output::<S, NB, NV, M, 1>("Φ", &phi)?;
    check_output::<S, NB, NV, M, 1>("Φ_t", &phi_t)?;
    let phi_dot = j_mul::<S, NB, NNZ, NV, M>(&w.values, &velocity_vector::<NB, NV>(state)) + phi_t;
    w.gamma -= phi_dot * (2.0 * alpha) + phi * (beta * beta);
    Ok(())
}

impl<S: SparseJacobian<NB, NNZ>, L, const NB: usize, const NV: usize, const M: usize, const NNZ: usize> core::fmt::Debug
    for AbsoluteSimulation<'_, S, L, NB, NV, M, NNZ>
{
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("AbsoluteSimulation")
            .field("scene", &core::any::type_name::<S>())
            .field("factor_blocks", &self.solver.factor.factor_blocks())
            .field("options", &self.options)
            .finish_non_exhaustive()
    }
}

impl<'a, S, L, const NB: usize, const NV: usize, const M: usize, const NNZ: usize>
    AbsoluteSimulation<'a, S, L, NB, NV, M, NNZ>
where
    S: Scene<NB, NV, M> + SparseJacobian<NB, NNZ>,
    L: AppliedLoads<NB>,
{
    /// A simulation of `scene` with user `loads` and `springs`; the block
    /// factor's schedule and the workspaces of `options.integrator` are
    /// built here, once (for another integrator later, call
    /// [`AbsoluteSimulation::prepare`]: a step never builds, so it never allocates).
    ///
    /// # Errors
    /// [`AnalysisError::BadInertia`] for a non-positive or non-finite mass or a
    /// singular inertia tensor, [`AnalysisError::BadOption`] for a spring attached
    /// to a body that does not exist or with non-finite coefficients (or, without
    /// feature `alloc`, an implicit integrator), [`AnalysisError::Dimensions`] if
    /// `NV ≠ 6 NB`, [`AnalysisError::Linalg`] if the scene's block pattern or
    /// factor storage is inconsistent (a hand-written
    /// [`SparseJacobian`](crate::SparseJacobian); the derive's never is).
    pub fn new(
        scene: &'a S,
        loads: L,
        springs: &'a [SpringDamper],
        options: SimulationOptions,
    ) -> Result<Self, AnalysisError> {
        let Mechanics { inertias, inverse, gravity } = Mechanics::new(scene, springs)?;
        let solver = Solver::new()?;
        let mut projected = boxed_with(|| const { (zero_state(), None) });
        at_rest(&mut projected.0);
        let sim = AbsoluteSimulation {
            scene,
            loads,
            springs,
            inertias,
            inverse,
            gravity,
            solver,
            projected,
            alpha: None,
            radau: None,
            radau_history: boxed_with(|| const { None }),
            radau_scratch: None,
            radau_work: None,
            midpoint: None,
            alpha_work: None,
            work: SolveWork::new(),
            rk4: Some(Rk4Work::new()),
            options,
        };
        // The implicit integrators' workspaces with their pattern: a step
        // allocates nothing.
        let sim = {
            let mut sim = sim;
            sim.prepare(options.integrator)?;
            sim
        };
        Ok(sim)
    }

    /// The state this simulation steps for the bodies' `system` state: the
    /// same, absolute coordinates being the bodies' own (the relative
    /// engine's [`TreeSimulation::state_of`](crate::relative::TreeSimulation::state_of)
    /// converts). A state off its joints is not refused here: the first
    /// step's projection closes it, as [`assemble`](crate::analysis::assemble) would.
    ///
    /// # Errors
    /// [`AnalysisError::NonFinite`] or [`AnalysisError::ZeroQuaternion`]
    /// naming the body.
    pub fn state_of(&self, system: &SystemState<NB>) -> Result<SystemState<NB>, AnalysisError> {
        check_state::<S, NB, NV, M>(system, true)?;
        Ok(*system)
    }

    /// The bodies' state of a state this simulation steps: the same (the
    /// relative engine's [`TreeSimulation::system_state`](crate::relative::TreeSimulation::system_state)
    /// runs the forward kinematics).
    pub fn system_state(&self, state: &SystemState<NB>) -> SystemState<NB> {
        *state
    }

    /// The scene.
    pub fn scene(&self) -> &'a S {
        self.scene
    }

    /// The generalised forces `Q` (gravity, user loads, gyroscopic terms, springs).
    pub fn forces(&mut self, state: &SystemState<NB>) -> SVector<f64, NV> {
        generalised_forces(&mut self.loads, self.springs, &self.inertias, &self.gravity, state)
    }

    /// Kinetic, gravitational and elastic energy at `state`.
    pub fn energy(&self, state: &SystemState<NB>) -> Energy {
        crate::dynamics::energy(&self.inertias, &self.gravity, self.springs, state)
    }

    /// The block factor (its size, and the rows the last factorisation dropped).
    pub fn factor(&self) -> &BlockFactor<S::Factor> {
        &self.solver.factor
    }

    /// The 6 × 6 blocks generalised-α's iteration matrix stores (its memory,
    /// fill included); `None` for RK4.
    pub fn iteration_blocks(&self) -> Option<usize> {
        self.alpha.as_deref().map(AlphaWorkspace::blocks)
    }

    /// Constrained accelerations and multipliers at `state`; redundant rows get
    /// zero multipliers and must agree with the others.
    ///
    /// # Errors
    /// Non-finite inputs or outputs; [`AnalysisError::Inconsistent`] when
    /// redundant constraints contradict each other.
    pub fn dynamics(&mut self, state: &SystemState<NB>) -> Result<Dynamics<NV, M>, AnalysisError> {
        self.solve_in_work(state, false, true)?;
        let w = &self.work;
        Ok(Dynamics { vdot: w.vdot, lambda: w.lambda, forces: w.forces, redundant: self.solver.redundant() })
    }

    /// The dynamics; `keep` factorises under the step's rule, `check` holds the
    /// dropped rows to [`REDUNDANT_TOLERANCE`].
    pub(super) fn solve(
        &mut self,
        state: &SystemState<NB>,
        keep: bool,
        check: bool,
    ) -> Result<Accelerations<NV, M>, AnalysisError> {
        self.solve_in_work(state, keep, check)?;
        Ok(Accelerations { vdot: self.work.vdot, lambda: self.work.lambda })
    }

    /// [`AbsoluteSimulation::solve`] into the workspace (`v̇`, `λ` in
    /// `self.work`): no vector of the scene's size in this frame but the
    /// stabilisation's.
    pub(super) fn solve_in_work(
        &mut self,
        state: &SystemState<NB>,
        keep: bool,
        check: bool,
    ) -> Result<(), AnalysisError> {
        check_state::<S, NB, NV, M>(state, true)?;
        let w: &mut SolveWork<NB, NV, M, NNZ> = &mut self.work;
        self.scene.jacobian_values_into(state, &mut w.values);
        w.gamma = self.scene.gamma(state);
        check_output::<S, NB, NV, M, 1>("γ", &w.gamma)?;
        if let Stabilisation::Baumgarte { alpha, beta } = self.options.stabilisation {
            baumgarte::<S, NB, NV, M, NNZ>(self.scene, state, w, (alpha, beta))?;
        }
        generalised_forces_into(
            &mut self.loads,
            self.springs,
            &self.inertias,
            &self.gravity,
            state,
            &mut w.loads,
            &mut w.forces,
        );
        if !w.forces.as_slice().iter().all(|x| x.is_finite()) {
            return Err(non_finite("forces"));
        }
        apply_metric_into(&self.inverse, &w.forces, &mut w.minv_q);
        // The last step's projection factorised `J W Jᵀ` at the state the
        // next step starts from, with no rule and the same tolerance.
        let (at, made): &(SystemState<NB>, Option<(u64, f64)>) = &self.projected;
        let count = self.solver.factor.factorisations();
        if keep || *made != Some((count, self.options.rank_tolerance)) || at != state {
            self.solver.factorise_by(&w.values, &self.inverse, self.options.rank_tolerance, keep)?;
        }
        j_mul_into::<S, NB, NNZ>(&w.values, w.minv_q.as_slice(), w.lambda.as_mut_slice());
        w.lambda -= &w.gamma;
        self.solver.solve(w.lambda.as_mut_slice());
        jt_mul_into::<S, NB, NNZ>(&w.values, w.lambda.as_slice(), w.jt_lambda.as_mut_slice());
        // v̇ = W Q − W Jᵀ λ.
        apply_metric_into(&self.inverse, &w.jt_lambda, &mut w.vdot);
        for (v, &q) in w.vdot.as_mut_slice().iter_mut().zip(w.minv_q.as_slice().iter()) {
            *v = q - *v;
        }
        j_mul_into::<S, NB, NNZ>(&w.values, w.vdot.as_slice(), w.r.as_mut_slice());
        w.r -= &w.gamma;
        if !w.r.norm().is_finite() || !w.vdot.as_slice().iter().all(|x| x.is_finite()) {
            return Err(non_finite("accelerations"));
        }
        let scale = 1.0 + w.gamma.norm() + libm::sqrt(w.values.iter().map(|x| x * x).sum::<f64>()) * w.vdot.norm();
        check_redundant::<S, NB, NV, M>(&w.r, self.solver.factor.dropped(), scale, check)
    }

    /// `J`'s entries at the state of the last solve.
    #[cfg(feature = "alloc")]
    pub(super) fn solved_values(&self) -> &[f64; NNZ] {
        &self.work.values
    }

    /// The reaction of the joint `block` (one of [`Scene::BLOCKS`]) on every
    /// body, from the multipliers of [`AbsoluteSimulation::dynamics`] at `state`:
    /// `−J_kᵀ λ_k` split by body, from the Jacobian's nonzero entries. Rows
    /// outside `0..M` are ignored.
    pub fn reactions(&self, state: &SystemState<NB>, lambda: &SVector<f64, M>, block: &RowBlock) -> [Reaction; NB] {
        let values = self.scene.jacobian_values(state);
        let mut out = [Reaction::default(); NB];
        let end = block.start.saturating_add(block.rows).min(M);
        for row in block.start.min(end)..end {
            let (Some(&a), Some(&b), Some(&l)) = (S::ROW_STARTS.get(row), S::ROW_STARTS.get(row + 1), lambda.get(row))
            else {
                continue;
            };
            for (v, &c) in values.iter().zip(S::COLUMNS.iter()).take(b).skip(a) {
                let Some(r) = out.get_mut(c / 6) else { continue };
                let part = if c % 6 < 3 { &mut r.force } else { &mut r.torque };
                part[c % 3] -= v * l;
            }
        }
        out
    }

    /// The rows the last factorisation dropped, by joint.
    pub fn redundant(&self) -> RowList<M> {
        self.solver.redundant()
    }

    /// One RK4 stage: the rate at `state` under the step's rule.
    pub(super) fn rate(&mut self, state: &SystemState<NB>) -> Result<Rate<NB, NV>, AnalysisError> {
        Ok(Rate::new(state, self.solve(state, true, false)?.vdot))
    }

    /// Advances `state` by one step `h` of the configured integrator (RK4,
    /// the implicit midpoint rule, generalised-α or Radau IIA), then projects
    /// onto the constraints if configured. On error `state` is unchanged.
    ///
    /// # Errors
    /// [`AnalysisError::BadOption`] for a step that is not positive and finite;
    /// [`AnalysisError::NotPrepared`] for an integrator whose workspace
    /// neither `new` nor [`AbsoluteSimulation::prepare`] made; non-finite inputs; failures of the dynamics, of the implicit iteration
    /// (or a midpoint solution its energy balance refuses,
    /// [`AnalysisError::SpuriousSolution`]) or of the projection. The
    /// implicit integrators' Newton matrices take the scene's generated
    /// second-order terms, or differences of `J`, `γ` and `Φ_t` for a scene
    /// derived without `second_order` ([`DifferenceTerms`](super::DifferenceTerms)).
    pub fn step(&mut self, state: &mut SystemState<NB>, h: f64) -> Result<StepReport, AnalysisError> {
        if !(h > 0.0 && h.is_finite()) {
            return Err(AnalysisError::BadOption { name: "step size" });
        }
        self.ready(self.options.integrator)?;
        self.check_assembled(state)?;
        let mut report = StepReport::default();
        // Each integrator in a frame of its own: a step's stack is the one
        // integrator's, not the sum of all four.
        match self.options.integrator {
            Integrator::Rk4 => self.advance_rk4(state, h, &mut report)?,
            Integrator::GeneralisedAlpha => self.advance_alpha(state, h, &mut report)?,
            Integrator::RadauIIA => self.advance_radau(state, h, &mut report)?,
            Integrator::ImplicitMidpoint => self.advance_midpoint(state, h, &mut report)?,
        }
        self.follow(state, self.options.integrator);
        Ok(report)
    }

    /// An RK4 step from `state`, settled on its last stage's factor and
    /// projected, written into `state` (unchanged on error). The stages and
    /// the end live in the boxed `Rk4Work`.
    #[inline(never)]
    fn advance_rk4(
        &mut self,
        state: &mut SystemState<NB>,
        h: f64,
        report: &mut StepReport,
    ) -> Result<(), AnalysisError> {
        with_taken(
            self,
            |s| &mut s.rk4,
            |sim, w| {
                let w: &mut Rk4Work<NB, NV> = w;
                sim.step_rk4(w, state, h)?;
                if let Some(options) = sim.options.projection {
                    report.projection_iterations = sim.settle(&mut w.end, &w.stage, &options);
                }
                sim.finish(&mut w.end, report)?;
                *state = w.end;
                Ok(())
            },
        )
    }

    /// A generalised-α step from `state`, projected, into `state`.
    #[inline(never)]
    fn advance_alpha(
        &mut self,
        state: &mut SystemState<NB>,
        h: f64,
        report: &mut StepReport,
    ) -> Result<(), AnalysisError> {
        // Generalised-α goes on from its last step only if handed back its state.
        let continuing = self.alpha.as_deref().and_then(|w| w.history.as_ref()).is_some_and(|h| h.state == *state);
        self.alpha_in_work(state, h, continuing, report)
    }

    /// A Radau IIA step from `state`, projected, into `state`.
    #[inline(never)]
    fn advance_radau(
        &mut self,
        state: &mut SystemState<NB>,
        h: f64,
        report: &mut StepReport,
    ) -> Result<(), AnalysisError> {
        with_taken(self, |s| &mut s.radau_work, |sim, w| sim.radau_started(w, state, h, report))
    }

    /// [`advance_radau`](Self::advance_radau) on the taken-out work `w`.
    fn radau_started(
        &mut self,
        w: &mut RadauWork<SystemState<NB>, NV>,
        state: &mut SystemState<NB>,
        h: f64,
        report: &mut StepReport,
    ) -> Result<(), AnalysisError> {
        self.begin(state, w.start_mut())?;
        self.remember_radau_start(w.start_mut());
        let step = step_radau_in(self, w, h, None)?;
        (report.newton_iterations, report.newton_matrices) = (step.iterations, step.matrices);
        self.finish(w.end_mut(), report)?;
        state.clone_from(w.end_mut());
        Ok(())
    }

    /// The last solve's dynamics (at `y0`) as a Radau step's start.
    pub(super) fn remember_radau_start(&mut self, y0: &SystemState<NB>) {
        if let Some(sc) = self.radau_scratch.as_deref_mut() {
            sc.start(y0, &self.work.vdot, &self.work.lambda);
        }
    }

    /// An implicit midpoint step from `state`, projected, into `state`.
    #[inline(never)]
    fn advance_midpoint(
        &mut self,
        state: &mut SystemState<NB>,
        h: f64,
        report: &mut StepReport,
    ) -> Result<(), AnalysisError> {
        self.midpoint_in_work(state, h, report)
    }

    /// A step's end: the projection if configured (its iterations added to
    /// the report's), and the residuals the report gives either way.
    #[inline(never)]
    pub(super) fn finish(&mut self, y: &mut SystemState<NB>, report: &mut StepReport) -> Result<(), AnalysisError> {
        match self.options.projection {
            Some(options) => {
                let (it, c, v) = self.project(y, &options)?;
                report.projection_iterations += it;
                (report.constraint_residual, report.velocity_residual) = (c, v);
            }
            None => self.residuals(y, report),
        }
        Ok(())
    }

    /// A start the last projection did not make must be on its joints to
    /// the projection's round-off floor (`1e3 ×` its tolerance): a step
    /// projects its end, never its start (without projection, nothing is
    /// checked: the drift is the user's choice).
    #[inline(never)]
    pub(super) fn check_assembled(&self, state: &SystemState<NB>) -> Result<(), AnalysisError> {
        let Some(options) = self.options.projection else { return Ok(()) };
        if self.projected.0 == *state {
            return Ok(());
        }
        check_state::<S, NB, NV, M>(state, true)?;
        // On unit quaternions, as the step takes them.
        let mut start = *state;
        normalise_orientations::<S, NB, NV, M>(&mut start)?;
        let phi = self.scene.phi(&start);
        let residual = phi.norm();
        if residual > 1e3 * options.tolerance {
            let worst = crate::analysis::WorstRows::of::<S, NB, NV, M>(&phi);
            return Err(AnalysisError::NotAssembled { residual, worst });
        }
        Ok(())
    }

    /// ‖Φ‖ and ‖J v + Φ_t‖ at an unprojected step's end, into the report (in
    /// a frame of its own, apart from the projection's).
    #[inline(never)]
    fn residuals(&mut self, y: &SystemState<NB>, report: &mut StepReport) {
        report.constraint_residual = self.scene.phi(y).norm();
        self.scene.jacobian_values_into(y, &mut self.work.values);
        let v = velocity_vector::<NB, NV>(y);
        report.velocity_residual = (j_mul::<S, NB, NNZ, NV, M>(&self.work.values, &v) + self.scene.phi_t(y)).norm();
    }

    /// A step's start: `state` checked and normalised, its dynamics, and the
    /// rule of redundant rows every stage of the step keeps.
    pub(super) fn step_start(
        &mut self,
        state: &SystemState<NB>,
    ) -> Result<(SystemState<NB>, Accelerations<NV, M>), AnalysisError> {
        let mut y0 = *state;
        self.begin(state, &mut y0)?;
        Ok((y0, Accelerations { vdot: self.work.vdot, lambda: self.work.lambda }))
    }

    /// The generalised forces at `state` into `q`, their loads gathered in
    /// the workspace.
    pub(super) fn forces_into(&mut self, state: &SystemState<NB>, q: &mut SVector<f64, NV>) {
        let (springs, loads) = (self.springs, &mut self.work.loads);
        generalised_forces_into(&mut self.loads, springs, &self.inertias, &self.gravity, state, loads, q);
    }

    /// The user's loads and the gyroscopic terms at `state` (the generalised
    /// forces without gravity or springs) into `q`.
    pub(super) fn user_forces_into(&mut self, state: &SystemState<NB>, q: &mut SVector<f64, NV>) {
        let (zero, loads) = (Vector3::zeros(), &mut self.work.loads);
        generalised_forces_into(&mut self.loads, &[], &self.inertias, &zero, state, loads, q);
    }

    /// The accelerations and multipliers of the last solve (in the
    /// workspace): after [`begin`](Self::begin), the step's start's.
    pub(super) fn solved(&self) -> (&SVector<f64, NV>, &SVector<f64, M>) {
        (&self.work.vdot, &self.work.lambda)
    }

    /// [`step_start`](Self::step_start) into `y0` and the workspace (`v̇`,
    /// `λ` in `self.work`): `state` checked, copied and normalised, solved
    /// at, and the step's rule taken from that factorisation.
    pub(super) fn begin(&mut self, state: &SystemState<NB>, y0: &mut SystemState<NB>) -> Result<(), AnalysisError> {
        check_state::<S, NB, NV, M>(state, true)?;
        *y0 = *state;
        normalise_orientations::<S, NB, NV, M>(y0)?;
        self.solve_in_work(y0, false, true)?;
        self.solver.factor.keep_rule();
        Ok(())
    }

    /// Generalised-α's workspace, built at its first use if
    /// [`AbsoluteSimulation::new`] did not (another integrator, then
    /// [`integrate`](Self::integrate) with it): allocated once.
    pub(super) fn alpha_workspace(&mut self) -> Result<(), AnalysisError> {
        if self.alpha.is_none() {
            self.make_alpha_workspace()?;
        }
        Ok(())
    }

    /// [`alpha_workspace`](Self::alpha_workspace)'s construction, in a frame
    /// of its own: a step that finds the workspace made never enters it.
    #[cold]
    #[inline(never)]
    fn make_alpha_workspace(&mut self) -> Result<(), AnalysisError> {
        self.alpha = Some(AlphaWorkspace::boxed::<S>(self.springs)?);
        self.alpha_work = Some(AlphaWork::new());
        self.midpoint = Some(MidpointWork::new());
        Ok(())
    }

    /// Builds the workspaces `integrator` steps in, unless they exist: the
    /// saddle-point matrix and its scratch for the implicit integrators (and
    /// Radau IIA's real and complex matrices). [`AbsoluteSimulation::new`] does it
    /// for the integrator of its options; call this before stepping with
    /// another one (a step never builds, so it never allocates):
    ///
    /// ```
    /// # use joint_runtime::dynamics::{Integrator, NoLoads, Simulation, SimulationOptions};
    /// # use joint_runtime::{OmegaBody, Scene, SystemState};
    /// # use joint_runtime::nalgebra::{UnitQuaternion, Vector3};
    /// #[derive(Scene)]
    /// #[scene(coordinates = absolute, gravity = [0, 0, -9.81])]
    /// #[body(link, mass = 1.0, inertia = [0.08, 0.08, 0.001])]
    /// #[joint(hinge = revolute(ground, link), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0, 0, 0], rho2 = [0, 0, 0.5])]
    /// struct Pendulum;
    ///
    /// let mut sim = Simulation::new(&Pendulum, NoLoads, &[], SimulationOptions::default())?; // RK4
    /// let link = OmegaBody::from_rotation(Vector3::new(0.0, 0.0, -0.5), &UnitQuaternion::identity(), Vector3::zeros(), Vector3::zeros());
    /// let mut state = SystemState { bodies: [link], t: 0.0 };
    /// sim.options.integrator = Integrator::RadauIIA;
    /// assert!(sim.step(&mut state, 1e-3).is_err()); // not prepared
    /// sim.prepare(Integrator::RadauIIA)?;
    /// sim.step(&mut state, 1e-3)?;
    /// # Ok::<(), joint_runtime::analysis::AnalysisError>(())
    /// ```
    ///
    /// # Errors
    /// [`AnalysisError::NonFiniteOutput`] for a scene structure the derive's
    /// sizes do not fit; without `alloc`, [`AnalysisError::BadOption`] for
    /// springs between bodies no joint joins under an implicit integrator.
    pub fn prepare(&mut self, integrator: Integrator) -> Result<(), AnalysisError> {
        match integrator {
            Integrator::Rk4 => Ok(()),
            Integrator::GeneralisedAlpha | Integrator::ImplicitMidpoint => self.alpha_workspace(),
            Integrator::RadauIIA => {
                self.alpha_workspace()?;
                if self.radau.is_none() {
                    self.make_radau_workspace()?;
                }
                Ok(())
            }
        }
    }

    /// Whether `integrator`'s workspaces exist; a step checks, never builds.
    ///
    /// # Errors
    /// [`AnalysisError::NotPrepared`] when they do not
    /// ([`AbsoluteSimulation::prepare`] builds them).
    pub(super) fn ready(&self, integrator: Integrator) -> Result<(), AnalysisError> {
        let implicit = self.alpha.is_some() && self.alpha_work.is_some() && self.midpoint.is_some();
        let radau = self.radau.is_some() && self.radau_scratch.is_some() && self.radau_work.is_some();
        let ready = match integrator {
            Integrator::Rk4 => true,
            Integrator::GeneralisedAlpha | Integrator::ImplicitMidpoint => implicit,
            Integrator::RadauIIA => implicit && radau,
        };
        let (integrator, option) = match integrator {
            Integrator::Rk4 => ("RK4", "Integrator::Rk4"),
            Integrator::GeneralisedAlpha => ("generalised-α", "Integrator::GeneralisedAlpha"),
            Integrator::ImplicitMidpoint => ("the implicit midpoint rule", "Integrator::ImplicitMidpoint"),
            Integrator::RadauIIA => ("Radau IIA", "Integrator::RadauIIA"),
        };
        if ready { Ok(()) } else { Err(AnalysisError::NotPrepared { integrator, option }) }
    }

    /// Radau's workspace on the implicit pattern, in a frame of its own.
    #[cold]
    #[inline(never)]
    fn make_radau_workspace(&mut self) -> Result<(), AnalysisError> {
        if let Some(ws) = &self.alpha {
            self.radau = Some(RadauWorkspace::boxed(&ws.kkt)?);
            self.radau_scratch = Some(RadauScratch::boxed());
            self.radau_work = Some(RadauWork::boxed());
        }
        Ok(())
    }

    /// One RK4 step from `state` (checked and normalised into `w.y0`) under
    /// the rule of its start: the end in `w.end`, the last stage's state
    /// (whose `J W Jᵀ` the factor holds on return) in `w.stage`. The stages
    /// live in `w`, not in this frame.
    fn step_rk4(&mut self, w: &mut Rk4Work<NB, NV>, state: &SystemState<NB>, h: f64) -> Result<(), AnalysisError> {
        self.begin(state, &mut w.y0)?;
        let t0 = w.y0.t;
        w.k[0].assign(&w.y0, &self.work.vdot);
        for (stage, c) in [(1, 0.5), (2, 0.5), (3, 1.0)] {
            advance_into(&w.y0, [(&w.k[stage - 1], c)], h, t0 + c * h, &mut w.stage);
            self.solve_in_work(&w.stage, true, false)?;
            w.k[stage].assign(&w.stage, &self.work.vdot);
        }
        let [k1, k2, k3, k4] = &w.k;
        advance_into(&w.y0, rk4_weights(k1, k2, k3, k4), h, t0 + h, &mut w.end);
        Ok(())
    }

    /// Simplified Newton on Φ = 0 at the end of an RK4 step, on the factor its
    /// last stage left (`J W Jᵀ` at `at`, `O(h)` from `y`, under the step's
    /// rule): minimum-norm corrections in the mass metric, each a solve and no
    /// factorisation, while each at least halves ‖Φ‖ (they contract at a rate
    /// of order `h |v|`). Returns the iterations taken; the exact projection
    /// that follows then usually needs none of its own, only the one
    /// factorisation at the end state that its velocity projection uses (and
    /// the next step's start reuses).
    // Not inlined: its vectors and trial state would sit in the step's frame
    // through the projection's Newton, which runs after it.
    #[inline(never)]
    fn settle(&mut self, y: &mut SystemState<NB>, at: &SystemState<NB>, options: &AssemblyOptions) -> usize {
        let w: &mut SolveWork<NB, NV, M, NNZ> = &mut self.work;
        let SolveWork { values, newton: nw, .. } = w;
        self.scene.jacobian_values_into(at, values);
        let inverse = &self.inverse;
        nw.phi = self.scene.phi(y);
        let mut norm = nw.phi.norm();
        let mut iterations = 0;
        while norm > options.tolerance && iterations < options.max_iterations {
            for (b, p) in nw.b.as_mut_slice().iter_mut().zip(nw.phi.as_slice().iter()) {
                *b = -p;
            }
            self.solver.min_norm_factored_in_place(values, &mut nw.b, inverse, &mut nw.delta);
            nw.trial.clone_from(y);
            apply_increment(&mut nw.trial, &nw.delta, 1.0);
            nw.p = self.scene.phi(&nw.trial);
            let n = nw.p.norm();
            if n.is_nan() || n > 0.5 * norm {
                break;
            }
            y.clone_from(&nw.trial);
            nw.phi.copy_from(&nw.p);
            norm = n;
            iterations += 1;
        }
        iterations
    }

    /// Projects `state` onto Φ = 0 (damped minimum-norm Newton in the mass
    /// metric) and its velocities onto `J v = −Φ_t`. Returns the iterations,
    /// ‖Φ‖ and ‖J v + Φ_t‖ afterwards.
    ///
    /// # Errors
    /// As [`crate::analysis::assemble`], except that stopping short of the
    /// tolerance by less than a factor 1000 (round-off floor) is accepted.
    pub fn project(
        &mut self,
        state: &mut SystemState<NB>,
        options: &AssemblyOptions,
    ) -> Result<(usize, f64, f64), AnalysisError> {
        let w: &mut SolveWork<NB, NV, M, NNZ> = &mut self.work;
        let SolveWork { values, newton: work, .. } = w;
        let newton = self.solver.newton(self.scene, state, options, &self.inverse, values, work);
        // A converged Newton factorised `J W Jᵀ` last at the state it returns
        // (to list its redundant rows), in this metric and with this
        // tolerance: the velocities are projected on that factor. Stopping
        // short (accepted by `near_enough`) left it one state behind.
        let factored = newton.is_ok();
        let (iterations, residual) = near_enough(newton, options)?;
        let velocity_residual = self.project_velocities(state, factored, options)?;
        Ok((iterations, residual, velocity_residual))
    }

    /// The velocity half of [`AbsoluteSimulation::project`] (`factored`: Newton
    /// converged, so the factor and the values buffer hold `J` at `state`);
    /// returns ‖J v + Φ_t‖. In a frame of its own, apart from Newton's.
    #[inline(never)]
    fn project_velocities(
        &mut self,
        state: &mut SystemState<NB>,
        factored: bool,
        options: &AssemblyOptions,
    ) -> Result<f64, AnalysisError> {
        let (inverse, w): (_, &mut SolveWork<NB, NV, M, NNZ>) = (&self.inverse, &mut self.work);
        let SolveWork { values, newton: nw, .. } = w;
        if !factored {
            self.scene.jacobian_values_into(state, values);
        }
        // b = −(J v + Φ_t), v += W Jᵀ (J W Jᵀ)⁻¹ b; ‖J v + Φ_t‖ after.
        nw.p = self.scene.phi_t(state);
        velocity_vector_into(state, &mut nw.v);
        j_mul_into::<S, NB, NNZ>(values, nw.v.as_slice(), nw.phi.as_mut_slice());
        for ((b, jv), pt) in nw.b.as_mut_slice().iter_mut().zip(nw.phi.as_slice().iter()).zip(nw.p.as_slice().iter()) {
            *b = -(jv + pt);
        }
        if factored {
            self.solver.min_norm_factored_in_place(values, &mut nw.b, inverse, &mut nw.delta);
        } else {
            self.solver.min_norm_in_place(values, &mut nw.b, inverse, options.rank_tolerance, &mut nw.delta)?;
        }
        nw.v += &nw.delta;
        set_velocities(state, &nw.v);
        // Velocities do not enter `J`: the factor is `J W Jᵀ` at `state`.
        self.projected.0 = *state;
        self.projected.1 = factored.then(|| (self.solver.factor.factorisations(), options.rank_tolerance));
        j_mul_into::<S, NB, NNZ>(values, nw.v.as_slice(), nw.phi.as_mut_slice());
        for ((b, jv), pt) in nw.b.as_mut_slice().iter_mut().zip(nw.phi.as_slice().iter()).zip(nw.p.as_slice().iter()) {
            *b = jv + pt;
        }
        Ok(nw.b.norm())
    }
}

impl<S: SparseJacobian<NB, NNZ>, L, const NB: usize, const NV: usize, const M: usize, const NNZ: usize>
    AbsoluteSimulation<'_, S, L, NB, NV, M, NNZ>
{
    /// The histories after a step of `integrator` was accepted at `state`:
    /// its own follows the state, the others' are dropped (as on the dense
    /// path).
    pub(super) fn follow(&mut self, state: &SystemState<NB>, integrator: Integrator) {
        if let Some(w) = self.alpha.as_deref_mut() {
            match (&mut w.history, integrator) {
                (Some(history), Integrator::GeneralisedAlpha) => history.state = *state,
                _ => w.history = None,
            }
        }
        match (&mut *self.radau_history, integrator) {
            (Some(radau), Integrator::RadauIIA) => radau.accept(state),
            _ => *self.radau_history = None,
        }
    }
}
