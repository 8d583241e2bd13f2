use joint_runtime::Scene;

// A row of joints that runs off its row of bodies, and a row of bodies named
// without an index: one error each.
#[derive(Scene)]
#[body(link[4], mass = 1.0, inertia = [0.1, 0.1, 0.1])]
#[joint(top = spherical(ground, link), rho1 = [0, 0, 0], rho2 = [0, 0, 0.5])]
#[joint(hinge[i in 0..4] = spherical(link[i], link[i + 1]), rho1 = [0, 0, -0.5], rho2 = [0, 0, 0.5])]
struct Chain;

fn main() {}
