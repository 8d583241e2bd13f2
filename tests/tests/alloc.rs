//! Generated code, batches and a fixed-size scene step allocate nothing: counted by a
//! global allocator around the calls.
//!
//! The counter is thread-local: the tests run in parallel threads, each
//! counting its own. `unsafe` is allowed here only, for `GlobalAlloc`; the
//! package denies it everywhere else.

#![allow(unsafe_code, missing_docs)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

use joint_runtime::analysis::{Analyses, AssemblyOptions};
use joint_runtime::batch::{WideF64x4, evaluate_batch, evaluate_batch_simd, splat};
use joint_runtime::dynamics::{Adaptive, Integrator, Loads, NoLoads, Simulation, SimulationOptions, Tolerance};
use joint_runtime::nalgebra::{SVector, UnitQuaternion, Vector3};
use joint_runtime::relative::{
    ForceGains, ForwardDerivatives, InverseDerivatives, StepJacobian, StepWork, TreeSimulation,
};
use joint_runtime::{Joint, OmegaBody, Ramp, Scene, SparseJacobian, SystemState, TwoBodies};

/// A double pendulum in relative coordinates with its derivatives.
#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], coordinates = relative, second_order)]
#[body(upper, mass = 1.0, inertia = [0.001, 0.0833, 0.0833])]
#[body(lower, mass = 1.0, inertia = [0.001, 0.0833, 0.0833])]
#[joint(shoulder = revolute(ground, upper), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0, 0, 0], rho2 = [-0.5, 0, 0])]
#[joint(elbow = revolute(upper, lower), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0.5, 0, 0], rho2 = [-0.5, 0, 0])]
struct Pendulum;

/// The same without `second_order`: its derivatives by the runtime's recursion.
#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], coordinates = relative)]
#[body(upper, mass = 1.0, inertia = [0.001, 0.0833, 0.0833])]
#[body(lower, mass = 1.0, inertia = [0.001, 0.0833, 0.0833])]
#[joint(shoulder = revolute(ground, upper), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0, 0, 0], rho2 = [-0.5, 0, 0])]
#[joint(elbow = revolute(upper, lower), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0.5, 0, 0], rho2 = [-0.5, 0, 0])]
struct RecursionPendulum;

thread_local! {
    static COUNT: Cell<usize> = const { Cell::new(0) };
}

struct Counting;

// SAFETY: forwards every call to the system allocator unchanged; counting
// touches only a const-initialised thread-local, which does not allocate.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        COUNT.with(|c| c.set(c.get() + 1));
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        COUNT.with(|c| c.set(c.get() + 1));
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

fn allocations(f: impl FnOnce()) -> usize {
    let before = COUNT.with(Cell::get);
    f();
    COUNT.with(Cell::get) - before
}

/// A Cardan joint with its axes along `y` and `z`, points half a unit out.
fn cardan() -> Cardan<f64> {
    Cardan {
        s: Vector3::new(0.0, 1.0, 0.0),
        h: Vector3::new(0.0, 0.0, 1.0),
        rho1: Vector3::new(0.5, 0.0, 0.0),
        rho2: Vector3::new(-0.5, 0.0, 0.0),
    }
}

#[derive(Joint)]
#[joint(universal, formulation = omega_body)]
struct Cardan<T> {
    s: Vector3<T>,
    h: Vector3<T>,
    rho1: Vector3<T>,
    rho2: Vector3<T>,
}

#[derive(Joint)]
#[joint(rotational_driver, formulation = euler, axis1 = [0, 0, 1], axis2 = [0, 0, 1])]
struct Motor<F> {
    theta: F,
}

/// A double pendulum with a driven first hinge and a spring-free second one
/// (with its second-order terms: the implicit integrators' exact matrices).
#[derive(Scene)]
#[scene(coordinates = absolute, gravity = [0, 0, -9.81], second_order)]
#[body(upper, mass = 1.0, inertia = [0.1, 0.1, 0.01])]
#[body(lower, mass = 0.5, inertia = [0.05, 0.05, 0.005])]
#[joint(top = revolute(ground, upper), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0, 0, 0], rho2 = [0, 0, 0.5])]
#[joint(elbow = revolute(upper, lower), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0, 0, -0.5], rho2 = [0, 0, 0.5])]
struct DoublePendulum;

