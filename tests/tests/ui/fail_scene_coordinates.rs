use joint_runtime::Scene;

#[derive(Scene)]
#[scene(coordinates = joint)]
#[body(arm, mass = 1.0, inertia = [0.1, 0.1, 0.1])]
#[joint(shoulder = spherical(ground, arm), rho1 = [0, 0, 0], rho2 = [0, 0, 1])]
struct Arm;

fn main() {}
