//! [`Engine`]: what both engines offer, as one trait, so that code over
//! "any scene" or "any robot" has one bound whichever coordinates the scene
//! declares.
//!
//! The absolute engine steps the bodies' [`SystemState`], the relative one
//! its tree's [`TreeState`]: the trait names the engine's own state
//! ([`Engine::State`]) and converts it to and from the bodies' poses, and a
//! [`Simulation`] implements it by its engine's.

use super::{Adaptive, AppliedLoads, Energy, IntegrationReport, Reaction, Simulate, Simulation, StepReport, Tolerance};
use crate::absolute::AbsoluteSimulation;
use crate::analysis::AnalysisError;
use crate::relative::{TreeError, TreeScene, TreeSimulation, TreeState};
use crate::{Scene, SparseJacobian, SystemState};

/// A simulation of `NB` bodies, whichever engine runs it.
///
/// ```
/// use joint_runtime::Scene;
/// use joint_runtime::dynamics::{Engine, NoLoads, Simulation, SimulationOptions};
///
/// /// The relative change of the energy over `steps` RK4 steps of `h` from
/// /// `state`: one function for every scene.
/// fn drift<E: Engine<NB>, const NB: usize>(sim: &mut E, mut state: E::State, h: f64, steps: usize) -> Result<f64, E::Error> {
///     let start = sim.energy(&state).total();
///     for _ in 0..steps {
///         sim.step(&mut state, h)?;
///     }
///     Ok((sim.energy(&state).total() - start).abs() / start.abs())
/// }
///
/// #[derive(Scene)]
/// #[scene(coordinates = absolute, gravity = [0, 0, -9.81])]
/// #[body(bar, mass = 1.0, inertia = [0.001, 0.0833, 0.0833])]
/// #[joint(pin = revolute(ground, bar), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0, 0, 0], rho2 = [-0.5, 0, 0])]
/// struct Absolute;
///
/// #[derive(Scene)]
/// #[scene(gravity = [0, 0, -9.81], coordinates = relative)]
/// #[body(bar, mass = 1.0, inertia = [0.001, 0.0833, 0.0833])]
/// #[joint(pin = revolute(ground, bar), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0, 0, 0], rho2 = [-0.5, 0, 0])]
/// struct Relative;
///
/// let options = SimulationOptions::default();
/// let mut r = Simulation::new(&Relative, NoLoads, &[], options)?;
/// let mut a = Simulation::new(&Absolute, NoLoads, &[], options)?;
/// // The bar swung out, as bodies, in each engine's own state.
/// let mut swung = r.tree().zero_state();
/// swung.q[0] = 1.0;
/// let bodies = Engine::system_state(&r, &swung);
/// let start = Engine::state_of(&a, &bodies)?;
/// assert!(drift(&mut r, swung, 1e-3, 500)? < 1e-9);
/// assert!(drift(&mut a, start, 1e-3, 500)? < 1e-6);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub trait Engine<const NB: usize> {
    /// The state it steps: the bodies' [`SystemState`] (absolute
    /// coordinates) or the tree's [`TreeState`] (relative).
    type State: Copy;
    /// Why a call failed ([`AnalysisError`], [`TreeError`]).
    type Error: core::error::Error + 'static;

    /// One step of length `h` with the configured integrator.
    ///
    /// # Errors
    /// The engine's (a singular matrix, a state that is not finite, …);
    /// `state` is unchanged on error.
    fn step(&mut self, state: &mut Self::State, h: f64) -> Result<StepReport, Self::Error>;

    /// To `t_end` by error-controlled steps of `method` (Dormand–Prince,
    /// Radau IIA or generalised-α, on both engines).
    ///
    /// # Errors
    /// The engine's, or a method it does not offer, by name.
    fn integrate(
        &mut self,
        state: &mut Self::State,
        t_end: f64,
        method: Adaptive,
        tolerance: Tolerance,
    ) -> Result<IntegrationReport, Self::Error>;

    /// Kinetic, gravitational and elastic energy.
    fn energy(&self, state: &Self::State) -> Energy;

    /// The engine's state of the bodies' poses and velocities.
    ///
    /// # Errors
    /// A state the engine cannot hold (not finite; off the tree's joints).
    fn state_of(&self, system: &SystemState<NB>) -> Result<Self::State, Self::Error>;

    /// The bodies' poses and velocities of the engine's state.
    fn system_state(&self, state: &Self::State) -> SystemState<NB>;

    /// The joint named `joint`'s reaction on every body at `state` (on its
    /// two bodies; zeros elsewhere) under the simulation's loads and
    /// springs, no joint forces: the [`Reaction`] convention, force in the
    /// world's components through each body's centre, torque about it in
    /// the body's. Every joint of the scene by its name, loop-closing ones
    /// included (and, in relative coordinates, a contact); `None` for a
    /// name the scene does not have. Both engines give the same numbers
    /// wherever the dynamics determine them (an overconstrained loop's
    /// redundant rows carry a force neither determines:
    /// [`TreeSimulation::closure_reactions`]).
    ///
    /// # Errors
    /// The engine's dynamics'.
    fn reaction(&mut self, state: &Self::State, joint: &str) -> Result<Option<[Reaction; NB]>, Self::Error>;
}

