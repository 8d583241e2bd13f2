//! The recursions on a tree: the articulated-body algorithm (forward
//! dynamics), the recursive Newton–Euler algorithm (inverse dynamics, bias
//! forces) and the composite-rigid-body algorithm (the mass matrix).
//! Featherstone, *Rigid Body Dynamics Algorithms* (2008), tables 5.1, 6.2,
//! 7.1, in each body's own frame with its origin at the centre of mass.
//! Gravity enters as the ground's acceleration `(0, −g)`.

use nalgebra::{Matrix3, Matrix6, SMatrix, SVector, Vector3, Vector6};

use super::TreeJointKind;
use super::TreeState;
use super::kinematics::{Kinematics, Subspace};
use super::spatial::{cross_force, cross_motion, join, split};
use super::tangent::{get, set};
use super::topology::{Tree, TreeError};

/// The energy of a tree's state.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct TreeEnergy {
    /// `½ Σ (m |ṙ|² + ω'ᵀ J' ω')`.
    pub kinetic: f64,
    /// `−Σ m g · r`.
    pub gravity: f64,
    /// `½ Σ k (q − q₀)²`: the joints' springs.
    pub elastic: f64,
}

impl TreeEnergy {
    /// Kinetic plus potential.
    pub fn total(&self) -> f64 {
        self.kinetic + self.gravity + self.elastic
    }
}

/// `Sᵀ f`, padded with zeros past the joint's freedoms.
fn project(s: &Subspace, f: &Vector6<f64>) -> Vector6<f64> {
    Vector6::from_fn(|i, _| if i < s.n { s.cols[i].dot(f) } else { 0.0 })
}

/// The first three of a joint's padded numbers (a joint other than a free one).
// Inlined: out of line LTO left it without `nounwind`, a landing pad in
// Radau IIA's step the no-panic proof counts.
#[inline(always)]
fn three(x: &Vector6<f64>) -> Vector3<f64> {
    x.fixed_rows::<3>(0).into_owned()
}

/// `a[i] += x` where `i` is in range (a parent's index, which the
/// optimiser cannot bound: every data index of the steps through `get`, so
/// that the no-panic proof covers them).
#[inline(always)]
fn add_at<T: core::ops::AddAssign, const NB: usize>(a: &mut [T; NB], i: usize, x: T) {
    if let Some(slot) = a.get_mut(i) {
        *slot += x;
    }
}

/// `S x` for the joint's freedoms.
fn expand(s: &Subspace, x: &Vector6<f64>) -> Vector6<f64> {
    s.cols.iter().zip(x.iter()).take(s.n).fold(Vector6::zeros(), |acc, (c, x)| acc + c * *x)
}

/// The inverse of a symmetric positive definite 3 × 3 matrix, by its
/// adjugate (`None` unless its leading minors are positive): closed form,
/// as the derive writes it, and several times cheaper than a factorisation
/// at this size.
fn spd_inverse(d: &Matrix3<f64>) -> Option<Matrix3<f64>> {
    let cof = |r: usize, c: usize| {
        let (r1, r2, c1, c2) = ((r + 1) % 3, (r + 2) % 3, (c + 1) % 3, (c + 2) % 3);
        d[(r1, c1)] * d[(r2, c2)] - d[(r1, c2)] * d[(r2, c1)]
    };
    let adj = Matrix3::from_fn(|r, c| cof(c, r));
    let det = d[(0, 0)] * adj[(0, 0)] + d[(0, 1)] * adj[(1, 0)] + d[(0, 2)] * adj[(2, 0)];
    let minor = d[(0, 0)] * d[(1, 1)] - d[(0, 1)] * d[(1, 0)];
    (d[(0, 0)] > 0.0 && minor > 0.0 && det > 0.0 && det.is_finite()).then(|| adj * (1.0 / det))
}

