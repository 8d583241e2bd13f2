//! The block factor of `J W Jᵀ` (`W` the inverse mass matrix) on the scene's
//! compile-time pattern: a static schedule built once, run at every step.

use crate::analysis::InverseMass;
use crate::linalg::LinalgError;
use crate::scene::RowBlock;

/// Runs `$body` with `$r` a constant equal to the row count `$n` (0 to 6;
/// larger blocks are refused by [`BlockFactor::new`]): the dispatch from a
/// block's run-time size to the kernel monomorphised for it.
macro_rules! with_rows {
    ($n:expr, $r:ident => $body:expr) => {
        with_rows!(@arms $n, $r, $body, 0 1 2 3 4 5)
    };
    (@arms $n:expr, $r:ident, $body:expr, $($k:literal)*) => {
        match $n {
            $($k => {
                const $r: usize = $k;
                $body
            })*
            _ => {
                const $r: usize = 6;
                $body
            }
        }
    };
}

mod build;
mod kernels;
mod program;
mod storage;

use storage::Parts;
pub use storage::{FactorArrays, FactorStorage};

/// A dense block of at most 6 × 6, row-major (`6 r + c`).
type Block = [f64; 36];

/// A joint's block: its rows and the bodies it connects.
#[derive(Clone, Copy, Debug)]
struct JointRows {
    start: usize,
    rows: usize,
    bodies: [Option<usize>; 2],
}

/// The factor of `A = J W Jᵀ` (`P A Pᵀ = L Lᵀ` on the rows kept), its pattern
/// and schedule fixed at construction, in storage sized at compile time
/// ([`FactorArrays`], sizes from the derive: no allocator needed).
///
/// The pattern, in `F`'s arrays: joint blocks by elimination position; the
/// block rows of factor column `k` (the diagonal first, each a position
/// `i ≥ k`); for each slot `(i, k)` the updates `(j, slot (i, j), slot (k,
/// j))`, `j < k`, whose products update it, and the bodies the two joints
/// share (`(side of i, side of k, body)`: the terms of
/// `A_ik = Σ J_i,b W_b J_k,bᵀ`); for each position `k` the slots
/// `(j, slot (k, j))`, `j < k` (the forward solve); each Jacobian entry's
/// place `(2 k + side, 6 r + c)`. The numbers: `J` and `J W` per joint and
/// side, the factor blocks per slot (the diagonal slot holds the block's own
/// columns), each block's pivot order and rank, and the solves' scratch.
#[derive(Clone, Debug)]
pub struct BlockFactor<F> {
    store: F,
    /// How many rows the last factorisation dropped (the first entries of
    /// the storage's `dropped`, ascending).
    dropped: usize,
    /// Factorisations made: a caller that remembers what it factorised
    /// knows the factor is still that one while the count stands.
    factorisations: u64,
}

/// A problem with the structure a scene declares (a derive bug, or a
/// hand-written impl that contradicts itself).
const BAD_STRUCTURE: LinalgError = LinalgError::NonFinite;

impl<F: FactorStorage> BlockFactor<F> {
    /// The factor's structure for a scene with joint row blocks `blocks`
    /// (in row order), their bodies, the Jacobian's CSR pattern and the
    /// derive's elimination order and factor pattern.
    ///
    /// # Errors
    /// [`LinalgError::NonFinite`] if the structure contradicts itself (a row of
    /// a joint with an entry outside its bodies' columns, a block over 6 rows,
    /// an order that is not a permutation) or does not fit `F`'s sizes.
    pub fn new(
        blocks: &[RowBlock],
        bodies: &[[Option<usize>; 2]],
        row_starts: &[usize],
        columns: &[usize],
        elimination: &[usize],
        factor_starts: &[usize],
        factor_below: &[usize],
    ) -> Result<Self, LinalgError> {
        let mut store = F::zeroed();
        let pattern = build::Pattern { blocks, bodies, row_starts, columns, elimination, factor_starts, factor_below };
        store.parts().build(&pattern)?;
        Ok(BlockFactor { store, dropped: 0, factorisations: 0 })
    }

    /// Number of Jacobian entries the factor reads.
    pub fn nonzeros(&self) -> usize {
        self.store.view().nonzeros
    }

    /// Blocks stored for the factor (diagonal and below, fill included).
    pub fn factor_blocks(&self) -> usize {
        self.store.view().slots
    }

    /// Rows dropped as redundant by the last factorisation, ascending.
    pub fn dropped(&self) -> &[usize] {
        self.store.view().dropped.get(..self.dropped).unwrap_or(&[])
    }

