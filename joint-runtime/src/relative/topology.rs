//! The tree checked and prepared once: parents before children, sizes, axes,
//! rest rotations, inertias; the conversions to and from absolute states.

use core::fmt;

use nalgebra::{Matrix3, Matrix6, SVector, Unit, UnitQuaternion, Vector3, Vector4};

use super::factor::FreedomTree;
use super::kinematics::Subspace;
use super::spatial::{link_inertia, split};
use super::{TreeGeometry, TreeJoint, TreeJointKind, TreeScene, TreeState};
use crate::{BodyInertia, OmegaBody, SystemState};

/// Why a tree or a state was refused.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TreeError {
    /// The joints' coordinates or freedoms do not add up to the tree's `NQ`, `NV`.
    Sizes {
        /// The joints' coordinates.
        coordinates: usize,
        /// The joints' freedoms.
        freedoms: usize,
    },
    /// A joint whose parent no earlier joint reached, or whose child an
    /// earlier joint already moves (a loop), or a body index out of range.
    Order {
        /// The joint's name.
        joint: &'static str,
    },
    /// A revolute joint's axis is zero or not finite.
    Axis {
        /// The joint's name.
        joint: &'static str,
    },
    /// A body's mass is not positive, or its inertia not symmetric positive
    /// definite with principal moments obeying the triangle inequality.
    Inertia {
        /// The body's index in the scene.
        body: usize,
    },
    /// A joint's articulated inertia `Sᵀ Iᴬ S` is not positive definite.
    Singular {
        /// The joint's name.
        joint: &'static str,
    },
    /// An absolute state that the tree's joints do not hold: a joint's points
    /// apart, or its bodies turned in a way it does not allow.
    NotOnJoint {
        /// The joint's name.
        joint: &'static str,
        /// The misfit: the points' distance plus the disallowed rotation
        /// (radians) or velocity.
        misfit: f64,
    },
    /// A state or a torque that is not finite.
    NonFinite,
    /// A joint's spring is negative or not finite, or on a joint with other
    /// than one freedom (revolute and prismatic joints carry springs).
    Spring {
        /// The joint's name.
        joint: &'static str,
    },
    /// A step left the finite range: a number of its state past
    /// [`DIVERGED`](crate::relative::DIVERGED) or not finite, or its stages'
    /// dynamics failing where its start's did not. The step is too long for
    /// the dynamics' fastest motion (stiff gains, springs or damping):
    /// shorter steps, or `implicit_step_with`.
    Diverged {
        /// The time the step reached (its end, or the failing stage's).
        t: f64,
    },
    /// A loop that the position projection did not close: the closure's
    /// largest row after the Newton iterations.
    Closure {
        /// The name of the joint closing the loop.
        joint: &'static str,
        /// Its largest row's magnitude.
        misfit: f64,
    },
    /// A step's start whose loop is open by more than the projection's
    /// round-off floor: the step would close it unasked. Close it first
    /// ([`TreeSimulation::assemble`](super::TreeSimulation::assemble)).
    NotAssembled {
        /// The name of the joint closing the loop.
        joint: &'static str,
        /// Its largest row's magnitude.
        misfit: f64,
    },
    /// A spring-damper whose end names a body the scene does not have.
    Attachment {
        /// The spring's index.
        spring: usize,
    },
    /// An option out of range (`tolerance`, `t_end` of
    /// [`TreeSimulation::integrate`](super::TreeSimulation::integrate)).
    BadOption {
        /// The option's name.
        name: &'static str,
    },
    /// Something the relative-coordinate engine does not offer (an
    /// integrator, an adaptive method), with where it is offered.
    NotOffered {
        /// What was asked for.
        what: &'static str,
        /// What to use instead.
        instead: &'static str,
    },
    /// No exact derivatives for this: the inverse dynamics' second
    /// derivatives of a scene that did not ask for them
    /// (`#[scene(second_order)]`) or whose tree is past the derive's
    /// straight line, the first derivatives of a tree whose closures' second-order
    /// terms are past the derive's operation limit, or the linearly implicit
    /// step of a tree whose loops are not a file's couplings.
    NotDerived,
    /// A step's exact Jacobian asked of a tree with springs or user loads:
    /// it covers the tree's own dynamics (gravity, armature, damping);
    /// `TreeSimulation::transition` differences such a step.
    Loaded,
    /// The implicit integrator's Newton iteration did not converge within
    /// the options' `newton_max_iterations` (or its correction stopped
    /// being finite): take a shorter step.
    NotConverged {
        /// Iterations taken.
        iterations: usize,
        /// The last correction's norm, `‖Δw‖₂`.
        correction: f64,
    },
    /// The error-controlled step fell below round-off at `t`.
    StepTooSmall {
        /// The time reached.
        t: f64,
        /// The step that was too small.
        step: f64,
    },
}

