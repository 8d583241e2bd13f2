//! A link-time proof that the generated code and a fixed-size scene step have
//! no panicking path in release builds.
//!
//! ```text
//! cargo build --release -p no-panic-check --features prove \
//!     --config 'profile.release.lto="fat"' \
//!     --config 'profile.release.package.no-panic-check.codegen-units=1'
//! ```
//!
//! The build succeeds (and `target/release/no-panic-check` prints how many
//! functions it holds) exactly when no checked function can panic.
//!
//! # What is checked
//!
//! - Every derived joint of `joint_tests::joints` (every catalogue kind in every
//!   formulation, parameters as run-time fields): `phi`, `phi_t`, `jacobian`,
//!   `gamma` and `evaluate` at `f64`, and at `f32` for each non-driver kind in one
//!   formulation ([`joints`]).
//! - The double Cardan shaft of `joint_examples::double_cardan`, driven
//!   (`Scene<3, 18, 19>`, a redundant row) and free (`Scene<3, 18, 18>`): the
//!   system Φ, Φ_t, J, γ, `evaluate` and the sparse J values; `Analyses`' `assemble`,
//!   `velocities`, `accelerations`; the free shaft's `second_order`; and both
//!   on the one `Simulation` (the block factor of `J M⁻¹ Jᵀ` and the
//!   saddle-point matrices): `step` with every integrator, stabilisation and
//!   projection option, `dynamics`, `project`, `reactions` and `energy`, and
//!   the free shaft's `integrate` with every method ([`scenes`]). The integrator,
//!   stabilisation, projection and springs are run-time options, so every one of
//!   them is inside the checked `step`.
//! - A three-hinge arm in relative coordinates: the exact derivatives of its
//!   inverse and forward dynamics and its RK4 and semi-implicit Euler step
//!   Jacobians ([`trees`]).
//! - Two robots read from their files with contacts (the floating Solo12 on
//!   its four feet, the UR5 welded): a constrained RK4 step and its exact
//!   Jacobian (projection included), the constrained dynamics, their exact
//!   derivatives and an impact's, the active set a run-time argument; a hard
//!   four-bar from its MJCF file: the projected RK4 step's exact Jacobian
//!   (Newton on a loop's position); the Panda from its MJCF file with its fingers
//!   coupled softly (MuJoCo's `<equality joint>`): its step, dynamics and
//!   their exact derivatives ([`contacts`]).
//! - The batch functions (`evaluate_batch`, `evaluate_batch_simd` in `f64 × 4`
//!   and `f32 × 8`, and over packed states) for a universal joint ([`batch`]).
//!
//! # How
//!
//! Each checked function is a non-inlined wrapper whose body runs under a guard
//! ([`guard`]): a value whose `Drop` calls an `extern` function that nothing
//! defines, and which the wrapper forgets (`mem::forget`) after the call
//! returns. The only way to drop the guard is to unwind out of the call, i.e. a
//! panic. `main` takes every wrapper's address through `black_box`, so each is
//! compiled on its own with unknown arguments (no constant folding from a call
//! site) and linked into this binary.
//!
//! # Why a link failure means a panic path
//!
//! LLVM removes an unwinding landing pad only when it proves that nothing the
//! function calls can unwind: every bounds check, `unwrap`, `expect`,
//! `unreachable!` or arithmetic check in the call tree (generated code, the
//! `joint-runtime` solvers, nalgebra, libm) must have been proven dead and
//! deleted. If one panic path survives, so does the landing pad that drops the
//! guard, and with it the call to the undefined symbol: the link fails with
//! `undefined symbol: ERROR[no-panic-check]: a panic path survives in
//! <function>`, naming the wrapper. Bisect from there, or look for calls to
//! `core::panicking` in `cargo rustc --release -p no-panic-check --features prove
//! --config 'profile.release.lto="fat"' -- --emit=llvm-ir` (one codegen unit).
//!
//! The proof is the optimiser's, so it needs to see all the code: **fat LTO**
//! (the runtime's non-generic helpers and libm's `sin`/`cos` are compiled in
//! other crates; without LTO a call to them keeps its landing pad whether or not
//! it can panic) and **one codegen unit** for this crate (split across units,
//! a wrapper and its callee are optimised apart and the callee's `nounwind` is
//! not always inferred). Hence the `--config` flags, and the feature `prove`
//! that arms the guards: a plain `cargo build --release --workspace` builds this
//! binary with inert guards instead of failing. The check is conservative (a
//! call the optimiser cannot see through fails it) and sound: a landing pad is
//! removed only on proof, so what links has no reachable panic for any input.
//! It says nothing about builds with debug assertions or overflow checks, which
//! add panics of their own; the guard is inert there. This is the technique of
//! dtolnay's `no-panic` crate, written out so that one generic wrapper can name
//! each monomorphised joint in its error (`SphericalEuler<f64>::phi`).

#[macro_use]
mod guard;
mod batch;
mod contacts;
mod joints;
mod robots;
mod scenes;
mod trees;

/// A function that can panic (the index may be out of range): with the feature
/// `canary` the check must fail, naming it.
#[cfg(feature = "canary")]
mod canary {
    checked! {
        fn index(values: &[f64], i: usize) -> f64 { values[i] }
    }
}

fn main() {
    let joints = joints::keep();
    let scenes = scenes::driven::keep() + scenes::free::keep() + scenes::block::keep() + trees::keep();
    let robots = robots::keep() + contacts::keep();
    let batches = batch::keep();
    #[cfg(feature = "canary")]
    let scenes = scenes + canary::keep();
    if cfg!(all(feature = "prove", not(debug_assertions))) {
        println!(
            "{joints} joint, {scenes} scene, {robots} robot (relative coordinates) and {batches} batch functions \
             linked without a panic path"
        );
    } else {
        println!(
            "{joints} joint, {scenes} scene, {robots} robot and {batches} batch wrappers built with inert guards: \
             the check needs a release build with the feature `prove` (see src/main.rs)"
        );
    }
}
