//! Relative coordinates (`joint_runtime::relative`) on `#[scene(coordinates =
//! relative)]` scenes: the recursions against closed forms, against the
//! kinetic energy computed from the bodies, against each other, and the motion
//! against the same declaration in absolute coordinates (`coordinates = both`).

use joint_runtime::dynamics::{AbsoluteSimulation, NoLoads, SimulationOptions};
use joint_runtime::nalgebra::{SMatrix, SVector, UnitQuaternion, Vector3};
use joint_runtime::relative::{Tree, TreeError, TreeScene, TreeSimulation, TreeState};
use joint_runtime::{Scene, SparseJacobian, SystemState};

/// One bar of 1 m, pinned at its end about y.
#[derive(Scene, Clone, Copy, Debug, Default)]
#[scene(gravity = [0, 0, -9.81], coordinates = relative)]
#[body(bar, mass = 1.0, inertia = [0.001, 0.08, 0.08])]
#[joint(pin = revolute(ground, bar), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0, 0, 0], rho2 = [-0.5, 0, 0])]
struct Bar;

/// A branching tree of four bodies: spherical and revolute joints, a joint
/// declared child first (`knee`), axes that differ between the two bodies
/// (`elbow`: `R₀` not the identity), an inertia with products.
#[derive(Scene, Clone, Copy, Debug, Default)]
#[scene(gravity = [0, 0, -9.81], coordinates = both)]
#[body(torso, mass = 2.0, inertia = [0.2, 0.3, 0.25, 0.01, -0.02, 0.015])]
#[body(shin, mass = 0.7, inertia = [0.02, 0.021, 0.004])]
#[body(upper, mass = 1.1, inertia = [0.03, 0.035, 0.006])]
#[body(hand, mass = 0.4, inertia = [0.002, 0.003, 0.0035])]
#[joint(hip = spherical(ground, torso), rho1 = [0, 0, 1], rho2 = [0, 0, 0.3])]
#[joint(knee = revolute(shin, torso), axis1 = [1, 0, 0], axis2 = [0, 1, 0], rho1 = [0, 0, 0.4], rho2 = [0.2, 0, -0.3])]
#[joint(elbow = revolute(torso, upper), axis1 = [1, 1, 0], axis2 = [0, 0, 1], rho1 = [0.3, 0, 0], rho2 = [0, 0, -0.25])]
#[joint(wrist = spherical(upper, hand), rho1 = [0, 0, 0.25], rho2 = [0.1, 0, 0])]
pub(crate) struct Walker;

/// The arm of `peer_bench`, three bars: revolute about z, y, z.
#[derive(Scene, Clone, Copy, Debug, Default)]
#[scene(gravity = [0, 0, -9.81], coordinates = both)]
#[body(bar[3], mass = 1.0, inertia = [0.00125, 0.08395833333333333, 0.08395833333333333])]
#[joint(base = revolute(ground, bar[0]), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0, 0, 0], rho2 = [-0.5, 0, 0])]
#[joint(j2 = revolute(bar[0], bar[1]), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0.5, 0, 0], rho2 = [-0.5, 0, 0])]
#[joint(j3 = revolute(bar[1], bar[2]), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0.5, 0, 0], rho2 = [-0.5, 0, 0])]
struct Arm3;

/// The pinned bar with its mass and its joint point as fields: the joint
/// point read at run time leaves the articulated-body algorithm to the
/// runtime's recursion.
#[derive(Scene, Clone, Copy, Debug)]
#[scene(gravity = [0, 0, -9.81], coordinates = relative)]
#[body(bar, mass = mass, inertia = [0.001, 0.08, 0.08])]
#[joint(pin = revolute(ground, bar), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0, 0, 0], rho2 = end)]
struct FieldBar {
    mass: f64,
    end: Vector3<f64>,
}

/// The pinned bar with only its mass a field: still written out.
#[derive(Scene, Clone, Copy, Debug)]
#[scene(gravity = [0, 0, -9.81], coordinates = relative)]
#[body(bar, mass = mass, inertia = [0.001, 0.08, 0.08])]
#[joint(pin = revolute(ground, bar), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0, 0, 0], rho2 = [-0.5, 0, 0])]
struct HeavyBar {
    mass: f64,
}

