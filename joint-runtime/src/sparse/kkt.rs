//! A block LU of a sparse saddle-point (KKT) matrix on a pattern fixed once:
//! the implicit integrators' iteration matrix
//!
//! ```text
//! [ S    Jᵀ ]   S: body blocks (mass, stiffness, damping), coupled where a
//! [ J T  0  ]   joint or a spring connects two bodies; J: joint rows
//! ```
//!
//! Nodes are the bodies (6 columns each) and the joints (their rows). The
//! elimination order is chosen once, in [`Kkt::new`], by minimum degree with
//! one rule: a joint is eliminated only after every body it connects. Then
//! every leading block the factorisation meets is the saddle-point matrix of
//! some bodies and the joints among them, nonsingular whenever `S` is (`c₁ M`
//! dominates it at the steps an integrator takes) and the joints' rows are
//! independent (the caller replaces redundant rows by identity rows): no
//! pivoting across blocks is needed, so the pattern and the update schedule are
//! static. Each pivot block (at most 6 × 6) is inverted with partial pivoting.
//!
//! On a chain or a ladder of loops the fill stays within a few neighbouring
//! nodes, so a factorisation costs `O(N)` block operations.

use alloc::collections::BTreeSet;
use alloc::vec;
use alloc::vec::Vec;

use nalgebra::ComplexField;

use crate::linalg::LinalgError;

/// A dense block of at most 6 × 6, row-major (`6 r + c`), of real (`f64`,
/// the default) or complex entries (Radau IIA's complex stage system).
pub(super) type Block<T = f64> = [T; 36];

/// The entries a [`Kkt`] may hold: `f64` or `Complex<f64>`.
pub(super) trait Entry: ComplexField<RealField = f64> + Copy {}
impl<T: ComplexField<RealField = f64> + Copy> Entry for T {}

