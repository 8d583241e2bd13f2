//! The sparse path (`joint_runtime::absolute`) against the dense one on every
//! example scene: the same accelerations and the same steps to round-off, the
//! same number of redundant rows (Bricard's one, the Cardan shafts' bearings).

use joint_examples::{bricard, cardan, double_cardan, four_bar, pendulum_chain, press, scaling, steering};
use joint_runtime::absolute::{RowTerm, SecondOrderLayout};
use joint_runtime::analysis::{Analyses, AssemblyOptions, assemble, velocities};
use joint_runtime::dynamics::{
    AbsoluteSimulation, Adaptive, DenseSimulation, Integrator, Loads, NoLoads, Simulation, SimulationOptions,
    SpringDamper, Stabilisation, Tolerance,
};
use joint_runtime::nalgebra::{DMatrix, SVector};
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

/// Runs `f` in a thread with a 16 MiB stack: the dense path keeps its `M × NV`
/// and `M × M` matrices on the stack, and a 65-row scene (the four-bar of nine
/// bodies) beside the sparse path in one test function needs about 2 MiB, the
/// default test thread's whole stack.
fn on_dense_stack<T: Send>(f: impl FnOnce() -> T + Send) -> T {
    std::thread::scope(|s| {
        std::thread::Builder::new()
            .stack_size(16 << 20)
            .spawn_scoped(s, f)
            .expect("thread")
            .join()
            .unwrap_or_else(|e| std::panic::resume_unwind(e))
    })
}

/// The dynamics at `state`, then `steps` RK4 steps with projection, both ways.
fn same<S, const NB: usize, const NV: usize, const M: usize, const NNZ: usize>(
    scene: &S,
    state: SystemState<NB>,
    steps: usize,
    h: f64,
) where
    S: Scene<NB, NV, M> + SparseJacobian<NB, NNZ> + Sync,
{
    on_dense_stack(|| {
        let options = SimulationOptions::default();
        let mut dense = DenseSimulation::new(scene, NoLoads, &[], options).expect("dense");
        let mut sparse = AbsoluteSimulation::new(scene, NoLoads, &[], options).expect("sparse");
        let (d, s) =
            (dense.dynamics(&state).expect("dense dynamics"), sparse.dynamics(&state).expect("sparse dynamics"));
        close("v̇", s.vdot.as_slice(), d.vdot.as_slice(), 1e-9);
        assert_eq!(sparse.redundant().len(), d.redundant.len(), "redundant rows");
        let (mut a, mut b) = (state, state);
        for _ in 0..steps {
            dense.step(&mut a, h).expect("dense step");
            sparse.step(&mut b, h).expect("sparse step");
        }
        close("state", &flat(&b), &flat(&a), 1e-8);
    });
}

/// Baumgarte stabilisation on the sparse path: the dense path's steps with
/// RK4 and with the implicit midpoint rule (whose saddle-point Newton matrix
/// takes the stabilised γ's derivatives: as many Newton iterations as the
/// dense matrix, 2 a step, where leaving them out took 5 at α = β = 200),
/// from a start 1 mm off the constraints, with the drift pulled in.
#[test]
fn baumgarte_as_on_the_dense_path() {
    let scene = bricard::scene();
    let mut start = bricard::initial_state();
    start.bodies[1].r.y += 1e-3;
    let phi0 = scene.phi(&start).norm();
    on_dense_stack(|| {
        for integrator in [Integrator::Rk4, Integrator::ImplicitMidpoint] {
            let options = SimulationOptions::default()
                .with_integrator(integrator)
                .with_projection(None)
                .with_stabilisation(Stabilisation::Baumgarte { alpha: 200.0, beta: 200.0 });
            let mut dense = DenseSimulation::new(&scene, NoLoads, &[], options).expect("dense");
            let mut sparse = Simulation::new(&scene, NoLoads, &[], options).expect("sparse");
            let (mut a, mut b, mut iterations) = (start, start, [0, 0]);
            for _ in 0..500 {
                iterations[0] += dense.step(&mut a, 1e-3).expect("dense step").newton_iterations;
                iterations[1] += sparse.step(&mut b, 1e-3).expect("sparse step").newton_iterations;
            }
            println!("Bricard, Baumgarte, {integrator:?}: Newton iterations dense, sparse {iterations:?}");
            close("state", &flat(&b), &flat(&a), 1e-8);
            assert!(iterations[1] <= iterations[0] + 50, "{iterations:?}");
            let phi = scene.phi(&b).norm();
            assert!(phi < 1e-2 * phi0, "|Φ| from {phi0:.2e} to {phi:.2e}");
        }
    });
}