/// Past the derive's limit for one straight line (10 000 operations): a
/// chain of 24 bars on spherical joints with a leg on a tilted revolute
/// joint declared child first, written as one kernel per distinct joint and
/// pass.
#[derive(Scene, Clone, Copy, Debug, Default)]
#[scene(gravity = [0, 0, -9.81], coordinates = relative)]
#[body(bar[24], mass = 1.0, inertia = [0.00125, 0.08395833333333333, 0.08395833333333333])]
#[body(leg, mass = 0.5, inertia = [0.01, 0.012, 0.006, 0.001, 0.0, -0.001])]
#[joint(pivot = spherical(ground, bar[0]), rho1 = [0, 0, 0], rho2 = [-0.5, 0, 0])]
#[joint(ball[i in 1..24] = spherical(bar[i - 1], bar[i]), rho1 = [0.5, 0, 0], rho2 = [-0.5, 0, 0])]
#[joint(knee = revolute(leg, bar[10]), axis1 = [1, 0, 0], axis2 = [0, 1, 1], rho1 = [0, 0, 0.3], rho2 = [0.2, 0, 0])]
struct LongChain;

/// A body whose principal moments are given at run time (numbers that
/// break the triangle inequality are a compile error).
#[derive(Scene, Clone, Copy, Debug, Default)]
#[scene(coordinates = relative)]
#[body(rod, mass = 1.0, inertia = moments)]
#[joint(ball = spherical(ground, rod), rho1 = [0, 0, 0], rho2 = [0, 0, 1])]
struct Impossible {
    moments: Vector3<f64>,
}

/// A block on a rail tilted in the x–z plane (`translational`: a prismatic
/// tree joint), its frame turned on the rail (its y axis along it).
#[derive(Scene, Clone, Copy, Debug, Default)]
#[scene(gravity = [0, 0, -9.81], coordinates = both)]
#[body(block, mass = 2.0, inertia = [0.1, 0.2, 0.25])]
#[joint(rail = translational(ground, block), axis1 = [1, 0, 0.5], axis2 = [0, 1, 0], rho1 = [0, 0, 1], rho2 = [0.1, 0, 0])]
struct Slider;

/// A cart on that rail and a pole pinned to it: prismatic, then revolute.
#[derive(Scene, Clone, Copy, Debug, Default)]
#[scene(gravity = [0, 0, -9.81], coordinates = both)]
#[body(cart, mass = 2.0, inertia = [0.1, 0.2, 0.25])]
#[body(pole, mass = 0.5, inertia = [0.04, 0.04, 0.001])]
#[joint(rail = translational(ground, cart), axis1 = [1, 0, 0.5], axis2 = [0, 1, 0], rho1 = [0, 0, 1], rho2 = [0.1, 0, 0])]
#[joint(pin = revolute(cart, pole), axis1 = [1, 0, 0], axis2 = [1, 0, 0], rho1 = [0, 0, 0.2], rho2 = [0, 0, 0.5])]
struct CartPole;

/// A bar hung from the ground by a universal joint (its axes not
/// perpendicular as declared: `R₀` turns the bar), and a second bar pinned
/// to it: the runtime's recursion with a subspace that turns with θ₂.
#[derive(Scene, Clone, Copy, Debug, Default)]
#[scene(gravity = [0, 0, -9.81], coordinates = both)]
#[body(upper, mass = 1.0, inertia = [0.08, 0.08, 0.002])]
#[body(lower, mass = 0.6, inertia = [0.05, 0.05, 0.004, 0.002, 0.0, 0.0])]
#[joint(gimbal = universal(ground, upper), s = [1, 0, 0], h = [0.2, 1, 0], rho1 = [0, 0, 2], rho2 = [0, 0, 0.5])]
#[joint(knee = revolute(upper, lower), axis1 = [1, 0, 0], axis2 = [1, 0, 0], rho1 = [0, 0, -0.5], rho2 = [0, 0, 0.4])]
struct Gimbal;

fn gimbal_state() -> GimbalTreeState {
    TreeState { q: SVector::from([0.4, -0.7, 0.3]), v: SVector::from([1.2, -0.8, 2.0]), t: 0.0 }
}

