use joint_runtime::Scene;
use joint_runtime::Joint;
use joint_runtime::nalgebra::Vector3;

// An option given twice: one error at the second, in either derive.
#[derive(Joint)]
#[joint(spherical, formulation = omega_body, ground = body1, ground = body2)]
struct Ball<T> {
    rho1: Vector3<T>,
    rho2: Vector3<T>,
}

#[derive(Scene)]
#[body(link, mass = 1.0, mass = 2.0, inertia = [0.1, 0.1, 0.01])]
#[joint(hinge = spherical(ground, link), rho1 = [0, 0, 0], rho2 = [0, 0, -1])]
struct Pendulum;

fn main() {}
