//! Spatial vectors in a body's link frame (its axes, origin at its inbound
//! joint point): motions `(ω, v)` and forces `(n, f)` as `Vector6`, angular
//! part first.
//!
//! A joint's transform from its parent's frame to its child's is `(E, r)`:
//! `E` takes parent components to child components, `r` is the child's origin
//! from the parent's, parent components. As a matrix on motions
//! `X = [E 0; −E[r]× E]`; forces go back to the parent with `Xᵀ`.

use nalgebra::{Matrix3, Matrix6, Vector3, Vector6};

/// A parent-to-child transform `(E, r)`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Transform {
    /// Parent components to child components.
    pub e: Matrix3<f64>,
    /// The child's origin from the parent's, parent components.
    pub r: Vector3<f64>,
}

/// The angular and linear halves. Always inlined, as [`join`]: a call left
/// out of line has been left as one that may unwind, which the no-panic
/// proof of the recursions (`relative/recursion.rs`) cannot see through.
#[inline(always)]
pub(crate) fn split(m: &Vector6<f64>) -> (Vector3<f64>, Vector3<f64>) {
    (m.fixed_rows::<3>(0).into_owned(), m.fixed_rows::<3>(3).into_owned())
}

/// Joins an angular and a linear half.
#[inline(always)]
pub(crate) fn join(a: &Vector3<f64>, l: &Vector3<f64>) -> Vector6<f64> {
    Vector6::new(a.x, a.y, a.z, l.x, l.y, l.z)
}

impl Transform {
    /// `X m`: a parent motion in the child's frame (the velocity of the point
    /// at the child's origin is `v + ω × r`).
    #[inline]
    pub fn motion(&self, m: &Vector6<f64>) -> Vector6<f64> {
        let (w, v) = split(m);
        join(&(self.e * w), &(self.e * (v - self.r.cross(&w))))
    }

    /// `Xᵀ f`: a child force in the parent's frame (the moment about the
    /// parent's origin gains `r × f`).
    #[inline]
    pub fn force_back(&self, f: &Vector6<f64>) -> Vector6<f64> {
        let (n, f) = split(f);
        let (n, f) = (self.e.transpose() * n, self.e.transpose() * f);
        join(&(n + self.r.cross(&f)), &f)
    }

    /// `Xᵀ I X`: a child inertia (symmetric, `[A B; Bᵀ C]`) in the parent's
    /// frame, by blocks: rotated, then shifted by `R = [r]×`:
    /// `[A + R Bᵀ − B R − R C R, B + R C; Bᵀ − C R, C]` (rotated blocks).
    pub fn inertia_back(&self, i: &Matrix6<f64>) -> Matrix6<f64> {
        let et = self.e.transpose();
        let block = |r: usize, c: usize| et * i.fixed_view::<3, 3>(r, c) * self.e;
        let (a, b, c) = (block(0, 0), block(0, 3), block(3, 3));
        let rx = self.r.cross_matrix();
        let rc = rx * c;
        let top_right = b + rc;
        let top_left = a + rx * b.transpose() - b * rx - rc * rx;
        let mut out = Matrix6::zeros();
        out.fixed_view_mut::<3, 3>(0, 0).copy_from(&top_left);
        out.fixed_view_mut::<3, 3>(0, 3).copy_from(&top_right);
        out.fixed_view_mut::<3, 3>(3, 0).copy_from(&top_right.transpose());
        out.fixed_view_mut::<3, 3>(3, 3).copy_from(&c);
        out
    }
}

impl Transform {
    /// `Xᵀ [0 0; 0 C] X`: an inertia with only its translational block
    /// (what a spherical joint hands on): `[−R C' R, R C'; −C' R, C']`
    /// with `C' = Eᵀ C E`.
    pub fn translational_back(&self, c: &Matrix3<f64>) -> Matrix6<f64> {
        let c = self.e.transpose() * c * self.e;
        let rx = self.r.cross_matrix();
        let rc = rx * c;
        let mut out = Matrix6::zeros();
        out.fixed_view_mut::<3, 3>(0, 0).copy_from(&(-(rc * rx)));
        out.fixed_view_mut::<3, 3>(0, 3).copy_from(&rc);
        out.fixed_view_mut::<3, 3>(3, 0).copy_from(&rc.transpose());
        out.fixed_view_mut::<3, 3>(3, 3).copy_from(&c);
        out
    }
}

/// `a ×m b`: the motion cross product.
#[inline]
pub(crate) fn cross_motion(a: &Vector6<f64>, b: &Vector6<f64>) -> Vector6<f64> {
    let ((w, v), (bw, bv)) = (split(a), split(b));
    join(&w.cross(&bw), &(w.cross(&bv) + v.cross(&bw)))
}

/// `m ×f f`: the force cross product.
#[inline]
pub(crate) fn cross_force(m: &Vector6<f64>, f: &Vector6<f64>) -> Vector6<f64> {
    let ((w, v), (n, f)) = (split(m), split(f));
    join(&(w.cross(&n) + v.cross(&f)), &w.cross(&f))
}

/// A rigid body's spatial inertia about a point from which its centre of
/// mass is `c`, body axes: `[I_c + m [c]× [c]×ᵀ, m [c]×; m [c]×ᵀ, m 1]`.
pub(crate) fn link_inertia(mass: f64, inertia: &Matrix3<f64>, c: &Vector3<f64>) -> Matrix6<f64> {
    let cx = c.cross_matrix();
    let mut out = Matrix6::zeros();
    out.fixed_view_mut::<3, 3>(0, 0).copy_from(&(inertia + cx * cx.transpose() * mass));
    out.fixed_view_mut::<3, 3>(0, 3).copy_from(&(cx * mass));
    out.fixed_view_mut::<3, 3>(3, 0).copy_from(&(cx.transpose() * mass));
    out.fixed_view_mut::<3, 3>(3, 3).copy_from(&Matrix3::from_diagonal_element(mass));
    out
}
