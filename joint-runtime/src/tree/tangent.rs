//! The tree's coordinates against its tangent space, to first order: what
//! the chain rule of a step's Jacobian needs where a joint's coordinates are
//! not its freedoms (a quaternion: four numbers, three freedoms).
//!
//! An increment `δ` (velocity-shaped, [`Tree::displace`]) moves the
//! coordinates by `T(q) δ`: an angle or a slide by itself; a quaternion `p`
//! by `½ p ⊗ (0, δθ)` (turned in its own frame); a free joint's offset by
//! `R(p̂) δ` (along its child's axes). `T⁺(q)` takes a change of the
//! coordinates back to the increment (the radial part of a quaternion's,
//! which no rotation sees, dropped): `δθ = 2 Im(p̄ ⊗ δp) / |p|²`,
//! `δ = R(p̂)ᵀ δr`. Both hold at any `p ≠ 0`, unit or not (an RK4 stage's is
//! not), as the derive's derivatives do.

use nalgebra::{Quaternion, SVector, UnitQuaternion, Vector3, Vector4};

use super::TreeJointKind;
use super::kinematics::unit;
use super::topology::Tree;

// Every access below goes through `get`: the offsets are the tree's own,
// checked by `Tree::new`, and a slice that cannot go out of range leaves no
// panic path for the no-panic proof to find.

/// `x[i]`, or zero past the end.
pub(super) fn get<const N: usize>(x: &SVector<f64, N>, i: usize) -> f64 {
    x.get(i).copied().unwrap_or(0.0)
}

/// `x[i] = value` where `i` is in range.
pub(super) fn set<const N: usize>(x: &mut SVector<f64, N>, i: usize, value: f64) {
    if let Some(slot) = x.get_mut(i) {
        *slot = value;
    }
}

/// The quaternion at `q[at..at + 4]` (w first).
pub(super) fn quaternion_at<const N: usize>(q: &SVector<f64, N>, at: usize) -> Quaternion<f64> {
    Quaternion::new(get(q, at), get(q, at + 1), get(q, at + 2), get(q, at + 3))
}

/// The unit quaternion at `q[at..at + 4]`.
pub(super) fn unit_at<const N: usize>(q: &SVector<f64, N>, at: usize) -> UnitQuaternion<f64> {
    let p = quaternion_at(q, at);
    unit(&Vector4::new(p.w, p.i, p.j, p.k))
}

/// The three numbers at `x[at..at + 3]`.
pub(super) fn three<const N: usize>(x: &SVector<f64, N>, at: usize) -> Vector3<f64> {
    Vector3::new(get(x, at), get(x, at + 1), get(x, at + 2))
}

/// `x[at..at + 3] = value`.
pub(super) fn put_three<const N: usize>(x: &mut SVector<f64, N>, at: usize, value: &Vector3<f64>) {
    for (i, v) in value.iter().enumerate() {
        set(x, at + i, *v);
    }
}

/// `x[at..at + 4] = p` (w first).
pub(super) fn put_quaternion<const N: usize>(x: &mut SVector<f64, N>, at: usize, p: &Quaternion<f64>) {
    for (i, v) in [p.w, p.i, p.j, p.k].into_iter().enumerate() {
        set(x, at + i, v);
    }
}

impl<const NB: usize, const NQ: usize, const NV: usize> Tree<NB, NQ, NV> {
    /// `T(q) δ`: the coordinates' change along the increment `delta`.
    pub(crate) fn along_increment(&self, q: &SVector<f64, NQ>, delta: &SVector<f64, NV>) -> SVector<f64, NQ> {
        let mut out = SVector::<f64, NQ>::zeros();
        for (k, j) in self.joints.iter().enumerate() {
            let (qa, va) = (self.q_at[k], self.v_at[k]);
            match j.kind {
                TreeJointKind::Spherical => spin_into(q, delta, (qa, va), &mut out),
                TreeJointKind::Free => {
                    let r = unit_at(q, qa + 3) * three(delta, va);
                    put_three(&mut out, qa, &r);
                    spin_into(q, delta, (qa + 3, va + 3), &mut out);
                }
                kind => {
                    for i in 0..kind.freedoms() {
                        set(&mut out, qa + i, get(delta, va + i));
                    }
                }
            }
        }
        out
    }

