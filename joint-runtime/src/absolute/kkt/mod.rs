//! A block LU of a sparse saddle-point (KKT) matrix on a pattern fixed once:
//! the implicit integrators' iteration matrix
//!
//! ```text
//! [ S    Jᵀ ]   S: body blocks (mass, stiffness, damping), coupled where a
//! [ J T  0  ]   joint or a spring connects two bodies; J: joint rows
//! ```
//!
//! Nodes are the bodies (6 columns each) and the joints (their rows). The
//! elimination order is minimum degree with one rule: a joint is eliminated
//! only after every body it connects. The derive fixes it for the scene's own
//! couplings (`SparseJacobian::KKT_ORDER`, [`Kkt::fixed`], in the arrays it
//! sized: no allocator); springs between bodies no joint joins get the same
//! rule's pattern at run time ([`Kkt::grown`], `pattern.rs`, with `alloc`). Then
//! every leading block the factorisation meets is the saddle-point matrix of
//! some bodies and the joints among them, nonsingular whenever `S` is (`c₁ M`
//! dominates it at the steps an integrator takes) and the joints' rows are
//! independent (the caller replaces redundant rows by identity rows): no
//! pivoting across blocks is needed, so the pattern and the update schedule are
//! static. Each pivot block (at most 6 × 6) is inverted with partial pivoting.
//!
//! On a chain or a ladder of loops the fill stays within a few neighbouring
//! nodes, so a factorisation costs `O(N)` block operations.

#[cfg(feature = "alloc")]
mod pattern;
mod storage;

use storage::KktVecs;
pub use storage::{BlocksRef, KktArrays, KktEntry, KktStorage, Pattern, PatternMut, Values};

use super::buf::{Boxed, boxed};
use crate::linalg::LinalgError;

/// A dense block of at most 6 × 6, row-major (`6 r + c`), of real (`f64`,
/// the default) or complex entries (Radau IIA's complex stage system).
pub(super) type Block<T = f64> = [T; 36];

fn zero<T: KktEntry>() -> Block<T> {
    [T::zero(); 36]
}

/// A vector by node, as [`Kkt::solve`] reads it: the bodies' `NV` entries
/// (`head`), then the joints' `M` rows (`tail`), one flat index over both.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct NodeVector<T, const NV: usize, const M: usize> {
    pub(super) head: [T; NV],
    pub(super) tail: [T; M],
}

impl<T: KktEntry, const NV: usize, const M: usize> NodeVector<T, NV, M> {
    /// Zeros.
    #[cfg(test)]
    pub(super) fn zeros() -> Self {
        NodeVector { head: [T::zero(); NV], tail: [T::zero(); M] }
    }

    /// `x` in every entry, usable in constants (a workspace's zeros, `buf`).
    pub(super) const fn repeat(x: T) -> Self {
        NodeVector { head: [x; NV], tail: [x; M] }
    }

    /// Entry `i` of the flat vector.
    pub(super) fn get(&self, i: usize) -> Option<&T> {
        if i < NV { self.head.get(i) } else { self.tail.get(i - NV) }
    }

    /// Entry `i` of the flat vector, to write.
    pub(super) fn get_mut(&mut self, i: usize) -> Option<&mut T> {
        if i < NV { self.head.get_mut(i) } else { self.tail.get_mut(i - NV) }
    }

    /// Every entry, in order.
    pub(super) fn iter(&self) -> impl Iterator<Item = &T> {
        self.head.iter().chain(self.tail.iter())
    }

    /// Every entry, in order, to write.
    pub(super) fn iter_mut(&mut self) -> impl Iterator<Item = &mut T> {
        self.head.iter_mut().chain(self.tail.iter_mut())
    }

    /// Sets every entry to `x`.
    pub(super) fn fill(&mut self, x: T) {
        self.head.fill(x);
        self.tail.fill(x);
    }
}

/// Where the block `(row node, column node)` lives.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Place {
    Diagonal(usize),
    /// `low[s]`: below the diagonal (row later in the order).
    Low(usize),
    /// `up[s]`: above it.
    Up(usize),
}

impl Pattern<'_> {
    /// Node `node`'s size, clamped to a block (the pattern's sizes are at
    /// most 6; said so the optimiser sees every index in range, hence
    /// inlined: the clamp must reach the caller's loops).
    #[inline(always)]
    fn size(&self, node: usize) -> usize {
        self.sizes.get(node).map_or(0, |&s| s.min(6))
    }

    /// The size of the node at elimination position `k`.
    #[inline(always)]
    fn size_at(&self, k: usize) -> usize {
        self.order.get(k).map_or(0, |&node| self.size(node))
    }
}

