//! A stiff mechanism of the project's own design for the integrator benchmark
//! (`report/stiff.md`): a motor-driven crank-rocker press with two rams on
//! stiff spring-dampers.
//!
//! A planar four-bar (ground pivots `A = 0` and `D = (2, 0, 0)`, crank 0.5 m,
//! coupler 2 m, rocker 1 m; spatial revolute joints about z, so three of its 20
//! rows are redundant) is driven by a motor at 20 rad/s. A ram slides on the
//! rocker and another on the coupler (translational joints), each held at its
//! rest point by a spring-damper along the slide (`k = 10⁷ N/m`,
//! `c = 400 N·s/m`, ram 0.2 kg: a mode at 7 071 rad/s with 14 % damping, the
//! 20 rad/s motion 350 times slower). Five bodies, 31 rows (3 redundant), two
//! freedoms, both stiff. An explicit integrator is held below `h ≈ 2.8 / 7 071`
//! by stability; an implicit one only by accuracy.

use joint_runtime::analysis::{AnalysisError, AssemblyOptions, assemble, velocities};
use joint_runtime::dynamics::{Attachment, SpringDamper};
use joint_runtime::nalgebra::{UnitQuaternion, Vector3};
use joint_runtime::{OmegaBody, Polynomial, SystemState};

/// Motor speed, rad/s.
pub const MOTOR_SPEED: f64 = 20.0;
/// Spring stiffness, N/m.
pub const STIFFNESS: f64 = 1e7;
/// Damping, N·s/m.
pub const DAMPING: f64 = 400.0;

/// The press (see the module documentation).
#[derive(joint_runtime::Scene)]
#[scene(gravity = [0, -9.81, 0], second_order, coordinates = both)]
#[body(crank, mass = 1.0, inertia = [0.001, 0.02, 0.02])]
#[body(coupler, mass = 2.0, inertia = [0.002, 0.67, 0.67])]
#[body(rocker, mass = 1.5, inertia = [0.0015, 0.125, 0.125])]
#[body(ram1, mass = 0.2, inertia = [0.001, 0.001, 0.001])]
#[body(ram2, mass = 0.2, inertia = [0.001, 0.001, 0.001])]
#[joint(a = revolute(ground, crank), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0, 0, 0], rho2 = [-0.25, 0, 0])]
#[joint(b = revolute(crank, coupler), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0.25, 0, 0], rho2 = [-1, 0, 0])]
#[joint(c = revolute(coupler, rocker), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [1, 0, 0], rho2 = [-0.5, 0, 0])]
#[joint(d = revolute(rocker, ground), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0.5, 0, 0], rho2 = [2, 0, 0])]
#[joint(motor = rotational_driver(ground, crank), axis1 = [0, 0, 1], axis2 = [0, 0, 1], theta = motor)]
#[joint(s1 = translational(rocker, ram1), axis1 = [1, 0, 0], axis2 = [1, 0, 0], rho1 = [0, 0, 0], rho2 = [0, 0, 0])]
#[joint(s2 = translational(coupler, ram2), axis1 = [1, 0, 0], axis2 = [1, 0, 0], rho1 = [0, 0, 0], rho2 = [0, 0, 0])]
pub struct Press {
    /// The motor's angle: `MOTOR_SPEED · t`.
    pub motor: Polynomial<2>,
}

/// The press with its motor.
pub fn scene() -> Press {
    Press { motor: Polynomial([0.0, MOTOR_SPEED]) }
}

/// The two stiff spring-dampers along the slides: from a point 0.3 m back on
/// the link to the ram's centre, at rest length at the start.
pub fn springs() -> [SpringDamper; 2] {
    let spring = |link: usize, ram: usize| SpringDamper {
        a: Attachment::Body { body: link, point: Vector3::new(-0.3, 0.0, 0.0) },
        b: Attachment::Body { body: ram, point: Vector3::zeros() },
        stiffness: STIFFNESS,
        damping: DAMPING,
        rest_length: 0.3,
    };
    [spring(Press::ROCKER, Press::RAM1), spring(Press::COUPLER, Press::RAM2)]
}

/// The assembled start at `t = 0` (crank along +x), velocities from the motor,
/// the rams still on their links.
///
/// # Errors
/// A failed assembly or velocity analysis.
pub fn initial_state() -> Result<SystemState<5>, AnalysisError> {
    // Crank B = (0.5, 0, 0); the coupler and rocker meet at C = (2.25, 0.968, 0).
    let c = Vector3::new(2.25, (1.0f64 - 0.0625).sqrt(), 0.0);
    let b = Vector3::new(0.5, 0.0, 0.0);
    let d = Vector3::new(2.0, 0.0, 0.0);
    let along = |from: Vector3<f64>, to: Vector3<f64>| {
        let u = to - from;
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), u.y.atan2(u.x))
    };
    let body = |centre: Vector3<f64>, q: UnitQuaternion<f64>| {
        OmegaBody::from_rotation(centre, &q, Vector3::zeros(), Vector3::zeros())
    };
    let (qc, qr) = (along(b, c), along(c, d));
    let bodies = [
        body(b * 0.5, UnitQuaternion::identity()),
        body((b + c) * 0.5, qc),
        body((c + d) * 0.5, qr),
        body((c + d) * 0.5, qr),
        body((b + c) * 0.5, qc),
    ];
    let mut state = SystemState { bodies, t: 0.0 };
    let scene = scene();
    assemble(&scene, &mut state, &AssemblyOptions::default())?;
    velocities(&scene, &mut state)?;
    // The minimum-norm velocities let the rams slide; start them still on
    // their links instead (the same point and turn, so J v + Φ_t stays 0).
    for (ram, link) in [(Press::RAM1, Press::ROCKER), (Press::RAM2, Press::COUPLER)] {
        state.bodies[ram].rdot = state.bodies[link].rdot;
        state.bodies[ram].omega = state.bodies[link].omega;
    }
    Ok(state)
}
