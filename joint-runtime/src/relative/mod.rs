//! The engine of `coordinates = relative`, every scene's default: a tree
//! of bodies in its joints' own freedoms.
//!
//! The lecture notes give every joint twice: in absolute coordinates (six per
//! body, the joint's rows as constraints: what [`Scene`](crate::Scene) and
//! [`AbsoluteSimulation`](crate::dynamics::AbsoluteSimulation) run on) and in relative
//! coordinates (body 2 relative to body 1). A scene that does not say
//! `#[scene(coordinates = absolute)]` gets a [`TreeScene`] impl instead of the
//! absolute ones (`coordinates = both`: both, from one declaration): its
//! joints as a spanning tree from the ground, each parametrised by its own
//! freedoms, and, where its joint points and axes are numbers, the
//! articulated-body algorithm written out for that tree
//! ([`TreeScene::forward_dynamics_into`]). The runtime here runs the
//! recursions on any tree (Featherstone's articulated-body algorithm for
//! forward dynamics, the recursive Newton–Euler algorithm for inverse
//! dynamics, the composite-rigid-body algorithm for the mass matrix), each
//! O(bodies) but the mass matrix.
//!
//! | joint | coordinates `q` | velocities `v` | the child's rotation relative to its parent |
//! |---|---|---|---|
//! | `revolute` | the angle θ | θ̇ | `R₀ · rot(h, θ)` |
//! | `spherical` | unit quaternion `[e0, e1, e2, e3]` | ω' of the child relative to the parent, child components | `q` |
//! | `translational` (prismatic) | the slide `d` along the axis | `ḋ` | `R₀` |
//! | `cylindrical` | the angle θ, then the slide `d` along the axis | θ̇, ḋ | `R₀ · rot(h, θ)` |
//! | `planar` | the point's `x`, `y` along the parent's in-plane axes `f`, `g`, then the angle θ | ẋ, ẏ, θ̇ | `R₀ · rot(h, θ)` |
//! | `universal` | the angles θ₁ about `s` (parent), θ₂ about `h` (child) | θ̇₁, θ̇₂ | `rot(s, θ₁) · R₀ · rot(h, θ₂)` |
//! | `fixed` | none | none | `R₀`, as `translational`'s |
//! | free (a floating body) | the child's joint point from the parent's, parent components, then a unit quaternion | that point's velocity relative to the parent in the child's components, then ω' | the quaternion |
//!
//! `R₀` is the shortest rotation that takes the child's axis `h` (`axis2`) onto
//! the parent's (`axis1`): θ = 0 where the two bodies' frames differ by that
//! rotation alone (with `axis1 = axis2`, where the frames are parallel). A
//! prismatic joint's `R₀` takes the child's axes `(h, k)` onto the parent's
//! `(a, g)` (the catalogue's second axes, across the first), and `d = 0`
//! where its two joint points coincide. A universal joint's `R₀` is the
//! shortest rotation that takes `h` across `s` (the identity when the two are
//! already perpendicular in the bodies' frames). The joint points (a prismatic
//! joint's line) hold at every `q`, so a tree state is assembled by
//! construction; [`Tree::system_state`] and [`Tree::tree_state`] convert to
//! and from the absolute [`SystemState`](crate::SystemState).
//!
//! A joint outside the tree (one that closes a loop, or of a kind without a
//! tree parametrisation between two bodies the tree moves) is a closure: its
//! rows stay constraints, composed with the tree's kinematics and
//! differentiated by the derive in the tree's coordinates
//! ([`TreeScene::closure_rows`]: `Φ(q, t)`, `J`, `γ`, `Φ_t`); rows the tree
//! keeps by construction (a planar loop's out-of-plane rows) are left out at
//! compile time. [`TreeSimulation`], the engine the one
//! [`Simulation`](crate::dynamics::Simulation) makes for a relative scene,
//! then solves `M v̇ + b = τ + Jᵀλ`,
//! `J v̇ = γ` (redundant closure rows dropped by a pivoted factorisation, as
//! the absolute `Simulation` drops redundant joint rows) and projects each
//! step back onto `Φ = 0`, `J v + Φ_t = 0`. Spring-dampers act through
//! [`TreeSimulation::with_springs`] and the absolute path's user loads
//! through [`TreeSimulation::with_loads`] (the same closure drives both
//! coordinate choices), as joint forces `Jᵀ f`. A tree joint's points and axes
//! given as numbers are folded into the closure rows; given as fields they
//! are read from the tree's [`TreeGeometry`]. A body that no path of tree
//! joints joins to the ground floats, as it does in absolute coordinates: the
//! derive gives it a free joint from the ground (its centre of mass from the
//! origin, then its rotation), and the joints that reach it are closures.
//!
//! [`Tree::new`] checks the tree once (parents before children, unit axes,
//! rest rotations, physical inertias). The recursions, here and as the derive
//! writes them, work in link frames: each body's axes with the origin at its
//! inbound joint point, so that a joint's motion subspace is constant
//! coordinate axes (but a universal or planar joint's, which turns with its
//! angle) and the offset between two joint points a constant of the parent;
//! gravity enters as the ground's acceleration. A step holds the joint forces
//! constant over it; with loops, each stage factorises `M` (a plain
//! Cholesky) and `J M⁻¹ Jᵀ` (pivoted), the first stage's pivots kept for the
//! step, and the projection closes `q` by simplified Newton on one factor,
//! then `v` with it. User loads and springs are wrenches on the bodies,
//! carried to the root as joint forces in one pass over the bodies; MJCF's
//! gravity compensation is the joint forces of point masses `c m` at rest,
//! their derivatives in closed form (`recursion.rs`). The derivatives'
//! recursion and the tangent maps index only through `get`, and gravity
//! compensation's derivative is inlined (out of line it kept a landing pad),
//! so `no-panic-check` proves the derivatives and the step Jacobians free of
//! panics.
//!
//! ```
//! use joint_runtime::Scene;
//! use joint_runtime::relative::TreeSimulation;
//!
//! /// A double pendulum on revolute joints about `y`.
//! #[derive(Scene)]
//! #[scene(gravity = [0, 0, -9.81])]
//! #[body(upper, mass = 1.0, inertia = [0.001, 0.0833, 0.0833])]
//! #[body(lower, mass = 1.0, inertia = [0.001, 0.0833, 0.0833])]
//! #[joint(shoulder = revolute(ground, upper), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0, 0, 0], rho2 = [-0.5, 0, 0])]
//! #[joint(elbow = revolute(upper, lower), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0.5, 0, 0], rho2 = [-0.5, 0, 0])]
//! struct Pendulum;
//!
//! let mut sim = TreeSimulation::new(&Pendulum).unwrap();
//! let mut state: PendulumTreeState = sim.tree().zero_state();
//! let start = sim.tree().energy(&state).total();
//! for _ in 0..1000 {
//!     sim.step(&mut state, 1e-3).unwrap();
//! }
//! // The arms fell from the horizontal: the angle about y grew, energy stayed.
//! assert!(state.q[0] > 0.5);
//! assert!((sim.tree().energy(&state).total() - start).abs() < 1e-9);
//! // The bodies' poses, for recording or comparing with the absolute scene.
//! let system = sim.tree().system_state(&state);
//! assert!((system.bodies[0].point(&[-0.5, 0.0, 0.0].into())).norm() < 1e-15);
//! ```

