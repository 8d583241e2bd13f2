//! Small dense linear algebra on fixed-size matrices, generic over `const N`.
//!
//! nalgebra's decompositions are generic over dimensions, but its rank-revealing
//! ones (`ColPivQR`, `SVD`) need `DimMin` bounds and allocator bounds on derived
//! dimensions (`DimMinimum<R, C>`, `DimDiff<D, U1>`) that a function generic over
//! `const N: usize` cannot name without carrying them through every caller, and
//! its `Cholesky` is not rank revealing. The two factorisations here are written
//! over indices instead: no bounds beyond `const N`, no allocation, no panic.
//!
//! - [`PivotedCholesky`]: `P A Pᵀ = L Lᵀ` with diagonal (symmetric) pivoting for a
//!   symmetric positive semidefinite `A`, stopping when the largest remaining
//!   pivot falls below a tolerance relative to the first (largest) pivot. It
//!   reports the numerical rank and which indices were dropped as dependent, and
//!   solves consistent systems `A x = b` with the basic solution (`x` zero at the
//!   dropped indices).
//! - [`Lu`]: LU with partial (row) pivoting of a general square matrix, real or
//!   complex, for the Newton iterations of the implicit integrators.

use nalgebra::{ComplexField, SMatrix, SVector};

/// Default relative pivot tolerance of [`PivotedCholesky`]: a pivot below
/// `1e-10 ×` the largest one counts as zero. On a Gram matrix `J Jᵀ` this treats
/// singular values of `J` below about `1e-5 σ_max` as zero.
pub const DEFAULT_RANK_TOLERANCE: f64 = 1e-10;

/// What can go wrong in a factorisation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum LinalgError {
    /// The matrix holds a NaN or an infinity.
    NonFinite,
    /// A zero (or negligible) pivot at this elimination step: the matrix is
    /// singular to working precision.
    Singular {
        /// The elimination step.
        step: usize,
    },
}

impl core::fmt::Display for LinalgError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            LinalgError::NonFinite => write!(f, "matrix has a non-finite entry"),
            LinalgError::Singular { step } => write!(f, "matrix is singular (zero pivot at step {step})"),
        }
    }
}

impl core::error::Error for LinalgError {}

fn all_finite<const R: usize, const C: usize>(a: &SMatrix<f64, R, C>) -> bool {
    finite(a.as_slice())
}

/// Whether every number is finite: every one tested, no early exit, so the
/// test runs in vector lanes (an early exit tests one number at a time, a
/// microsecond on a robot's derivative matrices).
pub(crate) fn finite(xs: &[f64]) -> bool {
    xs.iter().fold(true, |ok, x| ok & x.is_finite())
}

/// Rank-revealing Cholesky factorisation with diagonal pivoting of a symmetric
/// positive semidefinite matrix: `P A Pᵀ = L Lᵀ` with `L` lower trapezoidal of
/// `rank` columns.
///
/// At step `k` the largest remaining diagonal entry is moved to position `k`;
/// the factorisation stops when that entry is at most `tolerance ×` the first
/// (largest) pivot. The indices left over are linearly dependent on the others
/// (to that tolerance): for `A = J Jᵀ` they are redundant constraint rows.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PivotedCholesky<const N: usize> {
    /// `L` in the first `rank` columns of the lower triangle (pivoted order);
    /// everything else is scratch.
    factor: SMatrix<f64, N, N>,
    /// `perm[k]` is the original index at pivoted position `k`.
    perm: [usize; N],
    rank: usize,
    max_pivot: f64,
}

impl<const N: usize> PivotedCholesky<N> {
    /// The factor of nothing (rank 0): room that a later
    /// [`new`](Self::new) replaces.
    pub(crate) fn empty() -> Self {
        PivotedCholesky { factor: SMatrix::zeros(), perm: core::array::from_fn(|i| i), rank: 0, max_pivot: 0.0 }
    }

