//! The sparse path (`joint_runtime::sparse`) against the dense one on every
//! example scene: the same accelerations and the same steps to round-off, the
//! same number of redundant rows (Bricard's one, the Cardan shafts' bearings).

use joint_examples::{bricard, cardan, double_cardan, four_bar, pendulum_chain, steering};
use joint_runtime::analysis::{AssemblyOptions, assemble, velocities};
use joint_runtime::dynamics::{NoLoads, Simulation, SimulationOptions};
use joint_runtime::sparse::SparseSimulation;
use joint_runtime::{Ramp, Scene, SparseJacobian, SystemState};

/// `|a − b| ≤ tol (1 + |b|)` entry by entry.
#[track_caller]
fn close(what: &str, a: &[f64], b: &[f64], tol: f64) {
    let scale = 1.0 + b.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    for (i, (x, y)) in a.iter().zip(b).enumerate() {
        assert!((x - y).abs() <= tol * scale, "{what}[{i}]: sparse {x:e}, dense {y:e}");
    }
}

fn flat<const NB: usize>(s: &SystemState<NB>) -> Vec<f64> {
    s.bodies
        .iter()
        .flat_map(|b| {
            b.r.iter().chain(b.p.iter()).chain(b.rdot.iter()).chain(b.omega.iter()).copied().collect::<Vec<_>>()
        })
        .collect()
}

/// The dynamics at `state`, then `steps` RK4 steps with projection, both ways.
fn same<S, const NB: usize, const NV: usize, const M: usize, const NNZ: usize>(
    scene: &S,
    state: SystemState<NB>,
    steps: usize,
    h: f64,
) where
    S: Scene<NB, NV, M> + SparseJacobian<NB, NNZ>,
{
    let options = SimulationOptions::default();
    let mut dense = Simulation::new(scene, NoLoads, &[], options).expect("dense");
    let mut sparse = SparseSimulation::new(scene, NoLoads, &[], options).expect("sparse");
    let (d, s) = (dense.dynamics(&state).expect("dense dynamics"), sparse.dynamics(&state).expect("sparse dynamics"));
    close("v̇", s.vdot.as_slice(), d.vdot.as_slice(), 1e-9);
    assert_eq!(sparse.redundant().len(), d.redundant.len(), "redundant rows");
    let (mut a, mut b) = (state, state);
    for _ in 0..steps {
        dense.step(&mut a, h).expect("dense step");
        sparse.step(&mut b, h).expect("sparse step");
    }
    close("state", &flat(&b), &flat(&a), 1e-8);
}

#[test]
fn bricard_with_its_redundant_row() {
    same(&bricard::scene(), bricard::initial_state(), 50, 1e-3);
}

#[test]
fn four_bar() {
    same(&four_bar::scene(), four_bar::initial_state(), 50, 1e-3);
}

#[test]
fn pendulum_chain() {
    same(&pendulum_chain::scene(), pendulum_chain::initial_state(), 50, 1e-3);
}

#[test]
fn cardan_shaft_driven() {
    let shaft = cardan::CardanShaft::new(0.5, 10.0).expect("valid bend");
    same(&shaft, shaft.reference_state(), 50, 1e-3);
}

#[test]
fn double_cardan_with_its_bearings() {
    let geometry = double_cardan::Geometry::new(0.4, double_cardan::Arrangement::W, double_cardan::Phasing::InPhase)
        .expect("valid bend");
    let shaft = double_cardan::DoubleCardan::new(geometry, 10.0);
    same(&shaft, shaft.initial_state().expect("consistent start"), 50, 1e-3);
}

#[test]
fn steering_column() {
    let column = steering::SteeringColumn::new(Ramp { start: 0.0, rate: 1.0 }, 0.0);
    let mut state = column.rough_state(0.0);
    assemble(&column, &mut state, &AssemblyOptions::default()).expect("assembles");
    velocities(&column, &mut state).expect("driven velocities");
    same(&column, state, 50, 1e-3);
}
