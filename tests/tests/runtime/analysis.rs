//! Kinematic analyses (`joint_runtime::analysis`) on `#[derive(Scene)]` mechanisms:
//! assembly of a spherical pendulum chain, a duplicated joint, bad inputs, an
//! impossible configuration, and velocity/acceleration analysis of a driven pendulum.

#![allow(missing_docs)]

use joint_runtime::analysis::{AnalysisError, AssemblyOptions, accelerations, assemble, velocities};
use joint_runtime::nalgebra::{UnitQuaternion, Vector3};
use joint_runtime::{OmegaBody, Scene, Sinusoid, SystemState};
use joint_tests::scenes::hanging_rods;

// --- Scenes. ---

/// Three rods of length 1 (m = 1, I = diag(1/12, 1/12, 1e-3)) hanging from the
/// origin along −z, ball joints between.
#[derive(Scene)]
#[scene(coordinates = absolute, gravity = [0, 0, -9.81])]
#[body(link0, mass = 1.0, inertia = [0.08333333333333333, 0.08333333333333333, 1e-3])]
#[body(link1, mass = 1.0, inertia = [0.08333333333333333, 0.08333333333333333, 1e-3])]
#[body(link2, mass = 1.0, inertia = [0.08333333333333333, 0.08333333333333333, 1e-3])]
#[joint(ground = spherical(ground, link0), rho1 = [0, 0, 0], rho2 = [0, 0, 0.5])]
#[joint(ball01 = spherical(link0, link1), rho1 = [0, 0, -0.5], rho2 = [0, 0, 0.5])]
#[joint(ball12 = spherical(link1, link2), rho1 = [0, 0, -0.5], rho2 = [0, 0, 0.5])]
struct Chain;

/// The chain with the ground joint declared twice (three redundant rows). The
/// second declaration reads its points from fields: the derive rejects a row that
/// repeats another at compile time, so the repetition is made at run time.
#[derive(Scene)]
#[scene(coordinates = absolute, gravity = [0, 0, -9.81])]
#[body(link0, mass = 1.0, inertia = [0.08333333333333333, 0.08333333333333333, 1e-3])]
#[body(link1, mass = 1.0, inertia = [0.08333333333333333, 0.08333333333333333, 1e-3])]
#[body(link2, mass = 1.0, inertia = [0.08333333333333333, 0.08333333333333333, 1e-3])]
#[joint(ground = spherical(ground, link0), rho1 = [0, 0, 0], rho2 = [0, 0, 0.5])]
#[joint(ball01 = spherical(link0, link1), rho1 = [0, 0, -0.5], rho2 = [0, 0, 0.5])]
#[joint(ball12 = spherical(link1, link2), rho1 = [0, 0, -0.5], rho2 = [0, 0, 0.5])]
#[joint(ground_again = spherical(ground, link0), rho1 = pivot, rho2 = top)]
struct DuplicatedChain {
    pivot: Vector3<f64>,
    top: Vector3<f64>,
}

/// Each body turned a further 5° about its own axis `axes[i]` (positions kept).
fn perturb(s: &mut SystemState<3>) {
    let axes = [Vector3::new(1.0, 2.0, 0.5), Vector3::new(-0.3, 1.0, 1.0), Vector3::new(0.7, -0.2, 1.0)];
    for (b, axis) in s.bodies.iter_mut().zip(axes) {
        let dq =
            UnitQuaternion::from_axis_angle(&joint_runtime::nalgebra::Unit::new_normalize(axis), 5f64.to_radians());
        b.set_rotation(&(b.rotation() * dq));
    }
}

#[test]
fn chain_assembles_from_a_five_degree_perturbation() {
    let scene = Chain;
    let mut s = hanging_rods([0.3, -0.2, 0.5]);
    assert!(scene.phi(&s).norm() < 1e-15);
    perturb(&mut s);
    let before = scene.phi(&s).norm();
    let a = assemble(&scene, &mut s, &AssemblyOptions::default()).unwrap();
    println!("chain: |Φ| {before:.3e} → {:.3e} in {} iterations", a.residual, a.iterations);
    assert!(a.iterations <= 6, "{} iterations", a.iterations);
    assert!(a.residual <= 1e-12 && scene.phi(&s).norm() <= 1e-12);
    assert!(a.redundant.is_empty());
    for b in &s.bodies {
        assert!((b.p.norm() - 1.0).abs() < 1e-14);
    }
    // Already assembled: no iteration.
    assert_eq!(assemble(&scene, &mut s, &AssemblyOptions::default()).unwrap().iterations, 0);
}

