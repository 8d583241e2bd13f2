//! The dynamics' exact first derivatives (`#[scene(second_order)]` in
//! relative coordinates): every joint kind a tree has, armature and damping,
//! against central differences of the library's own inverse and forward
//! dynamics along the tangent space (`Tree::displace`); the robots from
//! their files against Pinocchio's analytical derivatives
//! (`tests/data/robots/derivatives.py` wrote them).

use joint_runtime::Scene;
use joint_runtime::nalgebra::{SMatrix, SVector};
use joint_runtime::relative::{
    ForwardDerivatives, InverseDerivatives, SecondDerivatives, StepJacobian, StepWork, TreeError, TreeScene,
    TreeSimulation, TreeState,
};

use super::tree::quaternion;

/// `menagerie!(Name, options..)`: every kind of tree joint at once: a floating drone (free) with a
/// gripper on a ball joint (damped) and a finger on a hinge (armature,
/// damping, a spring); a cylindrical shaft from the ground with a wheel, a
/// universal arm, a slider on the arm (a spring) and a plate welded to it; a
/// puck on a planar joint.
macro_rules! menagerie {
    ($name:ident $(, $option:ident)*) => {
        #[derive(Scene)]
        #[scene(gravity = [0, 0, -9.81], coordinates = relative $(, $option)*)]
        #[body(drone, mass = 2.0, inertia = [0.05, 0.06, 0.09, 0.004, -0.002, 0.001])]
        #[body(gripper, mass = 0.5, inertia = [0.004, 0.004, 0.001])]
        #[body(finger, mass = 0.1, inertia = [0.0005, 0.0005, 0.0001])]
        #[body(shaft, mass = 1.0, inertia = [0.1, 0.1, 0.02])]
        #[body(wheel, mass = 0.4, inertia = [0.008, 0.005, 0.005, 0.001, 0.0, 0.0])]
        #[body(arm, mass = 0.7, inertia = [0.03, 0.02, 0.012])]
        #[body(block, mass = 0.3, inertia = [0.002, 0.003, 0.004])]
        #[body(plate, mass = 0.2, inertia = [0.001, 0.002, 0.0025])]
        #[body(puck, mass = 1.0, inertia = [0.02, 0.02, 0.04])]
        #[joint(claw = spherical(drone, gripper), rho1 = [0.1, 0, -0.1], rho2 = [0, 0, 0.15], damping = 0.05)]
        #[joint(knuckle = revolute(gripper, finger), axis1 = [1, 0, 0], axis2 = [1, 0, 0], rho1 = [0, 0, -0.15], rho2 = [0, 0, 0.05], armature = 0.01, damping = 0.1, stiffness = 2.0, spring_rest = 0.3)]
        #[joint(bush = cylindrical(ground, shaft), axis1 = [0.3, 0, 1], axis2 = [0, 0, 1], rho1 = [0, 0, 1], rho2 = [0, 0, 0])]
        #[joint(hub = revolute(shaft, wheel), axis1 = [1, 0, 0], axis2 = [1, 0, 0], rho1 = [0.2, 0, 0.3], rho2 = [0, 0, 0])]
        #[joint(gimbal = universal(shaft, arm), s = [1, 0, 0], h = [0.2, 1, 0], rho1 = [0, 0, 0.4], rho2 = [0, 0, 0.5])]
        #[joint(rail = translational(arm, block), axis1 = [1, 0, 0.5], axis2 = [0, 1, 0], rho1 = [0, 0, -0.5], rho2 = [0.1, 0, 0], stiffness = 40.0, spring_rest = -0.1)]
        #[joint(weld = fixed(block, plate), axis1 = [0, 0, 1], axis2 = [1, 0, 0], rho1 = [0.2, 0, 0], rho2 = [0, 0, 0])]
        #[joint(table = planar(ground, puck), axis1 = [0, -0.4, 1], axis2 = [0, 0, 1], rho1 = [0, 0, 0.5], rho2 = [0, 0, 0])]
        struct $name;
    };
}

menagerie!(Menagerie, second_order);

/// A small deterministic generator (xorshift), uniform in `[-1, 1]`.
struct Draw(u64);

impl Draw {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }
}

/// A random state of `sim`'s tree: angles and slides in `[-1, 1]`, random
/// unit quaternions, velocities in `[-2, 2]`.
fn random_state<S: TreeScene<NB, NQ, NV, NC>, const NB: usize, const NQ: usize, const NV: usize, const NC: usize>(
    sim: &TreeSimulation<'_, S, NB, NQ, NV, NC>,
    draw: &mut Draw,
) -> TreeState<NQ, NV> {
    let mut q = SVector::<f64, NQ>::from_fn(|_, _| draw.next());
    let mut at = 0;
    for j in sim.tree().joints() {
        if let Some(p) = j.kind.quaternion() {
            let [a, b, c, d] = quaternion(draw.next(), draw.next(), draw.next(), draw.next());
            q.fixed_rows_mut::<4>(at + p).copy_from_slice(&[a, b, c, d]);
        }
        at += j.kind.coordinates();
    }
    TreeState { q, v: SVector::from_fn(|_, _| 2.0 * draw.next()), t: 0.0 }
}

