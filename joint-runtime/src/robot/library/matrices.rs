//! Matrices between the tree's conventions and a library's: the mass
//! matrix, Jacobians, the dynamics' derivatives and a step's Jacobian, both
//! ways, exactly (no differences).
//!
//! **The tangent map.** Both libraries and the tree perturb a coordinate
//! vector the way their velocities move it: the tree's free joint along its
//! body's axes and its quaternions in their own frames; MuJoCo's free joint
//! in the world's axes (`mj_integratePos`, `mjd_transitionFD`) and its
//! quaternions in their own frames; Pinocchio's free flyer along the link's
//! axes (`integrate` on SE(3), to first order) and its spherical joints in
//! their own frames. So one matrix `T(q)` takes the tree's velocities to
//! the library's and the tree's increments `δq` to the library's: `v_l = T
//! v`, `δq_l = T δq`. `T` is a reordering except at ball and free joints
//! (the link's rest turn and origin on its body), and depends on `q` only
//! at MuJoCo's free joint (the origin's velocity in the world's axes).
//!
//! **The terms `T` leaves.** Where `T` depends on `q` (MuJoCo's free joint),
//! four more matrices enter the chain rule, all zero elsewhere:
//! `D_v = ∂(T v)/∂q` (a velocity held in the library's components changes
//! the tree's as the body turns), `D_a = ∂(T a + c)/∂q` and `C_v = ∂c/∂v`
//! (MuJoCo's acceleration of the origin has the term `c = R (ω × w)`, `w` the
//! origin's velocity in the body), and `G = ∂(Tᵀ τ_l)/∂q` (a force held in
//! the world's components turns in the body's). With them, for forward
//! dynamics `a_l = T a + c`, `τ = Tᵀ τ_l`:
//!
//! ```text
//! ∂a_l/∂q_l = (D_a + T ∂a/∂q + T M⁻¹ G − (C_v + T ∂a/∂v) T⁻¹ D_v) T⁻¹
//! ∂a_l/∂v_l = (C_v + T ∂a/∂v) T⁻¹          ∂a_l/∂τ_l = T M⁻¹ Tᵀ
//! ```
//!
//! and likewise for inverse dynamics and a step (each function says its
//! formula). `M_l = T⁻ᵀ M T⁻¹` and `J_l = J T⁻¹` are the same rule without
//! the extra terms.

use nalgebra::{Matrix3, SMatrix, SVector, Vector3};

use super::{Library, LibraryJointKind, StateLayout, frame, tree_quaternion, vector3};
use crate::relative::{ForwardDerivatives, InverseDerivatives, StepJacobian, TreeState};

type Square<const NV: usize> = SMatrix<f64, NV, NV>;

/// The chain rule's pieces at one state (see the module's docs).
struct Terms<const NV: usize> {
    t: Square<NV>,
    t_inv: Square<NV>,
    /// `∂(T v)/∂q` at the state's `v`.
    d_v: Square<NV>,
    /// `∂(T a + c)/∂q` at the given accelerations.
    d_a: Square<NV>,
    /// `∂c/∂v`.
    c_v: Square<NV>,
    /// `∂(Tᵀ τ_l)/∂q` at the given forces.
    g: Square<NV>,
    /// `c`, MuJoCo's `ω × u` terms.
    c: SVector<f64, NV>,
}

/// `[x]×`: `cross(x) y = x × y`.
fn cross(x: &Vector3<f64>) -> Matrix3<f64> {
    x.cross_matrix()
}

fn put<const NV: usize>(m: &mut Square<NV>, (r, c): (usize, usize), block: &Matrix3<f64>) {
    m.fixed_view_mut::<3, 3>(r, c).copy_from(block);
}

impl<const NQ: usize, const NV: usize> StateLayout<NQ, NV> {
    /// `T(q)`: the library's velocities from the tree's, `v_l = T v`, at
    /// `state`'s coordinates; also the map of coordinate increments, the
    /// tangent on which each side differentiates by `q` (see the module's
    /// docs). A reordering but at ball and free joints; constant but at
    /// MuJoCo's free joints.
    pub fn tangent_map(&self, state: &TreeState<NQ, NV>) -> Square<NV> {
        self.terms(state, &SVector::zeros(), &SVector::zeros()).t
    }

