//! A `#![no_std]` static library built on `joint-runtime` without default
//! features: the proof that embedded users get what the README promises.
//!
//! ```text
//! cargo build --manifest-path checks/no-std-check/Cargo.toml             # must succeed
//! cargo build --manifest-path checks/no-std-check/Cargo.toml --features std  # must fail (E0152)
//! ```
//!
//! Building `joint-runtime` alone with `--no-default-features` on a host target
//! cannot tell whether a dependency still links `std` (the host has it). Here the
//! library defines its own `#[panic_handler]`: if anything in the crate graph
//! brought `std`, its `panic_impl` would clash with ours and the build would fail
//! with "found duplicate lang item `panic_impl`". The second command switches
//! `std` on to show that the check can fail. `.ci/run` runs both.
//!
//! The exported functions use a derived joint (f64 and f32), a SIMD batch, a
//! derived scene, the kinematic analyses, RK4 steps and the implicit integrators' steps, so
//! all of them are compiled and linked without `std` and without an
//! allocator.

#![no_std]

use core::panic::PanicInfo;

use joint_runtime::analysis::{Analyses, AssemblyOptions};
use joint_runtime::batch::{WideF32x8, evaluate_batch_simd, splat};
use joint_runtime::dynamics::{Integrator, NoLoads, Simulation, SimulationOptions};
use joint_runtime::nalgebra::{UnitQuaternion, Vector3};
use joint_runtime::{Joint, OmegaBody, Scene, SystemState, TwoBodies};

/// A Cardan joint with run-time yokes and offsets.
#[derive(Joint)]
#[joint(universal, formulation = omega_body)]
struct Cardan<T> {
    s: Vector3<T>,
    h: Vector3<T>,
    rho1: Vector3<T>,
    rho2: Vector3<T>,
}

/// A link hinged at the origin about y.
#[derive(Scene)]
#[scene(coordinates = absolute, gravity = [0, 0, -9.81])]
#[body(link, mass = 1.0, inertia = [0.0833, 0.0833, 0.001])]
#[joint(hinge = revolute(ground, link), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0, 0, 0], rho2 = [0, 0, 0.5])]
struct Pendulum;

/// Two links on hinges, in relative coordinates: the robots' engine.
#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], coordinates = relative)]
#[body(upper, mass = 1.0, inertia = [0.001, 0.0833, 0.0833])]
#[body(lower, mass = 0.5, inertia = [0.0005, 0.04, 0.04])]
#[joint(shoulder = revolute(ground, upper), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0, 0, 0], rho2 = [-0.5, 0, 0])]
#[joint(elbow = revolute(upper, lower), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0.5, 0, 0], rho2 = [-0.5, 0, 0])]
struct Arm;

/// The relative engine without std: the arm's forward and inverse dynamics
/// at the shoulder angle `angle`, `steps` RK4 steps of 1 ms, then its mass
/// matrix and bodies' frames at the end. Returns the energy plus three
/// residuals that are 0 up to rounding (inverse after forward dynamics,
/// `½ vᵀ M v` against the kinetic energy, `Σ m g z` of the frames against
/// the gravitational), or NaN.
#[unsafe(no_mangle)]
pub extern "C" fn joint_arm_relative(angle: f64, steps: u32) -> f64 {
    use joint_runtime::nalgebra::{SMatrix, SVector};
    let Ok(mut sim) = Simulation::new(&Arm, NoLoads, &[], SimulationOptions::default()) else {
        return f64::NAN;
    };
    let mut state = sim.tree().zero_state();
    state.q[0] = angle;
    let tau = SVector::<f64, 2>::new(0.1, -0.2);
    let Ok(vdot) = sim.forward_dynamics(&state, &tau) else {
        return f64::NAN;
    };
    let inverse = (sim.inverse_dynamics(&state, &vdot) - tau).norm();
    for _ in 0..steps {
        if sim.step(&mut state, 1e-3).is_err() {
            return f64::NAN;
        }
    }
    let mut m = SMatrix::<f64, 2, 2>::zeros();
    sim.mass_matrix_into(&state.q, &mut m);
    let e = sim.energy(&state);
    let kinetic = (0.5 * state.v.dot(&(m * state.v)) - e.kinetic).abs();
    let frames = sim.system_state(&state);
    let heights = 9.81 * (frames.bodies[0].r.z + 0.5 * frames.bodies[1].r.z);
    e.total() + inverse + kinetic + (heights - e.gravity).abs()
}

fn cardan<T: joint_runtime::nalgebra::RealField + Copy>() -> Cardan<T> {
    let half = joint_runtime::nalgebra::convert::<f64, T>(0.5);
    Cardan { s: Vector3::y(), h: Vector3::z(), rho1: Vector3::x() * half, rho2: -Vector3::x() * half }
}