/// An RK4 step starts on the factorisation its projection made at the
/// state it returned: the dynamics there and the next step are bit for bit a
/// fresh simulation's (Bricard, with its redundant row); a projection with
/// another rank tolerance is not reused.
#[test]
fn the_projections_factor_serves_the_next_step() {
    let scene = bricard::scene();
    let options = SimulationOptions::default();
    let mut sim = Simulation::new(&scene, NoLoads, &[], options).expect("sparse");
    let mut state = bricard::initial_state();
    for _ in 0..5 {
        sim.step(&mut state, 1e-3).expect("step");
    }
    let mut fresh = Simulation::new(&scene, NoLoads, &[], options).expect("sparse");
    let (a, b) = (sim.dynamics(&state).expect("reused"), fresh.dynamics(&state).expect("fresh"));
    assert_eq!((a.vdot, a.lambda), (b.vdot, b.lambda));
    assert_eq!(sim.redundant().len(), 1);
    let (mut x, mut y) = (state, state);
    sim.step(&mut x, 1e-3).expect("step");
    fresh.step(&mut y, 1e-3).expect("step");
    assert_eq!(x, y);
    // A projection made with a much looser rank tolerance drops other rows:
    // the dynamics must not take its factor.
    let loose = AssemblyOptions::default().with_rank_tolerance(0.5);
    sim.project(&mut x, &loose).expect("projection");
    let (a, b) = (sim.dynamics(&x).expect("refactorised"), fresh.dynamics(&x).expect("fresh"));
    assert_eq!((a.vdot, a.lambda), (b.vdot, b.lambda));
}

