//! The linearisation (`DenseSimulation::linearise`) against closed forms and
//! against differences of the dynamics: a ball-jointed pendulum's swing
//! frequency `√(m g l / (I + m l²))`, a hanging double compound pendulum's two
//! frequencies from its textbook 2 × 2 eigenproblem, and, at a swinging
//! state of the double pendulum, `T A = F T` (the full linearisation `F`
//! leaves the constraints' tangent space invariant) with `F`'s acceleration
//! rows against central differences of `DenseSimulation::dynamics` and against
//! dual numbers through a hand-written model of the same pendulum; the
//! midpoint step's state-transition Jacobian against differences of the step
//! and against dual numbers through the same step of that model.

#![allow(missing_docs)]

use joint_runtime::dynamics::{
    AppliedLoads, Attachment, DenseSimulation, Direction, Integrator, Loads, NoLoads, Simulation, SimulationOptions,
    SpringDamper, Stabilisation,
};
use joint_runtime::nalgebra::{Complex, DMatrix, Matrix2, Matrix3, RealField, SMatrix, SVector, Vector3, Vector4};
use joint_runtime::{Scene, SystemState};
use joint_tests::scenes::hanging_rods;
use num_dual::Dual64;

use super::dynamics::{DoublePendulum, double_start, pendulum, swung};

const G: f64 = 9.81;

/// Eigenvalues sorted by |imaginary part|, largest first.
fn sorted(mut e: Vec<Complex<f64>>) -> Vec<Complex<f64>> {
    e.sort_by(|a, b| b.im.abs().total_cmp(&a.im.abs()));
    e
}

#[test]
fn pendulum_swing_frequency_is_the_closed_form() {
    let scene = pendulum();
    let mut sim = DenseSimulation::new(&scene, NoLoads, &[], SimulationOptions::default()).unwrap();
    let lin = sim.linearise(&swung(0.0), &DMatrix::zeros(6, 0)).unwrap();
    assert_eq!(lin.freedoms, 3);
    // Point of suspension 1 m above the centre of mass, I = 0.01 about it.
    let omega = (scene.mass * G * 1.0 / (0.01 + scene.mass)).sqrt();
    let e = sorted(lin.eigenvalues().unwrap());
    println!("pendulum eigenvalues {e:?}, closed form ±{omega} i");
    for x in &e[..4] {
        assert!((x.im.abs() - omega).abs() < 1e-12 * omega && x.re.abs() < 1e-12, "{x}");
    }
    // The spin about the vertical: no restoring force, a double zero.
    for x in &e[4..] {
        assert!(x.norm() < 1e-6, "{x}");
    }
}

#[test]
fn double_pendulum_frequencies_are_the_compound_pendulum_ones() {
    // Rods m = 1, L = 1, centre at 0.5, I = 1/12 about the centre (across).
    let mass = Matrix2::new(1.0 / 12.0 + 0.25 + 1.0, 0.5, 0.5, 1.0 / 12.0 + 0.25);
    let stiffness = Matrix2::new(1.5 * G, 0.0, 0.0, 0.5 * G);
    let chol = mass.cholesky().unwrap();
    let l_inv = chol.l().try_inverse().unwrap();
    let reduced = l_inv * stiffness * l_inv.transpose();
    let mut want: Vec<f64> = reduced.symmetric_eigenvalues().iter().map(|x| x.sqrt()).collect();
    want.sort_by(|a, b| b.total_cmp(a));

    let scene = DoublePendulum;
    let mut sim = DenseSimulation::new(&scene, NoLoads, &[], SimulationOptions::default()).unwrap();
    let lin = sim.linearise(&hanging_rods([0.0, 0.0]), &DMatrix::zeros(12, 0)).unwrap();
    assert_eq!(lin.freedoms, 6);
    let e = sorted(lin.eigenvalues().unwrap());
    println!("double pendulum: {e:?}; closed form ±{want:?} i, each twice (two planes)");
    for (k, x) in e[..8].iter().enumerate() {
        let w = want[k / 4];
        assert!((x.im.abs() - w).abs() < 1e-11 * w && x.re.abs() < 1e-11, "{x} against ±{w} i");
    }
    for x in &e[8..] {
        assert!(x.norm() < 1e-6, "{x}");
    }
}

