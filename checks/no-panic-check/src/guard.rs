//! The guard: a value whose `Drop` calls a symbol that no library defines.
//!
//! [`guarded`] arms a guard, runs the checked call and forgets the guard. On the
//! normal return path the guard is forgotten, so nothing refers to the symbol;
//! the only path that drops it is unwinding out of the call. In a release build
//! the optimiser deletes that landing pad when it can prove that no callee
//! unwinds; if a panic path survives, the drop and with it the reference to the
//! undefined symbol survive, and the final link fails with the symbol's name,
//! which reads as the error message. Without the feature `prove`, or in builds
//! with debug assertions (the dev profile: unoptimised code keeps every landing
//! pad), the guard does nothing.

/// A guard type made by `guard_type!`: its `Drop` refers to an undefined symbol
/// that names the checked function.
pub trait Guard {
    /// The armed guard.
    fn arm() -> Self;
}

/// Runs `f` under the guard `G` (see the module documentation).
// The joints' wrappers call it; the no-alloc check includes this file and
// does not.
#[allow(dead_code)]
#[inline(always)]
pub fn guarded<G: Guard, R>(f: impl FnOnce() -> R) -> R {
    let guard = G::arm();
    let out = f();
    core::mem::forget(guard);
    out
}

/// `guard_type!(Name, "what")` declares the guard type `Name` whose drop refers
/// to the undefined symbol `ERROR[no-panic-check]: a panic path survives in what`
/// with the feature `prove` in builds without debug assertions (otherwise the
/// drop does nothing).
macro_rules! guard_type {
    ($name:ident, $what:expr) => {
        struct $name;

        impl $crate::guard::Guard for $name {
            #[inline(always)]
            fn arm() -> Self {
                $name
            }
        }

        impl Drop for $name {
            #[inline(always)]
            fn drop(&mut self) {
                #[cfg(all(feature = "prove", not(debug_assertions)))]
                {
                    // Declared, never defined: referring to it fails the link.
                    #[allow(unsafe_code)]
                    unsafe extern "C" {
                        #[link_name = concat!(
                                                            "\n\nERROR[no-panic-check]: a panic path survives in ",
                                                            $what,
                                                            " (release build; see checks/no-panic-check/src/main.rs)\n\n"
                                                        )]
                        safe fn panic_path_survives() -> !;
                    }
                    panic_path_survives();
                }
            }
        }
    };
}

/// Checked wrappers of concrete functions: each `fn` is emitted `#[inline(never)]`
/// with its body under a guard named after it, and `keep()` takes every
/// wrapper's address (so each one is compiled and linked) and returns how many
/// there are.
macro_rules! checked {
    ($(fn $name:ident $(<$lt:lifetime>)? ($($arg:ident: $t:ty),* $(,)?) -> $ret:ty $body:block)*) => {
        $(
            #[inline(never)]
            fn $name $(<$lt>)? ($($arg: $t),*) -> $ret {
                guard_type!(G, concat!("`", module_path!(), "::", stringify!($name), "`"));
                // The body in the wrapper itself, not in a closure: a large
                // closure stays out of line, and LTO infers `nounwind` before
                // inlining, so a closure whose panic paths vanish only once
                // its callees are inlined would keep a landing pad (a robot's
                // RK4 step did). What is checked is the same: every call left
                // in the body must be known not to unwind.
                let guard = <G as $crate::guard::Guard>::arm();
                let out: $ret = $body;
                core::mem::forget(guard);
                out
            }
        )*

        /// Takes the address of every wrapper above; returns their number.
        pub fn keep() -> usize {
            let mut n = 0;
            $(
                core::hint::black_box($name as for<$($lt)?> fn($($t),*) -> $ret);
                n += 1;
            )*
            n
        }
    };
}
