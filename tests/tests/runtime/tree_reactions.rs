//! The reactions of tree joints (`TreeSimulation::reactions`, from the
//! recursive Newton–Euler algorithm) and of loops' closing joints
//! (`TreeSimulation::closure_reactions`, `J_bᵀ λ` on the derive's body rows),
//! and every joint's on both its bodies by name (`Engine::reaction`),
//! against the absolute scene's reactions (`−J_kᵀ λ_k` of each joint's rows)
//! on the same declaration, with user loads and springs acting; a floating
//! body's free joint carries nothing; the share along a joint's freedom is
//! its joint force.

use joint_runtime::dynamics::{
    AbsoluteSimulation, AppliedLoads, Attachment, Engine, Loads, NoLoads, Reaction, SimulationOptions, SpringDamper,
};
use joint_runtime::nalgebra::{SVector, Vector3};
use joint_runtime::relative::{TreeJointKind, TreeScene, TreeSimulation, TreeState};
use joint_runtime::{Scene, SparseJacobian, SystemState};

use crate::floating::Drone;
use crate::loops::{FourBar, Spatial};

/// `mine` within 1e-11 of `theirs` (relative to its size), else a message naming `what`.
fn assert_same(mine: &Reaction, theirs: &Reaction, what: &str) {
    let scale = 1.0 + theirs.force.norm() + theirs.torque.norm();
    let apart = (mine.force - theirs.force).norm() + (mine.torque - theirs.torque).norm();
    assert!(apart < 1e-11 * scale, "{what}: {mine:?} against {theirs:?}");
}

/// Both coordinate choices' reactions at the start of `tree_state`, with
/// `loads` and `springs`: every tree joint's on its child, and every
/// closing joint's on each body; returns the largest force compared.
fn same_reactions<
    S,
    L,
    const NB: usize,
    const NV6: usize,
    const M: usize,
    const NNZ: usize,
    const NQ: usize,
    const NV: usize,
    const NC: usize,
>(
    scene: &S,
    tree_state: &TreeState<NQ, NV>,
    loads: L,
    springs: &[SpringDamper],
) -> f64
where
    S: Scene<NB, NV6, M> + SparseJacobian<NB, NNZ> + TreeScene<NB, NQ, NV, NC>,
    L: AppliedLoads<NB> + Copy,
{
    let mut relative = TreeSimulation::new(scene).unwrap().with_springs(springs).unwrap().with_loads(loads);
    let tau = SVector::zeros();
    let mine = relative.reactions(tree_state, &tau).unwrap();
    let forces = relative.closure_forces(tree_state, &tau).unwrap();
    let system: SystemState<NB> = relative.tree().system_state(tree_state);
    let mut absolute = AbsoluteSimulation::new(scene, loads, springs, SimulationOptions::default()).unwrap();
    let lambda = absolute.dynamics(&system).unwrap().lambda;
    let block_of = |name: &str| <S as Scene<NB, NV6, M>>::BLOCKS.iter().find(|b| b.name == name);
    let mut largest = 0.0_f64;
    for (k, joint) in relative.tree().joints().iter().enumerate() {
        let theirs = match block_of(joint.name) {
            Some(block) => absolute.reactions(&system, &lambda, block)[joint.child],
            // A floating body's free joint: no rows, no reaction.
            None => Reaction::default(),
        };
        assert_same(&mine[k], &theirs, &format!("joint `{}`", joint.name));
        largest = largest.max(theirs.force.norm());
    }
    // Every joint by name through `Engine::reaction`, both bodies.
    for block in <S as Scene<NB, NV6, M>>::BLOCKS {
        let mine = Engine::reaction(&mut relative, tree_state, block.name).unwrap();
        let theirs = Engine::reaction(&mut absolute, &system, block.name).unwrap().unwrap();
        // A joint the tree folds away entirely would have none; these all have one.
        let mine = mine.unwrap_or_else(|| panic!("no reaction of `{}`", block.name));
        for (body, (mine, theirs)) in mine.iter().zip(&theirs).enumerate() {
            assert_same(mine, theirs, &format!("joint `{}` on body {body}", block.name));
        }
    }
    for block in <S as TreeScene<NB, NQ, NV, NC>>::CLOSURES {
        let (mine, theirs) = (
            relative.closure_reactions(tree_state, &forces, block),
            absolute.reactions(&system, &lambda, block_of(block.name).unwrap()),
        );
        for (body, (mine, theirs)) in mine.iter().zip(&theirs).enumerate() {
            assert_same(mine, theirs, &format!("closing joint `{}` on body {body}", block.name));
            largest = largest.max(theirs.force.norm());
        }
    }
    largest
}

