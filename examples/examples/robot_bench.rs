//! Robots read from their URDF files (`tests/data/robots`), timed per call
//! as Pinocchio and MuJoCo are timed in the project's peer notes: forward
//! dynamics (`aba_ns`), the mass matrix (`crba_ns`), inverse dynamics
//! (`rnea_ns`) and an RK4 step at h = 1 ms (`rk4_us`), medians over
//! batches at one fixed state; one JSON line.
//!
//! ```text
//! cargo run --release --example robot_bench -- ur5 | panda | solo12 | solo12_floating [BATCHES] [BATCH_MS]
//! ```

use std::hint::black_box;
use std::time::Instant;

use joint_runtime::Scene;
use joint_runtime::nalgebra::{SMatrix, SVector};
use joint_runtime::tree::{TreeScene, TreeSimulation, TreeState};

#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], urdf = "../tests/data/robots/ur5.urdf")]
struct Ur5;

#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], urdf = "../tests/data/robots/panda.urdf")]
struct Panda;

#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], urdf = "../tests/data/robots/solo12.urdf")]
struct Solo12;

#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], urdf = "../tests/data/robots/solo12.urdf", floating_base)]
struct Solo12Floating;

/// Median nanoseconds per call of `f` over `batches` batches of about
/// `batch_ms` each.
fn time(batches: usize, batch_ms: f64, mut f: impl FnMut()) -> f64 {
    let mut calls = 1_usize;
    loop {
        let start = Instant::now();
        for _ in 0..calls {
            f();
        }
        if start.elapsed().as_secs_f64() * 1e3 > batch_ms / 4.0 {
            break;
        }
        calls *= 2;
    }
    calls *= 4;
    let mut each: Vec<f64> = (0..batches)
        .map(|_| {
            let start = Instant::now();
            for _ in 0..calls {
                f();
            }
            start.elapsed().as_secs_f64() * 1e9 / calls as f64
        })
        .collect();
    each.sort_by(f64::total_cmp);
    each[each.len() / 2]
}

fn bench<S, const NB: usize, const NQ: usize, const NV: usize>(scene: &S, robot: &str, batches: usize, ms: f64)
where
    S: TreeScene<NB, NQ, NV>,
{
    let mut sim = TreeSimulation::new(scene).expect("a valid tree");
    // A fixed state off every symmetry: angles 0.3 k − 1, rates and forces ±.
    let mut state = sim.tree().zero_state();
    for k in 0..NV {
        let x = 0.3 * k as f64 - 1.0;
        state.v[k] = (0.7 * x).sin();
    }
    let quaternions: Vec<usize> = sim.tree().joints().iter().filter_map(|j| j.kind.quaternion()).collect();
    if quaternions.is_empty() {
        for k in 0..NQ {
            state.q[k] = 0.3 * k as f64 - 1.0;
        }
    } else {
        // The floating base's quaternion and position first, then the legs.
        state.q[0] = 0.1;
        let (w, x, y, z) = (0.9_f64, 0.1, -0.3, 0.2);
        let n = (w * w + x * x + y * y + z * z).sqrt();
        for (i, c) in [w, x, y, z].into_iter().enumerate() {
            state.q[3 + i] = c / n;
        }
        for k in 7..NQ {
            state.q[k] = 0.3 * k as f64 - 1.0;
        }
    }
    let tau = SVector::<f64, NV>::from_fn(|k, _| (1.3 * k as f64).cos());
    let start = state;
    let aba = time(batches, ms, || {
        black_box(sim.forward_dynamics(black_box(&start), black_box(&tau)).ok());
    });
    let mut m = SMatrix::<f64, NV, NV>::zeros();
    let crba = time(batches, ms, || {
        sim.mass_matrix_into(black_box(&start.q), &mut m);
        black_box(&m);
    });
    let rnea = time(batches, ms, || {
        black_box(sim.inverse_dynamics(black_box(&start), black_box(&tau)));
    });
    let mut steps = 0_usize;
    let rk4 = time(batches, ms, || {
        if steps.is_multiple_of(1000) {
            state = start;
        }
        steps += 1;
        black_box(sim.step(&mut state, 1e-3).ok());
    });
    let end: TreeState<NQ, NV> = state;
    println!(
        "{{\"peer\":\"joint\",\"robot\":\"{robot}\",\"nq\":{NQ},\"nv\":{NV},\"aba_ns\":{aba:.1},\"crba_ns\":{crba:.1},\
         \"rnea_ns\":{rnea:.1},\"rk4_us\":{:.4},\"q0\":{:.6}}}",
        rk4 / 1e3,
        end.q[0]
    );
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let robot = args.get(1).map_or("ur5", String::as_str);
    let batches = args.get(2).and_then(|a| a.parse().ok()).unwrap_or(15);
    let ms = args.get(3).and_then(|a| a.parse().ok()).unwrap_or(10.0);
    match robot {
        "ur5" => bench(&Ur5, robot, batches, ms),
        "panda" => bench(&Panda, robot, batches, ms),
        "solo12" => bench(&Solo12, robot, batches, ms),
        "solo12_floating" => bench(&Solo12Floating, robot, batches, ms),
        other => eprintln!("unknown robot `{other}`; expected ur5, panda, solo12 or solo12_floating"),
    }
}
