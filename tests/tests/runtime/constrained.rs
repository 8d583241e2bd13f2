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
    ActiveRows, ConstrainedDerivatives, ForwardDerivatives, ImpulseDerivatives, InverseDerivatives, TreeScene,
    TreeSimulation, TreeState,
};
use joint_runtime::robot::StateLayout;
use serde_json::Value;

use crate::urdf::numbers;

/// The floating Solo12 on its four feet, the forces in the world's axes.
#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], urdf = "data/robots/solo12.urdf", floating_base)]
#[contact(fl = point(FL_FOOT); fr = point(FR_FOOT); hl = point(HL_FOOT); hr = point(HR_FOOT))]
pub(crate) struct SoloFeet;

/// The same feet in their own axes: a trot holds two of them.
#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], urdf = "data/robots/solo12.urdf", floating_base)]
#[contact(fl = point(FL_FOOT), axes = local; fr = point(FR_FOOT), axes = local)]
#[contact(hl = point(HL_FOOT), axes = local; hr = point(HR_FOOT), axes = local)]
pub(crate) struct SoloLocal;

/// The UR5's tool welded to the world, in the tool's axes.
#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], urdf = "data/robots/ur5.urdf")]
#[contact(weld = frame(tool0), axes = local)]
pub(crate) struct Ur5Weld;

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

#[test]
fn solo12_impact_equals_pinocchio() {
    let reference = case("solo12_4feet_lwa");
    let sim = TreeSimulation::new(&SoloFeet).unwrap();
    let layout = SoloFeet::PINOCCHIO;
    for sample in reference["samples"].as_array().unwrap() {
        let state = layout.state_from(&numbers(&sample["q"]), &numbers(&sample["v"])).unwrap();
        let (mut work, mut hit) = (InverseDerivatives::zeros(), ImpulseDerivatives::zeros());
        sim.impact_derivatives(&state, ActiveRows::all(), 0.0, &mut work, &mut hit).unwrap();
        // Pinocchio's T is constant: v_l = T v, and each ∂/∂q, ∂/∂v goes through T⁻¹.
        let t = layout.tangent_map(&state);
        let t_inv = t.try_inverse().unwrap();
        let ours = Outputs(vec![
            ("v_after", dense(&(t * hit.v_after))),
            ("impulse", dense(&hit.impulse)),
            ("dv_after_dq", dense(&(t * hit.v_after_q * t_inv))),
            ("dv_after_dv", dense(&(t * hit.v_after_v * t_inv))),
            ("dimpulse_dq", dense(&(hit.impulse_q * t_inv))),
            ("dimpulse_dv", dense(&(hit.impulse_v * t_inv))),
        ]);
        ours.check(&sample["impulse"], 1e-12, false);
    }
}

/// Central differences of `f` along the tree's increments of `q`, then `v`,
/// then `τ`: the three `R × NV` derivatives.
fn differences<const NQ: usize, const NV: usize, const R: usize>(
    state: &TreeState<NQ, NV>,
    tau: &SVector<f64, NV>,
    displaced: impl Fn(&SVector<f64, NQ>, &SVector<f64, NV>) -> SVector<f64, NQ>,
    f: impl Fn(&TreeState<NQ, NV>, &SVector<f64, NV>) -> SVector<f64, R>,
) -> [SMatrix<f64, R, NV>; 3] {
    let h = 1e-6;
    let mut out = [SMatrix::<f64, R, NV>::zeros(); 3];
    for i in 0..NV {
        let e = SVector::<f64, NV>::from_fn(|r, _| if r == i { h } else { 0.0 });
        let q = |s: f64| TreeState { q: displaced(&state.q, &(e * s)), ..*state };
        out[0].set_column(i, &((f(&q(1.0), tau) - f(&q(-1.0), tau)) / (2.0 * h)));
        let v = |s: f64| TreeState { v: state.v + e * s, ..*state };
        out[1].set_column(i, &((f(&v(1.0), tau) - f(&v(-1.0), tau)) / (2.0 * h)));
        out[2].set_column(i, &((f(state, &(tau + e)) - f(state, &(tau - e))) / (2.0 * h)));
    }
    out
}

fn close<const R: usize, const C: usize>(ours: &SMatrix<f64, R, C>, theirs: &SMatrix<f64, R, C>, what: &str) {
    let error = (ours - theirs).amax() / theirs.amax().max(1.0);
    assert!(error < 1e-6, "{what}: {error:e}");
}

