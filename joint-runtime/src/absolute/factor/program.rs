//! The steps of a factorisation and a solve as the derive writes them for one
//! scene (`SparseJacobian::factor_program`, `solve_program`): the schedule
//! that `BlockFactor` otherwise reads from its arrays, unrolled at compile
//! time into one call per block operation, each with its block sizes as
//! const generics and its slots as constants. After inlining, every index is
//! a constant into an array of constant length: no schedule look-up, no
//! dispatch on sizes and no bounds check remain (and no panic path, for
//! `no-panic-check`). Each step is the interpreter's own kernel in the
//! interpreter's order, so both give the same bits.

use super::kernels;
use super::storage::FactorArrays;

/// Slots `a < b` of `l`: `a` to read, `b` to write.
#[inline(always)]
fn pair<const S: usize>(l: &mut [[f64; 36]; S], a: usize, b: usize) -> Option<(&[f64; 36], &mut [f64; 36])> {
    let (before, rest) = l.split_at_mut_checked(b)?;
    Some((before.get(a)?, rest.first_mut()?))
}

/// The pivoted Cholesky kernel, not inlined: the largest step, compiled once
/// per block size rather than once per block (a 80-bar chain's program took
/// 12 s more to build with every copy inlined).
#[inline(never)]
fn cholesky<const R: usize>(
    block: &mut [f64; 36],
    tolerance: f64,
    rule: Option<([usize; 6], usize)>,
) -> ([usize; 6], usize) {
    kernels::pivoted_cholesky::<R>(block, tolerance, rule)
}

/// [`kernels::solve_below`], not inlined (as [`cholesky`]).
#[inline(never)]
fn solve_below<const RI: usize, const RK: usize>(lkk: &[f64; 36], perm: &[usize; 6], rank: usize, out: &mut [f64; 36]) {
    kernels::solve_below::<RI, RK>(lkk, perm, rank, out);
}

/// [`kernels::forward`], not inlined (as [`cholesky`]).
#[inline(never)]
fn forward<const R: usize>(l: &[f64; 36], perm: &[usize; 6], rank: usize, c: &[f64; 6]) -> [f64; 6] {
    kernels::forward::<R>(l, perm, rank, c)
}

/// [`kernels::backward`], not inlined (as [`cholesky`]).
#[inline(never)]
fn backward<const R: usize>(l: &[f64; 36], perm: &[usize; 6], rank: usize, c: &[f64; 6]) -> [f64; 6] {
    kernels::backward::<R>(l, perm, rank, c)
}

