//! Floating bodies in relative coordinates: a body that no path of tree
//! joints joins to the ground gets a free joint from the ground (7
//! coordinates, 6 velocities), as a body without joints is free in absolute
//! coordinates. Checked against the closed forms of free flight (the centre
//! of mass on its parabola, the angular momentum about it kept), against the
//! same declaration in absolute coordinates, and the recursions against the
//! kinetic energy, against each other and against the written-out code.

use joint_runtime::Scene;
use joint_runtime::SystemState;
use joint_runtime::dynamics::{Loads, Simulation, SimulationOptions};
use joint_runtime::nalgebra::{SVector, Vector3};
use joint_runtime::relative::TreeScene;
use joint_runtime::relative::{Tree, TreeJointKind, TreeSimulation, TreeState};

use crate::tree::{generated_against_recursion, mass_matrix_against_energy, quaternion, same_motion};

/// A drone carrying a gripper on a ball joint and a finger pinned to the
/// gripper: the drone floats (the derive's free joint), the rest hangs from it.
#[derive(Scene, Clone, Copy, Debug, Default)]
#[scene(gravity = [0, 0, -9.81], coordinates = both)]
#[body(drone, mass = 2.0, inertia = [0.05, 0.06, 0.09, 0.004, -0.002, 0.001])]
#[body(gripper, mass = 0.5, inertia = [0.004, 0.004, 0.001])]
#[body(finger, mass = 0.1, inertia = [0.0005, 0.0005, 0.0001])]
#[joint(claw = spherical(drone, gripper), rho1 = [0.1, 0, -0.1], rho2 = [0, 0, 0.15])]
#[joint(knuckle = revolute(gripper, finger), axis1 = [1, 0, 0], axis2 = [1, 0, 0], rho1 = [0, 0, -0.15], rho2 = [0, 0, 0.05])]
pub(crate) struct Drone;

/// A bead whose centre is held on the vertical line through the origin
/// (`point_on_line`, no tree parametrisation): the bead floats and the
/// joint's two rows close it to the ground.
#[derive(Scene, Clone, Copy, Debug, Default)]
#[scene(gravity = [0, 0, -9.81], coordinates = both)]
#[body(bead, mass = 1.0, inertia = [0.1, 0.1, 0.02])]
#[joint(wire = point_on_line(ground, bead), axis1 = [0, 0, 1], rho1 = [0, 0, 0], rho2 = [0, 0, 0])]
struct Bead;

/// The drone turned, moving and spinning, the gripper swinging, the finger turning.
pub(crate) fn drone_state() -> DroneTreeState {
    let [a, b, c, d] = quaternion(0.9, 0.2, -0.1, 0.3);
    let [e, f, g, h] = quaternion(0.8, -0.3, 0.2, 0.1);
    TreeState {
        q: SVector::from_column_slice(&[0.3, -0.2, 1.5, a, b, c, d, e, f, g, h, 0.4]),
        v: SVector::from_column_slice(&[1.0, -0.5, 2.0, 0.7, -1.2, 3.0, 1.5, -0.8, 0.6, -2.0]),
        t: 0.0,
    }
}

/// The system's centre of mass, its velocity, and the angular momentum about it.
pub(crate) fn momenta<const NB: usize>(
    masses: &[(f64, joint_runtime::nalgebra::Matrix3<f64>)],
    s: &SystemState<NB>,
) -> [Vector3<f64>; 3] {
    let total: f64 = masses.iter().map(|m| m.0).sum();
    let c = s.bodies.iter().zip(masses).map(|(b, m)| b.r * m.0).sum::<Vector3<f64>>() / total;
    let cdot = s.bodies.iter().zip(masses).map(|(b, m)| b.rdot * m.0).sum::<Vector3<f64>>() / total;
    let l = s
        .bodies
        .iter()
        .zip(masses)
        .map(|(b, (m, j))| (b.r - c).cross(&(b.rdot - cdot)) * *m + b.rotation() * (j * b.omega))
        .sum();
    [c, cdot, l]
}

