//! The linearisation of trees (`TreeSimulation::linearise`) against the
//! absolute path's exact one (`Simulation::linearise`, `second_order`) on
//! the same declaration: at an equilibrium the poles are the same whatever
//! the coordinates. And its input matrix against the mass matrix.

use joint_runtime::dynamics::{AbsoluteSimulation, Loads, NoLoads, SimulationOptions};
use joint_runtime::nalgebra::{Complex, DMatrix, SVector, Vector3};
use joint_runtime::relative::{TreeScene, TreeSimulation};
use joint_runtime::{Scene, SparseJacobian, SystemState};

/// A double pendulum hanging at rest: a ball-joint shoulder, a hinged elbow.
#[derive(Scene, Clone, Copy, Debug, Default)]
#[scene(gravity = [0, 0, -9.81], coordinates = both, second_order)]
#[body(upper, mass = 1.0, inertia = [0.08, 0.079, 0.002])]
#[body(lower, mass = 0.7, inertia = [0.05, 0.05, 0.001])]
#[joint(shoulder = spherical(ground, upper), rho1 = [0, 0, 0], rho2 = [0, 0, 0.5])]
#[joint(elbow = revolute(upper, lower), axis1 = [1, 0, 0], axis2 = [1, 0, 0], rho1 = [0, 0, -0.5], rho2 = [0, 0, 0.4])]
struct Hanging;

/// A drone hovering (thrust equal to the weight) with a gripper on a ball
/// joint and a finger hinged to it, at rest.
#[derive(Scene, Clone, Copy, Debug, Default)]
#[scene(gravity = [0, 0, -9.81], coordinates = both, second_order)]
#[body(drone, mass = 2.0, inertia = [0.05, 0.06, 0.09])]
#[body(gripper, mass = 0.5, inertia = [0.004, 0.004, 0.001])]
#[body(finger, mass = 0.1, inertia = [0.0005, 0.0005, 0.0001])]
#[joint(claw = spherical(drone, gripper), rho1 = [0, 0, -0.1], rho2 = [0, 0, 0.15])]
#[joint(knuckle = revolute(gripper, finger), axis1 = [1, 0, 0], axis2 = [1, 0, 0], rho1 = [0, 0, -0.15], rho2 = [0, 0, 0.05])]
struct Hover;

/// The eigenvalues sorted by imaginary part, then real part.
fn sorted(mut e: Vec<Complex<f64>>) -> Vec<Complex<f64>> {
    e.sort_by(|a, b| a.im.total_cmp(&b.im).then(a.re.total_cmp(&b.re)));
    e
}

/// The poles of both coordinate choices at the tree's zero state (an
/// equilibrium), with `loads`; returns the largest.
fn same_poles<
    S,
    L,
    const NB: usize,
    const NV6: usize,
    const M: usize,
    const NNZ: usize,
    const NQ: usize,
    const NV: usize,
    const NC: usize,
>(
    scene: &S,
    loads: L,
) -> f64
where
    S: Scene<NB, NV6, M> + SparseJacobian<NB, NNZ> + TreeScene<NB, NQ, NV, NC>,
    L: joint_runtime::dynamics::AppliedLoads<NB> + Copy,
{
    let mut tree = TreeSimulation::new(scene).unwrap().with_loads(loads);
    let state = tree.tree().zero_state();
    let lin = tree.linearise(&state, &SVector::zeros()).unwrap();
    let system: SystemState<NB> = tree.tree().system_state(&state);
    let mut absolute = AbsoluteSimulation::new(scene, loads, &[], SimulationOptions::default()).unwrap();
    let exact = absolute.linearise(&system, &DMatrix::zeros(NV6, 0)).unwrap();
    // Without loops every freedom is one; with them, the mobility.
    assert_eq!(lin.freedoms, exact.freedoms);
    assert!(NC > 0 || lin.freedoms == NV);
    let (mine, theirs) = (lin.eigenvalues().unwrap(), exact.eigenvalues().unwrap());
    let largest = theirs.iter().map(|e| e.norm()).fold(0.0, f64::max);
    // A floating body's rigid motions are a defective zero pole (a Jordan
    // block), which round-off spreads by its root (3e-4 here, against
    // poles of 7–10 rad/s): counted, not compared.
    let moving = |e: &Vec<Complex<f64>>| sorted(e.iter().copied().filter(|x| x.norm() > 1e-2 * largest).collect());
    let (mine, theirs) = (moving(&mine), moving(&theirs));
    assert_eq!(mine.len(), theirs.len(), "{mine:?} against {theirs:?}");
    for (a, b) in mine.iter().zip(&theirs) {
        assert!((a - b).norm() < 1e-8 * largest, "{mine:?} against {theirs:?}");
    }
    largest
}

