use joint_runtime::Joint;
use joint_runtime::nalgebra::Vector3;

#[derive(Joint)]
#[joint(
    universal_translational,
    formulation = euler,
    s = [1, 0, 0],
    h = [0, 1, 0],
    b = [1, 0, 1],
    c = [0, 1, 0],
    d = [0, 0, 1],
)]
struct TwoAngle<T> {
    rho1: Vector3<T>,
    rho2: Vector3<T>,
}

fn main() {}
