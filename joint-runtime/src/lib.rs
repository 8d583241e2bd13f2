//! Constraint code for multibody joints, derived at compile time.
//!
//! The crate's README follows; every example in it is compiled and run as a
//! doctest.
#![doc = include_str!("../README.md")]
#![cfg_attr(docsrs, feature(doc_cfg))]
#![warn(missing_debug_implementations)]
#![cfg_attr(not(feature = "std"), no_std)]

#[cfg(feature = "alloc")]
extern crate alloc;

pub mod absolute;
pub mod analysis;
pub mod conventions {
    #![doc = include_str!("../CONVENTIONS.md")]
}
pub mod batch;
pub mod conditioning;
pub mod dynamics;
mod geometry;
mod joint;
pub mod linalg;
#[cfg(feature = "record")]
pub mod record;
pub mod relative;
pub mod robot;
pub mod scene;
#[cfg(feature = "serde")]
mod serde_array;
mod state;
mod time;

pub use geometry::{AxisFrame, SlidingFrame, perpendicular_pair, rotation_matrix};
pub use joint::{Evaluation, Formulation, Joint, Ops, ParseFormulationError, SecondOrder, Singularity};
pub use scene::{BodyInertia, JointPoint, RowBlock, Scene, SparseJacobian, SystemState};
pub use state::{EulerBody, OmegaBody, OneBody, RelativeState, TwoBodies};
pub use time::{Constant, Drive, Polynomial, Profile, Ramp, Sinusoid, SmoothStep, TimeFunction};

/// The absolute-coordinate engine's former name: deprecated aliases of
/// [`absolute`]'s types (renamed in 0.2).
pub mod sparse;
/// The relative-coordinate engine's former name: deprecated aliases of
/// [`relative`]'s types (renamed in 0.2).
pub mod tree;

/// Re-exported so that users need one dependency.
pub use joint_derive::{Joint, Scene};
pub use nalgebra;

/// Paths used by generated code. Not public API: anything here may change.
#[doc(hidden)]
pub mod __private {
    pub use nalgebra::{ArrayStorage, SMatrix, SVector, SimdComplexField, SimdRealField, convert};

    /// Implemented by the stub the derive emits beside a compile error.
    pub trait FallbackJoint {}

    pub use crate::analysis::InverseMass;
    pub use crate::scene::dense_from_csr;
}
