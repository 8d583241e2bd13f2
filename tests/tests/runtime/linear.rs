//! The linearisation (`Simulation::linearise`) against closed forms and
//! against differences of the dynamics: a ball-jointed pendulum's swing
//! frequency `√(m g l / (I + m l²))`, a hanging double compound pendulum's two
//! frequencies from its textbook 2 × 2 eigenproblem, and, at a swinging
//! state of the double pendulum, `T A = F T` (the full linearisation `F`
//! leaves the constraints' tangent space invariant) with `F`'s acceleration
//! rows against central differences of `Simulation::dynamics`.

#![allow(missing_docs)]

use joint_runtime::dynamics::{
    AppliedLoads, Attachment, Direction, Loads, NoLoads, Simulation, SimulationOptions, SpringDamper,
};
use joint_runtime::nalgebra::{Complex, DMatrix, Matrix2, SVector, Vector3};
use joint_runtime::{Scene, SystemState};
use joint_tests::scenes::hanging_rods;

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
    let mut sim = Simulation::new(&scene, NoLoads, &[], SimulationOptions::default()).unwrap();
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
    let mut sim = Simulation::new(&scene, NoLoads, &[], SimulationOptions::default()).unwrap();
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
    let mut sim = Simulation::new(&scene, loads, springs, SimulationOptions::default()).unwrap();
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
        let mut sim = Simulation::new(&scene, load, &[], SimulationOptions::default()).unwrap();
        sim.dynamics(&state).unwrap().vdot
    };
    let fd = (pushed(1e-3) - pushed(-1e-3)) / 2e-3;

    for i in 0..12 {
        assert!((lin.full_b[(12 + i, 0)] - fd[i]).abs() < 1e-8 * (1.0 + fd.amax()), "{i}");
    }
}

/// At an equilibrium the full linearisation leaves the constraints' tangent
/// space invariant: `T A = F T`.
#[test]
fn at_an_equilibrium_minimal_coordinates_lose_nothing() {
    let scene = DoublePendulum;
    let mut sim = Simulation::new(&scene, NoLoads, &[], SimulationOptions::default()).unwrap();
    let lin = sim.linearise(&hanging_rods([0.0, 0.0]), &DMatrix::zeros(12, 0)).unwrap();
    let gap = (&lin.basis * &lin.a - &lin.full * &lin.basis).amax();
    assert!(gap < 1e-12 * (1.0 + lin.full.amax()), "{gap:e}");
}

/// A scene without `second_order` says what it needs.
#[test]
fn linearise_without_second_order_is_an_error() {
    #[derive(Scene)]
    #[body(bob, mass = 1.0, inertia = [1, 1, 1])]
    #[joint(pivot = spherical(ground, bob), rho1 = [0, 0, 0], rho2 = [0, 0, 1])]
    struct Plain;
    let mut sim = Simulation::new(&Plain, NoLoads, &[], SimulationOptions::default()).unwrap();
    let e = sim.linearise(&swung(0.0), &DMatrix::zeros(6, 0)).unwrap_err();
    assert!(e.to_string().contains("#[scene(second_order)]"), "{e}");
}

/// The state-transition Jacobian of an implicit midpoint step against central
/// differences of the step itself (no projection), increments in and out.
#[test]
fn transition_jacobian_matches_differences_of_the_step() {
    use joint_runtime::dynamics::Integrator;
    let scene = DoublePendulum;
    let options = SimulationOptions::default()
        .with_integrator(Integrator::ImplicitMidpoint)
        .with_projection(None)
        .with_newton_tolerance(1e-15);
    let mut sim = Simulation::new(&scene, NoLoads, &[], options).unwrap();
    let (start, h) = (double_start(), 5e-3);
    let mut end = start;
    let phi = sim.transition(&mut end, h).unwrap();
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
