//! The examples' tests, one binary: each module is one mechanism's or one
//! feature's checks (what the module's own documentation says). One binary
//! rather than one per file: the package builds at `opt-level = 3` even in
//! tests (its simulations run inside `cargo test`), and eighteen binaries
//! took 6 min 49 s of a cold CI build on two cores against one.

mod animation;
mod bricard;
mod cardan;
mod default_coordinates;
mod double_cardan;
mod four_bar;
mod handwritten;
mod ilqr;
mod long_run;
mod normal_blocks;
mod panda;
mod pendulum_chain;
mod press;
mod second_order;
mod solo_stance;
mod sparse;
mod stack;
mod steering;
mod stiff;
mod viewer;
