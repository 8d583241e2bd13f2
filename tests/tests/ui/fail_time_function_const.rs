use joint_runtime::Joint;
use joint_runtime::nalgebra::Vector3;

#[derive(Joint)]
#[joint(rotational_driver, formulation = omega_body, theta = 0.5)]
struct Motor<T> {
    f: Vector3<T>,
    g: Vector3<T>,
    k: Vector3<T>,
}

fn main() {}
