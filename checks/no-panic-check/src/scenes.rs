//! The double Cardan shaft of `joint_examples::double_cardan` (three bodies): the
//! derived system functions, the kinematic analyses and the dynamics, at their
//! fixed sizes.
//!
//! - [`driven`]: `DoubleCardan`, four joints and a motor, 19 rows of which one is
//!   redundant (`Scene<3, 18, 19>`), derived with `second_order`: the
//!   analyses, and on `Simulation` `step` with every integrator (the exact
//!   Newton matrices with a redundant row held), `dynamics`, `project`,
//!   `reactions`, `energy`.
//! - [`free`]: `FreeDoubleCardan`, no motor, 18 rows, one degree of freedom
//!   (`Scene<3, 18, 18>`), the scene of `examples/examples/step_bench.rs`,
//!   derived with `second_order`: its system functions and analyses.
//! - [`block`]: the free shaft on the one `Simulation` (the block factor and
//!   the saddle-point matrices): `step` with every integrator (RK4, the
//!   implicit midpoint rule, generalised-α, Radau IIA: the integrator is an
//!   argument), `integrate` with every method, `dynamics`, `project`,
//!   `reactions`, `energy`.
//!
//! A step never builds a workspace (`new` and `Simulation::prepare` do), so
//! none of this allocates. `Simulation::new` is not checked: with `alloc` it
//! boxes its workspaces, and `Box::new`'s out-of-memory path counts as a panic
//! (a lone `Box::new([0u64; 4])` fails the check too).
//!
//! Every branch the options select at run time (integrator, stabilisation,
//! projection, springs) is part of the checked code: the options are arguments.

use joint_runtime::analysis::{
    AccelerationAnalysis, Analyses, AnalysisError, Assembly, AssemblyOptions, VelocityAnalysis,
};
use joint_runtime::dynamics::{AbsoluteSimulation, AppliedLoads, Dynamics, Energy, Integrator, Loads, Reaction};
use joint_runtime::dynamics::{Adaptive, IntegrationReport, StepReport, Tolerance};
use joint_runtime::nalgebra::{SMatrix, SVector, Vector3};
use joint_runtime::{Evaluation, RowBlock, Scene, SecondOrder, SparseJacobian, SystemState};

/// Applied loads of the checked simulations: a torque on the input shaft and a
/// force at a point of the output shaft (through `Loads::add_force_at`).
pub struct Push;

impl AppliedLoads<3> for Push {
    fn apply(&mut self, state: &SystemState<3>, loads: &mut Loads<3>) {
        loads.torque[0].x += 0.5;
        loads.add_force_at(state, 2, &Vector3::new(0.0, 0.0, -1.0), &Vector3::new(0.5, 0.0, 0.0));
    }
}

/// The driven shaft, `Scene<3, 18, 19>`.
pub mod driven {
    use super::*;
    use joint_examples::double_cardan::DoubleCardan;

    type Sim<'a> = AbsoluteSimulation<'a, DoubleCardan, Push, 3, 18, 19, 62>;
    type Kinematics<'a> = Analyses<'a, DoubleCardan, 3, 18, 19, 62>;

    checked! {
        fn phi(scene: &DoubleCardan, state: &SystemState<3>) -> SVector<f64, 19> { scene.phi(state) }
        fn phi_t(scene: &DoubleCardan, state: &SystemState<3>) -> SVector<f64, 19> { scene.phi_t(state) }
        fn jacobian(scene: &DoubleCardan, state: &SystemState<3>) -> SMatrix<f64, 19, 18> { scene.jacobian(state) }
        fn gamma(scene: &DoubleCardan, state: &SystemState<3>) -> SVector<f64, 19> { scene.gamma(state) }
        fn evaluate(scene: &DoubleCardan, state: &SystemState<3>) -> Evaluation<f64, 19, 18> { scene.evaluate(state) }
        fn jacobian_values(scene: &DoubleCardan, state: &SystemState<3>) -> [f64; 62] { scene.jacobian_values(state) }
        fn assemble(
            analyses: &mut Kinematics<'_>,
            state: &mut SystemState<3>,
            options: &AssemblyOptions,
        ) -> Result<Assembly<19>, AnalysisError> {
            analyses.assemble(state, options)
        }
        fn velocities(
            analyses: &mut Kinematics<'_>,
            state: &mut SystemState<3>,
            tolerance: f64,
        ) -> Result<VelocityAnalysis<19>, AnalysisError> {
            analyses.rank_tolerance = tolerance;
            analyses.velocities(state)
        }
        fn accelerations(
            analyses: &mut Kinematics<'_>,
            state: &SystemState<3>,
            tolerance: f64,
        ) -> Result<AccelerationAnalysis<18, 19>, AnalysisError> {
            analyses.rank_tolerance = tolerance;
            analyses.accelerations(state)
        }
        fn step(
            sim: &mut Sim<'_>,
            state: &mut SystemState<3>,
            h: f64,
            integrator: Integrator,
        ) -> Result<StepReport, AnalysisError> {
            sim.options.integrator = integrator;
            sim.step(state, h)
        }
        fn dynamics(sim: &mut Sim<'_>, state: &SystemState<3>) -> Result<Dynamics<18, 19>, AnalysisError> {
            sim.dynamics(state)
        }
        fn project(
            sim: &mut Sim<'_>,
            state: &mut SystemState<3>,
            options: &AssemblyOptions,
        ) -> Result<(usize, f64, f64), AnalysisError> {
            sim.project(state, options)
        }
        fn reactions(
            sim: &Sim<'_>,
            state: &SystemState<3>,
            lambda: &SVector<f64, 19>,
            block: &RowBlock,
        ) -> [Reaction; 3] {
            sim.reactions(state, lambda, block)
        }
        fn energy(sim: &Sim<'_>, state: &SystemState<3>) -> Energy { sim.energy(state) }
    }
}

/// The free shaft, `Scene<3, 18, 18>`.
pub mod free {
    use super::*;
    use joint_examples::double_cardan::FreeDoubleCardan;