#[test]
fn a_body_without_a_path_to_the_ground_floats() {
    let tree = Tree::of(&Drone).unwrap();
    let kinds: Vec<_> = tree.joints().iter().map(|j| (j.name, j.kind)).collect();
    assert_eq!(
        kinds,
        [
            ("free(drone)", TreeJointKind::Free),
            ("claw", TreeJointKind::Spherical),
            ("knuckle", TreeJointKind::Revolute)
        ]
    );
    // The free joint's coordinates are the drone's centre and rotation.
    let state = drone_state();
    let drone = tree.system_state(&state).bodies[0];
    assert!((drone.r - Vector3::new(0.3, -0.2, 1.5)).norm() < 1e-15);
    let p = state.q.fixed_rows::<4>(3);
    assert!((drone.p - SVector::<f64, 4>::from_column_slice(p.as_slice())).norm() < 1e-15);
    // Its velocities: the centre's in the drone's components, then ω'.
    assert!((drone.rotation().inverse() * drone.rdot - Vector3::new(1.0, -0.5, 2.0)).norm() < 1e-14);
    assert!((drone.omega - Vector3::new(0.7, -1.2, 3.0)).norm() < 1e-15);
}

/// Free flight: whatever the bodies do among themselves, their centre of
/// mass falls on its parabola `c₀ + ċ₀ t + ½ g t²` and the angular momentum
/// about it stays (gravity has no moment about the centre of mass).
#[test]
fn a_floating_tree_keeps_its_momenta() {
    let masses: Vec<_> = Drone.tree_inertias().iter().map(|b| (b.mass, b.inertia)).collect();
    let mut sim = TreeSimulation::new(&Drone).unwrap();
    let mut state = drone_state();
    let [c0, cdot0, l0] = momenta(&masses, &sim.tree().system_state(&state));
    let energy = sim.tree().energy(&state).total();
    let (h, steps) = (1e-3, 1000);
    for _ in 0..steps {
        sim.step(&mut state, h).unwrap();
    }
    let t = h * steps as f64;
    let g = Vector3::new(0.0, 0.0, -9.81);
    let [c, cdot, l] = momenta(&masses, &sim.tree().system_state(&state));
    let parabola = c0 + cdot0 * t + g * (0.5 * t * t);
    assert!((c - parabola).norm() < 1e-10, "centre {c} against {parabola}");
    assert!((cdot - (cdot0 + g * t)).norm() < 1e-10, "its velocity {cdot}");
    assert!((l - l0).norm() < 1e-10 * l0.norm(), "angular momentum {l} against {l0}");
    assert!((sim.tree().energy(&state).total() - energy).abs() < 1e-9 * energy.abs());
    // Something happened: the finger turned and the drone tumbled.
    assert!((state.q[11] - 0.4).abs() > 0.1 && (state.q[3] - drone_state().q[3]).abs() > 0.1);
}

/// A bead free along its wire falls as a stone along it, spinning at its
/// start rate about the wire, and the closure keeps it on the wire.
#[test]
fn a_floating_body_held_by_a_closure_slides_on_it() {
    let mut sim = TreeSimulation::new(&Bead).unwrap();
    assert_eq!(sim.tree().joints()[0].kind, TreeJointKind::Free);
    let [a, b, c, d] = quaternion(0.8, 0.0, 0.0, 0.6);
    let mut state = TreeState {
        q: SVector::from_column_slice(&[0.0, 0.0, 1.0, a, b, c, d]),
        v: SVector::from_column_slice(&[0.0, 0.0, 0.5, 0.0, 0.0, 4.0]),
        t: 0.0,
    };
    for _ in 0..500 {
        sim.step(&mut state, 1e-3).unwrap();
    }
    let t = 0.5;
    let shaft = sim.tree().system_state(&state).bodies[0];
    let z = 1.0 + 0.5 * t - 0.5 * 9.81 * t * t;
    assert!((shaft.r - Vector3::new(0.0, 0.0, z)).norm() < 1e-12, "{} against {z}", shaft.r);
    assert!((shaft.omega - Vector3::new(0.0, 0.0, 4.0)).norm() < 1e-12);
    let turned = 2.0 * 0.6f64.atan2(0.8) + 4.0 * t;
    let angle = 2.0 * state.q[6].atan2(state.q[3]);
    assert!(
        (angle - turned).rem_euclid(std::f64::consts::TAU).min((turned - angle).rem_euclid(std::f64::consts::TAU))
            < 1e-12
    );
}

