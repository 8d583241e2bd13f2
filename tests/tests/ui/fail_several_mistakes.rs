use joint_runtime::Joint;
use joint_runtime::nalgebra::Vector3;

use joint_runtime::nalgebra::Vector4;

#[derive(Joint)]
#[joint(universal, formulation = relative_b2, ground = body2, s = [0, 0, 0], q = [1, 0, 0])]
struct Cardan<T> {
    h: Vector4<T>,
    rho1: Vector3<T>,
    rho1_again: Vector3<T>,
}

fn main() {}