#[test]
fn chain_assembles_from_a_rough_guess() {
    // Every body at the origin, unit orientation except a non-unit p: far from assembled.
    let scene = Chain;
    let mut s = hanging_rods([0.0; 3]);
    for (i, b) in s.bodies.iter_mut().enumerate() {
        b.r = Vector3::new(0.3 * i as f64, -0.2, -0.4 * i as f64);
        b.p = joint_runtime::nalgebra::Vector4::new(2.0, 0.1 * i as f64, 0.2, 0.0);
    }
    let a = assemble(&scene, &mut s, &AssemblyOptions::default()).unwrap();
    println!("chain from a rough guess: {} iterations, |Φ| = {:.3e}", a.iterations, a.residual);
    assert!(scene.phi(&s).norm() <= 1e-12);
}

#[test]
fn duplicated_joint_is_reported_redundant() {
    let scene = DuplicatedChain { pivot: Vector3::zeros(), top: Vector3::new(0.0, 0.0, 0.5) };
    let mut s = hanging_rods([0.3, -0.2, 0.5]);
    perturb(&mut s);
    let a = assemble(&scene, &mut s, &AssemblyOptions::default()).unwrap();
    println!("duplicated joint: {} iterations, redundant rows: {}", a.iterations, a.redundant);
    assert!(a.residual <= 1e-12);
    assert_eq!(a.redundant.len(), 3);
    for r in a.redundant.as_slice() {
        assert!(r.joint == "ground" || r.joint == "ground_again", "{r}");
    }
    // Velocity and acceleration analysis report them the same way.
    let v = velocities(&scene, &mut s).unwrap();
    assert_eq!(v.redundant.len(), 3);
    let acc = accelerations(&scene, &s).unwrap();
    assert_eq!(acc.redundant, v.redundant);
}

#[test]
fn non_finite_input_names_body_and_field() {
    let scene = Chain;
    let mut s = hanging_rods([0.3, -0.2, 0.5]);
    s.bodies[1].p[2] = f64::NAN;
    let e = assemble(&scene, &mut s, &AssemblyOptions::default()).unwrap_err();
    assert_eq!(e, AnalysisError::NonFinite { body: Some("link1"), field: "p" });
    let msg = e.to_string();
    println!("{msg}");
    assert!(msg.contains("`p`") && msg.contains("`link1`"));

    let mut s = hanging_rods([0.3, -0.2, 0.5]);
    s.bodies[2].r.x = f64::INFINITY;
    assert_eq!(
        assemble(&scene, &mut s, &AssemblyOptions::default()).unwrap_err(),
        AnalysisError::NonFinite { body: Some("link2"), field: "r" }
    );
    let mut s = hanging_rods([0.3, -0.2, 0.5]);
    s.bodies[0].omega.y = f64::NAN;
    assert_eq!(
        accelerations(&scene, &s).unwrap_err(),
        AnalysisError::NonFinite { body: Some("link0"), field: "omega" }
    );
    let mut s = hanging_rods([0.3, -0.2, 0.5]);
    s.t = f64::NAN;
    assert_eq!(velocities(&scene, &mut s).unwrap_err(), AnalysisError::NonFinite { body: None, field: "t" });
    let mut s = hanging_rods([0.3, -0.2, 0.5]);
    s.bodies[0].p = joint_runtime::nalgebra::Vector4::zeros();
    assert_eq!(
        assemble(&scene, &mut s, &AssemblyOptions::default()).unwrap_err(),
        AnalysisError::ZeroQuaternion { body: "link0" }
    );
}

/// One rod (length 1) whose top is held at the origin and whose bottom is held 5 m
/// below it: impossible.
#[derive(Scene)]
#[scene(coordinates = absolute)]
#[body(rod, mass = 1.0, inertia = [0.08333333333333333, 0.08333333333333333, 1e-3])]
#[joint(top = spherical(ground, rod), rho1 = [0, 0, 0], rho2 = [0, 0, 0.5])]
#[joint(bottom = spherical(ground, rod), rho1 = [0, 0, -5], rho2 = [0, 0, -0.5])]
struct Stretched;

#[test]
fn impossible_configuration_is_a_clear_error() {
    let scene = Stretched;
    let mut s = SystemState {
        bodies: [OmegaBody::from_rotation(
            Vector3::new(0.1, 0.0, -0.5),
            &UnitQuaternion::identity(),
            Vector3::zeros(),
            Vector3::zeros(),
        )],
        t: 0.0,
    };
    let e = assemble(&scene, &mut s, &AssemblyOptions::default()).unwrap_err();
    let msg = e.to_string();
    println!("{msg}");
    match e {
        AnalysisError::NoProgress { residual, worst, .. } | AnalysisError::NotConverged { residual, worst, .. } => {
            assert!(residual > 1.0);
            let w = worst.0[0].unwrap();
            assert!(w.row.joint == "top" || w.row.joint == "bottom");
        }
        other => panic!("unexpected {other:?}"),
    }
    assert!(msg.contains("top") || msg.contains("bottom"));

    // Too few iterations is `NotConverged`, naming the worst rows.
    let scene = Chain;
    let mut s = hanging_rods([0.3, -0.2, 0.5]);
    perturb(&mut s);
    let e = assemble(&scene, &mut s, &AssemblyOptions::default().with_max_iterations(1)).unwrap_err();
    println!("{e}");
    assert!(matches!(e, AnalysisError::NotConverged { iterations: 1, .. }));
}

