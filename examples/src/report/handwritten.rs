//! What a user writes without the library: Φ, J and γ by hand, with nalgebra,
//! from the lecture notes' matrix–vector forms and Haug's textbook
//! (*Computer-Aided Kinematics and Dynamics of Mechanical Systems*, 1989).
//!
//! Sixteen joint × formulation combinations, each a struct with the same
//! parameters, state, rows and columns as the derive's (`CONVENTIONS.md`), named
//! as in the conformance runner (`joint_tests::joints`), implementing
//! [`Joint<T, R, C>`] for every [`HandScalar`] (`f64`, `f32`, the counting
//! [`Counted`](super::counting::Counted)):
//!
//! | joint | formulations |
//! |---|---|
//! | `universal` | all five |
//! | `universal_translational` | all five |
//! | `spherical`, `revolute`, `translational` | `omega_body`, `euler` |
//!
//! The code is what a competent user would write, not a tuned kernel: the
//! rotation matrix `A(p)` entry by entry, skew matrices where the notes have
//! them, nalgebra's products, crosses and dots for the rest, and `evaluate`
//! computing the shared quantities (rotation matrices, joint points, the
//! separation `d`) once for Φ, J and γ. The formulas, row by row (`u = A1 a'`,
//! `v = A2 b'`, `s_i = A_i ρ_i'`, `d = r2 + s2 − r1 − s1`, `ω̃x = ω × x`):
//!
//! - **`omega_inertial`** (`u̇ = ω × u`). Spherical: `J = [−I, s̃1, I, −s̃2]`,
//!   `γ = ω1×(ω1×s1) − ω2×(ω2×s2)`. Dot-1: `J = [0, (u×v)ᵀ, 0, −(u×v)ᵀ]`,
//!   `γ = −[(ω1×(ω1×u))·v + 2(ω1×u)·(ω2×v) + u·(ω2×(ω2×v))]`. Dot-2:
//!   `J = [−uᵀ, (u×(r2 + s2 − r1))ᵀ, uᵀ, (s2×u)ᵀ]`,
//!   `γ = −[(ω1×(ω1×u))·d + 2(ω1×u)·ḋ + u·(ω2×(ω2×s2) − ω1×(ω1×s1))]`.
//! - **`omega_body`** (`u̇ = A (ω' × a')`, the notes' body-component forms with
//!   `C = A1ᵀ A2`). Spherical: `J = [−I, A1 ρ̃1, I, −A2 ρ̃2]`,
//!   `γ = A1(ω1'×(ω1'×ρ1)) − A2(ω2'×(ω2'×ρ2))`. Dot-1 (`a'ᵀ C b'`):
//!   `J = [0, (a×Cb)ᵀ, 0, (b×Cᵀa)ᵀ]`,
//!   `γ = −[(ω1'×(ω1'×a))·Cb + 2(ω1'×a)·C(ω2'×b) + Cᵀa·(ω2'×(ω2'×b))]`. Dot-2:
//!   `J = [−uᵀ, (a×A1ᵀ(r2 + s2 − r1))ᵀ, uᵀ, (ρ2×A2ᵀu)ᵀ]`, γ as in
//!   `omega_inertial` with `u̇ = A1(ω1'×a)`, `ü = A1(ω1'×(ω1'×a))`.
//! - **`euler`** (Haug: `∂(A(p)a')/∂p = B(p, a') = 2[(e0 I + ẽ)a', e a'ᵀ − (e0 I + ẽ)ã']`,
//!   and `d²/dt² (A a') = B(ṗ, a')ṗ = 2 A(ṗ) a'` at `p̈ = 0`; both exact off the
//!   unit sphere, where `A(p)` is the homogeneous quadratic of `CONVENTIONS.md`).
//!   Spherical: `J = [−I, −B(p1,ρ1), I, B(p2,ρ2)]`, `γ = 2A(ṗ1)ρ1 − 2A(ṗ2)ρ2`.
//!   Dot-1: `J = [0, vᵀB(p1,a), 0, uᵀB(p2,b)]`,
//!   `γ = −2[v·A(ṗ1)a + (B(p1,a)ṗ1)·(B(p2,b)ṗ2) + u·A(ṗ2)b]`. Dot-2:
//!   `J = [−uᵀ, dᵀB(p1,a) − uᵀB(p1,ρ1), uᵀ, uᵀB(p2,ρ2)]`,
//!   `γ = −[2d·A(ṗ1)a + 2(B(p1,a)ṗ1)·ḋ + 2u·(A(ṗ2)ρ2 − A(ṗ1)ρ1)]`.
//! - **`relative_b1`** (`A = A(p_rel)`, `v̇ = ω × v`): dot-1 `a·Ab`,
//!   `J = [0, (Ab×a)ᵀ]`, `γ = −a·(ω×(ω×Ab))`; dot-2 `a·δ`, `J = [aᵀ, 0]`, `γ = 0`;
//!   spherical `δ`, `J = [I, 0]`, `γ = 0`.
//! - **`relative_b2`** (`v̇ = A(ω × b)`): dot-1 `Aᵀa·b`, `J = [0, (b×Aᵀa)ᵀ]`,
//!   `γ = −Aᵀa·(ω×(ω×b))`; dot-2 and spherical as in `relative_b1`.
//!
//! `phi`, `jacobian` and `gamma` compute only what their output needs; `phi_t`
//! is zero (no joint here is driven) and `OPS` is all zeros: count with
//! [`count`](super::counting::count) instead.

use joint_runtime::nalgebra::{Matrix3, Matrix3x4, SMatrix, SVector, Scalar, Vector3, Vector4};
use joint_runtime::{EulerBody, Evaluation, Formulation, Joint, OmegaBody, Ops, RelativeState, TwoBodies};
use joint_tests::conformance::{Case, FromCase, required};

use super::counting::HandScalar;

// ---------------------------------------------------------------------------
// Haug's matrices
// ---------------------------------------------------------------------------

/// The skew matrix `ã` with `ã x = a × x`.
pub fn skew<T: HandScalar>(a: &Vector3<T>) -> Matrix3<T> {
    let o = T::zero();
    Matrix3::new(o, -a.z, a.y, a.z, o, -a.x, -a.y, a.x, o)
}

/// `A(p) = (e0² − eᵀe) I + 2 e eᵀ + 2 e0 ẽ`, entry by entry: the rotation matrix
/// for unit `p`, the homogeneous quadratic of `CONVENTIONS.md` otherwise.
pub fn rotation<T: HandScalar>(p: &Vector4<T>) -> Matrix3<T> {
    let (e0, e1, e2, e3) = (p[0], p[1], p[2], p[3]);
    let (e00, e11, e22, e33) = (e0 * e0, e1 * e1, e2 * e2, e3 * e3);
    let (e01, e02, e03) = (e0 * e1, e0 * e2, e0 * e3);
    let (e12, e13, e23) = (e1 * e2, e1 * e3, e2 * e3);
    let two = T::from_f64(2.0);
    Matrix3::new(
        e00 + e11 - e22 - e33,
        two * (e12 - e03),
        two * (e13 + e02),
        two * (e12 + e03),
        e00 - e11 + e22 - e33,
        two * (e23 - e01),
        two * (e13 - e02),
        two * (e23 + e01),
        e00 - e11 - e22 + e33,
    )
}