#[test]
fn tree_poles_are_the_absolute_scenes() {
    // Pendulum modes of several rad/s: something was compared.
    assert!(same_poles(&Hanging, NoLoads) > 3.0);
    let hover = |s: &SystemState<3>, l: &mut Loads<3>| {
        l.force[0] += s.bodies[0].rotation() * Vector3::new(0.0, 0.0, 2.6 * 9.81);
    };
    assert!(same_poles(&Hover, hover) > 3.0);
    // A loop: the tree's minimal coordinates on it (exact, from the closures' second-order terms) against
    // the absolute path's (exact second derivatives).
    assert!(same_poles(&HangingFourBar, NoLoads) > 1.0);
}

/// A parallelogram four-bar hanging from pivots 1 m apart (cranks down),
/// its loop closed by `d`: one freedom, a pendulum mode.
#[derive(Scene, Clone, Copy, Debug, Default)]
#[scene(gravity = [0, -9.81, 0], coordinates = both, second_order)]
#[body(crank, mass = 1.0, inertia = [0.1, 0.1, 0.1])]
#[body(coupler, mass = 1.5, inertia = [0.1, 0.15, 0.2])]
#[body(rocker, mass = 2.0, inertia = [0.2, 0.1, 0.2])]
#[joint(a = revolute(ground, crank), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0, 0, 0], rho2 = [0, 0.5, 0])]
#[joint(b = revolute(crank, coupler), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0, -0.5, 0], rho2 = [-0.5, 0, 0])]
#[joint(c = revolute(coupler, rocker), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0.5, 0, 0], rho2 = [0, -0.5, 0])]
#[joint(d = revolute(rocker, ground), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0, 0.5, 0], rho2 = [1, 0, 0])]
struct HangingFourBar;

/// `B = [0; M⁻¹]`: a joint force's acceleration.
#[test]
fn tree_inputs_act_through_the_inverse_mass_matrix() {
    let mut sim = TreeSimulation::new(&Hanging).unwrap();
    let state = sim.tree().zero_state();
    let lin = sim.linearise(&state, &SVector::zeros()).unwrap();
    let mut m = joint_runtime::nalgebra::SMatrix::<f64, 4, 4>::zeros();
    sim.mass_matrix_into(&state.q, &mut m);
    let b = lin.b.view((4, 0), (4, 4)).into_owned();
    assert!((b * m - DMatrix::<f64>::identity(4, 4)).amax() < 1e-12);
    assert!(lin.b.view((0, 0), (4, 4)).amax() == 0.0);
}

/// `q_b ⊖ q_a` for the drone's tree (free, spherical, revolute): the
/// increment `δq` with `q_b = q_a ⊕ δq`, to second order.
fn drone_difference(a: &SVector<f64, 12>, b: &SVector<f64, 12>) -> SVector<f64, 10> {
    use joint_runtime::nalgebra::{Quaternion, UnitQuaternion};
    let unit = |q: &SVector<f64, 12>, at: usize| {
        UnitQuaternion::from_quaternion(Quaternion::new(q[at], q[at + 1], q[at + 2], q[at + 3]))
    };
    let turn = |at: usize| (unit(a, at).inverse() * unit(b, at)).scaled_axis();
    let offset = unit(a, 3).inverse() * Vector3::new(b[0] - a[0], b[1] - a[1], b[2] - a[2]);
    let (t1, t2) = (turn(3), turn(7));
    SVector::from_column_slice(&[offset.x, offset.y, offset.z, t1.x, t1.y, t1.z, t2.x, t2.y, t2.z, b[11] - a[11]])
}