#[test]
fn joints_allocate_nothing() {
    let cardan = cardan();
    let q = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), 0.3);
    let body = |r| OmegaBody::from_rotation(r, &q, Vector3::zeros(), Vector3::new(1.0, 0.2, 0.0));
    let pair = TwoBodies::new(body(Vector3::zeros()), body(Vector3::x()));
    let n = allocations(|| {
        let e = std::hint::black_box(cardan.evaluate(&pair));
        let (p, j, g, t) = (cardan.phi(&pair), cardan.jacobian(&pair), cardan.gamma(&pair), cardan.phi_t(&pair));
        std::hint::black_box((e, p, j, g, t));
    });
    assert_eq!(n, 0, "a joint's generated functions allocated");
    let motor = Motor { theta: Ramp { start: 0.1, rate: 2.0 } };
    let euler = TwoBodies::new(
        joint_runtime::EulerBody {
            r: Vector3::zeros(),
            p: joint_runtime::nalgebra::Vector4::new(1.0, 0.0, 0.0, 0.0),
            rdot: Vector3::zeros(),
            pdot: joint_runtime::nalgebra::Vector4::zeros(),
        },
        joint_runtime::EulerBody {
            r: Vector3::x(),
            p: joint_runtime::nalgebra::Vector4::new(0.9, 0.1, 0.0, 0.3),
            rdot: Vector3::zeros(),
            pdot: joint_runtime::nalgebra::Vector4::new(0.0, 0.1, 0.2, 0.0),
        },
    );
    assert_eq!(
        allocations(|| {
            std::hint::black_box(motor.evaluate(&euler));
        }),
        0,
        "a driver allocated"
    );
}

#[test]
fn batches_allocate_nothing() {
    let cardan = cardan();
    let q = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), 0.3);
    let body = |r| OmegaBody::from_rotation(r, &q, Vector3::zeros(), Vector3::new(1.0, 0.2, 0.0));
    let pair = TwoBodies::new(body(Vector3::zeros()), body(Vector3::x()));
    // Batches into a caller's slice: scalar and SIMD lanes (a padded tail of 3).
    let wide = Cardan::<WideF64x4> {
        s: splat(&cardan.s),
        h: splat(&cardan.h),
        rho1: splat(&cardan.rho1),
        rho2: splat(&cardan.rho2),
    };
    let states = [pair; 7];
    let mut out = [cardan.evaluate(&pair); 7];
    let n = allocations(|| {
        let scalar = evaluate_batch(&cardan, &states, &mut out);
        let lanes = evaluate_batch_simd(&wide, &states, &mut out);
        std::hint::black_box((scalar, lanes)).1.expect("lengths agree");
    });
    assert_eq!(n, 0, "a batch allocated");
    assert_eq!(out[6], cardan.evaluate(&pair));
}