    /// The chain rule's pieces at `state`, tree accelerations `a` and tree
    /// forces `tau`.
    fn terms(&self, state: &TreeState<NQ, NV>, a: &SVector<f64, NV>, tau: &SVector<f64, NV>) -> Terms<NV> {
        let z = Square::<NV>::zeros();
        let mut out = Terms { t: z, t_inv: z, d_v: z, d_a: z, c_v: z, g: z, c: SVector::zeros() };
        for j in self.joints {
            let (turn, origin) = frame(j);
            let (turn, back) =
                (turn.to_rotation_matrix().into_inner(), turn.inverse().to_rotation_matrix().into_inner());
            let (at, tv) = (j.v_at, j.tree_v_at);
            match j.kind {
                LibraryJointKind::Ball => {
                    put(&mut out.t, (at, tv), &back);
                    put(&mut out.t_inv, (tv, at), &turn);
                }
                LibraryJointKind::Free => {
                    let body = tree_quaternion(&state.q, j.tree_q_at + 3).to_rotation_matrix().into_inner();
                    // The origin's components: the world's (MuJoCo), the link's (Pinocchio).
                    let (to, from) = match self.library {
                        Library::MuJoCo => (body, body.transpose()),
                        Library::Pinocchio => (back, turn),
                    };
                    let o = cross(&origin);
                    put(&mut out.t, (at, tv), &to);
                    put(&mut out.t, (at, tv + 3), &(-to * o));
                    put(&mut out.t, (at + 3, tv + 3), &back);
                    put(&mut out.t_inv, (tv, at), &from);
                    put(&mut out.t_inv, (tv, at + 3), &(o * turn));
                    put(&mut out.t_inv, (tv + 3, at + 3), &turn);
                    if self.library == Library::MuJoCo {
                        free_terms(&mut out, (at, tv), (&body, &origin), (state, a, tau));
                    }
                }
                _ => {
                    out.t[(at, tv)] = 1.0;
                    out.t_inv[(tv, at)] = 1.0;
                }
            }
        }
        out
    }

    /// The mass matrix in the library's velocities from the tree's: `M_l =
    /// T⁻ᵀ M T⁻¹` (the same kinetic energy `½ vᵀ M v`). With
    /// [`mass_matrix_from`](Self::mass_matrix_from) the way back.
    pub fn mass_matrix_to(&self, state: &TreeState<NQ, NV>, m: &Square<NV>) -> Square<NV> {
        let t_inv = self.terms(state, &SVector::zeros(), &SVector::zeros()).t_inv;
        t_inv.transpose() * m * t_inv
    }

    /// The tree's mass matrix from the library's (`mj_fullM`, Pinocchio's
    /// `crba`): `M = Tᵀ M_l T`.
    pub fn mass_matrix_from(&self, state: &TreeState<NQ, NV>, m: &Square<NV>) -> Square<NV> {
        let t = self.tangent_map(state);
        t.transpose() * m * t
    }

    /// A Jacobian on the tree's velocities (`R` rows: a point's, a frame's,
    /// a constraint's) as one on the library's: `J_l = J T⁻¹`, so that `J_l
    /// v_l = J v`. The rows keep their meaning (and their frame).
    pub fn jacobian_to<const R: usize>(
        &self,
        state: &TreeState<NQ, NV>,
        j: &SMatrix<f64, R, NV>,
    ) -> SMatrix<f64, R, NV> {
        j * self.terms(state, &SVector::zeros(), &SVector::zeros()).t_inv
    }

    /// A Jacobian on the library's velocities as one on the tree's: `J =
    /// J_l T`.
    pub fn jacobian_from<const R: usize>(
        &self,
        state: &TreeState<NQ, NV>,
        j: &SMatrix<f64, R, NV>,
    ) -> SMatrix<f64, R, NV> {
        j * self.tangent_map(state)
    }
}

/// MuJoCo's free joint at `(at, tv)` (library and tree velocity offsets):
/// the terms of `T`'s dependence on the body's turn `body` (origin `origin`
/// on the body), at the state's velocities, accelerations `a` and forces
/// `tau` (the tree's). With `w = u + ω × o` the origin's velocity in the
/// body's axes and `s = u̇ + ω̇ × o + ω × w` its acceleration:
/// `∂(R x)/∂δθ = −R [x]×` gives `D_v = −R [w]×`, `D_a = −R [s]×`; `c = R (ω ×
/// w)` gives `∂c/∂u = R [ω]×`, `∂c/∂ω = −R ([w]× + [ω]× [o]×)`; and `Rᵀ f`
/// turning the other way, `G = [Rᵀ f]×` on the force's rows and `[o]× [Rᵀ
/// f]×` on the moment's.
#[allow(clippy::type_complexity)]
fn free_terms<const NQ: usize, const NV: usize>(
    out: &mut Terms<NV>,
    (at, tv): (usize, usize),
    (body, origin): (&Matrix3<f64>, &Vector3<f64>),
    (state, a, tau): (&TreeState<NQ, NV>, &SVector<f64, NV>, &SVector<f64, NV>),
) {
    let (u, omega) = (vector3(&state.v, tv), vector3(&state.v, tv + 3));
    let w = u + omega.cross(origin);
    let s = vector3(a, tv) + vector3(a, tv + 3).cross(origin) + omega.cross(&w);
    put(&mut out.d_v, (at, tv + 3), &(-body * cross(&w)));
    put(&mut out.d_a, (at, tv + 3), &(-body * cross(&s)));
    put(&mut out.c_v, (at, tv), &(body * cross(&omega)));
    put(&mut out.c_v, (at, tv + 3), &(-body * (cross(&w) + cross(&omega) * cross(origin))));
    out.c.fixed_rows_mut::<3>(at).copy_from(&(body * omega.cross(&w)));
    let force = cross(&vector3(tau, tv));
    put(&mut out.g, (tv, tv + 3), &force);
    put(&mut out.g, (tv + 3, tv + 3), &(cross(origin) * force));
}

