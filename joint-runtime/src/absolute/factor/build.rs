//! The factor's schedule, built once from the derive's pattern into the
//! storage's arrays (no allocation: each list is counted, then filled).

use super::{BAD_STRUCTURE, JointRows, Parts};
use crate::linalg::LinalgError;
use crate::scene::RowBlock;

/// What the derive fixes for a scene (see [`SparseJacobian`](crate::SparseJacobian)).
#[derive(Clone, Copy, Debug)]
pub(in crate::absolute) struct Pattern<'a> {
    pub(in crate::absolute) blocks: &'a [RowBlock],
    pub(in crate::absolute) bodies: &'a [[Option<usize>; 2]],
    pub(in crate::absolute) row_starts: &'a [usize],
    pub(in crate::absolute) columns: &'a [usize],
    pub(in crate::absolute) elimination: &'a [usize],
    pub(in crate::absolute) factor_starts: &'a [usize],
    pub(in crate::absolute) factor_below: &'a [usize],
}

/// The slot of `(i, k)` in factor column `k`, if the pattern has it.
fn slot(col_range: &[(usize, usize)], col: &[usize], i: usize, k: usize) -> Option<usize> {
    let &(a, b) = col_range.get(k)?;
    col.get(a..b)?.binary_search(&i).ok().map(|x| a + x)
}

/// `*x = v`, or the structure error if the storage has no entry `i` (its
/// sizes do not match the pattern).
fn put<T>(list: &mut [T], i: usize, v: T) -> Result<(), LinalgError> {
    *list.get_mut(i).ok_or(BAD_STRUCTURE)? = v;
    Ok(())
}

/// `list[i]`, or the structure error: every look-up here is checked, so
/// that building a factor cannot panic whatever pattern it is given.
fn get<T: Copy>(list: &[T], i: usize) -> Result<T, LinalgError> {
    list.get(i).copied().ok_or(BAD_STRUCTURE)
}

/// Turns per-entry counts (in each range's end) into consecutive ranges,
/// each empty at its start (its end the fill cursor); returns the total.
fn prefix(ranges: &mut [(usize, usize)]) -> usize {
    let mut at = 0;
    for r in ranges {
        let count = r.1;
        *r = (at, at);
        at += count;
    }
    at
}

impl Parts<'_> {
    /// Fills the pattern's arrays; every list must fill its array exactly.
    pub(super) fn build(&mut self, p: &Pattern<'_>) -> Result<(), LinalgError> {
        let n = p.blocks.len();
        if p.bodies.len() != n
            || p.elimination.len() != n
            || p.factor_starts.len() != n + 1
            || self.joints.len() != n
            || p.row_starts.len() != self.dropped.len() + 1
        {
            return Err(BAD_STRUCTURE);
        }
        self.joint_order(p)?;
        self.columns(p)?;
        self.schedule()?;
        self.scatter_map(p)?;
        // `rank` held each block's elimination position meanwhile.
        self.rank.fill(0);
        Ok(())
    }

    /// Joint blocks by elimination position; `rank[b]` the position of block `b`.
    fn joint_order(&mut self, p: &Pattern<'_>) -> Result<(), LinalgError> {
        self.rank.fill(usize::MAX);
        for (k, &b) in p.elimination.iter().enumerate() {
            let (block, &bodies) = (p.blocks.get(b).ok_or(BAD_STRUCTURE)?, p.bodies.get(b).ok_or(BAD_STRUCTURE)?);
            let position = self.rank.get_mut(b).ok_or(BAD_STRUCTURE)?;
            if block.rows > 6 || *position != usize::MAX {
                return Err(BAD_STRUCTURE);
            }
            *position = k;
            put(self.joints, k, JointRows { start: block.start, rows: block.rows, bodies })?;
        }
        Ok(())
    }

    /// Factor columns: the diagonal, then the pattern below.
    fn columns(&mut self, p: &Pattern<'_>) -> Result<(), LinalgError> {
        let n = self.joints.len();
        let mut at = 0;
        for k in 0..n {
            let start = at;
            put(self.col, at, k)?;
            at += 1;
            let (a, b) = (get(p.factor_starts, k)?, get(p.factor_starts, k + 1)?);
            for &i in p.factor_below.get(a..b).ok_or(BAD_STRUCTURE)? {
                if i <= k || i >= n {
                    return Err(BAD_STRUCTURE);
                }
                put(self.col, at, i)?;
                at += 1;
            }
            put(self.col_range, k, (start, at))?;
        }
        if at != self.col.len() { Err(BAD_STRUCTURE) } else { Ok(()) }
    }

    /// The update schedule, the shared bodies of each slot and the rows of
    /// `L`, each list counted per slot (or row), then filled in order.
    fn schedule(&mut self) -> Result<(), LinalgError> {
        let n = self.joints.len();
        for fill in [false, true] {
            for j in 0..n {
                let (a, b) = get(self.col_range, j)?;
                for x in a + 1..b {
                    let k = get(self.col, x)?;
                    let r = &mut self.row_range.get_mut(k).ok_or(BAD_STRUCTURE)?.1;
                    if fill {
                        put(self.row, *r, (j, x))?;
                    }
                    *r += 1;
                    for y in x..b {
                        // Eliminating j joins i and k: the pattern has (i, k).
                        let sik = slot(self.col_range, self.col, get(self.col, y)?, k).ok_or(BAD_STRUCTURE)?;
                        let u = &mut self.sched_range.get_mut(sik).ok_or(BAD_STRUCTURE)?.1;
                        if fill {
                            put(self.sched, *u, (j, y, x))?;
                        }
                        *u += 1;
                    }
                }
            }
            if !fill
                && (prefix(self.sched_range) != self.sched.len()
                    || Some(prefix(self.row_range)) != self.col.len().checked_sub(n))
            {
                return Err(BAD_STRUCTURE);
            }
        }
        let mut at = 0;
        for k in 0..n {
            let (a, b) = get(self.col_range, k)?;
            for s in a..b {
                let start = at;
                let (x, y) = (get(self.joints, get(self.col, s)?)?.bodies, get(self.joints, k)?.bodies);
                for (si, bi) in x.iter().enumerate() {
                    for (sk, bk) in y.iter().enumerate() {
                        if let (Some(u), Some(v)) = (bi, bk)
                            && u == v
                        {
                            put(self.shared, at, (si, sk, *u))?;
                            at += 1;
                        }
                    }
                }
                put(self.shared_range, s, (start, at))?;
            }
        }
        if at != self.shared.len() { Err(BAD_STRUCTURE) } else { Ok(()) }
    }

    /// Where each Jacobian entry goes: its joint's block and side.
    fn scatter_map(&mut self, p: &Pattern<'_>) -> Result<(), LinalgError> {
        let mut at = 0;
        for (b, block) in p.blocks.iter().enumerate() {
            let k = get(self.rank, b)?;
            let bodies = get(self.joints, k)?.bodies;
            for r in 0..block.rows {
                let (Some(&a), Some(&e)) = (p.row_starts.get(block.start + r), p.row_starts.get(block.start + r + 1))
                else {
                    return Err(BAD_STRUCTURE);
                };
                for &c in p.columns.get(a..e).ok_or(BAD_STRUCTURE)? {
                    let side = bodies.iter().position(|x| *x == Some(c / 6)).ok_or(BAD_STRUCTURE)?;
                    put(self.scatter, at, (2 * k + side, 6 * r + c % 6))?;
                    at += 1;
                }
            }
        }
        if at != self.scatter.len() { Err(BAD_STRUCTURE) } else { Ok(()) }
    }
}
