//! Robots read from their URDF files (`tests/data/robots`), timed per call
//! as Pinocchio and MuJoCo are timed in the project's peer notes: forward
//! dynamics (`aba_ns`), the mass matrix (`crba_ns`), inverse dynamics
//! (`rnea_ns`) and an RK4 step at h = 1 ms (`rk4_us`) at one fixed state,
//! each the median of 15 calibrated batches (`report::variants::median_ns`);
//! one JSON line.
//!
//! ```text
//! cargo run --release --example robot_bench -- ur5 | panda | solo12 | solo12_floating
//! ```

use std::hint::black_box;

use joint_examples::report::variants::median_ns;
use joint_runtime::Scene;
use joint_runtime::nalgebra::{SMatrix, SVector};
use joint_runtime::tree::{TreeScene, TreeSimulation, TreeState};

#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], urdf = "../tests/data/robots/ur5.urdf")]
struct Ur5;

#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], urdf = "../tests/data/robots/panda.urdf", mimic = independent)]
struct Panda;

#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], urdf = "../tests/data/robots/solo12.urdf")]
struct Solo12;

#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], urdf = "../tests/data/robots/solo12.urdf", floating_base)]
struct Solo12Floating;

fn bench<S, const NB: usize, const NQ: usize, const NV: usize>(scene: &S, robot: &str)
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
    let aba = median_ns(1, || {
        black_box(sim.forward_dynamics(black_box(&start), black_box(&tau)).ok());
    });
    let mut m = SMatrix::<f64, NV, NV>::zeros();
    let crba = median_ns(1, || {
        sim.mass_matrix_into(black_box(&start.q), &mut m);
        black_box(&m);
    });
    let rnea = median_ns(1, || {
        black_box(sim.inverse_dynamics(black_box(&start), black_box(&tau)));
    });
    let mut steps = 0_usize;
    let rk4 = median_ns(1, || {
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
    match robot {
        "ur5" => bench(&Ur5, robot),
        "panda" => bench(&Panda, robot),
        "solo12" => bench(&Solo12, robot),
        "solo12_floating" => bench(&Solo12Floating, robot),
        other => eprintln!("unknown robot `{other}`; expected ur5, panda, solo12 or solo12_floating"),
    }
}
