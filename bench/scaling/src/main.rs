//! Scenes that scale: µs per RK4 and generalised-α step (with projection,
//! h = 1 ms) against the number of bodies for a chain, a ladder of closed loops
//! and a branched tree, sparse and dense, and the peers' numbers beside them;
//! writes `report/scaling.md` and `report/scaling.svg`.
//!
//! `cargo run --release -p joint-scaling` (about half a minute;
//! add `-- --build-times` to time release builds of chain crates of 10 … 200
//! bodies too, a few minutes, or `-- --quick` for fewer steps).

use joint_examples::bricard::{Curve, plot_lines};
use joint_examples::scaling::{chain_start, exponent, ladder_start, median_us, options, sparse_step_us, tree_start};
use joint_examples::{chain_scene, ladder_scene, tree_scene};
use joint_runtime::analysis::AnalysisError;
use joint_runtime::dynamics::Integrator;
use joint_runtime::dynamics::{DenseSimulation, NoLoads};
use joint_runtime::{Scene, SystemState};

// `second_order`: the terms generalised-α's iteration matrix is made of.
chain_scene!(Chain5, 5, second_order);
chain_scene!(Chain10, 10, second_order);
chain_scene!(Chain20, 20, second_order);
chain_scene!(Chain40, 40, second_order);
chain_scene!(Chain80, 80, second_order);
chain_scene!(Chain160, 160, second_order);
chain_scene!(Chain500, 500);
ladder_scene!(Ladder4, 4, 5, second_order);
ladder_scene!(Ladder10, 10, 11, second_order);
ladder_scene!(Ladder20, 20, 21, second_order);
ladder_scene!(Ladder40, 40, 41, second_order);
tree_scene!(Tree5, 5, second_order);
tree_scene!(Tree10, 10, second_order);
tree_scene!(Tree20, 20, second_order);
tree_scene!(Tree40, 40, second_order);
tree_scene!(Tree80, 80, second_order);

/// One measured size: µs per step of RK4 and generalised-α, sparse and dense,
/// and the blocks of the sparse iteration matrix.
struct Row {
    bodies: usize,
    sparse: f64,
    dense: Option<f64>,
    alpha: Option<f64>,
    dense_alpha: Option<f64>,
    blocks: usize,
}

/// µs per step on the dense reference path (`DenseSimulation`, feature
/// `__dense_reference`: the tests' reference, not in the API), in a thread with a stack of `stack` bytes (its
/// `M × NV` matrices live on the stack).
///
/// # Errors
/// The simulation's.
pub fn dense_step_us<S, const NB: usize, const NV: usize, const M: usize>(
    scene: &S,
    start: &SystemState<NB>,
    steps: usize,
    stack: usize,
    integrator: Integrator,
) -> Result<f64, AnalysisError>
where
    S: Scene<NB, NV, M> + Sync,
{
    std::thread::scope(|scope| {
        let run = move || {
            let mut sim = DenseSimulation::new(scene, NoLoads, &[], options(integrator))?;
            median_us(start, steps, 3, |s| sim.step(s, 1e-3).map(|_| ()))
        };
        match std::thread::Builder::new().stack_size(stack).spawn_scoped(scope, run) {
            Ok(handle) => handle.join().unwrap_or(Err(AnalysisError::BadOption { name: "dense thread panicked" })),
            Err(_) => Err(AnalysisError::BadOption { name: "dense thread" }),
        }
    })
}

/// The dense path's stack: its `M × NV` matrices are on it.
const DENSE_STACK: usize = 256 << 20;

/// The dense path's µs per step, for the sizes marked `dense` only: its code
/// is not even instantiated for the others (the dense `NV × NV` iteration
/// matrix of a 160-body scene alone took rustc minutes).
macro_rules! dense_us {
    ($scene:ident, $start:expr, $steps:expr, $integrator:expr, dense) => {
        Some(dense_step_us(&$scene, $start, $steps / 4 + 1, DENSE_STACK, $integrator))
    };
    ($scene:ident, $start:expr, $steps:expr, $integrator:expr,) => {
        None::<Result<f64, AnalysisError>>
    };
}