/// Central differences of `f` along each tangent direction of `q` and each
/// velocity: `(∂f/∂q, ∂f/∂v)`.
fn differences<S, const NB: usize, const NQ: usize, const NV: usize>(
    sim: &TreeSimulation<'_, S, NB, NQ, NV>,
    state: &TreeState<NQ, NV>,
    f: &dyn Fn(&TreeState<NQ, NV>) -> SVector<f64, NV>,
) -> (SMatrix<f64, NV, NV>, SMatrix<f64, NV, NV>)
where
    S: TreeScene<NB, NQ, NV>,
{
    let h = 1e-6;
    let mut d_q = SMatrix::<f64, NV, NV>::zeros();
    let mut d_v = SMatrix::<f64, NV, NV>::zeros();
    for i in 0..NV {
        let e = SVector::<f64, NV>::from_fn(|r, _| if r == i { h } else { 0.0 });
        let at = |sign: f64| TreeState { q: sim.tree().displaced(&state.q, &(e * sign)), ..*state };
        d_q.set_column(i, &((f(&at(1.0)) - f(&at(-1.0))) / (2.0 * h)));
        let at = |sign: f64| TreeState { v: state.v + e * sign, ..*state };
        d_v.set_column(i, &((f(&at(1.0)) - f(&at(-1.0))) / (2.0 * h)));
    }
    (d_q, d_v)
}

/// The largest difference over the largest entry of `theirs`.
fn relative<const R: usize, const C: usize>(ours: &SMatrix<f64, R, C>, theirs: &SMatrix<f64, R, C>) -> f64 {
    (ours - theirs).amax() / theirs.amax().max(f64::MIN_POSITIVE)
}

/// Both derivatives of `scene` at `samples` random states against central
/// differences of the library's own dynamics; returns the worst of each.
fn against_differences<S, const NB: usize, const NQ: usize, const NV: usize>(scene: &S, samples: usize) -> [f64; 6]
where
    S: TreeScene<NB, NQ, NV>,
{
    let sim = TreeSimulation::new(scene).unwrap();
    let mut draw = Draw(0x9e37_79b9_7f4a_7c15);
    let (mut inverse, mut forward) = (InverseDerivatives::<NV>::zeros(), ForwardDerivatives::<NV>::zeros());
    let mut worst = [0.0_f64; 6];
    for _ in 0..samples {
        let state = random_state(&sim, &mut draw);
        let a = SVector::<f64, NV>::from_fn(|_, _| draw.next());
        let tau = SVector::<f64, NV>::from_fn(|_, _| draw.next());
        sim.inverse_dynamics_derivatives(&state, &a, &mut inverse).unwrap();
        assert!((inverse.tau - sim.inverse_dynamics(&state, &a)).amax() < 1e-12 * (1.0 + inverse.tau.amax()));
        let (d_q, d_v) = differences(&sim, &state, &|s| sim.inverse_dynamics(s, &a));
        worst[0] = worst[0].max(relative(&inverse.d_q, &d_q));
        worst[1] = worst[1].max(relative(&inverse.d_v, &d_v));
        let mut m = SMatrix::<f64, NV, NV>::zeros();
        sim.mass_matrix_into(&state.q, &mut m);
        assert_eq!(inverse.d_a, m);

        sim.forward_dynamics_derivatives(&state, &tau, &mut inverse, &mut forward).unwrap();
        let (d_q, d_v) = differences(&sim, &state, &|s| sim.tree_dynamics(s, &tau).unwrap());
        worst[2] = worst[2].max(relative(&forward.d_q, &d_q));
        worst[3] = worst[3].max(relative(&forward.d_v, &d_v));
        worst[4] = worst[4].max((forward.d_tau * m - SMatrix::<f64, NV, NV>::identity()).amax());
        worst[5] = worst[5].max(relative(&forward.qdd, &sim.tree_dynamics(&state, &tau).unwrap()));
    }
    worst
}

#[test]
fn every_joint_kind_against_differences() {
    let worst = against_differences(&Menagerie, 20);
    eprintln!(
        "every kind: ∂τ/∂q {:.1e}, ∂τ/∂v {:.1e}, ∂q̈/∂q {:.1e}, ∂q̈/∂v {:.1e} of the largest entry; M⁻¹ M − I {:.1e}",
        worst[0], worst[1], worst[2], worst[3], worst[4]
    );
    for (what, w) in ["∂τ/∂q", "∂τ/∂v", "∂q̈/∂q", "∂q̈/∂v"].iter().zip(worst) {
        assert!(w < 1e-7, "{what} off its central differences by {w:e} of the largest entry");
    }
    assert!(worst[4] < 1e-10 && worst[5] < 1e-12, "{worst:?}");
}

/// Gravity compensation (MJCF `gravcomp`) on a floating robot with ball,
/// hinge and slide joints: its derivatives' closed form against central
/// differences, by the runtime's recursion (the derive would write them
/// out in 12 510 operations, past its limit of 8 000: `second_order` here
/// would change nothing, and says so).
#[derive(Scene)]
#[scene(mjcf = "data/mjcf/held_robot.xml")]
struct HeldRobot;