/// A joint's `U = Iᴬ S`, `D⁻¹ = (Sᵀ U)⁻¹` (identity past its freedoms) and
/// `u = τ − Sᵀ pᴬ`: what the articulated-body algorithm keeps per joint.
#[derive(Clone, Copy, Debug)]
struct Articulated {
    u_cols: [Vector6<f64>; 3],
    d_inv: Matrix3<f64>,
    u: Vector3<f64>,
}

impl Articulated {
    /// `armature` adds to `D`'s diagonal (the joint's own inertia).
    // Inlined: out of line, LTO left it without `nounwind` (though it
    // calls nothing that unwinds), which kept a landing pad in every step.
    #[inline(always)]
    fn new(s: &Subspace, ia: &Matrix6<f64>, pa: &Vector6<f64>, tau: Vector3<f64>, armature: f64) -> Option<Self> {
        // `get`: the array's map runs out of line, where `i` is not bounded.
        let u_cols: [Vector6<f64>; 3] = core::array::from_fn(|i| match s.cols.get(i) {
            Some(col) if i < s.n => ia * col,
            _ => Vector6::zeros(),
        });
        let d_inv = if s.n == 1 {
            let d = s.cols[0].dot(&u_cols[0]) + armature;
            (d > 0.0).then(|| Matrix3::new(1.0 / d, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0))?
        } else {
            // Padded with the identity past the joint's freedoms (a universal's 2).
            let d = Matrix3::from_fn(|r, c| match (r < s.n, c < s.n) {
                (true, true) => s.cols[r].dot(&u_cols[c]) + if r == c { armature } else { 0.0 },
                _ => f64::from(u8::from(r == c)),
            });
            spd_inverse(&d)?
        };
        Some(Articulated { u_cols, d_inv, u: tau - three(&project(s, pa)) })
    }

    /// `U x`.
    fn u_times(&self, n: usize, x: &Vector3<f64>) -> Vector6<f64> {
        self.u_cols.iter().zip(x.iter()).take(n).fold(Vector6::zeros(), |acc, (u, x)| acc + u * *x)
    }

    /// `C − Bᵀ A⁻¹ B` of `Iᴬ = [A B; Bᵀ C]`, for `S = [1; 0]` (`U = [A; Bᵀ]`,
    /// `D⁻¹ = A⁻¹`).
    // Inlined: out of line, LTO left it without `nounwind` (though it
    // calls nothing that unwinds), which kept a landing pad in every step.
    #[inline(always)]
    fn translational(&self, ia: &Matrix6<f64>) -> Matrix3<f64> {
        // Entry by entry: a strided view's `into_owned` goes through an
        // iterator whose length the optimiser cannot see (a panic path).
        let c = Matrix3::from_fn(|r, col| ia[(r + 3, col + 3)]);
        let b = Matrix3::from_fn(|r, col| ia[(r, col + 3)]);
        let lower = c - b.transpose() * self.d_inv * b;
        (lower + lower.transpose()) * 0.5
    }

    /// `Iᴬ − U D⁻¹ Uᵀ`.
    // Inlined: out of line, LTO left it without `nounwind` (though it
    // calls nothing that unwinds), which kept a landing pad in every step.
    #[inline(always)]
    fn reduced(&self, n: usize, ia: &Matrix6<f64>) -> Matrix6<f64> {
        let mut out = *ia;
        for (r, u) in self.u_cols.iter().enumerate().take(n) {
            let w = self.u_times(n, &self.d_inv.column(r).into_owned());
            out -= w * u.transpose();
        }
        out
    }
}

impl<const NB: usize, const NQ: usize, const NV: usize> Tree<NB, NQ, NV> {
    /// The ground's acceleration in joint `k`'s child frame, through its
    /// parent (`(0, −g)` at the ground).
    fn parent_acceleration(&self, kin: &Kinematics<NB>, k: usize, acc: &[Vector6<f64>; NB]) -> Vector6<f64> {
        let ground = || join(&Vector3::zeros(), &(-self.gravity));
        // Through `get`: out of line (Radau IIA's stages) the bounds on `k`
        // are not the caller's loop's, and an index kept a panic path.
        let a_p = self.parent.get(k).copied().flatten().and_then(|p| acc.get(p).copied()).unwrap_or_else(ground);
        kin.x.get(k).map_or_else(Vector6::zeros, |x| x.motion(&a_p))
    }

