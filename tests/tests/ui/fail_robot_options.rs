use joint_runtime::Scene;

// A file's `<mimic>` is a row of relative coordinates: not with the
// absolute engine as well (unless read as independent).
#[derive(Scene)]
#[scene(urdf = "../../data/robots/panda.urdf", coordinates = both)]
struct Both;

// `mimic` and `floating_base` are for files, `floating_base` for URDF ones.
#[derive(Scene)]
#[scene(mjcf = "../../data/robots/ur5.xml", floating_base)]
struct Floating;

#[derive(Scene)]
#[scene(mimic = independent)]
#[body(bar, mass = 1.0, inertia = [0.1, 0.1, 0.01])]
#[joint(pin = spherical(ground, bar), rho1 = [0, 0, 0], rho2 = [0, 0, 0.5])]
struct NoFile;

// `equality = hard` is for MJCF files, whose equalities MuJoCo makes soft.
#[derive(Scene)]
#[scene(urdf = "../../data/robots/ur5.urdf", equality = hard)]
struct HardUrdf;

#[derive(Scene)]
#[scene(mjcf = "../../data/robots/ur5.xml", equality = soft)]
struct Soft;

fn main() {}