/// The Solo12 on its feet with Baumgarte's gains (α = 3, β = 4), at the
/// four-feet reference's sample `n`: the simulation, the state, `τ`.
fn solo_with_gains(
    n: usize,
) -> (TreeSimulation<'static, SoloFeet, 13, 19, 18, 12>, TreeState<19, 18>, SVector<f64, 18>) {
    use joint_runtime::dynamics::{SimulationOptions, Stabilisation};
    let options = SimulationOptions::default().with_stabilisation(Stabilisation::Baumgarte { alpha: 3.0, beta: 4.0 });
    let sim = TreeSimulation::new(&SoloFeet).unwrap().with_options(options).unwrap();
    let sample = &case("solo12_4feet_lwa")["samples"][n];
    let layout = SoloFeet::PINOCCHIO;
    let state = layout.state_from(&numbers(&sample["q"]), &numbers(&sample["v"])).unwrap();
    let tau = layout.forces_from(&state, &numbers(&sample["tau"])).unwrap();
    (sim, state, tau)
}

/// Every derivative against central differences of our own maps, with
/// Baumgarte's gains on, three feet of four holding, and the UR5's weld in
/// the world's axes.
#[test]
fn derivatives_equal_differences_with_gains_and_an_active_set() {
    let (sim, state, tau) = solo_with_gains(1);
    let three = ActiveRows::named(SoloFeet::CLOSURES, &["fl", "fr", "hl"]).unwrap();
    let (mut work, mut out) = (InverseDerivatives::zeros(), ConstrainedDerivatives::zeros());
    sim.constrained_dynamics_derivatives(&state, &tau, three, &mut work, &mut out).unwrap();
    assert_eq!(out.rank, 9);
    assert!(out.lambda.rows(9, 3).iter().all(|x| *x == 0.0));
    let solve = |s: &TreeState<19, 18>, t: &SVector<f64, 18>| {
        let mut o = ConstrainedDerivatives::zeros();
        sim.constrained_dynamics(s, t, three, &mut o).unwrap();
        (o.qdd, o.lambda)
    };
    let moved = |q: &SVector<f64, 19>, d: &SVector<f64, 18>| sim.tree().displaced(q, d);
    let [q, v, t] = differences(&state, &tau, moved, |s, t| solve(s, t).0);
    close(&out.d_q, &q, "∂q̈/∂q");
    close(&out.d_v, &v, "∂q̈/∂v");
    close(&out.d_tau, &t, "∂q̈/∂τ");
    let [q, v, t] = differences(&state, &tau, moved, |s, t| solve(s, t).1);
    close(&out.lambda_q, &q, "∂λ/∂q");
    close(&out.lambda_v, &v, "∂λ/∂v");
    close(&out.lambda_tau, &t, "∂λ/∂τ");
}

/// An impact's derivatives against central differences of the impact
/// itself: the Solo12 on three feet with restitution 0.5, and the four-bar
/// closed between two moving bodies (where Pinocchio's constrained
/// derivatives are wrong, so its impulse ones are no reference).
#[test]
fn impact_derivatives_equal_differences() {
    fn check<S, const NB: usize, const NQ: usize, const NV: usize, const NC: usize>(
        scene: &S,
        state: &TreeState<NQ, NV>,
        active: ActiveRows,
        restitution: f64,
    ) where
        S: TreeScene<NB, NQ, NV, NC>,
    {
        let sim = TreeSimulation::new(scene).unwrap();
        let (mut work, mut ours) = (InverseDerivatives::zeros(), ImpulseDerivatives::zeros());
        sim.impact_derivatives(state, active, restitution, &mut work, &mut ours).unwrap();
        let hit = |s: &TreeState<NQ, NV>| {
            let mut o = ImpulseDerivatives::zeros();
            sim.impact(s, active, restitution, &mut o).unwrap();
            o
        };
        let moved = |q: &SVector<f64, NQ>, d: &SVector<f64, NV>| sim.tree().displaced(q, d);
        let zero = SVector::<f64, NV>::zeros();
        let [q, v, _] = differences(state, &zero, moved, |s, _| hit(s).v_after);
        close(&ours.v_after_q, &q, "∂v⁺/∂q");
        close(&ours.v_after_v, &v, "∂v⁺/∂v");
        let [q, v, _] = differences(state, &zero, moved, |s, _| hit(s).impulse);
        close(&ours.impulse_q, &q, "∂Λ/∂q");
        close(&ours.impulse_v, &v, "∂Λ/∂v");
    }
    let sample = &case("solo12_4feet_lwa")["samples"][3];
    let state = SoloFeet::PINOCCHIO.state_from(&numbers(&sample["q"]), &numbers(&sample["v"])).unwrap();
    check(&SoloFeet, &state, ActiveRows::named(SoloFeet::CLOSURES, &["fl", "fr", "hr"]).unwrap(), 0.5);
    let sample = &case("fourbar_branch")["samples"][0];
    let state = TreeState {
        q: SVector::from_column_slice(&numbers(&sample["q"])),
        v: SVector::from_column_slice(&numbers(&sample["v"])),
        t: 0.0,
    };
    check(&FourBarBranch, &state, ActiveRows::all(), 0.0);
}

