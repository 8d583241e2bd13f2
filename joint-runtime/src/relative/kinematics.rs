//! Each joint's transform and motion subspace from its coordinates, and the
//! bodies' spatial velocities, root to leaves.

use nalgebra::{Matrix3, SMatrix, SVector, UnitQuaternion, Vector3, Vector4, Vector6};

use super::TreeJointKind;
use super::spatial::{Transform, join};
use super::tangent::{get, three, unit_at};
use super::topology::Tree;

/// A joint's columns of `S` in the child's link frame (its axes, origin at
/// the joint point), constant there but for a universal joint's: at most
/// six (a free joint's), padded with zeros.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Subspace {
    pub cols: [Vector6<f64>; 6],
    pub n: usize,
}

impl Subspace {
    /// The columns given, padded.
    pub fn of(given: &[Vector6<f64>]) -> Self {
        let mut cols = [Vector6::zeros(); 6];
        cols[..given.len()].copy_from_slice(given);
        Subspace { cols, n: given.len() }
    }
}

/// `[a; 0]`: the child's spatial motion, at its link frame's origin (the
/// joint point), when it turns about `a`.
fn turning(a: &Vector3<f64>) -> Vector6<f64> {
    join(a, &Vector3::zeros())
}

/// `[0; a]`: the child's spatial motion when it slides along `a`.
fn sliding(a: &Vector3<f64>) -> Vector6<f64> {
    join(&Vector3::zeros(), a)
}

/// Unit Euler parameters from four coordinates (normalised: an RK4 stage's
/// quaternion is off the unit sphere by its truncation error).
pub(crate) fn unit(p: &Vector4<f64>) -> UnitQuaternion<f64> {
    UnitQuaternion::new_normalize(nalgebra::Quaternion::new(p[0], p[1], p[2], p[3]))
}

impl<const NB: usize, const NQ: usize, const NV: usize> Tree<NB, NQ, NV> {
    /// The motion subspace of joint `k` (kept by [`Tree::new`]).
    pub(crate) fn make_subspace(&self, k: usize) -> Subspace {
        let axes = [Vector3::x(), Vector3::y(), Vector3::z()];
        match self.joints[k].kind {
            TreeJointKind::Revolute => Subspace::of(&[turning(&self.axis[k])]),
            TreeJointKind::Spherical => Subspace::of(&axes.map(|e| turning(&e))),
            TreeJointKind::Prismatic => Subspace::of(&[sliding(&self.axis[k])]),
            TreeJointKind::Cylindrical => Subspace::of(&[turning(&self.axis[k]), sliding(&self.axis[k])]),
            // At θ = 0; `subspace_at` turns the two slides with θ.
            TreeJointKind::Planar => {
                let [f, g] = self.geometry.plane[k].map(|x| self.rest[k].inverse() * x);
                Subspace::of(&[sliding(&f), sliding(&g), turning(&self.axis[k])])
            }
            TreeJointKind::Fixed => Subspace::of(&[]),
            // At θ₂ = 0; `subspace_at` turns the first column with θ₂.
            TreeJointKind::Universal => {
                let b = self.rest[k].inverse() * self.slide[k];
                Subspace::of(&[turning(&b), turning(&self.axis[k])])
            }
            // The point's velocity, then ω': `S` is a constant permutation.
            TreeJointKind::Free => {
                let [x, y, z] = axes;
                Subspace::of(&[sliding(&x), sliding(&y), sliding(&z), turning(&x), turning(&y), turning(&z)])
            }
        }
    }