fn zero<T: Entry>() -> Block<T> {
    [T::zero(); 36]
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

/// The factorised matrix: `A = L U` with `L_ik = A_ik D_k⁻¹` (unit block
/// diagonal) and `U_kj = A_kj`, `U_kk = D_k`, blocks by elimination position.
#[derive(Clone, Debug)]
pub(super) struct Kkt<T = f64> {
    /// Each node's size, by node, and where each node's entries start in a
    /// vector by node (`starts[node]`; `n + 1` entries, made once).
    sizes: Vec<usize>,
    starts: Vec<usize>,
    /// Node at each elimination position, and the position of each node.
    order: Vec<usize>,
    position: Vec<usize>,
    /// Later positions adjacent to position `k` (fill included), ascending:
    /// `adj[adj_start[k]..adj_start[k + 1]]`; slot `s` of the pair
    /// `(k, adj[s])` holds `low[s]` (row `adj[s]`, column `k`) and `up[s]`.
    adj_start: Vec<usize>,
    adj: Vec<usize>,
    /// Per position `k`: `(slot (i, k), slot (k, j), target (i, j))` for every
    /// pair of later neighbours: the Schur update `A_ij −= L_ik U_kj`.
    updates_start: Vec<usize>,
    updates: Vec<(usize, usize, Place)>,
    diag: Vec<Block<T>>,
    low: Vec<Block<T>>,
    up: Vec<Block<T>>,
    /// Scratch of the solve, by position.
    x: Vec<[T; 6]>,
}

/// A problem with the declared structure.
const BAD_STRUCTURE: LinalgError = LinalgError::NonFinite;

impl<T: Entry> Kkt<T> {
    /// The pattern of a matrix over `bodies` body nodes (6 columns each) and
    /// joint nodes of `joint_rows` rows connecting `joint_bodies`, with bodies
    /// also coupled in pairs by `couplings` (springs, joints' stiffness).
    ///
    /// # Errors
    /// [`LinalgError::NonFinite`] for a joint of more than 6 rows or a body
    /// index out of range.
    pub(super) fn new(
        bodies: usize,
        joint_rows: &[usize],
        joint_bodies: &[[Option<usize>; 2]],
        couplings: &[(usize, usize)],
    ) -> Result<Self, LinalgError> {
        let n = bodies + joint_rows.len();
        let mut graph: Vec<BTreeSet<usize>> = vec![BTreeSet::new(); n];
        let mut link = |a: usize, b: usize| -> Result<(), LinalgError> {
            if a >= n || b >= n {
                return Err(BAD_STRUCTURE);
            }
            if a != b {
                graph[a].insert(b);
                graph[b].insert(a);
            }
            Ok(())
        };
        for (j, (&rows, pair)) in joint_rows.iter().zip(joint_bodies).enumerate() {
            if rows > 6 {
                return Err(BAD_STRUCTURE);
            }
            for &b in pair.iter().flatten() {
                if b >= bodies {
                    return Err(BAD_STRUCTURE);
                }
                link(bodies + j, b)?;
            }
        }
        for &(a, b) in couplings {
            if a >= bodies || b >= bodies {
                return Err(BAD_STRUCTURE);
            }
            link(a, b)?;
        }
        let mut sizes = vec![6; bodies];
        sizes.extend_from_slice(joint_rows);
        let (order, later) = elimination_order(graph, bodies, joint_bodies);
        let mut position = vec![0; n];
        for (k, &node) in order.iter().enumerate() {
            position[node] = k;
        }
        let mut starts = vec![0; n + 1];
        for (node, size) in sizes.iter().enumerate() {
            starts[node + 1] = starts[node] + size;
        }
        let mut kkt = Kkt {
            sizes,
            starts,
            order,
            position,
            adj_start: Vec::new(),
            adj: Vec::new(),
            updates_start: Vec::new(),
            updates: Vec::new(),
            diag: vec![zero(); n],
            low: Vec::new(),
            up: Vec::new(),
            x: vec![[T::zero(); 6]; n],
        };
        kkt.symbolic(later);
        Ok(kkt)
    }

    /// The fill pattern (each position's later neighbours, by node, from the
    /// elimination) and the update schedule of the order.
    fn symbolic(&mut self, later: Vec<Vec<usize>>) {
        let n = self.order.len();
        let later: Vec<Vec<usize>> = later
            .into_iter()
            .map(|nodes| {
                let mut ps: Vec<usize> = nodes.iter().map(|&x| self.position[x]).collect();
                ps.sort_unstable();
                ps
            })
            .collect();
        self.adj_start = vec![0];
        for ps in &later {
            self.adj.extend_from_slice(ps);
            self.adj_start.push(self.adj.len());
        }
        self.low = vec![zero(); self.adj.len()];
        self.up = vec![zero(); self.adj.len()];
        self.updates_start = vec![0];
        for k in 0..n {
            let (a, b) = (self.adj_start[k], self.adj_start[k + 1]);
            for si in a..b {
                for sj in a..b {
                    let target = self.place_at(self.adj[si], self.adj[sj]);
                    if let Some(t) = target {
                        self.updates.push((si, sj, t));
                    }
                }
            }
            self.updates_start.push(self.updates.len());
        }
    }

    /// The place of the block at positions `(i, j)`, if the pattern has it.
    fn place_at(&self, i: usize, j: usize) -> Option<Place> {
        use core::cmp::Ordering;
        let find = |k: usize, other: usize| {
            let (a, b) = (*self.adj_start.get(k)?, *self.adj_start.get(k + 1)?);
            self.adj.get(a..b)?.binary_search(&other).ok().map(|s| a + s)
        };
        match i.cmp(&j) {
            Ordering::Equal => Some(Place::Diagonal(i)),
            Ordering::Greater => find(j, i).map(Place::Low),
            Ordering::Less => find(i, j).map(Place::Up),
        }
    }

    /// Sets every block to zero (before an assembly).
    pub(super) fn clear(&mut self) {
        for b in self.diag.iter_mut().chain(self.low.iter_mut()).chain(self.up.iter_mut()) {
            *b = zero();
        }
    }

    /// The block of node `row` and node `column` (row-major, stride 6), if the
    /// pattern has it: where an assembly writes.
    pub(super) fn block_mut(&mut self, row: usize, column: usize) -> Option<&mut Block<T>> {
        let (i, j) = (*self.position.get(row)?, *self.position.get(column)?);
        match self.place_at(i, j)? {
            Place::Diagonal(k) => self.diag.get_mut(k),
            Place::Low(s) => self.low.get_mut(s),
            Place::Up(s) => self.up.get_mut(s),
        }
    }

    /// Factorises the assembled matrix in place.
    ///
    /// # Errors
    /// [`LinalgError::Singular`] when a pivot block is singular (a step too
    /// long for `S`, or dependent rows left in); [`LinalgError::NonFinite`]
    /// for a non-finite entry.
    pub(super) fn factor(&mut self) -> Result<(), LinalgError> {
        for k in 0..self.order.len() {
            let nk = self.sizes[self.order[k]];
            let inverse = invert(&self.diag[k], nk).map_err(|e| match e {
                LinalgError::Singular { .. } => LinalgError::Singular { step: k },
                e => e,
            })?;
            self.diag[k] = inverse;
            for s in self.adj_start[k]..self.adj_start[k + 1] {
                let ni = self.sizes[self.order[self.adj[s]]];
                self.low[s] = multiply(&self.low[s], &inverse, ni, nk, nk);
            }
            for &(si, sj, target) in &self.updates[self.updates_start[k]..self.updates_start[k + 1]] {
                let (ni, nj) = (self.sizes[self.order[self.adj[si]]], self.sizes[self.order[self.adj[sj]]]);
                let product = multiply(&self.low[si], &self.up[sj], ni, nk, nj);
                let out = match target {
                    Place::Diagonal(d) => &mut self.diag[d],
                    Place::Low(s) => &mut self.low[s],
                    Place::Up(s) => &mut self.up[s],
                };
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
    pub(super) fn solve(&mut self, b: &mut [T]) {
        let n = self.order.len();
        // Gather by position.
        for node in 0..n {
            let (k, size, start) = (self.position[node], self.sizes[node], self.starts[node]);
            let mut v = [T::zero(); 6];
            for (r, x) in v.iter_mut().enumerate().take(size) {
                *x = b.get(start + r).copied().unwrap_or_else(T::zero);
            }
            self.x[k] = v;
        }
        // Forward: y = L⁻¹ b.
        for k in 0..n {
            let nk = self.sizes[self.order[k]];
            let yk = self.x[k];
            for s in self.adj_start[k]..self.adj_start[k + 1] {
                let i = self.adj[s];
                let ni = self.sizes[self.order[i]];
                for r in 0..ni {
                    let row = &self.low[s][6 * r..6 * r + nk];
                    self.x[i][r] -= row.iter().zip(&yk).fold(T::zero(), |sum, (&a, &y)| sum + a * y);
                }
            }
        }
        // Backward: x_k = D_k⁻¹ (y_k − Σ U_kj x_j).
        for k in (0..n).rev() {
            let nk = self.sizes[self.order[k]];
            let mut rhs = self.x[k];
            for s in self.adj_start[k]..self.adj_start[k + 1] {
                let j = self.adj[s];
                let nj = self.sizes[self.order[j]];
                for (r, x) in rhs.iter_mut().enumerate().take(nk) {
                    for c in 0..nj {
                        *x -= self.up[s][6 * r + c] * self.x[j][c];
                    }
                }
            }
            let mut out = [T::zero(); 6];
            for (r, o) in out.iter_mut().enumerate().take(nk) {
                for (c, &x) in rhs.iter().enumerate().take(nk) {
                    *o += self.diag[k][6 * r + c] * x;
                }
            }
            self.x[k] = out;
        }
        for node in 0..n {
            let (k, size, start) = (self.position[node], self.sizes[node], self.starts[node]);
            for r in 0..size {
                if let Some(x) = b.get_mut(start + r) {
                    *x = self.x[k][r];
                }
            }
        }
    }

    /// Number of blocks stored (diagonal, below and above).
    pub(super) fn blocks(&self) -> usize {
        self.diag.len() + 2 * self.low.len()
    }

    /// A matrix on the same pattern with entries of type `U`, all zero.
    pub(super) fn like<U: Entry>(&self) -> Kkt<U> {
        Kkt {
            sizes: self.sizes.clone(),
            starts: self.starts.clone(),
            order: self.order.clone(),
            position: self.position.clone(),
            adj_start: self.adj_start.clone(),
            adj: self.adj.clone(),
            updates_start: self.updates_start.clone(),
            updates: self.updates.clone(),
            diag: vec![zero(); self.diag.len()],
            low: vec![zero(); self.low.len()],
            up: vec![zero(); self.up.len()],
            x: vec![[U::zero(); 6]; self.x.len()],
        }
    }

    /// Sets every block to `Σ c P` over the assembled (not factorised)
    /// real matrices `parts` on this pattern (made by [`Kkt::like`]); blocks
    /// of a part with another pattern are ignored.
    pub(super) fn combine(&mut self, parts: &[(&Kkt<f64>, T)]) {
        self.clear();
        for &(part, c) in parts {
            let pairs = [(&mut self.diag, &part.diag), (&mut self.low, &part.low), (&mut self.up, &part.up)];
            for (out, from) in pairs {
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
    pub(super) fn times(&self, x: &[T], out: &mut [T]) {
        out.fill(T::zero());
        let start = &self.starts;
        let mut add = |block: &Block<T>, row: usize, column: usize| {
            let (r0, c0) = (start[row], start[column]);
            for r in 0..self.sizes[row] {
                let mut sum = T::zero();
                for c in 0..self.sizes[column] {
                    sum += block[6 * r + c] * x.get(c0 + c).copied().unwrap_or_else(T::zero);
                }
                if let Some(o) = out.get_mut(r0 + r) {
                    *o += sum;
                }
            }
        };
        for (k, &node) in self.order.iter().enumerate() {
            add(&self.diag[k], node, node);
            for s in self.adj_start[k]..self.adj_start[k + 1] {
                let other = self.order[self.adj[s]];
                add(&self.low[s], other, node);
                add(&self.up[s], node, other);
            }
        }
    }
}

/// Minimum degree on `graph` (bodies are nodes `0..bodies`, joint `j` node
/// `bodies + j`), a joint eligible only once its bodies are eliminated; ties
/// go to the lower node, so the order is deterministic. Returns the order and,
/// for each step, the nodes still in the graph that the eliminated one reached
/// (fill included): the factor's pattern.
fn elimination_order(
    mut graph: Vec<BTreeSet<usize>>,
    bodies: usize,
    joint_bodies: &[[Option<usize>; 2]],
) -> (Vec<usize>, Vec<Vec<usize>>) {
    let n = graph.len();
    let mut done = vec![false; n];
    let (mut order, mut later) = (Vec::with_capacity(n), Vec::with_capacity(n));
    while order.len() < n {
        let eligible = |x: usize| {
            !done[x]
                && (x < bodies || joint_bodies.get(x - bodies).is_none_or(|p| p.iter().flatten().all(|&b| done[b])))
        };
        let Some(next) = (0..n).filter(|&x| eligible(x)).min_by_key(|&x| (graph[x].len(), x)) else { break };
        let neighbours: Vec<usize> = graph[next].iter().copied().collect();
        for &a in &neighbours {
            graph[a].remove(&next);
            for &b in &neighbours {
                if a != b {
                    graph[a].insert(b);
                }
            }
        }
        done[next] = true;
        order.push(next);
        later.push(neighbours);
    }
    (order, later)
}

/// `a (r × k) · b (k × c)`.
fn multiply<T: Entry>(a: &Block<T>, b: &Block<T>, r: usize, k: usize, c: usize) -> Block<T> {
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
/// pivoting.
fn invert<T: Entry>(a: &Block<T>, n: usize) -> Result<Block<T>, LinalgError> {
    let mut m = *a;
    let mut inv = zero::<T>();
    for i in 0..n {
        inv[6 * i + i] = T::one();
    }
    // |re| + |im| for complex entries: as good as the modulus, without its hypot.
    let scale = (0..n * 6).map(|i| m[i].norm1()).fold(0.0, f64::max);
    if !scale.is_finite() {
        return Err(LinalgError::NonFinite);
    }
    for col in 0..n {
        let Some(p) = (col..n).max_by(|&x, &y| m[6 * x + col].norm1().total_cmp(&m[6 * y + col].norm1())) else {
            break;
        };
        let pivot = m[6 * p + col];
        if !(pivot.norm1() > 1e-300 && pivot.norm1() > f64::EPSILON * 1e-3 * scale) {
            return Err(LinalgError::Singular { step: col });
        }
        for c in 0..6 {
            m.swap(6 * p + c, 6 * col + c);
            inv.swap(6 * p + c, 6 * col + c);
        }
        for c in 0..n {
            m[6 * col + c] /= pivot;
            inv[6 * col + c] /= pivot;
        }
        for r in 0..n {
            let f = m[6 * r + col];
            if r != col && f != T::zero() {
                for c in 0..n {
                    m[6 * r + c] -= f * m[6 * col + c];
                    inv[6 * r + c] -= f * inv[6 * col + c];
                }
            }
        }
    }
    Ok(inv)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A chain of three bodies on two joints plus a ground joint, against a
    /// dense solve of the same matrix.
    #[test]
    fn matches_a_dense_solve() {
        let joint_rows = [3, 3, 2];
        let joint_bodies = [[None, Some(0)], [Some(0), Some(1)], [Some(1), Some(2)]];
        let couplings = [(0, 1), (1, 2)];
        let mut kkt = Kkt::new(3, &joint_rows, &joint_bodies, &couplings).expect("pattern");
        let n = 18 + 8;
        let offsets = [0, 6, 12, 18, 21, 24];
        let mut dense = vec![0.0; n * n];
        let mut seed = 1u64;
        let mut random = || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let mut put = |kkt: &mut Kkt, dense: &mut Vec<f64>, a: usize, b: usize, na: usize, nb: usize, diag: f64| {
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
        let mut x = rhs.clone();
        kkt.factor().expect("nonsingular");
        kkt.solve(&mut x);
        let residual = (0..n)
            .map(|r| libm::fabs((0..n).map(|c| dense[r * n + c] * x[c]).sum::<f64>() - rhs[r]))
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
        let real = Kkt::<f64>::new(2, &joint_rows, &joint_bodies, &[(0, 1)]).expect("pattern");
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
        let mut complex = real.like::<Complex<f64>>();
        let weighted: Vec<(&Kkt<f64>, Complex<f64>)> = parts.iter().zip(coefficients).collect();
        complex.combine(&weighted);
        let n = 12 + 5;
        let x: Vec<Complex<f64>> = (0..n).map(|i| Complex::new((i as f64).sin(), (i as f64).cos())).collect();
        let mut b = vec![Complex::new(0.0, 0.0); n];
        complex.times(&x, &mut b);
        // The product part by part (real parts times x), weighted.
        let mut want = vec![Complex::new(0.0, 0.0); n];
        for (part, c) in parts.iter().zip(coefficients) {
            for (re, im) in [(true, false), (false, true)] {
                let xs: Vec<f64> = x.iter().map(|z| if re { z.re } else { z.im }).collect();
                let mut y = vec![0.0; n];
                part.times(&xs, &mut y);
                for (w, &y) in want.iter_mut().zip(&y) {
                    *w += c * if im { Complex::new(0.0, y) } else { Complex::new(y, 0.0) };
                }
            }
        }
        let product_gap = b.iter().zip(&want).map(|(p, q)| (p - q).norm()).fold(0.0, f64::max);
        assert!(product_gap < 1e-14, "{product_gap:e}");
        complex.factor().expect("nonsingular");
        let mut solved = b.clone();
        complex.solve(&mut solved);
        let gap = solved.iter().zip(&x).map(|(p, q)| (p - q).norm()).fold(0.0, f64::max);
        assert!(gap < 1e-12, "{gap:e}");
    }

    #[test]
    fn joints_wait_for_their_bodies() {
        // Bodies 0, 1; joint 2 grounds body 0, joint 3 joins 0 and 1. By degree
        // alone joint 2 (one neighbour) would go first, onto a zero pivot.
        let mut graph = vec![BTreeSet::new(); 4];
        for (a, b) in [(2, 0), (3, 0), (3, 1)] {
            graph[a].insert(b);
            graph[b].insert(a);
        }
        let (order, _) = elimination_order(graph, 2, &[[None, Some(0)], [Some(0), Some(1)]]);
        let at = |x: usize| order.iter().position(|&y| y == x).expect("every node");
        assert!(at(2) > at(0) && at(3) > at(0) && at(3) > at(1), "{order:?}");
    }
}