#[test]
fn tree_reactions_are_the_absolute_scenes() {
    let state = crate::tree::walker_state();
    assert!(same_reactions(&crate::tree::Walker, &state, NoLoads, &[]) > 1.0);
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

/// Loops: the planar four-bar (its closing joint keeps two of its five
/// rows, the tree carries the out-of-plane ones) swinging, and the spatial
/// loop closed by a spherical joint (no redundant row: its reactions are
/// determined) assembled in motion, a spring pulling its lever.
#[test]
fn loop_reactions_are_the_absolute_scenes() {
    let swinging = TreeState::<3, 3> { q: SVector::from([0.3, -0.3, 0.3]), v: SVector::from([1.0, -1.0, 1.0]), t: 0.0 };
    assert!(same_reactions(&FourBar, &swinging, NoLoads, &[]) > 1.0);
    let sim = TreeSimulation::new(&Spatial).unwrap();
    let (c, s) = (0.6_f64.cos(), -(0.6_f64.sin()));
    let guess = TreeState::<6, 5> {
        q: SVector::from([0.5, c, 0.0, 0.0, s, 0.3]),
        v: SVector::from([1.0, 0.3, -0.2, 0.5, 0.7]),
        t: 0.0,
    };
    let start = sim.assemble(&guess).unwrap();
    assert!(start.v.norm() > 0.5, "the loop's velocities were projected away: {}", start.v);
    let springs = [SpringDamper {
        a: Attachment::Ground(Vector3::new(1.5, 0.4, 0.0)),
        b: Attachment::Body { body: Spatial::LEVER, point: Vector3::new(0.0, 0.0, 0.3) },
        stiffness: 60.0,
        rest_length: 0.2,
        damping: 1.5,
    }];
    let loads =
        |s: &SystemState<3>, l: &mut Loads<3>| l.force[1] += s.bodies[1].rotation() * Vector3::new(0.0, 4.0, 0.0);
    assert!(same_reactions(&Spatial, &start, loads, &springs) > 1.0);
}

/// Each joint's reaction, projected on its own freedoms, is its joint
/// force: a revolute joint's torque about its axis at its point, a free
/// joint's whole wrench (in its child's axes). With contacts holding this
/// is Newton–Euler for everything past the joint: the contacts' wrenches on
/// their bodies (`J_bᵀ λ`, the derive's body rows) must balance what `Jᵀλ`
/// did to the accelerations, so a floating robot's free joint carries
/// nothing. Checked on the Solo12 on four feet (world's and its feet's
/// axes), the UR5 welded at its tool and MuJoCo's soft welds (a ball joint
/// and a hinge welded with half the torque, a slider to the world), in
/// motion under joint forces.
#[test]
fn a_joints_share_of_its_reaction_is_its_force_with_contacts() {
    fn shares<S: TreeScene<NB, NQ, NV, NC>, const NB: usize, const NQ: usize, const NV: usize, const NC: usize>(
        scene: &S,
        actuated: usize,
    ) -> f64 {
        let mut sim = TreeSimulation::new(scene).unwrap();
        let mut state = sim.tree().zero_state();
        let wave = |i: usize, a: f64| a * (1.3 * i as f64 + 0.4).sin();
        let turn = SVector::<f64, NV>::from_fn(|i, _| wave(i, 0.4));
        sim.tree().displace(&mut state.q, &turn);
        state.v = SVector::from_fn(|i, _| wave(i + 7, 1.5));
        // Joint forces on the actuated freedoms only (a floating base has none).
        let tau = SVector::<f64, NV>::from_fn(|i, _| if i + actuated >= NV { wave(i + 3, 2.0) } else { 0.0 });
        let lambda = sim.closure_forces(&state, &tau).unwrap();
        let r = sim.reactions(&state, &tau).unwrap();
        let system = sim.tree().system_state(&state);
        let mut at = 0;
        for (k, joint) in sim.tree().joints().iter().enumerate() {
            let turn = system.bodies[joint.child].rotation().inverse();
            let (force, torque) = (turn * r[k].force, r[k].torque);
            let at_point = torque - joint.rho_child.cross(&force);
            let share: Vec<f64> = match joint.kind {
                TreeJointKind::Revolute => vec![at_point.dot(&joint.axis_child)],
                TreeJointKind::Prismatic => vec![force.dot(&joint.axis_child)],
                TreeJointKind::Spherical => at_point.iter().copied().collect(),
                TreeJointKind::Free => force.iter().chain(torque.iter()).copied().collect(),
                other => panic!("joint `{}`: {other:?}", joint.name),
            };
            for (i, s) in share.iter().enumerate() {
                assert!((s - tau[at + i]).abs() < 1e-10, "joint `{}`: {s} against {}", joint.name, tau[at + i]);
            }
            at += share.len();
        }
        lambda.amax()
    }
    // The contacts bear loads (the robots' weights and more).
    assert!(shares(&crate::constrained::SoloFeet, 12) > 1.0);
    assert!(shares(&crate::constrained::SoloLocal, 12) > 1.0);
    assert!(shares(&crate::constrained::Ur5Weld, 6) > 1.0);
    assert!(shares(&crate::soft::SoftWeld, 5) > 1.0);
}