mod constrained;
mod derivatives;
mod dynamics;
mod factor;
mod impact;
mod implicit;
mod implicit_rules;
mod kinematics;
#[cfg(feature = "alloc")]
mod linear;
mod projected;
mod proximal;
mod radau;
mod reactions;
mod recursion;
mod simulation;
mod soft;
mod spatial;
mod step_jacobian;
mod tangent;
mod topology;

pub use constrained::{ActiveRows, ConstrainedDerivatives};
pub use derivatives::{ForwardDerivatives, InverseDerivatives, SecondDerivatives};
pub use dynamics::TreeEnergy;
pub use impact::ImpulseDerivatives;
pub use implicit::ForceGains;
pub use proximal::Proximal;
pub use simulation::{DIVERGED, TreeSimulation};
pub use soft::{InverseWeight, SoftEquality};
pub use step_jacobian::{StepJacobian, StepWork};
pub use topology::{JointLayout, Tree, TreeError};

use nalgebra::{SMatrix, SVector, Vector3};

use crate::{BodyInertia, RowBlock};

/// How a tree joint lets its child move relative to its parent.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum TreeJointKind {
    /// One angle about the joint's axis (1 coordinate, 1 velocity).
    Revolute,
    /// A unit quaternion (4 coordinates, 3 velocities).
    Spherical,
    /// A slide along the joint's axis, rotation locked (the catalogue's
    /// `translational`; 1 coordinate, 1 velocity).
    Prismatic,
    /// An angle about the joint's axis, then a slide along it (the
    /// catalogue's `cylindrical`; 2 coordinates, 2 velocities).
    Cylindrical,
    /// The child's joint point moving in the parent's plane and the child
    /// turning about its normal (the catalogue's `planar`; 3 coordinates:
    /// `x`, `y` along the parent's in-plane axes, then the angle).
    Planar,
    /// Two angles: about the parent's axis, then about the child's (the
    /// catalogue's `universal`, the notes' two-angle joint; 2 coordinates,
    /// 2 velocities).
    Universal,
    /// Welded: no freedom, the relative rotation locked as a prismatic
    /// joint's (the catalogue's `fixed`; URDF's fixed links).
    Fixed,
    /// A floating body (a free joint; 7 coordinates, 6 velocities): the
    /// child's joint point from the parent's in the parent's components,
    /// then a unit quaternion; velocities that point's velocity relative to
    /// the parent in the child's components, then ω' (Pinocchio's
    /// free-flyer order). The derive gives one to every body that no path
    /// of tree joints joins to the ground.
    Free,
}

