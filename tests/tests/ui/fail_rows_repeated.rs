use joint_runtime::Joint;
use joint_runtime::nalgebra::Vector3;

#[derive(Joint)]
#[joint(rows(dot1(s, h), spherical, dot1(s, h)), formulation = omega_body)]
struct Twice<T> {
    #[joint(body1)]
    s: Vector3<T>,
    #[joint(body2)]
    h: Vector3<T>,
    rho1: Vector3<T>,
    rho2: Vector3<T>,
}

fn main() {}
