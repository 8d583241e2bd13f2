//! The mass matrix factorised along the tree: `M = Lᵀ D L` with `L` unit
//! lower triangular and nonzero only where the column's freedom is an
//! ancestor of the row's (Featherstone's LTDL, *Rigid Body Dynamics
//! Algorithms* §6.5). A tree's branches make no fill-in, so the factor,
//! and every solve by it, cost the entries the tree couples rather than
//! `NV³` and `NV²`: on a floating quadruped (18 freedoms) `L` holds 99
//! entries where a dense factor holds 153, and a foot's Jacobian row stays
//! on its leg and the base through `L⁻ᵀ`.
//!
//! Invariant: freedom `i`'s parent (the freedom before it on the way to
//! the root) has a smaller index, as [`Tree::new`](super::Tree::new) orders
//! joints parents first, and freedom `c`'s descendants all lie in
//! `c + 1 .. end[c]`. The factor keeps `L` dense with exact zeros off the
//! ancestors, so the solves run over those ranges as contiguous dot
//! products and `axpy`s (the processor's vector lanes, no index chasing);
//! where the joints come depth first (a file's order) the ranges hold
//! descendants only.

use nalgebra::{SMatrix, SVector};

/// A tree over freedoms: each one's parent, and where its descendants end.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct FreedomTree<const NV: usize> {
    /// Freedom `i`'s parent freedom: the one before it in its joint, or the
    /// last of the nearest ancestor joint that has freedoms.
    pub(crate) parent: [Option<usize>; NV],
    /// One past the last of freedom `i`'s descendants (`i + 1` for a leaf).
    pub(crate) end: [usize; NV],
}

impl<const NV: usize> FreedomTree<NV> {
    /// From the parents (a parent that is not smaller than its child is
    /// taken as none: the walks to the root end).
    pub(crate) fn new(parent: [Option<usize>; NV]) -> Self {
        let parent: [Option<usize>; NV] = core::array::from_fn(|i| parent[i].filter(|&p| p < i));
        let mut end: [usize; NV] = core::array::from_fn(|i| i + 1);
        for k in (0..NV).rev() {
            let below = end[k];
            if let Some(slot) = parent[k].and_then(|p| end.get_mut(p)) {
                *slot = (*slot).max(below);
            }
        }
        FreedomTree { parent, end }
    }

    /// Freedom `i`'s parent, smaller than `i` (so a walk up ends).
    pub(crate) fn up(&self, i: usize) -> Option<usize> {
        self.parent.get(i).copied().flatten().filter(|&p| p < i)
    }
}

impl<const NV: usize> FreedomTree<NV> {
    /// Whether every freedom's parent is the one before it: a chain, whose
    /// mass matrix is dense.
    pub(crate) fn is_chain(&self) -> bool {
        self.parent.iter().enumerate().all(|(i, p)| *p == i.checked_sub(1))
    }
}

/// `M` ready to solve by: factorised along the tree, or inverted densely
/// (a chain, where the factor has no zeros to skip).
#[derive(Clone, Copy, Debug)]
pub(super) enum MassFactor<'a, const NV: usize> {
    /// `M = Lᵀ D L`.
    Tree(TreeFactor<'a, NV>),
    /// `M⁻¹`.
    Dense(SMatrix<f64, NV, NV>),
}

impl<const NV: usize> MassFactor<'_, NV> {
    /// `M⁻¹ b`.
    pub(super) fn solve(&self, b: &SVector<f64, NV>) -> SVector<f64, NV> {
        match self {
            MassFactor::Tree(factor) => factor.solve(b),
            MassFactor::Dense(inverse) => inverse * b,
        }
    }

    /// `M⁻¹`.
    pub(super) fn inverse(&self) -> SMatrix<f64, NV, NV> {
        match self {
            MassFactor::Tree(factor) => {
                let mut out = SMatrix::zeros();
                factor.inverse_into(&mut out);
                out
            }
            MassFactor::Dense(inverse) => *inverse,
        }
    }
}

/// `M = Lᵀ D L` over a tree's freedoms (see the module).
#[derive(Clone, Copy, Debug)]
pub(super) struct TreeFactor<'a, const NV: usize> {
    /// Column-major: `h[c][r]` for `r > c` is `L(r, c)` (zero unless `c` is
    /// an ancestor of `r`), `h[r][r]` is `D(r)`; above the diagonal unused.
    h: [[f64; NV]; NV],
    tree: &'a FreedomTree<NV>,
}

