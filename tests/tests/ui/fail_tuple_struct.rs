use joint_runtime::Joint;
use joint_runtime::nalgebra::Vector3;

#[derive(Joint)]
#[joint(spherical, formulation = euler)]
struct Ball<T>(Vector3<T>, Vector3<T>);

fn main() {}