#[test]
fn gravity_compensation_against_differences() {
    for worst in [against_differences(&HeldRobot, 10)] {
        eprintln!(
            "held robot: ∂τ/∂q {:.1e}, ∂τ/∂v {:.1e}, ∂q̈/∂q {:.1e}, ∂q̈/∂v {:.1e}",
            worst[0], worst[1], worst[2], worst[3]
        );
        // The accelerations' differences lose more digits: the tip's inertia
        // (2e-5 kg·m²) makes M⁻¹ large; compensation does not enter ∂/∂v.
        for ((what, w), bound) in ["∂τ/∂q", "∂τ/∂v", "∂q̈/∂q", "∂q̈/∂v"].iter().zip(worst).zip([1e-7, 1e-7, 1e-6, 1e-6])
        {
            assert!(w < bound, "{what} off its central differences by {w:e} of the largest entry");
        }
    }
}

/// A pendulum without `second_order` gets its derivatives by the runtime's
/// recursion: the closed form, and `NonFinite` for a state that is not.
#[test]
fn a_scene_that_did_not_ask_gets_the_recursion() {
    #[derive(Scene)]
    #[scene(gravity = [0, 0, -9.81], coordinates = relative)]
    #[body(bar, mass = 2.0, inertia = [0.001, 0.1, 0.1])]
    #[joint(pin = revolute(ground, bar), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0, 0, 0], rho2 = [-0.5, 0, 0], damping = 0.3)]
    struct Plain;

    let sim = TreeSimulation::new(&Plain).unwrap();
    let state = TreeState { q: SVector::from([0.3]), v: SVector::from([0.1]), t: 0.0 };
    let mut d = InverseDerivatives::zeros();
    sim.inverse_dynamics_derivatives(&state, &SVector::from([0.7]), &mut d).unwrap();
    // τ = (I + m l²) θ̈ − m g l cos θ + c θ̇ (the centre at height −l sin θ).
    let (m, g, l, c) = (2.0, 9.81, 0.5, 0.3);
    let expected = (0.1 + m * l * l) * 0.7 - m * g * l * 0.3f64.cos() + c * 0.1;
    assert!((d.tau[0] - expected).abs() < 1e-12, "{} against {expected}", d.tau[0]);
    assert!((d.d_q[(0, 0)] - m * g * l * 0.3f64.sin()).abs() < 1e-12, "{}", d.d_q[(0, 0)]);
    assert!((d.d_v[(0, 0)] - c).abs() < 1e-15, "{}", d.d_v[(0, 0)]);
    let bad = TreeState { q: SVector::from([f64::NAN]), ..state };
    assert_eq!(sim.inverse_dynamics_derivatives(&bad, &SVector::zeros(), &mut d), Err(TreeError::NonFinite));
}

// The menagerie again, without `second_order`: the recursion's.
menagerie!(MenagerieByRecursion);

#[test]
fn the_recursion_on_every_joint_kind() {
    let worst = against_differences(&MenagerieByRecursion, 20);
    eprintln!(
        "every kind, recursion: ∂τ/∂q {:.1e}, ∂τ/∂v {:.1e}, ∂q̈/∂q {:.1e}, ∂q̈/∂v {:.1e} of the largest entry",
        worst[0], worst[1], worst[2], worst[3]
    );
    for (what, w) in ["∂τ/∂q", "∂τ/∂v", "∂q̈/∂q", "∂q̈/∂v"].iter().zip(worst) {
        assert!(w < 1e-7, "{what} off its central differences by {w:e} of the largest entry");
    }
    // ...and the generated straight line's, to round-off.
    assert!(written(&Menagerie) && !written(&MenagerieByRecursion));
    let (generated, recursion) =
        (TreeSimulation::new(&Menagerie).unwrap(), TreeSimulation::new(&MenagerieByRecursion).unwrap());
    let mut draw = Draw(0x2545_f491_4f6c_dd1d);
    let (mut a, mut b) = (InverseDerivatives::zeros(), InverseDerivatives::zeros());
    let mut gap = [0.0_f64; 3];
    for _ in 0..50 {
        let state = random_state(&generated, &mut draw);
        let vdot = SVector::from_fn(|_, _| draw.next());
        generated.inverse_dynamics_derivatives(&state, &vdot, &mut a).unwrap();
        recursion.inverse_dynamics_derivatives(&state, &vdot, &mut b).unwrap();
        gap[0] = gap[0].max(relative(&b.tau, &a.tau));
        gap[1] = gap[1].max(relative(&b.d_q, &a.d_q));
        gap[2] = gap[2].max(relative(&b.d_v, &a.d_v));
        // The runtime's own recursions (springs, damping, armature) against the written ones.
        crate::tree::generated_against_recursion(&Menagerie, &state, true);
    }
    eprintln!(
        "every kind, recursion against the straight line: τ {:.1e}, ∂τ/∂q {:.1e}, ∂τ/∂v {:.1e}",
        gap[0], gap[1], gap[2]
    );
    assert!(gap.iter().all(|&g| g < 1e-13), "{gap:?}");
}