/// A step's Jacobian `ours` at `state`, `tau` (ending at `nominal`)
/// against central differences of `step`, `q₁` measured in the tree's
/// increments at the nominal end.
fn step_against_differences(
    sim: &TreeSimulation<'static, SoloFeet, 13, 19, 18, 12>,
    (state, tau): (&TreeState<19, 18>, &SVector<f64, 18>),
    (nominal, ours): (&TreeState<19, 18>, &joint_runtime::relative::StepJacobian<18>),
    step: impl Fn(&TreeState<19, 18>, &SVector<f64, 18>) -> TreeState<19, 18>,
) {
    let moved = |q: &SVector<f64, 19>, d: &SVector<f64, 18>| sim.tree().displaced(q, d);
    let [q, v, t] = differences(state, tau, moved, |s, t| sim.tree().difference(&nominal.q, &step(s, t).q));
    close(&ours.q_q, &q, "∂q₁/∂q₀");
    close(&ours.q_v, &v, "∂q₁/∂v₀");
    close(&ours.q_tau, &t, "∂q₁/∂τ");
    let [q, v, t] = differences(state, tau, moved, |s, t| step(s, t).v);
    close(&ours.v_q, &q, "∂v₁/∂q₀");
    close(&ours.v_v, &v, "∂v₁/∂v₀");
    close(&ours.v_tau, &t, "∂v₁/∂τ");
}

/// The projected RK4 step on four feet (`step_with`'s: the stages hold the
/// feet at the acceleration level with Baumgarte's gains, the end's foot
/// velocities projected out; a floating base's quaternion) has its exact
/// Jacobian, projection included: against central differences of the step.
#[test]
fn the_projected_rk4_step_on_four_feet_has_an_exact_jacobian() {
    use joint_runtime::relative::{StepJacobian, StepWork};
    let (sim, state, tau) = solo_with_gains(2);
    let h = 0.01;
    let step = |s: &TreeState<19, 18>, t: &SVector<f64, 18>| {
        let (mut work, mut jacobian) = (Box::new(StepWork::new()), StepJacobian::zeros());
        let mut end = *s;
        sim.rk4_step_jacobian(&mut end, h, t, &mut work, &mut jacobian).unwrap();
        (end, jacobian)
    };
    let (nominal, ours) = step(&state, &tau);
    // The feet stand still at the end: the projection held them.
    let rows = sim.closure_rows(&nominal);
    assert!((rows.jacobian * nominal.v).amax() < 1e-12, "{}", (rows.jacobian * nominal.v).amax());
    step_against_differences(&sim, (&state, &tau), (&nominal, &ours), |s, t| step(s, t).0);
}

/// The constrained semi-implicit Euler step's Jacobian (a contact MPC's
/// node: three feet holding, Baumgarte's gains on, a floating base whose
/// turn goes through `exp`) against central differences of the step itself,
/// `q₁` measured in the tree's increments at the nominal end.
#[test]
fn the_constrained_euler_step_has_an_exact_jacobian() {
    use joint_runtime::relative::StepJacobian;
    let (sim, state, tau) = solo_with_gains(2);
    let three = ActiveRows::named(SoloFeet::CLOSURES, &["fl", "hl", "hr"]).unwrap();
    let h = 0.01;
    let step = |s: &TreeState<19, 18>, t: &SVector<f64, 18>| {
        let (mut work, mut dynamics, mut jacobian) =
            (InverseDerivatives::zeros(), ConstrainedDerivatives::zeros(), StepJacobian::zeros());
        let mut end = *s;
        sim.constrained_euler_step_jacobian(&mut end, h, t, three, &mut work, &mut dynamics, &mut jacobian).unwrap();
        (end, dynamics, jacobian)
    };
    let (nominal, dynamics, ours) = step(&state, &tau);
    // The step is v₁ = v + h q̈ at the start, with the start's q̈.
    assert!((nominal.v - state.v - dynamics.qdd * h).amax() < 1e-12 * nominal.v.amax());
    step_against_differences(&sim, (&state, &tau), (&nominal, &ours), |s, t| step(s, t).0);
}

