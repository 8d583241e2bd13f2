//! Geometric helpers run once, outside the hot path.

use nalgebra::{Matrix3, RealField, Vector3, Vector4};

/// Two unit vectors `(b, c)` perpendicular to `d` and to each other, with
/// `(d/|d|, b, c)` right-handed; `None` when `d` is zero or not finite.
///
/// `b` is `d × e` normalised, where `e` is the coordinate axis least aligned with
/// `d` (the first one on a tie), and `c = d̂ × b`. `#[derive(Joint)]` applies the
/// same rule at compile time to a constant sliding direction, so a constant `d`
/// and a field filled by this function give the same numbers.
///
/// ```
/// use joint_runtime::{nalgebra::Vector3, perpendicular_pair};
/// let (b, c) = perpendicular_pair(&Vector3::new(0.0, 0.0, 2.0)).unwrap();
/// assert_eq!(b.dot(&Vector3::z()), 0.0);
/// assert!((b.cross(&c) - Vector3::z()).norm() < 1e-15);
/// ```
pub fn perpendicular_pair<T: RealField + Copy>(d: &Vector3<T>) -> Option<(Vector3<T>, Vector3<T>)> {
    let norm = d.norm();
    if norm.partial_cmp(&T::zero()) != Some(core::cmp::Ordering::Greater) || !norm.is_finite() {
        return None;
    }
    let unit = d / norm;
    let (ax, ay, az) = (unit.x.abs(), unit.y.abs(), unit.z.abs());
    let e = if ax <= ay && ax <= az {
        Vector3::x()
    } else if ay <= az {
        Vector3::y()
    } else {
        Vector3::z()
    };
    let b = unit.cross(&e).normalize();
    let c = unit.cross(&b);
    Some((b, c))
}

/// An axis with its perpendicular pair, computed once, outside the hot path.
///
/// Joints defined by an axis take one instead of their perpendicular vectors:
/// `axis1` (in B1) stands for `f, g` (and a planar joint's normal `n`), `axis2`
/// (in B2) for `h` (and `k`), and the sliding direction `d` of
/// `universal_translational` for `b, c`. Declare a field of this type with that
/// name (or tagged `#[joint(axis1)]`); the generated code reads the parts it needs.
///
/// ```
/// use joint_runtime::{AxisFrame, nalgebra::Vector3};
/// let frame = AxisFrame::new(Vector3::new(0.0, 0.0, 3.0)).unwrap();
/// assert_eq!(frame.b.dot(&frame.axis), 0.0);
/// assert_eq!(frame.c.dot(&frame.b), 0.0);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(
    feature = "serde",
    serde(bound(
        serialize = "T: nalgebra::Scalar + serde::Serialize",
        deserialize = "T: nalgebra::Scalar + serde::Deserialize<'de>"
    ))
)]
pub struct AxisFrame<T> {
    /// The axis as given.
    pub axis: Vector3<T>,
    /// First unit vector perpendicular to the axis.
    pub b: Vector3<T>,
    /// Second unit vector, perpendicular to the axis and to `b`.
    pub c: Vector3<T>,
}

/// The frame of the sliding direction `d` of a two-angle joint with one
/// translational degree of freedom: `b, c` are the notes' axes perpendicular to `d`.
pub type SlidingFrame<T> = AxisFrame<T>;

impl<T: RealField + Copy> AxisFrame<T> {
    /// The frame of `axis`, by [`perpendicular_pair`]; `None` for a zero or non-finite axis.
    pub fn new(axis: Vector3<T>) -> Option<Self> {
        perpendicular_pair(&axis).map(|(b, c)| AxisFrame { axis, b, c })
    }
}

/// `A(p) = (e0² − eᵀe) I + 2 e eᵀ + 2 e0 ẽ` for `p = [e0, e1, e2, e3]`: the rotation
/// matrix for unit `p`, the homogeneous quadratic of `CONVENTIONS.md` otherwise.
pub fn rotation_matrix<T: RealField + Copy>(p: &Vector4<T>) -> Matrix3<T> {
    let (e0, e) = (p[0], Vector3::new(p[1], p[2], p[3]));
    let two = T::one() + T::one();
    Matrix3::identity() * (e0 * e0 - e.dot(&e)) + e * e.transpose() * two + e.cross_matrix() * (two * e0)
}
