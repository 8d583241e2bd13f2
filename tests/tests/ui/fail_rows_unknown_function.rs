use joint_runtime::Joint;
use joint_runtime::nalgebra::Vector3;

#[derive(Joint)]
#[joint(rows(tan(alpha) - dot(s, h)), formulation = omega_body)]
struct Angle<T> {
    #[joint(body1)]
    s: Vector3<T>,
    #[joint(body2)]
    h: Vector3<T>,
    alpha: T,
}

fn main() {}
