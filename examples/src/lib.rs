//! Mechanisms built with `joint-runtime`, each a library module with a test that
//! asserts its numbers (`examples/tests/`) and a program that prints and plots it
//! (`cargo run --release -p joint-examples --example NAME`).

pub mod bricard;
pub mod coordinates;
pub mod double_cardan;
pub mod four_bar;
pub mod ilqr;
pub mod panda;
pub mod pendulum_chain;
pub mod press;
pub mod report;
pub mod scaling;
pub mod solo_stance;
pub mod steering;

// The Cardan shaft and the animation writer live in `joint-demo`, the main
// example's package (a first run builds nothing else).
pub use joint_demo::{cardan, write_animation};
