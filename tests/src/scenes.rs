//! What the analysis and dynamics tests (`tests/analysis.rs`, `tests/dynamics.rs`)
//! share about their `#[derive(Scene)]` mechanisms: chains of rods hanging from
//! ball joints.
//!
//! A rod has length 1 and its joint points at `±`[`half_rod`] in its own frame;
//! the chain hangs from the origin.

use joint_runtime::nalgebra::{UnitQuaternion, Vector3};
use joint_runtime::{OmegaBody, SystemState};

/// The upper joint point of a rod of length 1, in the rod's frame (the lower one is its negative).
pub fn half_rod() -> Vector3<f64> {
    Vector3::new(0.0, 0.0, 0.5)
}

/// An assembled chain of rods hanging from the origin, at rest at `t = 0`: rod `i`
/// turned by `angles[i]` about x, each joined to the one above (the first to the
/// origin) at its upper point.
pub fn hanging_rods<const NB: usize>(angles: [f64; NB]) -> SystemState<NB> {
    let mut joint = Vector3::zeros();
    let bodies = angles.map(|a| {
        let q = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), a);
        let r = joint - q * half_rod();
        joint = r - q * half_rod();
        OmegaBody::from_rotation(r, &q, Vector3::zeros(), Vector3::zeros())
    });
    SystemState { bodies, t: 0.0 }
}