    /// Factorises the symmetric part `(A + Aᵀ)/2` of `a`. `tolerance` is relative to
    /// the largest pivot (see [`DEFAULT_RANK_TOLERANCE`]); a negative or NaN
    /// tolerance is treated as zero.
    ///
    /// Errors only on a non-finite entry; a singular or zero matrix is not an
    /// error, it has a smaller rank.
    pub fn new(a: &SMatrix<f64, N, N>, tolerance: f64) -> Result<Self, LinalgError> {
        if !all_finite(a) {
            return Err(LinalgError::NonFinite);
        }
        let tolerance = if tolerance > 0.0 { tolerance } else { 0.0 };
        let mut w = SMatrix::<f64, N, N>::from_fn(|i, j| 0.5 * (a[(i, j)] + a[(j, i)]));
        let mut perm: [usize; N] = core::array::from_fn(|i| i);
        let mut rank = 0;
        let mut max_pivot = 0.0;
        for k in 0..N {
            let (mut best_at, mut best) = (k, w[(k, k)]);
            for i in k + 1..N {
                if w[(i, i)] > best {
                    best_at = i;
                    best = w[(i, i)];
                }
            }
            if k == 0 {
                max_pivot = if best > 0.0 { best } else { 0.0 };
            }
            if best.is_nan() || best <= tolerance * max_pivot || best <= 0.0 {
                break;
            }
            if best_at != k {
                symmetric_swap(&mut w, k, best_at);
                perm.swap(k, best_at);
            }
            eliminate(&mut w, k, best);
            rank = k + 1;
        }
        Ok(PivotedCholesky { factor: w, perm, rank, max_pivot })
    }

    /// Factorises `a` eliminating in a prescribed order — `order[..rank]` are the
    /// indices kept, the rest are dropped — for a sequence of nearby matrices
    /// that must drop the same indices (the stages of one integrator step: a
    /// redundant row switching between stages breaks the method's order). Falls
    /// back to [`PivotedCholesky::new`] if a prescribed pivot is not positive
    /// (the order no longer fits the matrix), or if `order` is not a permutation.
    pub fn with_order(
        a: &SMatrix<f64, N, N>,
        order: &[usize; N],
        rank: usize,
        tolerance: f64,
    ) -> Result<Self, LinalgError> {
        if !all_finite(a) {
            return Err(LinalgError::NonFinite);
        }
        let mut seen = [false; N];
        for &i in order {
            match seen.get_mut(i) {
                Some(s) if !*s => *s = true,
                _ => return Self::new(a, tolerance),
            }
        }
        let rank = rank.min(N);
        // `order` is a permutation of `0..N` (checked above): `get` never misses.
        let entry = |i: usize, j: usize| a.get((i, j)).copied().unwrap_or(0.0);
        let mut w = SMatrix::<f64, N, N>::from_fn(|i, j| {
            let (oi, oj) = (order[i], order[j]);
            0.5 * (entry(oi, oj) + entry(oj, oi))
        });
        let max_pivot = (0..N).map(|i| w[(i, i)]).fold(0.0, f64::max);
        for k in 0..rank {
            let pivot = w[(k, k)];
            if pivot.is_nan() || pivot <= 0.0 {
                return Self::new(a, tolerance);
            }
            eliminate(&mut w, k, pivot);
        }
        Ok(PivotedCholesky { factor: w, perm: *order, rank, max_pivot })
    }

    /// The numerical rank.
    pub fn rank(&self) -> usize {
        self.rank
    }

    /// Whether no index was dropped.
    pub fn is_full_rank(&self) -> bool {
        self.rank == N
    }

    /// The largest pivot (the largest diagonal entry of `A`).
    pub fn max_pivot(&self) -> f64 {
        self.max_pivot
    }

    /// The pivot order: `permutation()[k]` is the original index eliminated at step `k`.
    pub fn permutation(&self) -> &[usize; N] {
        &self.perm
    }

    /// The original indices dropped as dependent (unordered: in pivot order).
    pub fn dropped(&self) -> &[usize] {
        self.perm.get(self.rank..).unwrap_or(&[])
    }

    /// The factor `L` (pivoted order, `N × N`, zero beyond column `rank`): `P A Pᵀ ≈ L Lᵀ`.
    pub fn l(&self) -> SMatrix<f64, N, N> {
        SMatrix::from_fn(|i, j| if j < self.rank && i >= j { self.factor[(i, j)] } else { 0.0 })
    }