impl fmt::Display for TreeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            TreeError::Sizes { coordinates, freedoms } => write!(
                f,
                "the tree's joints have {coordinates} coordinates and {freedoms} freedoms, not the sizes of its state"
            ),
            TreeError::Order { joint } => write!(
                f,
                "joint `{joint}` is out of tree order: its parent is not reached before it, or its child already has \
                 a parent"
            ),
            TreeError::Axis { joint } => write!(f, "joint `{joint}` has a zero or non-finite axis"),
            TreeError::Inertia { body } => write!(
                f,
                "body {body} has a non-positive mass or an inertia that is not positive definite with moments obeying \
                 the triangle inequality"
            ),
            TreeError::Singular { joint } => write!(f, "joint `{joint}`'s articulated inertia is singular"),
            TreeError::NotOnJoint { joint, misfit } => {
                write!(f, "the state does not hold joint `{joint}` (misfit {misfit:e})")
            }
            TreeError::NonFinite => f.write_str("a state or torque that is not finite"),
            TreeError::Spring { joint } => write!(
                f,
                "joint `{joint}`'s spring is negative or not finite, or on a joint without exactly one freedom \
                 (revolute and prismatic joints carry springs)"
            ),
            TreeError::Diverged { t } => write!(
                f,
                "the step diverged at t = {t} (a number past 1e10 or not finite): it is too long for the dynamics' \
                 stiffness (gains, springs, damping); take shorter steps or `implicit_step_with`"
            ),
            TreeError::Attachment { spring } => {
                write!(f, "spring {spring} is attached to a body the scene does not have")
            }
            TreeError::Closure { joint, misfit } => {
                write!(f, "the projection did not close the loop of joint `{joint}` (misfit {misfit:e})")
            }
            TreeError::BadOption { name } => write!(f, "option `{name}` is out of range"),
            TreeError::NotConverged { iterations, correction } => write!(
                f,
                "the implicit step's Newton iteration did not converge in {iterations} iterations (last correction \
                 {correction:.3e}): take a shorter step"
            ),
            TreeError::NotOffered { what, instead } => {
                write!(f, "the relative-coordinate engine does not offer {what}: {instead}")
            }
            TreeError::NotAssembled { joint, misfit } => write!(
                f,
                "the step's start has the loop of joint `{joint}` open by {misfit:e}: close it first \
                 (`TreeSimulation::assemble`)"
            ),
            TreeError::NotDerived => f.write_str(
                "no exact derivatives for this: second derivatives need `second_order` in the `#[scene(..)]` (trees \
                 past the derive's limit have none), closures past the derive's limit have no second-order terms, and \
                 the linearly implicit step takes a file's couplings as its only loops",
            ),
            TreeError::Loaded => f.write_str(
                "the step's exact Jacobian covers the tree's own dynamics; springs or user loads act on this one \
                 (`transition` differences its step)",
            ),
            TreeError::StepTooSmall { t, step } => {
                write!(f, "the error-controlled step fell to {step:e} at t = {t}: the motion is too fast to follow")
            }
        }
    }
}

impl core::error::Error for TreeError {}

/// Where one joint's numbers sit in a tree's `q` and `v`
/// ([`Tree::layout`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct JointLayout {
    /// The joint's name (a robot file's own).
    pub name: &'static str,
    /// Its kind.
    pub kind: TreeJointKind,
    /// Its first coordinate in `q`.
    pub q_at: usize,
    /// How many coordinates it has (a quaternion's four, a free joint's seven).
    pub nq: usize,
    /// Its first freedom in `v`.
    pub v_at: usize,
    /// How many freedoms it has.
    pub nv: usize,
}

