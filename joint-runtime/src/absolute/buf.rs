//! Arrays of a scene's size, sized at compile time: boxed with `alloc` (off
//! the stack, cheap to move), inline without (a `static` or the caller's
//! frame holds them).
//!
//! With `alloc` none of them passes through the stack on its way to the
//! heap, so that making a simulation needs no more stack than stepping it:
//! an array is allocated filled ([`filled`]), and a workspace is written
//! where it lives ([`boxed_with`]). `Box::new(Workspace { .. })` would not
//! do: its argument is built in the caller's frame, then copied (a 500-body
//! chain's simulation needed most of a megabyte of stack that way). Safe
//! Rust cannot write into an allocation field by field; the optimiser does
//! it for a value that a call returns into the allocation, as long as the
//! value is a constant or a few moves: a literal of many parts, each made by
//! a call, is assembled in the frame and copied all the same. So a
//! workspace is made as a constant of zeros (`const { .. }`: one `memset`
//! into the heap), with [`zeros`] and [`zero_state`] for its vectors and
//! states, and what is not zero is written over it in place afterwards
//! (states at rest, [`at_rest`]; identity matrices). Unoptimised builds
//! copy through the stack all the same.

use nalgebra::{ArrayStorage, SMatrix};

use crate::OmegaBody;
use crate::scene::SystemState;

/// An array of `N` entries: boxed with `alloc`, inline without.
#[cfg(feature = "alloc")]
pub(crate) type Buf<T, const N: usize> = alloc::boxed::Box<[T; N]>;
#[cfg(not(feature = "alloc"))]
pub(crate) type Buf<T, const N: usize> = [T; N];

/// `N` copies of `v`, built where they will live (on the heap with `alloc`:
/// no array of the scene's size passes through the stack).
pub(crate) fn filled<T: Copy, const N: usize>(v: T) -> Buf<T, N> {
    #[cfg(feature = "alloc")]
    {
        match alloc::vec![v; N].into_boxed_slice().try_into() {
            Ok(b) => b,
            // Unreachable: the slice has N entries. Not `Box::new([v; N])`,
            // whose argument would take the array's size in this frame
            // whether or not this arm runs; this is where the allocation's
            // own failure goes.
            Err(_) => alloc::alloc::handle_alloc_error(core::alloc::Layout::new::<[T; N]>()),
        }
    }
    #[cfg(not(feature = "alloc"))]
    {
        [v; N]
    }
}

/// A workspace: boxed with `alloc` (off the stack, and cheap to move),
/// inline without; either way a pointer-like value (`Deref`), so the code
/// that uses it is the same.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Boxed<T>(#[cfg(feature = "alloc")] alloc::boxed::Box<T>, #[cfg(not(feature = "alloc"))] T);

impl<T> core::ops::Deref for Boxed<T> {
    type Target = T;
    fn deref(&self) -> &T {
        &self.0
    }
}

impl<T> core::ops::DerefMut for Boxed<T> {
    fn deref_mut(&mut self) -> &mut T {
        &mut self.0
    }
}

/// `x` where a workspace lives: for a small `x` (it is built in the
/// caller's frame first; a large one is made by [`boxed_with`]).
pub(crate) fn boxed<T>(x: T) -> Boxed<T> {
    #[cfg(feature = "alloc")]
    {
        Boxed(alloc::boxed::Box::new(x))
    }
    #[cfg(not(feature = "alloc"))]
    {
        Boxed(x)
    }
}

/// What `make` returns, written where a workspace lives: with `alloc` the
/// allocation is made first and `make` runs out of line with it as its
/// return slot ([`made`]). `make` returns a constant (`const { .. }`) or a
/// literal of constants and moves, and calls no user code (which could
/// panic: in `made` a panic aborts).
pub(crate) fn boxed_with<T>(make: impl FnOnce() -> T) -> Boxed<T> {
    #[cfg(feature = "alloc")]
    {
        Boxed(alloc::boxed::Box::write(alloc::boxed::Box::new_uninit(), made(make)))
    }
    #[cfg(not(feature = "alloc"))]
    {
        Boxed(make())
    }
}

/// `make()` in a frame of its own, whose return slot is the caller's
/// destination (the allocation of [`boxed_with`]). `extern "C"` so that it
/// cannot unwind: the optimiser writes a call's result straight into a heap
/// destination only if the call cannot unwind (a caller that caught the
/// unwinding could see the early writes).
#[cfg(feature = "alloc")]
#[inline(never)]
extern "C" fn made<T, F: FnOnce() -> T>(make: F) -> T {
    make()
}

/// A matrix (or vector) of zeros, usable in constants; `SMatrix::zeros`
/// is not `const`, and at run time fills a temporary in a loop.
pub(crate) const fn zeros<const R: usize, const C: usize>() -> SMatrix<f64, R, C> {
    SMatrix::from_array_storage(ArrayStorage([[0.0; R]; C]))
}

/// `NB` bodies at the origin with zero Euler parameters and zero
/// velocities, at time 0: every byte zero, for a workspace's constant;
/// [`at_rest`] makes it a state at rest in place.
pub(crate) const fn zero_state<const NB: usize>() -> SystemState<NB> {
    const ZERO: OmegaBody<f64> = OmegaBody { r: zeros(), p: zeros(), rdot: zeros(), omega: zeros() };
    SystemState { bodies: [ZERO; NB], t: 0.0 }
}

/// Bodies at rest at the origin ([`OmegaBody::default`]) at time 0, written
/// over `state` in place: a workspace's scratch states start as the
/// workspace's constructors always made them.
pub(crate) fn at_rest<const NB: usize>(state: &mut SystemState<NB>) {
    state.bodies.fill(OmegaBody::default());
    state.t = 0.0;
}
