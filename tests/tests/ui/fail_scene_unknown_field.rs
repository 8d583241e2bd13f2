use joint_runtime::Scene;
use joint_runtime::nalgebra::Vector3;

#[derive(Scene)]
#[body(link, mass = 1.0, inertia = [0.1, 0.1, 0.01])]
#[joint(hinge = revolute(ground, link), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0, 0, 0], rho2 = arm)]
struct Pendulum {
    lever: Vector3<f64>,
}

fn main() {}