impl TreeJointKind {
    /// Its number of coordinates.
    pub const fn coordinates(self) -> usize {
        match self {
            TreeJointKind::Fixed => 0,
            TreeJointKind::Revolute | TreeJointKind::Prismatic => 1,
            TreeJointKind::Universal | TreeJointKind::Cylindrical => 2,
            TreeJointKind::Planar => 3,
            TreeJointKind::Spherical => 4,
            TreeJointKind::Free => 7,
        }
    }

    /// Its number of velocities (freedoms).
    pub const fn freedoms(self) -> usize {
        match self {
            TreeJointKind::Fixed => 0,
            TreeJointKind::Revolute | TreeJointKind::Prismatic => 1,
            TreeJointKind::Universal | TreeJointKind::Cylindrical => 2,
            TreeJointKind::Spherical | TreeJointKind::Planar => 3,
            TreeJointKind::Free => 6,
        }
    }

    /// Where its unit quaternion starts among its coordinates (spherical,
    /// free), `None` for a joint without one.
    pub const fn quaternion(self) -> Option<usize> {
        match self {
            TreeJointKind::Spherical => Some(0),
            TreeJointKind::Free => Some(3),
            _ => None,
        }
    }
}

/// One joint of a tree: it moves `child` relative to `parent` (`None`: the ground).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct TreeJoint {
    /// The joint's name in the scene.
    pub name: &'static str,
    /// Its freedoms.
    pub kind: TreeJointKind,
    /// The parent body's index in the scene, `None` for the ground.
    pub parent: Option<usize>,
    /// The child body's index in the scene.
    pub child: usize,
    /// The joint point in the parent's frame (inertial components on the ground).
    pub rho_parent: Vector3<f64>,
    /// The joint point in the child's frame.
    pub rho_child: Vector3<f64>,
    /// The joint's axis in the parent's frame (`revolute`, `prismatic`, `cylindrical`; `s`
    /// of a `universal` joint; unused otherwise).
    pub axis_parent: Vector3<f64>,
    /// The joint's axis in the child's frame (`revolute`, `prismatic`, `cylindrical`; `h`
    /// of a `universal` joint; unused otherwise).
    pub axis_child: Vector3<f64>,
    /// `prismatic`, `fixed`: a second axis of the parent, across the first (the
    /// catalogue's `g`), that the child's [`lock_child`](Self::lock_child)
    /// stays on: with the axes, it fixes the relative rotation. `planar`: the
    /// parent's first in-plane axis (the catalogue's `f`; zero: the first of
    /// [`perpendicular_pair`](crate::perpendicular_pair) of the normal).
    /// Unused otherwise.
    pub lock_parent: Vector3<f64>,
    /// `prismatic`, `fixed`: the child's second axis (the catalogue's `k`).
    pub lock_child: Vector3<f64>,
    /// Inertia added to each of the joint's freedoms (kg m², kg for a
    /// slide): a motor's rotor seen through its gear, MuJoCo's `armature`.
    /// It adds to the mass matrix's diagonal, so the articulated-body
    /// algorithm, Newton–Euler and the mass matrix all carry it.
    pub armature: f64,
    /// Viscous damping of each of the joint's freedoms: the joint force
    /// `−damping · v` adds to the applied one (N m s/rad, N s/m).
    pub damping: f64,
    /// A revolute or prismatic joint's spring (MuJoCo's `stiffness`): the
    /// joint force `−stiffness · (q − spring_rest)` adds to the applied one
    /// (N m/rad, N/m); zero on every other kind (`Tree::new` refuses one).
    pub stiffness: f64,
    /// The coordinate where the spring's force is zero (MuJoCo's
    /// `springref`, in the tree's coordinate).
    pub spring_rest: f64,
}

