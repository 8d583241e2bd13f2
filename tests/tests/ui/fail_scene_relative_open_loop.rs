use joint_runtime::Scene;
use joint_runtime::relative::TreeSimulation;

// A four-bar whose closing joint `d` sits 0.1 m off the plane of the others:
// the tree keeps every body in that plane, so the joint's z row is the
// constant 0.1 and the loop can never close. The stub keeps the uses below
// type-checking: one mistake, one message.
#[derive(Scene)]
#[scene(gravity = [0, -9.81, 0], coordinates = relative)]
#[body(crank, mass = 1.0, inertia = [0.1, 0.1, 0.1])]
#[body(coupler, mass = 1.0, inertia = [0.1, 0.1, 0.1])]
#[body(rocker, mass = 1.0, inertia = [0.1, 0.1, 0.1])]
#[joint(a = revolute(ground, crank), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0, 0, 0], rho2 = [0, -0.5, 0])]
#[joint(b = revolute(crank, coupler), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0, 0.5, 0], rho2 = [-0.5, 0, 0])]
#[joint(c = revolute(coupler, rocker), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0.5, 0, 0], rho2 = [0, 0.5, 0])]
#[joint(d = revolute(rocker, ground), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0, -0.5, 0], rho2 = [1, 0, 0.1])]
struct FourBar;

fn main() {
    let sim = TreeSimulation::new(&FourBar).unwrap();
    let _state: FourBarTreeState = sim.tree().zero_state();
}