impl<'a, const NV: usize> TreeFactor<'a, NV> {
    /// Factorises `m` (only the entries between a freedom and its ancestors
    /// are read); `None` if a pivot is not positive and finite (`M` not
    /// positive definite: a massless chain).
    pub(super) fn new(m: &SMatrix<f64, NV, NV>, tree: &'a FreedomTree<NV>) -> Option<Self> {
        // Every index below comes from `up`, so is under `NV`: the `min`s
        // change nothing but let the optimiser drop the bounds checks.
        let last = NV.saturating_sub(1);
        let mut h = [[0.0; NV]; NV];
        for k in 0..NV {
            let mut i = Some(k);
            while let Some(a) = i {
                let a = a.min(last);
                h[a][k] = m.data.0[a][k];
                i = tree.up(a);
            }
        }
        // k's ancestors, nearest first: gathered once a freedom, so the
        // elimination below reads independent entries instead of chasing.
        let mut above = [0usize; NV];
        for k in (0..NV).rev() {
            let d = h[k][k];
            if !(d > 0.0 && d.is_finite()) {
                return None;
            }
            let mut depth = 0;
            let mut i = tree.up(k);
            while let (Some(a), Some(slot)) = (i, above.get_mut(depth)) {
                *slot = a.min(last);
                depth += 1;
                i = tree.up(a);
            }
            let chain = above.get(..depth).unwrap_or(&[]);
            for (n, &a) in chain.iter().enumerate() {
                let a = a.min(last);
                let ratio = h[a][k] / d;
                // (a, b) for b = a and a's ancestors: the lower triangle.
                for &b in chain.get(n..).unwrap_or(&[]) {
                    let b = b.min(last);
                    h[b][a] -= ratio * h[b][k];
                }
                h[a][k] = ratio;
            }
        }
        Some(TreeFactor { h, tree })
    }

    /// `X ← L⁻ᵀ X` for `X` stored by freedom (`x[k]` is row `k`, `C`
    /// columns side by side): from the leaves in, each freedom less its
    /// descendants'. Each step is an `axpy` over the `C` columns, so
    /// several right-hand sides cost little more than one (a row of `J`
    /// nonzero only on a path to the root stays there).
    pub(super) fn solve_lt<const C: usize>(&self, x: &mut [[f64; C]; NV]) {
        for c in (0..NV).rev() {
            let end = self.tree.end[c].min(NV);
            let (head, tail) = x.split_at_mut(c + 1);
            let (Some(target), Some(column)) = (head.last_mut(), self.h[c].get(c + 1..end)) else {
                continue;
            };
            for (l, row) in column.iter().zip(tail.iter()) {
                if *l != 0.0 {
                    axpy(target, -l, row);
                }
            }
        }
    }

    /// `X ← L⁻¹ X` (stored as for [`solve_lt`](Self::solve_lt)): from the
    /// root out, each freedom's value taken from its descendants.
    pub(super) fn solve_l<const C: usize>(&self, x: &mut [[f64; C]; NV]) {
        for c in 0..NV {
            let end = self.tree.end[c].min(NV);
            let (head, tail) = x.split_at_mut(c + 1);
            let (Some(source), Some(column)) = (head.last(), self.h[c].get(c + 1..end)) else {
                continue;
            };
            for (l, row) in column.iter().zip(tail.iter_mut()) {
                if *l != 0.0 {
                    axpy(row, -l, source);
                }
            }
        }
    }

    /// `X ← D⁻¹ X`.
    pub(super) fn scale<const C: usize>(&self, x: &mut [[f64; C]; NV]) {
        for (k, row) in x.iter_mut().enumerate() {
            let inverse = 1.0 / self.h[k][k];
            row.iter_mut().for_each(|value| *value *= inverse);
        }
    }

    /// `D`'s entry `k`.
    #[cfg(test)]
    fn pivot(&self, k: usize) -> f64 {
        self.h[k][k]
    }

    /// `M⁻¹ b`: the solves above for one column, written for it (a dot
    /// product in four running sums and a contiguous `axpy` a freedom).
    pub(super) fn solve(&self, b: &SVector<f64, NV>) -> SVector<f64, NV> {
        let mut x = b.data.0[0];
        for c in (0..NV).rev() {
            let end = self.tree.end[c].min(NV);
            if let (Some(column), Some(below)) = (self.h[c].get(c + 1..end), x.get(c + 1..end)) {
                x[c] -= dot(column, below);
            }
        }
        for (k, value) in x.iter_mut().enumerate() {
            *value /= self.h[k][k];
        }
        for c in 0..NV {
            let end = self.tree.end[c].min(NV);
            let value = x[c];
            if let (Some(column), Some(below)) = (self.h[c].get(c + 1..end), x.get_mut(c + 1..end)) {
                for (target, l) in below.iter_mut().zip(column) {
                    *target -= l * value;
                }
            }
        }
        SVector::from_data(nalgebra::ArrayStorage([x]))
    }

