//! Constrained dynamics on trees (`#[contact]`, loops): `q̈`, `λ` and their
//! exact derivatives against Pinocchio 4.1's `constraintDynamics` and
//! `computeConstraintDynamicsDerivatives` (`tests/data/constrained/`: the
//! floating Solo12 on four feet and trotting on two, the UR5's tool welded to
//! the world, a four-bar closed at a point in two ways), against central
//! differences where Pinocchio is wrong (a point held between two moving
//! bodies with no moving common ancestor) and everywhere on our own maps,
//! and against a closed form.

use joint_runtime::Scene;
use joint_runtime::nalgebra::{DMatrix, SMatrix, SVector};
use joint_runtime::relative::{
    ActiveRows, ConstrainedDerivatives, ForwardDerivatives, InverseDerivatives, TreeScene, TreeSimulation, TreeState,
};
use joint_runtime::robot::StateLayout;
use serde_json::Value;

use crate::urdf::numbers;

/// The floating Solo12 on its four feet, the forces in the world's axes.
#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], urdf = "data/robots/solo12.urdf", floating_base)]
#[contact(fl = point(FL_FOOT); fr = point(FR_FOOT); hl = point(HL_FOOT); hr = point(HR_FOOT))]
struct SoloFeet;

/// The same feet in their own axes: a trot holds two of them.
#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], urdf = "data/robots/solo12.urdf", floating_base)]
#[contact(fl = point(FL_FOOT), axes = local; fr = point(FR_FOOT), axes = local)]
#[contact(hl = point(HL_FOOT), axes = local; hr = point(HR_FOOT), axes = local)]
struct SoloLocal;

/// The UR5's tool welded to the world, in the tool's axes.
#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], urdf = "data/robots/ur5.urdf")]
#[contact(weld = frame(tool0), axes = local)]
struct Ur5Weld;

// The kit's four-bar: bars of 1 kg/m, radius 0.02, crank 0.3, coupler 1.0,
// rocker 0.8, ground pivots 1 m apart, every joint about y.

/// Crank, coupler and rocker in a chain, the rocker's tip held at the world's point.
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

/// Crank and coupler from one pivot, the rocker from the other, the
/// coupler's tip held to the rocker's.
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

fn case(name: &str) -> Value {
    let path = format!("{}/data/constrained/reference.json", env!("CARGO_MANIFEST_DIR"));
    let all: Value = serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    all["cases"][name].clone()
}

fn matrix(v: &Value) -> DMatrix<f64> {
    let rows: Vec<Vec<f64>> = v.as_array().unwrap().iter().map(numbers).collect();
    DMatrix::from_fn(rows.len(), rows[0].len(), |r, c| rows[r][c])
}

/// The largest difference over the largest entry of the reference (over 1
/// where the reference is round-off: the welded UR5's `∂q̈/∂τ`, zero).
fn relative(ours: &DMatrix<f64>, theirs: &DMatrix<f64>) -> f64 {
    assert_eq!(ours.shape(), theirs.shape());
    let scale = if theirs.amax() < 1e-9 { 1.0 } else { theirs.amax() };
    (ours - theirs).amax() / scale
}

fn dense<const R: usize, const C: usize>(m: &SMatrix<f64, R, C>) -> DMatrix<f64> {
    DMatrix::from_fn(R, C, |r, c| m[(r, c)])
}