/// A tree of `NB` bodies with `NQ` coordinates and `NV` freedoms, checked and
/// prepared for the recursions. Joint `k` moves body `joints()[k].child`.
#[derive(Clone, Debug)]
pub struct Tree<const NB: usize, const NQ: usize, const NV: usize> {
    pub(crate) joints: [TreeJoint; NB],
    /// The joint that moves joint `k`'s parent body.
    pub(crate) parent: [Option<usize>; NB],
    /// Revolute: the child axis `h`, unit.
    pub(crate) axis: [Vector3<f64>; NB],
    /// Revolute: `R₀`, the shortest rotation taking `h` onto the parent's
    /// axis; prismatic: the rotation taking `(h, k)` onto `(a, g)`.
    pub(crate) rest: [UnitQuaternion<f64>; NB],
    /// Revolute, prismatic, universal: the parent's unit axis `a` (`R₀ h`
    /// for the first two; the universal's `s`).
    pub(crate) slide: [Vector3<f64>; NB],
    /// The spatial inertia of joint `k`'s child about its joint point
    /// (its link frame's origin).
    pub(crate) inertia: [Matrix6<f64>; NB],
    /// The joint point from the parent's inbound joint point (the ground's
    /// origin for a root), parent components.
    pub(crate) offset: [Vector3<f64>; NB],
    pub(crate) mass: [BodyInertia; NB],
    /// Each joint's motion subspace, constant in its child's link frame.
    pub(crate) subspace: [Subspace; NB],
    pub(crate) q_at: [usize; NB],
    pub(crate) v_at: [usize; NB],
    /// The freedoms as a tree (what the mass matrix's factor walks).
    pub(crate) freedoms: FreedomTree<NV>,
    pub(crate) gravity: Vector3<f64>,
    /// Each body's gravity compensation (`TreeScene::tree_compensation`),
    /// in the scene's body order; `None` when every one is zero.
    pub(crate) compensation: Option<[f64; NB]>,
    /// The joints' geometry as the generated closure rows read it.
    pub(crate) geometry: TreeGeometry<NB>,
}

impl<const NB: usize, const NQ: usize, const NV: usize> Tree<NB, NQ, NV> {
    /// Each freedom's parent freedom (see `FreedomTree`); joints come
    /// parents first, so a parent's index is always the smaller.
    fn freedom_parents(&self) -> [Option<usize>; NV] {
        let freedoms = |k: usize| self.joints.get(k).map_or(0, |j| j.kind.freedoms());
        let last = |k: usize| self.v_at.get(k).map(|at| at + freedoms(k)).and_then(|end| end.checked_sub(1));
        let mut out = [None; NV];
        for k in 0..NB {
            let mut above = self.parent[k];
            while let Some(p) = above.filter(|&p| p < k && freedoms(p) == 0) {
                above = self.parent.get(p).copied().flatten();
            }
            let mut previous = above.and_then(last);
            for i in 0..freedoms(k) {
                let at = self.v_at[k] + i;
                if let Some(slot) = out.get_mut(at) {
                    *slot = previous;
                }
                previous = Some(at);
            }
        }
        out
    }

    /// The tree of a scene.
    pub fn of<S: TreeScene<NB, NQ, NV, NC>, const NC: usize>(scene: &S) -> Result<Self, TreeError> {
        let mut tree = Tree::new(scene.tree_joints(), scene.tree_inertias(), scene.tree_gravity())?;
        let compensation = scene.tree_compensation();
        if !compensation.iter().all(|c| c.is_finite()) {
            return Err(TreeError::NonFinite);
        }
        tree.compensation = compensation.iter().any(|&c| c != 0.0).then_some(compensation);
        Ok(tree)
    }