    /// Joint `k`'s subspace at `q`: constant but for a universal joint, whose
    /// first column `rot(h, θ₂)ᵀ R₀ᵀ s` turns with θ₂, and a planar one, whose
    /// slides `rot(h, θ)ᵀ R₀ᵀ (f, g)` turn with θ.
    // Inlined into the recursions' loops over the joints, where `k` is in
    // range by construction: no bounds check, no panic path.
    #[inline(always)]
    pub(crate) fn subspace_at(&self, k: usize, q: &SVector<f64, NQ>) -> Subspace {
        let mut s = self.subspace[k];
        if self.joints[k].kind == TreeJointKind::Planar {
            let h = nalgebra::Unit::new_unchecked(self.axis[k]);
            let turn = UnitQuaternion::from_axis_angle(&h, -get(q, self.q_at[k] + 2));
            for (col, x) in s.cols.iter_mut().zip(self.geometry.plane[k]) {
                *col = sliding(&(turn * (self.rest[k].inverse() * x)));
            }
        }
        if self.joints[k].kind == TreeJointKind::Universal {
            let h = nalgebra::Unit::new_unchecked(self.axis[k]);
            let turn = UnitQuaternion::from_axis_angle(&h, -get(q, self.q_at[k] + 1));
            let b = self.rest[k].inverse() * self.slide[k];
            s.cols[0] = turning(&(turn * b));
        }
        s
    }

    /// `Ṡ q̇` of joint `k` (a universal joint's: `θ̇₁ θ̇₂ (S₁ × h)`; a planar
    /// one's: `θ̇ [0; (ẋ S₁ + ẏ S₂) × h]`; zero for the others, whose
    /// subspace is constant).
    fn joint_bias(&self, s: &Subspace, k: usize, v: &SVector<f64, NV>) -> Vector6<f64> {
        let at = self.v_at[k];
        if self.joints[k].kind == TreeJointKind::Planar {
            let slide = s.cols[0].fixed_rows::<3>(3) * get(v, at) + s.cols[1].fixed_rows::<3>(3) * get(v, at + 1);
            return sliding(&(slide.cross(&self.axis[k]) * get(v, at + 2)));
        }
        if self.joints[k].kind != TreeJointKind::Universal {
            return Vector6::zeros();
        }
        let s1 = s.cols[0].fixed_rows::<3>(0).into_owned();
        turning(&(s1.cross(&self.axis[k]) * (get(v, at) * get(v, at + 1))))
    }

    /// The child's rotation relative to its parent (`A_child = A_parent R`).
    // Inlined into the recursions' loops over the joints, where `k` is in
    // range by construction: no bounds check, no panic path.
    #[inline(always)]
    pub(crate) fn relative_rotation(&self, k: usize, q: &SVector<f64, NQ>) -> UnitQuaternion<f64> {
        let at = self.q_at[k];
        match self.joints[k].kind {
            TreeJointKind::Revolute | TreeJointKind::Cylindrical => {
                let axis = nalgebra::Unit::new_unchecked(self.axis[k]);
                self.rest[k] * UnitQuaternion::from_axis_angle(&axis, get(q, at))
            }
            TreeJointKind::Planar => {
                let axis = nalgebra::Unit::new_unchecked(self.axis[k]);
                self.rest[k] * UnitQuaternion::from_axis_angle(&axis, get(q, at + 2))
            }
            TreeJointKind::Spherical => unit_at(q, at),
            TreeJointKind::Free => unit_at(q, at + 3),
            TreeJointKind::Prismatic | TreeJointKind::Fixed => self.rest[k],
            TreeJointKind::Universal => {
                let a = nalgebra::Unit::new_unchecked(self.slide[k]);
                let h = nalgebra::Unit::new_unchecked(self.axis[k]);
                UnitQuaternion::from_axis_angle(&a, get(q, at))
                    * self.rest[k]
                    * UnitQuaternion::from_axis_angle(&h, get(q, at + 1))
            }
        }
    }

    /// Joint `k`'s transform from its parent's link frame to its child's:
    /// the offset between the two joint points is a constant of the parent
    /// (plus the slide along the parent's axis, prismatic; plus the free
    /// joint's own offset).
    // Inlined into the recursions' loops over the joints, where `k` is in
    // range by construction: no bounds check, no panic path.
    #[inline(always)]
    pub(crate) fn transform(&self, k: usize, q: &SVector<f64, NQ>) -> Transform {
        let rel: Matrix3<f64> = self.relative_rotation(k, q).to_rotation_matrix().into_inner();
        let at = self.q_at[k];
        let r = match self.joints[k].kind {
            TreeJointKind::Prismatic => self.offset[k] + self.slide[k] * get(q, at),
            TreeJointKind::Cylindrical => self.offset[k] + self.slide[k] * get(q, at + 1),
            TreeJointKind::Planar => {
                self.offset[k] + self.geometry.plane[k][0] * get(q, at) + self.geometry.plane[k][1] * get(q, at + 1)
            }
            TreeJointKind::Free => self.offset[k] + three(q, at),
            _ => self.offset[k],
        };
        Transform { e: rel.transpose(), r }
    }