#[test]
fn scene_evaluation_assembly_and_steps_allocate_nothing() {
    // A scene: system functions, assembly, one step of each integrator.
    let scene = DoublePendulum;
    let tilt = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), 0.4);
    let mut state = SystemState {
        bodies: [
            OmegaBody::from_rotation(Vector3::new(0.2, 0.0, -0.45), &tilt, Vector3::zeros(), Vector3::zeros()),
            OmegaBody::from_rotation(Vector3::new(0.5, 0.0, -1.3), &tilt, Vector3::zeros(), Vector3::zeros()),
        ],
        t: 0.0,
    };
    let options = AssemblyOptions::default();
    let push = |_: &SystemState<2>, l: &mut Loads<2>| l.torque[0].y += 0.1;
    // Made for Radau IIA, whose workspaces hold every implicit integrator's:
    // `new` allocates them, then no step of any integrator does.
    let radau = SimulationOptions::default().with_integrator(Integrator::RadauIIA);
    let mut sim = Simulation::new(&scene, push, &[], radau).expect("valid options");
    // Likewise the analyses: `new` boxes their block factor, then none allocates.
    let mut analyses = Analyses::new(&scene).expect("structure");
    let mut reports = None;
    let n = allocations(|| {
        let e = std::hint::black_box(scene.evaluate(&state));
        let sparse = std::hint::black_box(scene.jacobian_values(&state));
        let a = analyses.assemble(&mut state, &options);
        let kinematics = analyses.velocities(&mut state).is_ok() && analyses.accelerations(&state).is_ok();
        sim.options.integrator = Integrator::Rk4;
        let rk4 = sim.step(&mut state, 1e-3);
        sim.options.integrator = Integrator::ImplicitMidpoint;
        let midpoint = sim.step(&mut state, 1e-3);
        sim.options.integrator = Integrator::GeneralisedAlpha;
        let alpha = sim.step(&mut state, 1e-3).is_ok() && sim.step(&mut state, 1e-3).is_ok();
        sim.options.integrator = Integrator::RadauIIA;
        let radau = sim.step(&mut state, 1e-3).is_ok() && sim.step(&mut state, 1e-3).is_ok();
        let t = state.t + 0.01;
        let tolerance = Tolerance { rtol: 1e-6, atol: 1e-6 };
        let adaptive = sim.integrate(&mut state, t, Adaptive::DormandPrince, tolerance).is_ok()
            && sim.integrate(&mut state, t + 0.01, Adaptive::GeneralisedAlpha, tolerance).is_ok()
            && sim.integrate(&mut state, t + 0.02, Adaptive::RadauIIA, tolerance).is_ok();
        let steps = kinematics && rk4.is_ok() && midpoint.is_ok() && alpha && radau && adaptive;
        reports = Some((e.phi.len(), sparse.len(), a.map(|a| a.iterations), steps));
    });
    assert_eq!(n, 0, "a scene evaluation, assembly or step allocated");
    let (rows, nnz, iterations, steps) = reports.expect("ran");
    assert_eq!(rows, 10);
    assert!(nnz > 0 && iterations.expect("assembled") > 0 && steps);
    // Made for generalised-α: its workspace (shared by the midpoint rule)
    // allocated in `new`, then no step or `integrate` allocates.
    let options = SimulationOptions::default().with_integrator(Integrator::GeneralisedAlpha);
    let mut alpha_sim = Simulation::new(&scene, NoLoads, &[], options).expect("valid options");
    let mut ok = false;
    let n = allocations(|| {
        let alpha = alpha_sim.step(&mut state, 1e-3).is_ok();
        alpha_sim.options.integrator = Integrator::ImplicitMidpoint;
        let midpoint = alpha_sim.step(&mut state, 1e-3).is_ok();
        alpha_sim.options.integrator = Integrator::Rk4;
        let rk4 = alpha_sim.step(&mut state, 1e-3).is_ok();
        let t = state.t + 0.01;
        let tolerance = Tolerance { rtol: 1e-6, atol: 1e-6 };
        let adaptive = alpha_sim.integrate(&mut state, t, Adaptive::DormandPrince, tolerance).is_ok()
            && alpha_sim.integrate(&mut state, t + 0.01, Adaptive::GeneralisedAlpha, tolerance).is_ok();
        ok = alpha && midpoint && rk4 && adaptive;
    });
    assert_eq!(n, 0, "a step or integrate allocated");
    assert!(ok, "the steps ran");
}

#[test]
fn tree_derivatives_and_step_jacobians_allocate_nothing() {
    // A tree's exact derivatives and step Jacobians: fixed-size outputs,
    // nothing allocated per call.
    let tree = TreeSimulation::new(&Pendulum).expect("a valid tree");
    let mut start: PendulumTreeState = tree.tree().zero_state();
    start.q[0] = 0.3;
    start.v[1] = -0.7;
    let tau = SVector::from([0.1, -0.2]);
    let (mut inverse, mut forward) = (InverseDerivatives::zeros(), ForwardDerivatives::zeros());
    let (mut work, mut jacobian) = (StepWork::new(), StepJacobian::zeros());
    let mut ok = false;
    let n = allocations(|| {
        let a = tree.inverse_dynamics_derivatives(&start, &tau, &mut inverse).is_ok();
        let b = tree.forward_dynamics_derivatives(&start, &tau, &mut inverse, &mut forward).is_ok();
        let mut end = start;
        let c = tree.rk4_step_jacobian(&mut end, 1e-3, &tau, &mut work, &mut jacobian).is_ok();
        let d = tree.euler_step_jacobian(&mut end, 1e-3, &tau, &mut work, &mut jacobian).is_ok();
        ok = a && b && c && d;
    });
    assert_eq!(n, 0, "a tree's derivatives allocated");
    assert!(ok, "the derivatives ran");
    let recursion = TreeSimulation::new(&RecursionPendulum).expect("a valid tree");
    let n = allocations(|| {
        let a = recursion.inverse_dynamics_derivatives(&start, &tau, &mut inverse).is_ok();
        let b = recursion.forward_dynamics_derivatives(&start, &tau, &mut inverse, &mut forward).is_ok();
        let mut end = start;
        let c = recursion.rk4_step_jacobian(&mut end, 1e-3, &tau, &mut work, &mut jacobian).is_ok();
        let gains = ForceGains::pd(&SVector::repeat(1e4), &SVector::repeat(1e2));
        let d = recursion.implicit_step_with(&mut end, 1e-3, &tau, &gains, &mut work).is_ok();
        ok = a && b && c && d;
    });
    assert_eq!(n, 0, "the recursion's derivatives allocated");
    assert!(ok, "the recursion's derivatives ran");
}

