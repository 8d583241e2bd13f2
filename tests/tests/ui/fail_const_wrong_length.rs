use joint_runtime::Joint;
use joint_runtime::nalgebra::Vector3;

#[derive(Joint)]
#[joint(universal, formulation = omega_body, s = [0, 1])]
struct Cardan<T> {
    h: Vector3<T>,
    rho1: Vector3<T>,
    rho2: Vector3<T>,
}

fn main() {}