/// The UR5's tool welded in the world's axes: the same `q̈` as in its own
/// axes, forces turned by the tool's rotation, and exact derivatives.
#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], urdf = "data/robots/ur5.urdf")]
#[contact(weld = frame(tool0))]
struct Ur5WeldWorld;

#[test]
fn a_weld_in_the_worlds_axes_turns_the_forces_alone() {
    let sample = &case("ur5_weld_local")["samples"][2];
    let (world, local) = (TreeSimulation::new(&Ur5WeldWorld).unwrap(), TreeSimulation::new(&Ur5Weld).unwrap());
    let state = Ur5Weld::PINOCCHIO.state_from(&numbers(&sample["q"]), &numbers(&sample["v"])).unwrap();
    let tau = Ur5Weld::PINOCCHIO.forces_from(&state, &numbers(&sample["tau"])).unwrap();
    let (mut work, mut a, mut b) =
        (InverseDerivatives::zeros(), ConstrainedDerivatives::zeros(), ConstrainedDerivatives::zeros());
    world.constrained_dynamics_derivatives(&state, &tau, ActiveRows::all(), &mut work, &mut a).unwrap();
    local.constrained_dynamics_derivatives(&state, &tau, ActiveRows::all(), &mut work, &mut b).unwrap();
    assert!((a.qdd - b.qdd).amax() < 1e-12 * b.qdd.amax());
    // |force| and |torque| are the same in either axes.
    for half in [0, 3] {
        let (x, y) = (a.lambda.fixed_rows::<3>(half).norm(), b.lambda.fixed_rows::<3>(half).norm());
        assert!((x - y).abs() < 1e-12 * y.max(1.0), "{x} {y}");
    }
    let solve = |s: &TreeState<6, 6>, t: &SVector<f64, 6>| {
        let mut o = ConstrainedDerivatives::zeros();
        world.constrained_dynamics(s, t, ActiveRows::all(), &mut o).unwrap();
        o.lambda
    };
    let [q, v, t] = differences(&state, &tau, |q, d| world.tree().displaced(q, d), solve);
    close(&a.lambda_q, &q, "∂λ/∂q");
    close(&a.lambda_v, &v, "∂λ/∂v");
    close(&a.lambda_tau, &t, "∂λ/∂τ");
}

/// A parallelogram hanging from pivots 1 m apart, its loop closed by a
/// revolute joint: one freedom with `θ̈ = −g sin θ (m₁/2 + m₃/2 + m₂) /
/// (I₁ + I₃ + (m₁ + m₃)/4 + m₂)` whatever `θ̇` (the coupler translates).
#[derive(Scene)]
#[scene(gravity = [0, -9.81, 0], coordinates = relative)]
#[body(crank, mass = 1.0, inertia = [0.1, 0.1, 0.1])]
#[body(coupler, mass = 1.5, inertia = [0.1, 0.15, 0.2])]
#[body(rocker, mass = 2.0, inertia = [0.2, 0.1, 0.2])]
#[joint(a = revolute(ground, crank), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0, 0, 0], rho2 = [0, 0.5, 0])]
#[joint(b = revolute(crank, coupler), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0, -0.5, 0], rho2 = [-0.5, 0, 0])]
#[joint(c = revolute(coupler, rocker), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0.5, 0, 0], rho2 = [0, -0.5, 0])]
#[joint(d = revolute(rocker, ground), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0, 0.5, 0], rho2 = [1, 0, 0])]
struct Parallelogram;