    /// The basic solution of `A x = b`: `x` is zero at the dropped indices and
    /// solves the kept rows exactly. When `b` lies in the range of `A` (a
    /// consistent system, e.g. `b = J c` for `A = J Jᵀ`) it solves every row.
    pub fn solve(&self, b: &SVector<f64, N>) -> SVector<f64, N> {
        // `rank ≤ N` and `perm` is a permutation of `0..N` by construction; the
        // `min` and the `get`s below only let the optimiser see it (no bounds
        // check, no panic path), they change nothing.
        let r = self.rank.min(N);
        let mut z = SVector::<f64, N>::zeros();
        // L11 z = P b (forward).
        // The sums run over iterators, not indices: at small `N` (a planar
        // loop's two rows) the optimiser did not prove `(i, k)` in bounds.
        // Same operations in the same order as indexed loops.
        for k in 0..r {
            let b = b.get(self.perm[k]).copied().unwrap_or(0.0);
            let row = self.factor.row(k);
            let s = row.iter().zip(z.iter()).take(k).fold(b, |s, (l, z)| s - l * z);
            z[k] = s / self.factor[(k, k)];
        }
        // L11ᵀ y = z (backward), in place.
        for k in (0..r).rev() {
            let column = self.factor.column(k);
            let s = column.iter().zip(z.iter()).take(r).skip(k + 1).fold(z[k], |s, (l, z)| s - l * z);
            z[k] = s / self.factor[(k, k)];
        }
        let mut x = SVector::<f64, N>::zeros();
        for k in 0..r {
            if let Some(xk) = x.get_mut(self.perm[k]) {
                *xk = z[k];
            }
        }
        x
    }

    /// The matrix that [`solve`](Self::solve) applies: `A`'s kept block
    /// inverted, zero on the dropped indices' rows and columns (the inverse
    /// itself at full rank). One triangular inverse and one product, where
    /// `N` solves would repeat the factor's traversal `N` times.
    ///
    /// ```
    /// use joint_runtime::linalg::PivotedCholesky;
    /// use joint_runtime::nalgebra::Matrix3;
    ///
    /// // Row 2 repeats row 0: dropped, and the kept block [[2, 1], [1, 2]] inverted.
    /// let a = Matrix3::new(2.0, 1.0, 2.0, 1.0, 2.0, 1.0, 2.0, 1.0, 2.0);
    /// let inverse = PivotedCholesky::new(&a, 1e-12)?.inverse();
    /// let kept = Matrix3::new(2.0, -1.0, 0.0, -1.0, 2.0, 0.0, 0.0, 0.0, 0.0) / 3.0;
    /// assert!((inverse - kept).amax() < 1e-15);
    /// # Ok::<(), joint_runtime::linalg::LinalgError>(())
    /// ```
    pub fn inverse(&self) -> SMatrix<f64, N, N> {
        let r = self.rank.min(N);
        // Every index is below `r ≤ N`; `get` lets the optimiser see it at
        // small `N` too (a planar loop's two rows kept an indexed bounds
        // check), and changes no value.
        let at = |m: &SMatrix<f64, N, N>, i: usize, j: usize| m.get((i, j)).copied().unwrap_or(0.0);
        // T = L11⁻¹, lower triangular, column by column (pivoted order).
        let mut t = SMatrix::<f64, N, N>::zeros();
        for j in 0..r {
            if let Some(x) = t.get_mut((j, j)) {
                *x = 1.0 / at(&self.factor, j, j);
            }
            for i in j + 1..r {
                let mut s = 0.0;
                for k in j..i {
                    s -= at(&self.factor, i, k) * at(&t, k, j);
                }
                if let Some(x) = t.get_mut((i, j)) {
                    *x = s / at(&self.factor, i, i);
                }
            }
        }
        // (L11 L11ᵀ)⁻¹ = Tᵀ T, scattered back to the original order.
        let mut out = SMatrix::<f64, N, N>::zeros();
        for a in 0..r {
            for b in 0..=a {
                let mut s = 0.0;
                for k in a..r {
                    s += at(&t, k, a) * at(&t, k, b);
                }
                let (pa, pb) = (self.perm[a], self.perm[b]);
                if pa < N && pb < N {
                    out[(pa, pb)] = s;
                    out[(pb, pa)] = s;
                }
            }
        }
        out
    }
}

/// `out ← β out + α A B` for fixed sizes, in place (no temporary to copy
/// back, as `a * b` makes): each column of the output summed in registers
/// over `A`'s columns, `axpy`s the processor's vector lanes take. On the
/// constrained dynamics' `18 × 18` products it takes about three quarters
/// of nalgebra's `*`.
pub(crate) fn gemm<const R: usize, const K: usize, const C: usize>(
    out: &mut SMatrix<f64, R, C>,
    alpha: f64,
    a: &SMatrix<f64, R, K>,
    b: &SMatrix<f64, K, C>,
    beta: f64,
) {
    let a = &a.data.0;
    for (target, column) in out.data.0.iter_mut().zip(&b.data.0) {
        let mut sum = [0.0; R];
        for (a_k, b_k) in a.iter().zip(column) {
            for (s, x) in sum.iter_mut().zip(a_k) {
                *s += x * b_k;
            }
        }
        for (t, s) in target.iter_mut().zip(&sum) {
            *t = if beta == 0.0 { alpha * s } else { beta * *t + alpha * s };
        }
    }
}