impl<const NQ: usize, const NV: usize> StateLayout<NQ, NV> {
    /// The tree's forward-dynamics derivatives ([`ForwardDerivatives`] at
    /// `state` under the tree's forces `tau`) in the library's coordinates:
    /// its `qacc` and `∂qacc/∂(q, v, τ)` on its tangent (`∂/∂q` as
    /// `mjd_transitionFD` and Pinocchio's `computeABADerivatives` take it),
    /// by the formulas of the module's docs. Exact where the tree's are.
    pub fn forward_derivatives_to(
        &self,
        state: &TreeState<NQ, NV>,
        tau: &SVector<f64, NV>,
        d: &ForwardDerivatives<NV>,
    ) -> ForwardDerivatives<NV> {
        let k = self.terms(state, &d.qdd, tau);
        let v_part = k.c_v + k.t * d.d_v;
        ForwardDerivatives {
            qdd: k.t * d.qdd + k.c,
            d_q: (k.d_a + k.t * d.d_q + k.t * d.d_tau * k.g - v_part * k.t_inv * k.d_v) * k.t_inv,
            d_v: v_part * k.t_inv,
            d_tau: k.t * d.d_tau * k.t.transpose(),
        }
    }

    /// The way back of [`forward_derivatives_to`](Self::forward_derivatives_to):
    /// the library's derivatives (`d`, at the library's state `state` in
    /// the tree's terms and the tree's forces `tau`) as the tree's.
    pub fn forward_derivatives_from(
        &self,
        state: &TreeState<NQ, NV>,
        tau: &SVector<f64, NV>,
        d: &ForwardDerivatives<NV>,
    ) -> ForwardDerivatives<NV> {
        let k0 = self.terms(state, &SVector::zeros(), tau);
        let qdd = k0.t_inv * (d.qdd - k0.c);
        let k = self.terms(state, &qdd, tau);
        let d_tau = k.t_inv * d.d_tau * k.t_inv.transpose();
        let d_v = k.t_inv * (d.d_v * k.t - k.c_v);
        let v_part = k.c_v + k.t * d_v;
        let d_q = k.t_inv * (d.d_q * k.t - k.d_a - k.t * d_tau * k.g + v_part * k.t_inv * k.d_v);
        ForwardDerivatives { qdd, d_q, d_v, d_tau }
    }

    /// The tree's inverse-dynamics derivatives ([`InverseDerivatives`] at
    /// `state` and the tree's accelerations `a`) in the library's
    /// coordinates: `τ_l = T⁻ᵀ τ` and, with `I_q, I_v, I_a` the tree's,
    /// `∂τ_l/∂q_l = T⁻ᵀ (I_q − I_v T⁻¹ D_v − I_a T⁻¹ (D_a − C_v T⁻¹ D_v) −
    /// G) T⁻¹`, `∂τ_l/∂v_l = T⁻ᵀ (I_v − I_a T⁻¹ C_v) T⁻¹`, `∂τ_l/∂a_l = T⁻ᵀ
    /// I_a T⁻¹` (Pinocchio's `computeRNEADerivatives`, at the library's
    /// `a_l = T a + c` held).
    pub fn inverse_derivatives_to(
        &self,
        state: &TreeState<NQ, NV>,
        a: &SVector<f64, NV>,
        d: &InverseDerivatives<NV>,
    ) -> InverseDerivatives<NV> {
        let k = self.terms(state, a, &d.tau);
        let back = k.t_inv.transpose();
        let a_part = d.d_a * k.t_inv;
        let q_part = d.d_q - d.d_v * k.t_inv * k.d_v - a_part * (k.d_a - k.c_v * k.t_inv * k.d_v) - k.g;
        InverseDerivatives {
            tau: back * d.tau,
            d_q: back * q_part * k.t_inv,
            d_v: back * (d.d_v - a_part * k.c_v) * k.t_inv,
            d_a: back * d.d_a * k.t_inv,
        }
    }

