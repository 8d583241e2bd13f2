//! Constrained dynamics timed per call, on the cases of the project's
//! Pinocchio reference (`tests/data/constrained/`, the same robots, contacts
//! and loops as `../shared/peers/constrained/`): the tree's own forward
//! dynamics (`aba_ns`), `q̈` and `λ` (`constraint_dynamics_ns`), the same
//! with all their first derivatives (`constraint_dynamics_derivatives_ns`,
//! which includes the solve: compare with Pinocchio's
//! `constraint_dynamics_plus_derivatives_ns`) and an impact's velocity and
//! impulses with their derivatives (`impulse_ns`, `impulse_derivatives_ns`),
//! at sample 0's state, each the median of 15 calibrated batches; one JSON
//! line per case.
//!
//! ```text
//! cargo run --release -p joint-examples --features bench --example constrained_bench [-- CASE ...]
//! ```

use std::hint::black_box;

use joint_examples::report::variants::median_ns;
use joint_runtime::Scene;
use joint_runtime::nalgebra::SVector;
use joint_runtime::relative::{
    ActiveRows, ConstrainedDerivatives, ImpulseDerivatives, InverseDerivatives, TreeScene, TreeSimulation, TreeState,
};
use joint_runtime::robot::StateLayout;
use serde_json::Value;

#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], urdf = "../tests/data/robots/solo12.urdf", floating_base)]
#[contact(fl = point(FL_FOOT); fr = point(FR_FOOT); hl = point(HL_FOOT); hr = point(HR_FOOT))]
struct SoloFeet;

#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], urdf = "../tests/data/robots/solo12.urdf", floating_base)]
#[contact(fl = point(FL_FOOT), axes = local; fr = point(FR_FOOT), axes = local)]
#[contact(hl = point(HL_FOOT), axes = local; hr = point(HR_FOOT), axes = local)]
struct SoloLocal;

#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], urdf = "../tests/data/robots/ur5.urdf")]
#[contact(weld = frame(tool0), axes = local)]
struct Ur5Weld;

#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], coordinates = relative)]
#[body(crank, mass = 0.3, inertia = [0.3 * 0.0004 / 2.0, 0.3 * (0.0012 + 0.09) / 12.0, 0.3 * (0.0012 + 0.09) / 12.0])]
#[body(coupler, mass = 1.0, inertia = [0.0004 / 2.0, (0.0012 + 1.0) / 12.0, (0.0012 + 1.0) / 12.0])]
#[body(rocker, mass = 0.8, inertia = [0.8 * 0.0004 / 2.0, 0.8 * (0.0012 + 0.64) / 12.0, 0.8 * (0.0012 + 0.64) / 12.0])]
#[joint(a = revolute(ground, crank), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0, 0, 0], rho2 = [-0.15, 0, 0])]
#[joint(b = revolute(crank, coupler), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0.15, 0, 0], rho2 = [-0.5, 0, 0])]
#[joint(c = revolute(coupler, rocker), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0.5, 0, 0], rho2 = [-0.4, 0, 0])]
#[contact(tip = point(rocker), at = [0.4, 0, 0], axes = local)]
struct FourBarSerial;

#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], coordinates = relative)]
#[body(crank, mass = 0.3, inertia = [0.3 * 0.0004 / 2.0, 0.3 * (0.0012 + 0.09) / 12.0, 0.3 * (0.0012 + 0.09) / 12.0])]
#[body(coupler, mass = 1.0, inertia = [0.0004 / 2.0, (0.0012 + 1.0) / 12.0, (0.0012 + 1.0) / 12.0])]
#[body(rocker, mass = 0.8, inertia = [0.8 * 0.0004 / 2.0, 0.8 * (0.0012 + 0.64) / 12.0, 0.8 * (0.0012 + 0.64) / 12.0])]
#[joint(a = revolute(ground, crank), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0, 0, 0], rho2 = [-0.15, 0, 0])]
#[joint(b = revolute(crank, coupler), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0.15, 0, 0], rho2 = [-0.5, 0, 0])]
#[joint(c = revolute(ground, rocker), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [1, 0, 0], rho2 = [-0.4, 0, 0])]
#[contact(tip = point(coupler, rocker), at = [0.5, 0, 0], at2 = [0.4, 0, 0], axes = local)]
struct FourBarBranch;

fn numbers(v: &Value) -> Vec<f64> {
    v.as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect()
}

