//! Geometric helpers run once, outside the hot path.

use nalgebra::{Matrix3, RealField, Scalar, Vector3, Vector4};

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

/// The axes `b, c` of a two-angle joint with one translational degree of freedom,
/// computed once from the sliding direction `d` (fixed in B1).
///
/// Declare a field of this type named `d` (or tagged `#[joint(d)]`) instead of
/// the fields `b` and `c`; the generated code reads `b` and `c` from it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SlidingFrame<T: Scalar> {
    /// The sliding direction as given.
    pub d: Vector3<T>,
    /// First axis perpendicular to `d`.
    pub b: Vector3<T>,
    /// Second axis perpendicular to `d` and `b`.
    pub c: Vector3<T>,
}

impl<T: RealField + Copy> SlidingFrame<T> {
    /// The frame of `d`, by [`perpendicular_pair`]; `None` for a zero or non-finite `d`.
    pub fn new(d: Vector3<T>) -> Option<Self> {
        perpendicular_pair(&d).map(|(b, c)| SlidingFrame { d, b, c })
    }
}

/// `A(p) = (e0² − eᵀe) I + 2 e eᵀ + 2 e0 ẽ` for `p = [e0, e1, e2, e3]`: the rotation
/// matrix for unit `p`, the homogeneous quadratic of `CONVENTIONS.md` otherwise.
pub fn rotation_matrix<T: RealField + Copy>(p: &Vector4<T>) -> Matrix3<T> {
    let (e0, e) = (p[0], Vector3::new(p[1], p[2], p[3]));
    let two = T::one() + T::one();
    Matrix3::identity() * (e0 * e0 - e.dot(&e)) + e * e.transpose() * two + e.cross_matrix() * (two * e0)
}
