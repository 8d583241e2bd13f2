use joint_runtime::Joint;
use joint_runtime::nalgebra::Vector3;

#[derive(Joint)]
#[joint(rows(dot(s, h)), formulation = omega_body, s = [0, 0, 1])]
struct Perp<T> {
    #[joint(body2)]
    h: Vector3<T>,
}

fn main() {}