/// Moves `s` by `scale × (δq, δv)` (`δθ'` in body components).
fn moved(s: &SystemState<2>, dq: &[f64], dv: &[f64], scale: f64) -> SystemState<2> {
    let mut s = *s;
    for (b, body) in s.bodies.iter_mut().enumerate() {
        let o = 6 * b;
        body.r += Vector3::new(dq[o], dq[o + 1], dq[o + 2]) * scale;
        let turn = joint_runtime::nalgebra::UnitQuaternion::from_scaled_axis(
            Vector3::new(dq[o + 3], dq[o + 4], dq[o + 5]) * scale,
        );
        body.set_rotation(&(body.rotation() * turn));
        body.rdot += Vector3::new(dv[o], dv[o + 1], dv[o + 2]) * scale;
        body.omega += Vector3::new(dv[o + 3], dv[o + 4], dv[o + 5]) * scale;
    }
    s
}

/// A viscous torque `−c ω'` on the upper rod, with its own derivative.
#[derive(Clone, Copy)]
struct Drag;

impl AppliedLoads<2> for Drag {
    fn apply(&mut self, state: &SystemState<2>, loads: &mut Loads<2>) {
        loads.torque[0] -= state.bodies[0].omega * 0.3;
    }
    fn derivative(&mut self, _: &SystemState<2>, direction: &Direction<2>, loads: &mut Loads<2>) -> bool {
        loads.torque[0] -= direction[0][3] * 0.3;
        true
    }
}

/// A spring-damper from the lower rod's tip to a ground point.
fn tip_spring() -> [SpringDamper; 1] {
    [SpringDamper {
        a: Attachment::Body { body: 1, point: Vector3::new(0.0, 0.1, -0.5) },
        b: Attachment::Ground(Vector3::new(0.4, 0.3, -1.2)),
        stiffness: 300.0,
        damping: 2.0,
        rest_length: 0.2,
    }]
}

#[test]
fn full_linearisation_at_a_swinging_state_matches_differences_of_the_dynamics() {
    check_full(NoLoads, &[]);
    // Springs (exact derivatives), user loads with their own derivative and
    // without (central differences of the loads).
    check_full(Drag, &tip_spring());
    check_full(|s: &SystemState<2>, l: &mut Loads<2>| l.force[1] += s.bodies[1].rdot * -0.5, &tip_spring());
}

fn check_full<L: AppliedLoads<2>>(loads: L, springs: &[SpringDamper]) {
    let scene = DoublePendulum;
    let mut sim = DenseSimulation::new(&scene, loads, springs, SimulationOptions::default()).unwrap();
    let state = double_start();
    // A load input: a horizontal force on the lower rod's centre.
    let mut inputs = DMatrix::zeros(12, 1);
    inputs[(6, 0)] = 1.0;
    let lin = sim.linearise(&state, &inputs).unwrap();
    let v: Vec<f64> =
        state.bodies.iter().flat_map(|b| b.rdot.iter().chain(b.omega.iter()).copied().collect::<Vec<_>>()).collect();
    let mut worst = 0.0f64;
    let mut seed = 0.3f64;
    for k in 0..24 {
        // Unit increments, then a few mixed ones.
        let direction: Vec<f64> = (0..24)
            .map(|i| {
                seed = (seed * 7.3 + 0.17).fract();
                if k < 20 { if i == k { 1.0 } else { 0.0 } } else { seed - 0.5 }
            })
            .collect();
        let (dq, dv) = direction.split_at(12);
        let image = &lin.full * DMatrix::from_column_slice(24, 1, &direction);
        // Upper block: δθ̇ = δω − ω × δθ, δṙ = δṙ (the group's own motion).
        for b in 0..2 {
            let w = Vector3::new(v[6 * b + 3], v[6 * b + 4], v[6 * b + 5]);
            let theta = Vector3::new(dq[6 * b + 3], dq[6 * b + 4], dq[6 * b + 5]);
            let want = Vector3::new(dv[6 * b + 3], dv[6 * b + 4], dv[6 * b + 5]) - w.cross(&theta);
            for i in 0..3 {
                assert!((image[6 * b + 3 + i] - want[i]).abs() < 1e-12);
                assert!((image[6 * b + i] - dv[6 * b + i]).abs() < 1e-12);
            }
        }
        // Lower block: δa against central differences of the dynamics.
        // Central differences, Richardson-extrapolated (error O(ε⁴)).
        let mut central = |eps: f64| -> SVector<f64, 12> {
            let plus = sim.dynamics(&moved(&state, dq, dv, eps)).unwrap().vdot;
            let minus = sim.dynamics(&moved(&state, dq, dv, -eps)).unwrap().vdot;
            (plus - minus) / (2.0 * eps)
        };
        let fd = (central(5e-4) * 4.0 - central(1e-3)) / 3.0;
        for i in 0..12 {
            worst = worst.max((image[12 + i] - fd[i]).abs() / (1.0 + fd.amax()));
        }
    }
    println!("full linearisation against differences of the dynamics: worst {worst:e}");
    assert!(worst < 1e-8, "{worst:e}");
    // The input: a unit force on the lower rod's centre, against a difference
    // of the dynamics under that load.
    let pushed = |f: f64| {
        let load = move |_: &SystemState<2>, l: &mut Loads<2>| l.force[1].x += f;
        let mut sim = DenseSimulation::new(&scene, load, &[], SimulationOptions::default()).unwrap();
        sim.dynamics(&state).unwrap().vdot
    };
    let fd = (pushed(1e-3) - pushed(-1e-3)) / 2e-3;

    for i in 0..12 {
        assert!((lin.full_b[(12 + i, 0)] - fd[i]).abs() < 1e-8 * (1.0 + fd.amax()), "{i}");
    }
}