    /// The joint accelerations `v̇` under joint forces `tau` (torques about a
    /// revolute axis; torque vectors in the child's frame at a spherical
    /// joint): the articulated-body algorithm, O(bodies).
    // Inlined: out of line, LTO's attribute inference left it without
    // `nounwind` although nothing in it unwinds, so every step that can fall
    // back to it kept a landing pad the no-panic proof counts.
    #[inline(always)]
    pub fn forward_dynamics(
        &self,
        state: &TreeState<NQ, NV>,
        tau: &SVector<f64, NV>,
    ) -> Result<SVector<f64, NV>, TreeError> {
        let kin = self.kinematics(&state.q, &state.v);
        let mut ia = self.inertia;
        let mut pa = [Vector6::zeros(); NB];
        let mut c = [Vector6::zeros(); NB];
        for k in 0..NB {
            let vel = kin.vel[k];
            c[k] = cross_motion(&vel, &self.joint_motion(&kin.s[k], k, &state.v)) + kin.bias[k];
            pa[k] = cross_force(&vel, &(self.inertia[k] * vel));
        }
        let blank = Articulated { u_cols: [Vector6::zeros(); 3], d_inv: Matrix3::zeros(), u: Vector3::zeros() };
        let mut art = [blank; NB];
        // A free joint's body acceleration (it does not depend on the parent's).
        let mut free = [Vector6::zeros(); NB];
        for k in (0..NB).rev() {
            // `get`: inlined into a step's stages, the reversed loop's bound
            // was lost (a bounds check, a panic path); the arrays after this
            // one share its length.
            let Some(s) = kin.s.get(k) else { continue };
            let t = self.joint_forces(k, tau) - self.passive_forces(k, state);
            let singular = TreeError::Singular { joint: self.joints[k].name };
            if self.joints[k].kind == TreeJointKind::Free {
                // S is a permutation, so U D⁻¹ Uᵀ = Iᴬ: nothing of the
                // inertia moves on, only the joint force (the reaction), and
                // the body's acceleration is Iᴬ⁻¹ (S τ − pᴬ) whatever the
                // parent's.
                let f = expand(s, &t);
                // The hand-written factor, which has no panic path
                // (nalgebra's Cholesky has, and the step is in the proof).
                let factor = crate::linalg::PivotedCholesky::new(&ia[k], crate::linalg::DEFAULT_RANK_TOLERANCE)
                    .ok()
                    .filter(|f| f.is_full_rank())
                    .ok_or(singular)?;
                free[k] = factor.solve(&(f - pa[k]));
                if let Some(p) = self.parent[k] {
                    add_at(&mut pa, p, kin.x[k].force_back(&f));
                }
                continue;
            }
            let armature = self.joints[k].armature;
            let a = Articulated::new(s, &ia[k], &pa[k], three(&t), armature).ok_or(singular)?;
            if let Some(p) = self.parent[k] {
                let handed = a.u_times(s.n, &(a.d_inv * a.u));
                if self.joints[k].kind == TreeJointKind::Spherical && armature == 0.0 {
                    // S = [1; 0] in the link frame: Iᴬ − U D⁻¹ Uᵀ is
                    // [0 0; 0 C − Bᵀ A⁻¹ B], exactly; only that block moves on.
                    let lower = a.translational(&ia[k]);
                    let (_, c_lin) = split(&c[k]);
                    let pa_k = pa[k] + join(&Vector3::zeros(), &(lower * c_lin)) + handed;
                    add_at(&mut ia, p, kin.x[k].translational_back(&lower));
                    add_at(&mut pa, p, kin.x[k].force_back(&pa_k));
                } else {
                    let reduced = a.reduced(s.n, &ia[k]);
                    let pa_k = pa[k] + reduced * c[k] + handed;
                    add_at(&mut ia, p, kin.x[k].inertia_back(&reduced));
                    add_at(&mut pa, p, kin.x[k].force_back(&pa_k));
                }
            }
            art[k] = a;
        }
        let mut acc = [Vector6::zeros(); NB];
        let mut vdot = SVector::<f64, NV>::zeros();
        for k in 0..NB {
            let Some(s) = kin.s.get(k) else { continue };
            let a = self.parent_acceleration(&kin, k, &acc) + c[k];
            let qdd = if self.joints[k].kind == TreeJointKind::Free {
                project(s, &(free[k] - a))
            } else {
                // The row taken out of the closure: `from_fn` left out of
                // line (Radau IIA's stages) kept a bounds check on `art[k]`.
                let ak = &art[k];
                let u_t_a = Vector3::from_fn(|i, _| match ak.u_cols.get(i) {
                    Some(u) if i < s.n => u.dot(&a),
                    _ => 0.0,
                });
                let qdd = ak.d_inv * (ak.u - u_t_a);
                Vector6::new(qdd.x, qdd.y, qdd.z, 0.0, 0.0, 0.0)
            };
            acc[k] = a + expand(s, &qdd);
            self.put(k, &qdd, &mut vdot);
        }
        Ok(vdot)
    }

