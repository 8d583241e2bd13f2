//! Tests of the generated code, and the conformance runner they share.
//!
//! [`conformance`] evaluates the cases of `shared/conformance/*.json` through
//! derive-generated code with run-time parameters and applies the accuracy test
//! of the conformance README.

pub mod conformance;
pub mod joints;