/// A bar pinned at one end with a block welded at the other (`fixed`: no
/// freedom; the block's frame turned, its x along the bar's z).
#[derive(Scene, Clone, Copy, Debug, Default)]
#[scene(gravity = [0, 0, -9.81], coordinates = both)]
#[body(bar, mass = 1.0, inertia = [0.001, 0.08, 0.08])]
#[body(block, mass = 0.5, inertia = [0.002, 0.002, 0.002])]
#[joint(pin = revolute(ground, bar), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0, 0, 0], rho2 = [-0.5, 0, 0])]
#[joint(weld = fixed(bar, block), axis1 = [0, 0, 1], axis2 = [1, 0, 0], rho1 = [0.5, 0, 0], rho2 = [0, 0, 0])]
struct Welded;

fn cart_pole_state() -> CartPoleTreeState {
    TreeState { q: SVector::from([0.2, 0.5]), v: SVector::from([1.0, -0.7]), t: 0.0 }
}

/// Unit Euler parameters from four numbers.
pub(crate) fn quaternion(w: f64, x: f64, y: f64, z: f64) -> [f64; 4] {
    let n = (w * w + x * x + y * y + z * z).sqrt();
    [w / n, x / n, y / n, z / n]
}

/// The walker turned and moving: every joint away from zero.
pub(crate) fn walker_state() -> WalkerTreeState {
    let [a, b, c, d] = quaternion(0.9, 0.1, -0.2, 0.3);
    let [e, f, g, h] = quaternion(0.8, -0.3, 0.2, 0.1);
    TreeState {
        q: SVector::from_column_slice(&[a, b, c, d, 0.4, -0.7, e, f, g, h]),
        v: SVector::from_column_slice(&[0.3, -0.5, 0.8, 1.2, -0.9, 0.6, 0.2, -1.1]),
        t: 0.0,
    }
}

fn arm_state() -> Arm3TreeState {
    TreeState { q: SVector::from([0.3, -0.4, 1.1]), v: SVector::from([0.5, -1.0, 2.0]), t: 0.0 }
}

/// `½ Σ (m |ṙ|² + ω'ᵀ J' ω')` from the bodies' absolute velocities: an
/// independent path to the kinetic energy.
fn kinetic<S: Scene<NB, NV, M>, const NB: usize, const NV: usize, const M: usize>(
    scene: &S,
    system: &SystemState<NB>,
) -> f64 {
    let inertias = scene.inertias();
    system
        .bodies
        .iter()
        .zip(&inertias)
        .map(|(b, i)| 0.5 * (i.mass * b.rdot.norm_squared() + b.omega.dot(&(i.inertia * b.omega))))
        .sum()
}

#[test]
fn pinned_bar_against_its_closed_form() {
    let tree = Tree::of(&Bar).unwrap();
    // Horizontal, at rest: gravity's moment about the pin is m g l/2 about +y
    // (r × F = (0.5, 0, 0) × (0, 0, −9.81)), the pin's inertia I_yy + m (l/2)².
    let state = TreeState { q: SVector::from([0.0]), v: SVector::from([0.0]), t: 0.0 };
    let accel = tree.forward_dynamics(&state, &SVector::zeros()).unwrap();
    let expected = 0.5 * 9.81 / (0.08 + 0.25);
    assert!((accel[0] - expected).abs() < 1e-14 * expected, "{} against {expected}", accel[0]);
    let bias = tree.bias_forces(&state);
    assert!((bias[0] + 0.5 * 9.81).abs() < 1e-14, "holding torque {}", bias[0]);
    // Turned by θ about y and spinning at ω: the moment is m g l/2 cos θ; the
    // pin's reaction does no work, so the bias is gravity's alone.
    let (theta, omega) = (0.7_f64, 3.0);
    let state = TreeState { q: SVector::from([theta]), v: SVector::from([omega]), t: 0.0 };
    let tau = tree.inverse_dynamics(&state, &SVector::from([2.0]));
    let expected = (0.08 + 0.25) * 2.0 - 0.5 * 9.81 * theta.cos();
    assert!((tau[0] - expected).abs() < 1e-14, "{} against {expected}", tau[0]);
    let mut m = SMatrix::<f64, 1, 1>::zeros();
    tree.mass_matrix_into(&state.q, &mut m);
    assert!((m[(0, 0)] - 0.33).abs() < 1e-15);
    // The bar's centre: turned about +y by θ, (0.5, 0, 0) goes to (0.5 cos θ, 0, −0.5 sin θ).
    let system = tree.system_state(&state);
    let centre = system.bodies[0].r;
    assert!((centre - Vector3::new(0.5 * theta.cos(), 0.0, -0.5 * theta.sin())).norm() < 1e-15);
    assert!((system.bodies[0].omega - Vector3::new(0.0, omega, 0.0)).norm() < 1e-15);
}

