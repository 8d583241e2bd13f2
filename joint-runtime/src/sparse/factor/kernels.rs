//! The factor's block kernels, their row counts const generics: each copy is
//! straight-line over its block's true size (constant loop bounds, which the
//! compiler unrolls), chosen once per block by `with_rows!`. A block is 6 × 6
//! row-major (`6 r + c`); entries past a block's rows, and an `L` block's
//! columns past its rank, are zero, so products can run over all six columns.

use super::{Block, ZERO};
use crate::analysis::InverseMass;

/// `out = J W` for a block of `R` rows: the translational columns times
/// `1/m`, the rotational ones times the inverse inertia.
#[inline(always)]
pub(super) fn times_metric<const R: usize>(j: &Block, m: &InverseMass, out: &mut Block) {
    let w = &m.inv_inertia;
    for r in 0..R {
        let row = 6 * r;
        for c in 0..3 {
            out[row + c] = j[row + c] * m.inv_mass;
        }
        for c in 0..3 {
            out[row + 3 + c] = j[row + 3] * w[(0, c)] + j[row + 4] * w[(1, c)] + j[row + 5] * w[(2, c)];
        }
    }
}

/// `out[x][y] += sign Σ_c a[x][c] b[y][c]` for `x < RI`, `y < RK`.
#[inline(always)]
pub(super) fn add_abt<const RI: usize, const RK: usize>(a: &Block, b: &Block, out: &mut Block, sign: f64) {
    for x in 0..RI {
        for y in 0..RK {
            let mut sum = 0.0;
            for c in 0..6 {
                sum += a[6 * x + c] * b[6 * y + c];
            }
            out[6 * x + y] += sign * sum;
        }
    }
}

/// Pivoted Cholesky of the `N × N` block `l`, in place: on return `l` holds
/// the factor's columns (rows in the block's order, column `c` at `6 r + c`)
/// and the pivot order and rank are returned. A pivot at or below
/// `tolerance` (or not positive) ends the factor: its row and the rest are
/// dropped as redundant. With `rule`, its pivots are kept (falling back to
/// choosing them if one is not positive).
#[inline(always)]
pub(super) fn pivoted_cholesky<const N: usize>(
    l: &mut Block,
    tolerance: f64,
    rule: Option<([usize; 6], usize)>,
) -> ([usize; 6], usize) {
    let d = *l;
    if let Some((perm, rank)) = rule {
        let rank = rank.min(N);
        if in_order::<N>(&d, &perm, rank, l) {
            return (perm, rank);
        }
    }
    let mut w = d;
    let mut perm = [0, 1, 2, 3, 4, 5];
    *l = ZERO;
    let mut rank = 0;
    for c in 0..N {
        let Some(p) = (c..N).max_by(|&a, &b| w[7 * perm[a]].total_cmp(&w[7 * perm[b]])) else { break };
        let pivot = w[7 * perm[p]];
        if pivot.is_nan() || pivot <= tolerance || pivot <= 0.0 {
            break;
        }
        perm.swap(c, p);
        eliminate::<N>(&mut w, l, &perm, c);
        rank = c + 1;
    }
    (perm, rank)
}

/// The factor of `d` with the pivots `perm[..rank]` prescribed, into `l`;
/// `false` if one of them is not positive.
#[inline(always)]
fn in_order<const N: usize>(d: &Block, perm: &[usize; 6], rank: usize, l: &mut Block) -> bool {
    let mut w = *d;
    *l = ZERO;
    for c in 0..rank {
        let pivot = w[7 * perm[c]];
        if pivot.is_nan() || pivot <= 0.0 {
            return false;
        }
        eliminate::<N>(&mut w, l, perm, c);
    }
    true
}

/// Column `c` of the factor at pivot `perm[c]`, and the update of the rest.
#[inline(always)]
fn eliminate<const N: usize>(w: &mut Block, l: &mut Block, perm: &[usize; 6], c: usize) {
    let p = perm[c];
    let root = libm::sqrt(w[7 * p]);
    l[6 * p + c] = root;
    for &r in &perm[c + 1..N] {
        l[6 * r + c] = w[6 * r + p] / root;
    }
    for &r in &perm[c + 1..N] {
        for &s in &perm[c + 1..N] {
            w[6 * r + s] -= l[6 * r + c] * l[6 * s + c];
        }
    }
}

/// A block below the diagonal, in place: each of its `RI` rows `b` becomes
/// `y` with `T y = b[perm[..rank]]`, `T[a][c] = L_kk[perm[a]][c]`; the
/// columns past the rank are zeroed.
#[inline(always)]
pub(super) fn solve_below<const RI: usize>(lkk: &Block, perm: &[usize; 6], rank: usize, out: &mut Block) {
    for x in 0..RI {
        let mut b = [0.0; 6];
        b.copy_from_slice(&out[6 * x..6 * x + 6]);
        let mut y = [0.0; 6];
        for a in 0..rank.min(6) {
            let mut sum = 0.0;
            for c in 0..a {
                sum += lkk[6 * perm[a] + c] * y[c];
            }
            y[a] = (b[perm[a]] - sum) / lkk[6 * perm[a] + a];
        }
        out[6 * x..6 * x + 6].copy_from_slice(&y);
    }
}

/// `out[x] += sign Σ_y a[x][y] v[y]` for `x < R`: the forward solve's
/// update (`sign = −1`) and one side of a joint's rows of `J x` (`+1`).
#[inline(always)]
pub(super) fn add_av<const R: usize>(a: &Block, v: &[f64; 6], out: &mut [f64; 6], sign: f64) {
    for x in 0..R {
        let mut sum = 0.0;
        for y in 0..6 {
            sum += a[6 * x + y] * v[y];
        }
        out[x] += sign * sum;
    }
}

/// `out[y] += sign Σ_x a[x][y] v[x]` over the `R` rows of `a`: the backward
/// solve's update (`sign = −1`) and one side of a joint's part of `Jᵀ v` (`+1`).
#[inline(always)]
pub(super) fn add_atv<const R: usize>(a: &Block, v: &[f64; 6], out: &mut [f64; 6], sign: f64) {
    for y in 0..6 {
        let mut sum = 0.0;
        for x in 0..R {
            sum += a[6 * x + y] * v[x];
        }
        out[y] += sign * sum;
    }
}

/// The forward solve with a diagonal block: `z` with `T z = c[perm[..rank]]`,
/// zero past the rank.
#[inline(always)]
pub(super) fn forward<const R: usize>(l: &Block, perm: &[usize; 6], rank: usize, c: &[f64; 6]) -> [f64; 6] {
    let mut z = [0.0; 6];
    for a in 0..rank.min(R) {
        let mut sum = 0.0;
        for y in 0..a {
            sum += l[6 * perm[a] + y] * z[y];
        }
        z[a] = (c[perm[a]] - sum) / l[6 * perm[a] + a];
    }
    z
}

/// The backward solve with a diagonal block: `Tᵀ y = c[..rank]`, returned
/// scattered to the block's rows (`λ[perm[a]] = y[a]`), zero on the dropped rows.
pub(super) fn backward(l: &Block, perm: &[usize; 6], rank: usize, c: &[f64; 6]) -> [f64; 6] {
    let rank = rank.min(6);
    let mut y = [0.0; 6];
    for a in (0..rank).rev() {
        let mut sum = 0.0;
        for e in a + 1..rank {
            sum += l[6 * perm[e] + a] * y[e];
        }
        y[a] = (c[a] - sum) / l[6 * perm[a] + a];
    }
    let mut lambda = [0.0; 6];
    for a in 0..rank {
        lambda[perm[a]] = y[a];
    }
    lambda
}