#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], urdf = "data/robots/ur5.urdf", second_order)]
struct Ur5;

/// The fingers' coupling read as an independent joint, as Pinocchio's
/// reader does by default (its values are for that model).
#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], urdf = "data/robots/panda.urdf", mimic = independent)]
struct Panda;

#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], urdf = "data/robots/solo12.urdf", floating_base)]
struct Solo12Floating;

/// Every sample of `robot`'s Pinocchio derivatives: `τ`, `∂τ/∂q`, `∂τ/∂v`
/// (`computeRNEADerivatives`) and `q̈`, `∂q̈/∂q`, `∂q̈/∂v`, `M⁻¹`
/// (`computeABADerivatives`); returns the worst of each, relative to each
/// matrix's largest entry.
fn against_pinocchio<S, const NB: usize, const NQ: usize, const NV: usize>(scene: &S, robot: &str) -> [f64; 8]
where
    S: TreeScene<NB, NQ, NV>,
{
    use super::urdf::{joint_map, numbers, our_q, our_v, reference};
    let data = reference(&format!("{robot}_derivatives"));
    let sim = TreeSimulation::new(scene).unwrap();
    let map = joint_map(&sim, &data);
    let mut index = Vec::with_capacity(NV);
    for &(kind, _, theirs) in &map {
        index.extend((0..kind.freedoms()).map(|i| theirs + i));
    }
    let matrix = |value: &serde_json::Value| {
        let rows: Vec<Vec<f64>> = value.as_array().unwrap().iter().map(numbers).collect();
        SMatrix::<f64, NV, NV>::from_fn(|r, c| rows[index[r]][index[c]])
    };
    let (mut inverse, mut forward) = (InverseDerivatives::<NV>::zeros(), ForwardDerivatives::<NV>::zeros());
    let (mut worst, mut residual) = ([0.0_f64; 8], 0.0_f64);
    for s in data["samples"].as_array().unwrap() {
        let v = |key: &str| our_v::<NV>(&map, &numbers(&s[key]));
        let state = TreeState::<NQ, NV> { q: our_q(&map, &numbers(&s["q"])), v: v("v"), t: 0.0 };
        sim.forward_dynamics_derivatives(&state, &v("tau"), &mut inverse, &mut forward).unwrap();
        worst[1] = worst[1].max(relative(&forward.qdd, &v("aba")));
        let ours = [forward.d_q, forward.d_v, forward.d_tau];
        for (w, (o, key)) in worst[5..].iter_mut().zip(ours.iter().zip(["daba_dq", "daba_dv", "minv"])) {
            *w = w.max(relative(o, &matrix(&s[key])));
        }
        sim.inverse_dynamics_derivatives(&state, &v("a"), &mut inverse).unwrap();
        worst[0] = worst[0].max(relative(&inverse.tau, &v("rnea")));
        worst[2] = worst[2].max(relative(&inverse.d_q, &matrix(&s["drnea_dq"])));
        worst[3] = worst[3].max(relative(&inverse.d_v, &matrix(&s["drnea_dv"])));
        let mut m = SMatrix::<f64, NV, NV>::zeros();
        sim.mass_matrix_into(&state.q, &mut m);
        worst[4] = worst[4].max(relative(&inverse.d_a, &m));
        residual = residual.max((matrix(&s["minv"]) * m - SMatrix::<f64, NV, NV>::identity()).amax());
    }
    eprintln!(
        "{robot}: τ {:.1e}, q̈ {:.1e}, ∂τ/∂q {:.1e}, ∂τ/∂v {:.1e}, ∂q̈/∂q {:.1e}, ∂q̈/∂v {:.1e}, M⁻¹ {:.1e} of the \
         largest entry (their M⁻¹ M − I {residual:.1e})",
        worst[0], worst[1], worst[2], worst[3], worst[5], worst[6], worst[7]
    );
    // What goes through M⁻¹ is as good as the reference's own inverse
    // (the floating Solo12's light legs on a heavy base: 5e-13).
    let bound = |i: usize| if i < 5 { 1e-12 } else { 1e-12_f64.max(4.0 * residual) };
    let names = ["τ", "q̈", "∂τ/∂q", "∂τ/∂v", "M", "∂q̈/∂q", "∂q̈/∂v", "M⁻¹"];
    for (i, (what, w)) in names.iter().zip(worst).enumerate() {
        assert!(w < bound(i), "{robot}: {what} off Pinocchio's by {w:e} of its largest entry");
    }
    worst
}

#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], urdf = "data/robots/ur5.urdf")]
struct Ur5ByRecursion;

/// Whether the derive wrote `scene`'s first derivatives out.
fn written<S: TreeScene<NB, NQ, NV, NC>, const NB: usize, const NQ: usize, const NV: usize, const NC: usize>(
    _: &S,
) -> bool {
    S::DERIVATIVES
}

