//! The symbolic engine: an arena of scalar nodes ([`graph`]), derivatives on it
//! ([`diff`]), emission to Rust ([`emit`]) and fill-reducing elimination orders
//! (`order`). It knows nothing of joints: the catalogue (`joints`) and the
//! formulations (`kinematics`) are stated over it.

pub mod diff;
pub mod emit;
pub mod graph;
pub mod order;

#[cfg(test)]
mod tests;

pub use diff::{TimeRules, grad};
pub use graph::{Graph, Id};
