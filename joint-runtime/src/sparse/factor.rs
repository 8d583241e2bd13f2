//! The block factor of `J W Jᵀ` (`W` the inverse mass matrix) on the scene's
//! compile-time pattern: a static schedule built once, run at every step.

use alloc::vec;
use alloc::vec::Vec;

use crate::analysis::InverseMass;
use crate::linalg::LinalgError;

/// A dense block of at most 6 × 6, row-major (`6 r + c`).
type Block = [f64; 36];

const ZERO: Block = [0.0; 36];

/// A joint's block: its rows and the bodies it connects.
#[derive(Clone, Copy, Debug)]
struct JointRows {
    start: usize,
    rows: usize,
    bodies: [Option<usize>; 2],
}

/// The factor of `A = J W Jᵀ` (`P A Pᵀ = L Lᵀ` on the rows kept), its pattern
/// and schedule fixed at construction.
#[derive(Clone, Debug)]
pub struct BlockFactor {
    /// Joint blocks by elimination position.
    joints: Vec<JointRows>,
    /// Block rows of factor column `k`: `col[col_start[k]..col_start[k + 1]]`,
    /// the diagonal first; each entry is a position `i ≥ k`.
    col_start: Vec<usize>,
    col: Vec<usize>,
    /// For each factor slot `(i, k)`: the pairs `(slot (i, j), slot (k, j))`,
    /// `j < k`, whose product updates it.
    sched_start: Vec<usize>,
    sched: Vec<(usize, usize)>,
    /// For each slot `(i, k)`: the bodies the two joints share, as `(side of i,
    /// side of k, body)`: the terms of `A_ik = Σ J_i,b W_b J_k,bᵀ`.
    shared_start: Vec<usize>,
    shared: Vec<(usize, usize, usize)>,
    /// For each position `k`: `(j, slot (k, j))` for `j < k` (the forward solve).
    row_start: Vec<usize>,
    row: Vec<(usize, usize)>,
    /// Each Jacobian entry's place: `(2 k + side, 6 r + c)`.
    scatter: Vec<(usize, usize)>,
    /// `J` per joint and side (rows × 6), and `J W`.
    jb: Vec<Block>,
    jw: Vec<Block>,
    /// Factor blocks per slot; the diagonal slot holds the block's own columns.
    l: Vec<Block>,
    /// Per position: pivot order within the block and rank.
    perm: Vec<[usize; 6]>,
    rank: Vec<usize>,
    /// Rows dropped as redundant, ascending.
    dropped: Vec<usize>,
    /// Scratch of the solves (allocated once).
    z: Vec<[f64; 6]>,
    lambda: Vec<[f64; 6]>,
}

/// The slot of `(i, k)` in factor column `k`, if the pattern has it.
fn slot(col_start: &[usize], col: &[usize], i: usize, k: usize) -> Option<usize> {
    let (a, b) = (*col_start.get(k)?, *col_start.get(k + 1)?);
    col.get(a..b)?.binary_search(&i).ok().map(|x| a + x)
}

/// A problem with the structure a scene declares (a derive bug, or a
/// hand-written impl that contradicts itself).
const BAD_STRUCTURE: LinalgError = LinalgError::NonFinite;

