//! Arrays of a scene's size, sized at compile time: boxed with `alloc` (off
//! the stack, cheap to move), inline without (a `static` or the caller's
//! frame holds them).

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
            // Unreachable: the slice has N entries.
            Err(_) => alloc::boxed::Box::new([v; N]),
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

/// `x` where a workspace lives.
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
