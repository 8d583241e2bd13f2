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
    /// The first freedom of the unbranched run that ends at `i`: each of
    /// `first[i] ..= i` is the parent of the next, so a walk to the root
    /// takes whole runs (contiguous ranges) rather than one parent at a time
    /// (a chain of dependent loads).
    pub(crate) first: [usize; NV],
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
        let mut first: [usize; NV] = core::array::from_fn(|i| i);
        for i in 1..NV {
            if parent[i] == Some(i - 1) {
                first[i] = first[i - 1];
            }
        }
        FreedomTree { parent, end, first }
    }

    /// Freedom `i`'s parent, smaller than `i` (so a walk up ends).
    pub(crate) fn up(&self, i: usize) -> Option<usize> {
        self.parent.get(i).copied().flatten().filter(|&p| p < i)
    }

    /// Whether every freedom's parent is the one before it: a chain, whose
    /// mass matrix is dense.
    pub(crate) fn is_chain(&self) -> bool {
        self.parent.iter().enumerate().all(|(i, p)| *p == i.checked_sub(1))
    }
}

/// `M` ready to solve by, in place: `M = Lᵀ D L` along the tree, or on a
/// chain (where that factor has no zeros to skip and the dense inverse's
/// products have no index work) `M⁻¹` itself.
#[derive(Clone, Copy, Debug)]
pub(super) struct MassFactor<'a, const NV: usize> {
    /// Column-major. Along the tree: `h[c][r]` for `r > c` is `L(r, c)`
    /// (zero unless `c` is an ancestor of `r`), `h[r][r]` is `D(r)`, above
    /// the diagonal unused. Dense: `M⁻¹`.
    h: [[f64; NV]; NV],
    tree: &'a FreedomTree<NV>,
    dense: bool,
}

impl<'a, const NV: usize> MassFactor<'a, NV> {
    /// Not yet factorised (zero): [`factorise`](Self::factorise) fills it.
    pub(super) fn new(tree: &'a FreedomTree<NV>) -> Self {
        MassFactor { h: [[0.0; NV]; NV], tree, dense: tree.is_chain() }
    }

    /// Factorises `m` (along the tree, only the entries between a freedom
    /// and its ancestors are read); `None` if a pivot is not positive and
    /// finite (`M` not positive definite: a massless chain).
    pub(super) fn factorise(&mut self, m: &SMatrix<f64, NV, NV>) -> Option<()> {
        if self.dense {
            let mut inverse = SMatrix::<f64, NV, NV>::zeros();
            super::derivatives::spd_inverse(m, &mut inverse)?;
            self.h = inverse.data.0;
            return Some(());
        }
        let (h, tree) = (&mut self.h, self.tree);
        // Every index below comes from `up`, so is under `NV`: the `min`s
        // change nothing but let the optimiser drop the bounds checks.
        let last = NV.saturating_sub(1);
        // Only the entries between a freedom and its ancestors are written,
        // the same ones at every call (the tree is fixed): the others keep
        // the zeros `new` gave them.
        // M's column k holds M(a, k) = M(k, a): row k of the lower triangle.
        for (k, column) in m.data.0.iter().enumerate() {
            let mut i = Some(k);
            while let Some(a) = i {
                let a = a.min(last);
                h[a][k] = column[a];
                i = tree.up(a);
            }
        }
        // From the leaves in (Featherstone's LTDL): row k of L is row k of
        // H over D(k), and H(a, b) −= L(k, a) H(k, b) for every ancestor
        // pair a ≥ b of k. Only ancestors are walked: the entries between
        // branches are zero and stay zero, and a freedom's work is its
        // depth squared, not its index squared.
        for k in (0..NV).rev() {
            let d = h[k][k];
            if !(d > 0.0 && d.is_finite()) {
                return None;
            }
            let inverse = 1.0 / d;
            let mut i = tree.up(k);
            while let Some(a) = i {
                let a = a.min(last);
                // H(k, a) is h[a][k]; H(a, b) is h[b][a], H(k, b) is h[b][k].
                let l = h[a][k] * inverse;
                let mut top = Some(a);
                while let Some(t) = top {
                    let low = tree.first.get(t).map_or(t, |&f| f.min(t));
                    for column in h.get_mut(low..=t).unwrap_or(&mut []) {
                        column[a] -= l * column[k];
                    }
                    top = tree.up(low);
                }
                h[a][k] = l;
                i = tree.up(a);
            }
        }
        Some(())
    }

