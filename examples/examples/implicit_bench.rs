//! The implicit midpoint rule with the generated iteration matrix
//! (`NewtonMatrix::Generated`, from `#[scene(second_order)]`) against the
//! finite-difference one it replaces, on four closed-loop mechanisms with
//! redundant rows: the IFToMM N-four-bar (A02) with 4 loops (9 bodies, 65
//! rows, 54 columns) and with 3 (7 bodies, ten spatial revolute joints, 50 ×
//! 42, 9 redundant rows: the size of the issue's seven-body planar linkage),
//! the Bricard mechanism (5 bodies, 30 × 30) and the free double Cardan shaft
//! (3 bodies). Projection on, `h = 1 ms`, `STEPS` steps from the
//! same start; the two matrices alternate round by round (`ROUNDS` rounds) and
//! each row gives the median over rounds of µs per step, with Newton
//! iterations and iteration matrices per step and how far apart the two runs
//! end. Both run on `Simulation`: the generated matrix is the exact
//! saddle-point matrix over bodies and joints, the differences' the same
//! pattern filled by central differences of `J`, `γ` and `Φ_t`.
//!
//! ```text
//! cargo run --release -p joint-examples --features bench --example implicit_bench
//! ```

use std::time::Instant;

use joint_examples::double_cardan::{Arrangement, DoubleCardan, FreeDoubleCardan, Geometry, Phasing};
use joint_examples::{bricard, four_bar};
use joint_runtime::dynamics::{AbsoluteSimulation, Integrator, NewtonMatrix, NoLoads, SimulationOptions, StepReport};
use joint_runtime::{Scene, SparseJacobian, SystemState};

const STEPS: usize = 500;

/// The N-four-bar with three loops (`joint_examples::scaling::ladder_scene!`
/// with `second_order`).
#[derive(joint_runtime::Scene, Clone, Copy, Debug, Default)]
#[scene(coordinates = absolute, gravity = [0, -9.81, 0], second_order)]
#[body(crank[4], mass = 1.0, inertia = [0.08333333333333333, 0.08333333333333333, 0.08333333333333333])]
#[body(coupler[3], mass = 1.0, inertia = [0.08333333333333333, 0.08333333333333333, 0.08333333333333333])]
#[joint(pin[i in 0..4] = revolute(ground, crank[i]), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [i, 0, 0], rho2 = [0, -0.5, 0])]
#[joint(left[i in 0..3] = revolute(crank[i], coupler[i]), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0, 0.5, 0], rho2 = [-0.5, 0, 0])]
#[joint(right[i in 0..3] = revolute(crank[i + 1], coupler[i]), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0, 0.5, 0], rho2 = [0.5, 0, 0])]
struct Ladder3;
const ROUNDS: usize = 7;
const H: f64 = 1e-3;

/// One run: µs per step, Newton iterations and matrices per step, the end state.
type Run<const NB: usize> = (f64, f64, f64, SystemState<NB>);

/// `STEPS` steps of `step` from `start`, timed.
fn timed<const NB: usize>(
    start: &SystemState<NB>,
    mut step: impl FnMut(&mut SystemState<NB>) -> Result<StepReport, joint_runtime::analysis::AnalysisError>,
) -> Result<Run<NB>, Box<dyn std::error::Error>> {
    let mut state = *start;
    let (mut iterations, mut matrices) = (0, 0);
    let clock = Instant::now();
    for _ in 0..STEPS {
        let report = step(&mut state)?;
        iterations += report.newton_iterations;
        matrices += report.newton_matrices;
    }
    let us = clock.elapsed().as_secs_f64() * 1e6 / STEPS as f64;
    Ok((us, iterations as f64 / STEPS as f64, matrices as f64 / STEPS as f64, state))
}

fn run<S, const NB: usize, const NV: usize, const M: usize, const NNZ: usize>(
    scene: &S,
    start: &SystemState<NB>,
    matrix: NewtonMatrix,
) -> Result<Run<NB>, Box<dyn std::error::Error>>
where
    S: Scene<NB, NV, M> + SparseJacobian<NB, NNZ>,
{
    let options = SimulationOptions::default().with_integrator(Integrator::ImplicitMidpoint).with_newton_matrix(matrix);
    let mut sim = AbsoluteSimulation::new(scene, NoLoads, &[], options)?;
    timed(start, |state| sim.step(state, H))
}

fn median(mut x: Vec<f64>) -> f64 {
    x.sort_by(f64::total_cmp);
    x[x.len() / 2]
}

fn row<S, const NB: usize, const NV: usize, const M: usize, const NNZ: usize>(
    name: &str,
    scene: &S,
    start: &SystemState<NB>,
) -> Result<(), Box<dyn std::error::Error>>
where
    S: Scene<NB, NV, M> + SparseJacobian<NB, NNZ>,
{
    let (mut generated, mut differences) = (Vec::new(), Vec::new());
    let (mut g, mut d) = ((0.0, 0.0, *start), (0.0, 0.0, *start));
    for _ in 0..ROUNDS {
        let a = run(scene, start, NewtonMatrix::Generated)?;
        let b = run(scene, start, NewtonMatrix::FiniteDifferences)?;
        generated.push(a.0);
        differences.push(b.0);
        g = (a.1, a.2, a.3);
        d = (b.1, b.2, b.3);
    }
    let apart =
        |x: &SystemState<NB>| x.bodies.iter().zip(&d.2.bodies).map(|(x, y)| (x.r - y.r).norm()).fold(0.0, f64::max);
    let (tg, td) = (median(generated), median(differences));
    println!(
        "| {name} | {NB} | {M} × {NV} | {td:.1} | {tg:.1} | {:.1} | {:.2} / {:.2} | {:.2} / {:.2} | {:.1e} |",
        td / tg,
        d.0,
        g.0,
        d.1,
        g.1,
        apart(&g.2),
    );
    Ok(())
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    println!(
        "Implicit midpoint, projection, h = {} ms, {STEPS} steps, median of {ROUNDS} alternating rounds.\n",
        H * 1e3
    );
    println!(
        "| mechanism | bodies | J | differences µs/step | generated µs/step | speed-up | iterations/step (diff / gen) | matrices/step (diff / gen) | end states apart (m) |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    row("N-four-bar, 4 loops", &four_bar::scene(), &four_bar::initial_state())?;
    row("N-four-bar, 3 loops", &Ladder3, &joint_examples::scaling::ladder_start::<7>())?;
    row("Bricard (falls from rest)", &bricard::scene(), &bricard::initial_state())?;
    let geometry = Geometry::new(30f64.to_radians(), Arrangement::Z, Phasing::InPhase).ok_or("geometry")?;
    let start = DoubleCardan::new(geometry, 10.0).initial_state()?;
    row("double Cardan, free", &FreeDoubleCardan::new(&geometry), &start)?;
    Ok(())
}
