//! The one `Simulation`: the same constructor, state conversions, energy
//! and step report whichever coordinates a scene declares, against the
//! other coordinate choice and the closure rows themselves.

use joint_runtime::dynamics::{
    Attachment, Integrator, Loads, NoLoads, Simulation, SimulationOptions, SpringDamper, Stabilisation,
};
use joint_runtime::nalgebra::{SVector, Vector3};
use joint_runtime::relative::{TreeError, TreeSimulation, TreeState};

use super::loops::Spatial;
use joint_runtime::{Scene, SystemState};

/// A four-bar whose coupler is pushed sideways and pulled by a spring to the
/// ground: declared once per coordinate choice (the same attributes).
macro_rules! four_bar {
    ($name:ident, $($coordinates:tt)*) => {
        #[derive(Scene, Clone, Copy, Debug, Default)]
        #[scene(gravity = [0, -9.81, 0] $($coordinates)*)]
        #[body(crank, mass = 1.0, inertia = [0.1, 0.1, 0.1])]
        #[body(coupler, mass = 1.5, inertia = [0.1, 0.15, 0.2])]
        #[body(rocker, mass = 2.0, inertia = [0.2, 0.1, 0.2])]
        #[joint(a = revolute(ground, crank), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0, 0, 0], rho2 = [0, -0.5, 0])]
        #[joint(b = revolute(crank, coupler), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0, 0.5, 0], rho2 = [-0.5, 0, 0])]
        #[joint(c = revolute(coupler, rocker), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0.5, 0, 0], rho2 = [0, 0.5, 0])]
        #[joint(d = revolute(rocker, ground), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0, -0.5, 0], rho2 = [1, 0, 0])]
        struct $name;
    };
}
four_bar!(Absolute, , coordinates = absolute);
four_bar!(Relative, , coordinates = relative);
four_bar!(Undeclared,);

/// The spatial loop closed near a guess (the arm turned 0.5 rad, the link
/// back 1.2 rad about z, the lever 0.3 rad), the arm turning at 2 rad/s.
fn spatial_start() -> TreeState<6, 5> {
    let r = TreeSimulation::new(&Spatial).unwrap();
    let (c, s) = (0.6_f64.cos(), -(0.6_f64.sin()));
    let guess =
        TreeState { q: SVector::from([0.5, c, 0.0, 0.0, s, 0.3]), v: SVector::from([2.0, 0.0, 0.0, 0.0, 0.0]), t: 0.0 };
    r.assemble(&guess).unwrap()
}

const SPRING: [SpringDamper; 1] = [SpringDamper {
    a: Attachment::Ground(Vector3::new(0.5, 2.0, 0.0)),
    b: Attachment::Body { body: 1, point: Vector3::new(0.2, 0.0, 0.0) },
    stiffness: 40.0,
    damping: 0.5,
    rest_length: 0.8,
}];

/// A sideways push on the coupler that grows with its height.
fn push(state: &SystemState<3>, loads: &mut Loads<3>) {
    loads.force[1] = Vector3::new(3.0 * state.bodies[1].r.y, 0.0, 0.0);
}

/// The parallelogram at crank angle `theta`, crank turning at `rate`.
fn start(theta: f64, rate: f64) -> TreeState<3, 3> {
    TreeState { q: SVector::from([theta, -theta, theta]), v: SVector::from([rate, -rate, rate]), t: 0.0 }
}

/// A scene that says nothing of coordinates runs on the tree: its one
/// `Simulation` is the relative engine (the type says so) and steps as the
/// scene that asks for relative coordinates does, to the bit; the absolute
/// engine agrees to RK4's error.
#[test]
fn a_scene_that_does_not_choose_runs_on_the_tree() {
    let options = SimulationOptions::default();
    let mut undeclared: TreeSimulation<'_, Undeclared, 3, 3, 3, 2, _> =
        Simulation::new(&Undeclared, push, &SPRING, options).unwrap().into_engine();
    let mut relative = Simulation::new(&Relative, push, &SPRING, options).unwrap();
    let mut absolute = Simulation::new(&Absolute, push, &SPRING, options).unwrap();
    let (mut su, mut sr) = (start(0.4, 1.5), start(0.4, 1.5));
    let mut sa = absolute.state_of(&relative.system_state(&sr)).unwrap();
    for _ in 0..500 {
        undeclared.step(&mut su, 1e-3).unwrap();
        relative.step(&mut sr, 1e-3).unwrap();
        absolute.step(&mut sa, 1e-3).unwrap();
    }
    assert_eq!(su, sr);
    let (bu, ba) = (undeclared.system_state(&su), absolute.system_state(&sa));
    for (u, a) in bu.bodies.iter().zip(&ba.bodies) {
        assert!((u.r - a.r).norm() < 1e-9, "{} {}", u.r, a.r);
    }
}