    /// Checks and prepares a tree: joints parents first, bodies' inertias in
    /// the scene's order.
    pub fn new(joints: [TreeJoint; NB], inertias: [BodyInertia; NB], gravity: Vector3<f64>) -> Result<Self, TreeError> {
        let mut tree = Tree {
            joints,
            parent: [None; NB],
            axis: [Vector3::zeros(); NB],
            rest: [UnitQuaternion::identity(); NB],
            slide: [Vector3::zeros(); NB],
            inertia: [Matrix6::zeros(); NB],
            offset: [Vector3::zeros(); NB],
            mass: inertias,
            subspace: [Subspace::of(&[]); NB],
            q_at: [0; NB],
            v_at: [0; NB],
            freedoms: FreedomTree::new([None; NV]),
            gravity,
            compensation: None,
            geometry: TreeGeometry {
                rest: [[Vector3::zeros(); 3]; NB],
                axis: [Vector3::zeros(); NB],
                axis_parent: [Vector3::zeros(); NB],
                rho_parent: [Vector3::zeros(); NB],
                rho_child: [Vector3::zeros(); NB],
                plane: [[Vector3::zeros(); 2]; NB],
            },
        };
        let mut moved_by: [Option<usize>; NB] = [None; NB];
        let (mut nq, mut nv) = (0, 0);
        for (k, j) in joints.iter().enumerate() {
            let order = TreeError::Order { joint: j.name };
            let slot = moved_by.get_mut(j.child).ok_or(order)?;
            if slot.is_some() || j.parent == Some(j.child) {
                return Err(order);
            }
            *slot = Some(k);
            tree.parent[k] = match j.parent {
                None => None,
                Some(b) => Some(moved_by.get(b).copied().flatten().ok_or(order)?),
            };
            let inbound = tree.parent[k].map_or_else(Vector3::zeros, |p| joints[p].rho_child);
            tree.offset[k] = j.rho_parent - inbound;
            let b = inertias[j.child];
            if !b.is_physical() {
                return Err(TreeError::Inertia { body: j.child });
            }
            tree.inertia[k] = link_inertia(b.mass, &b.inertia, &(-j.rho_child));
            if !matches!(j.kind, TreeJointKind::Spherical | TreeJointKind::Free) {
                let axis_error = TreeError::Axis { joint: j.name };
                let h = Unit::try_new(j.axis_child, 1e-300).ok_or(axis_error)?;
                let a = Unit::try_new(j.axis_parent, 1e-300).ok_or(axis_error)?;
                if !h.iter().chain(a.iter()).all(|x| x.is_finite()) {
                    return Err(axis_error);
                }
                tree.axis[k] = h.into_inner();
                tree.rest[k] = match j.kind {
                    TreeJointKind::Prismatic | TreeJointKind::Fixed => {
                        locked_rotation(&h, &j.lock_child, &a, &j.lock_parent).ok_or(axis_error)?
                    }
                    TreeJointKind::Universal => rest_rotation(&h, &across(&h, &a)),
                    _ => rest_rotation(&h, &a),
                };
                tree.slide[k] = a.into_inner();
                if j.kind == TreeJointKind::Planar {
                    tree.geometry.plane[k] = in_plane(&a, &j.lock_parent);
                }
            }
            let one_freedom = matches!(j.kind, TreeJointKind::Revolute | TreeJointKind::Prismatic);
            let spring = j.stiffness >= 0.0 && j.stiffness.is_finite() && j.spring_rest.is_finite();
            if !(spring && (one_freedom || j.stiffness == 0.0)) {
                return Err(TreeError::Spring { joint: j.name });
            }
            tree.subspace[k] = tree.make_subspace(k);
            let rest = tree.rest[k].to_rotation_matrix().into_inner();
            tree.geometry.rest[k] = [0, 1, 2].map(|c| rest.column(c).into_owned());
            tree.geometry.axis[k] = tree.axis[k];
            tree.geometry.axis_parent[k] = tree.slide[k];
            tree.geometry.rho_parent[k] = j.rho_parent;
            tree.geometry.rho_child[k] = j.rho_child;
            tree.q_at[k] = nq;
            tree.v_at[k] = nv;
            nq += j.kind.coordinates();
            nv += j.kind.freedoms();
        }
        if nq != NQ || nv != NV {
            return Err(TreeError::Sizes { coordinates: nq, freedoms: nv });
        }
        tree.freedoms = FreedomTree::new(tree.freedom_parents());
        Ok(tree)
    }

    /// The joints' geometry as prepared here (unit axes, rest rotations),
    /// which generated closure rows read where a tree joint's points or axes
    /// are fields.
    pub fn geometry(&self) -> &TreeGeometry<NB> {
        &self.geometry
    }

    /// The joints, in tree order.
    pub fn joints(&self) -> &[TreeJoint; NB] {
        &self.joints
    }