/// The floating Solo12 from its MJCF file: a free joint's quaternion and
/// twelve hinges, in relative coordinates.
#[derive(Scene)]
#[scene(mjcf = "data/robots/solo12_floating.xml")]
struct Solo12;

#[test]
fn a_robots_step_dynamics_mass_matrix_and_frames_allocate_nothing() {
    let mut sim = Simulation::new(&Solo12, NoLoads, &[], SimulationOptions::default()).expect("a valid robot");
    let mut state = sim.tree().zero_state();
    state.q[2] = 0.3;
    for (k, x) in state.v.iter_mut().enumerate() {
        *x = 0.1 * (k as f64).sin();
    }
    let tau = SVector::<f64, 18>::from_fn(|k, _| 0.2 * (k as f64).cos());
    let mut m = joint_runtime::nalgebra::SMatrix::<f64, 18, 18>::zeros();
    let (start, mut out) = (state, None);
    let n = allocations(|| {
        let vdot = sim.forward_dynamics(&state, &tau).expect("dynamics");
        let back = sim.inverse_dynamics(&state, &vdot);
        sim.mass_matrix_into(&state.q, &mut m);
        let frames = sim.system_state(&state);
        let steps = (0..3).all(|_| sim.step_with(&mut state, 1e-3, &tau).is_ok());
        out = Some(((back - tau).amax(), frames, steps));
    });
    assert_eq!(n, 0, "the relative engine allocated");
    let (inverse, frames, steps) = out.expect("ran");
    // Inverse after forward dynamics gives the forces back; the frames give
    // the joints' state back; M is symmetric.
    assert!(inverse < 1e-9 && steps, "inverse dynamics off by {inverse}");
    let again = sim.state_of(&frames).expect("on its joints");
    assert!((again.q - start.q).amax() < 1e-12 && (again.v - start.v).amax() < 1e-12);
    assert!((m - m.transpose()).amax() < 1e-12 && m[(0, 0)] > 0.0);
}

/// The floating Solo12 from its URDF file on its four feet.
#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], urdf = "data/robots/solo12.urdf", floating_base)]
#[contact(fl = point(FL_FOOT); fr = point(FR_FOOT); hl = point(HL_FOOT); hr = point(HR_FOOT))]
struct SoloFeet;

#[test]
fn constrained_dynamics_derivatives_and_impacts_allocate_nothing() {
    use joint_runtime::relative::{
        ActiveRows, ConstrainedDerivatives, ImpulseDerivatives, InverseDerivatives, StepJacobian, StepWork,
        TreeSimulation,
    };
    let mut sim = TreeSimulation::new(&SoloFeet).expect("a valid robot");
    let mut state = sim.tree().zero_state();
    state.q[2] = 0.3;
    for (k, x) in state.v.iter_mut().enumerate() {
        *x = 0.1 * (k as f64).sin();
    }
    let tau = SVector::<f64, 18>::from_fn(|k, _| 0.2 * (k as f64).cos());
    let (mut work, mut out, mut hit) =
        (InverseDerivatives::zeros(), ConstrainedDerivatives::zeros(), ImpulseDerivatives::zeros());
    let three = ActiveRows::all().without(3);
    let (mut done, mut jacobian, mut node) = (false, StepJacobian::zeros(), state);
    let (mut steps, mut stepped) = (Box::new(StepWork::new()), state);
    let n = allocations(|| {
        done = sim.constrained_dynamics(&state, &tau, three, &mut out).is_ok()
            && sim.rk4_step_jacobian(&mut stepped, 1e-3, &tau, &mut steps, &mut jacobian).is_ok()
            && sim
                .constrained_euler_step_jacobian(&mut node, 1e-3, &tau, three, &mut work, &mut out, &mut jacobian)
                .is_ok()
            && sim.constrained_dynamics_derivatives(&state, &tau, three, &mut work, &mut out).is_ok()
            && sim.impact_derivatives(&state, ActiveRows::all(), 0.5, &mut work, &mut hit).is_ok()
            && (0..3).all(|_| sim.step(&mut state, 1e-3).is_ok());
    });
    assert_eq!(n, 0, "the constrained dynamics allocated");
    assert!(done && out.rank == 9 && out.lambda.rows(9, 3).iter().all(|x| *x == 0.0));
}

