//! Every integrator on the benchmark mechanisms of `report/stiff.md`, briefly:
//! the stiff press (closed loop, redundant rows, a 20 rad/s motor, rams on
//! 10⁷ N/m spring-dampers) and Bricard's mechanism, each run against
//! Dormand–Prince at `rtol = atol = 1e-12`, with the constraints held (the
//! bounds are about ten times the errors measured when they were written).

use joint_examples::{bricard, press};
use joint_runtime::analysis::AnalysisError;
use joint_runtime::dynamics::{
    AbsoluteSimulation, Adaptive, DenseSimulation, IntegrationReport, Integrator, NewtonMatrix, NoLoads, Simulation,
    SimulationOptions, SpringDamper, StepReport, Tolerance,
};
use joint_runtime::{Scene, SparseJacobian, SystemState};

/// How a run advances.
#[derive(Clone, Copy, Debug)]
enum Run {
    Fixed(Integrator, f64),
    Adaptive(Adaptive, f64),
}

/// Accepted and rejected steps (error-controlled) or Newton iterations (fixed steps) of a run.
type Counts = (usize, usize);

/// What a run needs of a simulation, dense or sparse.
trait Steps<const NB: usize> {
    fn step(&mut self, state: &mut SystemState<NB>, h: f64) -> Result<StepReport, AnalysisError>;
    fn integrate(
        &mut self,
        state: &mut SystemState<NB>,
        t_end: f64,
        method: Adaptive,
        tolerance: Tolerance,
    ) -> Result<IntegrationReport, AnalysisError>;
}

impl<S: Scene<NB, NV, M>, const NB: usize, const NV: usize, const M: usize> Steps<NB>
    for DenseSimulation<'_, S, NoLoads, NB, NV, M>
{
    fn step(&mut self, state: &mut SystemState<NB>, h: f64) -> Result<StepReport, AnalysisError> {
        DenseSimulation::step(self, state, h)
    }
    fn integrate(
        &mut self,
        state: &mut SystemState<NB>,
        t_end: f64,
        method: Adaptive,
        tolerance: Tolerance,
    ) -> Result<IntegrationReport, AnalysisError> {
        DenseSimulation::integrate(self, state, t_end, method, tolerance)
    }
}

impl<S, const NB: usize, const NV: usize, const M: usize, const NNZ: usize> Steps<NB>
    for AbsoluteSimulation<'_, S, NoLoads, NB, NV, M, NNZ>
where
    S: Scene<NB, NV, M> + SparseJacobian<NB, NNZ>,
{
    fn step(&mut self, state: &mut SystemState<NB>, h: f64) -> Result<StepReport, AnalysisError> {
        AbsoluteSimulation::step(self, state, h)
    }
    fn integrate(
        &mut self,
        state: &mut SystemState<NB>,
        t_end: f64,
        method: Adaptive,
        tolerance: Tolerance,
    ) -> Result<IntegrationReport, AnalysisError> {
        AbsoluteSimulation::integrate(self, state, t_end, method, tolerance)
    }
}

/// The options of a run.
fn options_for(how: Run) -> SimulationOptions {
    let integrator = if let Run::Fixed(i, _) = how { i } else { Integrator::Rk4 };
    SimulationOptions::default().with_integrator(integrator).with_spectral_radius(0.8)
}

/// Advances `start` to `t_end` as `how` says: the end, and Newton's
/// iterations (fixed steps) or the accepted and rejected steps (error control).
fn advance<const NB: usize>(
    sim: &mut impl Steps<NB>,
    start: SystemState<NB>,
    t_end: f64,
    how: Run,
) -> (SystemState<NB>, Counts) {
    let mut state = start;
    let counts = match how {
        Run::Fixed(_, h) => (0..(t_end / h).round() as usize)
            .map(|_| sim.step(&mut state, h).unwrap_or_else(|e| panic!("{how:?}: {e}")).newton_iterations)
            .fold((0, 0), |(n, _), i| (n + i, 0)),
        Run::Adaptive(method, tol) => {
            let tolerance = Tolerance { rtol: tol, atol: tol };
            let r = sim.integrate(&mut state, t_end, method, tolerance).unwrap_or_else(|e| panic!("{how:?}: {e}"));
            (r.accepted, r.rejected)
        }
    };
    (state, counts)
}

fn run<S: Scene<NB, NV, M>, const NB: usize, const NV: usize, const M: usize>(
    scene: &S,
    springs: &[SpringDamper],
    start: SystemState<NB>,
    t_end: f64,
    how: Run,
) -> (SystemState<NB>, Counts) {
    let mut sim = DenseSimulation::new(scene, NoLoads, springs, options_for(how)).expect("simulation");
    advance(&mut sim, start, t_end, how)
}