/// Haug's `B(p, a') = 2[(e0 I + ẽ)a', e a'ᵀ − (e0 I + ẽ)ã']` (3×4), the exact
/// derivative `∂(A(p) a')/∂p` for any `p`.
pub fn b_matrix<T: HandScalar>(p: &Vector4<T>, a: &Vector3<T>) -> Matrix3x4<T> {
    let (e0, e) = (p[0], Vector3::new(p[1], p[2], p[3]));
    let m = Matrix3::new(e0, -e.z, e.y, e.z, e0, -e.x, -e.y, e.x, e0); // e0 I + ẽ
    let two = T::from_f64(2.0);
    let first = m * a * two;
    let rest = (e * a.transpose() - m * skew(a)) * two;
    let mut b = Matrix3x4::zeros();
    b.set_column(0, &first);
    b.fixed_columns_mut::<3>(1).copy_from(&rest);
    b
}

// ---------------------------------------------------------------------------
// Shared pieces
// ---------------------------------------------------------------------------

/// Which outputs a call computes.
#[derive(Clone, Copy)]
struct Want {
    phi: bool,
    jacobian: bool,
    gamma: bool,
}

const PHI: Want = Want { phi: true, jacobian: false, gamma: false };
const JACOBIAN: Want = Want { phi: false, jacobian: true, gamma: false };
const GAMMA: Want = Want { phi: false, jacobian: false, gamma: true };
const ALL: Want = Want { phi: true, jacobian: true, gamma: true };

fn zero_evaluation<T: HandScalar, const R: usize, const C: usize>() -> Evaluation<T, R, C> {
    Evaluation { phi: SVector::zeros(), jacobian: SMatrix::zeros(), gamma: SVector::zeros() }
}

/// Copies `block` into `j` at `(row, col)`.
fn put<T: HandScalar, const R: usize, const C: usize, const BR: usize, const BC: usize>(
    j: &mut SMatrix<T, R, C>,
    row: usize,
    col: usize,
    block: &SMatrix<T, BR, BC>,
) {
    j.fixed_view_mut::<BR, BC>(row, col).copy_from(block);
}

/// Writes `v` into rows `row..row + 3` of `x`.
fn put3<T: HandScalar, const R: usize>(x: &mut SVector<T, R>, row: usize, v: &Vector3<T>) {
    x.fixed_rows_mut::<3>(row).copy_from(v);
}

fn identity<T: HandScalar>() -> Matrix3<T> {
    Matrix3::identity()
}

/// The joint points in inertial components and the separation:
/// `s1 = A1 ρ1`, `s2 = A2 ρ2`, `rel = r2 + s2 − r1` (P2 seen from O1), `d = rel − s1`.
struct Points<T: Scalar> {
    s1: Vector3<T>,
    s2: Vector3<T>,
    rel: Vector3<T>,
    d: Vector3<T>,
}

impl<T: HandScalar> Points<T> {
    fn new(
        r1: &Vector3<T>,
        a1: &Matrix3<T>,
        rho1: &Vector3<T>,
        r2: &Vector3<T>,
        a2: &Matrix3<T>,
        rho2: &Vector3<T>,
    ) -> Self {
        let (s1, s2) = (a1 * rho1, a2 * rho2);
        let rel = r2 + s2 - r1;
        let d = rel - s1;
        Points { s1, s2, rel, d }
    }
}

// ---------------------------------------------------------------------------
// omega_inertial
// ---------------------------------------------------------------------------

/// Rotation matrices and the velocities of an `omega_inertial` state.
struct Inertial<T: Scalar> {
    a1: Matrix3<T>,
    a2: Matrix3<T>,
    r1: Vector3<T>,
    r2: Vector3<T>,
    v1: Vector3<T>,
    v2: Vector3<T>,
    w1: Vector3<T>,
    w2: Vector3<T>,
}

impl<T: HandScalar> Inertial<T> {
    fn new(st: &TwoBodies<OmegaBody<T>>) -> Self {
        let (b1, b2) = (&st.body1, &st.body2);
        Inertial {
            a1: rotation(&b1.p),
            a2: rotation(&b2.p),
            r1: b1.r,
            r2: b2.r,
            v1: b1.rdot,
            v2: b2.rdot,
            w1: b1.omega,
            w2: b2.omega,
        }
    }

    fn points(&self, rho1: &Vector3<T>, rho2: &Vector3<T>) -> Points<T> {
        Points::new(&self.r1, &self.a1, rho1, &self.r2, &self.a2, rho2)
    }

    /// `[−I, s̃1, I, −s̃2]`.
    fn spherical_jacobian(&self, p: &Points<T>) -> SMatrix<T, 3, 12> {
        let mut j = SMatrix::zeros();
        put(&mut j, 0, 0, &-identity());
        put(&mut j, 0, 3, &skew(&p.s1));
        put(&mut j, 0, 6, &identity());
        put(&mut j, 0, 9, &-skew(&p.s2));
        j
    }

    /// `ω1×(ω1×s1) − ω2×(ω2×s2)`.
    fn spherical_gamma(&self, p: &Points<T>) -> Vector3<T> {
        self.w1.cross(&self.w1.cross(&p.s1)) - self.w2.cross(&self.w2.cross(&p.s2))
    }

    /// `[0, (u×v)ᵀ, 0, −(u×v)ᵀ]`.
    fn dot1_jacobian(&self, u: &Vector3<T>, v: &Vector3<T>) -> SMatrix<T, 1, 12> {
        let n = u.cross(v);
        let mut j = SMatrix::zeros();
        put(&mut j, 0, 3, &n.transpose());
        put(&mut j, 0, 9, &-n.transpose());
        j
    }

    /// `−[(ω1×(ω1×u))·v + 2(ω1×u)·(ω2×v) + u·(ω2×(ω2×v))]`.
    fn dot1_gamma(&self, u: &Vector3<T>, v: &Vector3<T>) -> T {
        let (w1u, w2v) = (self.w1.cross(u), self.w2.cross(v));
        -(self.w1.cross(&w1u).dot(v) + T::from_f64(2.0) * w1u.dot(&w2v) + u.dot(&self.w2.cross(&w2v)))
    }

    /// `ḋ = ṙ2 + ω2×s2 − ṙ1 − ω1×s1`.
    fn d_dot(&self, p: &Points<T>) -> Vector3<T> {
        self.v2 + self.w2.cross(&p.s2) - self.v1 - self.w1.cross(&p.s1)
    }

    /// `[−uᵀ, (u×(r2 + s2 − r1))ᵀ, uᵀ, (s2×u)ᵀ]`.
    fn dot2_jacobian(&self, u: &Vector3<T>, p: &Points<T>) -> SMatrix<T, 1, 12> {
        let mut j = SMatrix::zeros();
        put(&mut j, 0, 0, &-u.transpose());
        put(&mut j, 0, 3, &u.cross(&p.rel).transpose());
        put(&mut j, 0, 6, &u.transpose());
        put(&mut j, 0, 9, &p.s2.cross(u).transpose());
        j
    }

    /// `ω2×(ω2×s2) − ω1×(ω1×s1)`: the part of `d̈` without accelerations.
    fn d_ddot(&self, p: &Points<T>) -> Vector3<T> {
        self.w2.cross(&self.w2.cross(&p.s2)) - self.w1.cross(&self.w1.cross(&p.s1))
    }

    /// `−[(ω1×(ω1×u))·d + 2(ω1×u)·ḋ + u·d̈]`.
    fn dot2_gamma(&self, u: &Vector3<T>, p: &Points<T>, d_dot: &Vector3<T>, d_ddot: &Vector3<T>) -> T {
        let w1u = self.w1.cross(u);
        -(self.w1.cross(&w1u).dot(&p.d) + T::from_f64(2.0) * w1u.dot(d_dot) + u.dot(d_ddot))
    }
}