/// An RK4 step with projection factorises `J M⁻¹ Jᵀ` four times on a chain
/// (three stages and the end state, which the next step starts on), a fifth
/// only when renormalising the start's quaternions moves a bit.
#[test]
fn four_factorisations_an_rk4_step() {
    joint_examples::chain_scene!(Chain10, 10);
    let scene = Chain10;
    let mut sim = Simulation::new(&scene, NoLoads, &[], SimulationOptions::default()).expect("sparse");
    let mut state = scaling::chain_start::<10>();
    sim.step(&mut state, 1e-3).expect("step");
    let before = sim.factor().factorisations();
    for _ in 0..50 {
        sim.step(&mut state, 1e-3).expect("step");
    }
    let per_step = (sim.factor().factorisations() - before) as f64 / 50.0;
    assert!((4.0..=4.5).contains(&per_step), "{per_step} factorisations a step");
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

joint_examples::chain_scene!(Chain200, 200, second_order);
joint_examples::ladder_scene!(Ladder40, 40, 41, second_order);

/// The dense path's stack for 200 bodies: `J` alone is 600 × 1200.
const BIG_STACK: usize = 512 << 20;

#[test]
fn a_200_body_chain_matches_the_dense_dynamics_and_keeps_its_energy() {
    let start = scaling::chain_start::<200>();
    let dense = std::thread::scope(|s| {
        let run = || {
            DenseSimulation::new(&Chain200, NoLoads, &[], SimulationOptions::default())
                .and_then(|mut d| d.dynamics(&start))
                .map(|d| d.vdot)
        };
        std::thread::Builder::new()
            .stack_size(BIG_STACK)
            .spawn_scoped(s, run)
            .expect("thread")
            .join()
            .expect("no panic")
    })
    .expect("dense dynamics");
    let mut sparse = Simulation::new(&Chain200, NoLoads, &[], SimulationOptions::default()).expect("sparse");
    close("v̇", sparse.dynamics(&start).expect("sparse dynamics").vdot.as_slice(), dense.as_slice(), 1e-9);
    // 100 ms of free fall and swing: energy and constraints kept.
    let (mut state, e0) = (start, sparse.energy(&start).total());
    for _ in 0..100 {
        let r = sparse.step(&mut state, 1e-3).expect("steps");
        assert!(r.constraint_residual < 1e-10 && r.velocity_residual < 1e-10, "{r:?}");
    }
    let drift = (sparse.energy(&state).total() - e0).abs() / e0.abs();
    println!("200-body chain, 100 ms: relative energy drift {drift:.1e}");
    assert!(drift < 1e-9, "relative energy drift {drift:e}");
    assert!(state.bodies[199].rdot.norm() > 0.1, "the chain moves");
}

/// The angle of crank `i` of a ladder of `loops` loops, from +x.
fn crank_angle<const NB: usize>(state: &SystemState<NB>, i: usize) -> f64 {
    let a = state.bodies[i].rotation_matrix() * joint_runtime::nalgebra::Vector3::y();
    a.y.atan2(a.x)
}

/// 4 s of the 40-loop ladder from `state`, every step projected to 1e-10:
/// the passages of crank 0 through the horizontal (singular) position, how
/// far any crank strays from the first (one degree of freedom) and the worst
/// relative energy change.
fn through_singular_positions<const NV: usize, const M: usize, const NNZ: usize>(
    sim: &mut AbsoluteSimulation<'_, Ladder40, NoLoads, 81, NV, M, NNZ>,
    mut state: SystemState<81>,
) -> (usize, f64, f64)
where
    Ladder40: Scene<81, NV, M> + SparseJacobian<81, NNZ>,
{
    let e0 = sim.energy(&state).total();
    let (mut passages, mut last, mut worst_branch, mut worst_energy) =
        (0, crank_angle(&state, 0).sin(), 0.0f64, 0.0f64);
    for _ in 0..4000 {
        let r = sim.step(&mut state, 1e-3).expect("steps through the singular positions");
        assert!(r.constraint_residual <= 1e-10, "{r:?}");
        let s = crank_angle(&state, 0).sin();
        passages += usize::from(s * last <= 0.0);
        last = s;
        let a0 = crank_angle(&state, 0);
        for i in 1..41 {
            worst_branch = worst_branch.max((crank_angle(&state, i) - a0).sin().abs());
        }
        worst_energy = worst_energy.max((sim.energy(&state).total() - e0).abs() / e0.abs());
    }
    (passages, worst_branch, worst_energy)
}

#[test]
fn the_40_loop_ladder_runs_through_its_singular_positions() {
    let mut sim = Simulation::new(&Ladder40, NoLoads, &[], SimulationOptions::default()).expect("sparse");
    let state = scaling::ladder_start::<81>();
    // Upright: three redundant rows per planar loop, found by joint.
    sim.dynamics(&state).expect("dynamics");
    assert_eq!(sim.factor().dropped().len(), 3 * 40);
    let (passages, worst_branch, worst_energy) = through_singular_positions(&mut sim, state);
    println!("40-loop ladder, 4 s: {passages} passages, cranks apart {worst_branch:.1e}, energy {worst_energy:.1e}");
    assert!(passages >= 3, "{passages} passages through the horizontal (singular) position in 4 s");
    assert!(worst_branch < 1e-8, "cranks apart by {worst_branch:e}");
    assert!(worst_energy < 1e-6, "energy {worst_energy:e}");
}

#[test]
fn the_analyses_match_the_dense_ones() {
    use joint_runtime::analysis::dense;
    // Assembly of Bricard's mechanism from a 5° perturbation, its redundant row found.
    let scene = bricard::scene();
    let mut analysis = Analyses::new(&scene).expect("structure");
    let (mut a, mut b) = (bricard::perturbed_state(5.0), bricard::perturbed_state(5.0));
    let dense = dense::assemble(&scene, &mut a, &AssemblyOptions::default()).expect("dense assembly");
    let sparse = analysis.assemble(&mut b, &AssemblyOptions::default()).expect("sparse assembly");
    assert_eq!((sparse.iterations, sparse.redundant.len()), (dense.iterations, dense.redundant.len()));
    assert!(sparse.residual <= 1e-12);
    close("assembled", &flat(&b), &flat(&a), 1e-9);
    // Velocity and acceleration analysis of the driven Cardan shaft.
    let shaft = cardan::CardanShaft::new(0.5, 10.0).expect("valid bend");
    let mut analysis = Analyses::new(&shaft).expect("structure");
    let (mut a, mut b) = (shaft.reference_state(), shaft.reference_state());
    let dense = dense::velocities(&shaft, &mut a).expect("dense velocities");
    let sparse = analysis.velocities(&mut b).expect("sparse velocities");
    assert_eq!(sparse.redundant.len(), dense.redundant.len());
    close("velocities", &flat(&b), &flat(&a), 1e-12);
    let dense = dense::accelerations(&shaft, &a).expect("dense accelerations");
    let sparse = analysis.accelerations(&b).expect("sparse accelerations");
    close("accelerations", sparse.vdot.as_slice(), dense.vdot.as_slice(), 1e-10);
}

#[test]
fn reactions_match_the_dense_ones() {
    let scene = pendulum_chain::scene();
    let state = pendulum_chain::initial_state();
    let options = SimulationOptions::default();
    let mut dense = DenseSimulation::new(&scene, NoLoads, &[], options).expect("dense");
    let mut sparse = Simulation::new(&scene, NoLoads, &[], options).expect("sparse");
    let (d, s) = (dense.dynamics(&state).expect("dense"), sparse.dynamics(&state).expect("sparse"));
    for block in pendulum_chain::Chain::BLOCKS {
        let (a, b) = (dense.reactions(&state, &d.lambda, block), sparse.reactions(&state, &s.lambda, block));
        let flat = |r: &[joint_runtime::dynamics::Reaction]| -> Vec<f64> {
            r.iter().flat_map(|x| x.force.iter().chain(x.torque.iter()).copied().collect::<Vec<_>>()).collect()
        };
        close(block.name, &flat(&b), &flat(&a), 1e-9);
    }
}

/// `steps` generalised-α steps both ways, with `springs`: the sparse
/// saddle-point factor against the dense Schur complement, to round-off.
fn same_alpha<S, const NB: usize, const NV: usize, const M: usize, const NNZ: usize>(
    scene: &S,
    state: SystemState<NB>,
    springs: &[SpringDamper],
    steps: usize,
    h: f64,
) where
    S: Scene<NB, NV, M> + SparseJacobian<NB, NNZ> + Sync,
{
    same_implicit(scene, state, springs, steps, h, Integrator::GeneralisedAlpha);
}

/// `steps` steps of the implicit `integrator` both ways, with `springs`.
fn same_implicit<S, const NB: usize, const NV: usize, const M: usize, const NNZ: usize>(
    scene: &S,
    state: SystemState<NB>,
    springs: &[SpringDamper],
    steps: usize,
    h: f64,
    integrator: Integrator,
) where
    S: Scene<NB, NV, M> + SparseJacobian<NB, NNZ> + Sync,
{
    on_dense_stack(|| {
        let mut options = SimulationOptions::default();
        options.integrator = integrator;
        let mut dense = DenseSimulation::new(scene, NoLoads, springs, options).expect("dense");
        let mut sparse = AbsoluteSimulation::new(scene, NoLoads, springs, options).expect("sparse");
        let (mut a, mut b) = (state, state);
        let (mut dense_iterations, mut sparse_iterations) = (0, 0);
        for _ in 0..steps {
            dense_iterations += dense.step(&mut a, h).expect("dense step").newton_iterations;
            sparse_iterations += sparse.step(&mut b, h).expect("sparse step").newton_iterations;
        }
        close("state", &flat(&b), &flat(&a), 1e-9);
        // Equal but where a step stops at the round-off floor, which the two
        // factorisations reach in different last digits.
        assert!(
            sparse_iterations.abs_diff(dense_iterations) * 20 <= dense_iterations,
            "Newton iterations: sparse {sparse_iterations}, dense {dense_iterations}"
        );
    });
}

#[test]
fn generalised_alpha_on_the_four_bar() {
    same_alpha(&four_bar::scene(), four_bar::initial_state(), &[], 50, 1e-3);
}

#[test]
fn generalised_alpha_on_bricard_with_its_redundant_row() {
    same_alpha(&bricard::scene(), bricard::initial_state(), &[], 50, 1e-3);
}

#[test]
fn generalised_alpha_on_the_double_cardan_with_its_bearings() {
    let geometry = double_cardan::Geometry::new(0.4, double_cardan::Arrangement::W, double_cardan::Phasing::InPhase)
        .expect("valid bend");
    let shaft = double_cardan::DoubleCardan::new(geometry, 10.0);
    same_alpha(&shaft, shaft.initial_state().expect("consistent start"), &[], 50, 1e-3);
}

#[test]
fn generalised_alpha_on_the_stiff_press() {
    let state = press::initial_state().expect("assembled press");
    same_alpha(&press::scene(), state, &press::springs(), 100, 1e-3);
}

/// The sparse second-order blocks against the dense matrices (themselves
/// checked against differences in `tests/runtime/second_order.rs`), entry by
/// entry, and zero wherever the layout has no entry.
fn same_terms<S, const NB: usize, const NV: usize, const M: usize, const NNZ: usize>(scene: &S, state: &SystemState<NB>)
where
    S: Scene<NB, NV, M> + SparseJacobian<NB, NNZ>,
{
    let lambda = SVector::<f64, M>::from_fn(|i, _| (i as f64 * 0.7).sin());
    let u = SVector::<f64, NV>::from_fn(|i, _| (i as f64 * 1.3).cos());
    let dense = scene.second_order(state, &lambda, &u).expect("dense terms");
    let layout = SecondOrderLayout::new(S::BLOCKS, S::BLOCK_BODIES);
    let mut values = vec![0.0; layout.len()];
    assert!(!scene.second_order_values(state, &lambda, &u, &mut values[1..]), "a wrong length is refused");
    assert!(scene.second_order_values(state, &lambda, &u, &mut values), "sparse terms");
    let mut k = DMatrix::<f64>::zeros(NV, NV);
    for (bodies, block) in layout.stiffness(&values) {
        let cols: Vec<usize> = bodies.as_slice().iter().flat_map(|b| 6 * b..6 * b + 6).collect();
        for (i, &r) in cols.iter().enumerate() {
            for (j, &c) in cols.iter().enumerate() {
                k[(r, c)] += block[i * cols.len() + j];
            }
        }
    }
    close("K", k.as_slice(), dense.stiffness.as_slice(), 1e-13);
    for (term, matrix) in [
        (RowTerm::JacobianQ, &dense.jacobian_q),
        (RowTerm::GammaQ, &dense.gamma_q),
        (RowTerm::GammaV, &dense.gamma_v),
        (RowTerm::PhiTQ, &dense.phi_t_q),
    ] {
        let mut m = DMatrix::<f64>::zeros(M, NV);
        for r in 0..M {
            let (bodies, row) = layout.row(&values, term, r).expect("every row");
            for (i, c) in bodies.as_slice().iter().flat_map(|b| 6 * b..6 * b + 6).enumerate() {
                m[(r, c)] = row[i];
            }
        }
        close(&format!("{term:?}"), m.as_slice(), matrix.as_slice(), 1e-13);
    }
}

#[test]
fn sparse_second_order_terms_match_the_dense_ones() {
    same_terms(&four_bar::scene(), &four_bar::initial_state());
    same_terms(&bricard::scene(), &bricard::perturbed_state(3.0));
    same_terms(&press::scene(), &press::initial_state().expect("assembled press"));
    let geometry = double_cardan::Geometry::new(0.4, double_cardan::Arrangement::W, double_cardan::Phasing::InPhase)
        .expect("valid bend");
    let shaft = double_cardan::DoubleCardan::new(geometry, 10.0);
    same_terms(&shaft, &shaft.initial_state().expect("consistent start"));
}

/// Generalised-α options with spectral radius `rho`.
fn alpha_options(rho: f64) -> SimulationOptions {
    let mut options = SimulationOptions::default();
    options.integrator = Integrator::GeneralisedAlpha;
    options.spectral_radius = rho;
    options
}

/// The 200-body chain on the sparse generalised-α converges to the sparse RK4
/// solution (fourth order, so exact to the figures compared) at second order:
/// halving the step quarters the error.
#[test]
fn generalised_alpha_on_a_200_body_chain_converges_at_second_order() {
    let start = scaling::chain_start::<200>();
    let run = |options: SimulationOptions, h: f64| {
        let mut sim = Simulation::new(&Chain200, NoLoads, &[], options).expect("sparse");
        let mut state = start;
        let steps = (0.02 / h).round() as usize;
        for _ in 0..steps {
            let r = sim.step(&mut state, h).expect("steps");
            assert!(r.constraint_residual < 1e-10, "{r:?}");
        }
        flat(&state)
    };
    let reference = run(SimulationOptions::default(), 1e-4);
    let error = |h: f64| {
        let y = run(alpha_options(0.9), h);
        y.iter().zip(&reference).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()))
    };
    let (coarse, fine) = (error(4e-4), error(2e-4));
    let order = (coarse / fine).log2();
    println!("200-body chain, generalised-α: errors {coarse:.2e}, {fine:.2e}, order {order:.2}");
    assert!(fine < 1e-4 && coarse > fine, "errors {coarse:e}, {fine:e}");
    assert!((1.8..2.3).contains(&order), "observed order {order}");
}