/// `M(q)` from the composite-rigid-body algorithm against second differences
/// of the kinetic energy of the bodies (exact: it is quadratic in `v`).
pub(crate) fn mass_matrix_against_energy<
    S,
    const NB: usize,
    const NV6: usize,
    const M: usize,
    const NQ: usize,
    const NV: usize,
>(
    scene: &S,
    state: &TreeState<NQ, NV>,
) where
    S: Scene<NB, NV6, M> + TreeScene<NB, NQ, NV>,
{
    let tree = Tree::of(scene).unwrap();
    let mut mass = SMatrix::<f64, NV, NV>::zeros();
    tree.mass_matrix_into(&state.q, &mut mass);
    let energy = |v: SVector<f64, NV>| kinetic(scene, &tree.system_state(&TreeState { q: state.q, v, t: 0.0 }));
    let unit = |i: usize| SVector::<f64, NV>::from_fn(|r, _| if r == i { 1.0 } else { 0.0 });
    let scale = mass.abs().max();
    for i in 0..NV {
        for j in 0..NV {
            let expected = if i == j {
                2.0 * energy(unit(i))
            } else {
                energy(unit(i) + unit(j)) - energy(unit(i)) - energy(unit(j))
            };
            assert!(
                (mass[(i, j)] - expected).abs() < 1e-13 * scale,
                "M[{i},{j}] = {} against {expected}",
                mass[(i, j)]
            );
        }
    }
    // And the tree's own energy agrees with the bodies'.
    let from_bodies = kinetic(scene, &tree.system_state(state));
    assert!((tree.energy(state).kinetic - from_bodies).abs() < 1e-13 * from_bodies);
    assert!((0.5 * state.v.dot(&(mass * state.v)) - from_bodies).abs() < 1e-13 * from_bodies);
}

#[test]
fn mass_matrix_is_the_kinetic_energy_hessian() {
    mass_matrix_against_energy(&Walker, &walker_state());
    mass_matrix_against_energy(&Arm3, &arm_state());
    mass_matrix_against_energy(&CartPole, &cart_pole_state());
    mass_matrix_against_energy(&Gimbal, &gimbal_state());
    let welded = TreeState { q: SVector::from([0.7]), v: SVector::from([1.5]), t: 0.0 };
    mass_matrix_against_energy(&Welded, &welded);
}

/// The recursions agree with each other: `RNEA(q, v, ABA(q, v, τ)) = τ`, and
/// `M v̇ + b = RNEA(q, v, v̇)`.
#[test]
fn inverse_dynamics_inverts_forward_dynamics() {
    let tree = Tree::of(&Walker).unwrap();
    let state = walker_state();
    let tau = SVector::<f64, 8>::from_column_slice(&[1.0, -2.0, 0.5, 3.0, -1.5, 0.25, 0.1, -0.4]);
    let vdot = tree.forward_dynamics(&state, &tau).unwrap();
    let back = tree.inverse_dynamics(&state, &vdot);
    assert!((back - tau).norm() < 1e-12 * tau.norm(), "{back} against {tau}");
    let mut mass = SMatrix::<f64, 8, 8>::zeros();
    tree.mass_matrix_into(&state.q, &mut mass);
    let rnea = tree.inverse_dynamics(&state, &vdot);
    let crba = mass * vdot + tree.bias_forces(&state);
    assert!((rnea - crba).norm() < 1e-12 * rnea.norm(), "{rnea} against {crba}");
    // With a universal joint (its subspace turning with θ₂: the joint's own
    // Ṡ q̇ enters both recursions).
    let tree = Tree::of(&Gimbal).unwrap();
    let state = gimbal_state();
    let tau = SVector::<f64, 3>::from([0.7, -1.1, 0.4]);
    let vdot = tree.forward_dynamics(&state, &tau).unwrap();
    let back = tree.inverse_dynamics(&state, &vdot);
    assert!((back - tau).norm() < 1e-12 * tau.norm(), "{back} against {tau}");
    let mut mass = SMatrix::<f64, 3, 3>::zeros();
    tree.mass_matrix_into(&state.q, &mut mass);
    let crba = mass * vdot + tree.bias_forces(&state);
    assert!((back - crba).norm() < 1e-12 * back.norm(), "{back} against {crba}");
}

