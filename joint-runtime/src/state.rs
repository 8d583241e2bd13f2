//! State types: what the generated functions read, one type per kind of input.
//!
//! Euler parameters are stored scalar first, `p = [e0, e1, e2, e3]`, as in
//! `CONVENTIONS.md` (nalgebra's `Quaternion` stores the scalar last; use
//! [`EulerBody::from_rotation`] or [`OmegaBody::from_rotation`] to convert).

use nalgebra::{Matrix3, Quaternion, RealField, UnitQuaternion, Vector3, Vector4};

fn euler_parameters<T: RealField>(q: &UnitQuaternion<T>) -> Vector4<T> {
    Vector4::new(q.w.clone(), q.i.clone(), q.j.clone(), q.k.clone())
}

/// A body in the `euler` formulation: position, Euler parameters and their rates.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(
    feature = "serde",
    serde(bound(
        serialize = "T: nalgebra::Scalar + serde::Serialize",
        deserialize = "T: nalgebra::Scalar + serde::Deserialize<'de>"
    ))
)]
pub struct EulerBody<T> {
    /// Origin of the body frame, inertial components.
    pub r: Vector3<T>,
    /// Euler parameters `[e0, e1, e2, e3]`; need not be unit (Newton passes through such `p`).
    pub p: Vector4<T>,
    /// `ṙ`, inertial components.
    pub rdot: Vector3<T>,
    /// `ṗ`; need not be tangent to the unit sphere.
    pub pdot: Vector4<T>,
}

/// A body in the `omega_inertial` and `omega_body` formulations.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(
    feature = "serde",
    serde(bound(
        serialize = "T: nalgebra::Scalar + serde::Serialize",
        deserialize = "T: nalgebra::Scalar + serde::Deserialize<'de>"
    ))
)]
pub struct OmegaBody<T> {
    /// Origin of the body frame, inertial components.
    pub r: Vector3<T>,
    /// Unit Euler parameters `[e0, e1, e2, e3]`.
    pub p: Vector4<T>,
    /// `ṙ`, inertial components.
    pub rdot: Vector3<T>,
    /// Angular velocity: inertial components in `omega_inertial`, the body's own
    /// components in `omega_body`.
    pub omega: Vector3<T>,
}

impl<T: RealField> EulerBody<T> {
    /// A body at `r` with orientation `rotation`, moving with `rdot` and `pdot`.
    pub fn from_rotation(r: Vector3<T>, rotation: &UnitQuaternion<T>, rdot: Vector3<T>, pdot: Vector4<T>) -> Self {
        EulerBody { r, p: euler_parameters(rotation), rdot, pdot }
    }
}

impl<T: RealField> OmegaBody<T> {
    /// A body at `r` with orientation `rotation`, moving with `rdot` and `omega`.
    pub fn from_rotation(r: Vector3<T>, rotation: &UnitQuaternion<T>, rdot: Vector3<T>, omega: Vector3<T>) -> Self {
        OmegaBody { r, p: euler_parameters(rotation), rdot, omega }
    }
}

/// Orientation helpers (`CONVENTIONS.md`: `p = [e0, e1, e2, e3]`, scalar first).
impl<T: RealField + Copy> OmegaBody<T> {
    /// The orientation as a unit quaternion (`p` normalised).
    pub fn rotation(&self) -> UnitQuaternion<T> {
        UnitQuaternion::new_normalize(Quaternion::new(self.p[0], self.p[1], self.p[2], self.p[3]))
    }

    /// Sets `p` to `rotation`.
    pub fn set_rotation(&mut self, rotation: &UnitQuaternion<T>) {
        self.p = euler_parameters(rotation);
    }

    /// `A(p)`: body components to inertial ones.
    pub fn rotation_matrix(&self) -> Matrix3<T> {
        crate::rotation_matrix(&self.p)
    }

    /// The body-fixed point `local` (body components, from the body's origin) in
    /// inertial components: `r + A(p) local`.
    pub fn point(&self, local: &Vector3<T>) -> Vector3<T> {
        self.r + self.rotation_matrix() * local
    }

    /// ω in inertial components, `A(p) ω'`, when `omega` holds the body's own
    /// components (the `omega_body` formulation, and every scene).
    pub fn omega_inertial(&self) -> Vector3<T> {
        self.rotation_matrix() * self.omega
    }
}

impl OmegaBody<f64> {
    /// Turns the body by the rotation vector `theta` in its own components:
    /// `p ← p ⊗ q(θ')`, renormalised (the increment `q ⊕ δθ` the analyses take).
    pub fn turn(&mut self, theta: &Vector3<f64>) {
        self.p = crate::analysis::rotate_body(&self.p, theta);
    }
}

/// At the origin, unrotated (`p = [1, 0, 0, 0]`), at rest.
impl<T: RealField> Default for EulerBody<T> {
    fn default() -> Self {
        EulerBody { r: Vector3::zeros(), p: Vector4::x(), rdot: Vector3::zeros(), pdot: Vector4::zeros() }
    }
}

/// At the origin, unrotated (`p = [1, 0, 0, 0]`), at rest.
impl<T: RealField> Default for OmegaBody<T> {
    fn default() -> Self {
        OmegaBody { r: Vector3::zeros(), p: Vector4::x(), rdot: Vector3::zeros(), omega: Vector3::zeros() }
    }
}

/// The state of an absolute formulation: both bodies and the time.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct TwoBodies<B> {
    /// Body 1 (`B1`).
    pub body1: B,
    /// Body 2 (`B2`).
    pub body2: B,
    /// Time, read only by driven joints.
    pub t: f64,
}

/// The state of an absolute formulation with one body grounded (`ground = body1`
/// or `ground = body2`): only the free body remains.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct OneBody<B> {
    /// The body that is not the ground.
    pub body: B,
    /// Time, read only by driven joints.
    pub t: f64,
}

/// The state of a relative formulation (`relative_b1`, `relative_b2`).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(
    feature = "serde",
    serde(bound(
        serialize = "T: nalgebra::Scalar + serde::Serialize",
        deserialize = "T: nalgebra::Scalar + serde::Deserialize<'de>"
    ))
)]
pub struct RelativeState<T> {
    /// `δ`: the point `rho2` of B2 seen from the point `rho1` of B1, B1 components.
    pub delta: Vector3<T>,
    /// `p_rel` with `A(p_rel) = A1ᵀ A2`.
    pub p: Vector4<T>,
    /// `δ̇`, the time derivative of those components.
    pub delta_dot: Vector3<T>,
    /// ω of B2 relative to B1: B1 components in `relative_b1`, B2 components in `relative_b2`.
    pub omega: Vector3<T>,
    /// Time, read only by driven joints.
    pub t: f64,
}

impl<B> TwoBodies<B> {
    /// Both bodies at time zero.
    pub fn new(body1: B, body2: B) -> Self {
        TwoBodies { body1, body2, t: 0.0 }
    }
}

impl<B> OneBody<B> {
    /// The free body at time zero.
    pub fn new(body: B) -> Self {
        OneBody { body, t: 0.0 }
    }
}
