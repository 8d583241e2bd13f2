//! The engine of `coordinates = absolute` (the default for a scene without a
//! file): six coordinates per body, every joint's rows as constraints, the
//! dynamics of a [`Scene`](crate::Scene) through its compile-time structure,
//! in time and memory proportional to the scene, in storage sized by the
//! derive (no allocator needed; with `alloc` boxed, and the linearisation's
//! dense outputs).
//!
//! The derive fixes, for every scene, which bodies each joint connects, a
//! fill-reducing elimination order of the joint blocks of `J M⁻¹ Jᵀ` (minimum
//! degree: leaves first on a tree, the fill of each closed loop kept local),
//! the pattern of its block factor and the sizes of the factor's arrays
//! ([`SparseJacobian`](crate::SparseJacobian), [`FactorArrays`]).
//! [`BlockFactor`] turns that pattern, once, into a compact static schedule
//! (which factor blocks update which) in those arrays; every factorisation then
//! runs the schedule on blocks of at most 6 × 6, with no search and no
//! allocation. For scenes up to 1 500 block operations the derive also writes
//! the schedule unrolled (`SparseJacobian::factor_program`): one call per
//! block operation with its sizes and slots constant, the same kernels in the
//! same order, so the same bits without the look-ups and the dispatch. Above
//! that the interpreter runs: unrolled code grows with the factor's operation
//! count and rustc's time faster, while the schedule is a few integers per
//! block pair and the kernels stay in cache.
//!
//! Redundant rows are found as in the dense path: each diagonal block is
//! factorised with diagonal pivoting, and a pivot below `rank_tolerance ×` the
//! largest diagonal of `J M⁻¹ Jᵀ` marks its row redundant (dropped, λ = 0). The
//! elimination order is the derive's, not the order the rows were written in.
//!
//! The factor's algorithms run on slices, compiled once rather than per scene.
//! The blocks of `J M⁻¹ Jᵀ` come from the scene's generated
//! `normal_blocks_into` where the derive wrote it (the factor then keeps no
//! `J`), otherwise from dense six-column blocks of `J`; `J x` and `Jᵀ y` are the
//! scene's generated products, or a walk over the CSR pattern (`solver.rs`).
//! Building the schedule refuses sizes that do not match the pattern, and
//! every look-up, there and at every step, goes through `get`, every pivot
//! clamped into its block: no path can panic, and `no-panic-check` proves it
//! for the whole step (a panic path anywhere in the call tree, even one the
//! optimiser would remove late, fails the link).
//!
//! [`AbsoluteSimulation`], the one simulation's engine for absolute
//! coordinates, runs on this factor (RK4 with the mass-metric projection), and so do the kinematic
//! analyses ([`Analyses`](crate::analysis::Analyses)), reading only Φ, Φ_t,
//! γ and the Jacobian's nonzero entries: no `M × NV` matrix is ever formed.
//! With [`Integrator::GeneralisedAlpha`](crate::dynamics::Integrator) the
//! simulation runs index-3 generalised-α with the exact iteration matrix, a
//! saddle-point matrix over bodies and joints factorised on a pattern fixed
//! once (`kkt/`: minimum degree, each joint after its bodies), from the
//! scene's sparse second-order terms ([`SecondOrderLayout`]), generated or,
//! for a scene derived without them, by central differences of its `J`, `γ`
//! and `Φ_t` ([`DifferenceTerms`]: bodies coloured so that a chain of any
//! length costs 24 evaluations per colour, two colours).
//! [`AbsoluteSimulation::integrate`] runs the dense path's error-controlled
//! driver (Dormand–Prince 5(4), generalised-α with its estimate) on these.
//! The implicit midpoint rule runs there too, its Newton matrix in the same
//! saddle-point form (`midpoint.rs`; the dense `I − (h/2) ∂a/∂w` is full).
//! Radau IIA runs there as well (`radau.rs`): its real and complex stage
//! systems on the same pattern, the real and complex block LU of `kkt/`.
//! [`AbsoluteSimulation::linearise`] and [`AbsoluteSimulation::transition`] give
//! the dense path's linearisation and state-transition Jacobian (`linear.rs`):
//! dense outputs, built column by column on the block factor.
//!
//! A step builds nothing. The workspaces of the options' integrator are made
//! in `new` and another integrator's by `prepare` (a step without its
//! workspace is `AnalysisError::NotPrepared`); every vector of the scene's
//! size (a solve's, the projection's Newton vectors, RK4's stages, the
//! implicit integrators' iterates) lives in a workspace (boxed with `alloc`)
//! that the solver's code writes into (`*_into`, `*_in_place`) rather than
//! returning vectors: no state or vector of the scene's size in a step's stack
//! frames. A workspace a step takes out while it borrows `self` is held in
//! `ManuallyDrop` (`with_taken`): no drop glue, so no cleanup path for
//! `no-panic-check` to find. An RK4 step takes about four factorisations,
//! one a stage (4.06 a step on a 10-bar chain, 4.2 on 160 bars, where
//! renormalising a start's quaternions moves it a little): its projection
//! starts with simplified Newton on the last stage's factor, and the next step
//! starts on the projection's own.

mod adaptive;
mod alpha;
pub(crate) mod buf;
mod differences;
mod factor;
mod kkt;
#[cfg(feature = "alloc")]
mod linear;
mod loads;
mod midpoint;
mod radau;
mod second_order;
mod simulation;
pub(crate) mod solver;

pub use differences::DifferenceTerms;
pub use factor::{BlockFactor, FactorArrays, FactorStorage};
pub use kkt::{KktArrays, KktEntry, KktStorage};
pub use second_order::{JointBodies, RowTerm, SecondOrderLayout, TermArray, TermStorage};
// The one simulation's public path is `dynamics::Simulation`.
#[doc(hidden)]
pub use simulation::AbsoluteSimulation;

/// The absolute engine's name before 0.2 (`sparse::SparseSimulation`).
/// Most code wants [`Simulation`](crate::dynamics::Simulation), which makes
/// this engine for a scene in absolute coordinates.
#[deprecated(since = "0.2.0", note = "renamed `absolute::AbsoluteSimulation`; most code wants `dynamics::Simulation`")]
pub type SparseSimulation<'a, S, L, const NB: usize, const NV: usize, const M: usize, const NNZ: usize> =
    AbsoluteSimulation<'a, S, L, NB, NV, M, NNZ>;
