//! Every integrator on the benchmark mechanisms of `report/stiff.md`, briefly:
//! the stiff press (closed loop, redundant rows, a 20 rad/s motor, rams on
//! 10⁷ N/m spring-dampers) and Bricard's mechanism, each run against
//! Dormand–Prince at `rtol = atol = 1e-12`, with the constraints held (the
//! bounds are about ten times the errors measured when they were written).

use joint_examples::{bricard, press};
use joint_runtime::dynamics::{Adaptive, Integrator, NoLoads, Simulation, SimulationOptions, SpringDamper, Tolerance};
use joint_runtime::{Scene, SystemState};

/// How a run advances.
#[derive(Clone, Copy, Debug)]
enum Run {
    Fixed(Integrator, f64),
    Adaptive(Adaptive, f64),
}

fn run<S: Scene<NB, NV, M>, const NB: usize, const NV: usize, const M: usize>(
    scene: &S,
    springs: &[SpringDamper],
    start: SystemState<NB>,
    t_end: f64,
    how: Run,
) -> SystemState<NB> {
    let integrator = if let Run::Fixed(i, _) = how { i } else { Integrator::Rk4 };
    let options = SimulationOptions::default().with_integrator(integrator).with_spectral_radius(0.8);
    let mut sim = Simulation::new(scene, NoLoads, springs, options).expect("simulation");
    let mut state = start;
    match how {
        Run::Fixed(_, h) => {
            for _ in 0..(t_end / h).round() as usize {
                sim.step(&mut state, h).unwrap_or_else(|e| panic!("{how:?}: {e}"));
            }
        }
        Run::Adaptive(method, tol) => {
            let tolerance = Tolerance { rtol: tol, atol: tol };
            sim.integrate(&mut state, t_end, method, tolerance).unwrap_or_else(|e| panic!("{how:?}: {e}"));
        }
    }
    state
}

/// `|Δr| + |Δp|` of the worst body.
fn distance<const NB: usize>(a: &SystemState<NB>, b: &SystemState<NB>) -> f64 {
    a.bodies.iter().zip(&b.bodies).map(|(x, y)| (x.r - y.r).norm() + (x.p - y.p).norm()).fold(0.0, f64::max)
}

fn every_integrator<S: Scene<NB, NV, M>, const NB: usize, const NV: usize, const M: usize>(
    name: &str,
    scene: &S,
    springs: &[SpringDamper],
    start: SystemState<NB>,
    t_end: f64,
    runs: &[(Run, f64)],
) {
    let reference = run(scene, springs, start, t_end, Run::Adaptive(Adaptive::DormandPrince, 1e-12));
    for &(how, allowed) in runs {
        let end = run(scene, springs, start, t_end, how);
        let error = distance(&end, &reference);
        println!("{name}, {how:?}: error {error:.2e}");
        assert!(error < allowed, "{name}, {how:?}: error {error:e} above {allowed:e}");
        assert!(scene.phi(&end).norm() < 1e-9, "{name}, {how:?}: |Φ| = {:e}", scene.phi(&end).norm());
    }
}

#[test]
fn every_integrator_on_the_stiff_press() {
    let start = press::initial_state().expect("assembled");
    let runs = [
        // RK4 below its stability limit (h ω < 2.8 for the 7 071 rad/s mode).
        (Run::Fixed(Integrator::Rk4, 2.5e-4), 1e-10),
        (Run::Fixed(Integrator::ImplicitMidpoint, 1e-3), 2e-6),
        (Run::Fixed(Integrator::GeneralisedAlpha, 1e-3), 2e-7),
        (Run::Adaptive(Adaptive::DormandPrince, 1e-8), 1e-9),
        (Run::Adaptive(Adaptive::GeneralisedAlpha, 1e-6), 1e-8),
    ];
    every_integrator("press", &press::scene(), &press::springs(), start, 0.05, &runs);
}

#[test]
fn every_integrator_on_bricard() {
    let runs = [
        (Run::Fixed(Integrator::Rk4, 1e-2), 1e-8),
        (Run::Fixed(Integrator::ImplicitMidpoint, 1e-2), 1e-4),
        (Run::Fixed(Integrator::GeneralisedAlpha, 1e-2), 1e-4),
        (Run::Adaptive(Adaptive::DormandPrince, 1e-8), 2e-8),
        (Run::Adaptive(Adaptive::GeneralisedAlpha, 1e-6), 2e-5),
    ];
    every_integrator("Bricard", &bricard::scene(), &[], bricard::initial_state(), 0.3, &runs);
}
