use joint_runtime::nalgebra::Vector3;
use joint_runtime::{Joint, Scene};

// `second_order` is a flag: a value is a mistake.
#[derive(Joint)]
#[joint(spherical, formulation = omega_body, second_order = yes)]
struct Ball {
    rho1: Vector3<f64>,
    rho2: Vector3<f64>,
}

// A misspelt scene option gets a did-you-mean.
#[derive(Scene)]
#[scene(second_ordre)]
#[body(bob, mass = 1.0, inertia = [1, 1, 1])]
#[joint(pivot = spherical(ground, bob), rho1 = [0, 0, 0], rho2 = [0, 0, 1])]
struct Pendulum;

fn main() {}