/// The 40-loop ladder on the sparse generalised-α (its 120 redundant rows held):
/// through its singular positions as with RK4, every crank with the first,
/// energy kept by the undamped method (ρ∞ = 1).
#[test]
fn generalised_alpha_takes_the_40_loop_ladder_through_its_singular_positions() {
    let mut sim = Simulation::new(&Ladder40, NoLoads, &[], alpha_options(1.0)).expect("sparse");
    let state = scaling::ladder_start::<81>();
    let (passages, worst_branch, worst_energy) = through_singular_positions(&mut sim, state);
    assert_eq!(sim.factor().dropped().len(), 3 * 40);
    println!(
        "40-loop ladder, generalised-α, 4 s: {passages} passages, cranks apart {worst_branch:.1e}, energy {worst_energy:.1e}"
    );
    assert!(passages >= 3, "{passages} passages through the horizontal (singular) position in 4 s");
    assert!(worst_branch < 1e-8, "cranks apart by {worst_branch:e}");
    assert!(worst_energy < 1e-4, "energy {worst_energy:e}");
}

/// A scene derived without `second_order`: the sparse implicit steps build
/// their Newton matrices from central differences of the generated J, γ and
/// Φ_t (`DifferenceTerms`, two colours for a chain of any length) and take
/// the steps the generated terms take, in as many Newton iterations.
#[test]
fn implicit_steps_without_second_order_terms_take_differences() {
    joint_examples::chain_scene!(Plain5, 5);
    joint_examples::chain_scene!(Full5, 5, second_order);
    let start = scaling::chain_start::<5>();
    for integrator in [Integrator::GeneralisedAlpha, Integrator::ImplicitMidpoint] {
        let options = alpha_options(0.9).with_integrator(integrator);
        let mut plain = Simulation::new(&Plain5, NoLoads, &[], options).expect("sparse");
        let mut full = Simulation::new(&Full5, NoLoads, &[], options).expect("sparse");
        let (mut a, mut b, mut iterations) = (start, start, [0, 0]);
        for _ in 0..100 {
            iterations[0] += plain.step(&mut a, 2e-3).expect("differences").newton_iterations;
            iterations[1] += full.step(&mut b, 2e-3).expect("generated").newton_iterations;
        }
        let gap =
            a.bodies.iter().zip(&b.bodies).map(|(x, y)| (x.r - y.r).norm() + (x.rdot - y.rdot).norm()).sum::<f64>();
        println!(
            "{integrator:?} on a 5-bar chain, 0.2 s: differences against generated terms {gap:.1e}, Newton iterations {iterations:?}"
        );
        assert!(gap < 1e-9, "{integrator:?}: {gap:e}");
        assert!(iterations[0] <= iterations[1] + 10, "{integrator:?}: {iterations:?}");
    }
}