/// A pendulum on a hinge about the ground z axis, driven to the angle θ(t): no
/// degree of freedom left. The centre of mass is 1 m from the hinge along body x.
#[derive(Scene)]
#[scene(coordinates = absolute)]
#[body(crank, mass = 1.0, inertia = [0.08333333333333333, 0.08333333333333333, 1e-3])]
#[joint(hinge = revolute(ground, crank), f = [1, 0, 0], g = [0, 1, 0], h = [0, 0, 1], rho1 = [0, 0, 0], rho2 = [-1, 0, 0])]
#[joint(motor = rotational_driver(ground, crank), f = [1, 0, 0], g = [0, 1, 0], k = [1, 0, 0], theta = drive)]
struct Driven<F> {
    drive: F,
}

#[test]
fn driven_pendulum_velocities_and_accelerations_match_closed_form() {
    let drive = Sinusoid { offset: 0.2, amplitude: 0.5, frequency: 2.0, phase: 0.3 };
    let scene = Driven { drive };
    for t in [0.0, 0.4, 1.1, 2.5] {
        let d = joint_runtime::TimeFunction::eval(&drive, t);
        let (th, w, al) = (d.value, d.rate, d.accel);
        // Start 4° off, slightly displaced.
        let q = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), th + 4f64.to_radians());
        let mut s = SystemState {
            bodies: [OmegaBody::from_rotation(Vector3::new(0.9, 0.1, 0.02), &q, Vector3::zeros(), Vector3::zeros())],
            t,
        };
        let a = assemble(&scene, &mut s, &AssemblyOptions::default()).unwrap();
        let (c, sn) = (th.cos(), th.sin());
        let b = s.bodies[0];
        assert!((b.r - Vector3::new(c, sn, 0.0)).norm() < 1e-12, "t = {t}: r = {}", b.r);
        velocities(&scene, &mut s).unwrap();
        let b = s.bodies[0];
        let rdot = Vector3::new(-sn, c, 0.0) * w;
        assert!((b.rdot - rdot).norm() < 1e-12, "ṙ {} vs {}", b.rdot, rdot);
        assert!((b.omega - Vector3::new(0.0, 0.0, w)).norm() < 1e-12);
        let acc = accelerations(&scene, &s).unwrap();
        let rddot = Vector3::new(-sn, c, 0.0) * al - Vector3::new(c, sn, 0.0) * (w * w);
        let got = acc.vdot.fixed_rows::<3>(0).into_owned();
        assert!((got - rddot).norm() < 1e-11, "r̈ {got} vs {rddot}");
        assert!((acc.vdot.fixed_rows::<3>(3) - Vector3::new(0.0, 0.0, al)).norm() < 1e-11);
        assert!(acc.redundant.is_empty());
        println!(
            "driven pendulum t = {t}: assembled in {} its; |ṙ err| = {:.1e}, |r̈ err| = {:.1e}",
            a.iterations,
            (b.rdot - rdot).norm(),
            (got - rddot).norm()
        );
    }
}

/// The state types' orientation helpers against nalgebra's own quaternions.
#[test]
fn orientation_helpers_agree_with_nalgebra() {
    let q = UnitQuaternion::from_axis_angle(
        &joint_runtime::nalgebra::Unit::new_normalize(Vector3::new(1.0, -2.0, 0.5)),
        0.9,
    );
    let omega = Vector3::new(0.3, -1.0, 2.0);
    let mut b = OmegaBody::from_rotation(Vector3::new(1.0, 2.0, 3.0), &q, Vector3::zeros(), omega);
    assert!(b.rotation().angle_to(&q) < 1e-15);
    assert!((b.rotation_matrix() - q.to_rotation_matrix().into_inner()).norm() < 1e-15);
    assert!((b.omega_inertial() - q * omega).norm() < 1e-14);
    let local = Vector3::new(0.5, 0.0, -0.2);
    assert!((b.point(&local) - (b.r + q * local)).norm() < 1e-15);
    // A turn in body components composes on the right: q ⊗ exp(θ').
    let theta = Vector3::new(0.01, -0.2, 0.05);
    b.turn(&theta);
    assert!(b.rotation().angle_to(&(q * UnitQuaternion::from_scaled_axis(theta))) < 1e-15);
    assert!((b.p.norm() - 1.0).abs() < 1e-15);
    // And a rotation set is read back.
    b.set_rotation(&q);
    assert!(b.rotation().angle_to(&q) < 1e-15);
}