/// A scene in relative coordinates, generated by `#[derive(Scene)]` unless
/// the scene says `#[scene(coordinates = absolute)]`: a spanning tree of its joints from the
/// ground (`NB` bodies, `NQ` coordinates, `NV` freedoms) and `NC` closure
/// rows: the rows of the joints outside the tree (each closes a loop) in the
/// tree's coordinates.
#[diagnostic::on_unimplemented(
    message = "`{Self}` is not derived in relative coordinates",
    label = "declared `coordinates = absolute`",
    note = "drop `coordinates = absolute` from `{Self}`'s `#[scene(..)]` (relative is the default), or write `coordinates = both`"
)]
pub trait TreeScene<const NB: usize, const NQ: usize, const NV: usize, const NC: usize = 0> {
    /// The joints outside the tree, each with its block of the closure rows,
    /// then the contacts' blocks (`#[contact(..)]`).
    const CLOSURES: &'static [RowBlock] = &[];
    /// The scene's contacts (`#[contact(..)]`): each one's block among
    /// [`CLOSURES`](Self::CLOSURES), kind and axes.
    const CONTACTS: &'static [Contact] = &[];
    /// A robot file's equalities as MuJoCo softens them (an MJCF file read
    /// without `equality = hard`): each one's block among
    /// [`CLOSURES`](Self::CLOSURES), `solref`, `solimp` and whose inverse
    /// weights scale it. Their rows are springs in the constraint space
    /// (MuJoCo's `(J M⁻¹ Jᵀ + R) f = a_ref − J q̈₀`), never projected.
    const SOFT: &'static [SoftEquality] = &[];
    /// Whether every closure row is linear in the coordinates (a constant
    /// `J`, no `γ`, no `Φ_t`: a file's couplings), so that the constrained
    /// accelerations' derivatives follow from the tree's.
    const LINEAR_CLOSURES: bool = false;
    /// Whether the derive wrote the dynamics' first derivatives out
    /// ([`inverse_dynamics_derivatives_into`](Self::inverse_dynamics_derivatives_into));
    /// where it did not, the runtime's recursion gives the same numbers.
    const DERIVATIVES: bool = false;
    /// A robot file's state layout, so that generic code reaches it: the
    /// scene's `MUJOCO` (an MJCF file) or `PINOCCHIO` (a URDF). `None` for
    /// a scene of attributes, or one that adds moving joints to its file's
    /// (freedoms no library vector holds).
    ///
    /// ```
    /// use joint_runtime::relative::TreeScene;
    ///
    /// /// The library's `nv` of any robot read from its file.
    /// fn library_nv<S: TreeScene<NB, NQ, NV, NC>, const NB: usize, const NQ: usize, const NV: usize, const NC: usize>(
    ///     _: &S,
    /// ) -> Option<usize> {
    ///     S::STATE_LAYOUT.map(|layout| layout.nv())
    /// }
    /// # #[cfg(feature = "mjcf")] {
    /// # use joint_runtime::Scene;
    /// # #[derive(Scene)]
    /// # #[scene(mjcf = "../tests/data/robots/solo12_floating.xml")]
    /// # struct Solo;
    /// # assert_eq!(library_nv(&Solo), Some(18));
    /// # }
    /// ```
    const STATE_LAYOUT: Option<crate::robot::StateLayout<NQ, NV>> = None;
    /// A robot file's link frames (the scene's `LINKS`); none without a file.
    const LINKS: &'static [crate::robot::LinkFrame] = &[];
    /// A robot file's joint limits (the scene's `LIMITS`); none without a file.
    const LIMITS: &'static [crate::robot::JointLimits] = &[];
    /// What a robot file asks of the step (the scene's `OPTIONS`); `None`s
    /// without a file.
    const OPTIONS: crate::robot::FileOptions = crate::robot::FileOptions { timestep: None, integrator: None };
    /// The tree joints, parents before children (joint `k` is the `k`-th
    /// joint reached from the ground).
    fn tree_joints(&self) -> [TreeJoint; NB];
    /// The bodies' mass properties, in the scene's body order.
    fn tree_inertias(&self) -> [BodyInertia; NB];
    /// Gravity, inertial components.
    fn tree_gravity(&self) -> Vector3<f64>;
    /// Each body's gravity compensation, in the scene's body order (MuJoCo's
    /// `gravcomp`): the fraction of its weight an upward force at its
    /// centre of mass holds. None unless the scene's file says so.
    fn tree_compensation(&self) -> [f64; NB] {
        [0.0; NB]
    }
    /// The articulated-body algorithm written out for this tree by the
    /// derive (every axis and point that is a number folded with the
    /// structural zeros; the others read from `geometry`, the tree's
    /// [`Tree::geometry`]): `v̇` into `out` and `true`, or `false` when not
    /// written (a tree too large, or a field-valued one past the straight
    /// line), and the runtime's recursion [`Tree::forward_dynamics`] runs.
    #[inline]
    fn forward_dynamics_into(
        &self,
        geometry: &TreeGeometry<NB>,
        q: &[f64; NQ],
        v: &[f64; NV],
        tau: &[f64; NV],
        out: &mut [f64; NV],
    ) -> bool {
        let _ = (geometry, q, v, tau, out);
        false
    }
    /// The recursive Newton–Euler algorithm written out by the derive (for
    /// trees it writes the forward dynamics of in one straight line):
    /// `τ(q, v, v̇)` into `out` and `true`, or `false` ([`Tree::inverse_dynamics`]).
    #[inline]
    fn inverse_dynamics_into(
        &self,
        geometry: &TreeGeometry<NB>,
        q: &[f64; NQ],
        v: &[f64; NV],
        vdot: &[f64; NV],
        out: &mut [f64; NV],
    ) -> bool {
        let _ = (geometry, q, v, vdot, out);
        false
    }
    /// The composite-rigid-body algorithm written out by the derive: `M(q)`
    /// into `out` (symmetric, so rows or columns alike) and `true`, or
    /// `false` ([`Tree::mass_matrix_into`]).
    #[inline]
    fn mass_matrix_into(&self, geometry: &TreeGeometry<NB>, q: &[f64; NQ], out: &mut [[f64; NV]; NV]) -> bool {
        let _ = (geometry, q, out);
        false
    }
    /// The inverse dynamics' first derivatives written out by the derive
    /// (`#[scene(second_order)]`, for trees whose derivatives fit its
    /// straight line): `τ`, `∂τ/∂q` (tangent columns) and `∂τ/∂v` into
    /// `out` (its `d_a` untouched) and `true`, or `false` when not written.
    #[inline]
    fn inverse_dynamics_derivatives_into(
        &self,
        geometry: &TreeGeometry<NB>,
        q: &[f64; NQ],
        v: &[f64; NV],
        vdot: &[f64; NV],
        out: &mut InverseDerivatives<NV>,
    ) -> bool {
        let _ = (geometry, q, v, vdot, out);
        false
    }
    /// The inverse dynamics' second derivatives contracted with `lambda`,
    /// written out by the derive (`#[scene(second_order)]`, trees whose
    /// straight line fits its limit): into `out` and `true`, or `false`.
    #[inline]
    fn inverse_dynamics_second_derivatives_into(
        &self,
        geometry: &TreeGeometry<NB>,
        q: &[f64; NQ],
        v: &[f64; NV],
        vdot: &[f64; NV],
        lambda: &[f64; NV],
        out: &mut SecondDerivatives<NV>,
    ) -> bool {
        let _ = (geometry, q, v, vdot, lambda, out);
        false
    }
    /// The closure rows at `state`, derived by the engine from the closing
    /// joints' rows composed with the tree's kinematics (rows that the tree
    /// keeps by construction, such as a planar loop's out-of-plane rows,
    /// left out at compile time). Nothing for a tree without loops.
    /// `geometry` is the tree's ([`Tree::geometry`]), read where a tree
    /// joint's points or axes are fields.
    #[inline]
    fn closure_rows(&self, state: &TreeState<NQ, NV>, geometry: &TreeGeometry<NB>) -> ClosureRows<NC, NV> {
        let _ = (state, geometry);
        ClosureRows::zeros()
    }
    /// Each block of [`CLOSURES`](Self::CLOSURES)'s two bodies, whose
    /// columns [`closure_body_rows`](Self::closure_body_rows) holds: a
    /// loop's joint's bodies, a contact's held body then the one holding it
    /// (`None`: the ground); a coupling acts on joints and has neither.
    const CLOSURE_ENDS: &'static [[Option<usize>; 2]] = &[];
    /// The closure rows on their bodies at `state` (the tree's state as
    /// bodies, [`Tree::system_state`]), derived by the engine from the same
    /// rows as [`closure_rows`](Self::closure_rows): row `r`'s first six
    /// entries are `∂Φ̇_r/∂(ṙ, ω')` of its block's first body in
    /// [`CLOSURE_ENDS`](Self::CLOSURE_ENDS) (`ṙ` the centre's velocity in
    /// the world's components, `ω'` in the body's), the next six its
    /// second's; zeros for the ground and a coupling. So a row's force
    /// `λ_r` loads the bodies with `J_bᵀ λ`, which is what a loop's
    /// reactions need ([`TreeSimulation::closure_reactions`]).
    #[inline]
    fn closure_body_rows(&self, state: &crate::SystemState<NB>) -> SMatrix<f64, NC, 12> {
        let _ = state;
        SMatrix::zeros()
    }
    /// The closure rows' second-order terms at `state`, derived by the
    /// engine: `K = ∂(Jᵀλ)/∂q`, `∂(J u)/∂q`, `∂γ/∂q`, `∂γ/∂v`, `∂Φ_t/∂q`,
    /// every `∂/∂q` in tangent columns; what the constrained dynamics'
    /// derivatives take. `None` where the derive did not write them (no
    /// closures, or past its operation limit).
    #[inline]
    fn closure_second_order(
        &self,
        state: &TreeState<NQ, NV>,
        geometry: &TreeGeometry<NB>,
        lambda: &SVector<f64, NC>,
        u: &SVector<f64, NV>,
    ) -> Option<crate::SecondOrder<f64, NC, NV>> {
        let _ = (state, geometry, lambda, u);
        None
    }
}