/// Our outputs in the reference's terms, by name: `q̈`, `λ` (`rows` of ours,
/// in the reference's order) and the six derivatives.
struct Outputs(Vec<(&'static str, DMatrix<f64>)>);

impl Outputs {
    fn check(&self, sample: &Value, bound: f64, fd: bool) -> f64 {
        let mut worst = 0.0_f64;
        for (name, ours) in &self.0 {
            let key =
                if fd && sample.get(format!("{name}_fd")).is_some() { format!("{name}_fd") } else { name.to_string() };
            let theirs = match &sample[&key] {
                v if v[0].is_array() => matrix(v),
                v => DMatrix::from_column_slice(v.as_array().unwrap().len(), 1, &numbers(v)),
            };
            let error = relative(ours, &theirs);
            // Central differences carry their own error (ε = 1e-6).
            let allowed = if key.ends_with("_fd") { 1e-6 } else { bound };
            assert!(error < allowed, "{key}: {error:e}");
            eprintln!("{key}: {error:.1e}");
            worst = worst.max(error);
        }
        worst
    }
}

/// Ours at a library state, in the library's coordinates, only `rows` of `λ`.
fn library_outputs<S, const NB: usize, const NQ: usize, const NV: usize, const NC: usize>(
    sim: &TreeSimulation<'_, S, NB, NQ, NV, NC>,
    layout: &StateLayout<NQ, NV>,
    sample: &Value,
    active: ActiveRows,
    rows: &[usize],
) -> Outputs
where
    S: TreeScene<NB, NQ, NV, NC>,
{
    let state = layout.state_from(&numbers(&sample["q"]), &numbers(&sample["v"])).unwrap();
    let tau = layout.forces_from(&state, &numbers(&sample["tau"])).unwrap();
    let (mut work, mut out) = (InverseDerivatives::zeros(), ConstrainedDerivatives::zeros());
    sim.constrained_dynamics_derivatives(&state, &tau, active, &mut work, &mut out).unwrap();
    let forward = ForwardDerivatives { qdd: out.qdd, d_q: out.d_q, d_v: out.d_v, d_tau: out.d_tau };
    let f = layout.forward_derivatives_to(&state, &tau, &forward);
    let t = layout.tangent_map(&state);
    let t_inv = t.try_inverse().unwrap();
    let pick = |m: DMatrix<f64>| DMatrix::from_fn(rows.len(), m.ncols(), |r, c| m[(rows[r], c)]);
    Outputs(vec![
        ("ddq", dense(&f.qdd)),
        ("lambda", pick(dense(&out.lambda))),
        ("ddq_dq", dense(&f.d_q)),
        ("ddq_dv", dense(&f.d_v)),
        ("ddq_dtau", dense(&f.d_tau)),
        ("dlambda_dq", pick(dense(&(out.lambda_q * t_inv)))),
        ("dlambda_dv", pick(dense(&(out.lambda_v * t_inv)))),
        ("dlambda_dtau", pick(dense(&(out.lambda_tau * t.transpose())))),
    ])
}

#[test]
fn solo12_on_four_feet_equals_pinocchio() {
    let reference = case("solo12_4feet_lwa");
    let sim = TreeSimulation::new(&SoloFeet).unwrap();
    assert_eq!(SoloFeet::CONTACTS.len(), 4);
    let rows: Vec<usize> = (0..12).collect();
    for sample in reference["samples"].as_array().unwrap() {
        let worst =
            library_outputs(&sim, &SoloFeet::PINOCCHIO, sample, ActiveRows::all(), &rows).check(sample, 1e-12, false);
        assert!(worst < 1e-12);
    }
}

#[test]
fn solo12_trotting_in_local_axes_equals_pinocchio() {
    let reference = case("solo12_trot_local");
    let sim = TreeSimulation::new(&SoloLocal).unwrap();
    // Front left and hind right of the four declared feet: the rows of blocks 0 and 3.
    let trot = ActiveRows::named(SoloLocal::CLOSURES, &["fl", "hr"]).unwrap();
    assert_eq!(trot, ActiveRows::none().with(0).with(3));
    let rows = [0, 1, 2, 9, 10, 11];
    for sample in reference["samples"].as_array().unwrap() {
        library_outputs(&sim, &SoloLocal::PINOCCHIO, sample, trot, &rows).check(sample, 1e-12, false);
    }
}

#[test]
fn ur5_welded_equals_pinocchio() {
    let reference = case("ur5_weld_local");
    let sim = TreeSimulation::new(&Ur5Weld).unwrap();
    let rows: Vec<usize> = (0..6).collect();
    for sample in reference["samples"].as_array().unwrap() {
        library_outputs(&sim, &Ur5Weld::PINOCCHIO, sample, ActiveRows::all(), &rows).check(sample, 1e-12, false);
    }
}

/// Ours on a scene whose coordinates are the reference's.
fn plain_outputs<S, const NB: usize, const NQ: usize, const NV: usize, const NC: usize>(
    sim: &TreeSimulation<'_, S, NB, NQ, NV, NC>,
    sample: &Value,
) -> Outputs
where
    S: TreeScene<NB, NQ, NV, NC>,
{
    let state = TreeState {
        q: SVector::from_column_slice(&numbers(&sample["q"])),
        v: SVector::from_column_slice(&numbers(&sample["v"])),
        t: 0.0,
    };
    let tau = SVector::from_column_slice(&numbers(&sample["tau"]));
    let (mut work, mut out) = (InverseDerivatives::zeros(), ConstrainedDerivatives::zeros());
    sim.constrained_dynamics_derivatives(&state, &tau, ActiveRows::all(), &mut work, &mut out).unwrap();
    Outputs(vec![
        ("ddq", dense(&out.qdd)),
        ("lambda", dense(&out.lambda)),
        ("ddq_dq", dense(&out.d_q)),
        ("ddq_dv", dense(&out.d_v)),
        ("ddq_dtau", dense(&out.d_tau)),
        ("dlambda_dq", dense(&out.lambda_q)),
        ("dlambda_dv", dense(&out.lambda_v)),
        ("dlambda_dtau", dense(&out.lambda_tau)),
    ])
}

#[test]
fn four_bar_closed_at_the_world_equals_pinocchio() {
    let sim = TreeSimulation::new(&FourBarSerial).unwrap();
    for sample in case("fourbar_serial")["samples"].as_array().unwrap() {
        plain_outputs(&sim, sample).check(sample, 1e-12, false);
    }
}

/// Pinocchio's `∂q̈/∂q` and `∂λ/∂q` are wrong here (errors the size of the
/// entries): ours equal the reference's central differences to their own
/// error, and Pinocchio's everything else.
#[test]
fn four_bar_closed_between_two_bodies_equals_differences() {
    let sim = TreeSimulation::new(&FourBarBranch).unwrap();
    for sample in case("fourbar_branch")["samples"].as_array().unwrap() {
        let ours = plain_outputs(&sim, sample);
        ours.check(sample, 1e-12, true);
        // And Pinocchio's own ∂q̈/∂q is not ours.
        let (_, d_q) = ours.0.iter().find(|(n, _)| *n == "ddq_dq").unwrap();
        assert!(relative(d_q, &matrix(&sample["ddq_dq"])) > 1e-2);
    }
}