impl BlockFactor {
    /// The factor's structure for a scene with joint row blocks `blocks`
    /// (`(start, rows)` in row order), their bodies, the Jacobian's CSR
    /// pattern and the derive's elimination order and factor pattern.
    ///
    /// # Errors
    /// [`LinalgError::NonFinite`] if the structure contradicts itself (a row of
    /// a joint with an entry outside its bodies' columns, a block over 6 rows,
    /// an order that is not a permutation).
    pub fn new(
        blocks: &[(usize, usize)],
        bodies: &[[Option<usize>; 2]],
        row_starts: &[usize],
        columns: &[usize],
        elimination: &[usize],
        factor_starts: &[usize],
        factor_below: &[usize],
    ) -> Result<Self, LinalgError> {
        let n = blocks.len();
        if bodies.len() != n || elimination.len() != n || factor_starts.len() != n + 1 {
            return Err(BAD_STRUCTURE);
        }
        let mut joints = Vec::with_capacity(n);
        let mut position = vec![usize::MAX; n];
        for (k, &b) in elimination.iter().enumerate() {
            let (&(start, rows), &bodies) = (blocks.get(b).ok_or(BAD_STRUCTURE)?, bodies.get(b).ok_or(BAD_STRUCTURE)?);
            if rows > 6 || position[b] != usize::MAX {
                return Err(BAD_STRUCTURE);
            }
            position[b] = k;
            joints.push(JointRows { start, rows, bodies });
        }
        // Factor columns: the diagonal, then the pattern below.
        let (mut col_start, mut col) = (vec![0], Vec::new());
        for k in 0..n {
            col.push(k);
            let below = factor_below.get(factor_starts[k]..factor_starts[k + 1]).ok_or(BAD_STRUCTURE)?;
            if below.iter().any(|&i| i <= k || i >= n) {
                return Err(BAD_STRUCTURE);
            }
            col.extend_from_slice(below);
            col_start.push(col.len());
        }
        let mut f = BlockFactor {
            joints,
            col_start,
            col,
            sched_start: Vec::new(),
            sched: Vec::new(),
            shared_start: Vec::new(),
            shared: Vec::new(),
            row_start: Vec::new(),
            row: Vec::new(),
            scatter: Vec::new(),
            jb: vec![ZERO; 2 * n],
            jw: vec![ZERO; 2 * n],
            l: Vec::new(),
            perm: vec![[0; 6]; n],
            rank: vec![0; n],
            dropped: Vec::new(),
            z: vec![[0.0; 6]; n],
            lambda: vec![[0.0; 6]; n],
        };
        f.l = vec![ZERO; f.col.len()];
        f.schedule()?;
        f.scatter_map(&position, blocks, row_starts, columns)?;
        Ok(f)
    }

    /// The update schedule, the shared bodies of each slot and the rows of `L`.
    fn schedule(&mut self) -> Result<(), LinalgError> {
        let n = self.joints.len();
        let mut updates: Vec<Vec<(usize, usize)>> = vec![Vec::new(); self.col.len()];
        let mut rows: Vec<Vec<(usize, usize)>> = vec![Vec::new(); n];
        for j in 0..n {
            let column = &self.col[self.col_start[j] + 1..self.col_start[j + 1]];
            for (x, &k) in column.iter().enumerate() {
                let skj = self.col_start[j] + 1 + x;
                rows[k].push((j, skj));
                for (y, &i) in column.iter().enumerate().skip(x) {
                    let sij = self.col_start[j] + 1 + y;
                    // Eliminating j joins i and k: the pattern has (i, k).
                    let sik = slot(&self.col_start, &self.col, i, k).ok_or(BAD_STRUCTURE)?;
                    updates[sik].push((sij, skj));
                }
            }
        }
        self.sched_start = vec![0];
        self.shared_start = vec![0];
        for k in 0..n {
            for (s, update) in updates.iter().enumerate().take(self.col_start[k + 1]).skip(self.col_start[k]) {
                self.sched.extend_from_slice(update);
                self.sched_start.push(self.sched.len());
                let (a, b) = (self.joints[self.col[s]].bodies, self.joints[k].bodies);
                for (si, bi) in a.iter().enumerate() {
                    for (sk, bk) in b.iter().enumerate() {
                        if let (Some(x), Some(y)) = (bi, bk)
                            && x == y
                        {
                            self.shared.push((si, sk, *x));
                        }
                    }
                }
                self.shared_start.push(self.shared.len());
            }
        }
        self.row_start = vec![0];
        for r in rows {
            self.row.extend(r);
            self.row_start.push(self.row.len());
        }
        Ok(())
    }

