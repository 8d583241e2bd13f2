//! Two robots read from their files with contacts (`#[contact]`), in
//! relative coordinates: an RK4 step holding every contact, the constrained
//! dynamics and their exact derivatives, a constrained Euler step with its
//! Jacobian, and an impact's, each with the
//! active set a run-time argument. The floating Solo12 from its URDF file on
//! its four feet (points in the world's axes), the UR5 from its URDF file
//! with its tool welded to the world (a frame in its own axes); and the
//! Panda from its MJCF file with its fingers coupled softly (MuJoCo's
//! `<equality joint>`): its step, dynamics and their derivatives. Each
//! projected RK4 step's exact Jacobian: on the feet and the weld (velocities
//! only), and on a hard four-bar from its MJCF file (a loop with a position).

use joint_runtime::Scene;
use joint_runtime::dynamics::{NoLoads, Simulate, StepReport};
use joint_runtime::nalgebra::SVector;
use joint_runtime::relative::{
    ActiveRows, ConstrainedDerivatives, ImpulseDerivatives, InverseDerivatives, StepJacobian, StepWork, TreeError,
    TreeState,
};

/// ODRI's Solo12 on a floating base (URDF), on its four feet.
#[derive(Scene)]
#[scene(urdf = "../../tests/data/robots/solo12.urdf", floating_base)]
#[contact(fl = point(FL_FOOT); fr = point(FR_FOOT); hl = point(HL_FOOT); hr = point(HR_FOOT))]
pub struct SoloFeet;

/// Universal Robots' UR5 (URDF), its tool welded to the world.
#[derive(Scene)]
#[scene(urdf = "../../tests/data/robots/ur5.urdf")]
#[contact(weld = frame(tool0), axes = local)]
pub struct Ur5Weld;

/// A robot's checked functions, by its scene and sizes.
macro_rules! contacts {
    ($module:ident, $scene:ty, $nq:literal, $nv:literal, $nc:literal) => {
        pub mod $module {
            use super::*;

            type Sim<'a> = <$scene as Simulate<'a, NoLoads>>::Engine;
            type State = TreeState<$nq, $nv>;
            type Tau = SVector<f64, $nv>;

            checked! {
                fn step(sim: &mut Sim<'_>, state: &mut State, h: f64) -> Result<StepReport, TreeError> {
                    sim.step(state, h)
                }
                fn constrained_dynamics(sim: &Sim<'_>, state: &State, tau: &Tau, active: u64, out: &mut ConstrainedDerivatives<$nv, $nc>) -> Result<(), TreeError> {
                    sim.constrained_dynamics(state, tau, ActiveRows(active), out)
                }
                fn constrained_dynamics_derivatives(sim: &Sim<'_>, state: &State, tau: &Tau, active: u64, work: &mut InverseDerivatives<$nv>, out: &mut ConstrainedDerivatives<$nv, $nc>) -> Result<(), TreeError> {
                    sim.constrained_dynamics_derivatives(state, tau, ActiveRows(active), work, out)
                }
                fn constrained_euler_step_jacobian(sim: &Sim<'_>, state: &mut State, step: (f64, u64), tau: &Tau, work: &mut InverseDerivatives<$nv>, dynamics: &mut ConstrainedDerivatives<$nv, $nc>, out: &mut StepJacobian<$nv>) -> Result<(), TreeError> {
                    // The step's length and active set in one argument: seven at most.
                    let (h, active) = step;
                    sim.constrained_euler_step_jacobian(state, h, tau, ActiveRows(active), work, dynamics, out)
                }
                fn rk4_step_jacobian(sim: &Sim<'_>, state: &mut State, h: f64, tau: &Tau, work: &mut StepWork<$nq, $nv>, out: &mut StepJacobian<$nv>) -> Result<(), TreeError> {
                    // Projected: the feet's (or the tool's) velocities at the end.
                    sim.rk4_step_jacobian(state, h, tau, work, out)
                }
                fn impact_derivatives(sim: &Sim<'_>, state: &State, active: u64, restitution: f64, work: &mut InverseDerivatives<$nv>, out: &mut ImpulseDerivatives<$nv, $nc>) -> Result<(), TreeError> {
                    sim.impact_derivatives(state, ActiveRows(active), restitution, work, out)
                }
            }
        }
    };
}

