//! Robots read from their URDF files (`tests/data/robots`), timed per call
//! as Pinocchio and MuJoCo are timed in the project's peer notes: forward
//! dynamics (`aba_ns`), the mass matrix (`crba_ns`), inverse dynamics
//! (`rnea_ns`), their exact first derivatives (`aba_derivatives_ns`:
//! `q̈`, `∂q̈/∂q`, `∂q̈/∂v`, `M⁻¹`; `rnea_derivatives_ns`: `τ`, `∂τ/∂q`,
//! `∂τ/∂v`, `M`), `linearise` on them (`linearise_us`), one step's exact
//! Jacobian (`rk4_jacobian_us`, `euler_jacobian_us`; a floating base's
//! too) beside `transition` (`transition_us`: the same exact RK4 Jacobian
//! as a dense matrix where the tree has no springs or loads, differences
//! elsewhere), a linearly implicit Euler step under stiff PD gains
//! (`implicit_us`), and an RK4 step at h = 1 ms (`rk4_us`) at one fixed state,
//! each the median of 15 calibrated batches (`report::variants::median_ns`);
//! one JSON line.
//!
//! ```text
//! cargo run --release -p joint-examples --features bench --example robot_bench -- ur5 | panda | solo12 | solo12_floating
//! cargo run --release -p joint-examples --features bench --example robot_bench -- ur5_recursion | panda_recursion | solo12_floating_recursion
//! ```
//!
//! The `_recursion` robots are the same files without `second_order`: their
//! derivatives are the runtime's recursion (`relative/recursion.rs`), not the
//! generated straight line.

use std::hint::black_box;

use joint_examples::report::variants::median_ns;
use joint_runtime::Scene;
use joint_runtime::nalgebra::{SMatrix, SVector};
use joint_runtime::relative::{
    ForceGains, ForwardDerivatives, InverseDerivatives, StepJacobian, StepWork, TreeScene, TreeSimulation, TreeState,
};

#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], urdf = "../tests/data/robots/ur5.urdf", second_order)]
struct Ur5;

#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], urdf = "../tests/data/robots/panda.urdf", mimic = independent)]
struct Panda;

#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], urdf = "../tests/data/robots/solo12.urdf", second_order)]
struct Solo12;

#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], urdf = "../tests/data/robots/solo12.urdf", floating_base)]
struct Solo12Floating;

// The same without `second_order`: derivatives by the runtime's recursion.
#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], urdf = "../tests/data/robots/ur5.urdf")]
struct Ur5Recursion;

#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], urdf = "../tests/data/robots/panda.urdf", mimic = independent)]
struct PandaRecursion;

#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], urdf = "../tests/data/robots/solo12.urdf", floating_base)]
struct Solo12FloatingRecursion;

/// A fixed state off every symmetry: angles 0.3 k − 1, rates and forces ±;
/// a floating base's quaternion turned.
fn fixed_state<S, const NB: usize, const NQ: usize, const NV: usize>(
    sim: &TreeSimulation<'_, S, NB, NQ, NV>,
) -> TreeState<NQ, NV>
where
    S: TreeScene<NB, NQ, NV>,
{
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
    state
}

fn bench<S, const NB: usize, const NQ: usize, const NV: usize>(scene: &S, robot: &str)
where
    S: TreeScene<NB, NQ, NV>,
{
    let mut sim = TreeSimulation::new(scene).expect("a valid tree");
    let mut state = fixed_state(&sim);
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
    let (mut inverse, mut forward) = (InverseDerivatives::zeros(), ForwardDerivatives::zeros());
    let aba_derivatives = median_ns(1, || {
        black_box(
            sim.forward_dynamics_derivatives(black_box(&start), black_box(&tau), &mut inverse, &mut forward).ok(),
        );
        black_box(&forward);
    });
    let rnea_derivatives = median_ns(1, || {
        black_box(sim.inverse_dynamics_derivatives(black_box(&start), black_box(&tau), &mut inverse).ok());
        black_box(&inverse);
    });
    // One step's Jacobian: exact (RK4, semi-implicit Euler; trees without
    // quaternions), and by central differences (`transition`).
    let (mut work, mut jacobian) = (StepWork::new(), StepJacobian::zeros());
    let mut exact_step = |euler: bool| {
        let mut s = start;
        if sim.rk4_step_jacobian(&mut s, 1e-3, &tau, &mut work, &mut jacobian).is_err() {
            return f64::NAN;
        }
        median_ns(1, || {
            let mut s = start;
            let done = if euler {
                sim.euler_step_jacobian(&mut s, 1e-3, &tau, &mut work, &mut jacobian)
            } else {
                sim.rk4_step_jacobian(&mut s, 1e-3, &tau, &mut work, &mut jacobian)
            };
            black_box((done.ok(), &jacobian));
        }) / 1e3
    };
    let (rk4_jacobian, euler_jacobian) = (exact_step(false), exact_step(true));
    let transition = median_ns(1, || {
        let mut s = start;
        black_box(sim.transition(&mut s, 1e-3, &tau).ok());
    }) / 1e3;
    let linearise = median_ns(1, || {
        black_box(sim.linearise(black_box(&start), &tau).ok());
    }) / 1e3;
    // The linearly implicit Euler step under a stiff PD law's gains.
    let gains = ForceGains::pd(&SVector::repeat(1e4), &SVector::repeat(1e2));
    let implicit = median_ns(1, || {
        let mut s = start;
        black_box(sim.implicit_step_with(&mut s, 1e-3, black_box(&tau), &gains, &mut work).ok());
    }) / 1e3;
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
         \"rnea_ns\":{rnea:.1},\
         \"aba_derivatives_ns\":{aba_derivatives:.1},\"rnea_derivatives_ns\":{rnea_derivatives:.1},\
         \"linearise_us\":{linearise:.3},\"rk4_jacobian_us\":{rk4_jacobian:.3},\"euler_jacobian_us\":{euler_jacobian:.3},\
         \"transition_us\":{transition:.3},\"implicit_us\":{implicit:.3},\"rk4_us\":{:.4},\"q0\":{:.6}}}",
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
        "ur5_recursion" => bench(&Ur5Recursion, robot),
        "panda_recursion" => bench(&PandaRecursion, robot),
        "solo12_floating_recursion" => bench(&Solo12FloatingRecursion, robot),
        other => eprintln!(
            "unknown robot `{other}`; expected ur5, panda, solo12 or solo12_floating, or the first, second or last \
             with `_recursion` (derivatives by the runtime's recursion)"
        ),
    }
}
