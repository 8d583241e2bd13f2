//! Tests of the generated code, and the conformance runner they share.
//!
//! [`conformance`] evaluates the cases of the repository's `conformance/*.json`
//! through derive-generated code with run-time parameters and applies the
//! accuracy test of the conformance README. [`trajectory`] holds the exact trajectories and
//! comparisons of the derivative tests, [`scenes`] the mechanisms of the analysis
//! and dynamics tests, [`random`] the deterministic random states of the batch
//! tests and benchmark.

/// The repository's README, whose examples run as doctests here (the crate
/// READMEs are their crates' own docs).
#[cfg(doctest)]
#[doc = include_str!("../../README.md")]
struct RepositoryReadme;

pub mod conformance;
pub mod joints;
pub mod random;
pub mod scenes;
pub mod second_order;
pub mod trajectory;