/// The largest difference between two absolute states: any body's position,
/// rotation (radians), velocity or angular velocity.
pub(crate) fn same_bodies<const NB: usize>(a: &SystemState<NB>, b: &SystemState<NB>) -> f64 {
    let mut worst = 0.0_f64;
    for (a, b) in a.bodies.iter().zip(&b.bodies) {
        worst = worst.max((a.r - b.r).norm()).max(a.rotation().angle_to(&b.rotation()));
        worst = worst.max((a.rdot - b.rdot).norm()).max((a.omega - b.omega).norm());
    }
    worst
}

/// Both coordinate choices of one declaration (loops closed or not): the
/// same start, RK4 at h = 1e-4 for `steps` steps, every body's pose and
/// velocity equal to `tol`, energy kept to `drift`, the loops still closed,
/// and the absolute state converted back to the same joints. Returns how far
/// the last body moved (m).
pub(crate) fn same_motion<
    S,
    const NB: usize,
    const NV6: usize,
    const M: usize,
    const NNZ: usize,
    const NQ: usize,
    const NV: usize,
    const NC: usize,
>(
    scene: &S,
    start: TreeState<NQ, NV>,
    steps: usize,
    (tol, drift): (f64, f64),
) -> f64
where
    S: Scene<NB, NV6, M> + SparseJacobian<NB, NNZ> + TreeScene<NB, NQ, NV, NC>,
{
    let mut relative = TreeSimulation::new(scene).unwrap();
    let mut absolute = AbsoluteSimulation::new(scene, NoLoads, &[], SimulationOptions::default()).unwrap();
    let mut tree_state = start;
    let mut system = relative.tree().system_state(&start);
    let energy = relative.tree().energy(&start).total();
    let h = 1e-4;
    for _ in 0..steps {
        relative.step(&mut tree_state, h).unwrap();
        absolute.step(&mut system, h).unwrap();
    }
    let mine = relative.tree().system_state(&tree_state);
    let worst = same_bodies(&mine, &system);
    assert!(worst < tol, "the two coordinate choices differ by {worst:e}");
    let kept = (relative.tree().energy(&tree_state).total() - energy).abs();
    assert!(kept < drift, "energy drift {kept:e}");
    let rows = relative.closure_rows(&tree_state);
    assert!(rows.phi.amax() <= 1e-12 && (rows.jacobian * tree_state.v).amax() <= 1e-12);
    let back = relative.tree().tree_state(&system, 1e-8).unwrap();
    let again = relative.tree().system_state(&back);
    for (a, b) in again.bodies.iter().zip(&system.bodies) {
        assert!((a.r - b.r).norm() < 1e-12 && a.rotation().angle_to(&b.rotation()) < 1e-12);
        assert!((a.rdot - b.rdot).norm() < 1e-11 && (a.omega - b.omega).norm() < 1e-11);
    }
    (mine.bodies[NB - 1].r - relative.tree().system_state(&start).bodies[NB - 1].r).norm()
}

#[test]
fn both_coordinate_choices_give_the_same_motion() {
    let starts = [
        same_motion(&Walker, walker_state(), 3000, (1e-10, 1e-9)),
        same_motion(&Arm3, arm_state(), 3000, (1e-10, 1e-9)),
        same_motion(&CartPole, cart_pole_state(), 3000, (1e-10, 1e-9)),
        same_motion(&Gimbal, gimbal_state(), 3000, (1e-10, 1e-9)),
        same_motion(
            &Welded,
            TreeState { q: SVector::from([0.7]), v: SVector::from([1.5]), t: 0.0 },
            3000,
            (1e-10, 1e-9),
        ),
    ];
    // Each last body moved: something was compared.
    assert!(starts.iter().all(|&moved| moved > 0.1), "{starts:?}");
}

