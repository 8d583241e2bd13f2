//! The press's mechanism in both coordinate choices: a tree of revolute and
//! translational (prismatic) joints, the rocker's ground pivot and the motor
//! closing the loop.

use joint_examples::{coordinates, press};

/// The one declaration in relative coordinates (crank, coupler and rocker
/// angles, the two rams' slides; the rocker's pivot `d` and the `motor`
/// close the loop) against the absolute scene: RK4 at h = 1e-4 for 0.2 s
/// (the crank turns 4 rad). Without the stiff springs (the relative
/// simulation takes joint forces only so far), the rams slide freely.
#[test]
fn both_coordinate_choices_agree() {
    let start = press::initial_state().expect("assembled press");
    let both = coordinates::both(&press::scene(), &start, 1e-4, 2_000, |_, _| {}).expect("both run");
    assert!(both.worst < 1e-10, "the coordinate choices differ by {:e}", both.worst);
    let travel = (both.relative.bodies[3].r - start.bodies[3].r).norm();
    assert!(travel > 0.1, "the rocker's ram moved {travel} m only");
}
