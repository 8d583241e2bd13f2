use joint_runtime::Scene;

#[derive(Scene)]
#[scene(coordinates = relative)]
#[body(shaft, mass = 1.0, inertia = [0.1, 0.1, 0.1])]
#[joint(bush = cylindrical(ground, shaft), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0, 0, 0], rho2 = [0, 0, 0])]
struct Bush;

fn main() {}