    /// Where each Jacobian entry goes: its joint's block and side.
    fn scatter_map(
        &mut self,
        position: &[usize],
        blocks: &[(usize, usize)],
        row_starts: &[usize],
        columns: &[usize],
    ) -> Result<(), LinalgError> {
        for (b, &(start, rows)) in blocks.iter().enumerate() {
            let k = position[b];
            let bodies = self.joints[k].bodies;
            for r in 0..rows {
                let (Some(&a), Some(&e)) = (row_starts.get(start + r), row_starts.get(start + r + 1)) else {
                    return Err(BAD_STRUCTURE);
                };
                for &c in columns.get(a..e).ok_or(BAD_STRUCTURE)? {
                    let side = bodies.iter().position(|x| *x == Some(c / 6)).ok_or(BAD_STRUCTURE)?;
                    self.scatter.push((2 * k + side, 6 * r + c % 6));
                }
            }
        }
        Ok(())
    }

    /// Number of Jacobian entries the factor reads.
    pub fn nonzeros(&self) -> usize {
        self.scatter.len()
    }

    /// Blocks stored for the factor (diagonal and below, fill included).
    pub fn factor_blocks(&self) -> usize {
        self.col.len()
    }

    /// Rows dropped as redundant by the last factorisation, ascending.
    pub fn dropped(&self) -> &[usize] {
        &self.dropped
    }

    /// The numerical rank of the last factorisation.
    pub fn rank(&self) -> usize {
        self.rank.iter().sum()
    }

    /// Factorises `J W Jᵀ` for the Jacobian entries `values` (the scene's CSR
    /// order) and the inverse masses `w`. With `keep` (from a previous
    /// factorisation, see [`BlockFactor::rule`]) each block keeps the same
    /// pivots, so that nearby matrices drop the same rows; without it, pivots
    /// are chosen here. `tolerance` is relative to the largest diagonal entry.
    ///
    /// # Errors
    /// [`LinalgError::NonFinite`] for a non-finite entry.
    pub(crate) fn factor(
        &mut self,
        values: &[f64],
        w: &[InverseMass],
        tolerance: f64,
        keep: Option<&[([usize; 6], usize)]>,
    ) -> Result<(), LinalgError> {
        if values.len() != self.scatter.len() || !values.iter().all(|x| x.is_finite()) {
            return Err(LinalgError::NonFinite);
        }
        self.jb.fill(ZERO);
        for (&(s, o), &v) in self.scatter.iter().zip(values) {
            self.jb[s][o] = v;
        }
        self.times_metric(w);
        let tolerance = if tolerance > 0.0 { tolerance * self.largest_diagonal() } else { 0.0 };
        self.dropped.clear();
        for k in 0..self.joints.len() {
            let rule = keep.and_then(|r| r.get(k)).copied();
            self.factor_column(k, tolerance, rule);
        }
        self.dropped.sort_unstable();
        Ok(())
    }