    /// Where each joint's numbers sit in `q` and `v`, in tree order: what
    /// Pinocchio calls `idx_q`, `nq`, `idx_v`, `nv` and MuJoCo
    /// `jnt_qposadr`, `jnt_dofadr`. A robot file's joints keep their names.
    ///
    /// ```
    /// use joint_runtime::Scene;
    /// use joint_runtime::relative::{TreeJointKind, TreeSimulation};
    ///
    /// /// An arm on a ball joint with a hand on a hinge.
    /// #[derive(Scene)]
    /// #[scene(gravity = [0, 0, -9.81])]
    /// #[body(arm, mass = 1.0, inertia = [0.08, 0.08, 0.01])]
    /// #[body(hand, mass = 0.2, inertia = [0.001, 0.001, 0.001])]
    /// #[joint(shoulder = spherical(ground, arm), rho1 = [0, 0, 0], rho2 = [0, 0, 0.5])]
    /// #[joint(wrist = revolute(arm, hand), axis1 = [1, 0, 0], axis2 = [1, 0, 0], rho1 = [0, 0, -0.5], rho2 = [0, 0, 0.1])]
    /// struct Arm;
    ///
    /// let sim = TreeSimulation::new(&Arm).unwrap();
    /// let wrist = sim.tree().joint_layout("wrist").unwrap();
    /// // After the ball joint's quaternion (four numbers) and its three freedoms:
    /// assert_eq!((wrist.kind, wrist.q_at, wrist.nq, wrist.v_at, wrist.nv), (TreeJointKind::Revolute, 4, 1, 3, 1));
    /// assert!(sim.tree().joint_layout("elbow").is_none());
    /// ```
    pub fn layout(&self) -> [JointLayout; NB] {
        core::array::from_fn(|k| {
            let (j, q_at, v_at) = (&self.joints[k], self.q_at[k], self.v_at[k]);
            JointLayout { name: j.name, kind: j.kind, q_at, nq: j.kind.coordinates(), v_at, nv: j.kind.freedoms() }
        })
    }

    /// The [`layout`](Self::layout) of the joint named `name`.
    pub fn joint_layout(&self, name: &str) -> Option<JointLayout> {
        self.layout().into_iter().find(|l| l.name == name)
    }

    /// Gravity, inertial components.
    pub fn gravity(&self) -> Vector3<f64> {
        self.gravity
    }

    /// Every angle zero, every quaternion `[1, 0, 0, 0]`, at rest, `t = 0`.
    pub fn zero_state(&self) -> TreeState<NQ, NV> {
        let mut q = SVector::<f64, NQ>::zeros();
        for (k, j) in self.joints.iter().enumerate() {
            if let Some(at) = j.kind.quaternion() {
                q[self.q_at[k] + at] = 1.0;
            }
        }
        TreeState { q, v: SVector::zeros(), t: 0.0 }
    }

    /// Each body's pose and velocity (forward kinematics): the absolute state.
    pub fn system_state(&self, state: &TreeState<NQ, NV>) -> SystemState<NB> {
        let kin = self.kinematics(&state.q, &state.v);
        let mut bodies = [OmegaBody::default(); NB];
        // Each link frame's orientation and origin (the joint point).
        let pose = self.link_poses(&state.q);
        for (k, &(a, o)) in pose.iter().enumerate() {
            // The centre of mass is −ρ from the joint point.
            let (w, v) = split(&kin.vel[k]);
            let rho = self.joints[k].rho_child;
            let r = o - a * rho;
            if let Some(body) = bodies.get_mut(self.joints[k].child) {
                *body = OmegaBody::from_rotation(r, &a, a * (v - w.cross(&rho)), w);
            }
        }
        SystemState { bodies, t: state.t }
    }