    /// How many factorisations this factor has made (attempts included):
    /// what a simulation step costs, in its dominant operation.
    pub fn factorisations(&self) -> u64 {
        self.factorisations
    }

    /// The numerical rank of the last factorisation.
    pub fn rank(&self) -> usize {
        self.store.view().rank.iter().sum()
    }

    /// Factorises `J W Jᵀ` for the Jacobian entries `values` (the scene's CSR
    /// order) and the inverse masses `w`. With `keep`, each block keeps the
    /// pivots and rank [`BlockFactor::keep_rule`] took, so that nearby
    /// matrices drop the same rows; without it, pivots are chosen here.
    /// `tolerance` is relative to the largest diagonal entry. `normal` writes
    /// the blocks of `J W Jᵀ` into the storage and says whether it did (the
    /// scene's generated [`normal_blocks_into`]); if not, they are formed
    /// here. `program` factorises them (the scene's generated
    /// [`factor_program`]: the schedule unrolled) and returns the count of
    /// dropped rows; `None`: the schedule is run here.
    ///
    /// # Errors
    /// [`LinalgError::NonFinite`] for a non-finite entry.
    ///
    /// [`normal_blocks_into`]: crate::SparseJacobian::normal_blocks_into
    /// [`factor_program`]: crate::SparseJacobian::factor_program
    pub(crate) fn factor(
        &mut self,
        values: &[f64],
        w: &[InverseMass],
        tolerance: f64,
        keep: bool,
        normal: impl FnOnce(&mut F) -> bool,
        program: impl FnOnce(&mut F, f64, bool) -> Option<usize>,
    ) -> Result<(), LinalgError> {
        self.factorisations = self.factorisations.wrapping_add(1);
        self.dropped = 0;
        if values.len() != self.store.view().nonzeros || !values.iter().all(|x| x.is_finite()) {
            return Err(LinalgError::NonFinite);
        }
        if !normal(&mut self.store) {
            self.store.parts().form(values, w);
        }
        self.dropped = match program(&mut self.store, tolerance, keep) {
            Some(dropped) => dropped,
            None => self.store.parts().factor(tolerance, keep),
        };
        Ok(())
    }

    /// Takes each block's pivots and rank from the last factorisation: the
    /// rule that makes later factorisations with `keep` drop the same rows.
    pub(crate) fn keep_rule(&mut self) {
        let p = self.store.parts();
        for ((kept, &perm), &rank) in p.kept.iter_mut().zip(p.perm.iter()).zip(p.rank.iter()) {
            *kept = (perm, rank);
        }
    }

    /// Solves `A λ = b` on the rows kept (λ = 0 on the dropped ones), in place.
    pub fn solve(&mut self, b: &mut [f64]) {
        self.store.parts().solve(b);
    }

    /// [`BlockFactor::solve`] by `program` (the scene's generated
    /// [`solve_program`]) where it returns `true`.
    ///
    /// [`solve_program`]: crate::SparseJacobian::solve_program
    pub(crate) fn solve_by(&mut self, b: &mut [f64], program: impl FnOnce(&mut F, &mut [f64]) -> bool) {
        if !program(&mut self.store, b) {
            self.store.parts().solve(b);
        }
    }
}

/// The rows a diagonal block dropped (`start + r` for each of its `rows`
/// pivots past the `rank`) appended to `dropped` after the `count` before:
/// the new count. The interpreter and the unrolled program both record so.
fn append_dropped(
    dropped: &mut [usize],
    count: usize,
    start: usize,
    perm: &[usize; 6],
    rows: usize,
    rank: usize,
) -> usize {
    let mut count = count;
    for &r in perm.iter().take(rows).skip(rank) {
        if let Some(x) = dropped.get_mut(count) {
            *x = start + r;
            count += 1;
        }
    }
    count
}

/// Sorts a few indices (a factorisation's dropped rows) ascending: by
/// insertion, which has no panic path, where the standard sort keeps one for
/// orderings that are not total (`no-panic-check`).
fn insertion_sort(v: &mut [usize]) {
    for i in 1..v.len() {
        let mut j = i;
        while j > 0 {
            let (Some(&a), Some(&b)) = (v.get(j - 1), v.get(j)) else { break };
            if a <= b {
                break;
            }
            v.swap(j - 1, j);
            j -= 1;
        }
    }
}