    /// Each block's pivots and rank: the rule that makes a later factorisation
    /// drop the same rows.
    // An iterator, not a `Vec`: the step copies it into its own buffer,
    // allocated once.
    pub(crate) fn rule(&self) -> impl Iterator<Item = ([usize; 6], usize)> + '_ {
        self.perm.iter().copied().zip(self.rank.iter().copied())
    }

    /// `J W` per joint and side.
    fn times_metric(&mut self, w: &[InverseMass]) {
        for (k, joint) in self.joints.iter().enumerate() {
            for side in 0..2 {
                let s = 2 * k + side;
                let Some(m) = joint.bodies[side].and_then(|b| w.get(b)) else {
                    self.jw[s] = ZERO;
                    continue;
                };
                let (j, out) = (&self.jb[s], &mut self.jw[s]);
                for r in 0..joint.rows {
                    for c in 0..3 {
                        out[6 * r + c] = j[6 * r + c] * m.inv_mass;
                        out[6 * r + 3 + c] = (0..3).map(|x| j[6 * r + 3 + x] * m.inv_inertia[(x, c)]).sum::<f64>();
                    }
                }
            }
        }
    }

    /// The largest diagonal entry of `A`, the scale of the rank tolerance: row
    /// by row, without the off-diagonal entries of the blocks (a third of the
    /// diagonal blocks' cost for a spherical joint's three rows).
    fn largest_diagonal(&self) -> f64 {
        let mut largest = 0.0f64;
        for (k, joint) in self.joints.iter().enumerate() {
            let s = self.col_start[k];
            let shared = &self.shared[self.shared_start[s]..self.shared_start[s + 1]];
            for r in 0..joint.rows {
                let entry: f64 = shared
                    .iter()
                    .map(|&(si, sk, _)| {
                        let (jw, jb) = (&self.jw[2 * k + si], &self.jb[2 * k + sk]);
                        (0..6).map(|c| jw[6 * r + c] * jb[6 * r + c]).sum::<f64>()
                    })
                    .sum();
                largest = largest.max(entry);
            }
        }
        largest
    }

    /// `A_ik = Σ_b (J W)_i,b J_k,bᵀ` for slot `s = (i, k)`.
    fn gram(&self, s: usize, k: usize) -> Block {
        let i = self.col[s];
        let (ri, rk) = (self.joints[i].rows, self.joints[k].rows);
        let mut a = ZERO;
        for &(si, sk, _) in &self.shared[self.shared_start[s]..self.shared_start[s + 1]] {
            let (jw, jb) = (&self.jw[2 * i + si], &self.jb[2 * k + sk]);
            for x in 0..ri {
                for y in 0..rk {
                    a[6 * x + y] += (0..6).map(|c| jw[6 * x + c] * jb[6 * y + c]).sum::<f64>();
                }
            }
        }
        a
    }

    /// `A_ik − Σ_j L_ij L_kjᵀ` for slot `s = (i, k)`.
    fn updated(&self, s: usize, k: usize) -> Block {
        let mut b = self.gram(s, k);
        let (ri, rk) = (self.joints[self.col[s]].rows, self.joints[k].rows);
        for &(sij, skj) in &self.sched[self.sched_start[s]..self.sched_start[s + 1]] {
            let (lij, lkj) = (&self.l[sij], &self.l[skj]);
            for x in 0..ri {
                for y in 0..rk {
                    b[6 * x + y] -= (0..6).map(|c| lij[6 * x + c] * lkj[6 * y + c]).sum::<f64>();
                }
            }
        }
        b
    }

    /// Column `k`: the diagonal block by pivoted Cholesky, the blocks below by
    /// triangular solves against it.
    fn factor_column(&mut self, k: usize, tolerance: f64, rule: Option<([usize; 6], usize)>) {
        let d = self.updated(self.col_start[k], k);
        let (perm, rank, l) = pivoted_cholesky(&d, self.joints[k].rows, tolerance, rule);
        self.l[self.col_start[k]] = l;
        self.perm[k] = perm;
        self.rank[k] = rank;
        let start = self.joints[k].start;
        self.dropped.extend(perm[rank..self.joints[k].rows].iter().map(|&r| start + r));
        for s in self.col_start[k] + 1..self.col_start[k + 1] {
            let b = self.updated(s, k);
            let ri = self.joints[self.col[s]].rows;
            let out = &mut self.l[s];
            *out = ZERO;
            for x in 0..ri {
                // T y = B[x, perm[..rank]], T[a][c] = L_kk[perm[a]][c].
                for a in 0..rank {
                    let sum: f64 = (0..a).map(|c| l[6 * perm[a] + c] * out[6 * x + c]).sum();
                    out[6 * x + a] = (b[6 * x + perm[a]] - sum) / l[6 * perm[a] + a];
                }
            }
        }
    }

    /// Solves `A λ = b` on the rows kept (λ = 0 on the dropped ones), in place.
    pub fn solve(&mut self, b: &mut [f64]) {
        let n = self.joints.len();
        let (mut z, mut lambda) = (core::mem::take(&mut self.z), core::mem::take(&mut self.lambda));
        for k in 0..n {
            let JointRows { start, rows, .. } = self.joints[k];
            let mut c = [0.0; 6];
            for (x, cx) in c.iter_mut().enumerate().take(rows) {
                *cx = b.get(start + x).copied().unwrap_or(0.0);
            }
            for &(j, s) in &self.row[self.row_start[k]..self.row_start[k + 1]] {
                for (x, cx) in c.iter_mut().enumerate().take(rows) {
                    *cx -= (0..self.rank[j]).map(|y| self.l[s][6 * x + y] * z[j][y]).sum::<f64>();
                }
            }
            let (l, perm) = (&self.l[self.col_start[k]], &self.perm[k]);
            for a in 0..self.rank[k] {
                let sum: f64 = (0..a).map(|y| l[6 * perm[a] + y] * z[k][y]).sum();
                z[k][a] = (c[perm[a]] - sum) / l[6 * perm[a] + a];
            }
        }
        lambda.fill([0.0; 6]);
        for k in (0..n).rev() {
            let rank = self.rank[k];
            let mut c = z[k];
            for s in self.col_start[k] + 1..self.col_start[k + 1] {
                let i = self.col[s];
                for (a, ca) in c.iter_mut().enumerate().take(rank) {
                    *ca -= (0..self.joints[i].rows).map(|x| self.l[s][6 * x + a] * lambda[i][x]).sum::<f64>();
                }
            }
            let (l, perm) = (&self.l[self.col_start[k]], &self.perm[k]);
            let mut y = [0.0; 6];
            for a in (0..rank).rev() {
                let sum: f64 = (a + 1..rank).map(|e| l[6 * perm[e] + a] * y[e]).sum();
                y[a] = (c[a] - sum) / l[6 * perm[a] + a];
            }
            for a in 0..rank {
                lambda[k][perm[a]] = y[a];
            }
        }
        for (joint, values) in self.joints.iter().zip(&lambda) {
            for (x, &v) in values.iter().enumerate().take(joint.rows) {
                if let Some(out) = b.get_mut(joint.start + x) {
                    *out = v;
                }
            }
        }
        (self.z, self.lambda) = (z, lambda);
    }
}

