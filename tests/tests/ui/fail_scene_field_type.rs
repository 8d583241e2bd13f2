use joint_runtime::Scene;
use joint_runtime::nalgebra::Vector3;

// A scene's parameter fields are `f64`, `Vector3<f64>` or `AxisFrame<f64>`: a
// field of another type is one error at its type, worded as for `#[derive(Joint)]`.
#[derive(Scene)]
#[body(link, mass = 1.0, inertia = [0.1, 0.1, 0.01])]
#[joint(hinge = spherical(ground, link), rho1 = [0, 0, 0], rho2 = arm)]
#[joint(rope = distance(ground, link), rho1 = [0, 0, 0], rho2 = [0, 0, 0], length = reach)]
struct Pendulum {
    arm: Vector3<f32>,
    reach: [f64; 1],
}

fn main() {}