#[test]
fn floating_bodies_move_alike_in_both_coordinate_choices() {
    let moved = same_motion(&Drone, drone_state(), 3000, (1e-10, 1e-9));
    assert!(moved > 0.1, "{moved}");
    let [a, b, c, d] = quaternion(0.8, 0.0, 0.0, 0.6);
    let start = TreeState {
        q: SVector::from_column_slice(&[0.0, 0.0, 1.0, a, b, c, d]),
        v: SVector::from_column_slice(&[0.0, 0.0, 0.5, 0.0, 0.0, 4.0]),
        t: 0.0,
    };
    assert!(same_motion(&Bead, start, 3000, (1e-10, 1e-9)) > 0.01);
}

#[test]
fn floating_recursions_agree() {
    let state = drone_state();
    mass_matrix_against_energy(&Drone, &state);
    generated_against_recursion(&Drone, &state, true);
    let tree = Tree::of(&Drone).unwrap();
    let tau = SVector::<f64, 10>::from_fn(|i, _| 0.4 * i as f64 - 1.3);
    let vdot = tree.forward_dynamics(&state, &tau).unwrap();
    let back = tree.inverse_dynamics(&state, &vdot);
    assert!((back - tau).norm() < 1e-12 * tau.norm(), "{back} against {tau}");
}

/// The user's loads of the absolute `Simulation` drive the tree too: a
/// thrust along the drone's own z through its centre, a yaw torque, a drag
/// on the gripper and a push at a point of the finger, one closure for both
/// coordinate choices: the same motion.
#[test]
fn user_loads_act_alike_in_both_coordinate_choices() {
    let loads = |s: &SystemState<3>, l: &mut Loads<3>| {
        l.force[0] += s.bodies[0].rotation() * Vector3::new(0.0, 0.0, 30.0);
        l.torque[0] += Vector3::new(0.0, 0.0, 0.05);
        l.force[1] -= s.bodies[1].rdot * 0.3;
        l.add_force_at(s, 2, &Vector3::new(0.5, 0.0, 0.2), &Vector3::new(0.0, 0.01, -0.05));
    };
    let mut relative = TreeSimulation::new(&Drone).unwrap().with_loads(loads);
    let mut absolute = Simulation::new(&Drone, loads, &[], SimulationOptions::default()).unwrap();
    let mut state = drone_state();
    let mut system = relative.tree().system_state(&state);
    for _ in 0..3000 {
        relative.step(&mut state, 1e-4).unwrap();
        absolute.step(&mut system, 1e-4).unwrap();
    }
    let mine = relative.tree().system_state(&state);
    let worst = crate::tree::same_bodies(&mine, &system);
    assert!(worst < 1e-10, "the two coordinate choices differ by {worst:e}");
    // The thrust lifted the drone against gravity (2.6 kg, 30 N).
    assert!(mine.bodies[0].r.z > drone_state().q[2] + 0.1, "{}", mine.bodies[0].r);
}

/// Equal and opposite torques about the knuckle's axis on the finger and
/// the gripper are the knuckle's joint torque.
#[test]
fn a_couple_about_a_hinge_is_its_joint_torque() {
    let torque = 0.3;
    let couple = move |s: &SystemState<3>, l: &mut Loads<3>| {
        let (gripper, finger) = (s.bodies[1].rotation(), s.bodies[2].rotation());
        l.torque[2] += Vector3::new(torque, 0.0, 0.0);
        l.torque[1] -= gripper.inverse() * (finger * Vector3::new(torque, 0.0, 0.0));
    };
    let state = drone_state();
    let loaded = TreeSimulation::new(&Drone).unwrap().with_loads(couple).forward_dynamics(&state, &SVector::zeros());
    let mut tau = SVector::<f64, 10>::zeros();
    tau[9] = torque;
    let joint = TreeSimulation::new(&Drone).unwrap().forward_dynamics(&state, &tau);
    let (loaded, joint) = (loaded.unwrap(), joint.unwrap());
    assert!((loaded - joint).norm() < 1e-13 * joint.norm(), "{loaded} against {joint}");
}
