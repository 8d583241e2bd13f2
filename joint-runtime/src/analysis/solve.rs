//! Minimum-norm solves of `J x = b` in the Euclidean or the kinetic-energy
//! metric, through the rank-revealing factorisation of the Gram matrix.

use nalgebra::{Matrix3, SVector};

/// Inverse mass of one body: `1/m` and `J'⁻¹` (public only for the code the
/// derive writes: [`SparseJacobian::normal_blocks_into`](crate::SparseJacobian)).
#[derive(Clone, Copy, Debug, PartialEq)]
#[doc(hidden)]
pub struct InverseMass {
    pub(crate) inv_mass: f64,
    pub(crate) inv_inertia: Matrix3<f64>,
}

impl InverseMass {
    /// `1/m`, then `J'⁻¹` row by row: the numbers generated code reads (by
    /// constant index, so without a bounds check).
    #[doc(hidden)]
    #[inline(always)]
    pub fn entries(&self) -> [f64; 10] {
        let w = &self.inv_inertia;
        [self.inv_mass, w.m11, w.m12, w.m13, w.m21, w.m22, w.m23, w.m31, w.m32, w.m33]
    }
}

/// The metric of a minimum-norm solve: Euclidean, or the inverse mass matrix
/// (`x = W Jᵀ y`, `(J W Jᵀ) y = b`: the solution closest in kinetic energy).
pub(crate) type Metric<'a, const NB: usize> = Option<&'a [InverseMass; NB]>;

/// `W x` for the block-diagonal metric (identity when `None`).
pub(crate) fn apply_metric<const NB: usize, const NV: usize>(
    metric: Metric<'_, NB>,
    x: &SVector<f64, NV>,
) -> SVector<f64, NV> {
    let Some(w) = metric else { return *x };
    let mut y = *x;
    apply_metric_into(w, x, &mut y);
    y
}

/// `y = W x` in place of the caller's vector (no `NV`-sized temporary).
pub(crate) fn apply_metric_into<const NB: usize, const NV: usize>(
    w: &[InverseMass; NB],
    x: &SVector<f64, NV>,
    y: &mut SVector<f64, NV>,
) {
    y.copy_from(x);
    apply_metric_in_place(w, y);
}

/// `x = W x` in place, body by body (the same operations as
/// [`apply_metric_into`]).
pub(crate) fn apply_metric_in_place<const NB: usize, const NV: usize>(w: &[InverseMass; NB], x: &mut SVector<f64, NV>) {
    for (i, m) in w.iter().enumerate() {
        if 6 * i + 6 > NV {
            break;
        }
        let f = x.fixed_rows::<3>(6 * i) * m.inv_mass;
        let t = m.inv_inertia * x.fixed_rows::<3>(6 * i + 3);
        x.fixed_rows_mut::<3>(6 * i).copy_from(&f);
        x.fixed_rows_mut::<3>(6 * i + 3).copy_from(&t);
    }
}