macro_rules! measure {
    ($steps:expr, $start:ident, $(($scene:ident, $nb:expr $(, $dense:ident)?)),*) => {{
        let mut rows = Vec::new();
        $(
            let start = $start::<$nb>();
            let failed = |e| format!("{}: {e}", stringify!($scene));
            let (sparse, _) = sparse_step_us(&$scene, &start, $steps, Integrator::Rk4).map_err(failed)?;
            let (alpha, blocks) = match sparse_step_us(&$scene, &start, $steps, Integrator::GeneralisedAlpha) {
                Ok((us, blocks)) => (Some(us), blocks),
                Err(AnalysisError::NoSecondOrder { .. }) => (None, None),
                Err(e) => return Err(failed(e)),
            };
            let dense = dense_us!($scene, &start, $steps, Integrator::Rk4, $($dense)?).transpose().map_err(failed)?;
            let dense_alpha = match alpha {
                Some(_) => dense_us!($scene, &start, $steps, Integrator::GeneralisedAlpha, $($dense)?).transpose().map_err(failed)?,
                None => None,
            };
            eprintln!("{}: sparse {sparse:.1} µs, dense {dense:?}; generalised-α {alpha:?}, dense {dense_alpha:?}", stringify!($scene));
            rows.push(Row { bodies: $nb, sparse, dense, alpha, dense_alpha, blocks: blocks.unwrap_or(0) });
        )*
        rows
    }};
}

/// The peers' µs per step for the same chain at N = 5 … 160, run on this
/// machine on 2026-12-01 with the scripts of the project's peer notes
/// (`exudyn_chain.py N --steps 200 --solver sparse`; `mujoco_make_chain.py N
/// [--integrator RK4]` and `bench_step chain.xml 200 3`), not in this program:
/// they need Python wheels the project does not depend on.
const PEERS: [(&str, [f64; 6]); 3] = [
    ("Exudyn 1.13.6, generalised-α, sparse", [32.0, 86.5, 133.3, 298.3, 635.8, 1401.3]),
    ("MuJoCo 4.0, Euler (tree, no constraints)", [2.3, 3.5, 11.9, 55.3, 335.8, 2339.5]),
    ("MuJoCo 4.0, RK4", [6.4, 14.7, 50.5, 224.8, 1366.2, 9564.6]),
];

fn table(title: &str, rows: &[Row], what: &str) -> String {
    let mut out = format!(
        "### {title}\n\n| bodies | {what} | RK4 sparse | RK4 dense | dense / sparse | generalised-α sparse | \
         generalised-α dense | dense / sparse | its factor's 6 × 6 blocks |\n|---|---|---|---|---|---|---|---|---|\n"
    );
    let cell = |x: Option<f64>| x.map_or("—".into(), |d| format!("{d:.1}"));
    for r in rows {
        out += &format!(
            "| {} | {} | {:.1} | {} | {} | {} | {} | {} | {} |\n",
            r.bodies,
            what_of(title, r.bodies),
            r.sparse,
            cell(r.dense),
            cell(r.dense.map(|d| d / r.sparse)),
            cell(r.alpha),
            cell(r.dense_alpha),
            cell(r.dense_alpha.zip(r.alpha).map(|(d, a)| d / a)),
            if r.blocks > 0 { r.blocks.to_string() } else { "—".into() }
        );
    }
    let from10 = |f: &dyn Fn(&Row) -> Option<f64>| -> Vec<(f64, f64)> {
        rows.iter().filter(|r| r.bodies >= 10).filter_map(|r| Some((r.bodies as f64, f(r)?))).collect()
    };
    out += &format!("\nSparse exponents over N ≥ 10: RK4 {:.2}", exponent(&from10(&|r| Some(r.sparse))));
    if rows.iter().all(|r| r.alpha.is_some()) {
        out += &format!(
            ", generalised-α {:.2}, its factor's blocks {:.2}",
            exponent(&from10(&|r| r.alpha)),
            exponent(&from10(&|r| Some(r.blocks as f64)))
        );
    }
    out + ".\n\n"
}

