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

use nalgebra::{Quaternion, SMatrix, SVector, UnitQuaternion, Vector3, Vector4};

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

/// `m[(r, c)]`, or zero out of range.
pub(super) fn at<const R: usize, const C: usize>(m: &SMatrix<f64, R, C>, r: usize, c: usize) -> f64 {
    m.get((r, c)).copied().unwrap_or(0.0)
}

/// `m[(r, c)] = value` where in range.
pub(super) fn put<const R: usize, const C: usize>(m: &mut SMatrix<f64, R, C>, r: usize, c: usize, value: f64) {
    if let Some(slot) = m.get_mut((r, c)) {
        *slot = value;
    }
}

/// Column `c`'s quaternion at rows `r..r + 4` (w first).
fn quaternion_in<const R: usize, const C: usize>(m: &SMatrix<f64, R, C>, r: usize, c: usize) -> Quaternion<f64> {
    Quaternion::new(at(m, r, c), at(m, r + 1, c), at(m, r + 2, c), at(m, r + 3, c))
}

/// Column `c`'s three numbers at rows `r..r + 3`.
fn three_in<const R: usize, const C: usize>(m: &SMatrix<f64, R, C>, r: usize, c: usize) -> Vector3<f64> {
    Vector3::new(at(m, r, c), at(m, r + 1, c), at(m, r + 2, c))
}

impl<const NB: usize, const NQ: usize, const NV: usize> Tree<NB, NQ, NV> {
    /// The derivative of [`Tree::coordinate_rates`] at `(q, v)` along every
    /// column of `(dq, dv)`, `∂q̇/∂q dq + G(q) dv`, into `out` (a joint whose
    /// coordinates are its freedoms: rows copied; a quaternion's rate is
    /// bilinear; a free joint's offset rate `R(p̂) u = p ⊗ (0, u) ⊗ p̄ / |p|²`).
    pub(crate) fn rates_along_columns(
        &self,
        (q, v): (&SVector<f64, NQ>, &SVector<f64, NV>),
        (dq, dv): (&SMatrix<f64, NQ, NV>, &SMatrix<f64, NV, NV>),
        out: &mut SMatrix<f64, NQ, NV>,
    ) {
        for (k, j) in self.joints.iter().enumerate() {
            let (qa, va) = (self.q_at[k], self.v_at[k]);
            let (offset, turn) = match j.kind {
                TreeJointKind::Spherical => (false, Some((qa, va))),
                TreeJointKind::Free => (true, Some((qa + 3, va + 3))),
                kind => {
                    for c in 0..NV {
                        for i in 0..kind.freedoms() {
                            put(out, qa + i, c, at(dv, va + i, c));
                        }
                    }
                    continue;
                }
            };
            if let Some((qt, vt)) = turn {
                let (p, omega) = (quaternion_at(q, qt), Quaternion::from_imag(three(v, vt)));
                for c in 0..NV {
                    let d_omega = Quaternion::from_imag(three_in(dv, vt, c));
                    let d = (quaternion_in(dq, qt, c) * omega + p * d_omega) * 0.5;
                    for (i, x) in [d.w, d.i, d.j, d.k].into_iter().enumerate() {
                        put(out, qt + i, c, x);
                    }
                }
            }
            if offset {
                let p = quaternion_at(q, qa + 3);
                let u = Quaternion::from_imag(three(v, va));
                let n = p.norm_squared();
                let turned = p * u * p.conjugate();
                for c in 0..NV {
                    let (dp, du) = (quaternion_in(dq, qa + 3, c), Quaternion::from_imag(three_in(dv, va, c)));
                    let d = (dp * u * p.conjugate() + p * u * dp.conjugate() + p * du * p.conjugate()) / n
                        - turned * (2.0 * p.coords.dot(&dp.coords) / (n * n));
                    for (i, x) in d.imag().iter().enumerate() {
                        put(out, qa + i, c, *x);
                    }
                }
            }
        }
    }

    /// `T⁺(q)` of every column of `dq` into `out`: the increments the changes
    /// make (`δθ = 2 Im(p̄ ⊗ δp) / |p|²`, an offset's `R(p̂)ᵀ δr`).
    pub(crate) fn increments_of_columns(
        &self,
        q: &SVector<f64, NQ>,
        dq: &SMatrix<f64, NQ, NV>,
        out: &mut SMatrix<f64, NV, NV>,
    ) {
        for (k, j) in self.joints.iter().enumerate() {
            let (qa, va) = (self.q_at[k], self.v_at[k]);
            let turn_at = match j.kind {
                TreeJointKind::Spherical => (qa, va),
                TreeJointKind::Free => {
                    let back = unit_at(q, qa + 3).inverse();
                    for c in 0..NV {
                        let r = back * three_in(dq, qa, c);
                        for (i, x) in r.iter().enumerate() {
                            put(out, va + i, c, *x);
                        }
                    }
                    (qa + 3, va + 3)
                }
                kind => {
                    for c in 0..NV {
                        for i in 0..kind.freedoms() {
                            put(out, va + i, c, at(dq, qa + i, c));
                        }
                    }
                    continue;
                }
            };
            let p = quaternion_at(q, turn_at.0);
            let scale = 2.0 / p.norm_squared();
            let conjugate = p.conjugate();
            for c in 0..NV {
                let d = (conjugate * quaternion_in(dq, turn_at.0, c)).imag() * scale;
                for (i, x) in d.iter().enumerate() {
                    put(out, turn_at.1 + i, c, *x);
                }
            }
        }
    }

    /// The derivative of [`Tree::normalise`] at `q` along every column of
    /// `dq`, in place: each quaternion's `(dp − p̂ (p̂ · dp)) / |p|`.
    pub(crate) fn normalised_columns(&self, q: &SVector<f64, NQ>, dq: &mut SMatrix<f64, NQ, NV>) {
        for (k, j) in self.joints.iter().enumerate() {
            if let Some(offset) = j.kind.quaternion() {
                let r = self.q_at[k] + offset;
                let p = quaternion_at(q, r).coords;
                let n = p.norm();
                if n > 0.0 {
                    let hat = p / n;
                    for c in 0..NV {
                        let dp = quaternion_in(dq, r, c).coords;
                        let d = Quaternion::from((dp - hat * hat.dot(&dp)) / n);
                        for (i, x) in [d.w, d.i, d.j, d.k].into_iter().enumerate() {
                            put(dq, r + i, c, x);
                        }
                    }
                }
            }
        }
    }
}
