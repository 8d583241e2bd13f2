//! Constraint code for multibody joints, derived at compile time.
//!
//! `#[derive(Joint)]` turns a joint declaration (the body-fixed axes `s, h, b, c, d`
//! and joint points `rho1, rho2` of the lecture notes) into fully unrolled,
//! allocation-free functions for the constraint Φ, its Jacobian and the
//! acceleration right-hand side γ, in one of five formulations. This crate holds
//! what the generated code implements and reads: the [`Joint`] trait, the state
//! types of each formulation, and small geometric helpers.
//!
//! The mathematical contract (frames, Euler parameters, rows, columns, γ) is the
//! project's `CONVENTIONS.md`; the README below is compiled as a doctest.
#![doc = include_str!("../../README.md")]
#![cfg_attr(not(feature = "std"), no_std)]

pub mod analysis;
pub mod batch;
pub mod conditioning;
pub mod dynamics;
mod geometry;
mod joint;
pub mod linalg;
pub mod scene;
mod state;
mod time;

pub use geometry::{AxisFrame, SlidingFrame, perpendicular_pair, rotation_matrix};
pub use joint::{Evaluation, Formulation, Joint, Ops, Singularity};
pub use scene::{BodyInertia, RowBlock, Scene, SparseJacobian, SystemState};
pub use state::{EulerBody, OmegaBody, OneBody, RelativeState, TwoBodies};
pub use time::{Constant, Drive, Polynomial, Profile, Ramp, Sinusoid, SmoothStep, TimeFunction};

/// Re-exported so that users need one dependency.
pub use joint_derive::{Joint, Scene};
pub use nalgebra;

/// Paths used by generated code. Not public API: anything here may change.
#[doc(hidden)]
pub mod __private {
    pub use nalgebra::{ArrayStorage, SMatrix, SVector, SimdComplexField, SimdRealField, convert};

    /// Implemented by the stub the derive emits beside a compile error.
    pub trait FallbackJoint {}
}
