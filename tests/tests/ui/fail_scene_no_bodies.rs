use joint_runtime::Scene;

#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81])]
struct Empty;

fn main() {}
