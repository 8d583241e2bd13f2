//! Where a problem is: rows located in their joints, lists of redundant rows,
//! the worst residuals, and the input and output checks every analysis makes.

use core::fmt;

use nalgebra::{SMatrix, SVector};

use super::AnalysisError;
use crate::scene::{Scene, SparseJacobian, SystemState};

/// One constraint row, located in its joint.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub struct RowInfo {
    /// The row in the system.
    pub row: u32,
    /// The row within its joint.
    pub joint_row: u32,
    /// The joint that owns it (`""` if no [`RowBlock`](crate::RowBlock) covers it).
    pub joint: &'static str,
}

impl RowInfo {
    const EMPTY: RowInfo = RowInfo { row: 0, joint: "", joint_row: 0 };

    fn of<S, const NB: usize, const NV: usize, const M: usize>(row: usize) -> Self
    where
        S: Scene<NB, NV, M>,
    {
        // Row counts are fixed-size matrix dimensions: far below u32::MAX.
        let narrow = |x: usize| u32::try_from(x).unwrap_or(u32::MAX);
        match S::block_of(row) {
            Some(b) => RowInfo { row: narrow(row), joint: b.name, joint_row: narrow(row - b.start) },
            None => RowInfo { row: narrow(row), joint: "", joint_row: 0 },
        }
    }
}

impl fmt::Display for RowInfo {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "row {} (joint `{}`, row {})", self.row, self.joint, self.joint_row)
    }
}

/// A set of at most `M` rows in increasing order, without allocation (e.g. the
/// redundant rows of a system of `M` constraints).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RowList<const M: usize> {
    rows: [RowInfo; M],
    len: usize,
}

impl<const M: usize> Default for RowList<M> {
    fn default() -> Self {
        RowList { rows: [RowInfo::EMPTY; M], len: 0 }
    }
}

impl<const M: usize> RowList<M> {
    pub(crate) fn from_rows<S, const NB: usize, const NV: usize>(rows: &[usize]) -> Self
    where
        S: Scene<NB, NV, M>,
    {
        let mut list = RowList::default();
        for &r in rows.iter().take(M) {
            // Insertion in increasing row order (after equal rows): the new row
            // goes into the first slot holding a larger row, and every later
            // entry moves up one slot, the last into the free slot `len`
            // (`len < M`: at most `M` rows are taken). Written as one pass over
            // the slots so that no index can be out of range.
            let len = list.len;
            let mut carried = RowInfo::of::<S, NB, NV, M>(r);
            let mut shifting = false;
            for (k, slot) in list.rows.iter_mut().enumerate().take(len + 1) {
                shifting = shifting || k == len || slot.row as usize > r;
                if shifting {
                    core::mem::swap(slot, &mut carried);
                }
            }
            list.len = (len + 1).min(M);
        }
        list
    }

    /// The rows.
    pub fn as_slice(&self) -> &[RowInfo] {
        self.rows.get(..self.len).unwrap_or(&[])
    }

    /// Number of rows.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Whether any row belongs to the joint `name`.
    pub fn contains_joint(&self, name: &str) -> bool {
        self.as_slice().iter().any(|r| r.joint == name)
    }
}

/// A sequence of its rows (only those in the list).
#[cfg(feature = "serde")]
impl<const M: usize> serde::Serialize for RowList<M> {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_seq(self.as_slice())
    }
}

impl<const M: usize> fmt::Display for RowList<M> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, r) in self.as_slice().iter().enumerate() {
            if i > 0 {
                f.write_str(", ")?;
            }
            write!(f, "{r}")?;
        }
        Ok(())
    }
}

/// A row and its residual value.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub struct RowResidual {
    /// Where the row is.
    pub row: RowInfo,
    /// Its residual (Φ for assembly, `J x − b` for the linear analyses).
    pub value: f64,
}

/// The (up to) three rows with the largest residuals, largest first.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub struct WorstRows(pub [Option<RowResidual>; 3]);