/// The UR5 without `second_order`: the runtime's recursion. (The Panda's
/// and the floating Solo12's straight lines would be past the limit where
/// the recursion is faster: theirs is the recursion either way.)
#[test]
fn the_recursion_against_pinocchio() {
    assert!(written(&Ur5) && !written(&Ur5ByRecursion));
    assert!(!written(&Panda) && !written(&Solo12Floating));
    against_pinocchio(&Ur5ByRecursion, "ur5");
}

#[test]
fn ur5_against_pinocchio() {
    against_pinocchio(&Ur5, "ur5");
}

#[test]
fn panda_against_pinocchio() {
    against_pinocchio(&Panda, "panda");
}

#[test]
fn solo12_floating_base_against_pinocchio() {
    against_pinocchio(&Solo12Floating, "solo12_floating");
}

/// One step's exact Jacobian (RK4 and semi-implicit Euler) against
/// Pinocchio's chain rule through its analytical derivatives (the first 20
/// samples of each fixed-base robot), its `τ` columns against central
/// differences of the step, and the step itself against `step_with`.
fn steps_against_pinocchio<S, const NB: usize, const NV: usize>(scene: &S, robot: &str) -> [f64; 3]
where
    S: TreeScene<NB, NV, NV>,
{
    use super::urdf::{joint_map, numbers, our_q, our_v, reference};
    let data = reference(&format!("{robot}_derivatives"));
    let mut sim = TreeSimulation::new(scene).unwrap();
    let map = joint_map(&sim, &data);
    let h = data["h"].as_f64().unwrap();
    let mut index = Vec::with_capacity(NV);
    for &(kind, _, theirs) in &map {
        index.extend((0..kind.freedoms()).map(|i| theirs + i));
    }
    let (mut work, mut out) = (StepWork::new(), StepJacobian::zeros());
    let mut worst = [0.0_f64; 3];
    for s in data["samples"].as_array().unwrap().iter().filter(|s| s.get("rk4_phi").is_some()) {
        let v = |key: &str| our_v::<NV>(&map, &numbers(&s[key]));
        let start = TreeState::<NV, NV> { q: our_q(&map, &numbers(&s["q"])), v: v("v"), t: 0.0 };
        let tau = v("tau");
        for (k, key) in ["rk4_phi", "euler_phi"].iter().enumerate() {
            let mut end = start;
            if k == 0 {
                sim.rk4_step_jacobian(&mut end, h, &tau, &mut work, &mut out).unwrap();
                let mut reference_end = start;
                sim.step_with(&mut reference_end, h, &tau).unwrap();
                assert!((end.q - reference_end.q).amax() < 1e-15 && (end.v - reference_end.v).amax() < 1e-13);
            } else {
                sim.euler_step_jacobian(&mut end, h, &tau, &mut work, &mut out).unwrap();
            }
            let rows: Vec<Vec<f64>> = s[*key].as_array().unwrap().iter().map(numbers).collect();
            let at = |i: usize| (i / NV) * NV + index[i % NV];
            let (mut diff, mut scale) = (0.0_f64, 0.0_f64);
            for r in 0..2 * NV {
                for c in 0..2 * NV {
                    diff = diff.max((out.entry(r, c) - rows[at(r)][at(c)]).abs());
                    scale = scale.max(rows[at(r)][at(c)].abs());
                }
            }
            worst[k] = worst[k].max(diff / scale);
        }
        // The RK4 step's τ columns against central differences of the step.
        let mut end = start;
        sim.rk4_step_jacobian(&mut end, h, &tau, &mut work, &mut out).unwrap();
        for i in 0..NV {
            let push = SVector::<f64, NV>::from_fn(|r, _| if r == i { 1e-4 } else { 0.0 });
            let stepped = |tau: SVector<f64, NV>| {
                let mut s = start;
                TreeSimulation::new(scene).unwrap().step_with(&mut s, h, &tau).unwrap();
                s
            };
            let (plus, minus) = (stepped(tau + push), stepped(tau - push));
            let dq = (plus.q - minus.q) / 2e-4;
            let dv = (plus.v - minus.v) / 2e-4;
            let scale = out.v_tau.amax();
            worst[2] = worst[2].max((dq - out.q_tau.column(i)).amax() / scale);
            worst[2] = worst[2].max((dv - out.v_tau.column(i)).amax() / scale);
        }
    }
    eprintln!(
        "{robot}: the RK4 step's Jacobian {:.1e}, the semi-implicit Euler step's {:.1e} of the largest entry off \
         Pinocchio's chain rule; ∂/∂τ {:.1e} off differences",
        worst[0], worst[1], worst[2]
    );
    assert!(worst[0] < 1e-12 && worst[1] < 1e-12, "{robot}: {worst:?}");
    assert!(worst[2] < 1e-7, "{robot}: {worst:?}");
    worst
}

#[test]
fn step_jacobians_against_pinocchio() {
    steps_against_pinocchio(&Ur5, "ur5");
    steps_against_pinocchio(&Panda, "panda");
}