/// Error-controlled integration both ways with `springs`: the one driver over
/// the dense and the sparse steps takes the same steps (accepted and rejected)
/// to the same state.
fn same_integrate<S, const NB: usize, const NV: usize, const M: usize, const NNZ: usize>(
    scene: &S,
    state: SystemState<NB>,
    springs: &[SpringDamper],
    t_end: f64,
    method: Adaptive,
) where
    S: Scene<NB, NV, M> + SparseJacobian<NB, NNZ> + Sync,
{
    on_dense_stack(|| {
        let options = SimulationOptions::default();
        let tolerance = Tolerance { rtol: 1e-6, atol: 1e-6 };
        let mut dense = DenseSimulation::new(scene, NoLoads, springs, options).expect("dense");
        let mut sparse = AbsoluteSimulation::new(scene, NoLoads, springs, options).expect("sparse");
        // Made for RK4: an implicit method's workspace is made here, not by
        // `integrate` (which never allocates).
        sparse.prepare(Integrator::RadauIIA).expect("prepared");
        let (mut a, mut b) = (state, state);
        let d = dense.integrate(&mut a, t_end, method, tolerance).expect("dense integrate");
        let s = sparse.integrate(&mut b, t_end, method, tolerance).expect("sparse integrate");
        println!("{method:?}: dense {d:?}\n    sparse {s:?}");
        assert_eq!((b.t, a.t), (t_end, t_end));
        assert!(d.accepted > 3, "{d:?}");
        assert_eq!((s.accepted, s.rejected), (d.accepted, d.rejected), "steps");
        assert_eq!(s.evaluations, d.evaluations, "stages");
        close("state", &flat(&b), &flat(&a), 1e-8);
        // Back to fixed steps: RK4 again, whatever integrate ran.
        let report = sparse.step(&mut b, 1e-4).expect("a fixed step after integrate");
        assert_eq!(report.newton_iterations, 0, "RK4 after integrate: {report:?}");
    });
}

