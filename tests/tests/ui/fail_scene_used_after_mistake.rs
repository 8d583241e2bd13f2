use joint_runtime::dynamics::{NoLoads, Simulation, SimulationOptions};
use joint_runtime::{OmegaBody, Scene, SystemState};

// One mistake (a field that does not exist) gives one message: the scene's uses
// below type-check against the stub the derive leaves in its place.
#[derive(Scene)]
#[body(link, mass = 1.0, inertia = [0.1, 0.1, 0.01])]
#[joint(hinge = revolute(ground, link), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0, 0, 0], rho2 = arm)]
struct Pendulum;

fn main() {
    let state = SystemState { bodies: [OmegaBody::default()], t: 0.0 };
    let _phi = Pendulum.phi(&state);
    let _sim = Simulation::new(&Pendulum, NoLoads, &[], SimulationOptions::default());
    let _link = state.bodies[Pendulum::LINK];
    assert_eq!(Pendulum::ROWS, 5);
}