/// Both steps' exact Jacobians on the tree of every joint kind (a floating
/// drone's and a ball joint's quaternions among them) against central
/// differences of the same steps in the tree's increments at both ends.
#[test]
fn step_jacobians_of_every_joint_kind_against_differences() {
    let sim = TreeSimulation::new(&Menagerie).unwrap();
    let mut draw = Draw(7);
    let (mut work, mut out) = (StepWork::new(), StepJacobian::zeros());
    let h = 1e-2;
    let mut worst = [0.0_f64; 2];
    for _ in 0..5 {
        let start = random_state(&sim, &mut draw);
        let tau = SVector::<f64, 19>::from_fn(|_, _| draw.next());
        for (k, worst) in worst.iter_mut().enumerate() {
            // The step `k` (RK4, Euler) from a moved start with moved forces.
            let step = |s: &mut MenagerieTreeState, t: &SVector<f64, 19>, out: &mut StepJacobian<19>| {
                let mut work = StepWork::new();
                if k == 0 {
                    sim.rk4_step_jacobian(s, h, t, &mut work, out).unwrap();
                } else {
                    sim.euler_step_jacobian(s, h, t, &mut work, out).unwrap();
                }
            };
            let mut end = start;
            if k == 0 {
                sim.rk4_step_jacobian(&mut end, h, &tau, &mut work, &mut out).unwrap();
            } else {
                sim.euler_step_jacobian(&mut end, h, &tau, &mut work, &mut out).unwrap();
            }
            let mut scratch = StepJacobian::zeros();
            let eps = 1e-6;
            let (mut diff, mut scale) = (0.0_f64, 0.0_f64);
            for c in 0..3 * 19 {
                let moved = |sign: f64| {
                    let (mut s, mut t) = (start, tau);
                    let e = SVector::<f64, 19>::from_fn(|r, _| if r == c % 19 { sign * eps } else { 0.0 });
                    match c / 19 {
                        0 => s.q = sim.tree().displaced(&start.q, &e),
                        1 => s.v += e,
                        _ => t += e,
                    }
                    (s, t)
                };
                let ((mut a, ta), (mut b, tb)) = (moved(1.0), moved(-1.0));
                step(&mut a, &ta, &mut scratch);
                step(&mut b, &tb, &mut scratch);
                let dq = (sim.tree().difference(&end.q, &a.q) - sim.tree().difference(&end.q, &b.q)) / (2.0 * eps);
                let dv = (a.v - b.v) / (2.0 * eps);
                for r in 0..19 {
                    for (row, value) in [(r, dq[r]), (19 + r, dv[r])] {
                        diff = diff.max((out.entry(row, c) - value).abs());
                        scale = scale.max(value.abs());
                    }
                }
            }
            *worst = worst.max(diff / scale);
        }
    }
    eprintln!(
        "every kind: the RK4 step's Jacobian {:.1e}, the Euler step's {:.1e} off differences",
        worst[0], worst[1]
    );
    assert!(worst[0] < 1e-7 && worst[1] < 1e-7, "{worst:?}");
}

/// Springs or loads are not the tree's own dynamics: refused, state kept.
#[test]
fn a_loaded_tree_has_no_exact_step_jacobian() {
    use joint_runtime::dynamics::{AppliedLoads, Loads};
    struct Push;
    impl AppliedLoads<9> for Push {
        fn apply(&mut self, _: &joint_runtime::SystemState<9>, loads: &mut Loads<9>) {
            loads.torque[0].x += 1.0;
        }
    }
    let sim = TreeSimulation::new(&Menagerie).unwrap().with_loads(Push);
    let mut state = random_state(&TreeSimulation::new(&Menagerie).unwrap(), &mut Draw(7));
    let before = state;
    let (mut work, mut out) = (StepWork::new(), StepJacobian::zeros());
    let err = sim.rk4_step_jacobian(&mut state, 1e-3, &SVector::zeros(), &mut work, &mut out).unwrap_err();
    assert_eq!(err, TreeError::Loaded);
    assert_eq!(state, before);
}

/// `linearise` on the exact derivatives: `A`'s lower blocks and `B` are
/// Pinocchio's `∂q̈/∂q`, `∂q̈/∂v`, `M⁻¹` (the UR5's first sample).
#[test]
fn linearise_is_exact_on_both_paths() {
    linearise_against_pinocchio(&Ur5);
    linearise_against_pinocchio(&Ur5ByRecursion);
}