/// Step `k` of Cholesky's factor on the lower triangle of `w`: column `k`
/// over `√pivot`, then `W[i, j] −= W[i, k] W[j, k]` for `i ≥ j > k`, a
/// column at a time on contiguous slices (the processor's vector lanes).
/// Only the lower triangle is kept: half the work of the whole trailing
/// block, which [`symmetric_swap`] makes possible.
fn eliminate<const N: usize>(w: &mut SMatrix<f64, N, N>, k: usize, pivot: f64) {
    let l = libm::sqrt(pivot);
    let columns = &mut w.data.0;
    let (head, tail) = columns.split_at_mut((k + 1).min(N));
    let Some(pivot_column) = head.last_mut() else { return };
    if let Some(x) = pivot_column.get_mut(k) {
        *x = l;
    }
    // A copy the updates cannot alias, so that they run in vector lanes.
    // Divided, not multiplied by `1 / l`: the same bits as before, which the
    // adaptive integrators' step choices are sensitive to.
    let mut below = [0.0; N];
    for ((x, y), _) in pivot_column.iter_mut().zip(below.iter_mut()).zip(0..N).skip(k + 1) {
        *x /= l;
        *y = *x;
    }
    for ((j, column), ljk) in (k + 1..N).zip(tail.iter_mut()).zip(below.iter().skip(k + 1)) {
        let ljk = *ljk;
        let (Some(targets), Some(sources)) = (column.get_mut(j..), below.get(j..)) else { continue };
        for (target, lik) in targets.iter_mut().zip(sources) {
            *target -= lik * ljk;
        }
    }
}

/// Swaps indices `p < q` of the symmetric matrix whose lower triangle is
/// `w` (LAPACK's `dpstrf` swap): the rows of the columns already
/// factorised, the two diagonals, and the entries between them reflected.
fn symmetric_swap<const N: usize>(w: &mut SMatrix<f64, N, N>, p: usize, q: usize) {
    let (p, q) = (p.min(q), q.max(p));
    if q >= N {
        return;
    }
    // Entry (i, j) is `w[j][i]` (column-major); every index below is under `N`.
    let w = &mut w.data.0;
    let mut swap = |(i, j): (usize, usize), (k, l): (usize, usize)| {
        let (Some(a), Some(b)) = (w.get(j).and_then(|c| c.get(i)), w.get(l).and_then(|c| c.get(k))) else {
            return;
        };
        let (a, b) = (*a, *b);
        if let Some(x) = w.get_mut(j).and_then(|c| c.get_mut(i)) {
            *x = b;
        }
        if let Some(x) = w.get_mut(l).and_then(|c| c.get_mut(k)) {
            *x = a;
        }
    };
    for j in 0..p {
        swap((p, j), (q, j));
    }
    swap((p, p), (q, q));
    for i in p + 1..q {
        swap((i, p), (q, i));
    }
    for i in q + 1..N {
        swap((i, p), (i, q));
    }
}

/// LU factorisation with partial pivoting, `P A = L U`, of a general square
/// matrix of real (`T = f64`, the default) or complex (`Complex<f64>`, for
/// Radau IIA's complex stage system) entries.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lu<const N: usize, T = f64> {
    /// `L` (unit diagonal, strictly below) and `U` (on and above the diagonal).
    lu: SMatrix<T, N, N>,
    /// `perm[k]` is the original row at position `k`.
    perm: [usize; N],
}

