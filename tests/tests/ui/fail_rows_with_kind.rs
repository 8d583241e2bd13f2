use joint_runtime::Joint;
use joint_runtime::nalgebra::Vector3;

#[derive(Joint)]
#[joint(universal, rows(dot1(s, h)), formulation = omega_body)]
struct Cardan<T> {
    s: Vector3<T>,
    h: Vector3<T>,
    rho1: Vector3<T>,
    rho2: Vector3<T>,
}

fn main() {}