    /// `S q̇` of joint `k`.
    pub(crate) fn joint_motion(&self, s: &Subspace, k: usize, v: &SVector<f64, NV>) -> Vector6<f64> {
        let at = self.v_at[k];
        s.cols.iter().take(s.n).enumerate().fold(Vector6::zeros(), |acc, (i, c)| acc + c * get(v, at + i))
    }

    /// Every joint's transform and every body's spatial velocity
    /// (its link frame), in tree order.
    pub(crate) fn kinematics(&self, q: &SVector<f64, NQ>, v: &SVector<f64, NV>) -> Kinematics<NB> {
        let mut out = Kinematics {
            x: [Transform { e: Matrix3::identity(), r: Vector3::zeros() }; NB],
            vel: [Vector6::zeros(); NB],
            s: self.subspace,
            bias: [Vector6::zeros(); NB],
        };
        for k in 0..NB {
            out.x[k] = self.transform(k, q);
            out.s[k] = self.subspace_at(k, q);
            out.bias[k] = self.joint_bias(&out.s[k], k, v);
            let parent =
                self.parent[k].and_then(|p| out.vel.get(p)).map_or_else(Vector6::zeros, |v| out.x[k].motion(v));
            out.vel[k] = parent + self.joint_motion(&out.s[k], k, v);
        }
        out
    }
}

impl<const NB: usize, const NQ: usize, const NV: usize> Tree<NB, NQ, NV> {
    /// The Jacobian of a point fixed in `body` (its index in the scene; the
    /// point in the body's frame, from its centre of mass): `[ω; ṗ] = J v`,
    /// 6 × NV, inertial components (the body's angular velocity, then the
    /// point's velocity). Each ancestor joint's columns of `S`, turned into
    /// the ground's axes and moved to the point; `None` for a body no joint
    /// moves (an index out of range).
    pub fn point_jacobian(
        &self,
        q: &SVector<f64, NQ>,
        body: usize,
        point: &Vector3<f64>,
    ) -> Option<SMatrix<f64, 6, NV>> {
        let target = self.joints.iter().position(|j| j.child == body)?;
        let poses = self.link_poses(q);
        let (a, o) = poses[target];
        let p = o + a * (point - self.joints[target].rho_child);
        let mut out = SMatrix::<f64, 6, NV>::zeros();
        let mut k = Some(target);
        while let Some(j) = k {
            let (a, o) = poses[j];
            let s = self.subspace_at(j, q);
            for i in 0..s.n {
                let (w, v) = (a * s.cols[i].fixed_rows::<3>(0), a * s.cols[i].fixed_rows::<3>(3));
                let column = join(&w, &(v + w.cross(&(p - o))));
                out.set_column(self.v_at[j] + i, &column);
            }
            k = self.parent[j];
        }
        Some(out)
    }

    /// Each link frame's orientation and origin (its inbound joint point), in
    /// the ground's axes, root to leaves.
    pub(crate) fn link_poses(&self, q: &SVector<f64, NQ>) -> [(UnitQuaternion<f64>, Vector3<f64>); NB] {
        let mut pose = [(UnitQuaternion::identity(), Vector3::zeros()); NB];
        for k in 0..NB {
            let ground = (UnitQuaternion::identity(), Vector3::zeros());
            let (a_p, o_p) = self.parent[k].and_then(|p| pose.get(p).copied()).unwrap_or(ground);
            pose[k] = (a_p * self.relative_rotation(k, q), o_p + a_p * self.transform(k, q).r);
        }
        pose
    }
}

/// What every recursion starts from.
pub(crate) struct Kinematics<const NB: usize> {
    pub x: [Transform; NB],
    pub vel: [Vector6<f64>; NB],
    /// Each joint's motion subspace at this state.
    pub s: [Subspace; NB],
    /// Each joint's `Ṡ q̇` (a universal joint's; zero for the others).
    pub bias: [Vector6<f64>; NB],
}
