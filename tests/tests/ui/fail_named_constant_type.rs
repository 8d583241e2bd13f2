use joint_runtime::Scene;

const ARM: i32 = 2;

// A named constant is an `f64` expression: the compiler reports a wrong type at it.
#[derive(Scene)]
#[body(link, mass = 1.0, inertia = [0.1, 0.1, 0.01])]
#[joint(hinge = spherical(ground, link), rho1 = [0, 0, 0], rho2 = [0, 0, -ARM])]
struct Pendulum;

fn main() {}
