use joint_runtime::Scene;

const RA: f64 = 0.007;

// A named constant in an attribute: one error at it, and no "needs joints" after.
#[derive(Scene)]
#[body(link, mass = 1.0, inertia = [0.1, 0.1, 0.01])]
#[joint(hinge = spherical(ground, link), rho1 = [0, 0, 0], rho2 = [-RA, 0, 0])]
struct Pendulum;

fn main() {}
