use joint_runtime::Joint;
use joint_runtime::nalgebra::Vector3;

const TILT: f64 = 0.5;

// An axis split into perpendicular vectors at compile time cannot name a constant.
#[derive(Joint)]
#[joint(revolute, formulation = omega_body, axis1 = [0, TILT, 1], axis2 = [0, 0, 1])]
struct Hinge<T> {
    rho1: Vector3<T>,
    rho2: Vector3<T>,
}

fn main() {}
