//! Forward dynamics of any [`Scene`]: constrained accelerations, Lagrange
//! multipliers and joint reactions, constraint stabilisation, four fixed-step
//! integrators on the rotation group and error-controlled steps. A step
//! allocates nothing (the workspaces are made in `new`; the linearisation,
//! behind `alloc`, allocates its run-time-sized matrices).
//!
//! [`Simulation`] is the one simulation for every scene: it solves the
//! equations below on the scene's compile-time block pattern (the block factor
//! of `J M⁻¹ Jᵀ` in arrays the derive sizes, the implicit integrators'
//! saddle-point matrices; see [`absolute`](crate::absolute)), in time and memory
//! proportional to the scene. (The same equations on dense matrices are kept
//! as the tests' independent reference, behind a feature that is not part of
//! the API.) For a scene in relative coordinates the same `Simulation::new`
//! makes the tree's engine instead (`relative::TreeSimulation`): the scene's
//! derived [`Simulate`] impl picks the engine, the `Simulation` dereferences
//! to it, and [`Engine`] is the one bound over both (`simulation.rs`,
//! `engine.rs`).
//!
//! This module also holds what both engines and every integrator share: the
//! options, loads, springs and reports; the state arithmetic on the rotation
//! group; the bookkeeping of every modified Newton iteration (midpoint and
//! generalised-α: when the matrix is rebuilt, when the iteration stops); the
//! forces' derivatives (`force_derivatives.rs`); generalised-α's equations and
//! Radau IIA's driver (written once over the host that solves its stage
//! systems); the error-controlled driver, one step-size loop over the state's
//! and the error's types that the absolute engine, the tree's and the dense
//! reference all run (`adaptive.rs`); and the linearisation's minimal
//! coordinates (`linear.rs`).
//!
//! # Equations and sign convention
//!
//! Per body (frame origin at the centre of mass) the velocities are `ṙ`
//! (inertial) and `ω'` (body components), `v = [ṙ_0, ω'_0, ṙ_1, ...]`, and the mass
//! matrix is `M = blockdiag(m_i I, J'_i)`. The generalised forces are
//! `Q_i = [m_i g + F_i + springs, T'_i − ω'_i × J'_i ω'_i + springs]`: forces in
//! inertial components acting at the centre of mass, torques in body components
//! about it. With `J v̇ = γ` (the project's convention, `CONVENTIONS.md`), the
//! equations of motion are Haug's
//!
//! ```text
//! M v̇ + Jᵀ λ = Q,        J v̇ = γ
//! ```
//!
//! so `(J M⁻¹ Jᵀ) λ = J M⁻¹ Q − γ` and `v̇ = M⁻¹ (Q − Jᵀ λ)`; indeed
//! `J v̇ = J M⁻¹ Q − (J M⁻¹ Q − γ) = γ`. The generalised constraint force acting on
//! the bodies is therefore `−Jᵀ λ`; a joint's reaction on each body is its rows'
//! share, `−J_kᵀ λ_k`, split into the body's `[force (inertial), torque (body)]`
//! ([`AbsoluteSimulation::reactions`]). `J M⁻¹ Jᵀ` is factorised on its block pattern
//! ([`BlockFactor`](crate::absolute::BlockFactor)), each diagonal block by a
//! rank-revealing pivoted Cholesky: for redundant
//! constraints λ is not unique (the dropped rows get λ = 0), but every λ gives
//! the same `v̇`.
//!
//! # Stabilisation
//!
//! - [`Stabilisation::Baumgarte`]: `γ ← γ − 2α Φ̇ − β² Φ` with `Φ̇ = J v + Φ_t`, so
//!   the constraint error obeys `ë + 2α ė + β² e = 0`.
//! - Projection ([`SimulationOptions::projection`]): after each step the positions
//!   are moved onto Φ = 0 by a few minimum-norm Newton steps and the velocities
//!   onto `J v = −Φ_t`. Both projections use the mass metric (`Δ = M⁻¹ Jᵀ y`), the
//!   correction of least kinetic energy, which does not depend on the units of
//!   lengths versus angles.
//!
//! # Integrators
//!
//! - [`Integrator::Rk4`]: the classical explicit Runge–Kutta method on
//!   `ṙ = ṙ`, `ṗ = ½ p ⊗ (0, ω')`, `v̇ = a(q, v)`, with `p` renormalised at every
//!   stage (where the scene is evaluated) and at the end. Fourth order, cheap,
//!   excellent energy behaviour at small steps; unstable for stiff springs once
//!   `h ω_max ≳ 2.8`.
//! - [`Integrator::ImplicitMidpoint`]: the implicit midpoint rule on the Lie
//!   group, on the index-1 (acceleration-level) equations. With the unknown
//!   midpoint velocity `w`, `q_½ = q_n ⊕ (h/2) w` (`r += (h/2) ṙ`,
//!   `p ← p ⊗ q((h/2) ω')`),
//!   `w = v_n + (h/2) a(q_½, w, t_n + h/2)`, then `q_{n+1} = q_n ⊕ h w` and
//!   `v_{n+1} = 2w − v_n`. The `NV` equations are solved by (modified) Newton
//!   in saddle-point form (`δw` and `δλ` unknown, the iteration matrix
//!   `I − (h/2) ∂a/∂w` never formed): exact,
//!   from the scene's generated second-order terms (`#[scene(second_order)]`,
//!   [`NewtonMatrix::Generated`]), or by central differences of `J`, `γ` and
//!   `Φ_t` for a scene without them (bodies coloured so that no joint sees
//!   two move: two colours for a chain, `absolute/differences.rs`).
//!
//!   A-stable (a stiff spring at any `h ω` stays bounded) and symmetric: no
//!   numerical damping, quadratic invariants conserved, energy bounded. Not
//!   L-stable: the stiffest modes are kept, not damped. The index-1 form drifts
//!   from Φ = 0 slowly; projection removes the drift.
//!
//!   At steps far beyond the motion's time scales the rule's nonlinear
//!   equations can have solutions far from the motion, and Newton may converge
//!   to one (on the stiff press at `h ω = 70`, a state 1.2 m off). A step is
//!   therefore returned only if its energy balance holds: the energy gained,
//!   less the work of the user's loads (evaluated once more, at the converged
//!   midpoint) and of the constraint forces there, at most a tenth of the
//!   step's energy scale (kinetic and elastic energy at its start, the work's
//!   size and the change of gravitational energy); otherwise
//!   [`AnalysisError::SpuriousSolution`] and the state unchanged.
//! - [`Integrator::GeneralisedAlpha`]: the index-3 generalised-α method on the
//!   Lie group (`generalised_alpha.rs`): `Φ(q) = 0` holds at every step, high
//!   frequencies are damped to [`SimulationOptions::spectral_radius`] per step,
//!   second order. Newton on `(Δq, λ)` with the exact iteration matrix
//!   (`M`, the generated tangent stiffness `∂(Jᵀλ)/∂q`, the forces'
//!   derivatives), solved through its Schur complement (`NV + M` is not a
//!   stable const generic). The method of choice for stiff springs.
//! - [`Integrator::RadauIIA`]: Radau IIA of order 5 on the Lie group
//!   (`radau.rs`): three implicit stages on the index-1 equations, L-stable
//!   and stiffly accurate, simplified Newton with the generated Jacobian
//!   `[[0, I], [∂a/∂q, ∂a/∂v]]` split by RADAU5's transformation into one real
//!   and one complex `NV × NV` system. Fifth order where the stiff motion is
//!   not followed; on the index-1 equations the iteration converges only for
//!   steps over which stiff springs turn little (see `radau.rs`).
//! - [`AbsoluteSimulation::integrate`]: error-controlled variable steps to a given
//!   time, with the explicit Dormand–Prince 5(4) pair, generalised-α and its
//!   local error estimate, or Radau IIA and RADAU5's estimate ([`Adaptive`],
//!   [`Tolerance`], `adaptive.rs`).
//!
//! [`AbsoluteSimulation::linearise`] (feature `alloc`) gives the linearised dynamics
//! about a state, in minimal coordinates and in full, and
//! [`AbsoluteSimulation::transition`] a midpoint step with its state-transition
//! Jacobian (`linear.rs`).