#[doc(hidden)]
impl<const N: usize, const S: usize, const T: usize, const U: usize, const NNZ: usize, const M: usize>
    FactorArrays<N, S, T, U, NNZ, M>
{
    /// `largest` and the `R` diagonal entries of slot `d`, the largest.
    #[inline(always)]
    pub fn largest_diagonal<const R: usize>(&self, d: usize, largest: f64) -> f64 {
        let Some(block) = self.l.get(d) else { return largest };
        (0..R).fold(largest, |m, r| m.max(block[7 * r]))
    }

    /// `l[s] −= l[a] l[b]ᵀ` for an `RI × RK` slot, over the `RJ` columns of
    /// an earlier factor column (`a`, `b < s`).
    #[inline(always)]
    pub fn update<const RI: usize, const RK: usize, const RJ: usize>(&mut self, s: usize, a: usize, b: usize) {
        let Some((before, rest)) = self.l.split_at_mut_checked(s) else { return };
        let (Some(la), Some(lb), Some(out)) = (before.get(a), before.get(b), rest.first_mut()) else { return };
        kernels::add_abt::<RI, RK, RJ>(la, lb, out, -1.0);
    }

    /// The diagonal slot `d` of elimination position `k` (rows from `start`):
    /// pivoted Cholesky under the kept rule with `keep`; its dropped rows
    /// appended after the `dropped` before. Returns the new count.
    #[inline(always)]
    pub fn diagonal<const R: usize>(
        &mut self,
        k: usize,
        d: usize,
        start: usize,
        tolerance: f64,
        keep: bool,
        dropped: usize,
    ) -> usize {
        let rule = if keep { self.kept.get(k).copied() } else { None };
        let Some(block) = self.l.get_mut(d) else { return dropped };
        let (perm, rank) = cholesky::<R>(block, tolerance, rule);
        if let (Some(p), Some(r)) = (self.perm.get_mut(k), self.rank.get_mut(k)) {
            (*p, *r) = (perm, rank);
        }
        super::append_dropped(&mut self.dropped[..], dropped, start, &perm, R, rank)
    }

    /// The `RI × RK` slot `s` below the diagonal slot `d` of position `k`,
    /// solved against it in place.
    #[inline(always)]
    pub fn below<const RI: usize, const RK: usize>(&mut self, k: usize, d: usize, s: usize) {
        let (Some(&perm), Some(&rank)) = (self.perm.get(k), self.rank.get(k)) else { return };
        let Some((lkk, out)) = pair(&mut self.l, d, s) else { return };
        solve_below::<RI, RK>(lkk, &perm, rank, out);
    }

    /// The dropped rows' count, sorted ascending (as the interpreter leaves them).
    #[inline(always)]
    pub fn sort_dropped(&mut self, dropped: usize) -> usize {
        if let Some(d) = self.dropped.get_mut(..dropped) {
            super::insertion_sort(d);
        }
        dropped
    }

    /// The `R` entries of `b` from `start`: a block's right-hand side.
    #[inline(always)]
    pub fn load<const R: usize>(&self, b: &[f64], start: usize) -> [f64; 6] {
        let mut c = [0.0; 6];
        for (x, cx) in c.iter_mut().enumerate().take(R) {
            *cx = b.get(start + x).copied().unwrap_or(0.0);
        }
        c
    }

    /// The forward solve at position `k` (diagonal slot `d`), its row's
    /// updates already taken from `c`: `z_k`.
    #[inline(always)]
    pub fn forward<const R: usize>(&mut self, k: usize, d: usize, c: &[f64; 6]) {
        let (Some(lkk), Some(perm), Some(&rank)) = (self.l.get(d), self.perm.get(k), self.rank.get(k)) else { return };
        let z = forward::<R>(lkk, perm, rank, c);
        if let Some(out) = self.z.get_mut(k) {
            *out = z;
        }
    }

    /// `c −= L_kj z_j` for the `R × RJ` slot `s` of row `k`.
    #[inline(always)]
    pub fn forward_update<const R: usize, const RJ: usize>(&self, s: usize, j: usize, c: &mut [f64; 6]) {
        if let (Some(lkj), Some(zj)) = (self.l.get(s), self.z.get(j)) {
            kernels::sub_av::<R, RJ>(lkj, zj, c);
        }
    }

    /// `z_k`, where the backward solve at position `k` starts.
    #[inline(always)]
    pub fn z(&self, k: usize) -> [f64; 6] {
        self.z.get(k).copied().unwrap_or([0.0; 6])
    }

    /// The backward solve at position `k` (diagonal slot `d`, `R` rows from
    /// `start`), its column's updates already taken from `c`: `λ_k`, kept
    /// for the positions before and written into `b`.
    #[inline(always)]
    pub fn backward<const R: usize>(&mut self, k: usize, d: usize, start: usize, c: &[f64; 6], b: &mut [f64]) {
        let (Some(lkk), Some(perm), Some(&rank)) = (self.l.get(d), self.perm.get(k), self.rank.get(k)) else { return };
        let lambda = backward::<R>(lkk, perm, rank, c);
        if let Some(out) = self.lambda.get_mut(k) {
            *out = lambda;
        }
        for (x, &v) in lambda.iter().enumerate().take(R) {
            if let Some(o) = b.get_mut(start + x) {
                *o = v;
            }
        }
    }

    /// `c −= L_ikᵀ λ_i` for the `RI × RK` slot `s` below position `k`, `i` its row.
    #[inline(always)]
    pub fn backward_update<const RI: usize, const RK: usize>(&self, s: usize, i: usize, c: &mut [f64; 6]) {
        if let (Some(lik), Some(li)) = (self.l.get(s), self.lambda.get(i)) {
            kernels::sub_atv::<RI, RK>(lik, li, c);
        }
    }
}