    /// `X ← L⁻ᵀ X` for `X` stored by freedom (`x[k]` is row `k`, `C`
    /// columns side by side): from the leaves in, each freedom less its
    /// descendants'. Each step is an `axpy` over the `C` columns, so
    /// several right-hand sides cost little more than one (a row of `J`
    /// nonzero only on a path to the root stays there).
    fn solve_lt<const C: usize>(&self, x: &mut [[f64; C]; NV]) {
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

    /// `X ← L⁻¹ X` (stored as for `solve_lt`): from the root out, each
    /// freedom's value taken from its descendants.
    fn solve_l<const C: usize>(&self, x: &mut [[f64; C]; NV]) {
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
    fn scale<const C: usize>(&self, x: &mut [[f64; C]; NV]) {
        for (k, row) in x.iter_mut().enumerate() {
            let inverse = 1.0 / self.h[k][k];
            row.iter_mut().for_each(|value| *value *= inverse);
        }
    }

    /// `M⁻¹ b`: along the tree, the solves for one column written for it
    /// (a dot product in four running sums and a contiguous `axpy` a
    /// freedom).
    pub(super) fn solve(&self, b: &SVector<f64, NV>) -> SVector<f64, NV> {
        if self.dense {
            return SMatrix::from_data(nalgebra::ArrayStorage(self.h)) * b;
        }
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

    /// `M⁻¹` into `out`, every column at once along the tree.
    pub(super) fn inverse_into(&self, out: &mut SMatrix<f64, NV, NV>) {
        if self.dense {
            out.data.0 = self.h;
            return;
        }
        let x = &mut out.data.0;
        for (k, row) in x.iter_mut().enumerate() {
            *row = [0.0; NV];
            row[k] = 1.0;
        }
        // Symmetric: stored by freedom or by column, the same numbers.
        self.solve_lt(x);
        self.scale(x);
        self.solve_l(x);
    }

    /// `S = J M⁻¹ Jᵀ` into `delassus`, and `Y = M⁻¹ Jᵀ` into `y` when
    /// given (the forward dynamics need only `Y λ`, one solve, where `Y`
    /// takes `NC`). Along the tree, `J` stored by column is `Jᵀ` by
    /// freedom; through `L⁻ᵀ` it is `W = J L⁻¹` (by column),
    /// `S = Σ_k W[:, k] W[:, k]ᵀ / D_k`, and through `D⁻¹` and `L⁻¹` it is
    /// `Y` (by freedom: `Yᵀ` by column).
    pub(super) fn delassus_into<const NC: usize>(
        &self,
        jacobian: &SMatrix<f64, NC, NV>,
        y: Option<&mut SMatrix<f64, NV, NC>>,
        delassus: &mut SMatrix<f64, NC, NC>,
    ) {
        if self.dense {
            let inverse = SMatrix::from_data(nalgebra::ArrayStorage(self.h));
            let mut room = SMatrix::<f64, NV, NC>::zeros();
            let y = y.unwrap_or(&mut room);
            y.gemm(1.0, &inverse, &jacobian.transpose(), 0.0);
            delassus.gemm(1.0, jacobian, y, 0.0);
            return;
        }
        let mut w = jacobian.data.0;
        self.solve_lt(&mut w);
        let mut scaled = w;
        self.scale(&mut scaled);
        // S's lower triangle, column c from row c down. A contact's rows
        // through L⁻ᵀ stay on its leg and the base, so a freedom's `w` is
        // zero on the other legs' rows: those columns are skipped.
        delassus.fill(0.0);
        for (column, row) in w.iter().zip(&scaled) {
            for (c, target) in delassus.data.0.iter_mut().enumerate() {
                let a = row[c];
                if a == 0.0 {
                    continue;
                }
                let (Some(targets), Some(sources)) = (target.get_mut(c..), column.get(c..)) else {
                    continue;
                };
                for (s, x) in targets.iter_mut().zip(sources) {
                    *s += a * x;
                }
            }
        }
        for c in 0..NC {
            for r in c + 1..NC {
                delassus[(c, r)] = delassus[(r, c)];
            }
        }
        let Some(y) = y else { return };
        self.solve_l(&mut scaled);
        for (k, row) in scaled.iter().enumerate() {
            for (c, value) in row.iter().enumerate() {
                y.data.0[c][k] = *value;
            }
        }
    }

    /// `D`'s entry `k` (along the tree).
    #[cfg(test)]
    fn pivot(&self, k: usize) -> f64 {
        self.h[k][k]
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
        assert_eq!(tree.first, [0, 0, 0, 0, 4, 5, 6]);
        let mut factor = MassFactor::new(&tree);
        assert!(!factor.dense);
        factor.factorise(&m).expect("positive definite");
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
        // Y and S for two rows, against the dense products; and a chain's
        // dense inverse gives the same.
        let jacobian = SMatrix::<f64, 2, 7>::from_fn(|r, c| if r == 0 { j[c] } else { (c as f64).sin() });
        let (mut y, mut delassus) = (SMatrix::zeros(), SMatrix::zeros());
        factor.delassus_into(&jacobian, Some(&mut y), &mut delassus);
        assert!((y - dense * jacobian.transpose()).amax() < 1e-13);
        assert!((delassus - jacobian * dense * jacobian.transpose()).amax() < 1e-13);
        let mut alone = SMatrix::zeros();
        factor.delassus_into(&jacobian, None, &mut alone);
        assert_eq!(alone, delassus);
        let chain = FreedomTree::new(core::array::from_fn(|i| i.checked_sub(1)));
        let mut full = MassFactor::new(&chain);
        assert!(full.dense);
        full.factorise(&m).expect("positive definite");
        assert!((full.solve(&b) - x).amax() < 1e-13);
        let (mut y2, mut delassus2) = (SMatrix::zeros(), SMatrix::zeros());
        full.delassus_into(&jacobian, Some(&mut y2), &mut delassus2);
        assert!((y2 - y).amax() < 1e-13 && (delassus2 - delassus).amax() < 1e-13);
    }

    #[test]
    fn refuses_a_matrix_that_is_not_positive_definite() {
        let mut m = tree_matrix();
        let tree = FreedomTree::new(PARENT);
        let mut factor = MassFactor::new(&tree);
        m[(6, 6)] = 0.0;
        assert!(factor.factorise(&m).is_none());
        m[(6, 6)] = f64::NAN;
        assert!(factor.factorise(&m).is_none());
    }
}