impl WorstRows {
    pub(crate) fn of<S, const NB: usize, const NV: usize, const M: usize>(residual: &SVector<f64, M>) -> Self
    where
        S: Scene<NB, NV, M>,
    {
        let mut worst = [None::<RowResidual>; 3];
        for (i, &v) in residual.iter().enumerate() {
            let a = libm::fabs(v);
            if a.is_nan() || a > 0.0 {
                let cand = RowResidual { row: RowInfo::of::<S, NB, NV, M>(i), value: v };
                let mut slot = 3;
                for (k, w) in worst.iter().enumerate() {
                    let beats = match w {
                        None => true,
                        Some(w) => a.is_nan() || a > libm::fabs(w.value),
                    };
                    if beats {
                        slot = k;
                        break;
                    }
                }
                if slot < 3 {
                    let mut k = 2;
                    while k > slot {
                        worst[k] = worst[k - 1];
                        k -= 1;
                    }
                    worst[slot] = Some(cand);
                }
            }
        }
        WorstRows(worst)
    }
}

impl fmt::Display for WorstRows {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut first = true;
        for r in self.0.iter().flatten() {
            if !first {
                f.write_str("; ")?;
            }
            first = false;
            write!(f, "{} = {:.3e}", r.row, r.value)?;
        }
        if first {
            f.write_str("none")?;
        }
        Ok(())
    }
}

pub(crate) fn check_dims<const NB: usize, const NV: usize>() -> Result<(), AnalysisError> {
    if NV == 6 * NB { Ok(()) } else { Err(AnalysisError::Dimensions { nb: NB, nv: NV }) }
}

/// Checks the positions (and, if `velocities`, the velocities) and the time.
pub(crate) fn check_state<S, const NB: usize, const NV: usize, const M: usize>(
    state: &SystemState<NB>,
    velocities: bool,
) -> Result<(), AnalysisError>
where
    S: Scene<NB, NV, M>,
{
    check_dims::<NB, NV>()?;
    for (i, b) in state.bodies.iter().enumerate() {
        let body = Some(S::BODIES.get(i).copied().unwrap_or(""));
        if !b.r.iter().all(|x| x.is_finite()) {
            return Err(AnalysisError::NonFinite { body, field: "r" });
        }
        if !b.p.iter().all(|x| x.is_finite()) {
            return Err(AnalysisError::NonFinite { body, field: "p" });
        }
        if velocities && !b.rdot.iter().all(|x| x.is_finite()) {
            return Err(AnalysisError::NonFinite { body, field: "rdot" });
        }
        if velocities && !b.omega.iter().all(|x| x.is_finite()) {
            return Err(AnalysisError::NonFinite { body, field: "omega" });
        }
    }
    if !state.t.is_finite() {
        return Err(AnalysisError::NonFinite { body: None, field: "t" });
    }
    Ok(())
}

/// The Jacobian's nonzero `values` all finite, or the first row (with its
/// joint) holding one that is not.
pub(crate) fn check_values<S, const NB: usize, const NV: usize, const M: usize, const NNZ: usize>(
    values: &[f64; NNZ],
) -> Result<(), AnalysisError>
where
    S: Scene<NB, NV, M> + SparseJacobian<NB, NNZ>,
{
    let Some(bad) = values.iter().position(|v| !v.is_finite()) else {
        return Ok(());
    };
    // The row whose entries hold `bad`: the last start at or before it.
    let row = S::ROW_STARTS.iter().take(M).rposition(|&start| start <= bad);
    Err(AnalysisError::NonFiniteOutput { quantity: "J", row: row.map(RowInfo::of::<S, NB, NV, M>) })
}

pub(crate) fn check_output<S, const NB: usize, const NV: usize, const M: usize, const C: usize>(
    quantity: &'static str,
    x: &SMatrix<f64, M, C>,
) -> Result<(), AnalysisError>
where
    S: Scene<NB, NV, M>,
{
    for i in 0..M {
        for j in 0..C {
            if !x[(i, j)].is_finite() {
                return Err(AnalysisError::NonFiniteOutput { quantity, row: Some(RowInfo::of::<S, NB, NV, M>(i)) });
            }
        }
    }
    Ok(())
}