/// The arrays a [`Kkt`] lives in: the derive's (the scene's pattern) or,
/// with `alloc`, vectors for a pattern found at run time.
#[derive(Clone, Debug)]
enum Store<T, A> {
    Fixed(A),
    /// Boxed: the vectors' headers would make every `Fixed` as large.
    /// (Without `alloc` its type has no values: never made.)
    #[cfg_attr(not(feature = "alloc"), allow(dead_code))]
    Grown(Boxed<KktVecs<T>>),
}

/// The factorised matrix: `A = L U` with `L_ik = A_ik D_k⁻¹` (unit block
/// diagonal) and `U_kj = A_kj`, `U_kk = D_k`, blocks by elimination position.
/// `A` is the scene's [`KktStorage`] (`SparseJacobian::Kkt<T>`).
#[derive(Clone, Debug)]
pub(super) struct Kkt<T, A> {
    store: Store<T, A>,
}

/// A problem with the declared structure.
const BAD_STRUCTURE: LinalgError = LinalgError::NonFinite;

impl<T: KktEntry, A: KktStorage<T>> Kkt<T, A> {
    /// The pattern the derive fixed for a scene's bodies (nodes
    /// `0..bodies`, 6 columns each) and joints of `joint_rows(j)` rows
    /// connecting `joint_bodies[j]` (node `bodies + j`): its elimination
    /// order (`order`, nodes) and, per position `k`, the later positions its
    /// column reaches, `below[starts[k]..starts[k + 1]]`.
    ///
    /// # Errors
    /// [`LinalgError::NonFinite`] when the pattern does not fit `A`'s sizes,
    /// is not an elimination's (a position out of order, a fill missing),
    /// lacks a block of a joint and its bodies or of the two bodies a joint
    /// joins, or eliminates a joint before one of its bodies.
    pub(super) fn fixed(
        joint_rows: impl Fn(usize) -> Option<usize>,
        joint_bodies: &[[Option<usize>; 2]],
        (order, starts, below): (&[usize], &[usize], &[usize]),
    ) -> Result<Self, LinalgError> {
        let bodies = order.len().saturating_sub(joint_bodies.len());
        let mut arrays = A::zeroed();
        let size = |node: usize| if node < bodies { Some(6) } else { joint_rows(node - bodies) };
        let below_of = |k: usize| below.get(*starts.get(k)?..*starts.get(k + 1)?);
        set_pattern(arrays.pattern_mut(), size, order, below_of)?;
        let mut kkt = Kkt { store: Store::Fixed(arrays) };
        for (j, pair) in joint_bodies.iter().enumerate() {
            let joint = bodies + j;
            let (p, _) = kkt.view();
            let at = |node: usize| p.position.get(node).copied();
            if pair.iter().flatten().any(|&b| at(b).is_none_or(|b| at(joint).is_none_or(|j| b > j))) {
                return Err(BAD_STRUCTURE);
            }
            let mut blocks = pair.iter().flatten().map(|&b| (joint, b)).chain(match *pair {
                [Some(a), Some(b)] => Some((a, b)),
                _ => None,
            });
            if blocks.any(|(a, b)| kkt.block_mut(a, b).is_none()) {
                return Err(BAD_STRUCTURE);
            }
        }
        Ok(kkt)
    }

    /// A matrix on the same pattern with entries of type `U` (in the
    /// scene's storage `B` for them), all zero.
    ///
    /// # Errors
    /// [`LinalgError::NonFinite`] when `B`'s sizes are not this pattern's.
    pub(super) fn like<U: KktEntry, B: KktStorage<U>>(&self) -> Result<Kkt<U, B>, LinalgError> {
        let (from, _) = self.view();
        let mut store = match &self.store {
            Store::Fixed(_) => Store::Fixed(B::zeroed()),
            Store::Grown(v) => Store::Grown(boxed(v.zeroed_like())),
        };
        let to = match &mut store {
            Store::Fixed(b) => b.pattern_mut(),
            Store::Grown(v) => v.pattern_mut(),
        };
        copy_pattern(from, to)?;
        Ok(Kkt { store })
    }

    fn split(&mut self) -> (Pattern<'_>, Values<'_, T>) {
        match &mut self.store {
            Store::Fixed(a) => a.split(),
            Store::Grown(v) => v.split(),
        }
    }