/// Sample 0 of `case` in the tree's terms.
fn start<const NQ: usize, const NV: usize>(
    case: &str,
    layout: Option<&StateLayout<NQ, NV>>,
) -> (TreeState<NQ, NV>, SVector<f64, NV>) {
    let path = format!("{}/../tests/data/constrained/reference.json", env!("CARGO_MANIFEST_DIR"));
    let all: Value = serde_json::from_str(&std::fs::read_to_string(path).expect("the reference")).unwrap();
    let sample = &all["cases"][case]["samples"][0];
    let (q, v, tau) = (numbers(&sample["q"]), numbers(&sample["v"]), numbers(&sample["tau"]));
    match layout {
        Some(layout) => {
            let state = layout.state_from(&q, &v).unwrap();
            let tau = layout.forces_from(&state, &tau).unwrap();
            (state, tau)
        }
        None => {
            let state = TreeState { q: SVector::from_column_slice(&q), v: SVector::from_column_slice(&v), t: 0.0 };
            (state, SVector::from_column_slice(&tau))
        }
    }
}

fn bench<S, const NB: usize, const NQ: usize, const NV: usize, const NC: usize>(
    scene: &S,
    case: &str,
    active: ActiveRows,
    impacts: bool,
) where
    S: TreeScene<NB, NQ, NV, NC>,
{
    let sim = TreeSimulation::new(scene).expect("a valid tree");
    // `LABEL:REFERENCE`: the kit's case name, then the reference case whose state is used.
    let (label, reference) = case.split_once(':').unwrap_or((case, case));
    let (state, tau) = start(reference, S::STATE_LAYOUT.as_ref());
    let aba = median_ns(1, || {
        black_box(sim.tree_dynamics(black_box(&state), black_box(&tau)).ok());
    });
    let mut out = ConstrainedDerivatives::zeros();
    let dynamics = median_ns(1, || {
        black_box(sim.constrained_dynamics(black_box(&state), black_box(&tau), active, &mut out).ok());
        black_box(&out);
    });
    let mut work = InverseDerivatives::zeros();
    let derivatives = median_ns(1, || {
        black_box(
            sim.constrained_dynamics_derivatives(black_box(&state), black_box(&tau), active, &mut work, &mut out).ok(),
        );
        black_box(&out);
    });
    let (mut impulse, mut impulse_derivatives) = (f64::NAN, f64::NAN);
    if impacts {
        let mut hit = ImpulseDerivatives::zeros();
        impulse = median_ns(1, || {
            black_box(sim.impact(black_box(&state), active, 0.0, &mut hit).ok());
            black_box(&hit);
        });
        impulse_derivatives = median_ns(1, || {
            black_box(sim.impact_derivatives(black_box(&state), active, 0.0, &mut work, &mut hit).ok());
            black_box(&hit);
        });
    }
    println!(
        "{{\"peer\":\"joint\",\"case\":\"{label}\",\"nv\":{NV},\"rows\":{NC},\"aba_ns\":{aba:.1},\
         \"constraint_dynamics_ns\":{dynamics:.1},\"constraint_dynamics_derivatives_ns\":{derivatives:.1},\
         \"impulse_ns\":{impulse:.1},\"impulse_derivatives_ns\":{impulse_derivatives:.1}}}"
    );
}

fn main() {
    let wanted: Vec<String> = std::env::args().skip(1).collect();
    let run = |case: &str| wanted.is_empty() || wanted.iter().any(|w| w == case);
    let all = ActiveRows::all();
    if run("solo12_4feet_lwa") {
        bench(&SoloFeet, "solo12_4feet_lwa", all, true);
    }
    if run("solo12_4feet_local") {
        bench(&SoloLocal, "solo12_4feet_local:solo12_trot_local", all, true);
    }
    if run("solo12_trot_lwa") {
        bench(&SoloFeet, "solo12_trot_lwa:solo12_4feet_lwa", ActiveRows::none().with(0).with(3), true);
    }
    if run("ur5_weld6d_local") {
        bench(&Ur5Weld, "ur5_weld6d_local:ur5_weld_local", all, true);
    }
    if run("fourbar_serial") {
        bench(&FourBarSerial, "fourbar_serial", all, false);
    }
    if run("fourbar_branch") {
        bench(&FourBarBranch, "fourbar_branch", all, false);
    }
}