// `AnalysisError` is returned by value (no allocator to box it).

pub(crate) mod adaptive;
#[cfg(feature = "__dense_reference")]
mod dense;
mod engine;
mod force_derivatives;
mod generalised_alpha;
#[cfg(feature = "alloc")]
pub(crate) mod linear;
mod newton_matrix;
pub(crate) mod radau;
mod simulation;

pub use crate::absolute::AbsoluteSimulation;
pub use adaptive::{Adaptive, IntegrationReport, Tolerance};
#[cfg(feature = "__dense_reference")]
#[doc(hidden)]
pub use dense::DenseSimulation;
pub use engine::Engine;
pub use force_derivatives::Direction;
#[cfg(feature = "alloc")]
pub(crate) use force_derivatives::force_column;
pub(crate) use force_derivatives::{LOAD_STEP, load_differences_along, spring_column};
pub(crate) use generalised_alpha::{AlphaHistory, Coefficients, Iterate, mass_times_into};
#[cfg(feature = "alloc")]
#[cfg_attr(docsrs, doc(cfg(feature = "alloc")))]
pub use linear::Linearisation;
#[cfg(feature = "alloc")]
pub(crate) use newton_matrix::update_blocks;
pub(crate) use newton_matrix::update_blocks_into;
pub use simulation::{Simulate, Simulation};

use nalgebra::{SVector, Vector3, Vector4};

use crate::absolute::buf::{Boxed, boxed, boxed_with, zeros};
use crate::analysis::{
    AnalysisError, AssemblyOptions, InverseMass, RowList, WorstRows, apply_increment, quat_mul, set_velocities,
};
use crate::linalg::DEFAULT_RANK_TOLERANCE;
use crate::rotation_matrix;
use crate::scene::{BodyInertia, Scene, SystemState};

/// Loads applied by user code to each body: a force in inertial components at
/// the centre of mass, and a torque in the body's components.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Loads<const NB: usize> {
    /// Force on each body (inertial components, through its centre of mass).
    #[cfg_attr(feature = "serde", serde(with = "crate::serde_array"))]
    pub force: [Vector3<f64>; NB],
    /// Torque on each body (body components).
    #[cfg_attr(feature = "serde", serde(with = "crate::serde_array"))]
    pub torque: [Vector3<f64>; NB],
}

impl<const NB: usize> Default for Loads<NB> {
    fn default() -> Self {
        Loads { force: [Vector3::zeros(); NB], torque: [Vector3::zeros(); NB] }
    }
}

impl<const NB: usize> Loads<NB> {
    /// No loads, as a constant (a workspace's, `absolute::buf`).
    pub(crate) const fn zeros() -> Self {
        Loads { force: [zeros(); NB], torque: [zeros(); NB] }
    }

    /// Every force and torque back to zero (a workspace's loads reused).
    pub(crate) fn clear(&mut self) {
        self.force.iter_mut().chain(self.torque.iter_mut()).for_each(|x| *x = Vector3::zeros());
    }

