use joint_runtime::Scene;

// `rows` would be named `ROWS`, the scene's row count; `Arm` and `arm` share `ARM`.
#[derive(Scene)]
#[body(rows, mass = 1.0, inertia = [0.1, 0.1, 0.01])]
#[body(arm, mass = 1.0, inertia = [0.1, 0.1, 0.01])]
#[body(Arm, mass = 1.0, inertia = [0.1, 0.1, 0.01])]
#[joint(ball = spherical(ground, rows), rho1 = [0, 0, 0], rho2 = [0, 0, 0.5])]
#[joint(elbow = spherical(rows, arm), rho1 = [0, 0, -0.5], rho2 = [0, 0, 0.5])]
#[joint(wrist = spherical(arm, Arm), rho1 = [0, 0, -0.5], rho2 = [0, 0, 0.5])]
struct Chain;

fn main() {}