#[test]
fn dormand_prince_on_bricard_and_the_double_cardan() {
    same_integrate(&bricard::scene(), bricard::initial_state(), &[], 0.2, Adaptive::DormandPrince);
    let geometry = double_cardan::Geometry::new(0.4, double_cardan::Arrangement::W, double_cardan::Phasing::InPhase)
        .expect("valid bend");
    let shaft = double_cardan::DoubleCardan::new(geometry, 10.0);
    same_integrate(&shaft, shaft.initial_state().expect("consistent start"), &[], 0.1, Adaptive::DormandPrince);
}

#[test]
fn adaptive_generalised_alpha_on_the_four_bar_and_the_stiff_press() {
    same_integrate(&four_bar::scene(), four_bar::initial_state(), &[], 0.2, Adaptive::GeneralisedAlpha);
    let state = press::initial_state().expect("assembled press");
    same_integrate(&press::scene(), state, &press::springs(), 0.05, Adaptive::GeneralisedAlpha);
}

/// The 200-body chain with error-controlled steps, against the sparse RK4
/// at a step 20 times below Dormand–Prince's: the error follows the
/// tolerance, and the implicit method with its estimate gets there too.
#[test]
fn error_controlled_steps_on_a_200_body_chain() {
    let start = scaling::chain_start::<200>();
    let t_end = 0.02;
    let mut reference = start;
    let mut sim = Simulation::new(&Chain200, NoLoads, &[], SimulationOptions::default()).expect("sparse");
    sim.prepare(Integrator::GeneralisedAlpha).expect("prepared");
    for _ in 0..200 {
        sim.step(&mut reference, t_end / 200.0).expect("reference steps");
    }
    let worst =
        |y: &SystemState<200>| flat(y).iter().zip(flat(&reference)).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
    let mut errors = Vec::new();
    for (method, tol) in
        [(Adaptive::DormandPrince, 1e-6), (Adaptive::DormandPrince, 1e-9), (Adaptive::GeneralisedAlpha, 1e-5)]
    {
        let mut state = start;
        let report = sim.integrate(&mut state, t_end, method, Tolerance { rtol: tol, atol: tol }).expect("integrate");
        let error = worst(&state);
        println!("{method:?}, tolerance {tol:e}: error {error:.2e}, {report:?}");
        assert_eq!(state.t, t_end);
        assert!(error < 100.0 * tol, "{method:?} at {tol:e}: error {error:e}");
        errors.push((error, report));
    }
    // A tighter tolerance costs more steps and gives a smaller error.
    assert!(errors[1].1.accepted > errors[0].1.accepted && errors[1].0 < errors[0].0, "{errors:?}");
    assert!(errors[2].1.newton_iterations > 0 && errors[2].1.evaluations == 0, "{:?}", errors[2]);
}