    /// Adds `force` (inertial components) acting at the body-fixed point `point`
    /// (body components, from the centre of mass) of body `body`: the force and its
    /// moment `point × Aᵀ force`. An out-of-range `body` is ignored.
    pub fn add_force_at(&mut self, state: &SystemState<NB>, body: usize, force: &Vector3<f64>, point: &Vector3<f64>) {
        let (Some(b), Some(f), Some(t)) = (state.bodies.get(body), self.force.get_mut(body), self.torque.get_mut(body))
        else {
            return;
        };
        *f += force;
        *t += point.cross(&(rotation_matrix(&b.p).transpose() * force));
    }

    /// Adds `torque` given in inertial components to body `body` (stored in the
    /// body's components, `Aᵀ torque`). An out-of-range `body` is ignored.
    pub fn add_torque_inertial(&mut self, state: &SystemState<NB>, body: usize, torque: &Vector3<f64>) {
        if let (Some(b), Some(t)) = (state.bodies.get(body), self.torque.get_mut(body)) {
            *t += rotation_matrix(&b.p).transpose() * torque;
        }
    }
}

/// User code that applies loads: called at every evaluation of the dynamics with
/// the state and loads zeroed; add to them. Implemented by every closure
/// `FnMut(&SystemState<NB>, &mut Loads<NB>)` and by [`NoLoads`].
pub trait AppliedLoads<const NB: usize> {
    /// `true` when [`apply`](Self::apply) never adds a load (as for
    /// [`NoLoads`]): the dynamics then neither zero nor read a [`Loads`].
    /// `false` unless an implementation says otherwise.
    const NONE: bool = false;

    /// Adds this evaluation's loads.
    fn apply(&mut self, state: &SystemState<NB>, loads: &mut Loads<NB>);

    /// Adds the derivative of the loads [`apply`](Self::apply) gives at
    /// `state` along `direction` (per body `[δr, δθ', δṙ, δω']`, `δθ'` a turn
    /// in body components) to `loads`, and returns `true`; the default returns
    /// `false`, and the implicit integrators and the linearisation then take
    /// central differences of `apply` instead.
    fn derivative(&mut self, state: &SystemState<NB>, direction: &Direction<NB>, loads: &mut Loads<NB>) -> bool {
        let _ = (state, direction, loads);
        false
    }
}

impl<const NB: usize, F: FnMut(&SystemState<NB>, &mut Loads<NB>)> AppliedLoads<NB> for F {
    fn apply(&mut self, state: &SystemState<NB>, loads: &mut Loads<NB>) {
        self(state, loads)
    }
}

/// No applied loads (gravity and springs only).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct NoLoads;

impl<const NB: usize> AppliedLoads<NB> for NoLoads {
    const NONE: bool = true;

    fn apply(&mut self, _state: &SystemState<NB>, _loads: &mut Loads<NB>) {}

    fn derivative(&mut self, _state: &SystemState<NB>, _direction: &Direction<NB>, _loads: &mut Loads<NB>) -> bool {
        true
    }
}

/// One end of a [`SpringDamper`].
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
pub enum Attachment {
    /// A point fixed in the inertial frame (inertial components).
    Ground(Vector3<f64>),
    /// A point fixed in body `body` (body components, from its centre of mass).
    Body {
        /// The body's index in the state.
        body: usize,
        /// The point.
        point: Vector3<f64>,
    },
}

/// A linear spring and damper between two points, acting along the line
/// joining them: tension `k (L − L₀) + c L̇`. When the points coincide (`L` below
/// `1e-12`) the direction is undefined and the element exerts no force.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct SpringDamper {
    /// First end.
    pub a: Attachment,
    /// Second end.
    pub b: Attachment,
    /// Stiffness `k`.
    pub stiffness: f64,
    /// Damping `c`.
    pub damping: f64,
    /// Rest length `L₀`.
    pub rest_length: f64,
}

/// Constraint stabilisation at the acceleration level.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
#[non_exhaustive]
pub enum Stabilisation {
    /// Plain `J v̇ = γ`.
    None,
    /// Baumgarte: `J v̇ = γ − 2α Φ̇ − β² Φ`.
    Baumgarte {
        /// α (1/s).
        alpha: f64,
        /// β (1/s).
        beta: f64,
    },
}

impl Stabilisation {
    /// `(α, β)`: zeros without stabilisation, where the Newton matrices'
    /// stabilisation terms vanish.
    pub(crate) fn coefficients(self) -> (f64, f64) {
        match self {
            Stabilisation::Baumgarte { alpha, beta } => (alpha, beta),
            Stabilisation::None => (0.0, 0.0),
        }
    }
}

/// The time integrator of [`AbsoluteSimulation::step`] (see the module documentation).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
#[non_exhaustive]
pub enum Integrator {
    /// Explicit fourth-order Runge–Kutta on the Lie group.
    Rk4,
    /// Implicit midpoint rule on the Lie group (A-stable, symmetric), Newton on
    /// the index-1 equations.
    ImplicitMidpoint,
    /// Index-3 generalised-α on the Lie group (second order, numerical damping
    /// of high frequencies set by [`SimulationOptions::spectral_radius`]), Newton
    /// with the exact iteration matrix (`dynamics/generalised_alpha.rs`).
    GeneralisedAlpha,
    /// Radau IIA of order 5 on the Lie group (three implicit stages, L-stable,
    /// stiffly accurate), simplified Newton with the generated Jacobian of the
    /// index-1 equations (`dynamics/radau.rs`; on the sparse path its real
    /// and complex stage systems on the saddle-point pattern).
    RadauIIA,
}