#[test]
fn a_parallelogram_swings_as_its_closed_form() {
    let sim = TreeSimulation::new(&Parallelogram).unwrap();
    let (g, reduced) = (9.81, 0.1 + 0.2 + 0.25 * (1.0 + 2.0) + 1.5);
    let weight = 0.5 * 1.0 + 0.5 * 2.0 + 1.5;
    let (mut work, mut out) = (InverseDerivatives::zeros(), ConstrainedDerivatives::zeros());
    for (theta, omega) in [(0.3, 0.0), (-1.1, 2.5), (2.0, -4.0)] {
        let state =
            TreeState { q: SVector::from([theta, -theta, theta]), v: SVector::from([omega, -omega, omega]), t: 0.0 };
        sim.constrained_dynamics_derivatives(&state, &SVector::zeros(), ActiveRows::all(), &mut work, &mut out)
            .unwrap();
        let expected = -g * f64::sin(theta) * weight / reduced;
        assert!((out.qdd - SVector::from([expected, -expected, expected])).amax() < 1e-12, "{}", out.qdd);
        // Along the loop's own freedom: dθ̈/dθ in closed form, nothing from θ̇.
        let along = SVector::from([1.0, -1.0, 1.0]);
        let d_theta = -g * f64::cos(theta) * weight / reduced;
        assert!(((out.d_q * along)[0] - d_theta).abs() < 1e-11, "{} {d_theta}", (out.d_q * along)[0]);
        assert!((out.d_v * along)[0].abs() < 1e-11);
    }
}

/// The parallelogram hanging still, linearised: `linearise` takes the
/// loop's minimal coordinates exactly (the closures' second-order terms),
/// and the mode is the closed form's, `ω² = g (m₁/2 + m₃/2 + m₂) / (I₁ + I₃
/// + (m₁ + m₃)/4 + m₂)`.
#[test]
fn the_parallelogram_linearises_exactly() {
    let mut sim = TreeSimulation::new(&Parallelogram).unwrap();
    let hanging = TreeState { q: SVector::zeros(), v: SVector::zeros(), t: 0.0 };
    let lin = sim.linearise(&hanging, &SVector::zeros()).unwrap();
    assert_eq!(lin.freedoms, 1);
    let omega = (9.81 * (0.5 + 1.0 + 1.5) / (0.1 + 0.2 + 0.25 * 3.0 + 1.5_f64)).sqrt();
    let poles = lin.eigenvalues().unwrap();
    assert_eq!(poles.len(), 2);
    for e in poles {
        assert!((e.im.abs() - omega).abs() < 1e-10 && e.re.abs() < 1e-10, "{e} against ±{omega} i");
    }
}

/// The kit's serial four-bar with its contact declared twice: six rows of
/// rank two.
#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], coordinates = relative)]
#[body(crank, mass = 0.3, inertia = [0.3 * 0.0004 / 2.0, 0.3 * (0.0012 + 0.09) / 12.0, 0.3 * (0.0012 + 0.09) / 12.0])]
#[body(coupler, mass = 1.0, inertia = [0.0004 / 2.0, (0.0012 + 1.0) / 12.0, (0.0012 + 1.0) / 12.0])]
#[body(rocker, mass = 0.8, inertia = [0.8 * 0.0004 / 2.0, 0.8 * (0.0012 + 0.64) / 12.0, 0.8 * (0.0012 + 0.64) / 12.0])]
#[joint(a = revolute(ground, crank), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0, 0, 0], rho2 = [-0.15, 0, 0])]
#[joint(b = revolute(crank, coupler), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0.15, 0, 0], rho2 = [-0.5, 0, 0])]
#[joint(c = revolute(coupler, rocker), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0.5, 0, 0], rho2 = [-0.4, 0, 0])]
#[contact(tip = point(rocker), at = [0.4, 0, 0], axes = local; again = point(rocker), at = [0.4, 0, 0], axes = local)]
struct FourBarTwice;