// The algorithms on the storage's slices: compiled once, not per scene.
impl Parts<'_> {
    /// `J W Jᵀ` into the factor's slots from the Jacobian entries `values`:
    /// `J` scattered into six-column blocks, `J W` per joint side, then each
    /// slot's products over the bodies its two joints share.
    fn form(&mut self, values: &[f64], w: &[InverseMass]) {
        // Entries outside the pattern were zeroed at construction and are
        // never written: no clearing here.
        // The schedule's indices are in range (`build.rs` checks them against
        // the storage); every read below still goes through `get`, so that a
        // step has no panic path (`no-panic-check`).
        for (&(s, o), &v) in self.scatter.iter().zip(values) {
            if let Some(x) = self.jb.get_mut(s).and_then(|b| b.get_mut(o)) {
                *x = v;
            }
        }
        self.times_metric(w);
        for k in 0..self.joints.len() {
            let Some(&(d, end)) = self.col_range.get(k) else { continue };
            for s in d..end {
                self.gram(s, k);
            }
        }
    }

    /// The factorisation of [`BlockFactor::factor`] on the blocks of
    /// `J W Jᵀ` in place; returns how many rows it dropped (the first
    /// entries of `dropped`, ascending).
    fn factor(&mut self, tolerance: f64, keep: bool) -> usize {
        // The diagonal blocks' largest entry scales the rank tolerance.
        let mut largest = 0.0f64;
        for k in 0..self.joints.len() {
            let (Some(&(s, _)), Some(joint)) = (self.col_range.get(k), self.joints.get(k)) else { continue };
            let Some(d) = self.l.get(s) else { continue };
            largest = (0..joint.rows.min(6)).fold(largest, |m, r| m.max(d[7 * r]));
        }
        let tolerance = if tolerance > 0.0 { tolerance * largest } else { 0.0 };
        let mut dropped = 0;
        for k in 0..self.joints.len() {
            let rule = if keep { self.kept.get(k).copied() } else { None };
            dropped = self.factor_column(k, tolerance, rule, dropped);
        }
        if let Some(d) = self.dropped.get_mut(..dropped) {
            insertion_sort(d);
        }
        dropped
    }

    /// `J W` per joint and side.
    fn times_metric(&mut self, w: &[InverseMass]) {
        for (k, joint) in self.joints.iter().enumerate() {
            for side in 0..2 {
                let s = 2 * k + side;
                let Some(m) = joint.bodies[side].and_then(|b| w.get(b)) else {
                    // A side on the ground: its J block is zero, so is J W.
                    continue;
                };
                let (Some(jb), Some(jw)) = (self.jb.get(s), self.jw.get_mut(s)) else { continue };
                with_rows!(joint.rows, R => kernels::times_metric::<R>(jb, m, jw));
            }
        }
    }

    /// `A_ik = Σ_b (J W)_i,b J_k,bᵀ` for slot `s = (i, k)`, written into `l[s]`.
    fn gram(&mut self, s: usize, k: usize) {
        let Some(&i) = self.col.get(s) else { return };
        let (Some(ri), Some(rk)) = (self.rows(i), self.rows(k)) else { return };
        let (Some(out), Some(&(a, b))) = (self.l.get_mut(s), self.shared_range.get(s)) else { return };
        // Only the `ri × rk` entries are ever nonzero (the kernels keep it so).
        with_rows!(ri, RI => with_rows!(rk, RK => kernels::clear::<RI, RK>(out)));
        for &(si, sk, _) in self.shared.get(a..b).unwrap_or_default() {
            let (Some(jw), Some(jb)) = (self.jw.get(2 * i + si), self.jb.get(2 * k + sk)) else { continue };
            with_rows!(ri, RI => with_rows!(rk, RK => kernels::add_abt::<RI, RK, 6>(jw, jb, out, 1.0)));
        }
    }

    /// The rows of joint `k`.
    fn rows(&self, k: usize) -> Option<usize> {
        self.joints.get(k).map(|j| j.rows)
    }

    /// Column `k`: the diagonal block by pivoted Cholesky, the blocks below by
    /// triangular solves against it, each slot updated in place by the
    /// columns before it (left-looking: `A_ik − Σ_j L_ij L_kjᵀ`). Its dropped
    /// rows are appended to the `dropped` before; returns the new count.
    fn factor_column(&mut self, k: usize, tolerance: f64, rule: Option<([usize; 6], usize)>, dropped: usize) -> usize {
        let (Some(&(d, end)), Some(&JointRows { start, rows, .. })) = (self.col_range.get(k), self.joints.get(k))
        else {
            return dropped;
        };
        self.update(d, k);
        let Some(diagonal) = self.l.get_mut(d) else { return dropped };
        let (perm, rank) = with_rows!(rows, R => kernels::pivoted_cholesky::<R>(diagonal, tolerance, rule));
        if let (Some(p), Some(r)) = (self.perm.get_mut(k), self.rank.get_mut(k)) {
            (*p, *r) = (perm, rank);
        }
        let count = append_dropped(self.dropped, dropped, start, &perm, rows, rank);
        for s in d + 1..end {
            self.update(s, k);
            let Some(ri) = self.col.get(s).and_then(|&i| self.rows(i)) else { continue };
            // Every slot of column k comes after its diagonal slot `d`.
            let Some((before, rest)) = self.l.split_at_mut_checked(s) else { continue };
            let (Some(lkk), Some(out)) = (before.get(d), rest.first_mut()) else { continue };
            with_rows!(ri, RI => with_rows!(rows, RK => kernels::solve_below::<RI, RK>(lkk, &perm, rank, out)));
        }
        count
    }

    /// `l[s] −= Σ_j L_ij L_kjᵀ` for slot `s = (i, k)` (the scheduled products,
    /// all from earlier columns, so from slots before `s`).
    fn update(&mut self, s: usize, k: usize) {
        let (Some(ri), Some(rk)) = (self.col.get(s).and_then(|&i| self.rows(i)), self.rows(k)) else { return };
        let Some(&(a, b)) = self.sched_range.get(s) else { return };
        let Some((before, rest)) = self.l.split_at_mut_checked(s) else { return };
        let Some(out) = rest.first_mut() else { return };
        for &(j, sij, skj) in self.sched.get(a..b).unwrap_or_default() {
            let (Some(lij), Some(lkj), Some(rj)) =
                (before.get(sij), before.get(skj), self.joints.get(j).map(|j| j.rows))
            else {
                continue;
            };
            with_rows!(ri, RI => with_rows!(rk, RK => with_rows!(rj, RJ => kernels::add_abt::<RI, RK, RJ>(lij, lkj, out, -1.0))));
        }
    }

    /// Solves `A λ = b` on the rows kept (λ = 0 on the dropped ones), in place.
    fn solve(&mut self, b: &mut [f64]) {
        let (z, lambda, l) = (&mut *self.z, &mut *self.lambda, &*self.l);
        let n = self.joints.len().min(z.len()).min(lambda.len());
        let diagonal = |k: usize| {
            let d = self.col_range.get(k).and_then(|&(d, _)| l.get(d));
            Some((d?, self.perm.get(k)?, *self.rank.get(k)?))
        };
        for k in 0..n {
            let JointRows { start, rows, .. } = self.joints[k];
            let mut c = [0.0; 6];
            for (x, cx) in c.iter_mut().enumerate().take(rows) {
                *cx = b.get(start + x).copied().unwrap_or(0.0);
            }
            let &(a, e) = self.row_range.get(k).unwrap_or(&(0, 0));
            for &(j, s) in self.row.get(a..e).unwrap_or_default() {
                let (Some(rj), Some(lkj), Some(zj)) = (self.joints.get(j).map(|j| j.rows), l.get(s), z.get(j)) else {
                    continue;
                };
                with_rows!(rows, R => with_rows!(rj, RJ => kernels::sub_av::<R, RJ>(lkj, zj, &mut c)));
            }
            let Some((lkk, perm, rank)) = diagonal(k) else { continue };
            z[k] = with_rows!(rows, R => kernels::forward::<R>(lkk, perm, rank, &c));
        }
        lambda.fill([0.0; 6]);
        for k in (0..n).rev() {
            let (Some(&(d, end)), mut c, rk) = (self.col_range.get(k), z[k], self.joints[k].rows) else { continue };
            for s in d + 1..end {
                let Some(&i) = self.col.get(s) else { continue };
                let (Some(ri), Some(lik), Some(li)) = (self.joints.get(i).map(|j| j.rows), l.get(s), lambda.get(i))
                else {
                    continue;
                };
                with_rows!(ri, R => with_rows!(rk, RK => kernels::sub_atv::<R, RK>(lik, li, &mut c)));
            }
            let (Some((lkk, perm, rank)), Some(out)) = (diagonal(k), lambda.get_mut(k)) else { continue };
            *out = with_rows!(rk, R => kernels::backward::<R>(lkk, perm, rank, &c));
        }
        for (joint, values) in self.joints.iter().zip(lambda.iter()) {
            for (x, &v) in values.iter().enumerate().take(joint.rows) {
                if let Some(out) = b.get_mut(joint.start + x) {
                    *out = v;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::{DMatrix, DVector, Matrix3};

    use super::*;

    /// Two spherical joints in a chain from the ground, eliminated in row
    /// order: blocks of 3 rows; the ground joint's rows reach body 0's six
    /// columns, the second joint's both bodies' twelve.
    const BLOCKS: [RowBlock; 2] =
        [RowBlock { name: "a", start: 0, rows: 3 }, RowBlock { name: "b", start: 3, rows: 3 }];
    const BODIES: [[Option<usize>; 2]; 2] = [[None, Some(0)], [Some(0), Some(1)]];

    fn csr() -> (Vec<usize>, Vec<usize>) {
        let (mut starts, mut columns) = (vec![0], Vec::new());
        for row in 0..6 {
            columns.extend(0..if row < 3 { 6 } else { 12 });
            starts.push(columns.len());
        }
        (starts, columns)
    }

    /// Counted by hand: 2 blocks; 3 slots (two diagonal, one below); 1
    /// update (column 0 has one slot below: 1 · 2 / 2); shared bodies: the
    /// ground joint with itself 1, the second joint with itself 2, the two
    /// joints 1 (body 0): 4; 18 + 36 entries; 6 rows.
    type Right = FactorArrays<2, 3, 1, 4, 54, 6>;

    fn factor<F: FactorStorage>() -> Result<BlockFactor<F>, LinalgError> {
        let (starts, columns) = csr();
        BlockFactor::new(&BLOCKS, &BODIES, &starts, &columns, &[0, 1], &[0, 1, 1], &[1])
    }

    #[test]
    fn storage_of_the_patterns_sizes_is_taken_and_any_other_refused() {
        assert!(factor::<Right>().is_ok());
        assert!(factor::<FactorArrays<3, 3, 1, 4, 54, 6>>().is_err());
        assert!(factor::<FactorArrays<2, 4, 1, 4, 54, 6>>().is_err());
        assert!(factor::<FactorArrays<2, 3, 2, 4, 54, 6>>().is_err());
        assert!(factor::<FactorArrays<2, 3, 1, 3, 54, 6>>().is_err());
        assert!(factor::<FactorArrays<2, 3, 1, 4, 53, 6>>().is_err());
        assert!(factor::<FactorArrays<2, 3, 1, 4, 54, 5>>().is_err());
    }

    /// The block solve against a dense solve of `J W Jᵀ λ = b` (nalgebra's
    /// LU), `J` random on the pattern, `W` two bodies' inverse masses.
    #[test]
    fn solves_as_the_dense_matrix_does() {
        let mut seed = 7u64;
        let mut random = || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let (starts, columns) = csr();
        let values: Vec<f64> = columns.iter().map(|_| random()).collect();
        let w = [
            InverseMass { inv_mass: 0.5, inv_inertia: Matrix3::new(2.0, 0.1, 0.0, 0.1, 3.0, 0.2, 0.0, 0.2, 4.0) },
            InverseMass { inv_mass: 0.25, inv_inertia: Matrix3::from_diagonal_element(1.5) },
        ];
        let mut j = DMatrix::<f64>::zeros(6, 12);
        for r in 0..6 {
            for e in starts[r]..starts[r + 1] {
                j[(r, columns[e])] = values[e];
            }
        }
        let mut metric = DMatrix::<f64>::zeros(12, 12);
        for (b, m) in w.iter().enumerate() {
            metric.view_mut((6 * b, 6 * b), (3, 3)).fill_diagonal(m.inv_mass);
            metric.view_mut((6 * b + 3, 6 * b + 3), (3, 3)).copy_from(&m.inv_inertia);
        }
        let a = &j * metric * j.transpose();
        let b = DVector::from_fn(6, |i, _| 1.0 + i as f64);
        let expected = a.lu().solve(&b).expect("a nonsingular J W Jᵀ");
        let mut f = factor::<Right>().expect("the pattern's sizes");
        f.factor(&values, &w, 1e-12, false, |_| false, |_, _, _| None).expect("finite");
        let mut x = b.clone();
        f.solve(x.as_mut_slice());
        assert_eq!((f.rank(), f.dropped()), (6, &[][..]));
        assert!((x - &expected).norm() <= 1e-12 * expected.norm(), "{expected}");
    }
}
