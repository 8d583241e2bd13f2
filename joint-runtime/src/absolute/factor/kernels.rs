//! The factor's block kernels, their row counts const generics: each copy is
//! straight-line over its block's true size (constant loop bounds, which the
//! compiler unrolls), chosen once per block by `with_rows!`. A block is 6 × 6
//! row-major (`6 r + c`); entries past a block's rows, and an `L` block's
//! columns past its rank, are zero, so a product runs over six columns for a
//! `J` block and over the column block's rows for an `L` block. A diagonal
//! block of `L` holds the reciprocals of its diagonal entries (each pivot's
//! `1/√d`), which is all the solves read of them.

use super::Block;
use crate::analysis::InverseMass;

/// `i` clamped into `0..n` (`0` for `n = 0`). A block's pivots are a
/// permutation of `0..n`, so clamping one never changes it: it only lets the
/// compiler see every pivoted index in bounds, so that no panic path is left
/// (`no-panic-check`); a `min` costs less than the bounds check it replaces.
#[inline(always)]
fn below(i: usize, n: usize) -> usize {
    i.min(n.saturating_sub(1))
}

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

/// `out[x][y] += sign Σ_c a[x][c] b[y][c]` for `x < RI`, `y < RK`, `c < C`
/// (`C = 6` for `J` blocks, the column block's rows for `L` blocks).
#[inline(always)]
pub(super) fn add_abt<const RI: usize, const RK: usize, const C: usize>(
    a: &Block,
    b: &Block,
    out: &mut Block,
    sign: f64,
) {
    for x in 0..RI {
        for y in 0..RK {
            let mut sum = 0.0;
            for c in 0..C {
                sum += a[6 * x + c] * b[6 * y + c];
            }
            out[6 * x + y] += sign * sum;
        }
    }
}

/// Pivoted Cholesky of the `N × N` block `l`, in place: on return `l` holds
/// the factor's columns (rows in the block's order, column `c` at `6 r + c`,
/// the diagonal entries as reciprocals)
/// and the pivot order and rank are returned. A pivot at or below
/// `tolerance` (or not positive) ends the factor: its row and the rest are
/// dropped as redundant. With `rule`, its pivots are kept (falling back to
/// choosing them if one is not positive). Only the block's `N × N` entries
/// are read, copied and written: the rest of `l` is zero and stays so.
#[inline(always)]
pub(super) fn pivoted_cholesky<const N: usize>(
    l: &mut Block,
    tolerance: f64,
    rule: Option<([usize; 6], usize)>,
) -> ([usize; 6], usize) {
    let mut d = [[0.0; N]; N];
    for (r, row) in d.iter_mut().enumerate() {
        for (c, x) in row.iter_mut().enumerate() {
            *x = l[6 * r + c];
        }
    }
    // A rule is this block's own earlier pivots: a permutation of `0..N`.
    if let Some((perm, rank)) = rule.filter(|(perm, _)| perm[..N].iter().all(|&p| p < N)) {
        let rank = rank.min(N);
        if in_order::<N>(&d, &perm, rank, l) {
            return (perm, rank);
        }
    }
    let mut w = d;
    let mut perm = [0, 1, 2, 3, 4, 5];
    clear::<N, N>(l);
    let mut rank = 0;
    for c in 0..N {
        let diagonal = |a: usize| {
            let q = below(perm[below(a, N)], N);
            w[q][q]
        };
        // The largest remaining diagonal, the last of equals (as
        // `max_by(total_cmp)`): a float comparison, the total order only
        // where a NaN takes part. (They differ only on −0 against +0, a
        // pivot that ends the factor either way.)
        let (mut p, mut pivot) = (c, diagonal(c));
        for a in c + 1..N {
            let x = diagonal(a);
            if x >= pivot || ((x.is_nan() || pivot.is_nan()) && x.total_cmp(&pivot).is_ge()) {
                (p, pivot) = (a, x);
            }
        }
        if pivot.is_nan() || pivot <= tolerance || pivot <= 0.0 {
            break;
        }
        perm.swap(below(c, 6), below(p, 6));
        eliminate::<N>(&mut w, l, &perm, c);
        rank = c + 1;
    }
    (perm, rank)
}

/// Zeroes the leading `R × C` entries of a block.
#[inline(always)]
pub(super) fn clear<const R: usize, const C: usize>(l: &mut Block) {
    for r in 0..R {
        for c in 0..C {
            l[6 * r + c] = 0.0;
        }
    }
}

/// The factor of `d` with the pivots `perm[..rank]` prescribed, into `l`;
/// `false` if one of them is not positive.
#[inline(always)]
fn in_order<const N: usize>(d: &[[f64; N]; N], perm: &[usize; 6], rank: usize, l: &mut Block) -> bool {
    let mut w = *d;
    clear::<N, N>(l);
    for c in 0..rank.min(N) {
        let q = below(perm[c], N);
        let pivot = w[q][q];
        if pivot.is_nan() || pivot <= 0.0 {
            return false;
        }
        eliminate::<N>(&mut w, l, perm, c);
    }
    true
}

