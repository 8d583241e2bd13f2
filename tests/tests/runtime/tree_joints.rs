//! The tree joints with a slide beside a turn: `cylindrical` (an angle and a
//! slide along one axis, constant subspace) and `planar` (two slides in the
//! parent's plane and the turn about its normal: the slides' columns turn
//! with the angle, whose `Ṡ q̇` enters the recursions). Checked against
//! closed forms (what the joint carries no force along), against the same
//! declaration in absolute coordinates, and the recursions against the
//! kinetic energy and against the written-out code.

use joint_runtime::Scene;
use joint_runtime::SystemState;
use joint_runtime::nalgebra::{SVector, Vector3};
use joint_runtime::relative::{TreeJointKind, TreeScene, TreeSimulation, TreeState};

use crate::floating::momenta;
use crate::tree::{generated_against_recursion, mass_matrix_against_energy, same_motion};

/// A shaft in a tilted bush (`cylindrical`: an angle and a slide), a
/// flywheel pinned across it off its axis.
#[derive(Scene, Clone, Copy, Debug, Default)]
#[scene(gravity = [0, 0, -9.81], coordinates = both)]
#[body(shaft, mass = 1.0, inertia = [0.1, 0.1, 0.02])]
#[body(wheel, mass = 0.4, inertia = [0.008, 0.005, 0.005, 0.001, 0.0, 0.0])]
#[joint(bush = cylindrical(ground, shaft), axis1 = [0.3, 0, 1], axis2 = [0, 0, 1], rho1 = [0, 0, 1], rho2 = [0, 0, 0])]
#[joint(hub = revolute(shaft, wheel), axis1 = [1, 0, 0], axis2 = [1, 0, 0], rho1 = [0.2, 0, 0.3], rho2 = [0, 0, 0])]
struct Bush;

fn bush_state() -> BushTreeState {
    TreeState { q: SVector::from([0.4, -0.2, 1.1]), v: SVector::from([2.0, 0.5, -3.0]), t: 0.0 }
}

/// The bush carries no force along its axis `a` (its slide is free), so,
/// whatever the wheel does, the two bodies' momentum along `a` grows at
/// `(m₁ + m₂) g·a`.
#[test]
fn a_cylindrical_joint_slides_as_gravity_pulls_along_it() {
    let mut sim = TreeSimulation::new(&Bush).unwrap();
    assert_eq!(sim.tree().joints()[0].kind, TreeJointKind::Cylindrical);
    let a = Vector3::new(0.3, 0.0, 1.0).normalize();
    let masses: Vec<_> = Bush.tree_inertias().iter().map(|b| (b.mass, b.inertia)).collect();
    let mut state = bush_state();
    let along = |s: &SystemState<2>| momenta(&masses, s)[1].dot(&a) * 1.4;
    let p0 = along(&sim.tree().system_state(&state));
    for _ in 0..500 {
        sim.step(&mut state, 1e-3).unwrap();
    }
    let expected = p0 + 1.4 * 9.81 * -a.z * 0.5;
    let p = along(&sim.tree().system_state(&state));
    assert!((p - expected).abs() < 1e-10, "{p} against {expected}");
}

/// A puck on a tilted table (`planar`), a stick pinned across it off its
/// centre: the puck's in-plane axes are the table's `f`, `g`.
#[derive(Scene, Clone, Copy, Debug, Default)]
#[scene(gravity = [0, 0, -9.81], coordinates = both)]
#[body(puck, mass = 1.0, inertia = [0.02, 0.02, 0.04])]
#[body(stick, mass = 0.3, inertia = [0.01, 0.01, 0.0005])]
#[joint(table = planar(ground, puck), axis1 = [0, -0.4, 1], axis2 = [0, 0, 1], rho1 = [0, 0, 0.5], rho2 = [0, 0, 0])]
#[joint(pin = revolute(puck, stick), axis1 = [1, 0, 0], axis2 = [1, 0, 0], rho1 = [0.1, 0.05, 0], rho2 = [0, 0, 0.3])]
struct Puck;

fn puck_state() -> PuckTreeState {
    TreeState { q: SVector::from([0.2, -0.1, 0.7, 0.4]), v: SVector::from([0.5, 1.0, 3.0, -2.0]), t: 0.0 }
}