    /// `T⁺(q) dq`: the increment a change `dq` of the coordinates makes.
    pub(crate) fn increment_of(&self, q: &SVector<f64, NQ>, dq: &SVector<f64, NQ>) -> SVector<f64, NV> {
        let mut out = SVector::<f64, NV>::zeros();
        let turn = |at: usize| -> Vector3<f64> {
            let p = quaternion_at(q, at);
            let d = p.conjugate() * quaternion_at(dq, at) * (2.0 / p.norm_squared());
            d.imag()
        };
        for (k, j) in self.joints.iter().enumerate() {
            let (qa, va) = (self.q_at[k], self.v_at[k]);
            match j.kind {
                TreeJointKind::Spherical => put_three(&mut out, va, &turn(qa)),
                TreeJointKind::Free => {
                    let r = unit_at(q, qa + 3).inverse() * three(dq, qa);
                    put_three(&mut out, va, &r);
                    put_three(&mut out, va + 3, &turn(qa + 3));
                }
                kind => {
                    for i in 0..kind.freedoms() {
                        set(&mut out, va + i, get(dq, qa + i));
                    }
                }
            }
        }
        out
    }

    /// The derivative of [`Tree::coordinate_rates`] at `(q, v)` along
    /// `(dq, dv)`: `∂q̇/∂q dq + G(q) dv`.
    pub(crate) fn rates_along(
        &self,
        (q, v): (&SVector<f64, NQ>, &SVector<f64, NV>),
        (dq, dv): (&SVector<f64, NQ>, &SVector<f64, NV>),
    ) -> SVector<f64, NQ> {
        let mut out = SVector::<f64, NQ>::zeros();
        // ½ (dp ⊗ (0, ω) + p ⊗ (0, dω)): the spin's rate is bilinear.
        let spin = |out: &mut SVector<f64, NQ>, (qa, va): (usize, usize)| {
            let omega = Quaternion::from_imag(three(v, va));
            let d_omega = Quaternion::from_imag(three(dv, va));
            let d = (quaternion_at(dq, qa) * omega + quaternion_at(q, qa) * d_omega) * 0.5;
            put_quaternion(out, qa, &d);
        };
        for (k, j) in self.joints.iter().enumerate() {
            let (qa, va) = (self.q_at[k], self.v_at[k]);
            match j.kind {
                TreeJointKind::Spherical => spin(&mut out, (qa, va)),
                TreeJointKind::Free => {
                    // R(p̂) u = p ⊗ (0, u) ⊗ p̄ / |p|², differentiated in p and u.
                    let (p, dp) = (quaternion_at(q, qa + 3), quaternion_at(dq, qa + 3));
                    let (u, du) = (Quaternion::from_imag(three(v, va)), Quaternion::from_imag(three(dv, va)));
                    let n = p.norm_squared();
                    let turned = p * u * p.conjugate();
                    let d = (dp * u * p.conjugate() + p * u * dp.conjugate() + p * du * p.conjugate()) / n
                        - turned * (2.0 * p.coords.dot(&dp.coords) / (n * n));
                    put_three(&mut out, qa, &d.imag());
                    spin(&mut out, (qa + 3, va + 3));
                }
                kind => {
                    for i in 0..kind.freedoms() {
                        set(&mut out, qa + i, get(dv, va + i));
                    }
                }
            }
        }
        out
    }

    /// The derivative of [`Tree::normalise`] at `q` along `dq`: each
    /// quaternion's `(dp − p̂ (p̂ · dp)) / |p|`, the rest unchanged.
    pub(crate) fn normalised_along(&self, q: &SVector<f64, NQ>, dq: &SVector<f64, NQ>) -> SVector<f64, NQ> {
        let mut out = *dq;
        for (k, j) in self.joints.iter().enumerate() {
            if let Some(at) = j.kind.quaternion() {
                let at = self.q_at[k] + at;
                let (p, dp) = (quaternion_at(q, at).coords, quaternion_at(dq, at).coords);
                let n = p.norm();
                if n > 0.0 {
                    let hat = p / n;
                    // `coords` are (i, j, k, w): back through a quaternion to w first.
                    let d = Quaternion::from((dp - hat * hat.dot(&dp)) / n);
                    put_quaternion(&mut out, at, &d);
                }
            }
        }
        out
    }
}

/// `½ p ⊗ (0, δθ)` of the quaternion at `q[qa..]` and the increment at
/// `delta[va..]`, into `out`.
fn spin_into<const NQ: usize, const NV: usize>(
    q: &SVector<f64, NQ>,
    delta: &SVector<f64, NV>,
    (qa, va): (usize, usize),
    out: &mut SVector<f64, NQ>,
) {
    let d = quaternion_at(q, qa) * Quaternion::from_imag(three(delta, va)) * 0.5;
    put_quaternion(out, qa, &d);
}
