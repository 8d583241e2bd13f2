use joint_runtime::Scene;

#[derive(Scene)]
#[scene(coordinates = relative)]
#[body(arm, mass = 1.0, inertia = [0.1, 0.1, 0.1])]
#[body(drone, mass = 1.0, inertia = [0.1, 0.1, 0.1])]
#[body(gripper, mass = 1.0, inertia = [0.1, 0.1, 0.1])]
#[joint(shoulder = spherical(ground, arm), rho1 = [0, 0, 0], rho2 = [0, 0, 1])]
#[joint(claw = spherical(drone, gripper), rho1 = [0, 0, 0], rho2 = [0, 0, 1])]
struct Floating;

fn main() {}
