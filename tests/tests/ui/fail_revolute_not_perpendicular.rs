use joint_runtime::Joint;
use joint_runtime::nalgebra::Vector3;

#[derive(Joint)]
#[joint(revolute, formulation = omega_body, f = [1, 0, 0], g = [1, 1, 0])]
struct Hinge<T> {
    h: Vector3<T>,
    rho1: Vector3<T>,
    rho2: Vector3<T>,
}

fn main() {}