/// The sparse path's linearisation and transition Jacobian are the dense
/// path's (which the tests above hold to differences and dual numbers), with
/// springs, user loads with and without their own derivative, an input, and
/// Baumgarte stabilisation.
#[test]
fn sparse_linearisation_and_transition_are_the_dense_ones() {
    let pull = |s: &SystemState<2>, l: &mut Loads<2>| l.force[1] += s.bodies[1].rdot * -0.5;
    let baumgarte = SimulationOptions::default().with_stabilisation(Stabilisation::Baumgarte { alpha: 5.0, beta: 5.0 });
    compare_paths(NoLoads, &[], SimulationOptions::default());
    compare_paths(Drag, &tip_spring(), SimulationOptions::default());
    compare_paths(pull, &tip_spring(), SimulationOptions::default());
    compare_paths(pull, &tip_spring(), baumgarte);
}

fn compare_paths<L: AppliedLoads<2> + Copy>(loads: L, springs: &[SpringDamper], options: SimulationOptions) {
    let state = double_start();
    let mut inputs = DMatrix::zeros(12, 2);
    (inputs[(6, 0)], inputs[(3, 1)]) = (1.0, 0.5);
    let mut dense = DenseSimulation::new(&DoublePendulum, loads, springs, options).unwrap();
    let mut sparse = Simulation::new(&DoublePendulum, loads, springs, options).unwrap();
    assert_eq!(dense.forces(&state), sparse.forces(&state));
    let (d, s) = (dense.linearise(&state, &inputs).unwrap(), sparse.linearise(&state, &inputs).unwrap());
    assert_eq!(d.freedoms, s.freedoms);
    for (name, x, y) in
        [("full", &d.full, &s.full), ("full_b", &d.full_b, &s.full_b), ("a", &d.a, &s.a), ("b", &d.b, &s.b)]
    {
        let gap = (x - y).amax() / (1.0 + x.amax());
        assert!(gap < 1e-12, "{name}: {gap:e}");
    }
    let midpoint =
        options.with_integrator(Integrator::ImplicitMidpoint).with_projection(None).with_newton_tolerance(1e-15);
    (dense.options, sparse.options) = (midpoint, midpoint);
    let (mut a, mut b) = (state, state);
    let (x, y) = (dense.transition(&mut a, 5e-3).unwrap(), sparse.transition(&mut b, 5e-3).unwrap());
    let gap = (&x - &y).amax() / (1.0 + x.amax());
    assert!(gap < 1e-11, "transition: {gap:e}");
    assert!((a.bodies[1].r - b.bodies[1].r).norm() < 1e-13);
}

