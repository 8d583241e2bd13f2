//! µs per RK4 step (h = 1 ms, projection after every step) of the scenes the
//! peers are timed on (`../shared/peers/`: MuJoCo's `bench_step`, Pinocchio's
//! `bench_tree`): the chain of N bars on spherical joints and the arm of N
//! bars on revolute joints (axes z, y, z, …). One JSON line, like the peers',
//! so that both can be run alternately in one session.
//!
//! ```text
//! cargo run --release -p joint-examples --features bench --example peer_bench -- chain 10 [STEPS] [ROUNDS]
//! cargo run --release -p joint-examples --features bench --example peer_bench -- arm 6 [STEPS] [ROUNDS]
//! cargo run --release -p joint-examples --features bench --example peer_bench -- double-cardan 3 [STEPS] [ROUNDS]
//! ```
//!
//! `double-cardan 3` is `step_bench`'s free double Cardan shaft (3 bodies,
//! 19 rows, 10 rad/s), which has no peer; `four-bar 4` and `bricard 5` are
//! the IFToMM benchmarks A02 and A04 (closed loops; no peer here either),
//! in both coordinate choices. With `STACK_KIB=n` in the
//! environment the steps run in a thread with an `n` KiB stack (the
//! simulation is built and boxed on the main thread; a step that needs more
//! aborts the process: how the stack a step needs is found). With
//! `INTEGRATOR=alpha`, `midpoint` or `radau` the steps are that implicit
//! integrator's (RK4 otherwise), so that their stack can be measured too.
//! With `COORDINATES=relative` the chains, arms and loops run in relative
//! coordinates (`joint_runtime::relative`, RK4, the same start converted);
//! `COORDINATES=default` runs the 6-bar arm declared with no word about
//! coordinates, through the one `Simulation::new` (whatever the scene gets); with
//! `MEASURE=dynamics` as well, `STEPS` calls of inverse dynamics and of the
//! mass matrix are timed instead (ns per call, at the state a MuJoCo harness
//! can time `mj_inverse` and `mj_fullM` at).
//!
//! `H=1e-4` (say) steps by that instead of 1 ms: a reference for the error
//! of the 1 ms steps at the same time (`STEPS` × `H`).
//!
//! Each round restarts from the scene's start and times `STEPS` steps; the
//! median round is printed with the tip (the last bar's end at `(0.5, 0, 0)`)
//! after the round, which the peers print too (the arm of 6 after 2 s:
//! `(-3.59644741, 0, -0.88653365)`).

use std::time::Instant;

use joint_examples::double_cardan::{Arrangement, DoubleCardan, FreeDoubleCardan, Geometry, Phasing};
use joint_examples::scaling::chain_start;
use joint_examples::{bricard, four_bar};
use joint_runtime::dynamics::{AbsoluteSimulation, Integrator, NoLoads, Simulation, SimulationOptions};
use joint_runtime::nalgebra::{UnitQuaternion, Vector3};
use joint_runtime::relative::{TreeScene, TreeSimulation};
use joint_runtime::{OmegaBody, Scene, SparseJacobian, SystemState};

joint_examples::chain_scene!(Chain3, 3, coordinates = both);
joint_examples::chain_scene!(Chain5, 5, coordinates = both);
joint_examples::chain_scene!(Chain10, 10, coordinates = both);
joint_examples::chain_scene!(Chain20, 20, coordinates = both);
joint_examples::chain_scene!(Chain40, 40, coordinates = both);
joint_examples::chain_scene!(Chain160, 160, coordinates = both);

