//! Three robots read from their files, in relative coordinates (the engine
//! robot controllers run on): an RK4 step, forward dynamics (the derive's
//! articulated-body algorithm, the runtime's recursion it falls back to, and
//! both with loads and closures), inverse dynamics, the mass matrix and the
//! bodies' frames, at their fixed sizes. The UR5 from
//! its URDF file (revolute joints), the Panda from its MJCF file (with its
//! fingers' slides and armature), the floating Solo12 from its MJCF file (a
//! free joint's quaternion and twelve hinges).

use joint_runtime::dynamics::{NoLoads, Simulate, StepReport};
use joint_runtime::nalgebra::{SMatrix, SVector};
use joint_runtime::relative::{TreeError, TreeState};
use joint_runtime::{Scene, SystemState};

/// Universal Robots' UR5 (example-robot-data's URDF).
#[derive(Scene)]
#[scene(urdf = "../../tests/data/robots/ur5.urdf")]
pub struct Ur5;

/// Franka Emika's Panda (MuJoCo Menagerie's MJCF).
#[derive(Scene)]
#[scene(mjcf = "../../tests/data/robots/panda.xml")]
pub struct Panda;

/// ODRI's Solo12 on a floating base (MJCF).
#[derive(Scene)]
#[scene(mjcf = "../../tests/data/robots/solo12_floating.xml")]
pub struct Solo12;

/// A robot's checked functions, by its scene and sizes.
macro_rules! robot {
    ($module:ident, $scene:ty, $nb:literal, $nq:literal, $nv:literal) => {
        pub mod $module {
            use super::*;

            type Sim<'a> = <$scene as Simulate<'a, NoLoads>>::Engine;
            type State = TreeState<$nq, $nv>;

            checked! {
                fn step(sim: &mut Sim<'_>, state: &mut State, h: f64) -> Result<StepReport, TreeError> {
                    sim.step(state, h)
                }
                fn forward_dynamics(sim: &mut Sim<'_>, state: &State, tau: &SVector<f64, $nv>) -> Result<SVector<f64, $nv>, TreeError> {
                    sim.forward_dynamics(state, tau)
                }
                fn inverse_dynamics(sim: &Sim<'_>, state: &State, vdot: &SVector<f64, $nv>) -> SVector<f64, $nv> {
                    sim.inverse_dynamics(state, vdot)
                }
                fn mass_matrix(sim: &Sim<'_>, q: &SVector<f64, $nq>, out: &mut SMatrix<f64, $nv, $nv>) -> f64 {
                    sim.mass_matrix_into(q, out);
                    out.trace()
                }
                fn forward_dynamics_by_recursion(sim: &Sim<'_>, state: &State, tau: &SVector<f64, $nv>) -> Result<SVector<f64, $nv>, TreeError> {
                    sim.tree().forward_dynamics(state, tau)
                }
                fn tree_dynamics(sim: &Sim<'_>, state: &State, tau: &SVector<f64, $nv>) -> Result<SVector<f64, $nv>, TreeError> {
                    sim.tree_dynamics(state, tau)
                }
                fn frames(sim: &Sim<'_>, state: &State) -> SystemState<$nb> {
                    sim.system_state(state)
                }
            }
        }
    };
}

robot!(ur5, Ur5, 6, 6, 6);
robot!(panda, Panda, 9, 9, 9);
robot!(solo12, Solo12, 13, 19, 18);

/// Every robot's wrappers kept; their number.
pub fn keep() -> usize {
    ur5::keep() + panda::keep() + solo12::keep()
}