/// Without second-order terms the sparse path says what it needs, too.
#[test]
fn sparse_linearise_without_second_order_is_an_error() {
    #[derive(Scene)]
    #[scene(coordinates = absolute)]
    #[body(bob, mass = 1.0, inertia = [1, 1, 1])]
    #[joint(pivot = spherical(ground, bob), rho1 = [0, 0, 0], rho2 = [0, 0, 1])]
    struct Plain;
    let mut sim = Simulation::new(&Plain, NoLoads, &[], SimulationOptions::default()).unwrap();
    let e = sim.linearise(&swung(0.0), &DMatrix::zeros(6, 0)).unwrap_err();
    assert!(e.to_string().contains("#[scene(second_order)]"), "{e}");
    let mut end = swung(0.3);
    let e = sim.transition(&mut end, 1e-3).unwrap_err();
    assert!(e.to_string().contains("#[scene(second_order)]") && end == swung(0.3), "{e}");
}

/// At an equilibrium the full linearisation leaves the constraints' tangent
/// space invariant: `T A = F T`.
#[test]
fn at_an_equilibrium_minimal_coordinates_lose_nothing() {
    let scene = DoublePendulum;
    let mut sim = DenseSimulation::new(&scene, NoLoads, &[], SimulationOptions::default()).unwrap();
    let lin = sim.linearise(&hanging_rods([0.0, 0.0]), &DMatrix::zeros(12, 0)).unwrap();
    let gap = (&lin.basis * &lin.a - &lin.full * &lin.basis).amax();
    assert!(gap < 1e-12 * (1.0 + lin.full.amax()), "{gap:e}");
}

/// A scene without `second_order` says what it needs.
#[test]
fn linearise_without_second_order_is_an_error() {
    #[derive(Scene)]
    #[scene(coordinates = absolute)]
    #[body(bob, mass = 1.0, inertia = [1, 1, 1])]
    #[joint(pivot = spherical(ground, bob), rho1 = [0, 0, 0], rho2 = [0, 0, 1])]
    struct Plain;
    let mut sim = DenseSimulation::new(&Plain, NoLoads, &[], SimulationOptions::default()).unwrap();
    let e = sim.linearise(&swung(0.0), &DMatrix::zeros(6, 0)).unwrap_err();
    assert!(e.to_string().contains("#[scene(second_order)]"), "{e}");
}

/// A midpoint simulation of the double pendulum (no projection, Newton to
/// round-off), the end of its step `h` from `start` and the step's
/// state-transition Jacobian.
fn midpoint_transition(
    start: &SystemState<2>,
    h: f64,
) -> (DenseSimulation<'static, DoublePendulum, NoLoads, 2, 12, 6>, SystemState<2>, DMatrix<f64>) {
    let options = SimulationOptions::default()
        .with_integrator(Integrator::ImplicitMidpoint)
        .with_projection(None)
        .with_newton_tolerance(1e-15);
    let mut sim = DenseSimulation::new(&DoublePendulum, NoLoads, &[], options).unwrap();
    let mut end = *start;
    let phi = sim.transition(&mut end, h).unwrap();
    (sim, end, phi)
}

/// The state-transition Jacobian of an implicit midpoint step against central
/// differences of the step itself (no projection), increments in and out.
#[test]
fn transition_jacobian_matches_differences_of_the_step() {
    let (start, h) = (double_start(), 5e-3);
    let (mut sim, end, phi) = midpoint_transition(&start, h);
    let mut stepped = start;
    sim.step(&mut stepped, h).unwrap();
    assert!((stepped.bodies[1].r - end.bodies[1].r).norm() < 1e-12, "transition takes the step");
    // An increment of the end state: δr, the body rotation vector, δv.
    let increment = |s: &SystemState<2>| -> Vec<f64> {
        let mut out = vec![0.0; 24];
        for (b, (x, y)) in s.bodies.iter().zip(&end.bodies).enumerate() {
            let turn = (y.rotation().inverse() * x.rotation()).scaled_axis();
            for i in 0..3 {
                out[6 * b + i] = x.r[i] - y.r[i];
                out[6 * b + 3 + i] = turn[i];
                out[12 + 6 * b + i] = x.rdot[i] - y.rdot[i];
                out[12 + 6 * b + 3 + i] = x.omega[i] - y.omega[i];
            }
        }
        out
    };
    let eps = 1e-5;
    let mut worst = 0.0f64;
    for k in 0..24 {
        let mut e = [0.0; 24];
        e[k] = 1.0;
        let mut column = |sign: f64| {
            let mut s = moved(&start, &e[..12], &e[12..], sign * eps);
            sim.step(&mut s, h).unwrap();
            increment(&s)
        };
        let (plus, minus) = (column(1.0), column(-1.0));
        for i in 0..24 {
            let fd = (plus[i] - minus[i]) / (2.0 * eps);
            worst = worst.max((phi[(i, k)] - fd).abs() / (1.0 + phi.column(k).amax()));
        }
    }
    println!("state-transition Jacobian against differences of the step: worst {worst:e}");
    assert!(worst < 1e-7, "{worst:e}");
}