/// `linearise`'s `A` and `B` on the UR5 against Pinocchio's `∂q̈/∂q`,
/// `∂q̈/∂v` and `M⁻¹`.
fn linearise_against_pinocchio<S: TreeScene<NB, 6, 6>, const NB: usize>(scene: &S) {
    use super::urdf::{joint_map, numbers, our_q, our_v, reference};
    let data = reference("ur5_derivatives");
    let mut sim = TreeSimulation::new(scene).unwrap();
    let map = joint_map(&sim, &data);
    let s = &data["samples"][0];
    let v = |key: &str| our_v::<6>(&map, &numbers(&s[key]));
    let state = TreeState::<6, 6> { q: our_q(&map, &numbers(&s["q"])), v: v("v"), t: 0.0 };
    let lin = sim.linearise(&state, &v("tau")).unwrap();
    let rows = |key: &str| -> Vec<Vec<f64>> { s[key].as_array().unwrap().iter().map(numbers).collect() };
    let (dq, dv, minv) = (rows("daba_dq"), rows("daba_dv"), rows("minv"));
    for r in 0..6 {
        for c in 0..6 {
            assert!((lin.a[(6 + r, c)] - dq[r][c]).abs() < 1e-12 * (1.0 + dq[r][c].abs()));
            assert!((lin.a[(6 + r, 6 + c)] - dv[r][c]).abs() < 1e-12 * (1.0 + dv[r][c].abs()));
            assert!((lin.b[(6 + r, c)] - minv[r][c]).abs() < 1e-12 * (1.0 + minv[r][c].abs()));
        }
    }
}

/// The contracted second derivatives against central differences of the
/// exact first ones (`λᵀ ∂τ/∂q`, `λᵀ ∂τ/∂v` moved along each direction);
/// returns the worst of `d_qq`, `d_qv`, `d_vv` over their largest entries.
fn second_against_differences<S, const NB: usize, const NQ: usize, const NV: usize>(
    scene: &S,
    samples: usize,
) -> [f64; 3]
where
    S: TreeScene<NB, NQ, NV>,
{
    let sim = TreeSimulation::new(scene).unwrap();
    let mut draw = Draw(0x2545_f491_4f6c_dd1d);
    let (mut second, mut first) = (SecondDerivatives::<NV>::zeros(), InverseDerivatives::<NV>::zeros());
    let mut worst = [0.0_f64; 3];
    for _ in 0..samples {
        let state = random_state(&sim, &mut draw);
        let a = SVector::<f64, NV>::from_fn(|_, _| draw.next());
        let lambda = SVector::<f64, NV>::from_fn(|_, _| draw.next());
        sim.inverse_dynamics_second_derivatives(&state, &a, &lambda, &mut second).unwrap();
        let mut contracted = |s: &TreeState<NQ, NV>| {
            sim.inverse_dynamics_derivatives(s, &a, &mut first).unwrap();
            (first.d_q.transpose() * lambda, first.d_v.transpose() * lambda)
        };
        let h = 1e-6;
        let (mut qq, mut qv, mut vv) =
            (SMatrix::<f64, NV, NV>::zeros(), SMatrix::<f64, NV, NV>::zeros(), SMatrix::<f64, NV, NV>::zeros());
        for j in 0..NV {
            let e = SVector::<f64, NV>::from_fn(|r, _| if r == j { h } else { 0.0 });
            let (plus, minus) = (
                contracted(&TreeState { q: sim.tree().displaced(&state.q, &e), ..state }),
                contracted(&TreeState { q: sim.tree().displaced(&state.q, &-e), ..state }),
            );
            qq.set_column(j, &((plus.0 - minus.0) / (2.0 * h)));
            let (plus, minus) = (
                contracted(&TreeState { v: state.v + e, ..state }),
                contracted(&TreeState { v: state.v - e, ..state }),
            );
            qv.set_column(j, &((plus.0 - minus.0) / (2.0 * h)));
            vv.set_column(j, &((plus.1 - minus.1) / (2.0 * h)));
        }
        for (w, (ours, theirs)) in worst.iter_mut().zip([(second.d_qq, qq), (second.d_qv, qv), (second.d_vv, vv)]) {
            *w = w.max(relative(&ours, &theirs));
        }
    }
    worst
}

/// A floating drone with a gripper on a ball joint and a finger on a hinge:
/// both quaternion kinds, small enough for the second derivatives' straight
/// line (the whole `Menagerie`'s is 40 705 operations, past the limit).
#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], coordinates = relative, second_order)]
#[body(drone, mass = 2.0, inertia = [0.05, 0.06, 0.09, 0.004, -0.002, 0.001])]
#[body(gripper, mass = 0.5, inertia = [0.004, 0.004, 0.001])]
#[body(finger, mass = 0.1, inertia = [0.0005, 0.0005, 0.0001])]
#[joint(claw = spherical(drone, gripper), rho1 = [0.1, 0, -0.1], rho2 = [0, 0, 0.15], damping = 0.05)]
#[joint(knuckle = revolute(gripper, finger), axis1 = [1, 0, 0], axis2 = [1, 0, 0], rho1 = [0, 0, -0.15], rho2 = [0, 0, 0.05], armature = 0.01, damping = 0.1, stiffness = 2.0, spring_rest = 0.3)]
struct Drone;