// ---------------------------------------------------------------------------
// omega_body
// ---------------------------------------------------------------------------

/// Rotation matrices and the velocities of an `omega_body` state (`w` in each body's components).
struct Body<T: Scalar> {
    a1: Matrix3<T>,
    a2: Matrix3<T>,
    r1: Vector3<T>,
    r2: Vector3<T>,
    v1: Vector3<T>,
    v2: Vector3<T>,
    w1: Vector3<T>,
    w2: Vector3<T>,
}

impl<T: HandScalar> Body<T> {
    fn new(st: &TwoBodies<OmegaBody<T>>) -> Self {
        let (b1, b2) = (&st.body1, &st.body2);
        Body {
            a1: rotation(&b1.p),
            a2: rotation(&b2.p),
            r1: b1.r,
            r2: b2.r,
            v1: b1.rdot,
            v2: b2.rdot,
            w1: b1.omega,
            w2: b2.omega,
        }
    }

    fn points(&self, rho1: &Vector3<T>, rho2: &Vector3<T>) -> Points<T> {
        Points::new(&self.r1, &self.a1, rho1, &self.r2, &self.a2, rho2)
    }

    /// `C = A1ᵀ A2`: B2's axes in B1 components.
    fn relative(&self) -> Matrix3<T> {
        self.a1.transpose() * self.a2
    }

    /// `[−I, A1 ρ̃1, I, −A2 ρ̃2]`.
    fn spherical_jacobian(&self, rho1: &Vector3<T>, rho2: &Vector3<T>) -> SMatrix<T, 3, 12> {
        let mut j = SMatrix::zeros();
        put(&mut j, 0, 0, &-identity());
        put(&mut j, 0, 3, &(self.a1 * skew(rho1)));
        put(&mut j, 0, 6, &identity());
        put(&mut j, 0, 9, &-(self.a2 * skew(rho2)));
        j
    }

    /// `A1(ω1'×(ω1'×ρ1))` and `A2(ω2'×(ω2'×ρ2))`, the accelerations of the joint points at `ω̇' = 0`.
    fn centripetal(&self, rho1: &Vector3<T>, rho2: &Vector3<T>) -> (Vector3<T>, Vector3<T>) {
        (self.a1 * self.w1.cross(&self.w1.cross(rho1)), self.a2 * self.w2.cross(&self.w2.cross(rho2)))
    }

    /// Dot-1 `a'ᵀ C b'` in body components, given `Cb` and `Cᵀa`: `[0, (a×Cb)ᵀ, 0, (b×Cᵀa)ᵀ]`.
    fn dot1_jacobian(&self, a: &Vector3<T>, b: &Vector3<T>, cb: &Vector3<T>, cta: &Vector3<T>) -> SMatrix<T, 1, 12> {
        let mut j = SMatrix::zeros();
        put(&mut j, 0, 3, &a.cross(cb).transpose());
        put(&mut j, 0, 9, &b.cross(cta).transpose());
        j
    }

    /// `−[(ω1'×(ω1'×a))·Cb + 2(ω1'×a)·C(ω2'×b) + Cᵀa·(ω2'×(ω2'×b))]`.
    fn dot1_gamma(
        &self,
        c: &Matrix3<T>,
        (a, cta): (&Vector3<T>, &Vector3<T>),
        (b, cb): (&Vector3<T>, &Vector3<T>),
    ) -> T {
        let (w1a, w2b) = (self.w1.cross(a), self.w2.cross(b));
        -(self.w1.cross(&w1a).dot(cb) + T::from_f64(2.0) * w1a.dot(&(c * w2b)) + cta.dot(&self.w2.cross(&w2b)))
    }

    /// `ḋ = ṙ2 + A2(ω2'×ρ2) − ṙ1 − A1(ω1'×ρ1)`.
    fn d_dot(&self, rho1: &Vector3<T>, rho2: &Vector3<T>) -> Vector3<T> {
        self.v2 + self.a2 * self.w2.cross(rho2) - self.v1 - self.a1 * self.w1.cross(rho1)
    }

    /// `[−uᵀ, (a×A1ᵀ(r2 + s2 − r1))ᵀ, uᵀ, (ρ2×A2ᵀu)ᵀ]` with `u = A1 a`.
    fn dot2_jacobian(&self, a: &Vector3<T>, u: &Vector3<T>, p: &Points<T>, rho2: &Vector3<T>) -> SMatrix<T, 1, 12> {
        let mut j = SMatrix::zeros();
        put(&mut j, 0, 0, &-u.transpose());
        put(&mut j, 0, 3, &a.cross(&(self.a1.transpose() * p.rel)).transpose());
        put(&mut j, 0, 6, &u.transpose());
        put(&mut j, 0, 9, &rho2.cross(&(self.a2.transpose() * u)).transpose());
        j
    }

    /// `−[ü·d + 2u̇·ḋ + u·d̈]` with `u̇ = A1(ω1'×a)`, `ü = A1(ω1'×(ω1'×a))` and
    /// `d̈ = A2(ω2'×(ω2'×ρ2)) − A1(ω1'×(ω1'×ρ1))` (no accelerations).
    fn dot2_gamma(&self, a: &Vector3<T>, u: &Vector3<T>, d: &Vector3<T>, d_dot: &Vector3<T>, d_ddot: &Vector3<T>) -> T {
        let w1a = self.w1.cross(a);
        let (u_dot, u_ddot) = (self.a1 * w1a, self.a1 * self.w1.cross(&w1a));
        -(u_ddot.dot(d) + T::from_f64(2.0) * u_dot.dot(d_dot) + u.dot(d_ddot))
    }
}

// ---------------------------------------------------------------------------
// euler
// ---------------------------------------------------------------------------

/// Euler parameters, their rates and rotation matrices of an `euler` state.
struct Euler<T: Scalar> {
    p1: Vector4<T>,
    p2: Vector4<T>,
    pd1: Vector4<T>,
    pd2: Vector4<T>,
    a1: Matrix3<T>,
    a2: Matrix3<T>,
    r1: Vector3<T>,
    r2: Vector3<T>,
    v1: Vector3<T>,
    v2: Vector3<T>,
}

impl<T: HandScalar> Euler<T> {
    fn new(st: &TwoBodies<EulerBody<T>>) -> Self {
        let (b1, b2) = (&st.body1, &st.body2);
        Euler {
            p1: b1.p,
            p2: b2.p,
            pd1: b1.pdot,
            pd2: b2.pdot,
            a1: rotation(&b1.p),
            a2: rotation(&b2.p),
            r1: b1.r,
            r2: b2.r,
            v1: b1.rdot,
            v2: b2.rdot,
        }
    }

    fn points(&self, rho1: &Vector3<T>, rho2: &Vector3<T>) -> Points<T> {
        Points::new(&self.r1, &self.a1, rho1, &self.r2, &self.a2, rho2)
    }

    /// `A(ṗ1)`, `A(ṗ2)`: `d²/dt² (A a') = 2 A(ṗ) a'` when `p̈ = 0`.
    fn rate_rotations(&self) -> (Matrix3<T>, Matrix3<T>) {
        (rotation(&self.pd1), rotation(&self.pd2))
    }

    /// `[−I, −B(p1,ρ1), I, B(p2,ρ2)]`.
    fn spherical_jacobian(&self, b1rho: &Matrix3x4<T>, b2rho: &Matrix3x4<T>) -> SMatrix<T, 3, 14> {
        let mut j = SMatrix::zeros();
        put(&mut j, 0, 0, &-identity());
        put(&mut j, 0, 3, &-b1rho);
        put(&mut j, 0, 7, &identity());
        put(&mut j, 0, 10, b2rho);
        j
    }

