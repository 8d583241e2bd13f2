//! A robot file's state as MuJoCo and Pinocchio write it: the derive's
//! `MUJOCO` (an MJCF file's scene) and `PINOCCHIO` (a URDF file's), each a
//! [`StateLayout`] that converts their `q`, `v`, accelerations and
//! generalised forces to and from the tree's.
//!
//! The tree's conventions differ from both in three places (the rest is a
//! reordering): a floating body's coordinates are its centre of mass from
//! the world's origin and the turn of a frame whose axes are the world's at
//! the file's zero configuration, with its centre's velocity and `ω` in that
//! frame; the libraries use the root link's origin and the link's own
//! orientation (MuJoCo: the origin's velocity in the world's components;
//! Pinocchio: in the link's, quaternion `x y z w`). A ball joint's quaternion
//! turns the child's frame here, the child link's frame there (the two
//! differ by the link's rest orientation). And Pinocchio writes a URDF
//! `continuous` joint as `cos θ, sin θ`. Joints come in each library's
//! order: MuJoCo's, the file's (depth first, as written); Pinocchio's, depth
//! first from the root with siblings by joint name (urdfdom keeps a link's
//! child joints in a map by name), a floating base first.
//!
//! Every conversion is exact (no differences): `q` and `v` both ways, and
//! the maps their velocities' linearity gives, generalised forces (the
//! transpose, so that `τᵀ v` is the same power on both sides) and
//! accelerations (with MuJoCo's `ω × u` term for a free joint's origin);
//! and matrices ([`StateLayout::tangent_map`] and the conversions beside it):
//! the mass matrix, Jacobians, the dynamics' derivatives and a step's
//! Jacobian, with the map of `∂/∂q` between the tangents each side
//! differentiates on.

use core::fmt;

use nalgebra::{Quaternion, Rotation3, SVector, UnitQuaternion, Vector3};

use super::LinkFrame;
use crate::relative::TreeState;

mod matrices;

/// The library whose state layout a [`StateLayout`] reads and writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Library {
    /// MuJoCo (`qpos`, `qvel`, `qacc`, `qfrc_*`): an MJCF file's.
    MuJoCo,
    /// Pinocchio (`q`, `v`, `a`, `tau`): a URDF file's.
    Pinocchio,
}

/// How a library writes one joint's coordinates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LibraryJointKind {
    /// A floating body: the link's origin, then its quaternion (MuJoCo
    /// `w x y z`, Pinocchio `x y z w`); 6 velocities, the origin's then `ω`
    /// in the link's frame (MuJoCo: the origin's in the world's components).
    Free,
    /// A ball joint: a quaternion, 3 velocities (`ω` in the child link's frame).
    Ball,
    /// A hinge (URDF `revolute`): one angle.
    Hinge,
    /// A URDF `continuous` joint in Pinocchio: `cos θ, sin θ`; one velocity.
    Continuous,
    /// A slide (URDF `prismatic`): one length.
    Slide,
}

impl LibraryJointKind {
    /// The library's number of coordinates and of velocities.
    pub const fn sizes(self) -> (usize, usize) {
        match self {
            LibraryJointKind::Free => (7, 6),
            LibraryJointKind::Ball => (4, 3),
            LibraryJointKind::Continuous => (2, 1),
            LibraryJointKind::Hinge | LibraryJointKind::Slide => (1, 1),
        }
    }
}

