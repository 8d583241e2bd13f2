use joint_runtime::Scene;

#[derive(Scene)]
#[body(link, mass = 1.0, inertia = [0.1, 0.1, 0.01])]
#[joint(hinge = revolute(ground, link), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0, 0, 0])]
struct Pendulum;

fn main() {}