    /// The joint forces `τ(q, v, v̇)` that give the accelerations `vdot`
    /// (gravity included): the recursive Newton–Euler algorithm, O(bodies).
    pub fn inverse_dynamics(&self, state: &TreeState<NQ, NV>, vdot: &SVector<f64, NV>) -> SVector<f64, NV> {
        let (kin, f) = self.joint_wrenches(state, vdot, None);
        let mut tau = SVector::<f64, NV>::zeros();
        for (k, (s, f)) in kin.s.iter().zip(&f).enumerate() {
            let j = &self.joints[k];
            let own = self.joint_forces(k, vdot) * j.armature + self.passive_forces(k, state);
            self.put(k, &(project(s, f) + own), &mut tau);
        }
        tau
    }

    /// The joint forces of the wrenches `external` on the joints' children
    /// (link frames, moment about the joint point): each carried towards the
    /// root and projected onto every joint it passes, `Sᵀ Σ Xᵀ f`, what the
    /// bodies' point Jacobians' `Jᵀ f` sum to, in O(bodies). Every data
    /// index through `get` (`put`, `add_at`): the steps, and the gravity
    /// compensation's forces, that call it are proved panic-free.
    pub(crate) fn wrench_forces(&self, q: &SVector<f64, NQ>, external: &[Vector6<f64>; NB]) -> SVector<f64, NV> {
        let mut f = *external;
        let mut tau = SVector::<f64, NV>::zeros();
        for k in (0..NB).rev() {
            self.put(k, &project(&self.subspace_at(k, q), &f[k]), &mut tau);
            if let Some(p) = self.parent[k] {
                let back = self.transform(k, q).force_back(&f[k]);
                add_at(&mut f, p, back);
            }
        }
        tau
    }

    /// Each joint's wrench `(n, f)` on its child, in the child's link frame
    /// (moment about the joint point), for the motion `vdot` with the
    /// wrenches `external` on the children (same frames; gravity included
    /// as the ground's acceleration): the recursive Newton–Euler algorithm's
    /// forces, before their projection onto the joints' freedoms.
    pub(crate) fn joint_wrenches(
        &self,
        state: &TreeState<NQ, NV>,
        vdot: &SVector<f64, NV>,
        external: Option<&[Vector6<f64>; NB]>,
    ) -> (Kinematics<NB>, [Vector6<f64>; NB]) {
        let kin = self.kinematics(&state.q, &state.v);
        let mut acc = [Vector6::zeros(); NB];
        let mut f = [Vector6::zeros(); NB];
        for k in 0..NB {
            let (s, vel) = (&kin.s[k], kin.vel[k]);
            let joint = self.joint_motion(s, k, &state.v);
            acc[k] = self.parent_acceleration(&kin, k, &acc)
                + self.joint_motion(s, k, vdot)
                + cross_motion(&vel, &joint)
                + kin.bias[k];
            f[k] = self.inertia[k] * acc[k] + cross_force(&vel, &(self.inertia[k] * vel));
            if let Some(e) = external {
                f[k] -= e[k];
            }
        }
        // Children come after their parents: each is complete when it is handed on.
        for k in (0..NB).rev() {
            if let Some(p) = self.parent[k] {
                let back = kin.x[k].force_back(&f[k]);
                f[p] += back;
            }
        }
        (kin, f)
    }

