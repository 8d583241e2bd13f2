use joint_runtime::Scene;

// Rows of bodies and of joints: a chain of 40 links and a ladder of four-bar loops.
#[derive(Scene)]
#[scene(coordinates = absolute, gravity = [0, 0, -9.81])]
#[body(link[40], mass = 1.0, inertia = [0.0833, 0.0833, 0.001])]
#[joint(top = spherical(ground, link[0]), rho1 = [0, 0, 0], rho2 = [0, 0, 0.5])]
#[joint(hinge[i in 1..40] = spherical(link[i - 1], link[i]), rho1 = [0, 0, -0.5], rho2 = [0, 0, 0.5])]
struct Chain;

#[derive(Scene)]
#[scene(coordinates = absolute)]
#[body(crank[5], mass = 1.0, inertia = [0.1, 0.1, 0.1])]
#[body(coupler[4], mass = 1.0, inertia = [0.1, 0.1, 0.1])]
#[joint(pin[i in 0..=4] = revolute(ground, crank[i]), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [i, 0, 0], rho2 = [0, -0.5, 0])]
#[joint(left[i in 0..4] = revolute(crank[i], coupler[i]), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0, 0.5, 0], rho2 = [-0.5, 0, 0])]
#[joint(right[i in 0..4] = revolute(coupler[i], crank[i + 1]), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0.5, 0, 0], rho2 = [0, 0.5, 0])]
struct Ladder;

// Several entries in one attribute, separated by `;` (rustc stops near 128
// attributes on one item).
#[derive(Scene)]
#[scene(coordinates = absolute)]
#[body(upper, mass = 1.0, inertia = [0.1, 0.1, 0.1]; lower, mass = 2.0, inertia = [0.2, 0.2, 0.2])]
#[joint(shoulder = spherical(ground, upper), rho1 = [0, 0, 0], rho2 = [0, 0, 0.5];
        elbow = spherical(upper, lower), rho1 = [0, 0, -0.5], rho2 = [0, 0, 0.5])]
struct Arm;

fn main() {
    assert_eq!((Arm::UPPER, Arm::LOWER, Arm::ROWS), (0, 1, 6));
    assert_eq!(Arm.inertias()[1].mass, 2.0);
    assert_eq!(Chain::NB, 40);
    assert_eq!(Chain::ROWS, 120);
    assert_eq!(Chain::LINK[39], 39);
    assert_eq!(<Chain as Scene<40, 240, 120>>::BODIES[3], "link[3]");
    assert_eq!(Chain::BLOCKS[2].name, "hinge[2]");
    assert_eq!(Ladder::CRANK, [0, 1, 2, 3, 4]);
    assert_eq!(Ladder::COUPLER, [5, 6, 7, 8]);
    assert_eq!(Ladder::ROWS, 13 * 5);
    let _state: Option<LadderState> = None;
}
