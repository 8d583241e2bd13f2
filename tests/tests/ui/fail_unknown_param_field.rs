use joint_runtime::Joint;
use joint_runtime::nalgebra::Vector3;

#[derive(Joint)]
#[joint(spherical, formulation = euler)]
struct Ball<T> {
    rho1: Vector3<T>,
    rho2: Vector3<T>,
    axis: Vector3<T>,
}

fn main() {}
