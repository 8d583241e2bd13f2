//! Forward dynamics (`joint_runtime::dynamics`) on `#[derive(Scene)]` mechanisms: a
//! simple pendulum's period and energy, a double pendulum with both integrators and
//! projection, a stiff spring, reactions.

#![allow(missing_docs)]

use joint_runtime::dynamics::{
    Attachment, Integrator, NewtonMatrix, NoLoads, Simulation, SimulationOptions, SpringDamper, Stabilisation,
};
use joint_runtime::nalgebra::{SVector, UnitQuaternion, Vector3};
use joint_runtime::{OmegaBody, Scene, SystemState};
use joint_tests::scenes::hanging_rods;

// --- Scenes and tests. ---

const G: f64 = 9.81;

/// A bob (mass `mass`, I = 0.01) 1 m below a ball joint at the origin.
#[derive(Scene)]
#[scene(coordinates = absolute, gravity = [0, 0, -9.81], second_order)]
#[body(bob, mass = mass, inertia = [0.01, 0.01, 0.01])]
#[joint(pivot = spherical(ground, bob), rho1 = [0, 0, 0], rho2 = [0, 0, 1])]
pub(crate) struct Pendulum {
    pub(crate) mass: f64,
}

pub(crate) fn pendulum() -> Pendulum {
    Pendulum { mass: 1.0 }
}

/// The bob turned by `angle` about x, at rest.
pub(crate) fn swung(angle: f64) -> SystemState<1> {
    let q = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), angle);
    let r = -(q * Vector3::new(0.0, 0.0, 1.0));
    SystemState { bodies: [OmegaBody::from_rotation(r, &q, Vector3::zeros(), Vector3::zeros())], t: 0.0 }
}

/// Two rods of length 1 (m = 1, I = diag(1/12, 1/12, 1e-3)) hanging from the
/// origin, ball joints.
#[derive(Scene)]
#[scene(coordinates = absolute, gravity = [0, 0, -9.81], second_order)]
#[body(upper, mass = 1.0, inertia = [0.08333333333333333, 0.08333333333333333, 1e-3])]
#[body(lower, mass = 1.0, inertia = [0.08333333333333333, 0.08333333333333333, 1e-3])]
#[joint(shoulder = spherical(ground, upper), rho1 = [0, 0, 0], rho2 = [0, 0, 0.5])]
#[joint(elbow = spherical(upper, lower), rho1 = [0, 0, -0.5], rho2 = [0, 0, 0.5])]
pub(crate) struct DoublePendulum;

/// Upper rod horizontal along +y, lower rod at 45°, lower rod spinning about its axis.
pub(crate) fn double_start() -> SystemState<2> {
    let mut s = hanging_rods([90f64.to_radians(), 135f64.to_radians()]);
    // Spin of the lower rod about its own axis (consistent with the ball joints).
    s.bodies[1].omega = Vector3::new(0.0, 0.0, 3.0);
    s
}

fn options(integrator: Integrator, project: bool) -> SimulationOptions {
    let mut o = SimulationOptions::default().with_integrator(integrator);
    if !project {
        o.projection = None;
    }
    o
}

#[test]
fn pendulum_period_matches_small_angle_closed_form() {
    let scene = pendulum();
    let mut sim = Simulation::new(&scene, NoLoads, &[], options(Integrator::Rk4, true)).unwrap();
    let theta0 = 2f64.to_radians();
    let mut s = swung(theta0);
    let h = 1e-3;
    let mut crossings = Vec::new();
    let mut y_prev = s.bodies[0].r.y;
    while crossings.len() < 6 {
        sim.step(&mut s, h).unwrap();
        let y = s.bodies[0].r.y;
        if y_prev > 0.0 && y <= 0.0 {
            crossings.push(s.t - h * y / (y - y_prev));
        }
        y_prev = y;
    }
    let period = (crossings[5] - crossings[0]) / 5.0;
    let t0 = 2.0 * std::f64::consts::PI * (1.01 / G).sqrt();
    let t1 = t0 * (1.0 + theta0 * theta0 / 16.0);
    println!(
        "pendulum period {period:.9} s; small-angle {t0:.9} s (rel. {:.2e}); with θ0²/16 correction {t1:.9} s (rel. {:.2e})",
        period / t0 - 1.0,
        period / t1 - 1.0
    );
    assert!((period / t0 - 1.0).abs() < 2e-4);
    assert!((period / t1 - 1.0).abs() < 1e-6);
}