    fn view(&self) -> (Pattern<'_>, BlocksRef<'_, T>) {
        match &self.store {
            Store::Fixed(a) => a.view(),
            Store::Grown(v) => v.view(),
        }
    }

    /// Sets every block to zero (before an assembly).
    pub(super) fn clear(&mut self) {
        let (_, v) = self.split();
        for b in v.diag.iter_mut().chain(v.low.iter_mut()).chain(v.up.iter_mut()) {
            *b = zero();
        }
    }

    /// The block of node `row` and node `column` (row-major, stride 6), if the
    /// pattern has it: where an assembly writes.
    pub(super) fn block_mut(&mut self, row: usize, column: usize) -> Option<&mut Block<T>> {
        let (p, v) = self.split();
        let (i, j) = (*p.position.get(row)?, *p.position.get(column)?);
        match place_at(p.adj_range, p.adj, i, j)? {
            Place::Diagonal(k) => v.diag.get_mut(k),
            Place::Low(s) => v.low.get_mut(s),
            Place::Up(s) => v.up.get_mut(s),
        }
    }

    /// Factorises the assembled matrix in place.
    ///
    /// # Errors
    /// [`LinalgError::Singular`] when a pivot block is singular (a step too
    /// long for `S`, or dependent rows left in); [`LinalgError::NonFinite`]
    /// for a non-finite entry.
    pub(super) fn factor(&mut self) -> Result<(), LinalgError> {
        let (p, v) = self.split();
        let size_at = |k: usize| p.size_at(k);
        for (k, &(a, b)) in p.adj_range.iter().enumerate() {
            let nk = size_at(k);
            let diag = v.diag.get_mut(k).ok_or(BAD_STRUCTURE)?;
            let inverse = invert(diag, nk).map_err(|e| match e {
                LinalgError::Singular { .. } => LinalgError::Singular { step: k },
                e => e,
            })?;
            *diag = inverse;
            for (low, &i) in v.low.get_mut(a..b).unwrap_or_default().iter_mut().zip(p.adj.get(a..b).unwrap_or_default())
            {
                *low = multiply(low, &inverse, size_at(i), nk, nk);
            }
            let (u0, u1) = p.updates_range.get(k).copied().unwrap_or_default();
            for &(si, sj, target) in p.updates.get(u0..u1).unwrap_or_default() {
                let (Some(&i), Some(&j)) = (p.adj.get(si), p.adj.get(sj)) else { return Err(BAD_STRUCTURE) };
                let (ni, nj) = (size_at(i), size_at(j));
                let (Some(l), Some(u)) = (v.low.get(si), v.up.get(sj)) else { return Err(BAD_STRUCTURE) };
                let product = multiply(l, u, ni, nk, nj);
                let out = match target {
                    Place::Diagonal(d) => v.diag.get_mut(d),
                    Place::Low(s) => v.low.get_mut(s),
                    Place::Up(s) => v.up.get_mut(s),
                }
                .ok_or(BAD_STRUCTURE)?;
                for r in 0..ni {
                    for c in 0..nj {
                        out[6 * r + c] -= product[6 * r + c];
                    }
                }
            }
        }
        Ok(())
    }