/// A block sliding down its rail: `d̈ = −g a_z / |a|` (the rail's slope), the
/// pose carried along the rail with the block's frame turned onto it.
#[test]
fn prismatic_joint_against_its_closed_form() {
    let mut sim = TreeSimulation::new(&Slider).unwrap();
    let state = TreeState { q: SVector::from([0.3]), v: SVector::from([0.4]), t: 0.0 };
    let a = Vector3::new(1.0, 0.0, 0.5).normalize();
    let vdot = sim.forward_dynamics(&state, &SVector::zeros()).unwrap();
    assert!((vdot[0] + 9.81 * a.z).abs() < 1e-14, "{vdot}");
    assert!((sim.tree().forward_dynamics(&state, &SVector::zeros()).unwrap()[0] - vdot[0]).abs() < 1e-14);
    // The block's point `rho2` on the rail 0.3 m from the ground's `rho1`.
    let system = sim.tree().system_state(&state);
    let block = &system.bodies[0];
    let point = block.point(&Vector3::new(0.1, 0.0, 0.0));
    assert!((point - (Vector3::new(0.0, 0.0, 1.0) + a * 0.3)).norm() < 1e-15);
    assert!((block.rotation_matrix() * Vector3::y() - a).norm() < 1e-15, "its y axis along the rail");
    assert!((block.rdot - a * 0.4).norm() < 1e-15 && block.omega.norm() == 0.0);
    // And back: the slide and its rate from the absolute state.
    let back = sim.tree().tree_state(&system, 1e-12).unwrap();
    assert!((back.q[0] - 0.3).abs() < 1e-15 && (back.v[0] - 0.4).abs() < 1e-15);
    // Pushed with 2 N along the rail against 2 kg: d̈ grows by 1 m/s².
    let pushed = sim.forward_dynamics(&state, &SVector::from([2.0])).unwrap();
    assert!((pushed[0] - vdot[0] - 1.0).abs() < 1e-14);
}

#[test]
fn states_off_their_joints_are_refused_by_name() {
    let tree = Tree::of(&Walker).unwrap();
    let state = walker_state();
    let mut system = tree.system_state(&state);
    let back = tree.tree_state(&system, 1e-12).unwrap();
    let again = tree.system_state(&back);
    assert!((again.bodies[3].r - system.bodies[3].r).norm() < 1e-14);
    // The hand 1 cm off the wrist.
    system.bodies[3].r.x += 0.01;
    match tree.tree_state(&system, 1e-6) {
        Err(TreeError::NotOnJoint { joint: "wrist", misfit }) => assert!((misfit - 0.01).abs() < 1e-9, "{misfit}"),
        other => panic!("expected the wrist refused, got {other:?}"),
    }
    // The upper arm turned about an axis the elbow does not allow.
    let mut system = tree.system_state(&state);
    let tilt = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), 0.1);
    let turned = system.bodies[2].rotation() * tilt;
    system.bodies[2].set_rotation(&turned);
    assert!(matches!(tree.tree_state(&system, 1e-6), Err(TreeError::NotOnJoint { joint: "elbow", .. })));
}

/// The derive's written-out articulated-body algorithm against the
/// runtime's recursion, joint forces included.
pub(crate) fn generated_against_recursion<S, const NB: usize, const NQ: usize, const NV: usize>(
    scene: &S,
    state: &TreeState<NQ, NV>,
    written: bool,
) where
    S: TreeScene<NB, NQ, NV>,
{
    let mut sim = TreeSimulation::new(scene).unwrap();
    let tau = SVector::<f64, NV>::from_fn(|i, _| 0.3 * i as f64 - 0.5);
    let mut out = [0.0; NV];
    let (q, v, t) = (state.q.into(), state.v.into(), tau.into());
    let geometry = *sim.tree().geometry();
    assert_eq!(scene.forward_dynamics_into(&geometry, &q, &v, &t, &mut out), written);
    let generated = sim.forward_dynamics(state, &tau).unwrap();
    let recursion = sim.tree().forward_dynamics(state, &tau).unwrap();
    let scale = recursion.norm();
    assert!((generated - recursion).norm() < 1e-13 * scale, "{generated} against {recursion}");
    if written {
        assert_eq!(SVector::<f64, NV>::from(out), generated);
    }
    // The controller's two: inverse dynamics and the mass matrix, written out
    // for the small trees, the recursion's otherwise.
    let (mut ids, mut mass) = ([0.0; NV], [[0.0; NV]; NV]);
    let small = NV <= 8;
    assert!(!small || scene.inverse_dynamics_into(&geometry, &q, &v, &t, &mut ids) == written);
    assert!(!small || scene.mass_matrix_into(&geometry, &q, &mut mass) == written);
    let (tau_generated, tau_recursion) = (sim.inverse_dynamics(state, &tau), sim.tree().inverse_dynamics(state, &tau));
    assert!(
        (tau_generated - tau_recursion).norm() < 1e-13 * tau_recursion.norm(),
        "{tau_generated} against {tau_recursion}"
    );
    let (mut m_generated, mut m_recursion) = (SMatrix::<f64, NV, NV>::zeros(), SMatrix::<f64, NV, NV>::zeros());
    sim.mass_matrix_into(&state.q, &mut m_generated);
    sim.tree().mass_matrix_into(&state.q, &mut m_recursion);
    assert!((m_generated - m_recursion).norm() < 1e-13 * m_recursion.norm(), "{m_generated} against {m_recursion}");
}

