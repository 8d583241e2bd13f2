//! The one [`Simulation`]: whichever coordinates a scene declares, the same
//! constructor, and the engine its derive chose underneath.
//!
//! `#[derive(Scene)]` implements [`Simulate`] for the scene: absolute
//! coordinates (the default, and `coordinates = both`) run on
//! [`AbsoluteSimulation`] (six coordinates per body, the joints' rows as
//! constraints, the block factor), `coordinates = relative` on
//! [`TreeSimulation`] (the tree in its joints' freedoms, the closures' rows
//! as constraints). A [`Simulation`] is made the same way for both and
//! dereferences to its engine, whose methods (`step`, `integrate`,
//! `energy`, `reactions`, `linearise`, …) it then offers; `state_of` and
//! `system_state` convert between the engine's state and the bodies'
//! [`SystemState`](crate::SystemState), so that code which builds, records
//! or compares bodies' poses runs unchanged on either choice.
//!
//! Why a wrapper over two engines rather than one engine: the two solve
//! different equations on different state types (bodies on the rotation
//! group against joint coordinates), and each is generated for its scene at
//! compile time; what a user should not have to know is which one to name.
//!
//! [`TreeSimulation`]: crate::relative::TreeSimulation

use core::ops::{Deref, DerefMut};

use super::{NoLoads, SimulationOptions, SpringDamper};
#[cfg(doc)]
use crate::absolute::AbsoluteSimulation;

/// How a scene is simulated: the engine its coordinates call for, made
/// from the scene, the user's loads `L`, springs and options. The derive
/// implements it for every scene (absolute coordinates:
/// [`AbsoluteSimulation`]; `coordinates = relative`:
/// [`TreeSimulation`](crate::relative::TreeSimulation)); a hand-written
/// [`Scene`](crate::Scene) implements it in one line through
/// [`AbsoluteSimulation::new`].
pub trait Simulate<'a, L>: Sized {
    /// The simulation that runs this scene.
    type Engine;
    /// What making or stepping it reports.
    type Error;
    /// The engine for `self` with `loads`, `springs` and `options`: an
    /// integrator, stabilisation or projection the engine does not offer is
    /// refused (`BadOption`), never replaced silently.
    ///
    /// # Errors
    /// The engine's construction errors (inertias, options, springs).
    fn engine(
        &'a self,
        loads: L,
        springs: &'a [SpringDamper],
        options: SimulationOptions,
    ) -> Result<Self::Engine, Self::Error>;
}

/// The simulation of a scene in the coordinates it declares: made by
/// [`Simulation::new`] for every scene, it dereferences to the engine
/// ([`Simulate::Engine`]) and offers all of its methods.
///
/// ```
/// use joint_runtime::Scene;
/// use joint_runtime::dynamics::{NoLoads, Simulation, SimulationOptions};
///
/// /// The same pendulum in both coordinate choices.
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
/// let mut a = Simulation::new(&Absolute, NoLoads, &[], options)?;
/// let mut r = Simulation::new(&Relative, NoLoads, &[], options)?;
/// // The bar hanging at rest, then swung 0.3 rad about its pin: built as bodies,
/// // converted to each engine's state.
/// let start = r.system_state(&r.tree().zero_state());
/// let mut sa = a.state_of(&start)?;
/// let mut sr = r.state_of(&start)?;
/// sr.v[0] = 1.0;
/// sa = a.state_of(&r.system_state(&sr))?;
/// for _ in 0..100 {
///     a.step(&mut sa, 1e-3)?;
///     r.step(&mut sr, 1e-3)?;
/// }
/// let (ea, er) = (a.system_state(&sa), r.system_state(&sr));
/// assert!((ea.bodies[0].r - er.bodies[0].r).norm() < 1e-10);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub struct Simulation<'a, S: Simulate<'a, L>, L = NoLoads> {
    engine: S::Engine,
}

impl<'a, S: Simulate<'a, L>, L> Simulation<'a, S, L> {
    /// The simulation of `scene` with the user's `loads` ([`NoLoads`] for
    /// none), `springs` and `options`, in the coordinates the scene
    /// declares. Every workspace of the configured integrator is made here:
    /// a step allocates nothing.
    ///
    /// # Errors
    /// The engine's: [`AnalysisError`](crate::analysis::AnalysisError) for
    /// absolute coordinates, [`TreeError`](crate::relative::TreeError) for
    /// relative ones (a bad inertia, spring or option, by name).
    pub fn new(
        scene: &'a S,
        loads: L,
        springs: &'a [SpringDamper],
        options: SimulationOptions,
    ) -> Result<Self, S::Error> {
        Ok(Simulation { engine: scene.engine(loads, springs, options)? })
    }

    /// The engine, by value.
    pub fn into_engine(self) -> S::Engine {
        self.engine
    }
}

impl<'a, S: Simulate<'a, L>, L> Deref for Simulation<'a, S, L> {
    type Target = S::Engine;
    fn deref(&self) -> &S::Engine {
        &self.engine
    }
}

impl<'a, S: Simulate<'a, L>, L> DerefMut for Simulation<'a, S, L> {
    fn deref_mut(&mut self) -> &mut S::Engine {
        &mut self.engine
    }
}

impl<'a, S: Simulate<'a, L>, L> core::fmt::Debug for Simulation<'a, S, L>
where
    S::Engine: core::fmt::Debug,
{
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_tuple("Simulation").field(&self.engine).finish()
    }
}
