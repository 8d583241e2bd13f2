//! Where a saddle-point matrix lives: arrays whose sizes the derive computed
//! from the scene's pattern ([`KktArrays`], the scene's
//! [`SparseJacobian::Kkt`](crate::SparseJacobian::Kkt)), so that the implicit
//! integrators need no allocator; or, with `alloc`, vectors sized at run time
//! for a pattern the derive could not know (springs between bodies no joint
//! joins).

use core::fmt::Debug;

use nalgebra::ComplexField;

use super::{Block, Place};
use crate::absolute::buf::{Buf, filled};

/// The entries a saddle-point matrix may hold: `f64`, or `Complex<f64>`
/// (Radau IIA's complex stage system).
pub trait KktEntry: ComplexField<RealField = f64> + Copy {}
impl<T: ComplexField<RealField = f64> + Copy> KktEntry for T {}

/// The storage of a saddle-point matrix's block LU: implemented by
/// [`KktArrays`], whose sizes the derive writes into each scene's
/// [`SparseJacobian::Kkt`](crate::SparseJacobian::Kkt).
pub trait KktStorage<T: KktEntry>: Clone + Debug + Send + Sync + sealed::Sealed {
    /// Storage with every entry zero (and an empty pattern).
    #[doc(hidden)]
    fn zeroed() -> Self;
    /// The pattern, to read, and the numbers, to write.
    #[doc(hidden)]
    fn split(&mut self) -> (Pattern<'_>, Values<'_, T>);
    /// The pattern, to write (once, when the matrix is made).
    #[doc(hidden)]
    fn pattern_mut(&mut self) -> PatternMut<'_>;
    /// The pattern and the blocks, to read.
    #[doc(hidden)]
    fn view(&self) -> (Pattern<'_>, BlocksRef<'_, T>);
}

mod sealed {
    pub trait Sealed {}
}

/// The arrays of a saddle-point matrix of `N` nodes (bodies and joints), `A`
/// block pairs below the diagonal (fill included) and `U` scheduled Schur
/// updates, with entries of type `T`. The derive computes the sizes from the
/// scene's pattern; a pattern of other sizes is refused.
#[derive(Clone, Debug)]
pub struct KktArrays<T: KktEntry, const N: usize, const A: usize, const U: usize> {
    sizes: Buf<usize, N>,
    starts: Buf<usize, N>,
    order: Buf<usize, N>,
    position: Buf<usize, N>,
    adj_range: Buf<(usize, usize), N>,
    adj: Buf<usize, A>,
    updates_range: Buf<(usize, usize), N>,
    updates: Buf<(usize, usize, Place), U>,
    diag: Buf<Block<T>, N>,
    low: Buf<Block<T>, A>,
    up: Buf<Block<T>, A>,
    x: Buf<[T; 6], N>,
}

/// A saddle-point matrix's pattern, borrowed: by node, each node's size and
/// where its entries start in a vector by node; the elimination order and
/// each node's position in it; by position, the later positions adjacent to
/// it (`adj[adj_range[k].0..adj_range[k].1]`, ascending) and its Schur
/// updates `(slot (i, k), slot (k, j), target (i, j))`.
#[doc(hidden)]
#[derive(Clone, Copy, Debug)]
pub struct Pattern<'a> {
    pub(super) sizes: &'a [usize],
    pub(super) starts: &'a [usize],
    pub(super) order: &'a [usize],
    pub(super) position: &'a [usize],
    pub(super) adj_range: &'a [(usize, usize)],
    pub(super) adj: &'a [usize],
    pub(super) updates_range: &'a [(usize, usize)],
    pub(super) updates: &'a [(usize, usize, Place)],
}

/// The pattern's arrays, to fill.
#[doc(hidden)]
#[derive(Debug)]
pub struct PatternMut<'a> {
    pub(super) sizes: &'a mut [usize],
    pub(super) starts: &'a mut [usize],
    pub(super) order: &'a mut [usize],
    pub(super) position: &'a mut [usize],
    pub(super) adj_range: &'a mut [(usize, usize)],
    pub(super) adj: &'a mut [usize],
    pub(super) updates_range: &'a mut [(usize, usize)],
    pub(super) updates: &'a mut [(usize, usize, Place)],
}

/// The blocks (by position: diagonal; below and above by slot) and the
/// solve's scratch, to write.
#[doc(hidden)]
#[derive(Debug)]
pub struct Values<'a, T> {
    pub(super) diag: &'a mut [Block<T>],
    pub(super) low: &'a mut [Block<T>],
    pub(super) up: &'a mut [Block<T>],
    pub(super) x: &'a mut [[T; 6]],
}

/// The blocks, to read.
#[doc(hidden)]
#[derive(Clone, Copy, Debug)]
pub struct BlocksRef<'a, T> {
    pub(super) diag: &'a [Block<T>],
    pub(super) low: &'a [Block<T>],
    pub(super) up: &'a [Block<T>],
}

/// The pattern of any of the storages below, borrowed (`&x[..]` reads an
/// array, a boxed array or a vector alike).
macro_rules! pattern {
    ($s:expr) => {
        Pattern {
            sizes: &$s.sizes[..],
            starts: &$s.starts[..],
            order: &$s.order[..],
            position: &$s.position[..],
            adj_range: &$s.adj_range[..],
            adj: &$s.adj[..],
            updates_range: &$s.updates_range[..],
            updates: &$s.updates[..],
        }
    };
}

