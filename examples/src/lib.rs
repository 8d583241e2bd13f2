//! Mechanisms built with `joint-runtime`, each a library module with a test that
//! asserts its numbers (`examples/tests/`) and a program that prints and plots it
//! (`cargo run --release --example NAME`).

pub mod bricard;
pub mod cardan;
pub mod double_cardan;
pub mod four_bar;
pub mod pendulum_chain;
pub mod report;
pub mod steering;