    /// The bias forces `τ(q, v, 0)`: Coriolis, centrifugal and gravity.
    pub fn bias_forces(&self, state: &TreeState<NQ, NV>) -> SVector<f64, NV> {
        self.inverse_dynamics(state, &SVector::zeros())
    }

    /// The joint-space mass matrix `M(q)` into `out` (a reference, so that a
    /// large tree's matrix need not live on the stack): the
    /// composite-rigid-body algorithm.
    pub fn mass_matrix_into(&self, q: &SVector<f64, NQ>, out: &mut SMatrix<f64, NV, NV>) {
        let kin = self.kinematics(q, &SVector::zeros());
        let mut ic = self.inertia;
        for k in (0..NB).rev() {
            if let Some(p) = self.parent[k] {
                let back = kin.x[k].inertia_back(&ic[k]);
                ic[p] += back;
            }
        }
        out.fill(0.0);
        for (k, ic_k) in ic.iter().enumerate() {
            let s = &kin.s[k];
            for i in 0..s.n {
                let col = self.v_at[k] + i;
                let mut force = ic_k * s.cols[i];
                let mut j = k;
                loop {
                    let sj = &kin.s[j];
                    for r in 0..sj.n {
                        let row = self.v_at[j] + r;
                        let m = sj.cols[r].dot(&force);
                        out[(row, col)] = m;
                        out[(col, row)] = m;
                    }
                    let Some(p) = self.parent[j] else { break };
                    force = kin.x[j].force_back(&force);
                    j = p;
                }
                out[(col, col)] += self.joints[k].armature;
            }
        }
    }

    /// Kinetic and potential energy.
    pub fn energy(&self, state: &TreeState<NQ, NV>) -> TreeEnergy {
        let kin = self.kinematics(&state.q, &state.v);
        let rotors = (0..NB).map(|k| 0.5 * self.joints[k].armature * self.joint_forces(k, &state.v).norm_squared());
        let kinetic =
            (0..NB).map(|k| 0.5 * kin.vel[k].dot(&(self.inertia[k] * kin.vel[k]))).sum::<f64>() + rotors.sum::<f64>();
        let system = self.system_state(state);
        let gravity = system.bodies.iter().zip(&self.mass).map(|(b, m)| -m.mass * self.gravity.dot(&b.r)).sum::<f64>()
            + self.compensation_energy(&system);
        TreeEnergy { kinetic, gravity, elastic: self.spring_energy(&state.q) }
    }

    /// `½ Σ k (q − q₀)²` over the joints' springs.
    pub(crate) fn spring_energy(&self, q: &SVector<f64, NQ>) -> f64 {
        let spring = |(j, at): (&super::TreeJoint, &usize)| {
            let x = q.get(*at).map_or(0.0, |x| x - j.spring_rest);
            0.5 * j.stiffness * x * x
        };
        self.joints.iter().zip(&self.q_at).filter(|(j, _)| j.stiffness != 0.0).map(spring).sum()
    }

    /// Joint `k`'s damping and spring forces, `d v + k (q − q₀)`, padded: what
    /// the joint resists with (subtracted from the applied forces).
    fn passive_forces(&self, k: usize, state: &TreeState<NQ, NV>) -> Vector6<f64> {
        let Some(j) = self.joints.get(k) else { return Vector6::zeros() };
        let mut out = self.joint_forces(k, &state.v) * j.damping;
        if j.stiffness != 0.0 {
            let position = self.q_at.get(k).and_then(|&at| state.q.get(at)).copied().unwrap_or(0.0);
            out[0] += j.stiffness * (position - j.spring_rest);
        }
        out
    }

