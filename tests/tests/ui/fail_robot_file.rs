use joint_runtime::Scene;
use joint_runtime::dynamics::{NoLoads, Simulation, SimulationOptions};
use joint_runtime::relative::TreeSimulation;

// An attribute that would change the dynamics without being modelled: one
// error, at the attribute's line and column, and the scene's uses still
// type-check (a stub of no bodies stands in, with the file's constants,
// empty).
#[derive(Scene)]
#[scene(mjcf = "../../data/robots/broken/springdamper.xml")]
struct Refused;

// A file cut short: one error, where the file ends.
#[derive(Scene)]
#[scene(urdf = "../../data/robots/broken/cut.urdf")]
struct Cut;

fn main() {
    let sim = TreeSimulation::new(&Refused).unwrap();
    let mut state: RefusedTreeState = sim.tree().zero_state();
    let _ = sim.inverse_dynamics(&state, &state.v);
    let _ = Refused::MUJOCO.state_from(&[], &[]);
    let _ = (Refused::LINKS.len(), Refused::LIMITS, Refused::OPTIONS.timestep, Cut::PINOCCHIO.nq());
    let _ = joint_runtime::robot::LinkFrame::find(&Cut::LINKS, "tool0");
    let mut cut = Simulation::new(&Cut, NoLoads, &[], SimulationOptions::default()).unwrap();
    let _ = cut.step(&mut state, 1e-3);
}