/// Declares an arm of bars `bar[$n]` on revolute joints: `$base` on the
/// ground, then `$name = (parent, child, axis)` for the rest.
macro_rules! arm_scene {
    ($scene:ident, $n:tt, $(($joint:ident, $parent:tt, $child:tt, $axis:tt)),*) => {
        /// An arm of bars on revolute joints, axes alternating z and y.
        #[derive(joint_runtime::Scene, Clone, Copy, Debug, Default)]
        #[scene(gravity = [0, 0, -9.81], coordinates = both)]
        #[body(bar[$n], mass = 1.0, inertia = [0.00125, 0.08395833333333333, 0.08395833333333333])]
        #[joint(base = revolute(ground, bar[0]), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0, 0, 0], rho2 = [-0.5, 0, 0])]
        $(#[joint($joint = revolute(bar[$parent], bar[$child]), axis1 = $axis, axis2 = $axis, rho1 = [0.5, 0, 0], rho2 = [-0.5, 0, 0])])*
        struct $scene;
    };
}

arm_scene!(Arm2, 2, (j2, 0, 1, [0, 1, 0]));
arm_scene!(
    Arm6,
    6,
    (j2, 0, 1, [0, 1, 0]),
    (j3, 1, 2, [0, 0, 1]),
    (j4, 2, 3, [0, 1, 0]),
    (j5, 3, 4, [0, 0, 1]),
    (j6, 4, 5, [0, 1, 0])
);
arm_scene!(
    Arm12,
    12,
    (j2, 0, 1, [0, 1, 0]),
    (j3, 1, 2, [0, 0, 1]),
    (j4, 2, 3, [0, 1, 0]),
    (j5, 3, 4, [0, 0, 1]),
    (j6, 4, 5, [0, 1, 0]),
    (j7, 5, 6, [0, 0, 1]),
    (j8, 6, 7, [0, 1, 0]),
    (j9, 7, 8, [0, 0, 1]),
    (j10, 8, 9, [0, 1, 0]),
    (j11, 9, 10, [0, 0, 1]),
    (j12, 10, 11, [0, 1, 0])
);

/// The 6-bar arm as a newcomer declares it: no word about coordinates
/// (`COORDINATES=default`, made by the one `Simulation::new`).
#[derive(joint_runtime::Scene, Clone, Copy, Debug, Default)]
#[scene(gravity = [0, 0, -9.81])]
#[body(bar[6], mass = 1.0, inertia = [0.00125, 0.08395833333333333, 0.08395833333333333])]
#[joint(base = revolute(ground, bar[0]), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0, 0, 0], rho2 = [-0.5, 0, 0])]
#[joint(j2 = revolute(bar[0], bar[1]), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0.5, 0, 0], rho2 = [-0.5, 0, 0])]
#[joint(j3 = revolute(bar[1], bar[2]), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0.5, 0, 0], rho2 = [-0.5, 0, 0])]
#[joint(j4 = revolute(bar[2], bar[3]), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0.5, 0, 0], rho2 = [-0.5, 0, 0])]
#[joint(j5 = revolute(bar[3], bar[4]), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0.5, 0, 0], rho2 = [-0.5, 0, 0])]
#[joint(j6 = revolute(bar[4], bar[5]), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0.5, 0, 0], rho2 = [-0.5, 0, 0])]
struct Arm6Undeclared;

/// The arm's start: bar `i` centred at `(i + 0.5, 0, 0)`, unrotated, at rest.
fn arm_start<const NB: usize>() -> SystemState<NB> {
    let bodies = core::array::from_fn(|i| {
        let r = Vector3::new(i as f64 + 0.5, 0.0, 0.0);
        OmegaBody::from_rotation(r, &UnitQuaternion::identity(), Vector3::zeros(), Vector3::zeros())
    });
    SystemState { bodies, t: 0.0 }
}

/// Times `rounds` runs of `steps` steps and prints the JSON line.
fn run<S, const NB: usize, const NV: usize, const M: usize, const NNZ: usize>(
    name: &str,
    scene: &S,
    start: SystemState<NB>,
    steps: usize,
    rounds: usize,
) -> Result<(), Box<dyn std::error::Error>>
where
    S: Scene<NB, NV, M> + SparseJacobian<NB, NNZ> + Sync,
{
    // Built here, on the main thread's stack, and boxed: what a step needs is
    // measured apart from what building the simulation needs.
    let integrator = match std::env::var("INTEGRATOR").as_deref() {
        Ok("alpha") => Integrator::GeneralisedAlpha,
        Ok("midpoint") => Integrator::ImplicitMidpoint,
        Ok("radau") => Integrator::RadauIIA,
        _ => Integrator::Rk4,
    };
    let mut options = SimulationOptions::default();
    options.integrator = integrator;
    let mut sim = Box::new(AbsoluteSimulation::new(scene, NoLoads, &[], options)?);
    let (start, mut end) = (Box::new(start), Box::new(start));
    let mut us = Vec::with_capacity(rounds);
    let mut time = || -> Result<(), String> {
        for _ in 0..rounds {
            *end = *start;
            let clock = Instant::now();
            for _ in 0..steps {
                sim.step(&mut end, step()).map_err(|e| e.to_string())?;
            }
            us.push(clock.elapsed().as_secs_f64() * 1e6 / steps as f64);
        }
        Ok(())
    };
    match std::env::var("STACK_KIB").ok().and_then(|s| s.parse::<usize>().ok()) {
        Some(kib) => std::thread::scope(|scope| {
            std::thread::Builder::new()
                .stack_size(kib << 10)
                .spawn_scoped(scope, time)?
                .join()
                .map_err(|_| "the stepping thread panicked")?
                .map_err(Box::<dyn std::error::Error>::from)
        })?,
        None => time()?,
    }
    us.sort_by(f64::total_cmp);
    print(name, NB, M, steps, &us, &end.bodies[NB - 1], end.t);
    Ok(())
}

/// [`run`] in relative coordinates: the same start, converted to the
/// scene's tree.
fn run_tree<S, const NB: usize, const NQ: usize, const NV: usize, const NC: usize>(
    name: &str,
    scene: &S,
    start: SystemState<NB>,
    steps: usize,
    rounds: usize,
) -> Result<(), Box<dyn std::error::Error>>
where
    S: TreeScene<NB, NQ, NV, NC>,
{
    let mut sim = Box::new(TreeSimulation::new(scene)?);
    if std::env::var("MEASURE").as_deref() == Ok("dynamics") {
        return time_dynamics(name, &sim, steps, rounds);
    }
    time_tree(name, &mut sim, start, steps, rounds)
}

/// The steps of [`run_tree`] on a simulation made already.
fn time_tree<S, const NB: usize, const NQ: usize, const NV: usize, const NC: usize>(
    name: &str,
    sim: &mut TreeSimulation<S, NB, NQ, NV, NC>,
    start: SystemState<NB>,
    steps: usize,
    rounds: usize,
) -> Result<(), Box<dyn std::error::Error>>
where
    S: TreeScene<NB, NQ, NV, NC>,
{
    let start = sim.tree().tree_state(&start, 1e-12)?;
    let mut end = start;
    let mut us = Vec::with_capacity(rounds);
    for _ in 0..rounds {
        end = start;
        let clock = Instant::now();
        for _ in 0..steps {
            sim.step(&mut end, step())?;
        }
        us.push(clock.elapsed().as_secs_f64() * 1e6 / steps as f64);
    }
    us.sort_by(f64::total_cmp);
    let system = sim.tree().system_state(&end);
    print(name, NB, NV, steps, &us, &system.bodies[NB - 1], end.t);
    Ok(())
}

/// ns per call of inverse dynamics (from `q, v, v̇`) and of the mass matrix
/// (from `q`), written out by the derive where it wrote them, at a state a MuJoCo harness can reproduce for `mj_inverse`
/// and `mj_fullM` (`q_i = 0.3 (7i mod 5) − 0.6`, `v_i = 0.2 (3i mod 7) − 0.6`,
/// `v̇_i = 0.5 (5i mod 3) − 0.5`, revolute joints only); prints `τ` too.
fn time_dynamics<S, const NB: usize, const NQ: usize, const NV: usize, const NC: usize>(
    name: &str,
    sim: &TreeSimulation<S, NB, NQ, NV, NC>,
    calls: usize,
    rounds: usize,
) -> Result<(), Box<dyn std::error::Error>>
where
    S: TreeScene<NB, NQ, NV, NC>,
{
    use joint_runtime::nalgebra::{SMatrix, SVector};
    let mut state = sim.tree().zero_state();
    state.q = SVector::from_fn(|i, _| 0.3 * ((i * 7) % 5) as f64 - 0.6);
    state.v = SVector::from_fn(|i, _| 0.2 * ((i * 3) % 7) as f64 - 0.6);
    let vdot = SVector::<f64, NV>::from_fn(|i, _| 0.5 * ((i * 5) % 3) as f64 - 0.5);
    let tau = sim.inverse_dynamics(&state, &vdot);
    println!("tau {}", tau.iter().map(|x| format!("{x:.12}")).collect::<Vec<_>>().join(" "));
    let (mut inverse, mut mass) = (Vec::new(), Vec::new());
    let mut matrix = Box::new(SMatrix::<f64, NV, NV>::zeros());
    let mut sink = 0.0;
    for _ in 0..rounds {
        let clock = Instant::now();
        for _ in 0..calls {
            state.q[0] += 1e-12;
            sink += std::hint::black_box(sim.inverse_dynamics(&state, &vdot))[0];
        }
        inverse.push(clock.elapsed().as_secs_f64() * 1e9 / calls as f64);
        let clock = Instant::now();
        for _ in 0..calls {
            state.q[0] += 1e-12;
            sim.mass_matrix_into(&state.q, &mut matrix);
            sink += std::hint::black_box(matrix[(0, 0)]);
        }
        mass.push(clock.elapsed().as_secs_f64() * 1e9 / calls as f64);
    }
    inverse.sort_by(f64::total_cmp);
    mass.sort_by(f64::total_cmp);
    println!(
        "{{\"peer\":\"joint\",\"scene\":\"{name}\",\"nv\":{NV},\"ns_inverse\":{:.1},\"ns_mass_matrix\":{:.1},\"sink\":{sink:e}}}",
        inverse[rounds / 2],
        mass[rounds / 2]
    );
    Ok(())
}

/// The step: 1 ms, or `H` from the environment (a finer reference run, to
/// measure the error of the 1 ms steps).
fn step() -> f64 {
    std::env::var("H").ok().and_then(|s| s.parse().ok()).unwrap_or(1e-3)
}

/// The JSON line: the median round, its spread, the tip and the last body's centre.
fn print(name: &str, bodies: usize, rows: usize, steps: usize, us: &[f64], last: &OmegaBody<f64>, t: f64) {
    let tip = last.point(&Vector3::new(0.5, 0.0, 0.0));
    println!(
        "{{\"peer\":\"joint\",\"scene\":\"{name}\",\"bodies\":{bodies},\"rows\":{rows},\"steps\":{steps},\
         \"us_per_step\":{:.4},\"us_min\":{:.4},\"us_max\":{:.4},\"tip\":[{:.10},{:.10},{:.10}],\
         \"centre\":[{:.10},{:.10},{:.10}],\"time\":{:.6}}}",
        us[us.len() / 2],
        us[0],
        us[us.len() - 1],
        tip.x,
        tip.y,
        tip.z,
        last.r.x,
        last.r.y,
        last.r.z,
        t
    );
}

/// Parses the command line and runs the scene it names.
fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let kind = args.first().map_or("chain", String::as_str);
    let n: usize = args.get(1).map_or(Ok(10), |s| s.parse())?;
    let steps: usize = args.get(2).map_or(Ok(2000), |s| s.parse())?;
    let rounds: usize = args.get(3).map_or(Ok(3), |s| s.parse())?;
    let name = format!("{kind}{n}");
    let relative = std::env::var("COORDINATES").as_deref() == Ok("relative");
    if std::env::var("COORDINATES").as_deref() == Ok("default") {
        let options = SimulationOptions::default();
        let mut sim = Box::new(Simulation::new(&Arm6Undeclared, NoLoads, &[], options)?.into_engine());
        return time_tree("arm6-default", &mut sim, arm_start(), steps, rounds);
    }
    // Each chain and arm in the coordinates asked for.
    macro_rules! go {
        ($scene:expr, $start:expr) => {
            if relative {
                run_tree(&name, &$scene, $start, steps, rounds)
            } else {
                run(&name, &$scene, $start, steps, rounds)
            }
        };
    }
    match (kind, n) {
        ("chain", 3) => go!(Chain3, chain_start()),
        ("chain", 5) => go!(Chain5, chain_start()),
        ("chain", 10) => go!(Chain10, chain_start()),
        ("chain", 20) => go!(Chain20, chain_start()),
        ("chain", 40) => go!(Chain40, chain_start()),
        ("chain", 160) => go!(Chain160, chain_start()),
        ("arm", 2) => go!(Arm2, arm_start()),
        ("arm", 6) => go!(Arm6, arm_start()),
        ("arm", 12) => go!(Arm12, arm_start()),
        ("four-bar", 4) => go!(four_bar::scene(), four_bar::initial_state()),
        ("bricard", 5) => go!(bricard::scene(), bricard::initial_state()),
        ("double-cardan", 3) => {
            let geometry = Geometry::new(30f64.to_radians(), Arrangement::Z, Phasing::InPhase).ok_or("geometry")?;
            let start = DoubleCardan::new(geometry, 10.0).initial_state()?;
            go!(FreeDoubleCardan::new(&geometry), start)
        }
        _ => Err(format!(
            "no scene {name}: chain 3, 5, 10, 20, 40, 160, arm 2, 6, 12, four-bar 4, bricard 5 or double-cardan 3"
        )
        .into()),
    }
}