#[test]
fn pendulum_energy_rk4_over_many_periods() {
    let scene = pendulum();
    let h = 5e-3;
    let period = 2.0 * std::f64::consts::PI * (1.01 / G).sqrt();
    let steps = (50.0 * period / h) as usize;
    for project in [false, true] {
        let mut sim = Simulation::new(&scene, NoLoads, &[], options(Integrator::Rk4, project)).unwrap();
        let mut s = swung(60f64.to_radians());
        let e0 = sim.energy(&s).total();
        let mut worst: f64 = 0.0;
        let mut drift: f64 = 0.0;
        for _ in 0..steps {
            sim.step(&mut s, h).unwrap();
            worst = worst.max((sim.energy(&s).total() - e0).abs());
            drift = drift.max(scene.phi(&s).norm());
        }
        let end = sim.energy(&s).total() - e0;
        println!(
            "pendulum RK4 h = {h}, 50 periods ({steps} steps), projection {project}: energy drift {end:.2e} J \
             (max {worst:.2e}, E scale m g L = {G}), max |Φ| {drift:.2e}"
        );
        assert!(worst < if project { 1e-6 } else { 1e-5 } * G);
        if project {
            assert!(drift < 1e-10);
        }
    }
}

fn run_double(integrator: Integrator, project: bool, h: f64, time: f64) -> (f64, f64, f64) {
    let scene = DoublePendulum;
    let mut sim = Simulation::new(&scene, NoLoads, &[], options(integrator, project)).unwrap();
    let mut s = double_start();
    let e0 = sim.energy(&s).total();
    let (mut worst_e, mut worst_phi, mut worst_v): (f64, f64, f64) = (0.0, 0.0, 0.0);
    let steps = (time / h).round() as usize;
    let mut newton = 0;
    for _ in 0..steps {
        let r = sim.step(&mut s, h).unwrap();
        newton += r.newton_iterations;
        worst_e = worst_e.max((sim.energy(&s).total() - e0).abs());
        worst_phi = worst_phi.max(scene.phi(&s).norm());
        worst_v = worst_v.max((scene.jacobian(&s) * velocity(&s)).norm());
    }
    println!(
        "double pendulum {integrator:?} h = {h}, {time} s, projection {project}: max |ΔE| {worst_e:.2e} J, \
         final ΔE {:.2e} J, max |Φ| {worst_phi:.2e}, max |J v| {worst_v:.2e}, Newton its/step {:.2}",
        sim.energy(&s).total() - e0,
        newton as f64 / steps as f64
    );
    (worst_e, worst_phi, worst_v)
}

fn velocity<const NB: usize, const NV: usize>(s: &SystemState<NB>) -> SVector<f64, NV> {
    let mut v = SVector::<f64, NV>::zeros();
    for (i, b) in s.bodies.iter().enumerate() {
        v.fixed_rows_mut::<3>(6 * i).copy_from(&b.rdot);
        v.fixed_rows_mut::<3>(6 * i + 3).copy_from(&b.omega);
    }
    v
}

#[test]
fn double_pendulum_rk4_with_projection() {
    let (e, phi, v) = run_double(Integrator::Rk4, true, 1e-3, 5.0);
    assert!(e < 1e-6, "energy drift {e}");
    assert!(phi < 1e-10 && v < 1e-10, "constraint drift {phi}, {v}");
    let (e, phi, _) = run_double(Integrator::Rk4, false, 1e-3, 5.0);
    assert!(e < 1e-5 && phi < 1e-6, "{e} {phi}");
}

#[test]
fn double_pendulum_implicit_midpoint_with_projection() {
    let (e, phi, v) = run_double(Integrator::ImplicitMidpoint, true, 2e-3, 5.0);
    assert!(e < 2e-2, "energy drift {e}");
    assert!(phi < 1e-10 && v < 1e-10, "constraint drift {phi}, {v}");
}