/// The implicit midpoint rule both ways: the sparse saddle-point Newton
/// matrix against the dense `I − (h/2) ∂a/∂w`, both exact.
#[test]
fn implicit_midpoint_on_the_example_scenes() {
    let midpoint = Integrator::ImplicitMidpoint;
    same_implicit(&four_bar::scene(), four_bar::initial_state(), &[], 50, 1e-3, midpoint);
    same_implicit(&bricard::scene(), bricard::initial_state(), &[], 50, 1e-3, midpoint);
    let geometry = double_cardan::Geometry::new(0.4, double_cardan::Arrangement::W, double_cardan::Phasing::InPhase)
        .expect("valid bend");
    let shaft = double_cardan::DoubleCardan::new(geometry, 10.0);
    same_implicit(&shaft, shaft.initial_state().expect("consistent start"), &[], 50, 1e-3, midpoint);
    let state = press::initial_state().expect("assembled press");
    same_implicit(&press::scene(), state, &press::springs(), 100, 1e-3, midpoint);
}

/// The 200-body chain on the sparse implicit midpoint rule converges to the
/// sparse RK4 solution at second order, with few Newton iterations a step
/// (the exact matrix: quadratic convergence).
#[test]
fn implicit_midpoint_on_a_200_body_chain_converges_at_second_order() {
    let start = scaling::chain_start::<200>();
    let run = |integrator: Integrator, h: f64| {
        let mut options = SimulationOptions::default();
        options.integrator = integrator;
        let mut sim = Simulation::new(&Chain200, NoLoads, &[], options).expect("sparse");
        let (mut state, mut iterations) = (start, 0);
        let steps = (0.02 / h).round() as usize;
        for _ in 0..steps {
            iterations += sim.step(&mut state, h).expect("steps").newton_iterations;
        }
        (flat(&state), iterations as f64 / steps as f64)
    };
    let (reference, _) = run(Integrator::Rk4, 1e-4);
    let error = |h: f64| {
        let (y, per_step) = run(Integrator::ImplicitMidpoint, h);
        (y.iter().zip(&reference).fold(0.0f64, |m, (a, b)| m.max((a - b).abs())), per_step)
    };
    let ((coarse, it_coarse), (fine, it_fine)) = (error(4e-4), error(2e-4));
    let order = (coarse / fine).log2();
    println!(
        "200-body chain, implicit midpoint: errors {coarse:.2e}, {fine:.2e}, order {order:.2}; Newton iterations a step {it_coarse:.1}, {it_fine:.1}"
    );
    assert!(fine < 1e-4 && coarse > fine, "errors {coarse:e}, {fine:e}");
    assert!((1.8..2.3).contains(&order), "observed order {order}");
    assert!(it_coarse <= 4.0 && it_fine <= 4.0, "Newton iterations a step: {it_coarse}, {it_fine}");
}

/// The 40-loop ladder on the sparse implicit midpoint rule (its 120 redundant
/// rows held at δλ = 0): through its singular positions as with RK4.
#[test]
fn implicit_midpoint_takes_the_40_loop_ladder_through_its_singular_positions() {
    let mut options = SimulationOptions::default();
    options.integrator = Integrator::ImplicitMidpoint;
    let mut sim = Simulation::new(&Ladder40, NoLoads, &[], options).expect("sparse");
    let (passages, worst_branch, worst_energy) = through_singular_positions(&mut sim, scaling::ladder_start::<81>());
    assert_eq!(sim.factor().dropped().len(), 3 * 40);
    println!(
        "40-loop ladder, implicit midpoint, 4 s: {passages} passages, cranks apart {worst_branch:.1e}, energy {worst_energy:.1e}"
    );
    assert!(passages >= 3, "{passages} passages through the horizontal (singular) position in 4 s");
    assert!(worst_branch < 1e-8, "cranks apart by {worst_branch:e}");
    assert!(worst_energy < 1e-4, "energy {worst_energy:e}");
}