#[test]
fn the_written_out_algorithm_matches_the_recursion() {
    generated_against_recursion(&Walker, &walker_state(), true);
    generated_against_recursion(&Arm3, &arm_state(), true);
    generated_against_recursion(&CartPole, &cart_pole_state(), true);
    generated_against_recursion(&Gimbal, &gimbal_state(), true);
    let welded = TreeState { q: SVector::from([0.7]), v: SVector::from([1.5]), t: 0.0 };
    generated_against_recursion(&Welded, &welded, true);
    let state = TreeState { q: SVector::from([0.7]), v: SVector::from([3.0]), t: 0.0 };
    generated_against_recursion(&HeavyBar { mass: 2.0 }, &state, true);
    let field = FieldBar { mass: 2.0, end: Vector3::new(-0.5, 0.0, 0.0) };
    generated_against_recursion(&field, &state, true);
    // The kernels: every quaternion turned, every joint moving.
    let tree = Tree::of(&LongChain).unwrap();
    let mut long = tree.zero_state();
    for (i, x) in long.q.iter_mut().enumerate() {
        *x += 0.1 * ((i * 7 % 5) as f64 - 2.0);
    }
    tree.normalise(&mut long.q);
    long.v = SVector::from_fn(|i, _| 0.2 * ((i * 3 % 7) as f64 - 3.0));
    generated_against_recursion(&LongChain, &long, true);
    // Both against the closed form: θ̈ = −m g (l/2) cos θ / (I_yy + m (l/2)²)
    // about +y for a bar turned by θ about y (gravity along −z).
    let closed = 2.0 * 9.81 * 0.5 * 0.7f64.cos() / (0.08 + 2.0 * 0.25);
    for accel in [
        TreeSimulation::new(&HeavyBar { mass: 2.0 }).unwrap().forward_dynamics(&state, &SVector::zeros()).unwrap()[0],
        TreeSimulation::new(&field).unwrap().forward_dynamics(&state, &SVector::zeros()).unwrap()[0],
    ] {
        assert!((accel - closed).abs() < 1e-14 * closed, "{accel} against {closed}");
    }
}

#[test]
fn bodies_that_cannot_exist_are_refused() {
    let impossible = Impossible { moments: Vector3::new(0.01, 0.01, 1.0) };
    assert_eq!(Tree::of(&impossible).err(), Some(TreeError::Inertia { body: 0 }));
    assert!(TreeSimulation::new(&impossible).is_err());
    // A thin rod, at the inequality's edge, is a body.
    assert!(Tree::of(&Impossible { moments: Vector3::new(0.5, 0.5, 1.0) }).is_ok());
}