impl<const N: usize, T: ComplexField<RealField = f64> + Copy> Lu<N, T> {
    /// Factorises `a`. Errors on a non-finite entry, or when a pivot is at most
    /// `1e-14 ×` the largest entry of `a` in magnitude (singular to working precision).
    pub fn new(a: &SMatrix<T, N, N>) -> Result<Self, LinalgError> {
        if !a.iter().all(|x| x.is_finite()) {
            return Err(LinalgError::NonFinite);
        }
        // |re| + |im| for complex pivots: as good a choice as the modulus, without its hypot.
        let scale = a.iter().fold(0.0f64, |m, x| m.max(x.norm1()));
        let mut w = *a;
        let mut perm: [usize; N] = core::array::from_fn(|i| i);
        for k in 0..N {
            let (mut best_at, mut best) = (k, w[(k, k)].norm1());
            for i in k + 1..N {
                let v = w[(i, k)].norm1();
                if v > best {
                    best_at = i;
                    best = v;
                }
            }
            if best.is_nan() || best <= 1e-14 * scale {
                return Err(LinalgError::Singular { step: k });
            }
            if best_at != k {
                w.swap_rows(k, best_at);
                perm.swap(k, best_at);
            }
            let pivot = w[(k, k)];
            for i in k + 1..N {
                let f = w[(i, k)] / pivot;
                w[(i, k)] = f;
                for j in k + 1..N {
                    let u = w[(k, j)];
                    w[(i, j)] -= f * u;
                }
            }
        }
        Ok(Lu { lu: w, perm })
    }

    /// Solves `A x = b`.
    pub fn solve(&self, b: &SVector<T, N>) -> SVector<T, N> {
        // `perm` is a permutation of `0..N`: `get` never misses.
        let mut x =
            SVector::<T, N>::from_fn(|i, _| self.perm.get(i).and_then(|&p| b.get(p)).copied().unwrap_or_else(T::zero));
        for i in 0..N {
            for j in 0..i {
                let xj = x[j];
                x[i] -= self.lu[(i, j)] * xj;
            }
        }
        for i in (0..N).rev() {
            for j in i + 1..N {
                let xj = x[j];
                x[i] -= self.lu[(i, j)] * xj;
            }
            x[i] /= self.lu[(i, i)];
        }
        x
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// xorshift64*: reproducible uniform numbers in [-1, 1) without a dependency.
    struct Rng(u64);
    impl Rng {
        fn next(&mut self) -> f64 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            let bits = self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11;
            bits as f64 / (1u64 << 52) as f64 - 1.0
        }
    }

    /// `B Bᵀ` with `B` an `N × 8` matrix whose last `8 − rank` columns are zero:
    /// a PSD matrix of rank `rank` (almost surely).
    fn psd<const N: usize>(rng: &mut Rng, rank: usize) -> SMatrix<f64, N, N> {
        let b = SMatrix::<f64, N, 8>::from_fn(|_, j| if j < rank { rng.next() } else { 0.0 });
        b * b.transpose()
    }

    fn check<const N: usize>(seed: u64) {
        let mut rng = Rng(seed);
        for rank in 0..=N.min(8) {
            for _ in 0..20 {
                let a = psd::<N>(&mut rng, rank);
                let f = PivotedCholesky::new(&a, DEFAULT_RANK_TOLERANCE).unwrap();
                assert_eq!(f.rank(), rank, "N = {N}");
                assert_eq!(f.dropped().len(), N - rank);
                // P A Pᵀ = L Lᵀ.
                let l = f.l();
                let pa = SMatrix::<f64, N, N>::from_fn(|i, j| a[(f.permutation()[i], f.permutation()[j])]);
                assert!((pa - l * l.transpose()).norm() < 1e-12 * (1.0 + a.norm()));
                // A consistent right-hand side is solved exactly, dropped entries zero.
                let b = a * SVector::<f64, N>::from_fn(|_, _| rng.next());
                let x = f.solve(&b);
                assert!((a * x - b).norm() < 1e-9 * (1.0 + b.norm()), "residual {}", (a * x - b).norm());
                for &d in f.dropped() {
                    assert_eq!(x[d], 0.0);
                }
                // The kept indices are independent: their principal submatrix is full rank.
                let kept = &f.permutation()[..f.rank()];
                let sub = SMatrix::<f64, N, N>::from_fn(|i, j| {
                    if i < kept.len() && j < kept.len() { a[(kept[i], kept[j])] } else { f64::from(u8::from(i == j)) }
                });
                assert!(PivotedCholesky::new(&sub, DEFAULT_RANK_TOLERANCE).unwrap().is_full_rank());
            }
        }
    }

    #[test]
    fn random_psd_matrices_of_known_rank() {
        check::<1>(1);
        check::<3>(2);
        check::<6>(3);
        check::<9>(4);
        check::<12>(5);
    }