/// The iteration matrix of the implicit integrator's Newton iteration.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
#[non_exhaustive]
pub enum NewtonMatrix {
    /// Exact, from the scene's generated second-order terms
    /// (`#[scene(second_order)]`; see `dynamics/newton_matrix.rs`): one
    /// factorisation and `NV` solves. Falls back to finite differences for a
    /// scene derived without them.
    #[default]
    Generated,
    /// Differences: for the implicit midpoint rule, forward differences of its
    /// residual (`NV` evaluations of the dynamics); for generalised-α, the
    /// tangent stiffness `∂(Jᵀλ)/∂q` by forward differences of `Jᵀλ` (the
    /// forces' derivatives stay exact). On the sparse path, for both, the
    /// second-order terms by central differences of the generated `J`, `γ`
    /// and `Φ_t`, several bodies at a time
    /// ([`DifferenceTerms`](crate::absolute::DifferenceTerms)), in the same
    /// saddle-point Newton matrix.
    FiniteDifferences,
}

/// How far (relative to the scale of `J v̇` and γ) a redundant row's
/// acceleration equation may disagree with the rows that determine the motion
/// before [`AbsoluteSimulation::dynamics`] calls the constraints contradictory: loose
/// enough for the `O(h²)` disagreement at an integrator's stage states, tight
/// enough for constraints that truly contradict each other (`O(1)`).
pub const REDUNDANT_TOLERANCE: f64 = 1e-4;

/// Options of a [`Simulation`].
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[non_exhaustive]
#[cfg_attr(feature = "serde", serde(default))]
pub struct SimulationOptions {
    /// The integrator.
    pub integrator: Integrator,
    /// Acceleration-level stabilisation.
    pub stabilisation: Stabilisation,
    /// Projection after each step (`None`: no projection). The Newton options of
    /// the position projection; a projection that stops above its tolerance but
    /// below `1e3 ×` it (round-off floor) is accepted.
    pub projection: Option<AssemblyOptions>,
    /// Relative rank tolerance for `J M⁻¹ Jᵀ`.
    pub rank_tolerance: f64,
    /// Implicit integrator: converged when ‖Δw‖ ≤ `newton_tolerance (1 + ‖w‖)`.
    pub newton_tolerance: f64,
    /// Implicit integrator: Newton iterations allowed per step.
    pub newton_max_iterations: usize,
    /// Implicit integrator: how its iteration matrix is made.
    pub newton_matrix: NewtonMatrix,
    /// Generalised-α: the spectral radius ρ∞ at infinite frequency, in
    /// `[0, 1]` (1: no numerical damping; 0: the highest frequencies removed in
    /// one step).
    pub spectral_radius: f64,
}

impl Default for SimulationOptions {
    fn default() -> Self {
        SimulationOptions {
            integrator: Integrator::Rk4,
            stabilisation: Stabilisation::None,
            projection: Some(AssemblyOptions { tolerance: 1e-12, max_iterations: 5, ..AssemblyOptions::default() }),
            rank_tolerance: DEFAULT_RANK_TOLERANCE,
            newton_tolerance: 1e-12,
            newton_max_iterations: 30,
            newton_matrix: NewtonMatrix::Generated,
            spectral_radius: 0.9,
        }
    }
}

/// Options are `#[non_exhaustive]` (more will come); set them from the defaults:
/// `SimulationOptions::default().with_integrator(Integrator::ImplicitMidpoint)`.
impl SimulationOptions {
    /// Sets [`integrator`](Self::integrator).
    pub const fn with_integrator(mut self, integrator: Integrator) -> Self {
        self.integrator = integrator;
        self
    }
    /// Sets [`stabilisation`](Self::stabilisation).
    pub const fn with_stabilisation(mut self, stabilisation: Stabilisation) -> Self {
        self.stabilisation = stabilisation;
        self
    }
    /// Sets [`projection`](Self::projection) (`None`: no projection).
    pub const fn with_projection(mut self, projection: Option<AssemblyOptions>) -> Self {
        self.projection = projection;
        self
    }
    /// Sets [`rank_tolerance`](Self::rank_tolerance).
    pub const fn with_rank_tolerance(mut self, rank_tolerance: f64) -> Self {
        self.rank_tolerance = rank_tolerance;
        self
    }
    /// Sets [`newton_tolerance`](Self::newton_tolerance).
    pub const fn with_newton_tolerance(mut self, newton_tolerance: f64) -> Self {
        self.newton_tolerance = newton_tolerance;
        self
    }
    /// Sets [`spectral_radius`](Self::spectral_radius).
    pub const fn with_spectral_radius(mut self, spectral_radius: f64) -> Self {
        self.spectral_radius = spectral_radius;
        self
    }
    /// Sets [`newton_matrix`](Self::newton_matrix).
    pub const fn with_newton_matrix(mut self, newton_matrix: NewtonMatrix) -> Self {
        self.newton_matrix = newton_matrix;
        self
    }
    /// Sets [`newton_max_iterations`](Self::newton_max_iterations).
    pub const fn with_newton_max_iterations(mut self, newton_max_iterations: usize) -> Self {
        self.newton_max_iterations = newton_max_iterations;
        self
    }
}

/// Constrained accelerations at one state.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
#[non_exhaustive]
pub struct Dynamics<const NV: usize, const M: usize> {
    /// `v̇ = [r̈_0, ω̇'_0, ...]`.
    pub vdot: SVector<f64, NV>,
    /// Lagrange multipliers (`M v̇ + Jᵀ λ = Q`); zero on redundant rows.
    pub lambda: SVector<f64, M>,
    /// The generalised forces `Q`.
    pub forces: SVector<f64, NV>,
    /// Rows of `J M⁻¹ Jᵀ` dropped as redundant.
    pub redundant: RowList<M>,
}

/// A joint's reaction on one body: the share of `−Jᵀ λ` in the body's columns.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Reaction {
    /// Force, inertial components, through the centre of mass.
    pub force: Vector3<f64>,
    /// Torque about the centre of mass, body components.
    pub torque: Vector3<f64>,
}