/// The proximal iterations give Pinocchio's `q̈` and least-norm `λ` (its
/// own proximal solve's, the out-of-plane force zero) on the four-bar, and,
/// with the contact declared twice, the same `q̈` and half the force on each
/// copy, where the pivoted solve puts all of it on one.
#[test]
fn proximal_iterations_give_the_least_norm_forces() {
    use joint_runtime::relative::Proximal;
    let (once, twice) = (TreeSimulation::new(&FourBarSerial).unwrap(), TreeSimulation::new(&FourBarTwice).unwrap());
    for sample in case("fourbar_serial")["samples"].as_array().unwrap() {
        let state = TreeState {
            q: SVector::from_column_slice(&numbers(&sample["q"])),
            v: SVector::from_column_slice(&numbers(&sample["v"])),
            t: 0.0,
        };
        let tau = SVector::from_column_slice(&numbers(&sample["tau"]));
        let (qdd, lambda) = (matrix_of(&sample["ddq"]), matrix_of(&sample["lambda"]));
        let mut one = ConstrainedDerivatives::zeros();
        let iterations = once
            .constrained_dynamics_proximal(&state, &tau, ActiveRows::all(), &Proximal::default(), &mut one)
            .unwrap();
        assert!(iterations <= 5, "{iterations}");
        assert!(relative(&dense(&one.qdd), &qdd) < 1e-12 && relative(&dense(&one.lambda), &lambda) < 1e-12);
        let mut two = ConstrainedDerivatives::zeros();
        let iterations = twice
            .constrained_dynamics_proximal(&state, &tau, ActiveRows::all(), &Proximal::default(), &mut two)
            .unwrap();
        assert_eq!(two.rank, 2);
        assert!(relative(&dense(&two.qdd), &qdd) < 1e-10);
        let half = &lambda * 0.5;
        let split = relative(&dense(&two.lambda.fixed_rows::<3>(0).into_owned()), &half)
            .max(relative(&dense(&two.lambda.fixed_rows::<3>(3).into_owned()), &half));
        eprintln!("proximal: {iterations} iterations, each copy {split:.1e} from half the force");
        assert!(split < 1e-9 && iterations <= 20);
        // The pivoted solve: the same q̈, the force on one copy.
        let mut basic = ConstrainedDerivatives::zeros();
        twice.constrained_dynamics(&state, &tau, ActiveRows::all(), &mut basic).unwrap();
        assert!(relative(&dense(&basic.qdd), &qdd) < 1e-12);
        let sum = basic.lambda.fixed_rows::<3>(0) + basic.lambda.fixed_rows::<3>(3);
        assert!(relative(&dense(&sum.into_owned()), &lambda) < 1e-12);
    }
}

fn matrix_of(v: &Value) -> DMatrix<f64> {
    DMatrix::from_column_slice(v.as_array().unwrap().len(), 1, &numbers(v))
}

/// The serial four-bar in both coordinates, with its contact.
#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], coordinates = both)]
#[body(crank, mass = 0.3, inertia = [0.3 * 0.0004 / 2.0, 0.3 * (0.0012 + 0.09) / 12.0, 0.3 * (0.0012 + 0.09) / 12.0])]
#[body(coupler, mass = 1.0, inertia = [0.0004 / 2.0, (0.0012 + 1.0) / 12.0, (0.0012 + 1.0) / 12.0])]
#[body(rocker, mass = 0.8, inertia = [0.8 * 0.0004 / 2.0, 0.8 * (0.0012 + 0.64) / 12.0, 0.8 * (0.0012 + 0.64) / 12.0])]
#[joint(a = revolute(ground, crank), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0, 0, 0], rho2 = [-0.15, 0, 0])]
#[joint(b = revolute(crank, coupler), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0.15, 0, 0], rho2 = [-0.5, 0, 0])]
#[joint(c = revolute(coupler, rocker), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0.5, 0, 0], rho2 = [-0.4, 0, 0])]
#[contact(tip = point(rocker), at = [0.4, 0, 0], axes = local)]
struct FourBarBoth;

/// Contacts are rows of the tree alone: a `both` scene with one runs on the
/// tree, where it holds, and its step keeps the rocker's tip still.
#[test]
fn a_scene_in_both_coordinates_with_contacts_runs_on_the_tree() {
    use joint_runtime::dynamics::{NoLoads, Simulation, SimulationOptions};
    let mut sim = Simulation::new(&FourBarBoth, NoLoads, &[], SimulationOptions::default()).unwrap();
    let tree: &TreeSimulation<'_, FourBarBoth, 3, 3, 3, 3> = &sim;
    let sample = &case("fourbar_serial")["samples"][0];
    let mut state = TreeState {
        q: SVector::from_column_slice(&numbers(&sample["q"])),
        v: SVector::from_column_slice(&numbers(&sample["v"])),
        t: 0.0,
    };
    let tip = |sim: &TreeSimulation<'_, FourBarBoth, 3, 3, 3, 3>, s: &TreeState<3, 3>| {
        sim.system_state(s).bodies[2].point(&joint_runtime::nalgebra::Vector3::new(0.4, 0.0, 0.0))
    };
    let start = tip(tree, &state);
    for _ in 0..200 {
        sim.step(&mut state, 1e-3).unwrap();
    }
    assert!((tip(&sim, &state) - start).norm() < 1e-6, "{}", (tip(&sim, &state) - start).norm());
}