/// One moving joint of the file: where it is in the library's vectors and
/// in the tree's, and its child link's frame on its body.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LibraryJoint {
    /// The file's name (Pinocchio's `root_joint` for a URDF's floating base).
    pub name: &'static str,
    /// How the library writes it.
    pub kind: LibraryJointKind,
    /// Its first coordinate in the library's `q` (`idx_q`, `jnt_qposadr`).
    pub q_at: usize,
    /// Its first velocity in the library's `v` (`idx_v`, `jnt_dofadr`).
    pub v_at: usize,
    /// Its first coordinate in the tree's `q`.
    pub tree_q_at: usize,
    /// Its first velocity in the tree's `v`.
    pub tree_v_at: usize,
    /// A hinge's or slide's coordinate in the library minus the tree's
    /// (MJCF's `ref`: MuJoCo's coordinate at the file's pose, where the
    /// tree's is zero); zero elsewhere.
    pub offset: f64,
    /// The child link's frame on its body: what a free joint's position and
    /// a free or ball joint's quaternion refer to in the library.
    pub link: LinkFrame,
}

/// What a conversion refuses.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum StateError {
    /// A vector's length is not the library's.
    Length {
        /// Which vector.
        what: &'static str,
        /// The library's length.
        expected: usize,
        /// The length given.
        found: usize,
    },
    /// A quaternion (or a continuous joint's `cos, sin`) of zero or
    /// non-finite length.
    NotUnit {
        /// The joint's name.
        joint: &'static str,
    },
}

impl fmt::Display for StateError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            StateError::Length { what, expected, found } => {
                write!(f, "`{what}` has {found} numbers; the library's has {expected}")
            }
            StateError::NotUnit { joint } => {
                write!(f, "joint `{joint}`'s quaternion (or cos, sin) has zero or non-finite length")
            }
        }
    }
}

impl core::error::Error for StateError {}

/// A robot file's state as a [`Library`] lays it out: the derive writes it
/// as the scene's `MUJOCO` (an MJCF file, relative coordinates) or
/// `PINOCCHIO` (a URDF file). `NQ` and `NV` are the tree's sizes.
///
/// The README's robot section copies states from both libraries.
#[derive(Clone, Copy, Debug)]
pub struct StateLayout<const NQ: usize, const NV: usize> {
    library: Library,
    nq: usize,
    nv: usize,
    joints: &'static [LibraryJoint],
}

impl<const NQ: usize, const NV: usize> StateLayout<NQ, NV> {
    /// The derive's constructor: `joints` in the library's order, its
    /// offsets consistent with `nq`, `nv`, `NQ` and `NV`.
    #[doc(hidden)]
    pub const fn __from_derive(library: Library, nq: usize, nv: usize, joints: &'static [LibraryJoint]) -> Self {
        StateLayout { library, nq, nv, joints }
    }

    /// The library.
    pub const fn library(&self) -> Library {
        self.library
    }

    /// The library's number of coordinates (`nq`, MuJoCo's `nq`).
    pub const fn nq(&self) -> usize {
        self.nq
    }

    /// The library's number of velocities (`nv`).
    pub const fn nv(&self) -> usize {
        self.nv
    }