/// The other kinds: a cylindrical shaft, a universal arm, a slider, a
/// welded plate and a planar puck.
#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], coordinates = relative, second_order)]
#[body(shaft, mass = 1.0, inertia = [0.1, 0.1, 0.02])]
#[body(arm, mass = 0.7, inertia = [0.03, 0.02, 0.012])]
#[body(block, mass = 0.3, inertia = [0.002, 0.003, 0.004])]
#[body(plate, mass = 0.2, inertia = [0.001, 0.002, 0.0025])]
#[body(puck, mass = 1.0, inertia = [0.02, 0.02, 0.04])]
#[joint(bush = cylindrical(ground, shaft), axis1 = [0.3, 0, 1], axis2 = [0, 0, 1], rho1 = [0, 0, 1], rho2 = [0, 0, 0])]
#[joint(gimbal = universal(shaft, arm), s = [1, 0, 0], h = [0.2, 1, 0], rho1 = [0, 0, 0.4], rho2 = [0, 0, 0.5])]
#[joint(rail = translational(arm, block), axis1 = [1, 0, 0.5], axis2 = [0, 1, 0], rho1 = [0, 0, -0.5], rho2 = [0.1, 0, 0], stiffness = 40.0, spring_rest = -0.1)]
#[joint(weld = fixed(block, plate), axis1 = [0, 0, 1], axis2 = [1, 0, 0], rho1 = [0.2, 0, 0], rho2 = [0, 0, 0])]
#[joint(table = planar(ground, puck), axis1 = [0, -0.4, 1], axis2 = [0, 0, 1], rho1 = [0, 0, 0.5], rho2 = [0, 0, 0])]
struct Linkage;

#[test]
fn second_derivatives_against_differences_of_the_first() {
    let runs = [
        ("quaternions", second_against_differences(&Drone, 5)),
        ("slides and turns", second_against_differences(&Linkage, 5)),
        ("UR5", second_against_differences(&Ur5, 10)),
    ];
    for (name, worst) in runs {
        eprintln!(
            "{name}: λᵀ∂²τ/∂q² {:.1e}, λᵀ∂²τ/∂q∂v {:.1e}, λᵀ∂²τ/∂v² {:.1e} of the largest entry off differences",
            worst[0], worst[1], worst[2]
        );
        assert!(worst.iter().all(|&w| w < 1e-7), "{name}: {worst:?}");
    }
}

/// The Panda's file as it says: the second finger follows the first (a
/// coupling row `q_f − q_l = 0`).
#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], urdf = "data/robots/panda.urdf")]
struct PandaCoupled;

/// On a coupled tree the derivatives are the constrained accelerations':
/// against central differences of `forward_dynamics` (the coupling's
/// Baumgarte terms included), and `M⁻¹`'s place taken by the projected
/// `P̃` (`J P̃ = 0`: no force moves the coupled fingers apart).
#[test]
fn a_coupled_tree_against_differences() {
    let mut sim = TreeSimulation::new(&PandaCoupled).unwrap();
    let mut draw = Draw(11);
    let (mut work, mut d) = (InverseDerivatives::zeros(), ForwardDerivatives::zeros());
    let mut worst = [0.0_f64; 3];
    for _ in 0..10 {
        let mut state = random_state(&sim, &mut draw);
        state.q[8] = state.q[7] + 0.01 * draw.next(); // near the coupling, not on it
        let tau = SVector::<f64, 9>::from_fn(|_, _| draw.next());
        sim.forward_dynamics_derivatives(&state, &tau, &mut work, &mut d).unwrap();
        let qdd = sim.forward_dynamics(&state, &tau).unwrap();
        worst[2] = worst[2].max((d.qdd - qdd).amax() / qdd.amax());
        let h = 1e-6;
        let (mut d_q, mut d_v, mut d_tau) =
            (SMatrix::<f64, 9, 9>::zeros(), SMatrix::<f64, 9, 9>::zeros(), SMatrix::<f64, 9, 9>::zeros());
        for i in 0..9 {
            let e = SVector::<f64, 9>::from_fn(|r, _| if r == i { h } else { 0.0 });
            let mut f = |s: TreeState<9, 9>, t: SVector<f64, 9>| sim.forward_dynamics(&s, &t).unwrap();
            d_q.set_column(
                i,
                &((f(TreeState { q: state.q + e, ..state }, tau) - f(TreeState { q: state.q - e, ..state }, tau))
                    / (2.0 * h)),
            );
            d_v.set_column(
                i,
                &((f(TreeState { v: state.v + e, ..state }, tau) - f(TreeState { v: state.v - e, ..state }, tau))
                    / (2.0 * h)),
            );
            d_tau.set_column(i, &((f(state, tau + e) - f(state, tau - e)) / (2.0 * h)));
        }
        worst[0] = worst[0].max(relative(&d.d_q, &d_q).max(relative(&d.d_v, &d_v)));
        worst[1] = worst[1].max(relative(&d.d_tau, &d_tau));
        // The fingers' coupled row: J P̃ = 0.
        let j = sim.closure_rows(&state).jacobian;
        assert!((j * d.d_tau).amax() < 1e-9 * d.d_tau.amax());
    }
    eprintln!("coupled Panda: ∂q̈/∂(q, v) {:.1e}, ∂q̈/∂τ {:.1e} off differences; q̈ {:.1e}", worst[0], worst[1], worst[2]);
    assert!(worst[0] < 1e-6 && worst[1] < 1e-7 && worst[2] < 1e-12, "{worst:?}");
}