/// The pattern, mutably borrowed.
macro_rules! pattern_mut {
    ($s:expr) => {
        PatternMut {
            sizes: &mut $s.sizes[..],
            starts: &mut $s.starts[..],
            order: &mut $s.order[..],
            position: &mut $s.position[..],
            adj_range: &mut $s.adj_range[..],
            adj: &mut $s.adj[..],
            updates_range: &mut $s.updates_range[..],
            updates: &mut $s.updates[..],
        }
    };
}

/// The pattern to read and the numbers to write, borrowed at once.
macro_rules! split {
    ($s:expr) => {
        (pattern!($s), Values { diag: &mut $s.diag[..], low: &mut $s.low[..], up: &mut $s.up[..], x: &mut $s.x[..] })
    };
}

/// The pattern and the blocks, to read.
macro_rules! view {
    ($s:expr) => {
        (pattern!($s), BlocksRef { diag: &$s.diag[..], low: &$s.low[..], up: &$s.up[..] })
    };
}

impl<T: KktEntry, const N: usize, const A: usize, const U: usize> sealed::Sealed for KktArrays<T, N, A, U> {}

impl<T: KktEntry, const N: usize, const A: usize, const U: usize> KktStorage<T> for KktArrays<T, N, A, U> {
    fn zeroed() -> Self {
        let zero = [T::zero(); 36];
        KktArrays {
            sizes: filled(0),
            starts: filled(0),
            order: filled(0),
            position: filled(0),
            adj_range: filled((0, 0)),
            adj: filled(0),
            updates_range: filled((0, 0)),
            updates: filled((0, 0, Place::Diagonal(0))),
            diag: filled(zero),
            low: filled(zero),
            up: filled(zero),
            x: filled([T::zero(); 6]),
        }
    }

    fn split(&mut self) -> (Pattern<'_>, Values<'_, T>) {
        split!(self)
    }

    fn pattern_mut(&mut self) -> PatternMut<'_> {
        pattern_mut!(self)
    }

    fn view(&self) -> (Pattern<'_>, BlocksRef<'_, T>) {
        view!(self)
    }
}

/// The same arrays as vectors, sized at run time: a pattern the derive did
/// not fix (springs between bodies no joint joins).
#[cfg(feature = "alloc")]
#[derive(Clone, Debug, Default)]
pub(in crate::absolute) struct KktVecs<T> {
    sizes: alloc::vec::Vec<usize>,
    starts: alloc::vec::Vec<usize>,
    order: alloc::vec::Vec<usize>,
    position: alloc::vec::Vec<usize>,
    adj_range: alloc::vec::Vec<(usize, usize)>,
    adj: alloc::vec::Vec<usize>,
    updates_range: alloc::vec::Vec<(usize, usize)>,
    updates: alloc::vec::Vec<(usize, usize, Place)>,
    diag: alloc::vec::Vec<Block<T>>,
    low: alloc::vec::Vec<Block<T>>,
    up: alloc::vec::Vec<Block<T>>,
    x: alloc::vec::Vec<[T; 6]>,
}

#[cfg(feature = "alloc")]
impl<T: KktEntry> KktVecs<T> {
    /// Zeros for `n` nodes, `a` block pairs and `u` updates.
    pub(in crate::absolute) fn sized(n: usize, a: usize, u: usize) -> Self {
        use alloc::vec;
        let zero = [T::zero(); 36];
        KktVecs {
            sizes: vec![0; n],
            starts: vec![0; n],
            order: vec![0; n],
            position: vec![0; n],
            adj_range: vec![(0, 0); n],
            adj: vec![0; a],
            updates_range: vec![(0, 0); n],
            updates: vec![(0, 0, Place::Diagonal(0)); u],
            diag: vec![zero; n],
            low: vec![zero; a],
            up: vec![zero; a],
            x: vec![[T::zero(); 6]; n],
        }
    }

    /// Zeros on a pattern of this one's sizes, with entries `U`.
    pub(in crate::absolute) fn zeroed_like<U: KktEntry>(&self) -> KktVecs<U> {
        KktVecs::sized(self.order.len(), self.adj.len(), self.updates.len())
    }

    pub(in crate::absolute) fn split(&mut self) -> (Pattern<'_>, Values<'_, T>) {
        split!(self)
    }

    pub(in crate::absolute) fn pattern_mut(&mut self) -> PatternMut<'_> {
        pattern_mut!(self)
    }

    pub(in crate::absolute) fn view(&self) -> (Pattern<'_>, BlocksRef<'_, T>) {
        view!(self)
    }
}

/// Without `alloc` there are no vectors: a type with no values, so that the
/// code over both stores needs no `cfg`.
#[cfg(not(feature = "alloc"))]
#[derive(Clone, Debug)]
pub(in crate::absolute) struct KktVecs<T>(core::convert::Infallible, core::marker::PhantomData<T>);

#[cfg(not(feature = "alloc"))]
impl<T: KktEntry> KktVecs<T> {
    pub(in crate::absolute) fn zeroed_like<U: KktEntry>(&self) -> KktVecs<U> {
        match self.0 {}
    }

    pub(in crate::absolute) fn split(&mut self) -> (Pattern<'_>, Values<'_, T>) {
        match self.0 {}
    }

    pub(in crate::absolute) fn pattern_mut(&mut self) -> PatternMut<'_> {
        match self.0 {}
    }

    pub(in crate::absolute) fn view(&self) -> (Pattern<'_>, BlocksRef<'_, T>) {
        match self.0 {}
    }
}
