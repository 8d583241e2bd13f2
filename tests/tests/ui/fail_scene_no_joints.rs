use joint_runtime::Scene;

#[derive(Scene)]
#[body(link, mass = 1.0, inertia = [0.1, 0.1, 0.01])]
struct Loose;

fn main() {}