    /// The way back of [`inverse_derivatives_to`](Self::inverse_derivatives_to):
    /// the library's (`d`, at `state` in the tree's terms and the tree's
    /// accelerations `a`) as the tree's.
    pub fn inverse_derivatives_from(
        &self,
        state: &TreeState<NQ, NV>,
        a: &SVector<f64, NV>,
        d: &InverseDerivatives<NV>,
    ) -> InverseDerivatives<NV> {
        let t = self.tangent_map(state);
        let tau = t.transpose() * d.tau;
        let k = self.terms(state, a, &tau);
        let d_a = t.transpose() * d.d_a * t;
        let a_part = d_a * k.t_inv;
        let d_v = t.transpose() * d.d_v * t + a_part * k.c_v;
        let d_q = t.transpose() * d.d_q * t + d_v * k.t_inv * k.d_v + a_part * (k.d_a - k.c_v * k.t_inv * k.d_v) + k.g;
        InverseDerivatives { tau, d_q, d_v, d_a }
    }

    /// A step's Jacobian ([`StepJacobian`]: from `start` under the tree's
    /// forces `tau`, held over the step, to `end`) in the library's
    /// coordinates at both ends, with the forces `τ_l = T₀⁻ᵀ τ` held in the
    /// library's components at the start. With `X` a row of blocks
    /// (`∂q₁`, `∂v₁`): `E_q = (X_q + X_τ G₀ − X_v T₀⁻¹ D_v₀) T₀⁻¹`, `E_v =
    /// X_v T₀⁻¹`, `E_τ = X_τ T₀ᵀ`, then `∂q₁_l = T₁ E(∂q₁)` and `∂v₁_l =
    /// D_v₁ E(∂q₁) + T₁ E(∂v₁)` (what `mjd_transitionFD` differences,
    /// exactly).
    pub fn step_jacobian_to(
        &self,
        (start, tau): (&TreeState<NQ, NV>, &SVector<f64, NV>),
        end: &TreeState<NQ, NV>,
        j: &StepJacobian<NV>,
    ) -> StepJacobian<NV> {
        let (k0, k1) = (self.terms(start, &SVector::zeros(), tau), self.terms(end, &SVector::zeros(), tau));
        let start_side = |[x_q, x_v, x_tau]: [&Square<NV>; 3]| {
            [(x_q + x_tau * k0.g - x_v * k0.t_inv * k0.d_v) * k0.t_inv, x_v * k0.t_inv, x_tau * k0.t.transpose()]
        };
        let [qq, qv, qt] = start_side([&j.q_q, &j.q_v, &j.q_tau]);
        let [vq, vv, vt] = start_side([&j.v_q, &j.v_v, &j.v_tau]);
        let (t1, d1) = (&k1.t, &k1.d_v);
        StepJacobian {
            q_q: t1 * qq,
            q_v: t1 * qv,
            q_tau: t1 * qt,
            v_q: d1 * qq + t1 * vq,
            v_v: d1 * qv + t1 * vv,
            v_tau: d1 * qt + t1 * vt,
        }
    }

    /// The way back of [`step_jacobian_to`](Self::step_jacobian_to): the
    /// library's step Jacobian (`j`, from `start` under the tree's forces
    /// `tau` to `end`, both in the tree's terms) as the tree's.
    pub fn step_jacobian_from(
        &self,
        (start, tau): (&TreeState<NQ, NV>, &SVector<f64, NV>),
        end: &TreeState<NQ, NV>,
        j: &StepJacobian<NV>,
    ) -> StepJacobian<NV> {
        let (k0, k1) = (self.terms(start, &SVector::zeros(), tau), self.terms(end, &SVector::zeros(), tau));
        let (qq, qv, qt) = (k1.t_inv * j.q_q, k1.t_inv * j.q_v, k1.t_inv * j.q_tau);
        let end_side = |x: &Square<NV>, q: &Square<NV>| k1.t_inv * (x - k1.d_v * q);
        let (vq, vv, vt) = (end_side(&j.v_q, &qq), end_side(&j.v_v, &qv), end_side(&j.v_tau, &qt));
        let start_side = |[e_q, e_v, e_tau]: [Square<NV>; 3]| {
            let (x_v, x_tau) = (e_v * k0.t, e_tau * k0.t_inv.transpose());
            [e_q * k0.t - x_tau * k0.g + x_v * k0.t_inv * k0.d_v, x_v, x_tau]
        };
        let [q_q, q_v, q_tau] = start_side([qq, qv, qt]);
        let [v_q, v_v, v_tau] = start_side([vq, vv, vt]);
        StepJacobian { q_q, q_v, q_tau, v_q, v_v, v_tau }
    }
}