    /// The joints' coordinates and velocities of an absolute state (inverse
    /// kinematics of each joint from its bodies), refused when a joint's
    /// points are more than `tolerance` apart or its bodies turn or move in a
    /// way it does not allow by more than `tolerance`.
    pub fn tree_state(&self, system: &SystemState<NB>, tolerance: f64) -> Result<TreeState<NQ, NV>, TreeError> {
        let mut state = TreeState::<NQ, NV> { q: SVector::zeros(), v: SVector::zeros(), t: system.t };
        for (k, j) in self.joints.iter().enumerate() {
            let child = &system.bodies[j.child];
            let (a_p, r_p, w_p, rdot_p) = match j.parent {
                None => (UnitQuaternion::identity(), Vector3::zeros(), Vector3::zeros(), Vector3::zeros()),
                Some(b) => {
                    let p = &system.bodies[b];
                    (p.rotation(), p.r, p.omega, p.rdot)
                }
            };
            let a_c = child.rotation();
            let rel = a_p.inverse() * a_c;
            // The joint point seen from both bodies, and its two velocities.
            let gap = (r_p + a_p * j.rho_parent) - child.point(&j.rho_child);
            let w_p_inertial = a_p * w_p;
            let slip = (rdot_p + w_p_inertial.cross(&(a_p * j.rho_parent)))
                - (child.rdot + (a_c * child.omega).cross(&(a_c * j.rho_child)));
            let w_rel = child.omega - rel.inverse() * w_p;
            let (qa, va) = (self.q_at[k], self.v_at[k]);
            // A prismatic joint's slide is its first coordinate, a cylindrical one's its second.
            let slid = match j.kind {
                TreeJointKind::Prismatic => Some((qa, va)),
                TreeJointKind::Cylindrical => Some((qa + 1, va + 1)),
                _ => None,
            };
            // The child's point from the parent's and its rate, parent
            // components (d/dt Aᵀx = Aᵀ(ẋ − ω × x)): a free or planar joint's
            // coordinates.
            let (x, x_rate) = (a_p.inverse() * -gap, a_p.inverse() * (-slip + w_p_inertial.cross(&gap)));
            let turn_misfit = match j.kind {
                TreeJointKind::Revolute | TreeJointKind::Cylindrical => {
                    self.angle(k, &rel, &w_rel, (qa, va), &mut state)
                }
                TreeJointKind::Planar => {
                    let [f, g] = self.geometry.plane[k];
                    state.q[qa] = f.dot(&x);
                    state.q[qa + 1] = g.dot(&x);
                    state.v[va] = f.dot(&x_rate);
                    state.v[va + 1] = g.dot(&x_rate);
                    // Off the plane: the point's normal offset and rate.
                    let off = self.slide[k].dot(&x).abs() + self.slide[k].dot(&x_rate).abs();
                    off + self.angle(k, &rel, &w_rel, (qa + 2, va + 2), &mut state)
                }
                TreeJointKind::Spherical => {
                    let p = Vector4::new(rel.w, rel.i, rel.j, rel.k);
                    state.q.fixed_rows_mut::<4>(qa).copy_from(&p);
                    state.v.fixed_rows_mut::<3>(va).copy_from(&w_rel);
                    0.0
                }
                TreeJointKind::Free => {
                    state.q.fixed_rows_mut::<3>(qa).copy_from(&x);
                    state.q.fixed_rows_mut::<4>(qa + 3).copy_from(&Vector4::new(rel.w, rel.i, rel.j, rel.k));
                    state.v.fixed_rows_mut::<3>(va).copy_from(&(rel.inverse() * x_rate));
                    state.v.fixed_rows_mut::<3>(va + 3).copy_from(&w_rel);
                    0.0
                }
                TreeJointKind::Universal => {
                    let (a, h) = (self.slide[k], self.axis[k]);
                    let (p, b) = (self.rest[k] * h, self.rest[k].inverse() * a);
                    let (rh, rta) = (rel * h, rel.inverse() * a);
                    let theta1 = nalgebra::RealField::atan2(a.dot(&p.cross(&rh)), p.dot(&rh));
                    let theta2 = -nalgebra::RealField::atan2(h.dot(&b.cross(&rta)), b.dot(&rta));
                    state.q[qa] = theta1;
                    state.q[qa + 1] = theta2;
                    let s1 = UnitQuaternion::from_axis_angle(&Unit::new_unchecked(h), -theta2) * b;
                    state.v[va] = s1.dot(&w_rel);
                    state.v[va + 1] = h.dot(&w_rel);
                    let back = self.relative_rotation(k, &state.q);
                    rel.angle_to(&back) + (w_rel - s1 * state.v[va] - h * state.v[va + 1]).norm()
                }
                TreeJointKind::Fixed => rel.angle_to(&self.rest[k]) + w_rel.norm(),
                TreeJointKind::Prismatic => rel.angle_to(&self.rest[k]) + w_rel.norm(),
            };
            let (gap, slip) = match (j.kind, slid) {
                // Any pose and motion (a planar joint's off-plane part is
                // its turn misfit): nothing more to misfit.
                (TreeJointKind::Free | TreeJointKind::Planar, _) => (Vector3::zeros(), Vector3::zeros()),
                (_, Some((qs, vs))) => {
                    // The child's point slides along the parent's axis: the
                    // gap and slip along it are the coordinate and its rate,
                    // and the parent's material point under the child's
                    // turns with the parent.
                    let axis = a_p * self.slide[k];
                    state.q[qs] = -gap.dot(&axis);
                    state.v[vs] = -slip.dot(&axis);
                    let carried = w_p_inertial.cross(&(axis * state.q[qs]));
                    (gap + axis * state.q[qs], slip + axis * state.v[vs] + carried)
                }
                _ => (gap, slip),
            };
            let misfit = gap.norm() + slip.norm() + turn_misfit;
            if !misfit.is_finite() || misfit > tolerance {
                return Err(TreeError::NotOnJoint { joint: j.name, misfit });
            }
        }
        Ok(state)
    }