/// The double pendulum's constrained accelerations written out by hand, over
/// any scalar (here dual numbers): two ball joints as point constraints, their
/// Jacobian rows `[I, −A ρ̃]` per body and `γ = −Σ ± A (ω' × (ω' × ρ))`, the
/// forces `m g` and `−ω' × J' ω'`, and `M v̇ + Jᵀ λ = Q`, `J v̇ = γ` solved by
/// `J M⁻¹ Jᵀ`. Nothing in it comes from the derive or the runtime.
fn hand_accelerations<T: RealField + Copy>(
    a: [Matrix3<T>; 2],
    r: [Vector3<T>; 2],
    v: &SVector<T, 12>,
) -> SVector<T, 12> {
    let c = |x: f64| T::from_f64(x).unwrap_or_else(T::zero);
    let _ = r; // Ball joints: the accelerations do not depend on where the bodies are, only on A.
    let inertia = Matrix3::from_diagonal(&Vector3::new(c(1.0 / 12.0), c(1.0 / 12.0), c(1e-3)));
    let omega = [Vector3::new(v[3], v[4], v[5]), Vector3::new(v[9], v[10], v[11])];
    // (body, point, sign) of each joint's two ends: shoulder = upper's top at
    // the origin, elbow = upper's bottom at the lower's top.
    let ends: [&[(usize, f64, f64)]; 2] = [&[(0, 0.5, 1.0)], &[(0, -0.5, 1.0), (1, 0.5, -1.0)]];
    let mut j = SMatrix::<T, 6, 12>::zeros();
    let mut gamma = SVector::<T, 6>::zeros();
    for (joint, ends) in ends.iter().enumerate() {
        for &(body, z, sign) in ends.iter() {
            let rho = Vector3::new(c(0.0), c(0.0), c(z));
            let s = c(sign);
            let arm = -(a[body] * rho.cross_matrix()) * s;
            for i in 0..3 {
                j[(3 * joint + i, 6 * body + i)] += s;
                for k in 0..3 {
                    j[(3 * joint + i, 6 * body + 3 + k)] += arm[(i, k)];
                }
            }
            let centripetal = a[body] * omega[body].cross(&omega[body].cross(&rho)) * s;
            for i in 0..3 {
                gamma[3 * joint + i] -= centripetal[i];
            }
        }
    }
    let mut q = SVector::<T, 12>::zeros();
    let mut minv = SVector::<T, 12>::zeros();
    for b in 0..2 {
        q[6 * b + 2] = c(-G);
        let gyro = -omega[b].cross(&(inertia * omega[b]));
        for i in 0..3 {
            minv[6 * b + i] = c(1.0);
            minv[6 * b + 3 + i] = c(1.0) / inertia[(i, i)];
            q[6 * b + 3 + i] = gyro[i];
        }
    }
    let jw = SMatrix::<T, 6, 12>::from_fn(|i, k| j[(i, k)] * minv[k]);
    let minv_q = q.component_mul(&minv);
    let lambda = (jw * j.transpose()).lu().solve(&(j * minv_q - gamma)).expect("J M⁻¹ Jᵀ is regular");
    minv_q - jw.transpose() * lambda
}