/// [`run`] on the sparse path.
fn run_sparse<S, const NB: usize, const NV: usize, const M: usize, const NNZ: usize>(
    scene: &S,
    springs: &[SpringDamper],
    start: SystemState<NB>,
    t_end: f64,
    how: Run,
) -> (SystemState<NB>, Counts)
where
    S: Scene<NB, NV, M> + SparseJacobian<NB, NNZ>,
{
    let mut sim = AbsoluteSimulation::new(scene, NoLoads, springs, options_for(how)).expect("simulation");
    // An error-controlled run names its method apart from the options'
    // integrator: its workspace is made here (`integrate` never allocates).
    sim.prepare(Integrator::RadauIIA).expect("prepared");
    advance(&mut sim, start, t_end, how)
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
    let reference = run(scene, springs, start, t_end, Run::Adaptive(Adaptive::DormandPrince, 1e-12)).0;
    for &(how, allowed) in runs {
        let end = run(scene, springs, start, t_end, how).0;
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
        (Run::Fixed(Integrator::RadauIIA, 2.5e-3), 5e-11),
        (Run::Adaptive(Adaptive::RadauIIA, 1e-6), 2e-9),
        (Run::Adaptive(Adaptive::RadauIIA, 1e-8), 5e-11),
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
        (Run::Fixed(Integrator::RadauIIA, 1e-2), 1e-11),
        (Run::Adaptive(Adaptive::RadauIIA, 1e-6), 5e-7),
        (Run::Adaptive(Adaptive::RadauIIA, 1e-8), 1.5e-8),
    ];
    every_integrator("Bricard", &bricard::scene(), &[], bricard::initial_state(), 0.3, &runs);
}

/// Radau IIA at fixed steps is fifth order: Bricard over 0.6 s at
/// h = 0.06, 0.03, 0.015 against Dormand–Prince at 1e-12.
#[test]
fn radau_is_fifth_order() {
    let (scene, start) = (bricard::scene(), bricard::initial_state());
    let reference = run(&scene, &[], start, 0.6, Run::Adaptive(Adaptive::DormandPrince, 1e-12)).0;
    let errors: Vec<f64> = [0.06, 0.03, 0.015]
        .iter()
        .map(|&h| distance(&run(&scene, &[], start, 0.6, Run::Fixed(Integrator::RadauIIA, h)).0, &reference))
        .collect();
    let orders: Vec<f64> = errors.windows(2).map(|e| (e[0] / e[1]).log2()).collect();
    println!("Radau IIA on Bricard: errors {errors:?}, orders {orders:?}");
    assert!(orders.iter().all(|&p| p > 4.5), "orders {orders:?} (errors {errors:?})");
}

/// A Radau step after another integrator's starts afresh (no stale stages or
/// Jacobian): bit for bit the step of a new simulation from the same state.
/// A step too large for Newton fails and leaves the state as it was.
#[test]
fn radau_starts_afresh_after_a_switch_and_fails_cleanly() {
    let (scene, springs) = (press::scene(), press::springs());
    let options = SimulationOptions::default().with_integrator(Integrator::RadauIIA);
    let mut sim = DenseSimulation::new(&scene, NoLoads, &springs, options).expect("simulation");
    let mut state = press::initial_state().expect("assembled");
    sim.step(&mut state, 1e-3).expect("Radau step");
    sim.options.integrator = Integrator::Rk4;
    sim.step(&mut state, 1e-4).expect("RK4 step");
    let mut fresh = DenseSimulation::new(&scene, NoLoads, &springs, options).expect("simulation");
    let mut other = state;
    sim.options.integrator = Integrator::RadauIIA;
    sim.step(&mut state, 1e-3).expect("Radau step");
    fresh.step(&mut other, 1e-3).expect("Radau step");
    assert_eq!(state, other);
    // h ω = 71 on the stiff rams at the start: Newton on the index-1 equations cannot follow.
    let before = state;
    let error = sim.step(&mut state, 1e-2).expect_err("too large a step");
    assert!(matches!(error, AnalysisError::ImplicitNotConverged { .. }), "{error}");
    assert_eq!(state, before);
}

/// Radau IIA on the sparse path (its real and complex stage systems on the
/// saddle-point pattern) takes the dense path's steps: at fixed steps and
/// error-controlled (the same accepted and rejected steps), on the stiff press
/// and on Bricard with its redundant row.
#[test]
fn sparse_radau_is_the_dense_one() {
    let runs = [
        (Run::Fixed(Integrator::RadauIIA, 2.5e-3), 1e-11),
        // Newton stops at κ·rtol (κ = 10⁻³ here): a round-off apart, one
        // step may take one iteration more, moving the state by up to that.
        (Run::Adaptive(Adaptive::RadauIIA, 1e-6), 1e-8),
        (Run::Adaptive(Adaptive::RadauIIA, 1e-8), 1e-11),
    ];
    let (press, springs, start) = (press::scene(), press::springs(), press::initial_state().expect("assembled"));
    for (how, allowed) in runs {
        let (dense, sparse) = (run(&press, &springs, start, 0.05, how), run_sparse(&press, &springs, start, 0.05, how));
        println!("press, {how:?}: dense {:?}, sparse {:?}", dense.1, sparse.1);
        let gap = distance(&dense.0, &sparse.0);
        assert!(gap < allowed, "press, {how:?}: {gap:e}");
        // Round-off apart, the same Jacobian: Newton's iterations (fixed steps)
        // or the accepted and rejected steps (error control) within a tenth.
        let near = |a: usize, b: usize| a.abs_diff(b) * 10 <= a.max(b).max(10);
        assert!(near(dense.1.0, sparse.1.0) && near(dense.1.1, sparse.1.1), "press, {how:?}");
    }
    let (bricard, start) = (bricard::scene(), bricard::initial_state());
    for how in [Run::Fixed(Integrator::RadauIIA, 1e-2), Run::Adaptive(Adaptive::RadauIIA, 1e-8)] {
        let (dense, sparse) = (run(&bricard, &[], start, 0.3, how), run_sparse(&bricard, &[], start, 0.3, how));
        println!("Bricard, {how:?}: dense {:?}, sparse {:?}", dense.1, sparse.1);
        let gap = distance(&dense.0, &sparse.0);
        assert!(gap < 1e-11, "Bricard, {how:?}: {gap:e}");
    }
}

