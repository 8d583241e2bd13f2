use joint_runtime::Joint;
use joint_runtime::nalgebra::Vector3;

#[derive(Joint)]
#[joint(rows(dot1(s, t)), formulation = omega_body)]
struct Perp<T> {
    #[joint(body1)]
    s: Vector3<T>,
    #[joint(body1)]
    t: Vector3<T>,
}

fn main() {}