    type Kinematics<'a> = Analyses<'a, FreeDoubleCardan, 3, 18, 18, 60>;

    checked! {
        fn phi(scene: &FreeDoubleCardan, state: &SystemState<3>) -> SVector<f64, 18> { scene.phi(state) }
        fn jacobian(scene: &FreeDoubleCardan, state: &SystemState<3>) -> SMatrix<f64, 18, 18> { scene.jacobian(state) }
        fn gamma(scene: &FreeDoubleCardan, state: &SystemState<3>) -> SVector<f64, 18> { scene.gamma(state) }
        fn evaluate(scene: &FreeDoubleCardan, state: &SystemState<3>) -> Evaluation<f64, 18, 18> {
            scene.evaluate(state)
        }
        fn assemble(
            analyses: &mut Kinematics<'_>,
            state: &mut SystemState<3>,
            options: &AssemblyOptions,
        ) -> Result<Assembly<18>, AnalysisError> {
            analyses.assemble(state, options)
        }
        fn accelerations(
            analyses: &mut Kinematics<'_>,
            state: &SystemState<3>,
        ) -> Result<AccelerationAnalysis<18, 18>, AnalysisError> {
            analyses.accelerations(state)
        }
        fn second_order(
            scene: &FreeDoubleCardan,
            state: &SystemState<3>,
            lambda: &SVector<f64, 18>,
            u: &SVector<f64, 18>,
        ) -> Option<SecondOrder<f64, 18, 18>> {
            scene.second_order(state, lambda, u)
        }
    }
}

/// The free shaft on [`AbsoluteSimulation`], the one `Simulation`'s absolute engine
/// (the block factor of `J M⁻¹ Jᵀ`, the implicit integrators' saddle-point
/// matrices): the integrator and the adaptive method are arguments, so every
/// one of their branches is part of the checked code.
pub mod block {
    use super::*;
    use joint_examples::double_cardan::FreeDoubleCardan;

    type Sim<'a> = AbsoluteSimulation<'a, FreeDoubleCardan, Push, 3, 18, 18, 60>;

    checked! {
        fn step(
            sim: &mut Sim<'_>,
            state: &mut SystemState<3>,
            h: f64,
            integrator: Integrator,
        ) -> Result<StepReport, AnalysisError> {
            sim.options.integrator = integrator;
            sim.step(state, h)
        }
        fn dynamics(sim: &mut Sim<'_>, state: &SystemState<3>) -> Result<Dynamics<18, 18>, AnalysisError> {
            sim.dynamics(state)
        }
        fn project(
            sim: &mut Sim<'_>,
            state: &mut SystemState<3>,
            options: &AssemblyOptions,
        ) -> Result<(usize, f64, f64), AnalysisError> {
            sim.project(state, options)
        }
        fn reactions(
            sim: &Sim<'_>,
            state: &SystemState<3>,
            lambda: &SVector<f64, 18>,
            block: &RowBlock,
        ) -> [Reaction; 3] {
            sim.reactions(state, lambda, block)
        }
        fn energy(sim: &Sim<'_>, state: &SystemState<3>) -> Energy { sim.energy(state) }
        fn integrate(
            sim: &mut Sim<'_>,
            state: &mut SystemState<3>,
            t_end: f64,
            method: Adaptive,
            tolerance: Tolerance,
        ) -> Result<IntegrationReport, AnalysisError> {
            sim.integrate(state, t_end, method, tolerance)
        }
    }
}
