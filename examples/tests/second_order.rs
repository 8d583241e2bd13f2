//! The example scenes derived with `#[scene(second_order)]` (the N-four-bar,
//! the Bricard mechanism, the free double Cardan shaft): their generated
//! second-order terms against Richardson-extrapolated central differences of
//! their generated J and γ on the rotation group, at states along a motion;
//! and the implicit midpoint rule with the generated iteration matrix against
//! the finite-difference one (the same steps to the Newton tolerance).

use joint_examples::double_cardan::{Arrangement, DoubleCardan, FreeDoubleCardan, Geometry, Phasing};
use joint_examples::{bricard, four_bar};
use joint_runtime::dynamics::{AbsoluteSimulation, Integrator, NewtonMatrix, NoLoads, Simulation, SimulationOptions};
use joint_runtime::{Scene, SparseJacobian, SystemState};
use joint_tests::second_order::worst_error;

/// The worst relative error over `steps` RK4 steps of the scene from `start`
/// (λ and a from the dynamics, so the terms are those a Newton matrix uses).
fn check<S, const NB: usize, const NV: usize, const M: usize, const NNZ: usize>(
    name: &str,
    scene: &S,
    start: SystemState<NB>,
) where
    S: Scene<NB, NV, M> + SparseJacobian<NB, NNZ>,
{
    let mut sim = AbsoluteSimulation::new(scene, NoLoads, &[], SimulationOptions::default()).expect("simulation");
    let mut state = start;
    let mut worst = (0.0f64, "");
    let mut largest = 0.0f64;
    for _ in 0..5 {
        for _ in 0..40 {
            sim.step(&mut state, 2e-3).expect("step");
        }
        let d = sim.dynamics(&state).expect("dynamics");
        let e = worst_error(scene, &state, &d.lambda, &d.vdot);
        let s = scene.second_order(&state, &d.lambda, &d.vdot).expect("derived with second_order");
        largest = largest.max(s.stiffness.amax()).max(s.gamma_q.amax());
        if e.0 > worst.0 {
            worst = e;
        }
    }
    println!("{name}: worst {} {:.1e}, largest entry {largest:.2}", worst.1, worst.0);
    assert!(worst.0 < 1e-8 && largest > 1e-2, "{name}: {} off by {:e}", worst.1, worst.0);
}

#[test]
fn example_scenes_second_order_terms_match_differences() {
    check("N-four-bar", &four_bar::scene(), four_bar::initial_state());
    check("Bricard", &bricard::scene(), bricard::initial_state());
    let geometry = Geometry::new(30f64.to_radians(), Arrangement::Z, Phasing::InPhase).expect("geometry");
    let start = DoubleCardan::new(geometry, 10.0).initial_state().expect("start");
    check("double Cardan", &FreeDoubleCardan::new(&geometry), start);
}

#[test]
fn implicit_midpoint_with_generated_matrix_takes_the_same_steps() {
    let scene = four_bar::scene();
    let run = |matrix: NewtonMatrix| {
        let options =
            SimulationOptions::default().with_integrator(Integrator::ImplicitMidpoint).with_newton_matrix(matrix);
        let mut sim = Simulation::new(&scene, NoLoads, &[], options).expect("simulation");
        let mut state = four_bar::initial_state();
        let mut iterations = 0;
        for _ in 0..50 {
            iterations += sim.step(&mut state, 5e-3).expect("step").newton_iterations;
        }
        (state, iterations)
    };
    let (a, ia) = run(NewtonMatrix::Generated);
    let (b, ib) = run(NewtonMatrix::FiniteDifferences);
    for (x, y) in a.bodies.iter().zip(&b.bodies) {
        assert!((x.r - y.r).norm() < 1e-10 && (x.omega - y.omega).norm() < 1e-8, "{x:?} against {y:?}");
    }
    assert!(ia <= ib, "{ia} Newton iterations with the generated matrix, {ib} with differences");
}