impl<S, L, const NB: usize, const NV: usize, const M: usize, const NNZ: usize> Engine<NB>
    for AbsoluteSimulation<'_, S, L, NB, NV, M, NNZ>
where
    S: Scene<NB, NV, M> + SparseJacobian<NB, NNZ>,
    L: AppliedLoads<NB>,
{
    type State = SystemState<NB>;
    type Error = AnalysisError;

    fn step(&mut self, state: &mut SystemState<NB>, h: f64) -> Result<StepReport, AnalysisError> {
        AbsoluteSimulation::step(self, state, h)
    }

    fn integrate(
        &mut self,
        state: &mut SystemState<NB>,
        t_end: f64,
        method: Adaptive,
        tolerance: Tolerance,
    ) -> Result<IntegrationReport, AnalysisError> {
        AbsoluteSimulation::integrate(self, state, t_end, method, tolerance)
    }

    fn energy(&self, state: &SystemState<NB>) -> Energy {
        AbsoluteSimulation::energy(self, state)
    }

    fn state_of(&self, system: &SystemState<NB>) -> Result<SystemState<NB>, AnalysisError> {
        AbsoluteSimulation::state_of(self, system)
    }

    fn system_state(&self, state: &SystemState<NB>) -> SystemState<NB> {
        AbsoluteSimulation::system_state(self, state)
    }

    fn reaction(&mut self, state: &SystemState<NB>, joint: &str) -> Result<Option<[Reaction; NB]>, AnalysisError> {
        let Some(block) = S::BLOCKS.iter().find(|b| b.name == joint) else { return Ok(None) };
        let lambda = self.dynamics(state)?.lambda;
        Ok(Some(self.reactions(state, &lambda, block)))
    }
}

impl<S, L, const NB: usize, const NQ: usize, const NV: usize, const NC: usize> Engine<NB>
    for TreeSimulation<'_, S, NB, NQ, NV, NC, L>
where
    S: TreeScene<NB, NQ, NV, NC>,
    L: AppliedLoads<NB>,
{
    type State = TreeState<NQ, NV>;
    type Error = TreeError;

    fn step(&mut self, state: &mut TreeState<NQ, NV>, h: f64) -> Result<StepReport, TreeError> {
        TreeSimulation::step(self, state, h)
    }

    fn integrate(
        &mut self,
        state: &mut TreeState<NQ, NV>,
        t_end: f64,
        method: Adaptive,
        tolerance: Tolerance,
    ) -> Result<IntegrationReport, TreeError> {
        TreeSimulation::integrate(self, state, t_end, method, tolerance)
    }

    fn energy(&self, state: &TreeState<NQ, NV>) -> Energy {
        TreeSimulation::energy(self, state)
    }

    fn state_of(&self, system: &SystemState<NB>) -> Result<TreeState<NQ, NV>, TreeError> {
        TreeSimulation::state_of(self, system)
    }

    fn system_state(&self, state: &TreeState<NQ, NV>) -> SystemState<NB> {
        TreeSimulation::system_state(self, state)
    }

    fn reaction(&mut self, state: &TreeState<NQ, NV>, joint: &str) -> Result<Option<[Reaction; NB]>, TreeError> {
        self.joint_reaction(state, &nalgebra::SVector::zeros(), joint)
    }
}

/// A [`Simulation`] is the engine it wraps.
impl<'a, S: Simulate<'a, L>, L, const NB: usize> Engine<NB> for Simulation<'a, S, L>
where
    S::Engine: Engine<NB>,
{
    type State = <S::Engine as Engine<NB>>::State;
    type Error = <S::Engine as Engine<NB>>::Error;

    fn step(&mut self, state: &mut Self::State, h: f64) -> Result<StepReport, Self::Error> {
        (**self).step(state, h)
    }

    fn integrate(
        &mut self,
        state: &mut Self::State,
        t_end: f64,
        method: Adaptive,
        tolerance: Tolerance,
    ) -> Result<IntegrationReport, Self::Error> {
        (**self).integrate(state, t_end, method, tolerance)
    }

    fn energy(&self, state: &Self::State) -> Energy {
        (**self).energy(state)
    }

    fn state_of(&self, system: &SystemState<NB>) -> Result<Self::State, Self::Error> {
        (**self).state_of(system)
    }

    fn system_state(&self, state: &Self::State) -> SystemState<NB> {
        (**self).system_state(state)
    }

    fn reaction(&mut self, state: &Self::State, joint: &str) -> Result<Option<[Reaction; NB]>, Self::Error> {
        (**self).reaction(state, joint)
    }
}
