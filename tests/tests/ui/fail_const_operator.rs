use joint_runtime::Joint;
use joint_runtime::nalgebra::Vector3;

#[derive(Joint)]
#[joint(spherical, formulation = euler, rho1 = [0, 0, 1.0 % 0.3], rho2 = [0, 0, 0])]
struct Ball<T> {
    #[joint(skip)]
    unused: Vector3<T>,
}

fn main() {}