    /// `M⁻¹`, every column at once (symmetric: stored by freedom or by
    /// column, the same numbers).
    pub(super) fn inverse_into(&self, out: &mut SMatrix<f64, NV, NV>) {
        let x = &mut out.data.0;
        for (k, row) in x.iter_mut().enumerate() {
            *row = [0.0; NV];
            row[k] = 1.0;
        }
        self.solve_lt(x);
        self.scale(x);
        self.solve_l(x);
    }
}

/// `y ← y + a x`.
fn axpy<const C: usize>(y: &mut [f64; C], a: f64, x: &[f64; C]) {
    for (target, value) in y.iter_mut().zip(x) {
        *target += a * value;
    }
}

/// `a · b` over the shorter, in four running sums: one sum is a chain of
/// dependent additions (the compiler may not reorder them), four overlap.
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let mut sums = [0.0; 4];
    let (mut a4, mut b4) = (a.chunks_exact(4), b.chunks_exact(4));
    for (x, y) in a4.by_ref().zip(b4.by_ref()) {
        for ((s, p), q) in sums.iter_mut().zip(x).zip(y) {
            *s += p * q;
        }
    }
    let rest: f64 = a4.remainder().iter().zip(b4.remainder()).map(|(p, q)| p * q).sum();
    (sums[0] + sums[2]) + (sums[1] + sums[3]) + rest
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A tree of 7 freedoms: 0 ← 1 ← 2 (a base), 3 ← 5 on 2, 4 ← 6 on 2:
    /// breadth first, so the ranges hold freedoms that are not descendants.
    const PARENT: [Option<usize>; 7] = [None, Some(0), Some(1), Some(2), Some(2), Some(3), Some(4)];

    fn ancestor(a: usize, mut k: usize) -> bool {
        loop {
            if a == k {
                return true;
            }
            match PARENT[k] {
                Some(p) => k = p,
                None => return false,
            }
        }
    }

    /// A positive definite matrix with the tree's sparsity: `Lᵀ D L` from a
    /// chosen `L` and `D`.
    fn tree_matrix() -> SMatrix<f64, 7, 7> {
        let l = SMatrix::<f64, 7, 7>::from_fn(|r, c| match () {
            _ if r == c => 1.0,
            _ if c < r && ancestor(c, r) => 0.3 * ((r * 7 + c) as f64).sin(),
            _ => 0.0,
        });
        let d = SMatrix::<f64, 7, 7>::from_diagonal(&SVector::from_fn(|k, _| 1.0 + 0.5 * k as f64));
        l.transpose() * d * l
    }

    #[test]
    fn solves_and_inverts_like_a_dense_factor() {
        let m = tree_matrix();
        // A non-ancestor pair is zero: the tree's branches do not couple.
        assert_eq!(m[(3, 6)], 0.0);
        let tree = FreedomTree::new(PARENT);
        assert_eq!(tree.end, [7, 7, 7, 6, 7, 6, 7]);
        let factor = TreeFactor::new(&m, &tree).expect("positive definite");
        let b = SVector::<f64, 7>::from_fn(|k, _| (k as f64 + 1.0).cos());
        let x = factor.solve(&b);
        assert!((m * x - b).amax() < 1e-13);
        let mut inverse = SMatrix::zeros();
        factor.inverse_into(&mut inverse);
        assert!((m * inverse - SMatrix::<f64, 7, 7>::identity()).amax() < 1e-13);
        let dense = m.cholesky().expect("positive definite").inverse();
        assert!((inverse - dense).amax() < 1e-13);
        // J L⁻¹ D⁻¹ L⁻ᵀ Jᵀ = J M⁻¹ Jᵀ, and a row on one branch stays there.
        let mut row = [[0.0], [0.0], [0.5], [0.0], [1.0], [0.0], [-2.0]];
        let j = SVector::<f64, 7>::from_fn(|k, _| row[k][0]);
        factor.solve_lt(&mut row);
        assert_eq!((row[3], row[5]), ([0.0], [0.0]));
        let s: f64 = (0..7).map(|k| row[k][0] * row[k][0] / factor.pivot(k)).sum();
        assert!((s - (j.transpose() * dense * j)[0]).abs() < 1e-13);
    }

    #[test]
    fn refuses_a_matrix_that_is_not_positive_definite() {
        let mut m = tree_matrix();
        let tree = FreedomTree::new(PARENT);
        m[(6, 6)] = 0.0;
        assert!(TreeFactor::new(&m, &tree).is_none());
        m[(6, 6)] = f64::NAN;
        assert!(TreeFactor::new(&m, &tree).is_none());
    }
}