/// Energy of the mechanism.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[non_exhaustive]
pub struct Energy {
    /// `½ Σ (m |ṙ|² + ω'ᵀ J' ω')`.
    pub kinetic: f64,
    /// `−Σ m g · r`.
    pub gravity: f64,
    /// `½ Σ k (L − L₀)²`.
    pub elastic: f64,
}

impl Energy {
    /// Kinetic plus potential.
    pub fn total(&self) -> f64 {
        self.kinetic + self.gravity + self.elastic
    }
}

/// What one [`AbsoluteSimulation::step`] did.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[non_exhaustive]
pub struct StepReport {
    /// Newton iterations of the implicit integrator (0 for RK4).
    pub newton_iterations: usize,
    /// Iteration matrices the implicit integrator built and factorised (0 for RK4).
    pub newton_matrices: usize,
    /// Newton iterations of the position projection. On the sparse path an
    /// RK4 step's projection starts with simplified Newton on its last
    /// stage's factor (each iteration a solve, no factorisation); those
    /// iterations are counted here too, so the count may exceed the
    /// projection's `max_iterations`.
    pub projection_iterations: usize,
    /// ‖Φ‖₂ at the end of the step.
    pub constraint_residual: f64,
    /// ‖J v + Φ_t‖₂ at the end of the step.
    pub velocity_residual: f64,
}

/// Position and velocity (inertial) of an attachment point, and its body and body-fixed point.
type PointMotion = (Vector3<f64>, Vector3<f64>, Option<(usize, Vector3<f64>)>);

/// Time derivative of the state for RK4.
#[derive(Clone, Copy)]
pub(crate) struct Rate<const NB: usize, const NV: usize> {
    rdot: [Vector3<f64>; NB],
    pdot: [Vector4<f64>; NB],
    vdot: SVector<f64, NV>,
}

impl<const NB: usize, const NV: usize> Rate<NB, NV> {
    /// The rate at `state` with accelerations `vdot`.
    #[inline]
    pub(crate) fn new(state: &SystemState<NB>, vdot: SVector<f64, NV>) -> Self {
        let mut rate = Rate { rdot: [Vector3::zeros(); NB], pdot: [Vector4::zeros(); NB], vdot };
        rate.positions(state);
        rate
    }

    /// Zero rates (a state at rest's, without accelerations), as a
    /// constant: an RK4 workspace's before its first stage.
    pub(crate) const fn zeros() -> Self {
        Rate { rdot: [zeros(); NB], pdot: [zeros(); NB], vdot: zeros() }
    }

    /// [`Rate::new`] written over `self` (no state-sized temporary).
    #[inline]
    pub(crate) fn assign(&mut self, state: &SystemState<NB>, vdot: &SVector<f64, NV>) {
        self.vdot.copy_from(vdot);
        self.positions(state);
    }

    /// `ṙ` and `ṗ = ½ p ⊗ (0, ω')` of every body at `state`.
    #[inline]
    fn positions(&mut self, state: &SystemState<NB>) {
        for ((b, rdot), pdot) in state.bodies.iter().zip(self.rdot.iter_mut()).zip(self.pdot.iter_mut()) {
            *rdot = b.rdot;
            *pdot = quat_mul(&b.p, &Vector4::new(0.0, b.omega.x, b.omega.y, b.omega.z)) * 0.5;
        }
    }
}