fn what_of(title: &str, bodies: usize) -> String {
    match title {
        t if t.starts_with("Ladder") => format!("{} loops", (bodies - 1) / 2),
        t if t.starts_with("Tree") => format!("{} ribs", bodies / 2),
        _ => bodies.to_string(),
    }
}

/// Release build time (s) and peak memory (MB, when `/usr/bin/time` is there)
/// of a crate holding one chain scene of `n` bodies and a simulation of it
/// (with `second`: the scene's second-order terms and a generalised-α step),
/// rebuilt after its dependencies are built.
fn build_time(n: usize, second: bool) -> Result<(f64, Option<f64>), String> {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../target/scaling-build");
    let dir = root.join(format!("chain{n}{}", if second { "_alpha" } else { "" }));
    let (option, integrator) = if second {
        (", second_order", "options.integrator = joint_runtime::dynamics::Integrator::GeneralisedAlpha;")
    } else {
        ("", "options.integrator = joint_runtime::dynamics::Integrator::Rk4;")
    };
    std::fs::create_dir_all(dir.join("src")).map_err(|e| e.to_string())?;
    let runtime = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../joint-runtime");
    let manifest = format!(
        "[package]\nname = \"chain{n}\"\nversion = \"0.1.0\"\nedition = \"2024\"\n\n[dependencies]\njoint-runtime = {{ path = {:?} }}\n\n[workspace]\n",
        runtime.display().to_string()
    );
    std::fs::write(dir.join("Cargo.toml"), manifest).map_err(|e| e.to_string())?;
    let main = format!(
        "use joint_runtime::dynamics::{{NoLoads, Simulation, SimulationOptions}};\n\
         #[derive(joint_runtime::Scene)]\n#[scene(gravity = [0, 0, -9.81], coordinates = absolute{option})]\n\
         #[body(bar[{n}], mass = 1.0, inertia = [0.00125, 0.084, 0.084])]\n\
         #[joint(pivot = spherical(ground, bar[0]), rho1 = [0, 0, 0], rho2 = [-0.5, 0, 0])]\n\
         #[joint(ball[i in 1..{n}] = spherical(bar[i - 1], bar[i]), rho1 = [0.5, 0, 0], rho2 = [-0.5, 0, 0])]\n\
         struct Chain;\n\
         fn main() {{\n    let mut state = joint_runtime::SystemState {{ bodies: [joint_runtime::OmegaBody::default(); {n}], t: 0.0 }};\n    \
         let mut options = SimulationOptions::default();\n    {integrator}\n    \
         if let Ok(mut sim) = Simulation::new(&Chain, NoLoads, &[], options) {{ let _ = sim.step(&mut state, 1e-3); }}\n}}\n"
    );
    std::fs::write(dir.join("src/main.rs"), main).map_err(|e| e.to_string())?;
    let target = root.join("target");
    let cargo = || {
        let mut c = std::process::Command::new("cargo");
        c.args(["build", "--release", "-q"]).current_dir(&dir).env("CARGO_TARGET_DIR", &target);
        c
    };
    // Dependencies first, then the crate alone, timed.
    let status = cargo().status().map_err(|e| e.to_string())?;
    if !status.success() {
        return Err(format!("building the {n}-body chain crate failed"));
    }
    let touch = std::fs::read_to_string(dir.join("src/main.rs")).map_err(|e| e.to_string())?;
    std::fs::write(dir.join("src/main.rs"), touch + "\n").map_err(|e| e.to_string())?;
    let timer = std::path::Path::new("/usr/bin/time");
    let t = std::time::Instant::now();
    let output = if timer.exists() {
        let mut c = std::process::Command::new(timer);
        c.args(["-f", "%M", "cargo", "build", "--release", "-q"]).current_dir(&dir).env("CARGO_TARGET_DIR", &target);
        c.output().map_err(|e| e.to_string())?
    } else {
        cargo().output().map_err(|e| e.to_string())?
    };
    let seconds = t.elapsed().as_secs_f64();
    let memory = String::from_utf8_lossy(&output.stderr)
        .lines()
        .last()
        .and_then(|l| l.trim().parse::<f64>().ok())
        .map(|kb| kb / 1024.0);
    Ok((seconds, memory))
}