    /// Solves `A x = b` in place; `b` is by node: body `i`'s 6 entries, then
    /// the joints' rows, in node order (`sizes` concatenated).
    pub(super) fn solve<const NV: usize, const M: usize>(&mut self, b: &mut NodeVector<T, NV, M>) {
        let (p, v) = self.split();
        let size_at = |k: usize| p.size_at(k);
        let x = v.x;
        // Gather by position.
        for ((&k, &size), &start) in p.position.iter().zip(p.sizes).zip(p.starts) {
            let mut y = [T::zero(); 6];
            for (r, e) in y.iter_mut().enumerate().take(size.min(6)) {
                *e = b.get(start + r).copied().unwrap_or_else(T::zero);
            }
            if let Some(slot) = x.get_mut(k) {
                *slot = y;
            }
        }
        // Forward: y = L⁻¹ b.
        for (k, &(a, e)) in p.adj_range.iter().enumerate() {
            let (nk, yk) = (size_at(k), x.get(k).copied().unwrap_or([T::zero(); 6]));
            for (low, &i) in v.low.get(a..e).unwrap_or_default().iter().zip(p.adj.get(a..e).unwrap_or_default()) {
                let Some(xi) = x.get_mut(i) else { continue };
                for (r, xr) in xi.iter_mut().enumerate().take(size_at(i)) {
                    let row = low.get(6 * r..6 * r + nk).unwrap_or(&[]);
                    *xr -= row.iter().zip(&yk).fold(T::zero(), |sum, (&a, &y)| sum + a * y);
                }
            }
        }
        // Backward: x_k = D_k⁻¹ (y_k − Σ U_kj x_j).
        for (k, &(a, e)) in p.adj_range.iter().enumerate().rev() {
            let nk = size_at(k);
            let mut rhs = x.get(k).copied().unwrap_or([T::zero(); 6]);
            for (up, &j) in v.up.get(a..e).unwrap_or_default().iter().zip(p.adj.get(a..e).unwrap_or_default()) {
                let xj = x.get(j).copied().unwrap_or([T::zero(); 6]);
                for (r, y) in rhs.iter_mut().enumerate().take(nk) {
                    for (c, &xc) in xj.iter().enumerate().take(size_at(j)) {
                        *y -= up[6 * r + c] * xc;
                    }
                }
            }
            let (Some(d), Some(out)) = (v.diag.get(k), x.get_mut(k)) else { continue };
            for (r, o) in out.iter_mut().enumerate() {
                *o = T::zero();
                if r < nk {
                    for (c, &y) in rhs.iter().enumerate().take(nk) {
                        *o += d[6 * r + c] * y;
                    }
                }
            }
        }
        for ((&k, &size), &start) in p.position.iter().zip(p.sizes).zip(p.starts) {
            let xk = x.get(k).copied().unwrap_or([T::zero(); 6]);
            for (r, &e) in xk.iter().enumerate().take(size) {
                if let Some(out) = b.get_mut(start + r) {
                    *out = e;
                }
            }
        }
    }

    /// Calls `f(row node, column node, block)` for every block both of whose
    /// nodes are bodies (nodes below `bodies`): the diagonal ones and those
    /// of body pairs, fill included.
    pub(super) fn for_each_body_block(&mut self, bodies: usize, mut f: impl FnMut(usize, usize, &mut Block<T>)) {
        let (p, v) = self.split();
        let ranges = p.order.iter().zip(p.adj_range).zip(v.diag.iter_mut());
        for ((&node, &(a, e)), diag) in ranges {
            if node >= bodies {
                continue;
            }
            f(node, node, diag);
            let slots = v.low.get_mut(a..e).unwrap_or_default().iter_mut().zip(v.up.get_mut(a..e).unwrap_or_default());
            for ((low, up), &position) in slots.zip(p.adj.get(a..e).unwrap_or_default()) {
                let other = p.order.get(position).copied().unwrap_or(usize::MAX);
                if other < bodies {
                    f(other, node, low);
                    f(node, other, up);
                }
            }
        }
    }

    /// Number of blocks stored (diagonal, below and above).
    pub(super) fn blocks(&self) -> usize {
        let (_, b) = self.view();
        b.diag.len() + b.low.len() + b.up.len()
    }

    /// Sets every block to `Σ c P` over the assembled (not factorised)
    /// real matrices `parts` on this pattern (made by [`Kkt::like`]); blocks
    /// of a part with another pattern are ignored.
    pub(super) fn combine<R: KktStorage<f64>>(&mut self, parts: &[(&Kkt<f64, R>, T)]) {
        self.clear();
        let (_, v) = self.split();
        for &(part, c) in parts {
            let (_, from) = part.view();
            for (out, from) in [(&mut *v.diag, from.diag), (&mut *v.low, from.low), (&mut *v.up, from.up)] {
                for (o, f) in out.iter_mut().zip(from) {
                    for (x, &y) in o.iter_mut().zip(f) {
                        *x += c * T::from_real(y);
                    }
                }
            }
        }
    }

    /// `out = A x` for the assembled (not factorised) matrix, both by node as
    /// in [`Kkt::solve`].
    pub(super) fn times<const NV: usize, const M: usize>(
        &self,
        x: &NodeVector<T, NV, M>,
        out: &mut NodeVector<T, NV, M>,
    ) {
        out.fill(T::zero());
        let (p, blocks) = self.view();
        let mut add = |block: &Block<T>, row: usize, column: usize| {
            let (Some(&r0), Some(&c0)) = (p.starts.get(row), p.starts.get(column)) else { return };
            let size = |node: usize| p.size(node);
            let (nr, nc) = (size(row), size(column));
            for r in 0..nr {
                let mut sum = T::zero();
                for c in 0..nc {
                    sum += block[6 * r + c] * x.get(c0 + c).copied().unwrap_or_else(T::zero);
                }
                if let Some(o) = out.get_mut(r0 + r) {
                    *o += sum;
                }
            }
        };
        for ((&node, d), &(a, e)) in p.order.iter().zip(blocks.diag).zip(p.adj_range) {
            add(d, node, node);
            let slots = blocks.low.get(a..e).unwrap_or_default().iter().zip(blocks.up.get(a..e).unwrap_or_default());
            for ((low, up), &position) in slots.zip(p.adj.get(a..e).unwrap_or_default()) {
                let other = p.order.get(position).copied().unwrap_or(usize::MAX);
                add(low, other, node);
                add(up, node, other);
            }
        }
    }
}

