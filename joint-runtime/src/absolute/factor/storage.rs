//! Where a block factor lives: arrays whose sizes the derive computed from the
//! scene's pattern, so that the factor needs no allocator (with `alloc`, each
//! array is boxed, which keeps a large scene's factor off the stack).

use super::{Block, JointRows};
use crate::absolute::buf::{Buf, filled};

/// The storage of a [`BlockFactor`](super::BlockFactor): implemented by
/// [`FactorArrays`], whose sizes the derive writes into each scene's
/// [`SparseJacobian::Factor`](crate::SparseJacobian::Factor).
pub trait FactorStorage: Clone + core::fmt::Debug + Send + Sync + sealed::Sealed {
    /// Storage with every entry zero.
    #[doc(hidden)]
    fn zeroed() -> Self;
    /// Every array, as slices.
    #[doc(hidden)]
    fn parts(&mut self) -> Parts<'_>;
    /// The arrays read after a factorisation.
    #[doc(hidden)]
    fn view(&self) -> View<'_>;
}

mod sealed {
    pub trait Sealed {}
}

/// The arrays of a block factor of `N` joint blocks, `S` factor slots
/// (diagonal and below, fill included), `T` scheduled block updates, `U`
/// shared-body terms of `J W Jᵀ`, `NNZ` Jacobian entries and `M` rows. The
/// derive computes these from the scene's pattern; [`BlockFactor::new`]
/// refuses storage whose sizes do not match it.
///
/// [`BlockFactor::new`]: super::BlockFactor::new
#[derive(Clone, Debug)]
pub struct FactorArrays<
    const N: usize,
    const S: usize,
    const T: usize,
    const U: usize,
    const NNZ: usize,
    const M: usize,
> {
    joints: Buf<JointRows, N>,
    col_range: Buf<(usize, usize), N>,
    col: Buf<usize, S>,
    sched_range: Buf<(usize, usize), S>,
    sched: Buf<(usize, usize, usize), T>,
    shared_range: Buf<(usize, usize), S>,
    shared: Buf<(usize, usize, usize), U>,
    row_range: Buf<(usize, usize), N>,
    /// `S − N` entries are used (the slots below the diagonal).
    row: Buf<(usize, usize), S>,
    scatter: Buf<(usize, usize), NNZ>,
    jb: Buf<[Block; 2], N>,
    jw: Buf<[Block; 2], N>,
    pub(super) l: Buf<Block, S>,
    pub(super) perm: Buf<[usize; 6], N>,
    pub(super) rank: Buf<usize, N>,
    /// The pivots and ranks a later factorisation keeps (`BlockFactor::keep_rule`).
    pub(super) kept: Buf<([usize; 6], usize), N>,
    pub(super) dropped: Buf<usize, M>,
    pub(super) z: Buf<[f64; 6], N>,
    pub(super) lambda: Buf<[f64; 6], N>,
}

/// A factor's arrays, borrowed at once (pattern and numbers).
#[derive(Debug)]
pub struct Parts<'a> {
    pub(super) joints: &'a mut [JointRows],
    pub(super) col_range: &'a mut [(usize, usize)],
    pub(super) col: &'a mut [usize],
    pub(super) sched_range: &'a mut [(usize, usize)],
    pub(super) sched: &'a mut [(usize, usize, usize)],
    pub(super) shared_range: &'a mut [(usize, usize)],
    pub(super) shared: &'a mut [(usize, usize, usize)],
    pub(super) row_range: &'a mut [(usize, usize)],
    pub(super) row: &'a mut [(usize, usize)],
    pub(super) scatter: &'a mut [(usize, usize)],
    /// `J` and `J W` per joint and side: entry `2 k + side`.
    pub(super) jb: &'a mut [Block],
    pub(super) jw: &'a mut [Block],
    pub(super) l: &'a mut [Block],
    pub(super) perm: &'a mut [[usize; 6]],
    pub(super) rank: &'a mut [usize],
    pub(super) kept: &'a mut [([usize; 6], usize)],
    pub(super) dropped: &'a mut [usize],
    pub(super) z: &'a mut [[f64; 6]],
    pub(super) lambda: &'a mut [[f64; 6]],
}

/// What a factorisation leaves to read: the ranks and the redundant rows.
#[derive(Clone, Copy, Debug)]
pub struct View<'a> {
    pub(super) slots: usize,
    pub(super) nonzeros: usize,
    pub(super) rank: &'a [usize],
    pub(super) dropped: &'a [usize],
}

impl<const N: usize, const S: usize, const T: usize, const U: usize, const NNZ: usize, const M: usize>
    FactorArrays<N, S, T, U, NNZ, M>
{
    /// The factor's blocks, by slot: where the derive's
    /// [`normal_blocks_into`](crate::SparseJacobian::normal_blocks_into)
    /// writes `J W Jᵀ` (by constant index, so without a bounds check).
    #[doc(hidden)]
    #[inline(always)]
    pub fn blocks_mut(&mut self) -> &mut [[f64; 36]; S] {
        &mut self.l
    }
}

impl<const N: usize, const S: usize, const T: usize, const U: usize, const NNZ: usize, const M: usize> sealed::Sealed
    for FactorArrays<N, S, T, U, NNZ, M>
{
}

impl<const N: usize, const S: usize, const T: usize, const U: usize, const NNZ: usize, const M: usize> FactorStorage
    for FactorArrays<N, S, T, U, NNZ, M>
{
    fn zeroed() -> Self {
        const ZERO: Block = [0.0; 36];
        FactorArrays {
            joints: filled(JointRows { start: 0, rows: 0, bodies: [None; 2] }),
            col_range: filled((0, 0)),
            col: filled(0),
            sched_range: filled((0, 0)),
            sched: filled((0, 0, 0)),
            shared_range: filled((0, 0)),
            shared: filled((0, 0, 0)),
            row_range: filled((0, 0)),
            row: filled((0, 0)),
            scatter: filled((0, 0)),
            jb: filled([ZERO; 2]),
            jw: filled([ZERO; 2]),
            l: filled(ZERO),
            perm: filled([0; 6]),
            rank: filled(0),
            kept: filled(([0; 6], 0)),
            dropped: filled(0),
            z: filled([0.0; 6]),
            lambda: filled([0.0; 6]),
        }
    }

    fn parts(&mut self) -> Parts<'_> {
        Parts {
            joints: &mut self.joints[..],
            col_range: &mut self.col_range[..],
            col: &mut self.col[..],
            sched_range: &mut self.sched_range[..],
            sched: &mut self.sched[..],
            shared_range: &mut self.shared_range[..],
            shared: &mut self.shared[..],
            row_range: &mut self.row_range[..],
            row: &mut self.row[..],
            scatter: &mut self.scatter[..],
            jb: self.jb.as_flattened_mut(),
            jw: self.jw.as_flattened_mut(),
            l: &mut self.l[..],
            perm: &mut self.perm[..],
            rank: &mut self.rank[..],
            kept: &mut self.kept[..],
            dropped: &mut self.dropped[..],
            z: &mut self.z[..],
            lambda: &mut self.lambda[..],
        }
    }

    fn view(&self) -> View<'_> {
        View { slots: S, nonzeros: NNZ, rank: &self.rank[..], dropped: &self.dropped[..] }
    }
}