    /// The moving joints in the library's order.
    pub const fn joints(&self) -> &'static [LibraryJoint] {
        self.joints
    }

    /// The tree's state (at `t = 0`) from the library's `q` and `v`.
    /// Quaternions are normalised (as both libraries do before using them).
    pub fn state_from(&self, q: &[f64], v: &[f64]) -> Result<TreeState<NQ, NV>, StateError> {
        check("q", self.nq, q.len())?;
        check("v", self.nv, v.len())?;
        let mut state = TreeState { q: SVector::zeros(), v: SVector::zeros(), t: 0.0 };
        for j in self.joints {
            let (turn, origin) = frame(j);
            let (q, v) = (&q[j.q_at..], &v[j.v_at..]);
            let (tq, tv) = (j.tree_q_at, j.tree_v_at);
            match j.kind {
                LibraryJointKind::Hinge | LibraryJointKind::Slide => {
                    state.q[tq] = q[0] - j.offset;
                    state.v[tv] = v[0];
                }
                LibraryJointKind::Continuous => {
                    let (c, s) = (q[0], q[1]);
                    if !(libm::hypot(c, s) > 0.0 && c.is_finite() && s.is_finite()) {
                        return Err(StateError::NotUnit { joint: j.name });
                    }
                    state.q[tq] = libm::atan2(s, c);
                    state.v[tv] = v[0];
                }
                LibraryJointKind::Ball => {
                    let link = self.quaternion(j, &q[..4])?;
                    put_quaternion(&mut state.q, tq, &(turn * link * turn.inverse()));
                    put3(&mut state.v, tv, &(turn * Vector3::new(v[0], v[1], v[2])));
                }
                LibraryJointKind::Free => {
                    let body = self.quaternion(j, &q[3..7])? * turn.inverse();
                    let centre = Vector3::new(q[0], q[1], q[2]) - body * origin;
                    put3(&mut state.q, tq, &centre);
                    put_quaternion(&mut state.q, tq + 3, &body);
                    let omega = turn * Vector3::new(v[3], v[4], v[5]);
                    let u = self.origin_in_body(&body, &turn, &Vector3::new(v[0], v[1], v[2]));
                    put3(&mut state.v, tv, &(u - omega.cross(&origin)));
                    put3(&mut state.v, tv + 3, &omega);
                }
            }
        }
        Ok(state)
    }

    /// Writes the tree's `state` as the library's `q` and `v` (quaternions
    /// as they are, `w ≥ 0` not enforced).
    pub fn write_state(&self, state: &TreeState<NQ, NV>, q: &mut [f64], v: &mut [f64]) -> Result<(), StateError> {
        check("q", self.nq, q.len())?;
        check("v", self.nv, v.len())?;
        for j in self.joints {
            let (turn, origin) = frame(j);
            let (tq, tv) = (j.tree_q_at, j.tree_v_at);
            let (q, v) = (&mut q[j.q_at..], &mut v[j.v_at..]);
            match j.kind {
                LibraryJointKind::Hinge | LibraryJointKind::Slide => {
                    q[0] = state.q[tq] + j.offset;
                    v[0] = state.v[tv];
                }
                LibraryJointKind::Continuous => {
                    (q[0], q[1]) = (libm::cos(state.q[tq]), libm::sin(state.q[tq]));
                    v[0] = state.v[tv];
                }
                LibraryJointKind::Ball => {
                    let body = tree_quaternion(&state.q, tq);
                    self.write_quaternion(&mut q[..4], &(turn.inverse() * body * turn));
                    v[..3].copy_from_slice((turn.inverse() * vector3(&state.v, tv)).as_slice());
                }
                LibraryJointKind::Free => {
                    let body = tree_quaternion(&state.q, tq + 3);
                    q[..3].copy_from_slice((vector3(&state.q, tq) + body * origin).as_slice());
                    self.write_quaternion(&mut q[3..7], &(body * turn));
                    let omega = vector3(&state.v, tv + 3);
                    let u = vector3(&state.v, tv) + omega.cross(&origin);
                    v[..3].copy_from_slice(self.origin_from_body(&body, &turn, &u).as_slice());
                    v[3..6].copy_from_slice((turn.inverse() * omega).as_slice());
                }
            }
        }
        Ok(())
    }

    /// The tree's generalised forces from the library's (`qfrc_applied`,
    /// Pinocchio's `tau`) at `state`: the same power on every velocity.
    pub fn forces_from(&self, state: &TreeState<NQ, NV>, tau: &[f64]) -> Result<SVector<f64, NV>, StateError> {
        self.vector_from("tau", tau, |j, (turn, origin), [f, m]| {
            let force = self.origin_in_body(&tree_quaternion(&state.q, j.tree_q_at + 3), turn, &f);
            (force, turn * m + origin.cross(&force))
        })
    }

    /// Writes the tree's generalised forces `tau` at `state` as the library's.
    pub fn write_forces(
        &self,
        state: &TreeState<NQ, NV>,
        tau: &SVector<f64, NV>,
        out: &mut [f64],
    ) -> Result<(), StateError> {
        self.vector_into(tau, out, |j, (turn, origin), [force, moment]| {
            let body = tree_quaternion(&state.q, j.tree_q_at + 3);
            (self.origin_from_body(&body, turn, &force), turn.inverse() * (moment - origin.cross(&force)))
        })
    }

    /// The tree's accelerations (`v̇`) from the library's (`qacc`, `a`) at
    /// `state`.
    pub fn accelerations_from(&self, state: &TreeState<NQ, NV>, a: &[f64]) -> Result<SVector<f64, NV>, StateError> {
        self.vector_from("a", a, |j, (turn, origin), [linear, angular]| {
            let tv = j.tree_v_at;
            let (omega, alpha) = (vector3(&state.v, tv + 3), turn * angular);
            let mut du = self.origin_in_body(&tree_quaternion(&state.q, j.tree_q_at + 3), turn, &linear);
            if self.library == Library::MuJoCo {
                // u̇ (world) = A (u̇_B + ω × u_B): the body's components turn.
                du -= omega.cross(&(vector3(&state.v, tv) + omega.cross(origin)));
            }
            (du - alpha.cross(origin), alpha)
        })
    }

    /// Writes the tree's accelerations `a` (`v̇`) at `state` as the library's.
    pub fn write_accelerations(
        &self,
        state: &TreeState<NQ, NV>,
        a: &SVector<f64, NV>,
        out: &mut [f64],
    ) -> Result<(), StateError> {
        self.vector_into(a, out, |j, (turn, origin), [dv, alpha]| {
            let tv = j.tree_v_at;
            let omega = vector3(&state.v, tv + 3);
            let mut du = dv + alpha.cross(origin);
            if self.library == Library::MuJoCo {
                du += omega.cross(&(vector3(&state.v, tv) + omega.cross(origin)));
            }
            (self.origin_from_body(&tree_quaternion(&state.q, j.tree_q_at + 3), turn, &du), turn.inverse() * alpha)
        })
    }

    /// The tree's vector from the library's velocity-like `x` (`what` names
    /// it in errors), joint by joint: a hinge's or slide's number as it is,
    /// a ball's three turned into the child's frame, a free joint's six by
    /// `free` (its link frame, its two triples → the tree's two).
    fn vector_from(
        &self,
        what: &'static str,
        x: &[f64],
        free: impl Fn(
            &LibraryJoint,
            (&UnitQuaternion<f64>, &Vector3<f64>),
            [Vector3<f64>; 2],
        ) -> (Vector3<f64>, Vector3<f64>),
    ) -> Result<SVector<f64, NV>, StateError> {
        check(what, self.nv, x.len())?;
        let mut out = SVector::zeros();
        for j in self.joints {
            let (turn, origin) = frame(j);
            let (x, tv) = (&x[j.v_at..], j.tree_v_at);
            let triple = |at: usize| Vector3::new(x[at], x[at + 1], x[at + 2]);
            match j.kind {
                LibraryJointKind::Ball => put3(&mut out, tv, &(turn * triple(0))),
                LibraryJointKind::Free => {
                    let (first, second) = free(j, (&turn, &origin), [triple(0), triple(3)]);
                    put3(&mut out, tv, &first);
                    put3(&mut out, tv + 3, &second);
                }
                _ => out[tv] = x[0],
            }
        }
        Ok(out)
    }

    /// The inverse of [`vector_from`](Self::vector_from): the tree's `x`
    /// written as the library's into `out`, a free joint's by `free`.
    fn vector_into(
        &self,
        x: &SVector<f64, NV>,
        out: &mut [f64],
        free: impl Fn(
            &LibraryJoint,
            (&UnitQuaternion<f64>, &Vector3<f64>),
            [Vector3<f64>; 2],
        ) -> (Vector3<f64>, Vector3<f64>),
    ) -> Result<(), StateError> {
        check("out", self.nv, out.len())?;
        for j in self.joints {
            let (turn, origin) = frame(j);
            let (out, tv) = (&mut out[j.v_at..], j.tree_v_at);
            match j.kind {
                LibraryJointKind::Ball => out[..3].copy_from_slice((turn.inverse() * vector3(x, tv)).as_slice()),
                LibraryJointKind::Free => {
                    let (first, second) = free(j, (&turn, &origin), [vector3(x, tv), vector3(x, tv + 3)]);
                    out[..3].copy_from_slice(first.as_slice());
                    out[3..6].copy_from_slice(second.as_slice());
                }
                _ => out[0] = x[tv],
            }
        }
        Ok(())
    }

    /// A free joint's origin vector (velocity, force, acceleration) from
    /// the library's components into the body's: MuJoCo's are the world's,
    /// Pinocchio's the link's.
    fn origin_in_body(&self, body: &UnitQuaternion<f64>, turn: &UnitQuaternion<f64>, x: &Vector3<f64>) -> Vector3<f64> {
        match self.library {
            Library::MuJoCo => body.inverse() * x,
            Library::Pinocchio => turn * x,
        }
    }

    /// The inverse of [`origin_in_body`](Self::origin_in_body).
    fn origin_from_body(
        &self,
        body: &UnitQuaternion<f64>,
        turn: &UnitQuaternion<f64>,
        x: &Vector3<f64>,
    ) -> Vector3<f64> {
        match self.library {
            Library::MuJoCo => body * x,
            Library::Pinocchio => turn.inverse() * x,
        }
    }

    /// The library's quaternion (its order), normalised.
    fn quaternion(&self, j: &LibraryJoint, x: &[f64]) -> Result<UnitQuaternion<f64>, StateError> {
        let raw = match self.library {
            Library::MuJoCo => Quaternion::new(x[0], x[1], x[2], x[3]),
            Library::Pinocchio => Quaternion::new(x[3], x[0], x[1], x[2]),
        };
        let n = raw.norm();
        if !(n > 0.0 && n.is_finite()) {
            return Err(StateError::NotUnit { joint: j.name });
        }
        Ok(UnitQuaternion::new_unchecked(raw / n))
    }

    fn write_quaternion(&self, out: &mut [f64], e: &UnitQuaternion<f64>) {
        let (w, x, y, z) = (e.w, e.i, e.j, e.k);
        let order = match self.library {
            Library::MuJoCo => [w, x, y, z],
            Library::Pinocchio => [x, y, z, w],
        };
        out[..4].copy_from_slice(&order);
    }
}