/// Newton matrices by differences on the sparse path: its implicit steps
/// honour the option with second-order terms by differences of J, γ and Φ_t
/// and take the press through the steps the generated terms take; so does
/// `integrate`'s generalised-α.
#[test]
fn sparse_newton_matrices_by_differences() {
    let (scene, springs) = (press::scene(), press::springs());
    let start = press::initial_state().expect("assembled");
    for integrator in [Integrator::ImplicitMidpoint, Integrator::GeneralisedAlpha] {
        let generated = SimulationOptions::default().with_integrator(integrator);
        let differences = generated.with_newton_matrix(NewtonMatrix::FiniteDifferences);
        let mut a = Simulation::new(&scene, NoLoads, &springs, generated).expect("generated");
        let mut b = Simulation::new(&scene, NoLoads, &springs, differences).expect("differences");
        let (mut x, mut y, mut iterations) = (start, start, [0, 0]);
        for _ in 0..50 {
            iterations[0] += a.step(&mut x, 1e-3).expect("generated").newton_iterations;
            iterations[1] += b.step(&mut y, 1e-3).expect("differences").newton_iterations;
        }
        let gap = x.bodies.iter().zip(&y.bodies).map(|(p, q)| (p.r - q.r).norm()).fold(0.0, f64::max);
        println!(
            "press, {integrator:?}, 50 ms: generated against differences {gap:.1e}, Newton iterations {iterations:?}"
        );
        assert!(gap < 1e-9, "{integrator:?}: {gap:e}");
        assert!(iterations[1] <= iterations[0] + 10, "{integrator:?}: {iterations:?}");
    }
    let options = SimulationOptions::default().with_newton_matrix(NewtonMatrix::FiniteDifferences);
    let mut sparse = Simulation::new(&scene, NoLoads, &springs, options).expect("RK4 takes the option");
    sparse.prepare(Integrator::GeneralisedAlpha).expect("prepared");
    let mut state = start;
    let tolerance = Tolerance { rtol: 1e-6, atol: 1e-6 };
    sparse.integrate(&mut state, 0.01, Adaptive::GeneralisedAlpha, tolerance).expect("differences");
    assert!((state.t - 0.01).abs() < 1e-12);
}

/// One step of a simulation of the press, dense or sparse.
type PressStep<'a> = Box<dyn FnMut(&mut SystemState<5>, f64) -> Result<(), AnalysisError> + 'a>;

/// The implicit midpoint rule at h = 10 ms on the press (h ω = 70): Newton
/// converges at the fifth step to a solution 1.2 m off that gains 1.7 MJ (115 J
/// in motion before it). Dense and sparse steps refuse it with
/// `SpuriousSolution` and leave the state alone; at 5 ms every step follows
/// the motion.
#[test]
fn midpoint_refuses_a_spurious_solution() {
    let (scene, springs) = (press::scene(), press::springs());
    let start = press::initial_state().expect("assembled");
    let options = SimulationOptions::default().with_integrator(Integrator::ImplicitMidpoint);
    let mut dense = DenseSimulation::new(&scene, NoLoads, &springs, options).expect("dense");
    let mut sparse = Simulation::new(&scene, NoLoads, &springs, options).expect("sparse");
    let mut steps: [PressStep; 2] =
        [Box::new(|s, h| dense.step(s, h).map(|_| ())), Box::new(|s, h| sparse.step(s, h).map(|_| ()))];
    for step in &mut steps {
        let mut state = start;
        let failed = (0..10).find_map(|k| {
            let before = state;
            step(&mut state, 1e-2).err().map(|e| (k, e, before))
        });
        let (k, error, before) = failed.expect("a spurious solution refused");
        assert!(matches!(error, AnalysisError::SpuriousSolution { gain, scale } if gain > 1e3 * scale), "{error}");
        assert!(error.to_string().contains("spurious"), "{error}");
        assert_eq!(state, before, "step {k} left the state changed");
        let mut state = start;
        for _ in 0..20 {
            step(&mut state, 5e-3).expect("h = 5 ms follows the motion");
        }
    }
}