/// The generated iteration matrix and the finite-difference one solve the same
/// equations: the same states to the Newton tolerance; the generated one in
/// fewer iterations (it is exact, where differences of step 1e-7 are not).
#[test]
fn implicit_midpoint_generated_matrix_agrees_with_differences() {
    let scene = DoublePendulum;
    let run = |matrix: NewtonMatrix, stabilisation: Stabilisation| {
        let o =
            options(Integrator::ImplicitMidpoint, true).with_newton_matrix(matrix).with_stabilisation(stabilisation);
        let mut sim = Simulation::new(&scene, NoLoads, &[], o).unwrap();
        let mut s = double_start();
        let (mut iterations, mut matrices) = (0, 0);
        for _ in 0..200 {
            let r = sim.step(&mut s, 5e-3).unwrap();
            iterations += r.newton_iterations;
            matrices += r.newton_matrices;
        }
        (s, iterations, matrices)
    };
    for stabilisation in [Stabilisation::None, Stabilisation::Baumgarte { alpha: 10.0, beta: 10.0 }] {
        let (a, ia, ma) = run(NewtonMatrix::Generated, stabilisation);
        let (b, ib, mb) = run(NewtonMatrix::FiniteDifferences, stabilisation);
        println!("{stabilisation:?}: generated {ia} iterations, {ma} matrices; differences {ib}, {mb}");
        for (x, y) in a.bodies.iter().zip(&b.bodies) {
            assert!((x.r - y.r).norm() < 1e-9 && (x.omega - y.omega).norm() < 1e-8, "{x:?} {y:?}");
        }
        assert!(ia <= ib, "generated {ia} iterations against {ib}");
    }
}

#[test]
fn baumgarte_keeps_drift_bounded() {
    let scene = DoublePendulum;
    let mut o = options(Integrator::Rk4, false);
    o.stabilisation = Stabilisation::Baumgarte { alpha: 20.0, beta: 20.0 };
    let mut sim = Simulation::new(&scene, NoLoads, &[], o).unwrap();
    let mut s = double_start();
    s.bodies[1].r.y += 1e-3; // start off the constraint
    for _ in 0..2000 {
        sim.step(&mut s, 1e-3).unwrap();
    }
    println!("Baumgarte α = β = 20: |Φ| after 2 s from 1e-3: {:.2e}", scene.phi(&s).norm());
    assert!(scene.phi(&s).norm() < 1e-6);
}

#[test]
fn stiff_spring_implicit_midpoint_stays_bounded_where_rk4_fails() {
    // A horizontal spring (k = 1e5, rest 0.5) from the bob's bottom point to a
    // ground point: a rotational mode of ω ≈ 630 rad/s; h ω ≈ 6.3.
    let scene = pendulum();
    let springs = [SpringDamper {
        a: Attachment::Body { body: 0, point: Vector3::new(0.0, 0.0, -1.0) },
        b: Attachment::Ground(Vector3::new(0.5, 0.0, -2.0)),
        stiffness: 1e5,
        damping: 0.0,
        rest_length: 0.5,
    }];
    let start = || {
        let mut s = swung(0.0);
        s.bodies[0].omega = Vector3::new(0.0, 0.1, 0.0);
        s.bodies[0].rdot = Vector3::new(-0.1, 0.0, 0.0); // consistent: ω × (r − pivot)
        s
    };
    let h = 1e-2;
    let mut sim = Simulation::new(&scene, NoLoads, &springs, options(Integrator::ImplicitMidpoint, true)).unwrap();
    let mut s = start();
    let e0 = sim.energy(&s).total();
    let mut worst: f64 = 0.0;
    for _ in 0..100 {
        sim.step(&mut s, h).unwrap();
        worst = worst.max((sim.energy(&s).total() - e0).abs());
    }
    println!("stiff spring, implicit midpoint h = {h}: max |ΔE| / E0 = {:.2e}", worst / e0.abs());
    assert!(worst < 1e-2 * e0.abs());

    let mut sim = Simulation::new(&scene, NoLoads, &springs, options(Integrator::Rk4, false)).unwrap();
    let mut s = start();
    let mut blew_up = false;
    for _ in 0..100 {
        match sim.step(&mut s, h) {
            Ok(_) if (sim.energy(&s).total() - e0).abs() < 1e3 * e0.abs() => {}
            _ => {
                blew_up = true;
                break;
            }
        }
    }
    println!("stiff spring, RK4 h = {h}: unstable = {blew_up}");
    assert!(blew_up);
}

