//! The runtime on derive-generated joints and scenes: one test binary, so that
//! two cores build it once.
//!
//! * `analysis`: assembly, velocity and acceleration analysis.
//! * `batch`: batches scalar, in SIMD lanes and with rayon.
//! * `corpus`: public robot files as shipped, against MuJoCo 4.0.
//! * `dynamics`: forward dynamics and the integrators.
//! * `library`: states copied from MuJoCo and Pinocchio (`MUJOCO`, `PINOCCHIO`).
//! * `library_matrices`: matrices and derivatives in MuJoCo's and Pinocchio's coordinates.
//! * `loops`: closed loops in relative coordinates.
//! * `record`: trajectories as CSV and SVG.
//! * `serde_io`: the types through serde.
//! * `tree`: relative coordinates (`coordinates = relative`).
//! * `tree_implicit`: a stiff arm at its own step (the linearly implicit Euler step).

#![allow(missing_docs)]

mod analysis;
mod batch;
mod constrained;
mod corpus;
mod dynamics;
mod floating;
mod library;
mod library_matrices;
mod linear;
mod loops;
mod mjcf;
mod one_simulation;
mod record;
mod record_3d;
mod second_order;
mod serde_io;
mod soft;
mod tree;
mod tree_adaptive;
mod tree_derivatives;
mod tree_implicit;
mod tree_implicit_rules;
mod tree_joints;
mod tree_linear;
mod tree_radau;
mod tree_reactions;
mod urdf;