/// The release build time and peak memory of a crate holding one chain
/// scene, with and without `second_order`, over N.
fn build_times() -> Result<String, String> {
    let mut md = String::from(
        "\n### Release build time of a crate holding one chain scene (the derive, then rustc)\n\n\
           With `second_order`, the crate also runs a generalised-α step, so that the terms are compiled.\n\n\
           | N | build s | peak rustc memory MB | with `second_order`: build s | peak MB |\n|---|---|---|---|---|\n",
    );
    let (mut points, mut second) = (Vec::new(), Vec::new());
    let mb = |m: Option<f64>| m.map_or("—".into(), |m| format!("{m:.0}"));
    for n in [10, 20, 40, 80, 160, 200] {
        let (s, m) = build_time(n, false)?;
        let (s2, m2) = build_time(n, true)?;
        eprintln!("build N={n}: {s:.2} s {m:?} MB; second order {s2:.2} s {m2:?} MB");
        md += &format!("| {n} | {s:.2} | {} | {s2:.2} | {} |\n", mb(m), mb(m2));
        points.push((n as f64, s));
        second.push((n as f64, s2));
    }
    md += &format!(
        "\nBuild-time exponents over N = 40 … 200: {:.2}, with `second_order` {:.2}.\n",
        exponent(&points[2..]),
        exponent(&second[2..])
    );
    Ok(md)
}

/// `report/scaling.svg`: µs per step against bodies, log-log, with the peers.
fn plot(chain: &[Row], ladder: &[Row], tree: &[Row]) -> Result<(), String> {
    let log = |rows: &[Row], f: &dyn Fn(&Row) -> Option<f64>| -> Vec<(f64, f64)> {
        rows.iter().filter_map(|r| f(r).map(|y| ((r.bodies as f64).log10(), y.log10()))).collect()
    };
    let mut curves: Vec<Curve> = vec![
        ("chain, sparse".into(), log(chain, &|r| Some(r.sparse))),
        ("chain, dense".into(), log(chain, &|r| r.dense)),
        ("chain, generalised-α, sparse".into(), log(chain, &|r| r.alpha)),
        ("ladder, sparse".into(), log(ladder, &|r| Some(r.sparse))),
        ("tree, sparse".into(), log(tree, &|r| Some(r.sparse))),
        ("ladder, generalised-α, sparse".into(), log(ladder, &|r| r.alpha)),
        ("tree, generalised-α, sparse".into(), log(tree, &|r| r.alpha)),
    ];
    for (name, p) in PEERS {
        let pts = chain.iter().zip(p).map(|(r, y)| ((r.bodies as f64).log10(), y.log10())).collect();
        curves.push((format!("chain, {name}"), pts));
    }
    plot_lines(
        std::path::Path::new("report/scaling.svg"),
        "µs per step against bodies (log10-log10)",
        ("log10 bodies", "log10 µs per step"),
        &curves,
    )?;
    Ok(())
}