#[cfg(feature = "alloc")]
impl<T: KktEntry, A: KktStorage<T>> Kkt<T, A> {
    /// The pattern of a matrix over `bodies` body nodes (6 columns each) and
    /// joint nodes of `joint_rows` rows connecting `joint_bodies`, with bodies
    /// also coupled in pairs by `couplings` (springs, joints' stiffness),
    /// found at run time (`pattern.rs`) in vectors: for couplings the
    /// derive's pattern does not have.
    ///
    /// # Errors
    /// [`LinalgError::NonFinite`] for a joint of more than 6 rows or a body
    /// index out of range.
    pub(super) fn grown(
        bodies: usize,
        joint_rows: &[usize],
        joint_bodies: &[[Option<usize>; 2]],
        couplings: &[(usize, usize)],
    ) -> Result<Self, LinalgError> {
        let (order, below) = pattern::eliminate(bodies, joint_rows, joint_bodies, couplings)?;
        let adjacent = below.iter().map(alloc::vec::Vec::len);
        let (a, u) = adjacent.fold((0, 0), |(a, u), m| (a + m, u + m * m));
        let mut vecs = boxed(KktVecs::sized(order.len(), a, u));
        let size = |node: usize| if node < bodies { Some(6) } else { joint_rows.get(node - bodies).copied() };
        set_pattern(vecs.pattern_mut(), size, &order, |k| below.get(k).map(|b| &b[..]))?;
        Ok(Kkt { store: Store::Grown(vecs) })
    }
}

/// Writes an elimination's pattern: each node's size (`size`, at most 6),
/// the order (nodes), and each position's later neighbours (`below`,
/// positions ascending); then the Schur updates of every pair of a
/// position's later neighbours, whose block the elimination's fill must
/// hold.
fn set_pattern<'b>(
    p: PatternMut<'_>,
    size: impl Fn(usize) -> Option<usize>,
    order: &[usize],
    below: impl Fn(usize) -> Option<&'b [usize]>,
) -> Result<(), LinalgError> {
    let n = p.order.len();
    if order.len() != n || [p.sizes.len(), p.starts.len(), p.position.len(), p.adj_range.len()].iter().any(|&l| l != n)
    {
        return Err(BAD_STRUCTURE);
    }
    let mut start = 0;
    for (node, (s, first)) in p.sizes.iter_mut().zip(p.starts.iter_mut()).enumerate() {
        *s = size(node).filter(|&s| s <= 6).ok_or(BAD_STRUCTURE)?;
        *first = start;
        start += *s;
    }
    p.position.fill(usize::MAX);
    for (k, (&node, slot)) in order.iter().zip(p.order.iter_mut()).enumerate() {
        let at = p.position.get_mut(node).ok_or(BAD_STRUCTURE)?;
        if *at != usize::MAX {
            return Err(BAD_STRUCTURE);
        }
        (*at, *slot) = (k, node);
    }
    let mut used = 0;
    for (k, range) in p.adj_range.iter_mut().enumerate() {
        let later = below(k).ok_or(BAD_STRUCTURE)?;
        let ascending = later.windows(2).all(|w| w[0] < w[1]) && later.iter().all(|&i| i > k && i < n);
        let slots = p.adj.get_mut(used..used + later.len()).ok_or(BAD_STRUCTURE)?;
        if !ascending {
            return Err(BAD_STRUCTURE);
        }
        slots.copy_from_slice(later);
        *range = (used, used + later.len());
        used += later.len();
    }
    if used != p.adj.len() || p.updates_range.len() != n {
        return Err(BAD_STRUCTURE);
    }
    let (adj_range, adj) = (&*p.adj_range, &*p.adj);
    let mut count = 0;
    for (range, &(a, b)) in p.updates_range.iter_mut().zip(adj_range) {
        let first = count;
        for si in a..b {
            for sj in a..b {
                let (Some(&i), Some(&j)) = (adj.get(si), adj.get(sj)) else { return Err(BAD_STRUCTURE) };
                let target = place_at(adj_range, adj, i, j).ok_or(BAD_STRUCTURE)?;
                *p.updates.get_mut(count).ok_or(BAD_STRUCTURE)? = (si, sj, target);
                count += 1;
            }
        }
        *range = (first, count);
    }
    if count != p.updates.len() {
        return Err(BAD_STRUCTURE);
    }
    Ok(())
}
/// The place of the block at positions `(i, j)`, if the pattern has it.
#[inline]
fn place_at(adj_range: &[(usize, usize)], adj: &[usize], i: usize, j: usize) -> Option<Place> {
    use core::cmp::Ordering;
    let find = |k: usize, other: usize| {
        let &(a, b) = adj_range.get(k)?;
        adj.get(a..b)?.binary_search(&other).ok().map(|s| a + s)
    };
    match i.cmp(&j) {
        Ordering::Equal => Some(Place::Diagonal(i)),
        Ordering::Greater => find(j, i).map(Place::Low),
        Ordering::Less => find(i, j).map(Place::Up),
    }
}