#[test]
fn reactions_and_multipliers_of_a_hanging_pendulum() {
    let scene = pendulum();
    let mut sim = Simulation::new(&scene, NoLoads, &[], SimulationOptions::default()).unwrap();
    let s = swung(0.0);
    let d = sim.dynamics(&s).unwrap();
    assert!(d.vdot.norm() < 1e-12);
    let r = sim.reactions(&s, &d.lambda, &Pendulum::BLOCKS[0]);
    println!("hanging pendulum: λ = {:?}, reaction {:?}", d.lambda.as_slice(), r[0]);
    assert!((r[0].force - Vector3::new(0.0, 0.0, G)).norm() < 1e-12);
    assert!(r[0].torque.norm() < 1e-12);
    // User loads through a closure: a horizontal push of 1 N at the centre of mass.
    let push = |_: &SystemState<1>, l: &mut joint_runtime::dynamics::Loads<1>| l.force[0].y += 1.0;
    let mut sim = Simulation::new(&scene, push, &[], SimulationOptions::default()).unwrap();
    let d = sim.dynamics(&s).unwrap();
    // Angular acceleration about x of a physical pendulum pushed at distance 1: 1 / 1.01.
    assert!((d.vdot[3] - 1.0 / 1.01).abs() < 1e-12, "{}", d.vdot);
    // Bad step and bad inertia are errors.
    assert!(sim.step(&mut swung(0.1), f64::NAN).is_err());
    let bad = Pendulum { mass: 0.0 };
    assert!(Simulation::new(&bad, NoLoads, &[], SimulationOptions::default()).is_err());
}

/// A torque given in inertial components lands in the body's own components
/// (`Aᵀ τ`), and a force at a point adds its moment there.
#[test]
fn loads_in_inertial_components() {
    let s = swung(0.7);
    let mut loads = joint_runtime::dynamics::Loads::<1>::default();
    let torque = Vector3::new(1.0, -2.0, 0.5);
    loads.add_torque_inertial(&s, 0, &torque);
    let body = s.bodies[0];
    assert!((body.rotation() * loads.torque[0] - torque).norm() < 1e-15);
    loads.add_torque_inertial(&s, 3, &torque); // no such body: ignored
    assert!((body.rotation() * loads.torque[0] - torque).norm() < 1e-15);
    let mut at_point = joint_runtime::dynamics::Loads::<1>::default();
    let point = Vector3::new(0.0, 0.0, 1.0);
    at_point.add_force_at(&s, 0, &Vector3::x(), &point);
    // The same moment given inertially: (A point) × F.
    let mut moment = joint_runtime::dynamics::Loads::<1>::default();
    moment.add_torque_inertial(&s, 0, &(body.rotation() * point).cross(&Vector3::x()));
    assert!((at_point.torque[0] - moment.torque[0]).norm() < 1e-15);
}

/// The double pendulum's state after `t_end` with `integrator` at step `h`.
fn double_at(integrator: Integrator, matrix: NewtonMatrix, h: f64, t_end: f64) -> (SystemState<2>, usize, usize) {
    let scene = DoublePendulum;
    let o = options(integrator, true).with_newton_matrix(matrix).with_spectral_radius(0.8);
    let mut sim = Simulation::new(&scene, NoLoads, &[], o).unwrap();
    let mut s = double_start();
    let (mut iterations, mut matrices) = (0, 0);
    for _ in 0..(t_end / h).round() as usize {
        let r = sim.step(&mut s, h).unwrap();
        iterations += r.newton_iterations;
        matrices += r.newton_matrices;
    }
    (s, iterations, matrices)
}

fn distance(a: &SystemState<2>, b: &SystemState<2>) -> f64 {
    a.bodies.iter().zip(&b.bodies).map(|(x, y)| (x.r - y.r).norm() + (x.rdot - y.rdot).norm()).fold(0.0, f64::max)
}