/// Column `c` of the factor at pivot `perm[c]`, and the update of the rest.
#[inline(always)]
// Index loops on purpose: with `N` constant and `c` constant once the caller
// is unrolled, each is straight-line and every index is seen in range (an
// iterator's `skip(c + 1)` with the pivot search's doubled clamp cost the
// double Cardan's 2000 RK4 steps 617 M instructions against 600 M).
#[allow(clippy::needless_range_loop)]
fn eliminate<const N: usize>(w: &mut [[f64; N]; N], l: &mut Block, perm: &[usize; 6], c: usize) {
    let c = below(c, N);
    let p = below(perm[c], N);
    // The diagonal is stored as its reciprocal: every use divides by it,
    // and the solves then multiply (a division's latency is several
    // multiplications', and the solves are chains of them).
    let inverse = 1.0 / libm::sqrt(w[p][p]);
    l[6 * p + c] = inverse;
    for i in c + 1..N {
        let r = below(perm[i], N);
        l[6 * r + c] = w[r][p] * inverse;
    }
    for i in c + 1..N {
        let r = below(perm[i], N);
        for j in c + 1..N {
            let s = below(perm[j], N);
            w[r][s] -= l[6 * r + c] * l[6 * s + c];
        }
    }
}

/// A block below the diagonal, in place: each of its `RI` rows `b` becomes
/// `y` with `T y = b[perm[..rank]]`, `T[a][c] = L_kk[perm[a]][c]`, over the
/// diagonal block's `RK` rows; the columns past the rank are zeroed.
#[inline(always)]
pub(super) fn solve_below<const RI: usize, const RK: usize>(
    lkk: &Block,
    perm: &[usize; 6],
    rank: usize,
    out: &mut Block,
) {
    let rank = rank.min(RK);
    for x in 0..RI {
        let mut y = [0.0; RK];
        for a in 0..rank {
            let pa = below(perm[a], RK);
            let mut sum = 0.0;
            for (c, yc) in y.iter().enumerate().take(a) {
                sum += lkk[6 * pa + c] * yc;
            }
            y[a] = (out[6 * x + pa] - sum) * lkk[6 * pa + a];
        }
        for (o, &v) in out.iter_mut().skip(6 * x).zip(&y) {
            *o = v;
        }
    }
}

/// `out[x] −= Σ_y a[x][y] v[y]` for `x < R`, `y < C`: the forward solve's
/// update (`C` the rows of the column's block).
#[inline(always)]
pub(super) fn sub_av<const R: usize, const C: usize>(a: &Block, v: &[f64; 6], out: &mut [f64; 6]) {
    for x in 0..R {
        let mut sum = 0.0;
        for y in 0..C {
            sum += a[6 * x + y] * v[y];
        }
        out[x] -= sum;
    }
}

/// `out[y] −= Σ_x a[x][y] v[x]` over the `R` rows of `a`, `y < C`: the
/// backward solve's update (`C` the rows of the column's block).
#[inline(always)]
pub(super) fn sub_atv<const R: usize, const C: usize>(a: &Block, v: &[f64; 6], out: &mut [f64; 6]) {
    for y in 0..C {
        let mut sum = 0.0;
        for x in 0..R {
            sum += a[6 * x + y] * v[x];
        }
        out[y] -= sum;
    }
}

/// The forward solve with a diagonal block: `z` with `T z = c[perm[..rank]]`,
/// zero past the rank.
#[inline(always)]
pub(super) fn forward<const R: usize>(l: &Block, perm: &[usize; 6], rank: usize, c: &[f64; 6]) -> [f64; 6] {
    let mut z = [0.0; 6];
    for a in 0..rank.min(R) {
        let pa = below(perm[a], R);
        let mut sum = 0.0;
        for y in 0..a {
            sum += l[6 * pa + y] * z[y];
        }
        z[a] = (c[pa] - sum) * l[6 * pa + a];
    }
    z
}

/// The backward solve with a diagonal block of `R` rows: `Tᵀ y = c[..rank]`,
/// returned scattered to the block's rows (`λ[perm[a]] = y[a]`), zero on the
/// dropped rows. Constant bounds (the rank a branch), so each copy is
/// straight-line and every index is seen in range.
#[inline(always)]
pub(super) fn backward<const R: usize>(l: &Block, perm: &[usize; 6], rank: usize, c: &[f64; 6]) -> [f64; 6] {
    let mut y = [0.0; 6];
    for a in (0..R).rev() {
        if a >= rank {
            continue;
        }
        let mut sum = 0.0;
        for e in a + 1..R {
            if e < rank {
                sum += l[6 * below(perm[e], R) + a] * y[e];
            }
        }
        y[a] = (c[a] - sum) * l[6 * below(perm[a], R) + a];
    }
    let mut lambda = [0.0; 6];
    for a in 0..R {
        if a < rank {
            lambda[below(perm[a], R)] = y[a];
        }
    }
    lambda
}
