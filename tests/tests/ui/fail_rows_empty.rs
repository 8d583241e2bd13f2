use joint_runtime::Joint;
use joint_runtime::nalgebra::Vector3;

#[derive(Joint)]
#[joint(rows(), formulation = omega_body)]
struct Nothing<T> {
    #[joint(body1)]
    s: Vector3<T>,
}

fn main() {}