/// RK4's combination of its four stage rates.
pub(crate) fn rk4_weights<'r, const NB: usize, const NV: usize>(
    k1: &'r Rate<NB, NV>,
    k2: &'r Rate<NB, NV>,
    k3: &'r Rate<NB, NV>,
    k4: &'r Rate<NB, NV>,
) -> [(&'r Rate<NB, NV>, f64); 4] {
    let sixth = 1.0 / 6.0;
    [(k1, sixth), (k2, 2.0 * sixth), (k3, 2.0 * sixth), (k4, sixth)]
}

/// `y0 + h Σ c_k k_k`, with `p` renormalised, at time `t`.
#[inline]
pub(crate) fn advance<'r, const NB: usize, const NV: usize>(
    y0: &SystemState<NB>,
    rates: impl IntoIterator<Item = (&'r Rate<NB, NV>, f64)>,
    h: f64,
    t: f64,
) -> SystemState<NB> {
    let mut y = *y0;
    advance_into(y0, rates, h, t, &mut y);
    y
}

/// [`advance`] written into `y` (no state- or velocity-sized temporary; the
/// same operations in the same order, so the same bits).
#[inline]
pub(crate) fn advance_into<'r, const NB: usize, const NV: usize>(
    y0: &SystemState<NB>,
    rates: impl IntoIterator<Item = (&'r Rate<NB, NV>, f64)>,
    h: f64,
    t: f64,
    y: &mut SystemState<NB>,
) {
    y.bodies.copy_from_slice(&y0.bodies);
    for (k, c) in rates {
        for (i, ((b, rdot), pdot)) in y.bodies.iter_mut().zip(k.rdot.iter()).zip(k.pdot.iter()).enumerate() {
            b.r += rdot * (h * c);
            b.p += pdot * (h * c);
            // Through `get` and an array: no index the optimiser must prove
            // (the no-panic check links only without a panic path).
            let vdot = k.vdot.as_slice().get(6 * i..6 * i + 6).and_then(|a| <&[f64; 6]>::try_from(a).ok());
            if let Some(a) = vdot {
                b.rdot += Vector3::new(a[0], a[1], a[2]) * (h * c);
                b.omega += Vector3::new(a[3], a[4], a[5]) * (h * c);
            }
        }
    }
    for b in y.bodies.iter_mut() {
        let n = b.p.norm();
        if n > 0.0 {
            b.p /= n;
        }
    }
    y.t = t;
}

/// [`displaced`] written into `y` (a workspace's state).
pub(crate) fn displaced_into<const NB: usize, const NV: usize>(
    y0: &SystemState<NB>,
    u: &SVector<f64, NV>,
    s: f64,
    v: &SVector<f64, NV>,
    t: f64,
    y: &mut SystemState<NB>,
) {
    y.clone_from(y0);
    apply_increment(y, u, s);
    set_velocities(y, v);
    y.t = t;
}

#[cfg(feature = "alloc")]
/// The implicit midpoint rule's midpoint: `q_n ⊕ (h/2) w` with velocities
/// `w`, at `t_n + h/2`.
pub(crate) fn midpoint_state<const NB: usize, const NV: usize>(
    y0: &SystemState<NB>,
    w: &SVector<f64, NV>,
    h: f64,
) -> SystemState<NB> {
    let mut mid = *y0;
    midpoint_state_into(y0, w, h, &mut mid);
    mid
}

/// [`midpoint_state`] written into `mid` (a workspace's state).
pub(crate) fn midpoint_state_into<const NB: usize, const NV: usize>(
    y0: &SystemState<NB>,
    w: &SVector<f64, NV>,
    h: f64,
    mid: &mut SystemState<NB>,
) {
    displaced_into(y0, w, 0.5 * h, w, y0.t + 0.5 * h, mid);
}

/// [`midpoint_end`] written into `end`, the end's velocities into `v`
/// (both a workspace's).
pub(crate) fn midpoint_end_into<const NB: usize, const NV: usize>(
    y0: &SystemState<NB>,
    v0: &SVector<f64, NV>,
    w: &SVector<f64, NV>,
    h: f64,
    v: &mut SVector<f64, NV>,
    end: &mut SystemState<NB>,
) {
    for (v, (w, v0)) in v.as_mut_slice().iter_mut().zip(w.as_slice().iter().zip(v0.as_slice().iter())) {
        *v = w * 2.0 - v0;
    }
    displaced_into(y0, w, h, v, y0.t + h, end);
}

/// How much energy an implicit midpoint step may gain beyond the work, relative
/// to its scale: the kinetic and elastic energy at the step's start, the
/// work's size and the change of gravitational energy (plus 1e-12 J, so that
/// a mechanism at rest is not refused for round-off).
/// The rule conserves a quadratic energy exactly and a smooth one to
/// `O(h³)`: on the stiff press at 50, 100 and 200 steps every step that
/// follows the motion gains at most 1.3e-4 of this scale (most lose energy
/// to the dampers), while the spurious solution at 50 steps gains 1.5e4.
const ENERGY_GAIN: f64 = 0.1;

/// Refuses an implicit midpoint solution that gains more energy than the
/// work done allows ([`ENERGY_GAIN`]): Newton converged, but to a solution
/// of the rule's equations far from the motion (the step is too large for
/// them to have one solution near it).
pub(crate) fn energy_balance(before: &Energy, after: &Energy, work: f64) -> Result<(), AnalysisError> {
    let gain = after.total() - before.total() - work;
    let scale = before.kinetic + before.elastic + libm::fabs(work) + libm::fabs(after.gravity - before.gravity);
    if gain.is_nan() || gain > ENERGY_GAIN * scale + 1e-12 {
        return Err(AnalysisError::SpuriousSolution { gain, scale });
    }
    Ok(())
}

/// Whether a Newton correction of `size` ends an implicit integrator's
/// iteration: below `tolerance × scale`, or stalled at the round-off floor
/// (no longer halving from the `last` one, and within 1000 times that or
/// `√ε × scale`, whichever is larger). Stiff springs make the residual's
/// round-off larger than the tolerance allows; so does a large closed-loop
/// mechanism near a singular position, whose multipliers the iteration matrix
/// then determines only to about 1e-3 (the 40-loop ladder's corrections stall
/// at 4e-9 relative there).
pub(crate) fn newton_done(size: f64, last: f64, scale: f64, tolerance: f64) -> bool {
    let floor = (1e3 * tolerance).max(STALLED);
    size <= tolerance * scale || (size <= floor * scale && size > 0.5 * last)
}

/// `√ε`: a correction that stops shrinking below this (relative) is round-off.
const STALLED: f64 = 1.4901161193847656e-8;

/// The bookkeeping of the modified Newton iterations of the implicit midpoint
/// rule and generalised-α, dense and sparse: the iteration cap, when the
/// iteration matrix is rebuilt (at the start, and when a correction shrank by
/// less than a factor 4: convergence is slow) and when the iteration stops
/// ([`newton_done`]).
pub(crate) struct ModifiedNewton {
    iterations: usize,
    matrices: usize,
    last: f64,
    stale: bool,
    /// The slowest contraction kept before the matrix is rebuilt: ¼, or
    /// 1/10 while an earlier step's matrix is in use.
    slowest: f64,
    max_iterations: usize,
    tolerance: f64,
}

impl ModifiedNewton {
    pub(crate) fn new(options: &SimulationOptions) -> Self {
        ModifiedNewton {
            iterations: 0,
            matrices: 0,
            last: f64::INFINITY,
            stale: true,
            slowest: 0.25,
            max_iterations: options.newton_max_iterations,
            tolerance: options.newton_tolerance,
        }
    }

    /// Another iteration, or the error when the cap is reached.
    pub(crate) fn next(&self) -> Result<(), AnalysisError> {
        if self.iterations >= self.max_iterations {
            return Err(AnalysisError::ImplicitNotConverged { iterations: self.iterations, correction: self.last });
        }
        Ok(())
    }

    /// Whether the iteration matrix must be built before this iteration.
    pub(crate) fn stale(&self) -> bool {
        self.stale
    }

    /// A matrix built before this iteration began (an earlier step's) is
    /// in use: the first iteration does not build one, and a correction
    /// that shrinks by less than a factor 10 has it rebuilt (a fresh
    /// matrix is cheaper than the iterations an old one's slow contraction
    /// would take to the tolerance).
    pub(crate) fn kept(&mut self) {
        self.stale = false;
        self.slowest = 0.1;
    }

    /// The iteration matrix was built.
    pub(crate) fn built(&mut self) {
        self.matrices += 1;
        self.stale = false;
        self.slowest = 0.25;
    }

    /// After a correction of norm `size` to an iterate of norm about `scale`:
    /// whether the iteration has converged; an error for a correction that
    /// is not finite.
    pub(crate) fn converged(&mut self, size: f64, scale: f64) -> Result<bool, AnalysisError> {
        self.iterations += 1;
        if !size.is_finite() {
            return Err(AnalysisError::ImplicitNotConverged { iterations: self.iterations, correction: size });
        }
        if newton_done(size, self.last, scale, self.tolerance) {
            return Ok(true);
        }
        if size > self.slowest * self.last {
            self.stale = true;
        }
        self.last = size;
        Ok(false)
    }

    /// Newton iterations and matrices built.
    pub(crate) fn counts(&self) -> (usize, usize) {
        (self.iterations, self.matrices)
    }
}

/// What every simulation of a scene reads besides the scene: its inertias,
/// their inverses and gravity, checked together with the springs. The
/// arrays are boxed with `alloc` (the inverses made where they live,
/// `absolute::buf`).
pub(crate) struct Mechanics<const NB: usize> {
    pub(crate) inertias: Boxed<[BodyInertia; NB]>,
    pub(crate) inverse: Boxed<[InverseMass; NB]>,
    pub(crate) gravity: Vector3<f64>,
}

impl<const NB: usize> Mechanics<NB> {
    /// The mechanics of `scene` with `springs`.
    ///
    /// # Errors
    /// As [`AbsoluteSimulation::new`].
    pub(crate) fn new<S: Scene<NB, NV, M>, const NV: usize, const M: usize>(
        scene: &S,
        springs: &[SpringDamper],
    ) -> Result<Self, AnalysisError> {
        crate::analysis::check_dims::<NB, NV>()?;
        // The scene returns its array by value, through this frame: the one
        // array of the scene's size on the stack while a simulation is made.
        let inertias = boxed(scene.inertias());
        let mut inverse = boxed_with(|| const { [InverseMass { inv_mass: 0.0, inv_inertia: zeros() }; NB] });
        inverse_masses::<S, NB, NV, M>(&inertias, &mut inverse)?;
        check_springs::<NB>(springs)?;
        let gravity = scene.gravity();
        if !gravity.iter().all(|x| x.is_finite()) {
            return Err(AnalysisError::BadOption { name: "gravity" });
        }
        Ok(Mechanics { inertias, inverse, gravity })
    }
}

/// The rows a factorisation kept hold to round-off by construction (relative
/// to `scale`); with `check`, the `dropped` (redundant) rows must agree to
/// [`REDUNDANT_TOLERANCE`], or the constraints contradict each other.
pub(crate) fn check_redundant<S: Scene<NB, NV, M>, const NB: usize, const NV: usize, const M: usize>(
    r: &SVector<f64, M>,
    dropped: &[usize],
    scale: f64,
    check: bool,
) -> Result<(), AnalysisError> {
    let mut kept = *r;
    for &i in dropped {
        if let Some(x) = kept.get_mut(i) {
            *x = 0.0;
        }
    }
    let disagreement = (r - kept).norm();
    if kept.norm() > 1e-9 * scale || (check && disagreement > REDUNDANT_TOLERANCE * scale) {
        let worst = WorstRows::of::<S, NB, NV, M>(r);
        return Err(AnalysisError::Inconsistent {
            analysis: crate::analysis::Analysis::Dynamics,
            residual: r.norm(),
            worst,
        });
    }
    Ok(())
}

/// A projection's Newton iterations and final ‖Φ‖, where stopping short of the
/// tolerance by less than a factor 1000 (the round-off floor) is accepted.
pub(crate) fn near_enough(
    newton: Result<(usize, f64), AnalysisError>,
    options: &AssemblyOptions,
) -> Result<(usize, f64), AnalysisError> {
    match newton {
        Ok(done) => Ok(done),
        Err(
            AnalysisError::NotConverged { residual, iterations, .. }
            | AnalysisError::NoProgress { residual, iterations, .. },
        ) if residual <= 1e3 * options.tolerance => Ok((iterations, residual)),
        Err(e) => Err(e),
    }
}

/// The inverse mass of every body, checked, into `inverse`.
fn inverse_masses<S: Scene<NB, NV, M>, const NB: usize, const NV: usize, const M: usize>(
    inertias: &[BodyInertia; NB],
    inverse: &mut [InverseMass; NB],
) -> Result<(), AnalysisError> {
    for (i, (b, inv)) in inertias.iter().zip(inverse.iter_mut()).enumerate() {
        *inv = inverse_mass(b).ok_or(AnalysisError::BadInertia { body: S::BODIES.get(i).copied().unwrap_or("") })?;
    }
    Ok(())
}

/// One body's inverse mass: `None` for mass properties no rigid body has
/// ([`BodyInertia::is_physical`]) or an inertia tensor that is not
/// invertible. Not generic, so compiled once in this crate: nalgebra's
/// `try_inverse` brings its 4 × 4 and general branches along wherever it is
/// instantiated (7 000 lines of LLVM IR in every scene's crate).
#[inline(never)]
fn inverse_mass(b: &BodyInertia) -> Option<InverseMass> {
    let sym = (b.inertia + b.inertia.transpose()) * 0.5;
    let j = if b.is_physical() { sym.try_inverse()? } else { return None };
    j.iter()
        .all(|x| x.is_finite())
        .then(|| InverseMass { inv_mass: 1.0 / b.mass, inv_inertia: (j + j.transpose()) * 0.5 })
}

/// Springs attached to bodies that exist, with finite coefficients.
fn check_springs<const NB: usize>(springs: &[SpringDamper]) -> Result<(), AnalysisError> {
    for s in springs {
        for end in [s.a, s.b] {
            let ok = match end {
                Attachment::Ground(x) => x.iter().all(|v| v.is_finite()),
                Attachment::Body { body, point } => body < NB && point.iter().all(|v| v.is_finite()),
            };
            if !ok {
                return Err(AnalysisError::BadOption { name: "spring attachment" });
            }
        }
        if !(s.stiffness.is_finite() && s.damping.is_finite() && s.rest_length.is_finite()) {
            return Err(AnalysisError::BadOption { name: "spring coefficients" });
        }
    }
    Ok(())
}

/// Position and velocity (inertial) of an attachment point.
#[inline]
fn point_motion<const NB: usize>(state: &SystemState<NB>, end: &Attachment) -> PointMotion {
    match *end {
        Attachment::Ground(x) => (x, Vector3::zeros(), None),
        Attachment::Body { body, point } => match state.bodies.get(body) {
            Some(b) => {
                let a = rotation_matrix(&b.p);
                (b.r + a * point, b.rdot + a * b.omega.cross(&point), Some((body, point)))
            }
            None => (Vector3::zeros(), Vector3::zeros(), None),
        },
    }
}

/// The generalised forces `Q` (gravity, user loads, gyroscopic terms, springs).
#[inline]
pub(crate) fn generalised_forces<L: AppliedLoads<NB>, const NB: usize, const NV: usize>(
    user: &mut L,
    springs: &[SpringDamper],
    inertias: &[BodyInertia; NB],
    gravity: &Vector3<f64>,
    state: &SystemState<NB>,
) -> SVector<f64, NV> {
    let (mut loads, mut q) = (Loads::<NB>::default(), SVector::<f64, NV>::zeros());
    generalised_forces_into(user, springs, inertias, gravity, state, &mut loads, &mut q);
    q
}

/// [`generalised_forces`] into `q`, the loads gathered in `loads`: both a
/// workspace's, so that no array of the scene's size sits in the caller's frame.
pub(crate) fn generalised_forces_into<L: AppliedLoads<NB>, const NB: usize, const NV: usize>(
    user: &mut L,
    springs: &[SpringDamper],
    inertias: &[BodyInertia; NB],
    gravity: &Vector3<f64>,
    state: &SystemState<NB>,
    loads: &mut Loads<NB>,
    q: &mut SVector<f64, NV>,
) {
    // Without user loads or springs the loads are zero: not gathered, so a
    // step's forces cost what the gravity and gyroscopic terms do.
    let gathered = !(L::NONE && springs.is_empty());
    if gathered {
        loads.clear();
        user.apply(state, loads);
    }
    for s in springs {
        let (xa, va, a) = point_motion(state, &s.a);
        let (xb, vb, b) = point_motion(state, &s.b);
        let d = xb - xa;
        let len = d.norm();
        if len.is_nan() || len <= 1e-12 {
            continue;
        }
        let u = d / len;
        let tension = s.stiffness * (len - s.rest_length) + s.damping * u.dot(&(vb - va));
        // Tension pulls a towards b and b towards a.
        if let Some((body, point)) = a {
            loads.add_force_at(state, body, &(u * tension), &point);
        }
        if let Some((body, point)) = b {
            loads.add_force_at(state, body, &(u * -tension), &point);
        }
    }
    let bodies = state.bodies.iter().zip(inertias.iter()).zip(loads.force.iter().zip(loads.torque.iter()));
    let mut written = 0;
    for (((b, inertia), (f, t)), out) in bodies.zip(q.as_mut_slice().chunks_exact_mut(6)) {
        let (f, t) = if gathered { (*f, *t) } else { (Vector3::zeros(), Vector3::zeros()) };
        let force = gravity * inertia.mass + f;
        let torque = t - b.omega.cross(&(inertia.inertia * b.omega));
        for (o, x) in out.iter_mut().zip(force.iter().chain(torque.iter())) {
            *o = *x;
        }
        written += 6;
    }
    if let Some(rest) = q.as_mut_slice().get_mut(written..) {
        rest.fill(0.0);
    }
}

/// Kinetic, gravitational and elastic energy at `state`.
pub(crate) fn energy<const NB: usize>(
    inertias: &[BodyInertia; NB],
    gravity: &Vector3<f64>,
    springs: &[SpringDamper],
    state: &SystemState<NB>,
) -> Energy {
    let mut e = Energy { kinetic: 0.0, gravity: 0.0, elastic: 0.0 };
    for (b, inertia) in state.bodies.iter().zip(inertias.iter()) {
        e.kinetic += 0.5 * (inertia.mass * b.rdot.norm_squared() + b.omega.dot(&(inertia.inertia * b.omega)));
        e.gravity -= inertia.mass * gravity.dot(&b.r);
    }
    for s in springs {
        let (xa, _, _) = point_motion(state, &s.a);
        let (xb, _, _) = point_motion(state, &s.b);
        let stretch = (xb - xa).norm() - s.rest_length;
        e.elastic += 0.5 * s.stiffness * stretch * stretch;
    }
    e
}
