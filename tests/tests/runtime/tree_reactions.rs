//! The reactions of tree joints (`TreeSimulation::reactions`, from the
//! recursive Newton–Euler algorithm) against the absolute scene's reactions
//! (`−J_kᵀ λ_k` of each joint's rows) on the same declaration, with user
//! loads and springs acting; a floating body's free joint carries nothing;
//! the share along a joint's freedom is its joint force.

use joint_runtime::dynamics::{
    AbsoluteSimulation, AppliedLoads, Attachment, Loads, Reaction, SimulationOptions, SpringDamper,
};
use joint_runtime::nalgebra::{SVector, Vector3};
use joint_runtime::relative::{TreeScene, TreeSimulation, TreeState};
use joint_runtime::{Scene, SparseJacobian, SystemState};

use crate::floating::Drone;

/// Both coordinate choices' reactions of every tree joint on its child, at
/// the start of `tree_state`, with `loads` and `springs`; returns the
/// largest force compared.
fn same_reactions<
    S,
    L,
    const NB: usize,
    const NV6: usize,
    const M: usize,
    const NNZ: usize,
    const NQ: usize,
    const NV: usize,
>(
    scene: &S,
    tree_state: &TreeState<NQ, NV>,
    loads: L,
    springs: &[SpringDamper],
) -> f64
where
    S: Scene<NB, NV6, M> + SparseJacobian<NB, NNZ> + TreeScene<NB, NQ, NV>,
    L: AppliedLoads<NB> + Copy,
{
    let mut relative = TreeSimulation::new(scene).unwrap().with_springs(springs).unwrap().with_loads(loads);
    let mine = relative.reactions(tree_state, &SVector::zeros()).unwrap();
    let system: SystemState<NB> = relative.tree().system_state(tree_state);
    let mut absolute = AbsoluteSimulation::new(scene, loads, springs, SimulationOptions::default()).unwrap();
    let lambda = absolute.dynamics(&system).unwrap().lambda;
    let mut largest = 0.0_f64;
    for (k, joint) in relative.tree().joints().iter().enumerate() {
        let theirs = match S::BLOCKS.iter().find(|b| b.name == joint.name) {
            Some(block) => absolute.reactions(&system, &lambda, block)[joint.child],
            // A floating body's free joint: no rows, no reaction.
            None => Reaction::default(),
        };
        let scale = 1.0 + theirs.force.norm() + theirs.torque.norm();
        let apart = (mine[k].force - theirs.force).norm() + (mine[k].torque - theirs.torque).norm();
        assert!(apart < 1e-11 * scale, "joint `{}`: {:?} against {:?}", joint.name, mine[k], theirs);
        largest = largest.max(theirs.force.norm());
    }
    largest
}

#[test]
fn tree_reactions_are_the_absolute_scenes() {
    let state = crate::tree::walker_state();
    assert!(same_reactions(&crate::tree::Walker, &state, joint_runtime::dynamics::NoLoads, &[]) > 1.0);
    let loads = |s: &SystemState<3>, l: &mut Loads<3>| {
        l.force[0] += s.bodies[0].rotation() * Vector3::new(0.0, 0.0, 30.0);
        l.torque[2] += Vector3::new(0.01, -0.02, 0.0);
    };
    let springs = [SpringDamper {
        a: Attachment::Ground(Vector3::new(0.0, 0.0, 3.0)),
        b: Attachment::Body { body: 1, point: Vector3::new(0.02, 0.0, 0.05) },
        stiffness: 40.0,
        rest_length: 1.0,
        damping: 0.5,
    }];
    assert!(same_reactions(&Drone, &crate::floating::drone_state(), loads, &springs) > 1.0);
}

/// A joint's own force is the share of its reaction along its freedom: the
/// knee's torque about its axis at the joint point, the free joint's whole
/// wrench.
#[test]
fn a_joints_force_is_its_reaction_along_its_freedom() {
    let mut sim = TreeSimulation::new(&Drone).unwrap();
    let state = crate::floating::drone_state();
    let tau = SVector::<f64, 10>::from_fn(|i, _| 0.2 * i as f64 - 0.9);
    let r: [Reaction; 3] = sim.reactions(&state, &tau).unwrap();
    let joints = *sim.tree().joints();
    // The knuckle (revolute about the finger's x): the moment about the joint point.
    let knuckle = &r[2];
    let at_joint = knuckle.torque
        - joints[2].rho_child.cross(&(sim.tree().system_state(&state).bodies[2].rotation().inverse() * knuckle.force));
    assert!((at_joint.x - tau[9]).abs() < 1e-12, "{} against {}", at_joint.x, tau[9]);
    // The free joint: its force and torque are the drone's joint forces (the
    // point's force in the drone's components, then the torque).
    let drone = sim.tree().system_state(&state).bodies[0].rotation();
    let force = drone.inverse() * r[0].force;
    for i in 0..3 {
        assert!((force[i] - tau[i]).abs() < 1e-12 && (r[0].torque[i] - tau[3 + i]).abs() < 1e-12, "{:?} {tau}", r[0]);
    }
}