/// An MJCF four-bar closed by `connect`, read as an ideal row.
#[derive(Scene)]
#[scene(mjcf = "data/mjcf/four_bar.xml", equality = hard)]
struct FourBarConnect;

/// A file's loop gets the same: its constrained dynamics' derivatives
/// against central differences (the loop's rows with positions, Baumgarte's
/// gains on), at a closed state.
#[test]
fn a_files_connect_has_exact_derivatives() {
    use joint_runtime::dynamics::{SimulationOptions, Stabilisation};
    let options = SimulationOptions::default().with_stabilisation(Stabilisation::Baumgarte { alpha: 2.0, beta: 3.0 });
    let sim = TreeSimulation::new(&FourBarConnect).unwrap().with_options(options).unwrap();
    let mut guess = sim.tree().zero_state();
    guess.v = SVector::from([1.0, -0.5, 0.7]);
    let state = sim.assemble(&guess).unwrap();
    let tau = SVector::from([0.3, -0.2, 0.1]);
    let (mut work, mut out) = (InverseDerivatives::zeros(), ConstrainedDerivatives::zeros());
    sim.constrained_dynamics_derivatives(&state, &tau, ActiveRows::all(), &mut work, &mut out).unwrap();
    let solve = |s: &TreeState<3, 3>, t: &SVector<f64, 3>| {
        let mut o = ConstrainedDerivatives::<3, 2>::zeros();
        sim.constrained_dynamics(s, t, ActiveRows::all(), &mut o).unwrap();
        (o.qdd, o.lambda)
    };
    let moved = |q: &SVector<f64, 3>, d: &SVector<f64, 3>| sim.tree().displaced(q, d);
    let [q, v, t] = differences(&state, &tau, moved, |s, t| solve(s, t).0);
    close(&out.d_q, &q, "∂q̈/∂q");
    close(&out.d_v, &v, "∂q̈/∂v");
    close(&out.d_tau, &t, "∂q̈/∂τ");
    let [q, v, t] = differences(&state, &tau, moved, |s, t| solve(s, t).1);
    close(&out.lambda_q, &q, "∂λ/∂q");
    close(&out.lambda_v, &v, "∂λ/∂v");
    close(&out.lambda_tau, &t, "∂λ/∂τ");
}

/// Contacts at an MJCF file's sites: the ball pendulum's `tip` site (on the
/// bob, its z turned onto x) held as a point in the world's axes and as a
/// frame in its own; each contact's `J v` against the site's velocity from
/// the runtime's own kinematics (`LinkFrame::velocity`, `LinkFrame::pose`):
/// `ṗ`, and `[R_fᵀ ṗ; R_fᵀ ω]`.
#[derive(Scene)]
#[scene(mjcf = "data/mjcf/ball_pendulum.xml")]
#[contact(point_at_tip = point(tip); frame_at_tip = frame(tip), axes = local)]
struct HeldAtItsSite;

#[test]
fn contacts_at_mjcf_sites() {
    use joint_runtime::nalgebra::{Vector3, Vector4};
    use joint_runtime::robot::LinkFrame;
    let sim = TreeSimulation::new(&HeldAtItsSite).unwrap();
    let tip = LinkFrame::find(&HeldAtItsSite::LINKS, "tip").unwrap();
    let mut worst = 0.0_f64;
    for k in 0..5 {
        let x = f64::from(k);
        let q = Vector4::new(0.9, 0.3 - 0.1 * x, -0.2, 0.25 + 0.05 * x).normalize();
        let state = TreeState::<4, 3> { q, v: Vector3::new(0.7 - 0.2 * x, -1.1, 0.4 + 0.3 * x), t: 0.0 };
        let rows = sim.closure_rows(&state);
        let psi = rows.jacobian * state.v;
        let system = sim.system_state(&state);
        let (turn, _) = tip.pose(&system);
        let (spin, velocity) = tip.velocity(&system);
        let back = turn.to_rotation_matrix().transpose();
        let expected = [velocity, back * velocity, back * spin];
        for (n, e) in expected.iter().enumerate() {
            worst = worst.max((psi.fixed_rows::<3>(3 * n) - e).amax());
        }
    }
    eprintln!("contacts at an MJCF site: J v to {worst:.1e} of the site's own velocity");
    assert!(worst < 1e-13, "{worst:e}");
}
