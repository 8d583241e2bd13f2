//! The absolute-coordinate engine's former name (renamed in 0.2: a scene
//! that declares `coordinates = absolute` finds it under
//! [`absolute`](crate::absolute)). Every type and constant here is a
//! deprecated alias, so that a path through `sparse` compiles with a
//! warning that names the new one; the traits are re-exported as they are
//! (rustc cannot deprecate a re-export).
#![allow(deprecated)]

pub use crate::absolute::{FactorStorage, KktEntry, KktStorage, TermStorage};

/// Renamed [`absolute::DifferenceTerms`](crate::absolute::DifferenceTerms).
#[deprecated(since = "0.2.0", note = "renamed `joint_runtime::absolute::DifferenceTerms` (CHANGELOG.md)")]
pub type DifferenceTerms<const NB: usize> = crate::absolute::DifferenceTerms<NB>;
/// Renamed [`absolute::BlockFactor`](crate::absolute::BlockFactor).
#[deprecated(since = "0.2.0", note = "renamed `joint_runtime::absolute::BlockFactor` (CHANGELOG.md)")]
pub type BlockFactor<F> = crate::absolute::BlockFactor<F>;
/// Renamed [`absolute::FactorArrays`](crate::absolute::FactorArrays).
#[deprecated(since = "0.2.0", note = "renamed `joint_runtime::absolute::FactorArrays` (CHANGELOG.md)")]
pub type FactorArrays<
    const N: usize,
    const S: usize,
    const T: usize,
    const U: usize,
    const NNZ: usize,
    const M: usize,
> = crate::absolute::FactorArrays<N, S, T, U, NNZ, M>;
/// Renamed [`absolute::KktArrays`](crate::absolute::KktArrays).
#[deprecated(since = "0.2.0", note = "renamed `joint_runtime::absolute::KktArrays` (CHANGELOG.md)")]
pub type KktArrays<T, const N: usize, const A: usize, const U: usize> = crate::absolute::KktArrays<T, N, A, U>;
/// Renamed [`absolute::JointBodies`](crate::absolute::JointBodies).
#[deprecated(since = "0.2.0", note = "renamed `joint_runtime::absolute::JointBodies` (CHANGELOG.md)")]
pub type JointBodies = crate::absolute::JointBodies;
/// Renamed [`absolute::RowTerm`](crate::absolute::RowTerm).
#[deprecated(since = "0.2.0", note = "renamed `joint_runtime::absolute::RowTerm` (CHANGELOG.md)")]
pub type RowTerm = crate::absolute::RowTerm;
/// Renamed [`absolute::SecondOrderLayout`](crate::absolute::SecondOrderLayout).
#[deprecated(since = "0.2.0", note = "renamed `joint_runtime::absolute::SecondOrderLayout` (CHANGELOG.md)")]
pub type SecondOrderLayout<'s> = crate::absolute::SecondOrderLayout<'s>;
/// Renamed [`absolute::TermArray`](crate::absolute::TermArray).
#[deprecated(since = "0.2.0", note = "renamed `joint_runtime::absolute::TermArray` (CHANGELOG.md)")]
pub type TermArray<const L: usize> = crate::absolute::TermArray<L>;
/// The absolute engine's name before 0.2; most code wants
/// [`Simulation`](crate::dynamics::Simulation).
#[deprecated(since = "0.2.0", note = "renamed `absolute::AbsoluteSimulation`; most code wants `dynamics::Simulation`")]
pub type SparseSimulation<'a, S, L, const NB: usize, const NV: usize, const M: usize, const NNZ: usize> =
    crate::absolute::AbsoluteSimulation<'a, S, L, NB, NV, M, NNZ>;