/// Off any equilibrium, the linearisation is the rate of the flow's own
/// increments: `(Φ_τ − I) / τ → A` for the drone tumbling and falling, `Φ_τ`
/// by central differences of one short RK4 step from `x ⊕ ±ε eᵢ`, its
/// increments measured on the group (`drone_difference`). This checks the
/// exact `Λ(v)` (a spinning quaternion's and the free joint's offset's own
/// rate) as well as the differenced accelerations.
#[test]
fn tree_linearisation_is_the_flows_rate() {
    use crate::floating::{Drone, drone_state};
    let mut sim = TreeSimulation::new(&Drone).unwrap();
    let state = drone_state();
    let lin = sim.linearise(&state, &SVector::zeros()).unwrap();
    let (tau, eps) = (1e-5, 1e-6);
    let mut base = state;
    sim.step(&mut base, tau).unwrap();
    let scale = lin.a.amax();
    for i in 0..20 {
        let run = |sign: f64, sim: &mut TreeSimulation<'_, Drone, 3, 12, 10>| {
            let mut start = state;
            let mut e = SVector::<f64, 10>::zeros();
            if i < 10 {
                e[i] = sign * eps;
                start.q = sim.tree().displaced(&state.q, &e);
            } else {
                start.v[i - 10] += sign * eps;
            }
            sim.step(&mut start, tau).unwrap();
            let (dq, dv) = (drone_difference(&base.q, &start.q), start.v - base.v);
            SVector::<f64, 20>::from_fn(|r, _| if r < 10 { dq[r] } else { dv[r - 10] })
        };
        let column = (run(1.0, &mut sim) - run(-1.0, &mut sim)) / (2.0 * eps);
        let mut rate = column / tau;
        rate[i] -= 1.0 / tau;
        let expected = lin.a.column(i);
        let apart = (rate - expected).amax();
        assert!(apart < 1e-3 * scale, "column {i}: {rate} against {expected}");
    }
}

/// `Tree::difference` undoes `Tree::displace` and is the test's own
/// increment on the drone's tree.
#[test]
fn tree_differences_undo_displacements() {
    use crate::floating::{Drone, drone_state};
    let sim = TreeSimulation::new(&Drone).unwrap();
    let q = drone_state().q;
    let delta = SVector::<f64, 10>::from_fn(|i, _| 0.05 * (i as f64 - 4.5));
    let moved = sim.tree().displaced(&q, &delta);
    assert!((sim.tree().difference(&q, &moved) - delta).amax() < 1e-15, "{}", sim.tree().difference(&q, &moved));
    assert!((sim.tree().difference(&q, &moved) - drone_difference(&q, &moved)).amax() < 1e-15);
}

/// A bar of 1 m pinned at its end about y, hanging at θ = π/2.
#[derive(Scene, Clone, Copy, Debug, Default)]
#[scene(gravity = [0, 0, -9.81], coordinates = relative)]
#[body(bar, mass = 1.0, inertia = [0.001, 0.08, 0.08])]
#[joint(pin = revolute(ground, bar), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0, 0, 0], rho2 = [-0.5, 0, 0])]
struct Pendulum;

/// The hanging bar's step: `Φ = [[cos ωh, sin ωh / ω], [−ω sin ωh, cos ωh]]`
/// about the bottom at rest, `ω² = m g (l/2) / (I + m (l/2)²)`; and the
/// drone's short step against `exp(A h)` of its linearisation.
#[test]
fn tree_transitions_are_the_linear_flow() {
    let mut sim = TreeSimulation::new(&Pendulum).unwrap();
    let mut state = joint_runtime::relative::TreeState {
        q: SVector::from([std::f64::consts::FRAC_PI_2]),
        v: SVector::zeros(),
        t: 0.0,
    };
    // (RK4's own error in Φ is (ωh)⁵/120 ≈ 7e-15 at this step.)
    let h = 1e-3;
    let phi = sim.transition(&mut state, h, &SVector::zeros()).unwrap();
    let w = (9.81 * 0.5 / (0.08 + 0.25f64)).sqrt();
    let (c, s) = ((w * h).cos(), (w * h).sin());
    let expected = DMatrix::from_row_slice(2, 2, &[c, s / w, -w * s, c]);
    assert!((&phi - &expected).amax() < 1e-9, "{phi} against {expected}");
    assert!((state.t - h).abs() < 1e-15 && state.q[0] == std::f64::consts::FRAC_PI_2);

    use crate::floating::{Drone, drone_state};
    let mut sim = TreeSimulation::new(&Drone).unwrap();
    let start = drone_state();
    let a = sim.linearise(&start, &SVector::zeros()).unwrap().a;
    // exp(A h) to third order; A itself moves along the step by O(h²).
    let h = 2e-5;
    let mut state = start;
    let phi = sim.transition(&mut state, h, &SVector::zeros()).unwrap();
    let ah = &a * h;
    let taylor = DMatrix::<f64>::identity(20, 20) + &ah + &ah * &ah * 0.5 + &ah * &ah * &ah * (1.0 / 6.0);
    let apart = (&phi - &taylor).amax();
    assert!(apart < 1e-7, "{apart:e}");
    // And the step moved the state as `step` does.
    let mut stepped = start;
    sim.step(&mut stepped, h).unwrap();
    assert_eq!(stepped, state);
}