/// The same table declared from the puck (`planar(puck, ground)`): the
/// ground is the joint's second body, its plane normal `h`, and the plane's
/// axes the runtime's pick.
#[derive(Scene, Clone, Copy, Debug, Default)]
#[scene(gravity = [0, 0, -9.81], coordinates = both)]
#[body(puck, mass = 1.0, inertia = [0.02, 0.02, 0.04])]
#[joint(table = planar(puck, ground), axis1 = [0, 0, 1], axis2 = [0, -0.4, 1], rho1 = [0, 0, 0], rho2 = [0, 0, 0.5])]
struct Upside;

/// A lone puck slides on the table as gravity's in-plane part pulls it,
/// spinning at its start rate (the table carries no force in its plane and
/// no moment about its normal).
#[test]
fn a_planar_joint_slides_as_gravity_pulls_in_its_plane() {
    for reversed in [false, true] {
        let start = TreeState { q: SVector::from([0.2, -0.1, 0.7]), v: SVector::from([0.5, 1.0, 3.0]), t: 0.0 };
        let (r, omega, turned) = if reversed { run(&Upside, start) } else { run_lone(start) };
        let n = Vector3::new(0.0, -0.4, 1.0).normalize();
        let g = Vector3::new(0.0, 0.0, -9.81);
        let along = g - n * n.dot(&g);
        let expected = r[0] + r[1] * 0.5 + along * (0.5 * 0.25);
        assert!((r[2] - expected).norm() < 1e-12, "{} against {expected}", r[2]);
        assert!((omega[1] - omega[0]).norm() < 1e-12 && (turned - 1.5).abs() < 1e-12, "{omega:?} {turned}");
    }
}

/// The puck alone: the puck-and-stick scene with the stick's pin held is
/// not a lone puck, so a one-body scene runs this.
fn run_lone(start: TreeState<3, 3>) -> ([Vector3<f64>; 3], [Vector3<f64>; 2], f64) {
    run(&Lone, start)
}

/// The puck on the table without the stick.
#[derive(Scene, Clone, Copy, Debug, Default)]
#[scene(gravity = [0, 0, -9.81], coordinates = both)]
#[body(puck, mass = 1.0, inertia = [0.02, 0.02, 0.04])]
#[joint(table = planar(ground, puck), axis1 = [0, -0.4, 1], axis2 = [0, 0, 1], rho1 = [0, 0, 0.5], rho2 = [0, 0, 0])]
struct Lone;

/// Runs a one-puck scene 0.5 s: the centre at the start, its velocity at
/// the start, the centre at the end; ω at both ends (inertial); the angle
/// turned about the normal.
fn run<S: TreeScene<1, 3, 3>>(scene: &S, mut state: TreeState<3, 3>) -> ([Vector3<f64>; 3], [Vector3<f64>; 2], f64) {
    let mut sim = TreeSimulation::new(scene).unwrap();
    assert_eq!(sim.tree().joints()[0].kind, TreeJointKind::Planar);
    let body = |s: &SystemState<1>| s.bodies[0];
    let first = body(&sim.tree().system_state(&state));
    for _ in 0..500 {
        sim.step(&mut state, 1e-3).unwrap();
    }
    let last = body(&sim.tree().system_state(&state));
    let turn = (first.rotation().inverse() * last.rotation()).angle();
    ([first.r, first.rdot, last.r], [first.rotation() * first.omega, last.rotation() * last.omega], turn)
}

#[test]
fn slides_beside_turns_move_alike_in_both_coordinate_choices() {
    assert!(same_motion(&Bush, bush_state(), 3000, (1e-10, 1e-9)) > 0.1);
    assert!(same_motion(&Puck, puck_state(), 3000, (1e-10, 1e-9)) > 0.1);
    let upside = TreeState { q: SVector::from([0.2, -0.1, 0.7]), v: SVector::from([0.5, 1.0, 3.0]), t: 0.0 };
    assert!(same_motion(&Upside, upside, 3000, (1e-10, 1e-9)) > 0.1);
}

#[test]
fn slides_beside_turns_in_the_recursions() {
    mass_matrix_against_energy(&Bush, &bush_state());
    generated_against_recursion(&Bush, &bush_state(), true);
    mass_matrix_against_energy(&Puck, &puck_state());
    generated_against_recursion(&Puck, &puck_state(), true);
    let tree = joint_runtime::relative::Tree::of(&Puck).unwrap();
    let tau = SVector::<f64, 4>::from([0.3, -0.6, 0.2, 0.1]);
    let vdot = tree.forward_dynamics(&puck_state(), &tau).unwrap();
    let back = tree.inverse_dynamics(&puck_state(), &vdot);
    assert!((back - tau).norm() < 1e-12 * tau.norm(), "{back} against {tau}");
}