/// The rotation matrices, positions and velocities of `state` in dual
/// numbers, moved along increment `k` (`0..12` positions: `r ← r + ε e`, or
/// `A ← A (I + ε ẽ)` for a turn; `12..24` velocities: `v ← v + ε e`).
#[allow(clippy::type_complexity)]
fn perturbed(state: &SystemState<2>, k: usize) -> ([Matrix3<Dual64>; 2], [Vector3<Dual64>; 2], SVector<Dual64, 12>) {
    let eps = Dual64::from_re(0.0).derivative();
    let mut a: [Matrix3<Dual64>; 2] = core::array::from_fn(|b| rotation(&state.bodies[b].p));
    let mut r: [Vector3<Dual64>; 2] = core::array::from_fn(|b| state.bodies[b].r.map(Dual64::from_re));
    let mut v = SVector::<Dual64, 12>::from_fn(|i, _| {
        let b = &state.bodies[i / 6];
        Dual64::from_re(if i % 6 < 3 { b.rdot[i % 6] } else { b.omega[i % 6 - 3] })
    });
    let (b, c) = ((k % 12) / 6, k % 6);
    match (k < 12, c < 3) {
        (true, true) => r[b][c] += eps,
        (true, false) => {
            let mut turn = Vector3::zeros();
            turn[c - 3] = eps;
            a[b] *= Matrix3::identity() + turn.cross_matrix();
        }
        (false, _) => v[k - 12] += eps,
    }
    (a, r, v)
}

/// `A(p)` of Euler parameters `(e₀, e)`: `(e₀² − e·e) I + 2 e eᵀ + 2 e₀ ẽ`.
fn rotation<T: RealField + Copy>(p: &Vector4<f64>) -> Matrix3<T> {
    let p = p.map(|x| T::from_f64(x).unwrap_or_else(T::zero));
    let (e0, e) = (p[0], Vector3::new(p[1], p[2], p[3]));
    let two = T::one() + T::one();
    Matrix3::identity() * (e0 * e0 - e.dot(&e)) + e * e.transpose() * two + e.cross_matrix() * (e0 * two)
}

/// The linearisation's acceleration rows `[A_q, A_v]` at the swinging state
/// against dual-number derivatives of [`hand_accelerations`] along every
/// increment (`A ← A (I + ε ẽ_k)` for a turn, `v ← v + ε e_k`): exact to
/// round-off, where differences agree only to 1e-8.
#[test]
fn full_linearisation_matches_dual_numbers_through_a_hand_written_model() {
    let scene = DoublePendulum;
    let mut sim = DenseSimulation::new(&scene, NoLoads, &[], SimulationOptions::default()).unwrap();
    let state = double_start();
    let lin = sim.linearise(&state, &DMatrix::zeros(12, 0)).unwrap();
    let a0: [Matrix3<f64>; 2] = core::array::from_fn(|b| rotation(&state.bodies[b].p));
    let v0 = SVector::<f64, 12>::from_fn(|i, _| {
        let b = &state.bodies[i / 6];
        if i % 6 < 3 { b.rdot[i % 6] } else { b.omega[i % 6 - 3] }
    });
    // The hand model agrees with the runtime's dynamics at the state itself.
    let plain = hand_accelerations::<f64>(a0, [state.bodies[0].r, state.bodies[1].r], &v0);
    let runtime = sim.dynamics(&state).unwrap().vdot;
    assert!((plain - runtime).amax() < 1e-12 * (1.0 + runtime.amax()), "{:e}", (plain - runtime).amax());
    let worst = against_dual_accelerations(&lin.full, &state);
    println!("full linearisation against dual numbers of a hand-written model: worst {worst:e}");
    assert!(worst < 1e-12, "{worst:e}");
    // The sparse path's, through the block factor and the sparse second-order terms.
    let mut sparse = Simulation::new(&scene, NoLoads, &[], SimulationOptions::default()).unwrap();
    let worst = against_dual_accelerations(&sparse.linearise(&state, &DMatrix::zeros(12, 0)).unwrap().full, &state);
    println!("sparse full linearisation against dual numbers of a hand-written model: worst {worst:e}");
    assert!(worst < 1e-12, "{worst:e}");
}

/// The largest relative gap between the acceleration rows of `full` and the
/// dual-number derivatives of [`hand_accelerations`] along every increment.
fn against_dual_accelerations(full: &DMatrix<f64>, state: &SystemState<2>) -> f64 {
    let mut worst = 0.0f64;
    for k in 0..24 {
        let (a, r, v) = perturbed(state, k);
        let derivative = hand_accelerations(a, r, &v).map(|x| x.eps);
        for i in 0..12 {
            worst = worst.max((full[(12 + i, k)] - derivative[i]).abs() / (1.0 + derivative.amax()));
        }
    }
    worst
}

