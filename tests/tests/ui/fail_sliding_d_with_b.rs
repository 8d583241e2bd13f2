use joint_runtime::Joint;
use joint_runtime::nalgebra::Vector3;

#[derive(Joint)]
#[joint(universal_translational, formulation = omega_body, d = [0, 0, 1], b = [1, 0, 0])]
struct TwoAngle<T> {
    s: Vector3<T>,
    h: Vector3<T>,
    rho1: Vector3<T>,
    rho2: Vector3<T>,
}

fn main() {}
