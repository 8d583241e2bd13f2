use joint_runtime::Joint;
use joint_runtime::nalgebra::Vector3;

#[derive(Joint)]
#[joint(spherical, formulation = omega_bdy)]
struct Ball<T> {
    rho1: Vector3<T>,
    rho2: Vector3<T>,
}

fn main() {}
