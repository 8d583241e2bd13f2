//! A robot arm in relative coordinates (`coordinates = relative`,
//! `second_order`): the exact derivatives of its dynamics and one step's
//! exact Jacobian, what a controller calls every tick, at their fixed sizes.
//! Written with every joint a hinge, so that the step Jacobians run (a
//! quaternion tree refuses them with an error, which is not a panic either).

use joint_runtime::Scene;
use joint_runtime::nalgebra::SVector;
use joint_runtime::relative::{
    ForceGains, ForwardDerivatives, InverseDerivatives, StepJacobian, StepWork, TreeError, TreeSimulation, TreeState,
};

/// Three links on hinges about `y`, `x`, `y`, damped.
#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], coordinates = relative, second_order)]
#[body(base, mass = 2.0, inertia = [0.02, 0.03, 0.02])]
#[body(upper, mass = 1.0, inertia = [0.001, 0.0833, 0.0833])]
#[body(lower, mass = 0.5, inertia = [0.0005, 0.04, 0.04])]
#[joint(turn = revolute(ground, base), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0, 0, 0.1], rho2 = [0, 0, -0.1])]
#[joint(shoulder = revolute(base, upper), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0, 0, 0.1], rho2 = [-0.5, 0, 0], damping = 0.1)]
#[joint(elbow = revolute(upper, lower), axis1 = [1, 0.2, 0], axis2 = [1, 0.2, 0], rho1 = [0.5, 0, 0], rho2 = [-0.5, 0, 0], armature = 0.01)]
pub struct Arm;

/// The same arm without `second_order`: its derivatives by the runtime's
/// recursion.
#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], coordinates = relative)]
#[body(base, mass = 2.0, inertia = [0.02, 0.03, 0.02])]
#[body(upper, mass = 1.0, inertia = [0.001, 0.0833, 0.0833])]
#[body(lower, mass = 0.5, inertia = [0.0005, 0.04, 0.04])]
#[joint(turn = revolute(ground, base), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0, 0, 0.1], rho2 = [0, 0, -0.1])]
#[joint(shoulder = revolute(base, upper), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0, 0, 0.1], rho2 = [-0.5, 0, 0], damping = 0.1)]
#[joint(elbow = revolute(upper, lower), axis1 = [1, 0.2, 0], axis2 = [1, 0.2, 0], rho1 = [0.5, 0, 0], rho2 = [-0.5, 0, 0], armature = 0.01)]
pub struct RecursionArm;

type Sim<'a> = TreeSimulation<'a, Arm, 3, 3, 3>;
type RecursionSim<'a> = TreeSimulation<'a, RecursionArm, 3, 3, 3>;
type State = TreeState<3, 3>;

checked! {
    fn inverse_derivatives(sim: &Sim<'_>, state: &State, vdot: &SVector<f64, 3>, out: &mut InverseDerivatives<3>) -> Result<(), TreeError> {
        sim.inverse_dynamics_derivatives(state, vdot, out)
    }
    fn forward_derivatives(
        sim: &Sim<'_>,
        state: &State,
        tau: &SVector<f64, 3>,
        work: &mut InverseDerivatives<3>,
        out: &mut ForwardDerivatives<3>,
    ) -> Result<(), TreeError> {
        sim.forward_dynamics_derivatives(state, tau, work, out)
    }
    fn inverse_derivatives_by_recursion(
        sim: &RecursionSim<'_>,
        state: &State,
        vdot: &SVector<f64, 3>,
        out: &mut InverseDerivatives<3>,
    ) -> Result<(), TreeError> {
        sim.inverse_dynamics_derivatives(state, vdot, out)
    }
    fn implicit_step(
        sim: &Sim<'_>,
        state: &mut State,
        h: f64,
        tau: &SVector<f64, 3>,
        gains: &ForceGains<3>,
        work: &mut StepWork<3, 3>,
    ) -> Result<(), TreeError> {
        sim.implicit_step_with(state, h, tau, gains, work)
    }
    fn rk4_step_jacobian(
        sim: &Sim<'_>,
        state: &mut State,
        h: f64,
        tau: &SVector<f64, 3>,
        work: &mut StepWork<3, 3>,
        out: &mut StepJacobian<3>,
    ) -> Result<(), TreeError> {
        sim.rk4_step_jacobian(state, h, tau, work, out)
    }
    fn euler_step_jacobian(
        sim: &Sim<'_>,
        state: &mut State,
        h: f64,
        tau: &SVector<f64, 3>,
        work: &mut StepWork<3, 3>,
        out: &mut StepJacobian<3>,
    ) -> Result<(), TreeError> {
        sim.euler_step_jacobian(state, h, tau, work, out)
    }
}
