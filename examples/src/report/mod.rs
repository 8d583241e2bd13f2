//! The speed-against-error report: the generated code beside what a user would
//! otherwise write — a hand-written nalgebra implementation, forward-mode
//! automatic differentiation (num-dual) and central finite differences — timed
//! and checked against the 60-digit conformance vectors in one run, plus
//! work–precision diagrams of the simulations and, at the robot level, the
//! dynamics' derivatives exact and by differences and a stiff arm's
//! implicit step beside RK4.
//!
//! `cargo run --release -p joint-examples --bin speed-vs-error` writes `report/`.

pub mod counting;
pub mod derivatives;
pub mod handwritten;
pub mod simulation;
pub mod stiff;
pub mod stiff_robot;
pub mod variants;