/// `to`'s pattern made `from`'s (of the same sizes).
fn copy_pattern(from: Pattern<'_>, to: PatternMut<'_>) -> Result<(), LinalgError> {
    fn copy<X: Copy>(from: &[X], to: &mut [X]) -> Result<(), LinalgError> {
        if from.len() != to.len() {
            return Err(BAD_STRUCTURE);
        }
        to.iter_mut().zip(from).for_each(|(t, &f)| *t = f);
        Ok(())
    }
    copy(from.sizes, to.sizes)?;
    copy(from.starts, to.starts)?;
    copy(from.order, to.order)?;
    copy(from.position, to.position)?;
    copy(from.adj_range, to.adj_range)?;
    copy(from.adj, to.adj)?;
    copy(from.updates_range, to.updates_range)?;
    copy(from.updates, to.updates)
}

/// `a (r × k) · b (k × c)`.
#[inline(always)]
fn multiply<T: KktEntry>(a: &Block<T>, b: &Block<T>, r: usize, k: usize, c: usize) -> Block<T> {
    let (r, k, c) = (r.min(6), k.min(6), c.min(6));
    let mut out = zero();
    for i in 0..r {
        for l in 0..k {
            let x = a[6 * i + l];
            if x != T::zero() {
                for j in 0..c {
                    out[6 * i + j] += x * b[6 * l + j];
                }
            }
        }
    }
    out
}