/// ‖Φ‖ + ‖J v‖ of a straight Cardan shaft turned by `angle` and spinning at
/// `speed` about its axis, in f64 (0 up to rounding).
#[unsafe(no_mangle)]
pub extern "C" fn joint_cardan_residual(angle: f64, speed: f64) -> f64 {
    let q = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), angle);
    let shaft = |r| OmegaBody::from_rotation(r, &q, Vector3::zeros(), Vector3::new(speed, 0.0, 0.0));
    let state = TwoBodies::new(shaft(Vector3::zeros()), shaft(Vector3::x()));
    let e = cardan::<f64>().evaluate(&state);
    let v = joint_runtime::nalgebra::SVector::<f64, 12>::from_fn(|i, _| if i % 6 == 3 { speed } else { 0.0 });
    e.phi.norm() + (e.jacobian * v).norm()
}

/// The same in f32, eight states per call in `WideF32x8` lanes: the largest
/// ‖Φ‖ over the eight.
#[unsafe(no_mangle)]
pub extern "C" fn joint_cardan_batch_f32(angle: f32) -> f32 {
    let joint = cardan::<f32>();
    let wide = Cardan::<WideF32x8> {
        s: splat(&joint.s),
        h: splat(&joint.h),
        rho1: splat(&joint.rho1),
        rho2: splat(&joint.rho2),
    };
    let states: [TwoBodies<OmegaBody<f32>>; 8] = core::array::from_fn(|i| {
        let q = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), angle + 0.1 * i as f32);
        let shaft = |r| OmegaBody::from_rotation(r, &q, Vector3::zeros(), Vector3::zeros());
        TwoBodies::new(shaft(Vector3::zeros()), shaft(Vector3::x()))
    });
    let mut out = [joint.evaluate(&states[0]); 8];
    match evaluate_batch_simd(&wide, &states, &mut out) {
        Ok(_) => out.iter().map(|e| e.phi.norm()).fold(0.0, f32::max),
        Err(_) => f32::NAN,
    }
}

#[panic_handler]
fn panic(_: &PanicInfo) -> ! {
    loop {}
}

/// The pendulum assembled from a tilt of `angle`, then its velocity and
/// acceleration analysis, on the analyses' block factor (storage the derive
/// sized, inline: no allocator behind it): ‖Φ‖ + ‖v̇‖, or NaN.
#[unsafe(no_mangle)]
pub extern "C" fn joint_pendulum_analyses(angle: f64) -> f64 {
    let tilt = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), angle);
    let link = OmegaBody::from_rotation(Vector3::new(0.3, 0.1, -0.4), &tilt, Vector3::zeros(), Vector3::zeros());
    let mut state = SystemState { bodies: [link], t: 0.0 };
    let Ok(mut analyses) = Analyses::new(&Pendulum) else {
        return f64::NAN;
    };
    if analyses.assemble(&mut state, &AssemblyOptions::default()).is_err() || analyses.velocities(&mut state).is_err() {
        return f64::NAN;
    }
    match analyses.accelerations(&state) {
        Ok(a) => Pendulum.phi(&state).norm() + a.vdot.norm(),
        Err(_) => f64::NAN,
    }
}

/// RK4 steps with projection on the one `Simulation`: its factor, solves and
/// workspaces all inline, sized at compile time.
#[unsafe(no_mangle)]
pub extern "C" fn joint_pendulum_steps(angle: f64, steps: u32) -> f64 {
    pendulum_steps(angle, steps, Integrator::Rk4)
}

/// `steps` steps of 1 ms of each implicit integrator (the implicit midpoint
/// rule, generalised-α, Radau IIA; `which` 0, 1, 2) on the sparse path: the
/// saddle-point matrices, second-order terms (by differences: the pendulum
/// is derived without `second_order`) and colourings in arrays the derive
/// sized, with no allocator. Returns the energy at the end, or NaN.
#[unsafe(no_mangle)]
pub extern "C" fn joint_pendulum_implicit_steps(angle: f64, steps: u32, which: u32) -> f64 {
    let integrator = match which {
        0 => Integrator::ImplicitMidpoint,
        1 => Integrator::GeneralisedAlpha,
        _ => Integrator::RadauIIA,
    };
    pendulum_steps(angle, steps, integrator)
}

/// The pendulum tilted by `angle`, projected, then `steps` steps of 1 ms of
/// `integrator` on the one `Simulation`: its energy at the end, or NaN.
fn pendulum_steps(angle: f64, steps: u32, integrator: Integrator) -> f64 {
    let tilt = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), angle);
    let link = OmegaBody::from_rotation(Vector3::new(0.3, 0.1, -0.4), &tilt, Vector3::zeros(), Vector3::zeros());
    let mut state = SystemState { bodies: [link], t: 0.0 };
    let Ok(mut sim) =
        Simulation::new(&Pendulum, NoLoads, &[], SimulationOptions::default().with_integrator(integrator))
    else {
        return f64::NAN;
    };
    if sim.project(&mut state, &AssemblyOptions::default()).is_err() {
        return f64::NAN;
    }
    for _ in 0..steps {
        if sim.step(&mut state, 1e-3).is_err() {
            return f64::NAN;
        }
    }
    sim.energy(&state).total()
}