/// Generalised-α converges at second order to the RK4 solution of a small
/// step, keeps the constraints, and takes the same steps with the generated
/// K as with K by differences, in no more iterations.
#[test]
fn generalised_alpha_is_second_order_and_keeps_the_constraints() {
    let t_end = 0.5;
    let (reference, _, _) = double_at(Integrator::Rk4, NewtonMatrix::Generated, 1e-4, t_end);
    let errors: Vec<f64> = [4e-3, 2e-3, 1e-3]
        .iter()
        .map(|&h| distance(&double_at(Integrator::GeneralisedAlpha, NewtonMatrix::Generated, h, t_end).0, &reference))
        .collect();
    let orders: Vec<f64> = errors.windows(2).map(|e| (e[0] / e[1]).log2()).collect();
    println!("generalised-α errors {errors:?}, observed orders {orders:?}");
    assert!(orders.iter().all(|&p| (1.8..2.3).contains(&p)), "{orders:?}");
    let (a, ia, ma) = double_at(Integrator::GeneralisedAlpha, NewtonMatrix::Generated, 2e-3, t_end);
    let (b, ib, mb) = double_at(Integrator::GeneralisedAlpha, NewtonMatrix::FiniteDifferences, 2e-3, t_end);
    println!("generated K: {ia} iterations, {ma} matrices; differences: {ib}, {mb}");
    assert!(distance(&a, &b) < 1e-9, "{:e}", distance(&a, &b));
    // No more iterations, up to one in a hundred: each count ends on a
    // tolerance test, and round-off alone moves a step by one iteration
    // either way (summing J W Jᵀ's blocks in another order made it 673
    // against 672 over 250 steps).
    assert!(ia <= ib + ib / 100, "{ia} iterations against {ib}");
    assert!(DoublePendulum.phi(&a).norm() < 1e-10);
}

/// Error-controlled steps: the error at the end follows the tolerance asked
/// in proportion, with fewer steps for looser ones,
/// for the explicit Dormand–Prince pair and the implicit generalised-α.
#[test]
fn integrate_meets_the_tolerance() {
    use joint_runtime::dynamics::{Adaptive, Tolerance};
    let t_end = 0.5;
    let (reference, _, _) = double_at(Integrator::Rk4, NewtonMatrix::Generated, 1e-4, t_end);
    let scene = DoublePendulum;
    // Global error over local tolerance: 2–6 for Dormand–Prince, about 14 for
    // generalised-α (its estimate is of the leading local terms only).
    for (method, tolerances, ratio) in
        [(Adaptive::DormandPrince, [1e-4, 1e-6, 1e-8], 10.0), (Adaptive::GeneralisedAlpha, [1e-4, 1e-5, 1e-6], 30.0)]
    {
        let mut steps = Vec::new();
        for tol in tolerances {
            let mut sim = Simulation::new(&scene, NoLoads, &[], options(Integrator::Rk4, true)).unwrap();
            sim.prepare(Integrator::GeneralisedAlpha).unwrap();
            let mut s = double_start();
            let r = sim.integrate(&mut s, t_end, method, Tolerance { rtol: tol, atol: tol }).unwrap();
            let error = distance(&s, &reference);
            println!("{method:?} tol {tol:e}: error {error:.2e}, {r:?}");
            assert!((s.t - t_end).abs() < 1e-12 && error < ratio * tol, "{error:e}");
            steps.push(r.accepted);
        }
        assert!(steps.windows(2).all(|w| w[0] < w[1]), "{steps:?}");
    }
}

/// Mass properties given at run time that no rigid body has are refused by
/// `new`, naming the body; numbers in the attribute are a compile error.
#[test]
fn unphysical_inertia_at_run_time_is_refused_by_body() {
    #[derive(Scene)]
    #[scene(coordinates = absolute, gravity = [0, 0, -9.81])]
    #[body(rod, mass = mass, inertia = moments)]
    #[joint(pin = spherical(ground, rod), rho1 = [0, 0, 0], rho2 = [0, 0, 1])]
    struct Rod {
        mass: f64,
        moments: Vector3<f64>,
    }
    let options = SimulationOptions::default();
    let new = |mass: f64, moments: [f64; 3]| {
        let rod = Rod { mass, moments: Vector3::from(moments) };
        Simulation::new(&rod, NoLoads, &[], options).err()
    };
    let bad = Some(joint_runtime::analysis::AnalysisError::BadInertia { body: "rod" });
    assert_eq!(new(1.0, [0.01, 0.01, 1.0]), bad);
    assert_eq!(new(0.0, [0.1, 0.1, 0.1]), bad);
    assert_eq!(new(1.0, [0.1, -0.1, 0.1]), bad);
    assert_eq!(new(1.0, [0.5, 0.5, 1.0]), None);
}