/// The inverse of the leading `n × n` of `a`, by Gauss–Jordan with partial
/// pivoting. Worked on as rows of six (`m[r][c]`): every index is a loop
/// counter below `n ≤ 6`, which the optimiser sees is in range (no panic
/// path, `no-panic-check`).
fn invert<T: KktEntry>(a: &Block<T>, n: usize) -> Result<Block<T>, LinalgError> {
    let n = n.min(6);
    let mut m: [[T; 6]; 6] = core::array::from_fn(|r| core::array::from_fn(|c| a[6 * r + c]));
    let mut inv = [[T::zero(); 6]; 6];
    for (i, row) in inv.iter_mut().enumerate().take(n) {
        row[i] = T::one();
    }
    // |re| + |im| for complex entries: as good as the modulus, without its hypot.
    let scale = m.iter().flatten().take(n * 6).map(|x| x.norm1()).fold(0.0, f64::max);
    if !scale.is_finite() {
        return Err(LinalgError::NonFinite);
    }
    for col in 0..n {
        // The last of the largest, by the total order (as `max_by` picks).
        let (mut p, mut largest) = (col, m[col][col].norm1());
        for (x, row) in m.iter().enumerate().take(n).skip(col + 1) {
            if row[col].norm1().total_cmp(&largest).is_ge() {
                (p, largest) = (x, row[col].norm1());
            }
        }
        // A row of the block (p < n ≤ 6), said so the optimiser sees it.
        let p = p.min(5);
        let pivot = m[p][col];
        if !(pivot.norm1() > 1e-300 && pivot.norm1() > f64::EPSILON * 1e-3 * scale) {
            return Err(LinalgError::Singular { step: col });
        }
        m.swap(p, col);
        inv.swap(p, col);
        for c in 0..n {
            m[col][c] /= pivot;
            inv[col][c] /= pivot;
        }
        for r in 0..n {
            let f = m[r][col];
            if r != col && f != T::zero() {
                for c in 0..n {
                    let (mc, ic) = (m[col][c], inv[col][c]);
                    m[r][c] -= f * mc;
                    inv[r][c] -= f * ic;
                }
            }
        }
    }
    let mut out = zero();
    for (o, x) in out.iter_mut().zip(inv.iter().flatten()) {
        *o = *x;
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use alloc::vec;
    use alloc::vec::Vec;

    /// A matrix on a pattern found at run time (the storage type is unused).
    type Grown<T = f64> = Kkt<T, KktArrays<T, 0, 0, 0>>;

    /// A chain of three bodies on two joints plus a ground joint, against a
    /// dense solve of the same matrix.
    #[test]
    fn matches_a_dense_solve() {
        let joint_rows = [3, 3, 2];
        let joint_bodies = [[None, Some(0)], [Some(0), Some(1)], [Some(1), Some(2)]];
        let couplings = [(0, 1), (1, 2)];
        let mut kkt = Grown::grown(3, &joint_rows, &joint_bodies, &couplings).expect("pattern");
        let n = 18 + 8;
        let offsets = [0, 6, 12, 18, 21, 24];
        let mut dense = vec![0.0; n * n];
        let mut seed = 1u64;
        let mut random = || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let mut put = |kkt: &mut Grown, dense: &mut Vec<f64>, a: usize, b: usize, na: usize, nb: usize, diag: f64| {
            let block = kkt.block_mut(a, b).expect("in the pattern");
            for r in 0..na {
                for c in 0..nb {
                    let x = random() + if a == b && r == c { diag } else { 0.0 };
                    block[6 * r + c] = x;
                    dense[(offsets[a] + r) * n + offsets[b] + c] = x;
                }
            }
        };
        for b in 0..3 {
            put(&mut kkt, &mut dense, b, b, 6, 6, 4.0);
        }
        for &(a, b) in &couplings {
            put(&mut kkt, &mut dense, a, b, 6, 6, 0.0);
            put(&mut kkt, &mut dense, b, a, 6, 6, 0.0);
        }
        for (j, pair) in joint_bodies.iter().enumerate() {
            for &b in pair.iter().flatten() {
                put(&mut kkt, &mut dense, 3 + j, b, joint_rows[j], 6, 0.0);
                put(&mut kkt, &mut dense, b, 3 + j, 6, joint_rows[j], 0.0);
            }
        }
        let rhs: Vec<f64> = (0..n).map(|i| (i as f64).sin()).collect();
        let mut x = NodeVector::<f64, 18, 8>::zeros();
        x.iter_mut().zip(&rhs).for_each(|(x, &r)| *x = r);
        kkt.factor().expect("nonsingular");
        kkt.solve(&mut x);
        let residual = (0..n)
            .map(|r| {
                libm::fabs(
                    (0..n).map(|c| dense[r * n + c] * x.get(c).copied().unwrap_or(f64::NAN)).sum::<f64>() - rhs[r],
                )
            })
            .fold(0.0, f64::max);
        assert!(residual < 1e-12, "residual {residual}");
    }

    /// The same pattern with complex entries, combined from real parts
    /// `P0 + P1 / μ + P2 / μ²` as Radau's complex system is, against the
    /// dense product: `A x = b` solved, and `times` the dense product.
    #[test]
    fn complex_combination_matches_a_dense_product() {
        use nalgebra::Complex;
        let joint_rows = [3, 2];
        let joint_bodies = [[None, Some(0)], [Some(0), Some(1)]];
        let real = Grown::grown(2, &joint_rows, &joint_bodies, &[(0, 1)]).expect("pattern");
        let mut parts = [real.clone(), real.clone(), real.clone()];
        let mut seed = 3u64;
        let mut random = || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let blocks = [(0, 0, 6, 6), (1, 1, 6, 6), (0, 1, 6, 6), (1, 0, 6, 6), (2, 0, 3, 6), (0, 2, 6, 3)];
        let blocks = [&blocks[..], &[(3, 0, 2, 6), (0, 3, 6, 2), (3, 1, 2, 6), (1, 3, 6, 2)]].concat();
        for (p, part) in parts.iter_mut().enumerate() {
            for &(a, b, na, nb) in &blocks {
                let block = part.block_mut(a, b).expect("in the pattern");
                for r in 0..na {
                    for c in 0..nb {
                        block[6 * r + c] = random() + if p == 0 && a == b && a < 2 && r == c { 4.0 } else { 0.0 };
                    }
                }
            }
        }
        let mu = Complex::new(2.0, 3.0);
        let coefficients = [Complex::new(1.0, 0.0), mu.inv(), (mu * mu).inv()];
        let mut complex: Grown<Complex<f64>> = real.like().expect("same pattern");
        let weighted: Vec<(&Grown, Complex<f64>)> = parts.iter().zip(coefficients).collect();
        complex.combine(&weighted);
        let n = 12 + 5;
        let mut x = NodeVector::<Complex<f64>, 12, 5>::zeros();
        x.iter_mut().enumerate().for_each(|(i, x)| *x = Complex::new((i as f64).sin(), (i as f64).cos()));
        let mut b = NodeVector::zeros();
        complex.times(&x, &mut b);
        // The product part by part (real parts times x), weighted.
        let mut want = vec![Complex::new(0.0, 0.0); n];
        for (part, c) in parts.iter().zip(coefficients) {
            for (re, im) in [(true, false), (false, true)] {
                let mut xs = NodeVector::<f64, 12, 5>::zeros();
                xs.iter_mut().zip(x.iter()).for_each(|(o, z)| *o = if re { z.re } else { z.im });
                let mut y = NodeVector::zeros();
                part.times(&xs, &mut y);
                for (w, &y) in want.iter_mut().zip(y.iter()) {
                    *w += c * if im { Complex::new(0.0, y) } else { Complex::new(y, 0.0) };
                }
            }
        }
        let product_gap = b.iter().zip(&want).map(|(p, q)| (p - q).norm()).fold(0.0, f64::max);
        assert!(product_gap < 1e-14, "{product_gap:e}");
        complex.factor().expect("nonsingular");
        let mut solved = b.clone();
        complex.solve(&mut solved);
        let gap = solved.iter().zip(x.iter()).map(|(p, q)| (p - q).norm()).fold(0.0, f64::max);
        assert!(gap < 1e-12, "{gap:e}");
    }

    /// The chain of `matches_a_dense_solve` with its pattern written into
    /// arrays of its sizes, as the derive does: the same blocks, the same
    /// factor and solution bit for bit as the pattern found at run time;
    /// arrays of other sizes, or a joint before its body, are refused.
    #[test]
    fn fixed_arrays_match_the_run_time_pattern() {
        // The chain's block pairs below the diagonal and Schur updates.
        const A: usize = 10;
        const U: usize = 22;
        let joint_rows = [3, 3, 2];
        let joint_bodies = [[None, Some(0)], [Some(0), Some(1)], [Some(1), Some(2)]];
        let couplings = [(0, 1), (1, 2)];
        let (order, below) = pattern::eliminate(3, &joint_rows, &joint_bodies, &couplings).expect("pattern");
        let (mut starts, mut flat) = (vec![0], Vec::new());
        for b in &below {
            flat.extend_from_slice(b);
            starts.push(flat.len());
        }
        let updates: usize = below.iter().map(|b| b.len() * b.len()).sum();
        assert_eq!((flat.len(), updates), (A, U), "the chain's sizes");
        let rows = |j: usize| joint_rows.get(j).copied();
        let mut fixed =
            Kkt::<f64, KktArrays<f64, 6, A, U>>::fixed(rows, &joint_bodies, (&order, &starts, &flat)).expect("fits");
        let mut grown = Grown::grown(3, &joint_rows, &joint_bodies, &couplings).expect("pattern");
        let mut x = 0.3;
        for a in 0..6 {
            for b in 0..6 {
                let Some(g) = grown.block_mut(a, b) else { continue };
                for (r, e) in g.iter_mut().enumerate() {
                    x = libm::sin(x * 7.1 + 0.2);
                    *e = x + if a == b && a < 3 && r % 7 == 0 { 4.0 } else { 0.0 };
                }
                let g = *g;
                *fixed.block_mut(a, b).expect("the same blocks") = g;
            }
        }
        let mut xf = NodeVector::<f64, 18, 8>::zeros();
        xf.iter_mut().enumerate().for_each(|(i, x)| *x = libm::cos(i as f64));
        let mut xg = xf.clone();
        fixed.factor().expect("nonsingular");
        grown.factor().expect("nonsingular");
        fixed.solve(&mut xf);
        grown.solve(&mut xg);
        assert_eq!(xf, xg);
        let bigger = Kkt::<f64, KktArrays<f64, 6, A, { U + 1 }>>::fixed(rows, &joint_bodies, (&order, &starts, &flat));
        assert!(bigger.is_err());
        // The first joint (node 3, grounding body 0) first of all.
        let early = [3, 0, 1, 2, 4, 5];
        assert!(Kkt::<f64, KktArrays<f64, 6, A, U>>::fixed(rows, &joint_bodies, (&early, &starts, &flat)).is_err());
    }
}
