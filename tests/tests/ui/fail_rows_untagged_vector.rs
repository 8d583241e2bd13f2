use joint_runtime::Joint;
use joint_runtime::nalgebra::Vector3;

#[derive(Joint)]
#[joint(rows(dot(s, h)), formulation = omega_body)]
struct Perp<T> {
    #[joint(body1)]
    s: Vector3<T>,
    h: Vector3<T>,
}

fn main() {}
