//! What `#[derive(Joint)]` and `#[derive(Scene)]` generate, checked against
//! independent references: one test binary, so that two cores build it once.
//!
//! * `catalogue`: every catalogue joint in every formulation, the drivers' time
//!   terms, user-written rows, axis parameters and singularity measures.
//! * `derivatives`: J and γ against num-dual and finite differences; variants and
//!   scalars.
//! * `conformance`, `hard_cases`: the 60-digit reference vectors, all and by regime.
//! * `op_counts`: the generated operation counts against `tests/op_counts.txt`.
//! * `attributes`: named constants and arithmetic in attributes.

mod attributes;
mod catalogue;
mod conformance;
mod derivatives;
mod hard_cases;
mod op_counts;
