//! The symbolic engine: an arena of scalar nodes ([`graph`]), derivatives on it
//! ([`diff`]) and emission to Rust ([`emit`]). It knows nothing of joints.

pub mod diff;
pub mod emit;
pub mod graph;
pub mod order;

#[cfg(test)]
mod tests;

pub use diff::{TimeRules, grad};
pub use graph::{Graph, Id};