/// The saddle-point pattern found at run time (a spring between bodies no
/// joint joins: the four-bar's first and last crank) against the derive's:
/// with no stiffness and no damping the spring changes only the order of
/// elimination, so generalised-α, the midpoint rule and Radau IIA take the
/// same steps to round-off.
#[test]
fn a_spring_outside_the_derived_pattern_gets_a_run_time_one() {
    use joint_runtime::dynamics::Attachment;
    let scene = four_bar::scene();
    let idle = [SpringDamper {
        a: Attachment::Body { body: 0, point: SVector::zeros() },
        b: Attachment::Body { body: 8, point: SVector::zeros() },
        stiffness: 0.0,
        damping: 0.0,
        rest_length: 1.0,
    }];
    for integrator in [Integrator::GeneralisedAlpha, Integrator::ImplicitMidpoint, Integrator::RadauIIA] {
        let mut options = alpha_options(0.9);
        options.integrator = integrator;
        let mut derived = Simulation::new(&scene, NoLoads, &[], options).expect("derived pattern");
        let mut found = Simulation::new(&scene, NoLoads, &idle, options).expect("run-time pattern");
        let (mut a, mut b) = (four_bar::initial_state(), four_bar::initial_state());
        for _ in 0..20 {
            derived.step(&mut a, 1e-3).expect("step");
            found.step(&mut b, 1e-3).expect("step");
        }
        close(&format!("{integrator:?}"), &flat(&b), &flat(&a), 1e-12);
        assert_ne!(derived.iteration_blocks(), found.iteration_blocks(), "{integrator:?}: the patterns differ");
    }
}

/// Switching integrators between steps: generalised-α starts afresh after a
/// step of another one (its history would be stale), exactly as a new
/// simulation would from that state.
#[test]
fn generalised_alpha_starts_afresh_after_another_integrator() {
    let scene = four_bar::scene();
    let mut sim = Simulation::new(&scene, NoLoads, &[], alpha_options(0.9)).expect("sparse");
    let mut state = four_bar::initial_state();
    for _ in 0..3 {
        sim.step(&mut state, 1e-3).expect("generalised-α");
    }
    sim.options.integrator = Integrator::ImplicitMidpoint;
    sim.step(&mut state, 1e-3).expect("midpoint");
    let mut fresh = Simulation::new(&scene, NoLoads, &[], alpha_options(0.9)).expect("sparse");
    let mut other = state;
    sim.options.integrator = Integrator::GeneralisedAlpha;
    sim.step(&mut state, 1e-3).expect("generalised-α again");
    fresh.step(&mut other, 1e-3).expect("a fresh generalised-α");
    assert_eq!(flat(&state), flat(&other));
}

/// Stiff user loads enter the sparse Newton matrices (on the pattern's
/// blocks, three colours of bodies for a chain): a viscous drag on every bar
/// and a stiff spring between neighbouring bars' centres, written as a
/// closure (so differenced), take the dense path's steps in as many Newton
/// iterations with the implicit midpoint rule, generalised-α and Radau IIA.
#[test]
fn stiff_user_loads_enter_the_sparse_newton_matrices() {
    joint_examples::chain_scene!(Full5, 5, second_order);
    let start = scaling::chain_start::<5>();
    let loads = |s: &SystemState<5>, l: &mut Loads<5>| {
        for b in 0..5 {
            l.force[b] -= s.bodies[b].rdot * 300.0;
            l.torque[b] -= s.bodies[b].omega * 30.0;
        }
        for b in 1..5 {
            let d = s.bodies[b].r - s.bodies[b - 1].r;
            let f = d * (2e4 * (d.norm() - 1.0) / d.norm());
            l.force[b] -= f;
            l.force[b - 1] += f;
        }
    };
    for integrator in [Integrator::ImplicitMidpoint, Integrator::GeneralisedAlpha, Integrator::RadauIIA] {
        let options = SimulationOptions::default().with_integrator(integrator);
        let mut dense = DenseSimulation::new(&Full5, loads, &[], options).expect("dense");
        let mut sparse = Simulation::new(&Full5, loads, &[], options).expect("sparse");
        let (mut a, mut b, mut iterations) = (start, start, [0, 0]);
        for _ in 0..50 {
            iterations[0] += dense.step(&mut a, 2e-3).expect("dense").newton_iterations;
            iterations[1] += sparse.step(&mut b, 2e-3).expect("sparse").newton_iterations;
        }
        let gap = a.bodies.iter().zip(&b.bodies).map(|(x, y)| (x.r - y.r).norm()).fold(0.0, f64::max);
        println!(
            "{integrator:?}, stiff user loads: dense and sparse {gap:.1e} apart, Newton iterations {iterations:?}"
        );
        assert!(gap < 1e-9, "{integrator:?}: {gap:e}");
        assert!(iterations[1] * 10 <= iterations[0] * 11 + 10, "{integrator:?}: {iterations:?}");
    }
}