/// The Panda with its fingers coupled softly, as MuJoCo makes a file's
/// `<equality joint>`.
#[derive(Scene)]
#[scene(mjcf = "data/mjcf/panda_fingers.xml")]
struct PandaFingers;

#[test]
fn soft_equalities_allocate_nothing() {
    use joint_runtime::relative::{ForwardDerivatives, InverseDerivatives, TreeSimulation};
    let (mut work, mut out) = (InverseDerivatives::zeros(), ForwardDerivatives::zeros());
    let mut done = false;
    let n = allocations(|| {
        let Ok(mut sim) = TreeSimulation::new(&PandaFingers) else { return };
        let mut state = sim.tree().zero_state();
        state.q[7] = 0.001;
        let tau = SVector::<f64, 9>::from_fn(|k, _| 0.2 * (k as f64).cos());
        done = sim.forward_dynamics(&state, &tau).is_ok()
            && sim.forward_dynamics_derivatives(&state, &tau, &mut work, &mut out).is_ok()
            && (0..3).all(|_| sim.step(&mut state, 1e-3).is_ok());
    });
    assert_eq!(n, 0, "the soft equalities allocated");
    assert!(done && out.d_q[(7, 7)] < 0.0);
}

/// A planar four-bar from its MJCF file, its `connect` held exactly.
#[derive(Scene)]
#[scene(mjcf = "data/mjcf/four_bar.xml", equality = hard)]
struct HardFourBar;

#[test]
fn the_projected_step_jacobian_on_a_loop_allocates_nothing() {
    use joint_runtime::relative::{StepJacobian, StepWork, TreeSimulation};
    let sim = TreeSimulation::new(&HardFourBar).expect("a valid mechanism");
    let (mut work, mut jacobian) = (StepWork::new(), StepJacobian::zeros());
    let mut state = sim.tree().zero_state();
    let mut done = false;
    let n = allocations(|| {
        done = (0..3)
            .all(|_| sim.rk4_step_jacobian(&mut state, 1e-2, &SVector::zeros(), &mut work, &mut jacobian).is_ok());
    });
    assert_eq!(n, 0, "the projected step Jacobian allocated");
    // The implicit rules and Radau IIA on the loop, their Newton matrix exact.
    for integrator in [Integrator::ImplicitMidpoint, Integrator::GeneralisedAlpha, Integrator::RadauIIA] {
        let options = SimulationOptions::default().with_integrator(integrator);
        let mut sim =
            TreeSimulation::new(&HardFourBar).expect("a valid mechanism").with_options(options).expect("offered");
        let (mut stepped, mut iterations) = (sim.tree().zero_state(), 0);
        let n = allocations(|| {
            for _ in 0..3 {
                iterations += sim.step(&mut stepped, 1e-2).map_or(0, |r| r.newton_iterations);
            }
        });
        assert_eq!(n, 0, "the {integrator:?} step allocated");
        assert!(iterations >= 3 && stepped.t > 0.02);
    }
    // Error-controlled steps by the three methods.
    let mut sim = TreeSimulation::new(&HardFourBar).expect("a valid mechanism");
    let (mut stepped, tolerance) = (sim.tree().zero_state(), Tolerance { rtol: 1e-6, atol: 1e-6 });
    let mut integrated = false;
    let n = allocations(|| {
        integrated = [(Adaptive::DormandPrince, 0.05), (Adaptive::RadauIIA, 0.1), (Adaptive::GeneralisedAlpha, 0.15)]
            .into_iter()
            .all(|(method, t)| sim.integrate(&mut stepped, t, method, tolerance).is_ok());
    });
    assert_eq!(n, 0, "error-controlled steps allocated");
    assert!(integrated && stepped.t == 0.15);
    // Gravity moves the loop, and the end moves with the start's velocity.
    assert!(done && jacobian.q_v[(0, 0)].abs() > 1e-4 && state.v.amax() > 0.0);
}

#[test]
fn the_counter_counts() {
    // The counter counts: a vector allocates.
    assert!(allocations(|| drop(std::hint::black_box(vec![1u8; 64]))) >= 1);
}