contacts!(solo12, SoloFeet, 19, 18, 12);
contacts!(ur5, Ur5Weld, 6, 6, 6);

/// The Panda from its MJCF file with its fingers coupled softly, as MuJoCo
/// makes an `<equality joint>`.
#[derive(Scene)]
#[scene(mjcf = "../../tests/data/mjcf/panda_fingers.xml")]
pub struct PandaFingers;

/// A soft equality's step, dynamics and exact derivatives.
pub mod soft {
    use super::*;
    use joint_runtime::relative::ForwardDerivatives;

    type Sim<'a> = <PandaFingers as Simulate<'a, NoLoads>>::Engine;
    type State = TreeState<9, 9>;
    type Tau = SVector<f64, 9>;

    checked! {
        fn step(sim: &mut Sim<'_>, state: &mut State, h: f64) -> Result<StepReport, TreeError> {
            sim.step(state, h)
        }
        fn forward_dynamics(sim: &mut Sim<'_>, state: &State, tau: &Tau) -> Result<Tau, TreeError> {
            sim.forward_dynamics(state, tau)
        }
        fn forward_dynamics_derivatives(sim: &Sim<'_>, state: &State, tau: &Tau, work: &mut InverseDerivatives<9>, out: &mut ForwardDerivatives<9>) -> Result<(), TreeError> {
            sim.forward_dynamics_derivatives(state, tau, work, out)
        }
    }
}

/// A planar four-bar from its MJCF file, its `connect` held exactly
/// (`equality = hard`): a loop with a position, and a redundant row.
#[derive(Scene)]
#[scene(mjcf = "../../tests/data/mjcf/four_bar.xml", equality = hard)]
pub struct HardFourBar;

/// A loop with a position: its step and assembly (simplified Newton on Φ),
/// its constrained dynamics and their derivatives (a planar loop's two
/// rows), and the projected RK4 step's exact Jacobian.
pub mod four_bar {
    use super::*;

    type Sim<'a> = <HardFourBar as Simulate<'a, NoLoads>>::Engine;
    type State = TreeState<3, 3>;
    type Tau = SVector<f64, 3>;

    checked! {
        fn rk4_step_jacobian(sim: &Sim<'_>, state: &mut State, h: f64, tau: &Tau, work: &mut StepWork<3, 3>, out: &mut StepJacobian<3>) -> Result<(), TreeError> {
            sim.rk4_step_jacobian(state, h, tau, work, out)
        }
        fn constrained_dynamics(sim: &Sim<'_>, state: &State, tau: &Tau, active: u64, out: &mut ConstrainedDerivatives<3, 2>) -> Result<(), TreeError> {
            sim.constrained_dynamics(state, tau, ActiveRows(active), out)
        }
        fn assemble(sim: &Sim<'_>, state: &State) -> Result<State, TreeError> {
            sim.assemble(state)
        }
        fn step(sim: &mut Sim<'_>, state: &mut State, h: f64) -> Result<StepReport, TreeError> {
            sim.step(state, h)
        }
        fn constrained_dynamics_derivatives(sim: &Sim<'_>, state: &State, tau: &Tau, active: u64, work: &mut InverseDerivatives<3>, out: &mut ConstrainedDerivatives<3, 2>) -> Result<(), TreeError> {
            sim.constrained_dynamics_derivatives(state, tau, ActiveRows(active), work, out)
        }
    }
}

/// Every robot's wrappers kept; their number.
pub fn keep() -> usize {
    solo12::keep() + ur5::keep() + soft::keep() + four_bar::keep()
}