    /// `ḋ = ṙ2 + B(p2,ρ2)ṗ2 − ṙ1 − B(p1,ρ1)ṗ1`.
    fn d_dot(&self, b1rho: &Matrix3x4<T>, b2rho: &Matrix3x4<T>) -> Vector3<T> {
        self.v2 + b2rho * self.pd2 - self.v1 - b1rho * self.pd1
    }

    /// `2A(ṗ2)ρ2 − 2A(ṗ1)ρ1`: the part of `d̈` without `p̈`.
    fn d_ddot(&self, ad: &(Matrix3<T>, Matrix3<T>), rho1: &Vector3<T>, rho2: &Vector3<T>) -> Vector3<T> {
        (ad.1 * rho2 - ad.0 * rho1) * T::from_f64(2.0)
    }

    /// Dot-1 of `u = A1 a`, `v = A2 b`: `[0, vᵀB(p1,a), 0, uᵀB(p2,b)]`.
    fn dot1_jacobian(&self, u: &Vector3<T>, v: &Vector3<T>, ba: &Matrix3x4<T>, bb: &Matrix3x4<T>) -> SMatrix<T, 1, 14> {
        let mut j = SMatrix::zeros();
        put(&mut j, 0, 3, &(v.transpose() * ba));
        put(&mut j, 0, 10, &(u.transpose() * bb));
        j
    }

    /// `−2[v·A(ṗ1)a + (B(p1,a)ṗ1)·(B(p2,b)ṗ2) + u·A(ṗ2)b]`.
    fn dot1_gamma(
        &self,
        ad: &(Matrix3<T>, Matrix3<T>),
        (a, u, ba): (&Vector3<T>, &Vector3<T>, &Matrix3x4<T>),
        (b, v, bb): (&Vector3<T>, &Vector3<T>, &Matrix3x4<T>),
    ) -> T {
        let (u_dot, v_dot) = (ba * self.pd1, bb * self.pd2);
        -(v.dot(&(ad.0 * a)) + u_dot.dot(&v_dot) + u.dot(&(ad.1 * b))) * T::from_f64(2.0)
    }

    /// Dot-2 of `u = A1 a`: `[−uᵀ, dᵀB(p1,a) − uᵀB(p1,ρ1), uᵀ, uᵀB(p2,ρ2)]`.
    fn dot2_jacobian(
        &self,
        u: &Vector3<T>,
        ba: &Matrix3x4<T>,
        d: &Vector3<T>,
        b1rho: &Matrix3x4<T>,
        b2rho: &Matrix3x4<T>,
    ) -> SMatrix<T, 1, 14> {
        let mut j = SMatrix::zeros();
        put(&mut j, 0, 0, &-u.transpose());
        put(&mut j, 0, 3, &(d.transpose() * ba - u.transpose() * b1rho));
        put(&mut j, 0, 7, &u.transpose());
        put(&mut j, 0, 10, &(u.transpose() * b2rho));
        j
    }

    /// `−[2d·A(ṗ1)a + 2(B(p1,a)ṗ1)·ḋ + u·d̈]`.
    fn dot2_gamma(
        &self,
        ad: &(Matrix3<T>, Matrix3<T>),
        (a, u, ba): (&Vector3<T>, &Vector3<T>, &Matrix3x4<T>),
        d: &Vector3<T>,
        d_dot: &Vector3<T>,
        d_ddot: &Vector3<T>,
    ) -> T {
        let two = T::from_f64(2.0);
        -(two * d.dot(&(ad.0 * a)) + two * (ba * self.pd1).dot(d_dot) + u.dot(d_ddot))
    }
}

// ---------------------------------------------------------------------------
// relative_b1, relative_b2
// ---------------------------------------------------------------------------

/// `A(p_rel)` and the velocities of a relative state.
struct Relative<T: Scalar> {
    a: Matrix3<T>,
    delta: Vector3<T>,
    w: Vector3<T>,
}

impl<T: HandScalar> Relative<T> {
    fn new(st: &RelativeState<T>) -> Self {
        Relative { a: rotation(&st.p), delta: st.delta, w: st.omega }
    }

    /// Spherical rows `δ`: `J = [I, 0]`, `γ = 0`.
    fn spherical_jacobian(&self) -> SMatrix<T, 3, 6> {
        let mut j = SMatrix::zeros();
        put(&mut j, 0, 0, &identity());
        j
    }

    /// Dot-2 row `a'·δ`: `J = [a'ᵀ, 0]`, `γ = 0`.
    fn dot2_jacobian(&self, a: &Vector3<T>) -> SMatrix<T, 1, 6> {
        let mut j = SMatrix::zeros();
        put(&mut j, 0, 0, &a.transpose());
        j
    }

    /// Dot-1 with ω_rel in B1 components: `(a·v, [0, (v×a)ᵀ], −a·(ω×(ω×v)))`, `v = A b`.
    fn dot1_b1(&self, a: &Vector3<T>, b: &Vector3<T>, want: Want) -> (T, SMatrix<T, 1, 6>, T) {
        let v = self.a * b;
        let mut j = SMatrix::zeros();
        if want.jacobian {
            put(&mut j, 0, 3, &v.cross(a).transpose());
        }
        let gamma = if want.gamma { -a.dot(&self.w.cross(&self.w.cross(&v))) } else { T::zero() };
        (a.dot(&v), j, gamma)
    }

    /// Dot-1 with ω_rel in B2 components: `(Aᵀa·b, [0, (b×Aᵀa)ᵀ], −Aᵀa·(ω×(ω×b)))`.
    fn dot1_b2(&self, a: &Vector3<T>, b: &Vector3<T>, want: Want) -> (T, SMatrix<T, 1, 6>, T) {
        let a2 = self.a.transpose() * a;
        let mut j = SMatrix::zeros();
        if want.jacobian {
            put(&mut j, 0, 3, &b.cross(&a2).transpose());
        }
        let gamma = if want.gamma { -a2.dot(&self.w.cross(&self.w.cross(b))) } else { T::zero() };
        (a2.dot(b), j, gamma)
    }
}

// ---------------------------------------------------------------------------
// The joints
// ---------------------------------------------------------------------------