/// Pivoted Cholesky of the leading `n × n` of `d`: the columns `l_c` (rows in
/// the block's order, column `c` in `6 r + c`), the pivot order and the rank.
/// With `rule`, its pivots are kept (falling back to choosing them if one is
/// not positive).
fn pivoted_cholesky(
    d: &Block,
    n: usize,
    tolerance: f64,
    rule: Option<([usize; 6], usize)>,
) -> ([usize; 6], usize, Block) {
    if let Some((perm, rank)) = rule
        && let Some(l) = cholesky_in_order(d, n, &perm, rank.min(n))
    {
        return (perm, rank.min(n), l);
    }
    let mut w = *d;
    let mut perm = [0, 1, 2, 3, 4, 5];
    let mut l = ZERO;
    let mut rank = 0;
    for c in 0..n {
        let Some(p) = (c..n).max_by(|&a, &b| w[7 * perm[a]].total_cmp(&w[7 * perm[b]])) else { break };
        let pivot = w[7 * perm[p]];
        if pivot.is_nan() || pivot <= tolerance || pivot <= 0.0 {
            break;
        }
        perm.swap(c, p);
        eliminate(&mut w, &mut l, &perm, c, n);
        rank = c + 1;
    }
    (perm, rank, l)
}

/// Column `c` of the factor at pivot `perm[c]`, and the update of the rest.
fn eliminate(w: &mut Block, l: &mut Block, perm: &[usize; 6], c: usize, n: usize) {
    let p = perm[c];
    let root = libm::sqrt(w[7 * p]);
    l[6 * p + c] = root;
    for &r in &perm[c + 1..n] {
        l[6 * r + c] = w[6 * r + p] / root;
    }
    for &r in &perm[c + 1..n] {
        for &s in &perm[c + 1..n] {
            w[6 * r + s] -= l[6 * r + c] * l[6 * s + c];
        }
    }
}

/// The factor with the pivots `perm[..rank]` prescribed, if each is positive.
fn cholesky_in_order(d: &Block, n: usize, perm: &[usize; 6], rank: usize) -> Option<Block> {
    let mut w = *d;
    let mut l = ZERO;
    for c in 0..rank {
        let pivot = w[7 * perm[c]];
        if pivot.is_nan() || pivot <= 0.0 {
            return None;
        }
        eliminate(&mut w, &mut l, perm, c, n);
    }
    Some(l)
}
