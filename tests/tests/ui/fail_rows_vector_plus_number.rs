use joint_runtime::Joint;
use joint_runtime::nalgebra::Vector3;

#[derive(Joint)]
#[joint(rows(s + 1), formulation = omega_body)]
struct Perp<T> {
    #[joint(body1)]
    s: Vector3<T>,
    #[joint(body2)]
    h: Vector3<T>,
}

fn main() {}