    /// A revolute-like joint's angle about its axis (at `q[qi]`, its rate at
    /// `v[vi]`) from the relative rotation and angular velocity: the misfit
    /// of the turn about any other axis.
    fn angle(
        &self,
        k: usize,
        rel: &UnitQuaternion<f64>,
        w_rel: &Vector3<f64>,
        (qi, vi): (usize, usize),
        state: &mut TreeState<NQ, NV>,
    ) -> f64 {
        let local = self.rest[k].inverse() * rel;
        let h = self.axis[k];
        let angle = 2.0 * nalgebra::RealField::atan2(local.imag().dot(&h), local.w);
        state.q[qi] = angle;
        state.v[vi] = h.dot(w_rel);
        let off = local.angle_to(&UnitQuaternion::from_axis_angle(&Unit::new_unchecked(h), angle));
        off + (w_rel - h * state.v[vi]).norm()
    }
}

/// A planar joint's in-plane unit axes `(f, g)` of the parent, `f × g = a`:
/// `f` made perpendicular to `a` (the first of `perpendicular_pair(a)` when
/// it is zero or along `a`).
fn in_plane(a: &Unit<Vector3<f64>>, f: &Vector3<f64>) -> [Vector3<f64>; 2] {
    let f = Unit::try_new(f - a.as_ref() * a.dot(f), 1e-12)
        .map_or_else(|| crate::perpendicular_pair(a).map_or(Vector3::x(), |(b, _)| b), |f| f.into_inner());
    [f, a.cross(&f)]
}

/// The rotation taking the child's axes `(h, k)` onto the parent's `(a, g)`
/// (each second axis made perpendicular to its first), or `None` when a
/// second axis is zero or along its first.
fn locked_rotation(
    h: &Unit<Vector3<f64>>,
    k: &Vector3<f64>,
    a: &Unit<Vector3<f64>>,
    g: &Vector3<f64>,
) -> Option<UnitQuaternion<f64>> {
    let frame = |x: &Unit<Vector3<f64>>, y: &Vector3<f64>| -> Option<Matrix3<f64>> {
        let y = Unit::try_new(y - x.as_ref() * x.dot(y), 1e-12)?;
        Some(Matrix3::from_columns(&[x.into_inner(), y.into_inner(), x.cross(&y)]))
    };
    let (child, parent) = (frame(h, k)?, frame(a, g)?);
    let rotation = nalgebra::Rotation3::from_matrix_unchecked(parent * child.transpose());
    Some(UnitQuaternion::from_rotation_matrix(&rotation))
}

/// `h` made perpendicular to `a` (both unit): a universal joint's rest
/// direction of its child axis in the parent's frame (`perpendicular_pair`'s
/// first when `h` is along `a`).
fn across(h: &Unit<Vector3<f64>>, a: &Unit<Vector3<f64>>) -> Unit<Vector3<f64>> {
    Unit::try_new(h.as_ref() - a.as_ref() * a.dot(h), 1e-9).unwrap_or_else(|| {
        let first = crate::perpendicular_pair(a).map_or(Vector3::x(), |(b, _)| b);
        Unit::new_normalize(first)
    })
}

/// `R₀`: the shortest rotation taking `h` onto `a` (half a turn about a
/// perpendicular when they are opposite).
fn rest_rotation(h: &Unit<Vector3<f64>>, a: &Unit<Vector3<f64>>) -> UnitQuaternion<f64> {
    UnitQuaternion::rotation_between_axis(h, a).unwrap_or_else(|| {
        let perpendicular = crate::perpendicular_pair(h).map_or(Vector3::x(), |(b, _)| b);
        UnitQuaternion::from_axis_angle(&Unit::new_normalize(perpendicular), core::f64::consts::PI)
    })
}