fn run() -> Result<(), String> {
    let quick = std::env::args().any(|a| a == "--quick");
    let builds = std::env::args().any(|a| a == "--build-times");
    let steps = if quick { 100 } else { 400 };
    let chain = measure!(
        steps,
        chain_start,
        (Chain5, 5, dense),
        (Chain10, 10, dense),
        (Chain20, 20, dense),
        (Chain40, 40, dense),
        (Chain80, 80),
        (Chain160, 160)
    );
    let ladder =
        measure!(steps, ladder_start, (Ladder4, 9, dense), (Ladder10, 21, dense), (Ladder20, 41), (Ladder40, 81));
    let tree = measure!(
        steps,
        tree_start,
        (Tree5, 10, dense),
        (Tree10, 20, dense),
        (Tree20, 40, dense),
        (Tree40, 80),
        (Tree80, 160)
    );
    // 500 bodies in a thread with a 2 MiB stack, the sparse path only.
    let big = std::thread::Builder::new()
        .stack_size(2 << 20)
        .spawn(|| sparse_step_us(&Chain500, &chain_start::<500>(), 50, Integrator::Rk4).map(|(us, _)| us))
        .map_err(|e| e.to_string())?
        .join()
        .map_err(|_| "the 500-body chain overflowed its 2 MiB stack".to_string())?
        .map_err(|e| e.to_string())?;
    let mut md = String::from("# Scenes that scale\n\n");
    md += "Written by `cargo run --release -p joint-scaling`. µs per step with projection \
           (`SimulationOptions::default()` with the integrator named, h = 1 ms), median of 3 rounds, one core. \
           The sparse path is `joint_runtime::dynamics::Simulation` (the block factor); the dense one the tests' dense reference `DenseSimulation` (not in the API) \
           (run in a thread with a 256 MiB stack, as its `M × NV` matrices are on the stack). Generalised-α \
           (ρ∞ = 0.9, the default; index 3) builds its exact iteration matrix from the scenes' generated second-order \
           terms: on the sparse path a saddle-point matrix over bodies and joints factorised on its fixed \
           pattern; on the dense path `NV × NV` and its Schur complement (with `K` by differences of J above \
           20 000 Jacobian entries, where the dense terms are not generated).\n\n";
    md += &table("Chain (spherical joints)", &chain, "joints");
    md += &table("Ladder (N-four-bar, A02)", &ladder, "loops");
    md += &table("Tree (a spine with a rib on every bar)", &tree, "ribs");
    md += &format!("A 500-body chain in a thread with a 2 MiB stack: {big:.0} µs per step.\n\n");
    md += "The implicit midpoint rule runs on the sparse path too (its Newton matrix in the same saddle-point \
           form as generalised-α's); it is not in these tables.\n\n";
    md += "### The chain beside the peers (µs per step)\n\nThe peers ran the same chain on this machine on \
           2026-12-01 (Exudyn: `exudyn_chain.py N --steps 200 --solver sparse`; MuJoCo: `mujoco_make_chain.py N` \
           and its C timer `bench_step chain.xml 200 3`), one after the other, not beside this program. \
           MuJoCo integrates a tree of ball joints in generalised coordinates (no constraint rows), with its \
           first-order Euler step or RK4; Exudyn uses generalised-α with its sparse solver, Euler parameters \
           and constraints, as this project does.\n\n| N | this project, sparse RK4 | this project, sparse generalised-α |";
    for (name, _) in PEERS {
        md += &format!(" {name} |");
    }
    md += "\n|---|---|---|---|---|---|\n";
    for (i, r) in chain.iter().enumerate() {
        md += &format!("| {} | {:.1} | {} |", r.bodies, r.sparse, r.alpha.map_or("—".into(), |a| format!("{a:.1}")));
        for (_, p) in PEERS {
            md += &format!(" {} |", p[i]);
        }
        md += "\n";
    }
    if builds {
        md += &build_times()?;
    }
    std::fs::create_dir_all("report").map_err(|e| e.to_string())?;
    std::fs::write("report/scaling.md", md).map_err(|e| e.to_string())?;
    plot(&chain, &ladder, &tree)?;
    println!("wrote report/scaling.md and report/scaling.svg");
    Ok(())
}

fn main() {
    if let Err(e) = run() {
        eprintln!("scaling: {e}");
        std::process::exit(1);
    }
}
