use joint_runtime::Joint;
use joint_runtime::nalgebra::Vector3;

#[derive(Joint)]
#[joint(spherical, formulation = euler)]
enum Ball<T> {
    A(Vector3<T>),
    B(Vector3<T>),
}

fn main() {}
