use joint_runtime::Joint;
use joint_runtime::nalgebra::Vector3;

#[derive(Joint)]
#[joint(universal_translational, formulation = omega_body, s = [1, 0, 0], h = [0, 1, 0])]
struct TwoAngle<T> {
    d: Vector3<T>,
    rho1: Vector3<T>,
    rho2: Vector3<T>,
}

fn main() {}
