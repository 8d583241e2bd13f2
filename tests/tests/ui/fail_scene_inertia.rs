use joint_runtime::Scene;

// Principal moments that break the triangle inequality (1 > 0.01 + 0.01),
// a tensor that is not positive definite, and no mass: each its own message.
#[derive(Scene)]
#[body(rod, mass = 1.0, inertia = [0.01, 0.01, 1.0])]
#[body(plate, mass = 1.0, inertia = [1, 1, 2, 2, 0, 0])]
#[body(ghost, mass = 0.0, inertia = [0.1, 0.1, 0.1])]
#[joint(a = spherical(ground, rod), rho1 = [0, 0, 0], rho2 = [0, 0, 1])]
#[joint(b = spherical(rod, plate), rho1 = [0, 0, 0], rho2 = [0, 0, 1])]
#[joint(c = spherical(plate, ghost), rho1 = [0, 0, 0], rho2 = [0, 0, 1])]
struct Unphysical;

fn main() {}
