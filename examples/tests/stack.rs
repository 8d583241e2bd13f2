//! A simulation's size by value and its stack do not grow with its scene:
//! with `alloc` every array of the scene's size lives on the heap (the
//! block factor, the workspaces, the inertias, the histories), made there
//! rather than built on the stack and moved (`joint_runtime`'s
//! `absolute/buf.rs`), so a 500-body chain's simulation is a few hundred
//! bytes, and is made and steps in a thread of 256 KiB (with its state, 104
//! bytes a body).

use joint_runtime::dynamics::{NoLoads, Simulation, SimulationOptions};
use joint_runtime::nalgebra::{UnitQuaternion, Vector3};
use joint_runtime::{OmegaBody, Scene};

joint_examples::chain_scene!(Chain500, 500);

/// The chain hanging straight, turned rigidly by 0.3 rad about `y` at its
/// pivot: on its joints, at rest, and swinging under gravity once released.
fn tilted() -> joint_runtime::SystemState<500> {
    let mut state = joint_examples::scaling::chain_start::<500>();
    let tilt = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), 0.3);
    for b in &mut state.bodies {
        *b = OmegaBody::from_rotation(tilt * b.r, &(tilt * b.rotation()), Vector3::zeros(), Vector3::zeros());
    }
    state
}

/// The scene, `'static` for the thread that makes and steps its simulation.
static CHAIN: Chain500 = Chain500;

#[test]
fn a_500_body_chain_is_made_and_steps_in_a_256_kib_thread_and_is_small_by_value() {
    let run = std::thread::Builder::new()
        .stack_size(256 << 10)
        .spawn(|| {
            let mut sim =
                Simulation::new(&CHAIN, NoLoads, &[], SimulationOptions::default()).map_err(|e| e.to_string())?;
            let bytes = size_of_val(&sim);
            let mut state = tilted();
            let start = sim.energy(&state).total();
            for _ in 0..5 {
                sim.step(&mut state, 1e-3).map_err(|e| e.to_string())?;
            }
            let end = sim.energy(&state);
            Ok::<_, String>((bytes, start, end.total(), end.kinetic, CHAIN.phi(&state).amax()))
        })
        .expect("a thread");
    let (bytes, start, end, kinetic, residual) = run.join().expect("no stack overflow").expect("made and stepped");
    assert!(bytes < 2048, "the simulation is {bytes} bytes by value");
    // It swings (gravity's work is kinetic energy), keeps its energy and its joints.
    assert!(kinetic > 1e-3, "kinetic energy {kinetic}");
    assert!((end - start).abs() < 1e-8 * start.abs(), "energy {start} → {end}");
    assert!(residual < 1e-10, "constraint residual {residual}");
}