/// A body point's Jacobian against the point's velocity in the absolute
/// state (the bodies' velocities, root to leaves) and against central
/// differences of its position along `q ⊕ ε v`.
fn point_jacobian_against_the_motion<S, const NB: usize, const NQ: usize, const NV: usize>(
    scene: &S,
    state: &TreeState<NQ, NV>,
    body: usize,
    point: Vector3<f64>,
) where
    S: TreeScene<NB, NQ, NV>,
{
    let tree = Tree::of(scene).unwrap();
    let jacobian = tree.point_jacobian(&state.q, body, &point).unwrap();
    let b = tree.system_state(state).bodies[body];
    let omega = b.rotation() * b.omega;
    let velocity = b.rdot + omega.cross(&(b.rotation() * point));
    let jv = jacobian * state.v;
    let scale = velocity.norm() + omega.norm();
    assert!((jv.fixed_rows::<3>(0) - omega).norm() < 1e-14 * scale, "ω: {jv} against {omega}");
    assert!((jv.fixed_rows::<3>(3) - velocity).norm() < 1e-14 * scale, "ṗ: {jv} against {velocity}");
    let at = |c: f64| {
        let q = tree.displaced(&state.q, &(state.v * c));
        tree.system_state(&TreeState { q, ..*state }).bodies[body].point(&point)
    };
    let eps = 1e-6;
    let diff = (at(eps) - at(-eps)) / (2.0 * eps);
    assert!((diff - velocity).norm() < 1e-8 * scale, "{diff} against {velocity}");
    assert!(tree.point_jacobian(&state.q, NB, &point).is_none());
}

#[test]
fn point_jacobians_move_points_as_the_bodies_do() {
    point_jacobian_against_the_motion(&Walker, &walker_state(), 3, Vector3::new(0.1, -0.05, 0.2));
    point_jacobian_against_the_motion(&Gimbal, &gimbal_state(), 1, Vector3::new(0.0, 0.03, -0.4));
    point_jacobian_against_the_motion(&CartPole, &cart_pole_state(), 1, Vector3::new(0.0, 0.0, -0.5));
    point_jacobian_against_the_motion(&Arm3, &arm_state(), 2, Vector3::new(0.5, 0.0, 0.0));
}

/// A welded block moves with its bar: the pendulum's closed form with the
/// block's mass and inertia added about the pivot,
/// `θ̈ = (m₁ l/2 + m₂ l) g cos θ / (I₁ + m₁ (l/2)² + I₂ + m₂ l²)` (a turn
/// about +y takes the bar's x down), from the
/// written-out algorithm and from the recursion.
#[test]
fn a_welded_body_moves_with_its_parent() {
    let mut sim = TreeSimulation::new(&Welded).unwrap();
    let theta: f64 = 0.7;
    let state = TreeState { q: SVector::from([theta]), v: SVector::from([1.5]), t: 0.0 };
    let expected = (1.0 * 0.5 + 0.5 * 1.0) * 9.81 * theta.cos() / (0.08 + 0.25 + 0.002 + 0.5);
    let generated = sim.forward_dynamics(&state, &SVector::zeros()).unwrap()[0];
    let recursion = sim.tree().forward_dynamics(&state, &SVector::zeros()).unwrap()[0];
    assert!(
        (generated - expected).abs() < 1e-14 && (recursion - expected).abs() < 1e-14,
        "{generated}, {recursion} against {expected}"
    );
    // The block sits at the bar's end, its x axis along the bar's z.
    let system = sim.tree().system_state(&state);
    let (bar, block) = (&system.bodies[0], &system.bodies[1]);
    assert!((block.r - bar.point(&Vector3::new(0.5, 0.0, 0.0))).norm() < 1e-15);
    let turned = block.rotation_matrix() * Vector3::x() - bar.rotation_matrix() * Vector3::z();
    assert!(turned.norm() < 1e-15, "{turned}");
}

/// A spring whose end names a body the scene does not have is refused when
/// it is given, by its index.
#[test]
fn springs_on_missing_bodies_are_refused() {
    use joint_runtime::dynamics::{Attachment, SpringDamper};
    let to = |body: usize| SpringDamper {
        a: Attachment::Ground(Vector3::zeros()),
        b: Attachment::Body { body, point: Vector3::zeros() },
        stiffness: 10.0,
        damping: 0.0,
        rest_length: 0.5,
    };
    let springs = [to(0), to(2)];
    assert!(TreeSimulation::new(&Welded).unwrap().with_springs(&springs[..1]).is_ok());
    let refused = TreeSimulation::new(&Welded).unwrap().with_springs(&springs).err();
    assert_eq!(refused, Some(TreeError::Attachment { spring: 1 }));
}