/// One constructor for both choices; a start built as bodies converts to
/// each engine's state; 0.5 s under gravity, the spring and the push gives
/// the same bodies' motion and the same energy.
#[test]
fn both_choices_through_one_constructor() {
    let options = SimulationOptions::default();
    let mut a = Simulation::new(&Absolute, push, &SPRING, options).unwrap();
    let mut r = Simulation::new(&Relative, push, &SPRING, options).unwrap();
    let bodies = r.system_state(&start(0.4, 1.5));
    let (mut sa, mut sr) = (a.state_of(&bodies).unwrap(), r.state_of(&bodies).unwrap());
    let (ea, er) = (a.energy(&sa), r.energy(&sr));
    assert!((ea.total() - er.total()).abs() < 1e-12 * ea.total().abs(), "{ea:?} {er:?}");
    assert!(er.elastic > 1.0, "the spring is stretched: {}", er.elastic);
    // The tree's own kinetic energy (spatial inertias at the joints) is an
    // independent sum of the same number.
    let tree_kinetic = r.tree().energy(&sr).kinetic;
    assert!((er.kinetic - tree_kinetic).abs() < 1e-12 * tree_kinetic, "{} {tree_kinetic}", er.kinetic);
    for _ in 0..500 {
        a.step(&mut sa, 1e-3).unwrap();
        r.step(&mut sr, 1e-3).unwrap();
    }
    let sr_bodies = r.system_state(&sr);
    for i in 0..3 {
        let gap =
            (sa.bodies[i].r - sr_bodies.bodies[i].r).norm() + (sa.bodies[i].rdot - sr_bodies.bodies[i].rdot).norm();
        assert!(gap < 1e-9, "body {i}: {gap:e}");
    }
    assert!((sa.bodies[1].r - a.system_state(&sa).bodies[1].r).norm() == 0.0);
}

/// The relative engine's step report: `‖Φ‖₂` and `‖J v + Φ_t‖₂` are the
/// closure rows' at the state it returns.
#[test]
fn step_report_is_the_closure_rows_at_the_end() {
    let mut r = TreeSimulation::new(&Spatial).unwrap();
    let mut s = spatial_start();
    let mut iterations = 0;
    for _ in 0..50 {
        let report = r.step(&mut s, 2e-2).unwrap();
        let rows = r.closure_rows(&s);
        assert!((report.constraint_residual - rows.phi.norm()).abs() < 1e-15);
        assert!((report.velocity_residual - (rows.jacobian * s.v + rows.phi_t).norm()).abs() < 1e-14);
        assert!(report.constraint_residual < 1e-12 && report.velocity_residual < 1e-12, "{report:?}");
        iterations += report.projection_iterations;
    }
    assert!(iterations > 0, "steps of 20 ms leave the loop open before the projection");
}

/// Without projection the spatial loop drifts open; Baumgarte's terms on
/// the closure rows hold it an order of magnitude closer over the same steps.
#[test]
fn projection_off_and_baumgarte() {
    let start = spatial_start();
    let drift = |stabilisation| {
        let options = SimulationOptions::default().with_projection(None).with_stabilisation(stabilisation);
        let mut r = TreeSimulation::new(&Spatial).unwrap().with_options(options).unwrap();
        let mut s = start;
        for _ in 0..100 {
            let report = r.step(&mut s, 2e-2).unwrap();
            assert_eq!(report.projection_iterations, 0);
        }
        r.closure_rows(&s).phi.amax()
    };
    let plain = drift(Stabilisation::None);
    let held = drift(Stabilisation::Baumgarte { alpha: 20.0, beta: 20.0 });
    assert!(plain > 1e-8, "RK4 at 20 ms drifts: {plain:e}");
    assert!(held < plain / 10.0, "Baumgarte {held:e} against {plain:e}");
}

/// Options out of range are refused by name, never replaced.
#[test]
fn options_the_tree_does_not_offer() {
    let bad = |options: SimulationOptions| match Simulation::new(&Relative, NoLoads, &[], options) {
        Err(TreeError::BadOption { name }) => name,
        other => panic!("{:?}", other.map(|_| ())),
    };
    let default = SimulationOptions::default();
    // Every integrator it runs.
    for integrator in [Integrator::ImplicitMidpoint, Integrator::GeneralisedAlpha, Integrator::RadauIIA] {
        assert!(Simulation::new(&Relative, NoLoads, &[], default.with_integrator(integrator)).is_ok());
    }
    let alpha = default.with_integrator(Integrator::GeneralisedAlpha);
    assert_eq!(bad(alpha.with_spectral_radius(1.5)), "spectral_radius");
    assert_eq!(bad(default.with_stabilisation(Stabilisation::Baumgarte { alpha: -1.0, beta: 1.0 })), "stabilisation");
    assert_eq!(bad(default.with_rank_tolerance(f64::NAN)), "rank_tolerance");
    assert_eq!(bad(default.with_newton_tolerance(0.0)), "newton_tolerance");
    let mut loose = default;
    loose.projection.as_mut().unwrap().tolerance = 0.0;
    assert_eq!(bad(loose), "projection");
    // The absolute engine runs them all.
    assert!(Simulation::new(&Absolute, NoLoads, &[], default.with_integrator(Integrator::RadauIIA)).is_ok());
}

/// A start off its joints is reported by the joint's name, not moved: a
/// crank 1 cm off its hinge, and a loop open by 0.1 rad at the rocker.
#[test]
fn a_start_off_its_joints_is_refused() {
    let r = Simulation::new(&Relative, NoLoads, &[], SimulationOptions::default()).unwrap();
    let mut off = r.system_state(&start(0.4, 0.0));
    off.bodies[0].r.x += 0.01;
    match r.state_of(&off) {
        Err(TreeError::NotOnJoint { joint, misfit }) => {
            assert_eq!(joint, "a");
            assert!((misfit - 0.01).abs() < 1e-12, "{misfit}");
        }
        other => panic!("{other:?}"),
    }
    let mut open = start(0.4, 0.0);
    open.q[2] += 0.1;
    match r.state_of(&r.system_state(&open)) {
        Err(TreeError::NotAssembled { joint, misfit }) => assert!(joint == "d" && misfit > 0.01, "{joint} {misfit}"),
        other => panic!("{other:?}"),
    }
}
