//! Every closed-loop mechanism of the examples (the guide's four-bar,
//! Bricard's linkage, the free double Cardan shaft and the stiff press) in
//! relative coordinates, the default a scene gets when it does not choose,
//! against its absolute run: both by Dormand–Prince at `rtol = atol =
//! 1e-10` from the same start, the bodies' poses at the end equal to the
//! integrators' tolerance (the bounds are about ten times the differences
//! measured when they were written: 5.0e-10 m, 2.2e-10, 5.5e-11, and
//! 5.8e-14 for the press, whose motor prescribes its linkage); and their
//! joints' reactions, closing joints included, against the absolute
//! engine's.

use joint_examples::double_cardan::{Arrangement, DoubleCardan, FreeDoubleCardan, Geometry, Phasing};
use joint_examples::{bricard, four_bar, press};
use joint_runtime::dynamics::{AbsoluteSimulation, Adaptive, NoLoads, SimulationOptions, SpringDamper, Tolerance};
use joint_runtime::nalgebra::SVector;
use joint_runtime::relative::{TreeScene, TreeSimulation};
use joint_runtime::{Scene, SparseJacobian, SystemState};

/// The largest `|Δr| + |Δp|` (`p` up to its sign) of a body between the two
/// engines' ends after `t_end`.
fn engines_apart<
    S,
    const NB: usize,
    const NV6: usize,
    const M: usize,
    const NNZ: usize,
    const NQ: usize,
    const NV: usize,
    const NC: usize,
>(
    scene: &S,
    springs: &[SpringDamper],
    start: SystemState<NB>,
    t_end: f64,
) -> f64
where
    S: Scene<NB, NV6, M> + SparseJacobian<NB, NNZ> + TreeScene<NB, NQ, NV, NC>,
{
    let tolerance = Tolerance { rtol: 1e-10, atol: 1e-10 };
    let options = SimulationOptions::default();
    let mut absolute = AbsoluteSimulation::new(scene, NoLoads, springs, options).unwrap();
    let mut a = start;
    absolute.integrate(&mut a, t_end, Adaptive::DormandPrince, tolerance).unwrap();
    let mut relative = TreeSimulation::new(scene).unwrap().with_springs(springs).unwrap();
    let mut r = relative.state_of(&start).unwrap();
    relative.integrate(&mut r, t_end, Adaptive::DormandPrince, tolerance).unwrap();
    let r = relative.tree().system_state(&r);
    a.bodies
        .iter()
        .zip(&r.bodies)
        .map(|(a, b)| (a.r - b.r).norm() + (a.p - b.p).norm().min((a.p + b.p).norm()))
        .fold(0.0, f64::max)
}

#[test]
fn the_four_bar_moves_alike_in_both_coordinates() {
    let apart = engines_apart(&four_bar::scene(), &[], four_bar::initial_state(), 1.0);
    assert!(apart < 5e-9, "{apart:e}");
}

#[test]
fn bricard_moves_alike_in_both_coordinates() {
    let apart = engines_apart(&bricard::scene(), &[], bricard::initial_state(), 1.0);
    assert!(apart < 2e-9, "{apart:e}");
}

#[test]
fn the_double_cardan_shaft_moves_alike_in_both_coordinates() {
    let geometry = Geometry::new(30f64.to_radians(), Arrangement::Z, Phasing::InPhase).unwrap();
    let start = DoubleCardan::new(geometry, 10.0).initial_state().unwrap();
    let apart = engines_apart(&FreeDoubleCardan::new(&geometry), &[], start, 1.0);
    assert!(apart < 5e-10, "{apart:e}");
}

#[test]
fn the_stiff_press_moves_alike_in_both_coordinates() {
    let start = press::initial_state().unwrap();
    let apart = engines_apart(&press::scene(), &press::springs(), start, 0.5);
    assert!(apart < 1e-12, "{apart:e}");
}

/// The largest difference between the two engines' reactions at `start`
/// (every tree joint's on its child, every closing joint's on each of its
/// bodies) and the largest force compared.
fn reactions_apart<
    S,
    const NB: usize,
    const NV6: usize,
    const M: usize,
    const NNZ: usize,
    const NQ: usize,
    const NV: usize,
    const NC: usize,
>(
    scene: &S,
    springs: &[SpringDamper],
    start: SystemState<NB>,
) -> (f64, f64)
where
    S: Scene<NB, NV6, M> + SparseJacobian<NB, NNZ> + TreeScene<NB, NQ, NV, NC>,
{
    let mut absolute = AbsoluteSimulation::new(scene, NoLoads, springs, SimulationOptions::default()).unwrap();
    let mut relative = TreeSimulation::new(scene).unwrap().with_springs(springs).unwrap();
    let state = relative.state_of(&start).unwrap();
    let system = relative.tree().system_state(&state);
    let lambda = absolute.dynamics(&system).unwrap().lambda;
    let tau = SVector::zeros();
    let mine = relative.reactions(&state, &tau).unwrap();
    let forces = relative.closure_forces(&state, &tau).unwrap();
    let block_of = |name: &str| <S as Scene<NB, NV6, M>>::BLOCKS.iter().find(|b| b.name == name).unwrap();
    let mut pairs = Vec::new();
    for (k, joint) in relative.tree().joints().iter().enumerate() {
        pairs.push((mine[k], absolute.reactions(&system, &lambda, block_of(joint.name))[joint.child]));
    }
    for block in <S as TreeScene<NB, NQ, NV, NC>>::CLOSURES {
        let mine = relative.closure_reactions(&state, &forces, block);
        pairs.extend(mine.into_iter().zip(absolute.reactions(&system, &lambda, block_of(block.name))));
    }
    let apart = pairs.iter().map(|(a, b)| (a.force - b.force).norm() + (a.torque - b.torque).norm());
    (apart.fold(0.0, f64::max), pairs.iter().map(|(_, b)| b.force.norm()).fold(0.0, f64::max))
}

/// The examples' loops whose reactions the dynamics determine carry the
/// same wrenches in both coordinates: the four-bar ladder (planar: the tree
/// carries the out-of-plane rows it folds, the absolute engine drops them
/// as redundant, and neither gives them a force), the double Cardan shaft
/// and the press at its start, driven by its motor. (Bricard's linkage is
/// overconstrained: one row's force is not determined, and the engines
/// drop different rows, so their splits differ.) Measured when written:
/// 8.7e-15 N of 18 N, 2.5e-14 of 29, 3.3e-12 of 954.
#[test]
fn loop_reactions_match_the_absolute_engines() {
    let geometry = Geometry::new(30f64.to_radians(), Arrangement::Z, Phasing::InPhase).unwrap();
    let cardan = DoubleCardan::new(geometry, 10.0).initial_state().unwrap();
    for (name, (apart, largest)) in [
        ("four-bar", reactions_apart(&four_bar::scene(), &[], four_bar::initial_state())),
        ("double Cardan", reactions_apart(&FreeDoubleCardan::new(&geometry), &[], cardan)),
        ("press", reactions_apart(&press::scene(), &press::springs(), press::initial_state().unwrap())),
    ] {
        assert!(largest > 10.0 && apart < 1e-13 * largest, "{name}: {apart:e} of {largest}");
    }
}