/// What a contact holds (`#[contact(NAME = point(..) | frame(..))]`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ContactKind {
    /// A point: 3 rows, a force.
    Point,
    /// A frame: 6 rows (linear, then angular), a wrench about its point.
    Frame,
}

/// In whose axes a contact's rows and force are given.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ContactAxes {
    /// The world's (Pinocchio's `LOCAL_WORLD_ALIGNED`), the default.
    World,
    /// The contact frame's own (`LOCAL`).
    Local,
}

/// A contact of a scene (`#[contact(..)]`): rows on the tree at the
/// velocity level (no position), switched on and off per call with
/// [`ActiveRows`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Contact {
    /// Its block among the scene's `CLOSURES`.
    pub block: usize,
    /// Point or frame.
    pub kind: ContactKind,
    /// The rows' axes.
    pub axes: ContactAxes,
    /// The body held (its index in the scene).
    pub body: usize,
    /// The body that holds it, `None` for the ground.
    pub other: Option<usize>,
}

/// Each tree joint's geometry, in tree order, as [`Tree::new`] prepared it
/// from [`TreeScene::tree_joints`]: what generated closure rows read where a
/// joint's points or axes are fields (numbers are folded into the code).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TreeGeometry<const NB: usize> {
    /// The rest rotation `R₀` (revolute; the identity otherwise), by columns.
    pub rest: [[Vector3<f64>; 3]; NB],
    /// The child's unit axis `h` (revolute, prismatic, universal; zero otherwise).
    pub axis: [Vector3<f64>; NB],
    /// The parent's unit axis (revolute, prismatic, universal; zero otherwise).
    pub axis_parent: [Vector3<f64>; NB],
    /// The joint point in the parent's frame.
    pub rho_parent: [Vector3<f64>; NB],
    /// The joint point in the child's frame.
    pub rho_child: [Vector3<f64>; NB],
    /// Planar: the parent's unit in-plane axes `f`, `g` (zero otherwise).
    pub plane: [[Vector3<f64>; 2]; NB],
}