/// `Exp(φ)`: Rodrigues' formula, by its series near `φ = 0`.
fn exp_rotation<T: RealField + Copy>(phi: &Vector3<T>) -> Matrix3<T> {
    let c = |x: f64| T::from_f64(x).unwrap_or_else(T::zero);
    let (k, t2) = (phi.cross_matrix(), phi.dot(phi));
    let (s, q) = if t2 < c(1e-12) {
        (c(1.0) - t2 / c(6.0), c(0.5) - t2 / c(24.0))
    } else {
        let t = t2.sqrt();
        (t.sin() / t, (c(1.0) - t.cos()) / t2)
    };
    Matrix3::identity() + k * s + k * k * q
}

/// The state-transition Jacobian of an implicit midpoint step against dual
/// numbers through the same step of [`hand_accelerations`]: the midpoint
/// velocity `w = v₀ + (h/2) a(q₀ ⊕ (h/2) w, w)` by fixed-point iteration in
/// dual numbers (the derivative converges with the value), then
/// `q₁ = q₀ ⊕ h w`, `v₁ = 2w − v₀`, and the end's increments read off the dual
/// parts (`δθ̃₁ = A₁ᵀ dA₁`).
#[test]
fn transition_jacobian_matches_dual_numbers_through_a_hand_written_step() {
    let (start, h) = (double_start(), 5e-3);
    let (_, end, phi) = midpoint_transition(&start, h);
    let worst = against_dual_step(&phi, &start, h);
    println!("state-transition Jacobian against dual numbers of a hand-written step: worst {worst:e}");
    assert!(worst < 1e-12, "{worst:e}");
    // The sparse path's: the same step, its Newton matrix from the sparse terms.
    let options = SimulationOptions::default()
        .with_integrator(Integrator::ImplicitMidpoint)
        .with_projection(None)
        .with_newton_tolerance(1e-15);
    let mut sparse = Simulation::new(&DoublePendulum, NoLoads, &[], options).unwrap();
    let mut sparse_end = start;
    let sparse_phi = sparse.transition(&mut sparse_end, h).unwrap();
    assert!((sparse_end.bodies[1].r - end.bodies[1].r).norm() < 1e-13, "the same step");
    let worst = against_dual_step(&sparse_phi, &start, h);
    println!("sparse state-transition Jacobian against dual numbers of a hand-written step: worst {worst:e}");
    assert!(worst < 1e-12, "{worst:e}");
}

/// The largest relative gap between the state-transition Jacobian `phi` of a
/// midpoint step `h` from `start` and dual numbers through the same step of
/// [`hand_accelerations`].
fn against_dual_step(phi: &DMatrix<f64>, start: &SystemState<2>, h: f64) -> f64 {
    let hd = Dual64::from_re(h);
    let mut worst = 0.0f64;
    for k in 0..24 {
        let (a0, r0, v) = perturbed(start, k);
        let moved = |w: &SVector<Dual64, 12>, s: Dual64| {
            let a: [Matrix3<Dual64>; 2] = core::array::from_fn(|b| {
                a0[b] * exp_rotation(&(Vector3::new(w[6 * b + 3], w[6 * b + 4], w[6 * b + 5]) * s))
            });
            let r: [Vector3<Dual64>; 2] =
                core::array::from_fn(|b| r0[b] + Vector3::new(w[6 * b], w[6 * b + 1], w[6 * b + 2]) * s);
            (a, r)
        };
        let mut w = v;
        for _ in 0..400 {
            let (a, r) = moved(&w, hd * 0.5);
            let next = v + hand_accelerations(a, r, &w) * (hd * 0.5);
            let change = (next - w).map(|x| x.re.abs() + x.eps.abs()).amax();
            w = next;
            if change < 1e-17 {
                break;
            }
        }
        let (a1, r1) = moved(&w, hd);
        let v1 = w * Dual64::from_re(2.0) - v;
        let mut column = [0.0; 24];
        for b in 0..2 {
            let turn = a1[b].map(|x| x.re).transpose() * a1[b].map(|x| x.eps);
            let theta = [turn[(2, 1)], turn[(0, 2)], turn[(1, 0)]];
            for i in 0..3 {
                column[6 * b + i] = r1[b][i].eps;
                column[6 * b + 3 + i] = theta[i];
            }
        }
        for (i, x) in v1.iter().enumerate() {
            column[12 + i] = x.eps;
        }
        for (i, x) in column.iter().enumerate() {
            worst = worst.max((phi[(i, k)] - x).abs() / (1.0 + phi.column(k).amax()));
        }
    }
    worst
}
