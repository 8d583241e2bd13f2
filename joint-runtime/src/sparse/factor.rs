//! The block factor of `J W Jᵀ` (`W` the inverse mass matrix) on the scene's
//! compile-time pattern: a static schedule built once, run at every step.

use alloc::vec;
use alloc::vec::Vec;

use crate::analysis::InverseMass;
use crate::linalg::LinalgError;

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

mod kernels;

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
    /// For each factor slot `(i, k)`: the triples `(j, slot (i, j), slot (k,
    /// j))`, `j < k`, whose product updates it.
    sched_start: Vec<usize>,
    sched: Vec<(usize, usize, usize)>,
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
    /// Factorisations made: a caller that remembers what it factorised
    /// knows the factor is still that one while the count stands.
    factorisations: u64,
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
            factorisations: 0,
        };
        f.l = vec![ZERO; f.col.len()];
        f.schedule()?;
        f.scatter_map(&position, blocks, row_starts, columns)?;
        Ok(f)
    }

    /// The update schedule, the shared bodies of each slot and the rows of `L`.
    fn schedule(&mut self) -> Result<(), LinalgError> {
        let n = self.joints.len();
        let mut updates: Vec<Vec<(usize, usize, usize)>> = vec![Vec::new(); self.col.len()];
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
                    updates[sik].push((j, sij, skj));
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

    /// How many factorisations this factor has made (attempts included):
    /// what a simulation step costs, in its dominant operation.
    pub fn factorisations(&self) -> u64 {
        self.factorisations
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
        self.factorisations = self.factorisations.wrapping_add(1);
        if values.len() != self.scatter.len() || !values.iter().all(|x| x.is_finite()) {
            return Err(LinalgError::NonFinite);
        }
        // Entries outside the pattern were zeroed at construction and are
        // never written: no clearing here.
        for (&(s, o), &v) in self.scatter.iter().zip(values) {
            self.jb[s][o] = v;
        }
        self.times_metric(w);
        // The diagonal blocks of `A` first: their largest entry scales the
        // rank tolerance, and each is factorised where it was formed.
        let mut largest = 0.0f64;
        for k in 0..self.joints.len() {
            let s = self.col_start[k];
            self.gram(s, k);
            let d = &self.l[s];
            largest = (0..self.joints[k].rows).fold(largest, |m, r| m.max(d[7 * r]));
        }
        let tolerance = if tolerance > 0.0 { tolerance * largest } else { 0.0 };
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
                    // A side on the ground: its J block is zero, so is J W.
                    continue;
                };
                with_rows!(joint.rows, R => kernels::times_metric::<R>(&self.jb[s], m, &mut self.jw[s]));
            }
        }
    }

    /// `A_ik = Σ_b (J W)_i,b J_k,bᵀ` for slot `s = (i, k)`, written into `l[s]`.
    fn gram(&mut self, s: usize, k: usize) {
        let i = self.col[s];
        let (ri, rk) = (self.joints[i].rows, self.joints[k].rows);
        let out = &mut self.l[s];
        // Only the `ri × rk` entries are ever nonzero (the kernels keep it so).
        with_rows!(ri, RI => with_rows!(rk, RK => kernels::clear::<RI, RK>(out)));
        for &(si, sk, _) in &self.shared[self.shared_start[s]..self.shared_start[s + 1]] {
            let (jw, jb) = (&self.jw[2 * i + si], &self.jb[2 * k + sk]);
            with_rows!(ri, RI => with_rows!(rk, RK => kernels::add_abt::<RI, RK, 6>(jw, jb, out, 1.0)));
        }
    }

    /// Column `k`: the diagonal block by pivoted Cholesky, the blocks below by
    /// triangular solves against it, each slot updated in place by the
    /// columns before it (left-looking: `A_ik − Σ_j L_ij L_kjᵀ`).
    fn factor_column(&mut self, k: usize, tolerance: f64, rule: Option<([usize; 6], usize)>) {
        let (d, rows) = (self.col_start[k], self.joints[k].rows);
        self.update(d, k);
        let (perm, rank) = with_rows!(rows, R => kernels::pivoted_cholesky::<R>(&mut self.l[d], tolerance, rule));
        self.perm[k] = perm;
        self.rank[k] = rank;
        let start = self.joints[k].start;
        self.dropped.extend(perm[rank..rows].iter().map(|&r| start + r));
        for s in d + 1..self.col_start[k + 1] {
            self.gram(s, k);
            self.update(s, k);
            let ri = self.joints[self.col[s]].rows;
            // Every slot of column k comes after its diagonal slot `d`.
            let (before, rest) = self.l.split_at_mut(s);
            let (Some(lkk), Some(out)) = (before.get(d), rest.first_mut()) else { continue };
            with_rows!(ri, RI => with_rows!(rows, RK => kernels::solve_below::<RI, RK>(lkk, &perm, rank, out)));
        }
    }

    /// `l[s] −= Σ_j L_ij L_kjᵀ` for slot `s = (i, k)` (the scheduled products,
    /// all from earlier columns, so from slots before `s`).
    fn update(&mut self, s: usize, k: usize) {
        let (ri, rk) = (self.joints[self.col[s]].rows, self.joints[k].rows);
        let (before, rest) = self.l.split_at_mut(s);
        let Some(out) = rest.first_mut() else { return };
        for &(j, sij, skj) in &self.sched[self.sched_start[s]..self.sched_start[s + 1]] {
            let (Some(lij), Some(lkj), Some(rj)) =
                (before.get(sij), before.get(skj), self.joints.get(j).map(|j| j.rows))
            else {
                continue;
            };
            with_rows!(ri, RI => with_rows!(rk, RK => with_rows!(rj, RJ => kernels::add_abt::<RI, RK, RJ>(lij, lkj, out, -1.0))));
        }
    }

    /// `out = J x` from the Jacobian of the last factorisation, block by
    /// block (regular six-column rows with their structural zeros, which
    /// beats the CSR walk's indirection at these sizes).
    pub(crate) fn j_mul(&self, x: &[f64], out: &mut [f64]) {
        out.fill(0.0);
        for (k, joint) in self.joints.iter().enumerate() {
            let mut acc = [0.0; 6];
            for (side, body) in joint.bodies.iter().enumerate() {
                let Some(x) = body.and_then(|b| x.get(6 * b..6 * b + 6)).and_then(|x| <&[f64; 6]>::try_from(x).ok())
                else {
                    continue;
                };
                with_rows!(joint.rows, R => kernels::add_av::<R, 6>(&self.jb[2 * k + side], x, &mut acc, 1.0));
            }
            for (o, &a) in out.iter_mut().skip(joint.start).zip(&acc[..joint.rows]) {
                *o = a;
            }
        }
    }

    /// `out = Jᵀ y` from the Jacobian of the last factorisation, block by block.
    pub(crate) fn jt_mul(&self, y: &[f64], out: &mut [f64]) {
        out.fill(0.0);
        for (k, joint) in self.joints.iter().enumerate() {
            let mut yk = [0.0; 6];
            for (v, &w) in yk.iter_mut().zip(y.iter().skip(joint.start).take(joint.rows)) {
                *v = w;
            }
            for (side, body) in joint.bodies.iter().enumerate() {
                let Some(o) =
                    body.and_then(|b| out.get_mut(6 * b..6 * b + 6)).and_then(|o| <&mut [f64; 6]>::try_from(o).ok())
                else {
                    continue;
                };
                with_rows!(joint.rows, R => kernels::add_atv::<R, 6>(&self.jb[2 * k + side], &yk, o, 1.0));
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
                let rj = self.joints[j].rows;
                with_rows!(rows, R => with_rows!(rj, RJ => kernels::add_av::<R, RJ>(&self.l[s], &z[j], &mut c, -1.0)));
            }
            z[k] = with_rows!(rows, R => kernels::forward::<R>(&self.l[self.col_start[k]], &self.perm[k], self.rank[k], &c));
        }
        lambda.fill([0.0; 6]);
        for k in (0..n).rev() {
            let (mut c, rk) = (z[k], self.joints[k].rows);
            for s in self.col_start[k] + 1..self.col_start[k + 1] {
                let i = self.col[s];
                with_rows!(self.joints[i].rows, R => with_rows!(rk, RK => kernels::add_atv::<R, RK>(&self.l[s], &lambda[i], &mut c, -1.0)));
            }
            lambda[k] = kernels::backward(&self.l[self.col_start[k]], &self.perm[k], self.rank[k], &c);
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
