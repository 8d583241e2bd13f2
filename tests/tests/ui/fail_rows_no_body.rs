use joint_runtime::Joint;
use joint_runtime::nalgebra::Vector3;

#[derive(Joint)]
#[joint(rows(dot1(s, h), alpha * alpha - 1), formulation = omega_body)]
struct Constant<T> {
    #[joint(body1)]
    s: Vector3<T>,
    #[joint(body2)]
    h: Vector3<T>,
    alpha: T,
}

fn main() {}
