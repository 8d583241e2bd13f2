use joint_runtime::Scene;

// `armature`, `damping` and springs: on a tree's moving joints in relative
// coordinates only, each a number at least zero (a spring's rest any
// number), a spring on a joint of one freedom.
#[derive(Scene)]
#[scene(coordinates = absolute)]
#[body(bar, mass = 1.0, inertia = [0.1, 0.1, 0.01])]
#[joint(pin = revolute(ground, bar), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0, 0, 0], rho2 = [0, 0, 0.5], damping = 0.1)]
struct Absolute;

#[derive(Scene)]
#[scene(coordinates = relative)]
#[body(bar, mass = 1.0, inertia = [0.1, 0.1, 0.01])]
#[joint(pin = revolute(ground, bar), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0, 0, 0], rho2 = [0, 0, 0.5], armature = -1)]
struct Negative;

#[derive(Scene)]
#[scene(coordinates = relative)]
#[body(crank, mass = 1.0, inertia = [0.1, 0.1, 0.01])]
#[body(tool, mass = 1.0, inertia = [0.1, 0.1, 0.01])]
#[joint(a = revolute(ground, crank), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0, 0, 0], rho2 = [0, 0, 0.5], armature = 0.1)]
#[joint(w = fixed(crank, tool), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0, 0, 0.5], rho2 = [0, 0, 0], damping = 2)]
#[joint(c = spherical(ground, tool), rho1 = [0, 0, 1], rho2 = [0, 0, 0], armature = 0.1)]
struct Relative;

#[derive(Scene)]
#[scene(coordinates = relative)]
#[body(bob, mass = 1.0, inertia = [0.1, 0.1, 0.01])]
#[joint(ball = spherical(ground, bob), rho1 = [0, 0, 0], rho2 = [0, 0, 0.5], stiffness = 10, spring_rest = 0.2)]
struct SprungBall;

fn main() {}