/// The closure rows of a relative-coordinate scene at one state: `Φ(q, t)`,
/// `Φ̇ = J v + Φ_t` and `J v̇ = γ`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClosureRows<const NC: usize, const NV: usize> {
    /// `Φ`.
    pub phi: SVector<f64, NC>,
    /// `J = ∂Φ̇/∂v`.
    pub jacobian: SMatrix<f64, NC, NV>,
    /// `γ = −(dΦ̇/dt)` with `v` held.
    pub gamma: SVector<f64, NC>,
    /// `Φ_t`, the rows' rate with the coordinates held (drivers).
    pub phi_t: SVector<f64, NC>,
}

impl<const NC: usize, const NV: usize> ClosureRows<NC, NV> {
    /// All zero.
    pub fn zeros() -> Self {
        ClosureRows {
            phi: SVector::zeros(),
            jacobian: SMatrix::zeros(),
            gamma: SVector::zeros(),
            phi_t: SVector::zeros(),
        }
    }
}

/// The state of a tree: its joints' coordinates and velocities, and the time.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct TreeState<const NQ: usize, const NV: usize> {
    /// Coordinates, joint by joint in the tree's order.
    pub q: SVector<f64, NQ>,
    /// Velocities, joint by joint in the tree's order.
    pub v: SVector<f64, NV>,
    /// Time.
    pub t: f64,
}
