//! The relative-coordinate engine's former name (renamed in 0.2: a scene
//! that declares `coordinates = relative` finds it under
//! [`relative`](crate::relative)). Every type and constant here is a
//! deprecated alias, so that a path through `tree` compiles with a warning
//! that names the new one; the trait `TreeScene` is re-exported as it is
//! (rustc cannot deprecate a re-export).
//!
//! ```
//! #![allow(deprecated)]
//! use joint_runtime::nalgebra::SVector;
//! // Compiles (with a warning without the `allow`).
//! let _: joint_runtime::tree::TreeState<1, 1> = joint_runtime::relative::TreeState { q: SVector::zeros(), v: SVector::zeros(), t: 0.0 };
//! ```
#![allow(deprecated)]

pub use crate::relative::TreeScene;

/// Renamed [`relative::ForwardDerivatives`](crate::relative::ForwardDerivatives).
#[deprecated(since = "0.2.0", note = "renamed `joint_runtime::relative::ForwardDerivatives` (CHANGELOG.md)")]
pub type ForwardDerivatives<const NV: usize> = crate::relative::ForwardDerivatives<NV>;
/// Renamed [`relative::InverseDerivatives`](crate::relative::InverseDerivatives).
#[deprecated(since = "0.2.0", note = "renamed `joint_runtime::relative::InverseDerivatives` (CHANGELOG.md)")]
pub type InverseDerivatives<const NV: usize> = crate::relative::InverseDerivatives<NV>;
/// Renamed [`relative::SecondDerivatives`](crate::relative::SecondDerivatives).
#[deprecated(since = "0.2.0", note = "renamed `joint_runtime::relative::SecondDerivatives` (CHANGELOG.md)")]
pub type SecondDerivatives<const NV: usize> = crate::relative::SecondDerivatives<NV>;
/// Renamed [`relative::TreeEnergy`](crate::relative::TreeEnergy).
#[deprecated(since = "0.2.0", note = "renamed `joint_runtime::relative::TreeEnergy` (CHANGELOG.md)")]
pub type TreeEnergy = crate::relative::TreeEnergy;
/// Renamed [`relative::ForceGains`](crate::relative::ForceGains).
#[deprecated(since = "0.2.0", note = "renamed `joint_runtime::relative::ForceGains` (CHANGELOG.md)")]
pub type ForceGains<const NV: usize> = crate::relative::ForceGains<NV>;
/// Renamed [`relative::TreeSimulation`](crate::relative::TreeSimulation).
#[deprecated(since = "0.2.0", note = "renamed `joint_runtime::relative::TreeSimulation` (CHANGELOG.md)")]
pub type TreeSimulation<
    'a,
    S,
    const NB: usize,
    const NQ: usize,
    const NV: usize,
    const NC: usize = 0,
    L = crate::dynamics::NoLoads,
> = crate::relative::TreeSimulation<'a, S, NB, NQ, NV, NC, L>;
/// Renamed [`relative::StepJacobian`](crate::relative::StepJacobian).
#[deprecated(since = "0.2.0", note = "renamed `joint_runtime::relative::StepJacobian` (CHANGELOG.md)")]
pub type StepJacobian<const NV: usize> = crate::relative::StepJacobian<NV>;
/// Renamed [`relative::StepWork`](crate::relative::StepWork).
#[deprecated(since = "0.2.0", note = "renamed `joint_runtime::relative::StepWork` (CHANGELOG.md)")]
pub type StepWork<const NQ: usize, const NV: usize> = crate::relative::StepWork<NQ, NV>;
/// Renamed [`relative::JointLayout`](crate::relative::JointLayout).
#[deprecated(since = "0.2.0", note = "renamed `joint_runtime::relative::JointLayout` (CHANGELOG.md)")]
pub type JointLayout = crate::relative::JointLayout;
/// Renamed [`relative::Tree`](crate::relative::Tree).
#[deprecated(since = "0.2.0", note = "renamed `joint_runtime::relative::Tree` (CHANGELOG.md)")]
pub type Tree<const NB: usize, const NQ: usize, const NV: usize> = crate::relative::Tree<NB, NQ, NV>;
/// Renamed [`relative::TreeError`](crate::relative::TreeError).
#[deprecated(since = "0.2.0", note = "renamed `joint_runtime::relative::TreeError` (CHANGELOG.md)")]
pub type TreeError = crate::relative::TreeError;
/// Renamed [`relative::TreeJointKind`](crate::relative::TreeJointKind).
#[deprecated(since = "0.2.0", note = "renamed `joint_runtime::relative::TreeJointKind` (CHANGELOG.md)")]
pub type TreeJointKind = crate::relative::TreeJointKind;
/// Renamed [`relative::TreeJoint`](crate::relative::TreeJoint).
#[deprecated(since = "0.2.0", note = "renamed `joint_runtime::relative::TreeJoint` (CHANGELOG.md)")]
pub type TreeJoint = crate::relative::TreeJoint;
/// Renamed [`relative::TreeGeometry`](crate::relative::TreeGeometry).
#[deprecated(since = "0.2.0", note = "renamed `joint_runtime::relative::TreeGeometry` (CHANGELOG.md)")]
pub type TreeGeometry<const NB: usize> = crate::relative::TreeGeometry<NB>;
/// Renamed [`relative::ClosureRows`](crate::relative::ClosureRows).
#[deprecated(since = "0.2.0", note = "renamed `joint_runtime::relative::ClosureRows` (CHANGELOG.md)")]
pub type ClosureRows<const NC: usize, const NV: usize> = crate::relative::ClosureRows<NC, NV>;
/// Renamed [`relative::TreeState`](crate::relative::TreeState).
#[deprecated(since = "0.2.0", note = "renamed `joint_runtime::relative::TreeState` (CHANGELOG.md)")]
pub type TreeState<const NQ: usize, const NV: usize> = crate::relative::TreeState<NQ, NV>;

/// Renamed [`relative::DIVERGED`](crate::relative::DIVERGED).
#[deprecated(since = "0.2.0", note = "renamed `joint_runtime::relative::DIVERGED` (CHANGELOG.md)")]
pub const DIVERGED: f64 = crate::relative::DIVERGED;