macro_rules! hand_joint {
    (
        $(#[$doc:meta])*
        $name:ident: $kind:literal, $form:ident, $state:ty, R = $r:literal, C = $c:literal,
        { $($p:ident: $pdoc:literal),* $(,)? }
    ) => {
        $(#[$doc])*
        #[derive(Clone, Copy, Debug, PartialEq)]
        pub struct $name<T> {
            $(#[doc = $pdoc] pub $p: Vector3<T>,)*
        }

        impl<T: Scalar> $name<T> {
            /// The same joint with every parameter component mapped by `f` (to a [`Counted`](super::counting::Counted) one, say).
            pub fn map<U: Scalar>(&self, mut f: impl FnMut(T) -> U) -> $name<U> {
                $name { $($p: self.$p.map(&mut f),)* }
            }
        }

        impl<T: HandScalar> Joint<T, $r, $c> for $name<T> {
            type State = $state;
            const KIND: &'static str = $kind;
            const FORMULATION: Formulation = Formulation::$form;
            /// Not counted at compile time: see [`count`](super::counting::count).
            const OPS: Ops = Ops { phi: 0, phi_t: 0, jacobian: 0, gamma: 0, evaluate: 0 };

            fn phi(&self, state: &Self::State) -> SVector<T, $r> {
                self.compute(state, PHI).phi
            }

            fn phi_t(&self, _state: &Self::State) -> SVector<T, $r> {
                SVector::zeros()
            }

            fn jacobian(&self, state: &Self::State) -> SMatrix<T, $r, $c> {
                self.compute(state, JACOBIAN).jacobian
            }

            fn gamma(&self, state: &Self::State) -> SVector<T, $r> {
                self.compute(state, GAMMA).gamma
            }

            fn evaluate(&self, state: &Self::State) -> Evaluation<T, $r, $c> {
                self.compute(state, ALL)
            }
        }

        /// Built from a whole conformance case: its `params`.
        impl FromCase for $name<f64> {
            fn from_case(case: &Case) -> Result<Self, String> {
                Ok($name { $($p: required(case.params.$p, stringify!($p))?.into(),)* })
            }
        }
    };
}

type Omega<T> = TwoBodies<OmegaBody<T>>;
type Eul<T> = TwoBodies<EulerBody<T>>;

// --- universal --------------------------------------------------------------

hand_joint! {
    /// `universal`, `omega_inertial`: spherical (3); dot-1(s, h). 4 rows, 12 columns.
    UniversalOmegaInertial: "universal", OmegaInertial, Omega<T>, R = 4, C = 12,
    { s: "Yoke axis fixed in B1.", h: "Yoke axis fixed in B2.", rho1: "Joint point in B1.", rho2: "Joint point in B2." }
}

impl<T: HandScalar> UniversalOmegaInertial<T> {
    fn compute(&self, st: &Omega<T>, want: Want) -> Evaluation<T, 4, 12> {
        let f = Inertial::new(st);
        let p = f.points(&self.rho1, &self.rho2);
        let (u, v) = (f.a1 * self.s, f.a2 * self.h);
        let mut e = zero_evaluation();
        if want.phi {
            put3(&mut e.phi, 0, &p.d);
            e.phi[3] = u.dot(&v);
        }
        if want.jacobian {
            put(&mut e.jacobian, 0, 0, &f.spherical_jacobian(&p));
            put(&mut e.jacobian, 3, 0, &f.dot1_jacobian(&u, &v));
        }
        if want.gamma {
            put3(&mut e.gamma, 0, &f.spherical_gamma(&p));
            e.gamma[3] = f.dot1_gamma(&u, &v);
        }
        e
    }
}

hand_joint! {
    /// `universal`, `omega_body`: spherical (3); dot-1(s, h). 4 rows, 12 columns.
    UniversalOmegaBody: "universal", OmegaBody, Omega<T>, R = 4, C = 12,
    { s: "Yoke axis fixed in B1.", h: "Yoke axis fixed in B2.", rho1: "Joint point in B1.", rho2: "Joint point in B2." }
}

impl<T: HandScalar> UniversalOmegaBody<T> {
    fn compute(&self, st: &Omega<T>, want: Want) -> Evaluation<T, 4, 12> {
        let f = Body::new(st);
        let c = f.relative();
        let ch = c * self.h;
        let mut e = zero_evaluation();
        if want.phi {
            put3(&mut e.phi, 0, &f.points(&self.rho1, &self.rho2).d);
            e.phi[3] = self.s.dot(&ch);
        }
        if want.jacobian || want.gamma {
            let cts = c.transpose() * self.s;
            if want.jacobian {
                put(&mut e.jacobian, 0, 0, &f.spherical_jacobian(&self.rho1, &self.rho2));
                put(&mut e.jacobian, 3, 0, &f.dot1_jacobian(&self.s, &self.h, &ch, &cts));
            }
            if want.gamma {
                let (c1, c2) = f.centripetal(&self.rho1, &self.rho2);
                put3(&mut e.gamma, 0, &(c1 - c2));
                e.gamma[3] = f.dot1_gamma(&c, (&self.s, &cts), (&self.h, &ch));
            }
        }
        e
    }
}

hand_joint! {
    /// `universal`, `euler`: spherical (3); dot-1(s, h). 4 rows, 14 columns.
    UniversalEuler: "universal", Euler, Eul<T>, R = 4, C = 14,
    { s: "Yoke axis fixed in B1.", h: "Yoke axis fixed in B2.", rho1: "Joint point in B1.", rho2: "Joint point in B2." }
}

impl<T: HandScalar> UniversalEuler<T> {
    fn compute(&self, st: &Eul<T>, want: Want) -> Evaluation<T, 4, 14> {
        let f = Euler::new(st);
        let (u, v) = (f.a1 * self.s, f.a2 * self.h);
        let mut e = zero_evaluation();
        if want.phi {
            put3(&mut e.phi, 0, &f.points(&self.rho1, &self.rho2).d);
            e.phi[3] = u.dot(&v);
        }
        if want.jacobian || want.gamma {
            let (bs, bh) = (b_matrix(&f.p1, &self.s), b_matrix(&f.p2, &self.h));
            if want.jacobian {
                let (b1rho, b2rho) = (b_matrix(&f.p1, &self.rho1), b_matrix(&f.p2, &self.rho2));
                put(&mut e.jacobian, 0, 0, &f.spherical_jacobian(&b1rho, &b2rho));
                put(&mut e.jacobian, 3, 0, &f.dot1_jacobian(&u, &v, &bs, &bh));
            }
            if want.gamma {
                let ad = f.rate_rotations();
                put3(&mut e.gamma, 0, &-f.d_ddot(&ad, &self.rho1, &self.rho2));
                e.gamma[3] = f.dot1_gamma(&ad, (&self.s, &u, &bs), (&self.h, &v, &bh));
            }
        }
        e
    }
}

hand_joint! {
    /// `universal`, `relative_b1`: `δ` (3); `s'ᵀ A(p_rel) h'`. 4 rows, 6 columns.
    UniversalRelativeB1: "universal", RelativeB1, RelativeState<T>, R = 4, C = 6,
    { s: "Yoke axis fixed in B1.", h: "Yoke axis fixed in B2.", rho1: "Joint point in B1 (no part in Φ).", rho2: "Joint point in B2 (no part in Φ)." }
}

impl<T: HandScalar> UniversalRelativeB1<T> {
    fn compute(&self, st: &RelativeState<T>, want: Want) -> Evaluation<T, 4, 6> {
        let f = Relative::new(st);
        let (phi, j, gamma) = f.dot1_b1(&self.s, &self.h, want);
        let mut e = zero_evaluation();
        if want.phi {
            put3(&mut e.phi, 0, &f.delta);
            e.phi[3] = phi;
        }
        if want.jacobian {
            put(&mut e.jacobian, 0, 0, &f.spherical_jacobian());
            put(&mut e.jacobian, 3, 0, &j);
        }
        if want.gamma {
            e.gamma[3] = gamma;
        }
        e
    }
}

hand_joint! {
    /// `universal`, `relative_b2`: `δ` (3); `s'ᵀ A(p_rel) h'`, ω_rel in B2 components. 4 rows, 6 columns.
    UniversalRelativeB2: "universal", RelativeB2, RelativeState<T>, R = 4, C = 6,
    { s: "Yoke axis fixed in B1.", h: "Yoke axis fixed in B2.", rho1: "Joint point in B1 (no part in Φ).", rho2: "Joint point in B2 (no part in Φ)." }
}

impl<T: HandScalar> UniversalRelativeB2<T> {
    fn compute(&self, st: &RelativeState<T>, want: Want) -> Evaluation<T, 4, 6> {
        let f = Relative::new(st);
        let (phi, j, gamma) = f.dot1_b2(&self.s, &self.h, want);
        let mut e = zero_evaluation();
        if want.phi {
            put3(&mut e.phi, 0, &f.delta);
            e.phi[3] = phi;
        }
        if want.jacobian {
            put(&mut e.jacobian, 0, 0, &f.spherical_jacobian());
            put(&mut e.jacobian, 3, 0, &j);
        }
        if want.gamma {
            e.gamma[3] = gamma;
        }
        e
    }
}

// --- universal_translational ------------------------------------------------

hand_joint! {
    /// `universal_translational` (the notes' two-angle joint with one translational
    /// DOF), `omega_inertial`: dot-2(b); dot-2(c); dot-1(s, h). 3 rows, 12 columns.
    UniversalTranslationalOmegaInertial: "universal_translational", OmegaInertial, Omega<T>, R = 3, C = 12,
    {
        s: "Yoke axis fixed in B1.", h: "Yoke axis fixed in B2.",
        b: "First normal to the sliding direction, fixed in B1.", c: "Second normal to the sliding direction, fixed in B1.",
        rho1: "Joint point in B1.", rho2: "Joint point in B2."
    }
}

impl<T: HandScalar> UniversalTranslationalOmegaInertial<T> {
    fn compute(&self, st: &Omega<T>, want: Want) -> Evaluation<T, 3, 12> {
        let f = Inertial::new(st);
        let p = f.points(&self.rho1, &self.rho2);
        let (ub, uc) = (f.a1 * self.b, f.a1 * self.c);
        let (u, v) = (f.a1 * self.s, f.a2 * self.h);
        let mut e = zero_evaluation();
        if want.phi {
            e.phi = SVector::from([ub.dot(&p.d), uc.dot(&p.d), u.dot(&v)]);
        }
        if want.jacobian {
            put(&mut e.jacobian, 0, 0, &f.dot2_jacobian(&ub, &p));
            put(&mut e.jacobian, 1, 0, &f.dot2_jacobian(&uc, &p));
            put(&mut e.jacobian, 2, 0, &f.dot1_jacobian(&u, &v));
        }
        if want.gamma {
            let (d_dot, d_ddot) = (f.d_dot(&p), f.d_ddot(&p));
            e.gamma = SVector::from([
                f.dot2_gamma(&ub, &p, &d_dot, &d_ddot),
                f.dot2_gamma(&uc, &p, &d_dot, &d_ddot),
                f.dot1_gamma(&u, &v),
            ]);
        }
        e
    }
}

hand_joint! {
    /// `universal_translational`, `omega_body`: dot-2(b); dot-2(c); dot-1(s, h). 3 rows, 12 columns.
    UniversalTranslationalOmegaBody: "universal_translational", OmegaBody, Omega<T>, R = 3, C = 12,
    {
        s: "Yoke axis fixed in B1.", h: "Yoke axis fixed in B2.",
        b: "First normal to the sliding direction, fixed in B1.", c: "Second normal to the sliding direction, fixed in B1.",
        rho1: "Joint point in B1.", rho2: "Joint point in B2."
    }
}

impl<T: HandScalar> UniversalTranslationalOmegaBody<T> {
    fn compute(&self, st: &Omega<T>, want: Want) -> Evaluation<T, 3, 12> {
        let f = Body::new(st);
        let p = f.points(&self.rho1, &self.rho2);
        let (ub, uc) = (f.a1 * self.b, f.a1 * self.c);
        let c = f.relative();
        let ch = c * self.h;
        let mut e = zero_evaluation();
        if want.phi {
            e.phi = SVector::from([ub.dot(&p.d), uc.dot(&p.d), self.s.dot(&ch)]);
        }
        if want.jacobian || want.gamma {
            let cts = c.transpose() * self.s;
            if want.jacobian {
                put(&mut e.jacobian, 0, 0, &f.dot2_jacobian(&self.b, &ub, &p, &self.rho2));
                put(&mut e.jacobian, 1, 0, &f.dot2_jacobian(&self.c, &uc, &p, &self.rho2));
                put(&mut e.jacobian, 2, 0, &f.dot1_jacobian(&self.s, &self.h, &ch, &cts));
            }
            if want.gamma {
                let d_dot = f.d_dot(&self.rho1, &self.rho2);
                let (c1, c2) = f.centripetal(&self.rho1, &self.rho2);
                let d_ddot = c2 - c1;
                e.gamma = SVector::from([
                    f.dot2_gamma(&self.b, &ub, &p.d, &d_dot, &d_ddot),
                    f.dot2_gamma(&self.c, &uc, &p.d, &d_dot, &d_ddot),
                    f.dot1_gamma(&c, (&self.s, &cts), (&self.h, &ch)),
                ]);
            }
        }
        e
    }
}

hand_joint! {
    /// `universal_translational`, `euler`: dot-2(b); dot-2(c); dot-1(s, h). 3 rows, 14 columns.
    UniversalTranslationalEuler: "universal_translational", Euler, Eul<T>, R = 3, C = 14,
    {
        s: "Yoke axis fixed in B1.", h: "Yoke axis fixed in B2.",
        b: "First normal to the sliding direction, fixed in B1.", c: "Second normal to the sliding direction, fixed in B1.",
        rho1: "Joint point in B1.", rho2: "Joint point in B2."
    }
}

impl<T: HandScalar> UniversalTranslationalEuler<T> {
    fn compute(&self, st: &Eul<T>, want: Want) -> Evaluation<T, 3, 14> {
        let f = Euler::new(st);
        let p = f.points(&self.rho1, &self.rho2);
        let (ub, uc) = (f.a1 * self.b, f.a1 * self.c);
        let (u, v) = (f.a1 * self.s, f.a2 * self.h);
        let mut e = zero_evaluation();
        if want.phi {
            e.phi = SVector::from([ub.dot(&p.d), uc.dot(&p.d), u.dot(&v)]);
        }
        if want.jacobian || want.gamma {
            let (bb, bc) = (b_matrix(&f.p1, &self.b), b_matrix(&f.p1, &self.c));
            let (bs, bh) = (b_matrix(&f.p1, &self.s), b_matrix(&f.p2, &self.h));
            let (b1rho, b2rho) = (b_matrix(&f.p1, &self.rho1), b_matrix(&f.p2, &self.rho2));
            if want.jacobian {
                put(&mut e.jacobian, 0, 0, &f.dot2_jacobian(&ub, &bb, &p.d, &b1rho, &b2rho));
                put(&mut e.jacobian, 1, 0, &f.dot2_jacobian(&uc, &bc, &p.d, &b1rho, &b2rho));
                put(&mut e.jacobian, 2, 0, &f.dot1_jacobian(&u, &v, &bs, &bh));
            }
            if want.gamma {
                let ad = f.rate_rotations();
                let (d_dot, d_ddot) = (f.d_dot(&b1rho, &b2rho), f.d_ddot(&ad, &self.rho1, &self.rho2));
                e.gamma = SVector::from([
                    f.dot2_gamma(&ad, (&self.b, &ub, &bb), &p.d, &d_dot, &d_ddot),
                    f.dot2_gamma(&ad, (&self.c, &uc, &bc), &p.d, &d_dot, &d_ddot),
                    f.dot1_gamma(&ad, (&self.s, &u, &bs), (&self.h, &v, &bh)),
                ]);
            }
        }
        e
    }
}

hand_joint! {
    /// `universal_translational`, `relative_b1`: `b'·δ`; `c'·δ`; `s'ᵀ A(p_rel) h'`. 3 rows, 6 columns.
    UniversalTranslationalRelativeB1: "universal_translational", RelativeB1, RelativeState<T>, R = 3, C = 6,
    {
        s: "Yoke axis fixed in B1.", h: "Yoke axis fixed in B2.",
        b: "First normal to the sliding direction, fixed in B1.", c: "Second normal to the sliding direction, fixed in B1.",
        rho1: "Joint point in B1 (no part in Φ).", rho2: "Joint point in B2 (no part in Φ)."
    }
}

impl<T: HandScalar> UniversalTranslationalRelativeB1<T> {
    fn compute(&self, st: &RelativeState<T>, want: Want) -> Evaluation<T, 3, 6> {
        let f = Relative::new(st);
        let (phi, j, gamma) = f.dot1_b1(&self.s, &self.h, want);
        let mut e = zero_evaluation();
        if want.phi {
            e.phi = SVector::from([self.b.dot(&f.delta), self.c.dot(&f.delta), phi]);
        }
        if want.jacobian {
            put(&mut e.jacobian, 0, 0, &f.dot2_jacobian(&self.b));
            put(&mut e.jacobian, 1, 0, &f.dot2_jacobian(&self.c));
            put(&mut e.jacobian, 2, 0, &j);
        }
        if want.gamma {
            e.gamma[2] = gamma;
        }
        e
    }
}

hand_joint! {
    /// `universal_translational`, `relative_b2`: `b'·δ`; `c'·δ`; `s'ᵀ A(p_rel) h'`, ω_rel in
    /// B2 components. 3 rows, 6 columns.
    UniversalTranslationalRelativeB2: "universal_translational", RelativeB2, RelativeState<T>, R = 3, C = 6,
    {
        s: "Yoke axis fixed in B1.", h: "Yoke axis fixed in B2.",
        b: "First normal to the sliding direction, fixed in B1.", c: "Second normal to the sliding direction, fixed in B1.",
        rho1: "Joint point in B1 (no part in Φ).", rho2: "Joint point in B2 (no part in Φ)."
    }
}

impl<T: HandScalar> UniversalTranslationalRelativeB2<T> {
    fn compute(&self, st: &RelativeState<T>, want: Want) -> Evaluation<T, 3, 6> {
        let f = Relative::new(st);
        let (phi, j, gamma) = f.dot1_b2(&self.s, &self.h, want);
        let mut e = zero_evaluation();
        if want.phi {
            e.phi = SVector::from([self.b.dot(&f.delta), self.c.dot(&f.delta), phi]);
        }
        if want.jacobian {
            put(&mut e.jacobian, 0, 0, &f.dot2_jacobian(&self.b));
            put(&mut e.jacobian, 1, 0, &f.dot2_jacobian(&self.c));
            put(&mut e.jacobian, 2, 0, &j);
        }
        if want.gamma {
            e.gamma[2] = gamma;
        }
        e
    }
}

// --- spherical --------------------------------------------------------------

hand_joint! {
    /// `spherical`, `omega_body`: `d = 0`. 3 rows, 12 columns.
    SphericalOmegaBody: "spherical", OmegaBody, Omega<T>, R = 3, C = 12,
    { rho1: "Joint point in B1.", rho2: "Joint point in B2." }
}

impl<T: HandScalar> SphericalOmegaBody<T> {
    fn compute(&self, st: &Omega<T>, want: Want) -> Evaluation<T, 3, 12> {
        let f = Body::new(st);
        let mut e = zero_evaluation();
        if want.phi {
            e.phi = f.points(&self.rho1, &self.rho2).d;
        }
        if want.jacobian {
            e.jacobian = f.spherical_jacobian(&self.rho1, &self.rho2);
        }
        if want.gamma {
            let (c1, c2) = f.centripetal(&self.rho1, &self.rho2);
            e.gamma = c1 - c2;
        }
        e
    }
}

hand_joint! {
    /// `spherical`, `euler`: `d = 0`. 3 rows, 14 columns.
    SphericalEuler: "spherical", Euler, Eul<T>, R = 3, C = 14,
    { rho1: "Joint point in B1.", rho2: "Joint point in B2." }
}

impl<T: HandScalar> SphericalEuler<T> {
    fn compute(&self, st: &Eul<T>, want: Want) -> Evaluation<T, 3, 14> {
        let f = Euler::new(st);
        let mut e = zero_evaluation();
        if want.phi {
            e.phi = f.points(&self.rho1, &self.rho2).d;
        }
        if want.jacobian {
            let (b1rho, b2rho) = (b_matrix(&f.p1, &self.rho1), b_matrix(&f.p2, &self.rho2));
            e.jacobian = f.spherical_jacobian(&b1rho, &b2rho);
        }
        if want.gamma {
            e.gamma = -f.d_ddot(&f.rate_rotations(), &self.rho1, &self.rho2);
        }
        e
    }
}

// --- revolute ---------------------------------------------------------------

hand_joint! {
    /// `revolute`, `omega_body`: spherical (3); dot-1(f, h); dot-1(g, h). 5 rows, 12 columns.
    RevoluteOmegaBody: "revolute", OmegaBody, Omega<T>, R = 5, C = 12,
    {
        f: "First normal to the axis, fixed in B1.", g: "Second normal to the axis, fixed in B1.",
        h: "The axis, fixed in B2.", rho1: "Joint point in B1.", rho2: "Joint point in B2."
    }
}

impl<T: HandScalar> RevoluteOmegaBody<T> {
    fn compute(&self, st: &Omega<T>, want: Want) -> Evaluation<T, 5, 12> {
        let fr = Body::new(st);
        let c = fr.relative();
        let ch = c * self.h;
        let mut e = zero_evaluation();
        if want.phi {
            put3(&mut e.phi, 0, &fr.points(&self.rho1, &self.rho2).d);
            e.phi[3] = self.f.dot(&ch);
            e.phi[4] = self.g.dot(&ch);
        }
        if want.jacobian || want.gamma {
            let (ctf, ctg) = (c.transpose() * self.f, c.transpose() * self.g);
            if want.jacobian {
                put(&mut e.jacobian, 0, 0, &fr.spherical_jacobian(&self.rho1, &self.rho2));
                put(&mut e.jacobian, 3, 0, &fr.dot1_jacobian(&self.f, &self.h, &ch, &ctf));
                put(&mut e.jacobian, 4, 0, &fr.dot1_jacobian(&self.g, &self.h, &ch, &ctg));
            }
            if want.gamma {
                let (c1, c2) = fr.centripetal(&self.rho1, &self.rho2);
                put3(&mut e.gamma, 0, &(c1 - c2));
                e.gamma[3] = fr.dot1_gamma(&c, (&self.f, &ctf), (&self.h, &ch));
                e.gamma[4] = fr.dot1_gamma(&c, (&self.g, &ctg), (&self.h, &ch));
            }
        }
        e
    }
}

hand_joint! {
    /// `revolute`, `euler`: spherical (3); dot-1(f, h); dot-1(g, h). 5 rows, 14 columns.
    RevoluteEuler: "revolute", Euler, Eul<T>, R = 5, C = 14,
    {
        f: "First normal to the axis, fixed in B1.", g: "Second normal to the axis, fixed in B1.",
        h: "The axis, fixed in B2.", rho1: "Joint point in B1.", rho2: "Joint point in B2."
    }
}

impl<T: HandScalar> RevoluteEuler<T> {
    fn compute(&self, st: &Eul<T>, want: Want) -> Evaluation<T, 5, 14> {
        let fr = Euler::new(st);
        let (uf, ug, v) = (fr.a1 * self.f, fr.a1 * self.g, fr.a2 * self.h);
        let mut e = zero_evaluation();
        if want.phi {
            put3(&mut e.phi, 0, &fr.points(&self.rho1, &self.rho2).d);
            e.phi[3] = uf.dot(&v);
            e.phi[4] = ug.dot(&v);
        }
        if want.jacobian || want.gamma {
            let (bf, bg, bh) = (b_matrix(&fr.p1, &self.f), b_matrix(&fr.p1, &self.g), b_matrix(&fr.p2, &self.h));
            if want.jacobian {
                let (b1rho, b2rho) = (b_matrix(&fr.p1, &self.rho1), b_matrix(&fr.p2, &self.rho2));
                put(&mut e.jacobian, 0, 0, &fr.spherical_jacobian(&b1rho, &b2rho));
                put(&mut e.jacobian, 3, 0, &fr.dot1_jacobian(&uf, &v, &bf, &bh));
                put(&mut e.jacobian, 4, 0, &fr.dot1_jacobian(&ug, &v, &bg, &bh));
            }
            if want.gamma {
                let ad = fr.rate_rotations();
                put3(&mut e.gamma, 0, &-fr.d_ddot(&ad, &self.rho1, &self.rho2));
                e.gamma[3] = fr.dot1_gamma(&ad, (&self.f, &uf, &bf), (&self.h, &v, &bh));
                e.gamma[4] = fr.dot1_gamma(&ad, (&self.g, &ug, &bg), (&self.h, &v, &bh));
            }
        }
        e
    }
}

// --- translational ----------------------------------------------------------

hand_joint! {
    /// `translational`, `omega_body`: dot-1(f, h); dot-1(g, h); dot-2(f); dot-2(g);
    /// dot-1(f, k). 5 rows, 12 columns.
    TranslationalOmegaBody: "translational", OmegaBody, Omega<T>, R = 5, C = 12,
    {
        f: "First normal to the sliding axis, fixed in B1.", g: "Second normal to the sliding axis, fixed in B1.",
        h: "The sliding axis, fixed in B2.", k: "A normal to `h`, fixed in B2.",
        rho1: "Joint point in B1.", rho2: "Joint point in B2."
    }
}

impl<T: HandScalar> TranslationalOmegaBody<T> {
    fn compute(&self, st: &Omega<T>, want: Want) -> Evaluation<T, 5, 12> {
        let fr = Body::new(st);
        let p = fr.points(&self.rho1, &self.rho2);
        let (uf, ug) = (fr.a1 * self.f, fr.a1 * self.g);
        let c = fr.relative();
        let (ch, ck) = (c * self.h, c * self.k);
        let mut e = zero_evaluation();
        if want.phi {
            e.phi = SVector::from([self.f.dot(&ch), self.g.dot(&ch), uf.dot(&p.d), ug.dot(&p.d), self.f.dot(&ck)]);
        }
        if want.jacobian || want.gamma {
            let (ctf, ctg) = (c.transpose() * self.f, c.transpose() * self.g);
            if want.jacobian {
                put(&mut e.jacobian, 0, 0, &fr.dot1_jacobian(&self.f, &self.h, &ch, &ctf));
                put(&mut e.jacobian, 1, 0, &fr.dot1_jacobian(&self.g, &self.h, &ch, &ctg));
                put(&mut e.jacobian, 2, 0, &fr.dot2_jacobian(&self.f, &uf, &p, &self.rho2));
                put(&mut e.jacobian, 3, 0, &fr.dot2_jacobian(&self.g, &ug, &p, &self.rho2));
                put(&mut e.jacobian, 4, 0, &fr.dot1_jacobian(&self.f, &self.k, &ck, &ctf));
            }
            if want.gamma {
                let d_dot = fr.d_dot(&self.rho1, &self.rho2);
                let (c1, c2) = fr.centripetal(&self.rho1, &self.rho2);
                let d_ddot = c2 - c1;
                e.gamma = SVector::from([
                    fr.dot1_gamma(&c, (&self.f, &ctf), (&self.h, &ch)),
                    fr.dot1_gamma(&c, (&self.g, &ctg), (&self.h, &ch)),
                    fr.dot2_gamma(&self.f, &uf, &p.d, &d_dot, &d_ddot),
                    fr.dot2_gamma(&self.g, &ug, &p.d, &d_dot, &d_ddot),
                    fr.dot1_gamma(&c, (&self.f, &ctf), (&self.k, &ck)),
                ]);
            }
        }
        e
    }
}

hand_joint! {
    /// `translational`, `euler`: dot-1(f, h); dot-1(g, h); dot-2(f); dot-2(g); dot-1(f, k).
    /// 5 rows, 14 columns.
    TranslationalEuler: "translational", Euler, Eul<T>, R = 5, C = 14,
    {
        f: "First normal to the sliding axis, fixed in B1.", g: "Second normal to the sliding axis, fixed in B1.",
        h: "The sliding axis, fixed in B2.", k: "A normal to `h`, fixed in B2.",
        rho1: "Joint point in B1.", rho2: "Joint point in B2."
    }
}

impl<T: HandScalar> TranslationalEuler<T> {
    fn compute(&self, st: &Eul<T>, want: Want) -> Evaluation<T, 5, 14> {
        let fr = Euler::new(st);
        let p = fr.points(&self.rho1, &self.rho2);
        let (uf, ug) = (fr.a1 * self.f, fr.a1 * self.g);
        let (vh, vk) = (fr.a2 * self.h, fr.a2 * self.k);
        let mut e = zero_evaluation();
        if want.phi {
            e.phi = SVector::from([uf.dot(&vh), ug.dot(&vh), uf.dot(&p.d), ug.dot(&p.d), uf.dot(&vk)]);
        }
        if want.jacobian || want.gamma {
            let (bf, bg) = (b_matrix(&fr.p1, &self.f), b_matrix(&fr.p1, &self.g));
            let (bh, bk) = (b_matrix(&fr.p2, &self.h), b_matrix(&fr.p2, &self.k));
            let (b1rho, b2rho) = (b_matrix(&fr.p1, &self.rho1), b_matrix(&fr.p2, &self.rho2));
            if want.jacobian {
                put(&mut e.jacobian, 0, 0, &fr.dot1_jacobian(&uf, &vh, &bf, &bh));
                put(&mut e.jacobian, 1, 0, &fr.dot1_jacobian(&ug, &vh, &bg, &bh));
                put(&mut e.jacobian, 2, 0, &fr.dot2_jacobian(&uf, &bf, &p.d, &b1rho, &b2rho));
                put(&mut e.jacobian, 3, 0, &fr.dot2_jacobian(&ug, &bg, &p.d, &b1rho, &b2rho));
                put(&mut e.jacobian, 4, 0, &fr.dot1_jacobian(&uf, &vk, &bf, &bk));
            }
            if want.gamma {
                let ad = fr.rate_rotations();
                let (d_dot, d_ddot) = (fr.d_dot(&b1rho, &b2rho), fr.d_ddot(&ad, &self.rho1, &self.rho2));
                let (f, g) = ((&self.f, &uf, &bf), (&self.g, &ug, &bg));
                e.gamma = SVector::from([
                    fr.dot1_gamma(&ad, f, (&self.h, &vh, &bh)),
                    fr.dot1_gamma(&ad, g, (&self.h, &vh, &bh)),
                    fr.dot2_gamma(&ad, f, &p.d, &d_dot, &d_ddot),
                    fr.dot2_gamma(&ad, g, &p.d, &d_dot, &d_ddot),
                    fr.dot1_gamma(&ad, f, (&self.k, &vk, &bk)),
                ]);
            }
        }
        e
    }
}
