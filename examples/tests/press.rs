//! The press in both coordinate choices: a tree of revolute and
//! translational (prismatic) joints, the rocker's ground pivot and the motor
//! closing the loop, the rams on their stiff spring-dampers.

use joint_examples::{coordinates, press};

/// The one declaration in relative coordinates (crank, coupler and rocker
/// angles, the two rams' slides; the rocker's pivot `d` and the `motor`
/// close the loop; the springs' forces enter as joint forces through their
/// ends' Jacobians) against the absolute scene: RK4 at h = 1e-4 (inside the
/// 4e-4 the 7 071 rad/s ram mode allows) for 0.1 s, the crank turning 2 rad;
/// and without the springs, where the rams slide freely, for 0.2 s.
#[test]
fn both_coordinate_choices_agree() {
    let start = press::initial_state().expect("assembled press");
    let springs = press::springs();
    let both = coordinates::both(&press::scene(), &start, &springs, 1e-4, 1_000, |_, _| {}).expect("both run");
    assert!(both.worst < 1e-10, "the coordinate choices differ by {:e}", both.worst);
    let held = (both.relative.bodies[3].r - start.bodies[3].r).norm();
    assert!(held > 0.05, "the rocker's ram moved {held} m only");
    let both = coordinates::both(&press::scene(), &start, &[], 1e-4, 2_000, |_, _| {}).expect("both run");
    assert!(both.worst < 1e-10, "without springs, the coordinate choices differ by {:e}", both.worst);
    let travel = (both.relative.bodies[3].r - start.bodies[3].r).norm();
    assert!(travel > 0.1, "the rocker's ram moved {travel} m only");
}