    #[test]
    fn duplicated_rows_are_dropped() {
        // J with row 3 = row 0 and row 4 = row 1 + row 2: rank 3 of 5.
        let mut rng = Rng(7);
        let mut j = SMatrix::<f64, 5, 6>::from_fn(|_, _| rng.next());
        let (r0, r1, r2) = (j.row(0).into_owned(), j.row(1).into_owned(), j.row(2).into_owned());
        j.set_row(3, &r0);
        j.set_row(4, &(r1 + r2));
        let f = PivotedCholesky::new(&(j * j.transpose()), DEFAULT_RANK_TOLERANCE).unwrap();
        assert_eq!(f.rank(), 3);
        assert_eq!(f.dropped().len(), 2);
    }

    #[test]
    fn gemm_is_the_product() {
        let mut rng = Rng(23);
        let a = SMatrix::<f64, 5, 7>::from_fn(|_, _| rng.next());
        let b = SMatrix::<f64, 7, 3>::from_fn(|_, _| rng.next());
        let mut out = SMatrix::<f64, 5, 3>::from_fn(|_, _| rng.next());
        let expected = out * 0.5 - a * b * 2.0;
        gemm(&mut out, -2.0, &a, &b, 0.5);
        assert!((out - expected).amax() < 1e-14);
        gemm(&mut out, 1.0, &a, &b, 0.0);
        assert!((out - a * b).amax() < 1e-14);
    }

    #[test]
    fn inverse_is_what_solve_applies() {
        // Rank 4 of 7, and full rank: column j of `inverse` is `solve(e_j)`,
        // and on the kept block it inverts `A` (A X A = A there).
        let mut rng = Rng(19);
        for rank in [4, 7] {
            let a = psd::<7>(&mut rng, rank);
            let f = PivotedCholesky::new(&a, DEFAULT_RANK_TOLERANCE).unwrap();
            let inverse = f.inverse();
            for j in 0..7 {
                let e = SVector::<f64, 7>::from_fn(|i, _| f64::from(u8::from(i == j)));
                assert!((inverse.column(j) - f.solve(&e)).amax() < 1e-9 * inverse.amax());
            }
            assert!((a * inverse * a - a).amax() < 1e-9 * a.amax());
            assert_eq!(inverse, inverse.transpose());
        }
    }

    #[test]
    fn degenerate_inputs() {
        let z = SMatrix::<f64, 4, 4>::zeros();
        let f = PivotedCholesky::new(&z, DEFAULT_RANK_TOLERANCE).unwrap();
        assert_eq!(f.rank(), 0);
        assert_eq!(f.solve(&SVector::<f64, 4>::repeat(1.0)), SVector::<f64, 4>::zeros());
        let mut n = SMatrix::<f64, 4, 4>::identity();
        n[(2, 1)] = f64::NAN;
        assert_eq!(PivotedCholesky::new(&n, DEFAULT_RANK_TOLERANCE), Err(LinalgError::NonFinite));
        assert_eq!(Lu::new(&n).unwrap_err(), LinalgError::NonFinite);
        assert!(matches!(Lu::new(&z), Err(LinalgError::Singular { step: 0 })));
        let e = PivotedCholesky::<0>::new(&SMatrix::<f64, 0, 0>::zeros(), 1e-10).unwrap();
        assert_eq!(e.rank(), 0);
    }

    #[test]
    fn lu_solves_random_systems() {
        let mut rng = Rng(11);
        for _ in 0..50 {
            let a = SMatrix::<f64, 7, 7>::from_fn(|_, _| rng.next());
            let x = SVector::<f64, 7>::from_fn(|_, _| rng.next());
            let lu = Lu::new(&a).unwrap();
            assert!((lu.solve(&(a * x)) - x).norm() < 1e-9);
        }
    }

    #[test]
    fn lu_solves_random_complex_systems() {
        use nalgebra::Complex;
        let mut rng = Rng(13);
        for _ in 0..50 {
            let mut z = || Complex::new(rng.next(), rng.next());
            let a = SMatrix::<Complex<f64>, 6, 6>::from_fn(|_, _| z());
            let x = SVector::<Complex<f64>, 6>::from_fn(|_, _| z());
            let lu = Lu::new(&a).unwrap();
            assert!((lu.solve(&(a * x)) - x).norm() < 1e-9);
        }
        let mut n = SMatrix::<Complex<f64>, 3, 3>::identity();
        n[(1, 2)] = Complex::new(0.0, f64::NAN);
        assert_eq!(Lu::new(&n).unwrap_err(), LinalgError::NonFinite);
    }
}