    /// The bodies' gravity compensation (each body's fraction `c` of its
    /// weight held up at its centre of mass) as wrenches on the joints'
    /// children (link frames, moment about the joint point): what `c m`
    /// point masses at rest need against gravity. `None` without
    /// compensation. Every data index through `get` (the steps that call it
    /// are proved panic-free).
    pub(crate) fn compensation_wrenches(&self, q: &SVector<f64, NQ>) -> Option<[Vector6<f64>; NB]> {
        let c = self.compensation.as_ref()?;
        let ground = join(&Vector3::zeros(), &(-self.gravity));
        let (mut acc, mut f) = ([Vector6::zeros(); NB], [Vector6::zeros(); NB]);
        for k in 0..NB {
            let parent = self.parent[k].and_then(|p| acc.get(p).copied()).unwrap_or(ground);
            acc[k] = self.transform(k, q).motion(&parent);
            let body = self.joints[k].child;
            let m = c.get(body).copied().unwrap_or(0.0) * self.mass.get(body).map_or(0.0, |b| b.mass);
            f[k] = super::spatial::link_inertia(m, &Matrix3::zeros(), &(-self.joints[k].rho_child)) * acc[k];
        }
        Some(f)
    }

    /// Their joint forces, `Gᶜ(q)`: the compensated point masses' gravity
    /// torques, each wrench carried to the root and projected on the joints
    /// it passes. `None` without compensation.
    pub(crate) fn compensation_forces(&self, q: &SVector<f64, NQ>) -> Option<SVector<f64, NV>> {
        self.compensation_wrenches(q).map(|f| self.wrench_forces(q, &f))
    }

    /// Gravity compensation's share of the inverse dynamics' derivatives
    /// taken out of `out`: its joint forces `Gᶜ(q)` are the compensated
    /// point masses' inverse dynamics at rest, so their `τ` and `∂/∂q`
    /// subtract (nothing without compensation).
    #[inline(always)]
    pub(crate) fn subtract_compensation(&self, q: &SVector<f64, NQ>, out: &mut super::InverseDerivatives<NV>) {
        if self.compensation.is_none() {
            return;
        }
        let mut held = super::InverseDerivatives::<NV>::zeros();
        self.compensation_derivatives(q, &mut held);
        out.tau -= held.tau;
        out.d_q -= held.d_q;
    }

    /// The compensated masses' potential, `Σ c m g · r` (what their upward
    /// forces store): zero without compensation.
    pub(crate) fn compensation_energy(&self, system: &crate::SystemState<NB>) -> f64 {
        let Some(c) = &self.compensation else { return 0.0 };
        system.bodies.iter().zip(&self.mass).zip(c).map(|((b, m), c)| c * m.mass * self.gravity.dot(&b.r)).sum()
    }

    /// Joint `k`'s entries of `tau`, padded.
    fn joint_forces(&self, k: usize, tau: &SVector<f64, NV>) -> Vector6<f64> {
        // `k` through `get` too: out of line, the optimiser cannot bound it.
        let (Some(&at), Some(j)) = (self.v_at.get(k), self.joints.get(k)) else { return Vector6::zeros() };
        let n = j.kind.freedoms();
        Vector6::from_fn(|i, _| if i < n { get(tau, at + i) } else { 0.0 })
    }

    /// Writes joint `k`'s entries of `x` into `out`.
    fn put(&self, k: usize, x: &Vector6<f64>, out: &mut SVector<f64, NV>) {
        let (Some(&at), Some(j)) = (self.v_at.get(k), self.joints.get(k)) else { return };
        let n = j.kind.freedoms();
        for (i, x) in x.iter().enumerate().take(n) {
            set(out, at + i, *x);
        }
    }
}