/// The joint's child link on its body: its rotation (link components to
/// body components) and its origin from the body's centre.
fn frame(j: &LibraryJoint) -> (UnitQuaternion<f64>, Vector3<f64>) {
    let turn = Rotation3::from_matrix_unchecked(j.link.turn());
    (UnitQuaternion::from_rotation_matrix(&turn), Vector3::from(j.link.origin))
}

fn check(what: &'static str, expected: usize, found: usize) -> Result<(), StateError> {
    if expected == found { Ok(()) } else { Err(StateError::Length { what, expected, found }) }
}

fn vector3<const N: usize>(x: &SVector<f64, N>, at: usize) -> Vector3<f64> {
    Vector3::new(x[at], x[at + 1], x[at + 2])
}

fn put3<const N: usize>(x: &mut SVector<f64, N>, at: usize, v: &Vector3<f64>) {
    x.fixed_rows_mut::<3>(at).copy_from(v);
}

/// The tree's quaternion (`w` first) at `at`, normalised.
fn tree_quaternion<const N: usize>(q: &SVector<f64, N>, at: usize) -> UnitQuaternion<f64> {
    UnitQuaternion::from_quaternion(Quaternion::new(q[at], q[at + 1], q[at + 2], q[at + 3]))
}

fn put_quaternion<const N: usize>(q: &mut SVector<f64, N>, at: usize, e: &UnitQuaternion<f64>) {
    q.fixed_rows_mut::<4>(at).copy_from_slice(&[e.w, e.i, e.j, e.k]);
}
