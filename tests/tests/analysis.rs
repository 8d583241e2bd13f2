//! Kinematic analyses (`joint_runtime::analysis`) on hand-stacked scenes: assembly
//! of a spherical pendulum chain, a duplicated joint, bad inputs, an impossible
//! configuration, and velocity/acceleration analysis of a driven pendulum.

#![allow(missing_docs)]

use std::marker::PhantomData;

use joint_runtime::analysis::{AnalysisError, AssemblyOptions, accelerations, assemble, velocities};
use joint_runtime::nalgebra::{SVector, UnitQuaternion, Vector3};
use joint_runtime::{
    BodyInertia, Evaluation, Joint, OmegaBody, OneBody, Ops, RowBlock, Scene, Sinusoid, SystemState, TwoBodies,
};

// --- A hand-written `Scene`: joints stacked by hand into the system matrices. ---

#[derive(Joint)]
#[joint(spherical, formulation = omega_body, ground = body1)]
struct GroundBall<T> {
    rho1: Vector3<T>,
    rho2: Vector3<T>,
}

#[derive(Joint)]
#[joint(spherical, formulation = omega_body)]
struct Ball<T> {
    rho1: Vector3<T>,
    rho2: Vector3<T>,
}

#[derive(Joint)]
#[joint(revolute, formulation = omega_body, ground = body1, f = [1, 0, 0], g = [0, 1, 0], h = [0, 0, 1])]
struct GroundHinge<T> {
    rho1: Vector3<T>,
    rho2: Vector3<T>,
}

#[derive(Joint)]
#[joint(rotational_driver, formulation = omega_body, ground = body1, f = [1, 0, 0], g = [0, 1, 0], k = [1, 0, 0])]
struct Motor<F> {
    theta: F,
}

type Eval<const M: usize, const NV: usize> = Evaluation<f64, M, NV>;

trait Part<const NB: usize, const NV: usize, const M: usize> {
    fn add(&self, s: &SystemState<NB>, start: usize, out: &mut Eval<M, NV>, phi_t: &mut SVector<f64, M>);
}

/// A joint with `ground = body1` on body `body`.
struct Grounded<J, const R: usize>(J, usize);
/// A joint between bodies `.1` and `.2`.
struct Between<J, const R: usize>(J, usize, usize);

impl<J, const R: usize, const NB: usize, const NV: usize, const M: usize> Part<NB, NV, M> for Grounded<J, R>
where
    J: Joint<f64, R, 6, State = OneBody<OmegaBody<f64>>>,
{
    fn add(&self, s: &SystemState<NB>, start: usize, out: &mut Eval<M, NV>, phi_t: &mut SVector<f64, M>) {
        let st = OneBody { body: s.bodies[self.1], t: s.t };
        let e = self.0.evaluate(&st);
        let pt = self.0.phi_t(&st);
        for r in 0..R {
            out.phi[start + r] = e.phi[r];
            out.gamma[start + r] = e.gamma[r];
            phi_t[start + r] = pt[r];
            for c in 0..6 {
                out.jacobian[(start + r, 6 * self.1 + c)] = e.jacobian[(r, c)];
            }
        }
    }
}

impl<J, const R: usize, const NB: usize, const NV: usize, const M: usize> Part<NB, NV, M> for Between<J, R>
where
    J: Joint<f64, R, 12, State = TwoBodies<OmegaBody<f64>>>,
{
    fn add(&self, s: &SystemState<NB>, start: usize, out: &mut Eval<M, NV>, phi_t: &mut SVector<f64, M>) {
        let st = TwoBodies { body1: s.bodies[self.1], body2: s.bodies[self.2], t: s.t };
        let e = self.0.evaluate(&st);
        let pt = self.0.phi_t(&st);
        for r in 0..R {
            out.phi[start + r] = e.phi[r];
            out.gamma[start + r] = e.gamma[r];
            phi_t[start + r] = pt[r];
            for c in 0..6 {
                out.jacobian[(start + r, 6 * self.1 + c)] = e.jacobian[(r, c)];
                out.jacobian[(start + r, 6 * self.2 + c)] = e.jacobian[(r, 6 + c)];
            }
        }
    }
}

/// Names of a hand-written scene.
trait Layout<const NB: usize> {
    const BODIES: [&'static str; NB];
    const BLOCKS: &'static [RowBlock];
}

struct Hand<L, const NB: usize, const NV: usize, const M: usize> {
    parts: Vec<Box<dyn Part<NB, NV, M>>>,
    inertias: [BodyInertia; NB],
    gravity: Vector3<f64>,
    layout: PhantomData<L>,
}

impl<L: Layout<NB>, const NB: usize, const NV: usize, const M: usize> Hand<L, NB, NV, M> {
    fn all(&self, s: &SystemState<NB>) -> (Eval<M, NV>, SVector<f64, M>) {
        let mut out = Evaluation {
            phi: SVector::zeros(),
            jacobian: joint_runtime::nalgebra::SMatrix::zeros(),
            gamma: SVector::zeros(),
        };
        let mut phi_t = SVector::zeros();
        for (part, block) in self.parts.iter().zip(L::BLOCKS) {
            part.add(s, block.start, &mut out, &mut phi_t);
        }
        (out, phi_t)
    }
}

impl<L: Layout<NB>, const NB: usize, const NV: usize, const M: usize> Scene<NB, NV, M> for Hand<L, NB, NV, M> {
    const BODIES: [&'static str; NB] = L::BODIES;
    const BLOCKS: &'static [RowBlock] = L::BLOCKS;
    const OPS: Ops = Ops { phi: 0, phi_t: 0, jacobian: 0, gamma: 0, evaluate: 0 };
    fn phi(&self, s: &SystemState<NB>) -> SVector<f64, M> {
        self.all(s).0.phi
    }
    fn phi_t(&self, s: &SystemState<NB>) -> SVector<f64, M> {
        self.all(s).1
    }
    fn jacobian(&self, s: &SystemState<NB>) -> joint_runtime::nalgebra::SMatrix<f64, M, NV> {
        self.all(s).0.jacobian
    }
    fn gamma(&self, s: &SystemState<NB>) -> SVector<f64, M> {
        self.all(s).0.gamma
    }
    fn evaluate(&self, s: &SystemState<NB>) -> Eval<M, NV> {
        self.all(s).0
    }
    fn inertias(&self) -> [BodyInertia; NB] {
        self.inertias
    }
    fn gravity(&self) -> Vector3<f64> {
        self.gravity
    }
}

const fn block(name: &'static str, start: usize, rows: usize) -> RowBlock {
    RowBlock { name, start, rows }
}

// --- Scenes. ---

/// Three rods of length 1 hanging from the origin along −z, ball joints between.
struct ChainLayout;
impl Layout<3> for ChainLayout {
    const BODIES: [&'static str; 3] = ["link0", "link1", "link2"];
    const BLOCKS: &'static [RowBlock] = &[block("ground", 0, 3), block("ball01", 3, 3), block("ball12", 6, 3)];
}

/// The chain with the ground joint declared twice.
struct DuplicateLayout;
impl Layout<3> for DuplicateLayout {
    const BODIES: [&'static str; 3] = ["link0", "link1", "link2"];
    const BLOCKS: &'static [RowBlock] =
        &[block("ground", 0, 3), block("ball01", 3, 3), block("ball12", 6, 3), block("ground_again", 9, 3)];
}

fn up() -> Vector3<f64> {
    Vector3::new(0.0, 0.0, 0.5)
}

fn rod() -> BodyInertia {
    BodyInertia::principal(1.0, Vector3::new(1.0 / 12.0, 1.0 / 12.0, 1e-3))
}

fn chain_parts<const M: usize>() -> Vec<Box<dyn Part<3, 18, M>>> {
    vec![
        Box::new(Grounded::<_, 3>(GroundBall { rho1: Vector3::zeros(), rho2: up() }, 0)),
        Box::new(Between::<_, 3>(Ball { rho1: -up(), rho2: up() }, 0, 1)),
        Box::new(Between::<_, 3>(Ball { rho1: -up(), rho2: up() }, 1, 2)),
    ]
}

fn chain() -> Hand<ChainLayout, 3, 18, 9> {
    Hand { parts: chain_parts(), inertias: [rod(); 3], gravity: Vector3::new(0.0, 0.0, -9.81), layout: PhantomData }
}

fn duplicated_chain() -> Hand<DuplicateLayout, 3, 18, 12> {
    let mut parts = chain_parts::<12>();
    parts.push(Box::new(Grounded::<_, 3>(GroundBall { rho1: Vector3::zeros(), rho2: up() }, 0)));
    Hand { parts, inertias: [rod(); 3], gravity: Vector3::new(0.0, 0.0, -9.81), layout: PhantomData }
}

/// The assembled chain, bent: link i turned by `angles[i]` about x.
fn bent_chain(angles: [f64; 3]) -> SystemState<3> {
    let mut joint = Vector3::zeros();
    let bodies = angles.map(|a| {
        let q = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), a);
        let r = joint - q * up();
        joint = r - q * up();
        OmegaBody::from_rotation(r, &q, Vector3::zeros(), Vector3::zeros())
    });
    SystemState { bodies, t: 0.0 }
}

/// Each body turned a further 5° about its own axis `axes[i]` (positions kept).
fn perturb(s: &mut SystemState<3>) {
    let axes = [Vector3::new(1.0, 2.0, 0.5), Vector3::new(-0.3, 1.0, 1.0), Vector3::new(0.7, -0.2, 1.0)];
    for (b, axis) in s.bodies.iter_mut().zip(axes) {
        let q0 =
            UnitQuaternion::from_quaternion(joint_runtime::nalgebra::Quaternion::new(b.p[0], b.p[1], b.p[2], b.p[3]));
        let dq =
            UnitQuaternion::from_axis_angle(&joint_runtime::nalgebra::Unit::new_normalize(axis), 5f64.to_radians());
        let q = q0 * dq;
        b.p = joint_runtime::nalgebra::Vector4::new(q.w, q.i, q.j, q.k);
    }
}

#[test]
fn chain_assembles_from_a_five_degree_perturbation() {
    let scene = chain();
    let mut s = bent_chain([0.3, -0.2, 0.5]);
    assert!(scene.phi(&s).norm() < 1e-15);
    perturb(&mut s);
    let before = scene.phi(&s).norm();
    let a = assemble(&scene, &mut s, &AssemblyOptions::default()).unwrap();
    println!("chain: |Φ| {before:.3e} → {:.3e} in {} iterations", a.residual, a.iterations);
    assert!(a.iterations <= 6, "{} iterations", a.iterations);
    assert!(a.residual <= 1e-12 && scene.phi(&s).norm() <= 1e-12);
    assert!(a.redundant.is_empty());
    for b in &s.bodies {
        assert!((b.p.norm() - 1.0).abs() < 1e-14);
    }
    // Already assembled: no iteration.
    assert_eq!(assemble(&scene, &mut s, &AssemblyOptions::default()).unwrap().iterations, 0);
}

#[test]
fn chain_assembles_from_a_rough_guess() {
    // Every body at the origin, unit orientation except a non-unit p: far from assembled.
    let scene = chain();
    let mut s = bent_chain([0.0; 3]);
    for (i, b) in s.bodies.iter_mut().enumerate() {
        b.r = Vector3::new(0.3 * i as f64, -0.2, -0.4 * i as f64);
        b.p = joint_runtime::nalgebra::Vector4::new(2.0, 0.1 * i as f64, 0.2, 0.0);
    }
    let a = assemble(&scene, &mut s, &AssemblyOptions::default()).unwrap();
    println!("chain from a rough guess: {} iterations, |Φ| = {:.3e}", a.iterations, a.residual);
    assert!(scene.phi(&s).norm() <= 1e-12);
}

#[test]
fn duplicated_joint_is_reported_redundant() {
    let scene = duplicated_chain();
    let mut s = bent_chain([0.3, -0.2, 0.5]);
    perturb(&mut s);
    let a = assemble(&scene, &mut s, &AssemblyOptions::default()).unwrap();
    println!("duplicated joint: {} iterations, redundant rows: {}", a.iterations, a.redundant);
    assert!(a.residual <= 1e-12);
    assert_eq!(a.redundant.len(), 3);
    for r in a.redundant.as_slice() {
        assert!(r.joint == "ground" || r.joint == "ground_again", "{r}");
    }
    // Velocity and acceleration analysis report them the same way.
    let v = velocities(&scene, &mut s).unwrap();
    assert_eq!(v.redundant.len(), 3);
    let acc = accelerations(&scene, &s).unwrap();
    assert_eq!(acc.redundant, v.redundant);
}

#[test]
fn non_finite_input_names_body_and_field() {
    let scene = chain();
    let mut s = bent_chain([0.3, -0.2, 0.5]);
    s.bodies[1].p[2] = f64::NAN;
    let e = assemble(&scene, &mut s, &AssemblyOptions::default()).unwrap_err();
    assert_eq!(e, AnalysisError::NonFinite { body: Some("link1"), field: "p" });
    let msg = e.to_string();
    println!("{msg}");
    assert!(msg.contains("`p`") && msg.contains("`link1`"));

    let mut s = bent_chain([0.3, -0.2, 0.5]);
    s.bodies[2].r.x = f64::INFINITY;
    assert_eq!(
        assemble(&scene, &mut s, &AssemblyOptions::default()).unwrap_err(),
        AnalysisError::NonFinite { body: Some("link2"), field: "r" }
    );
    let mut s = bent_chain([0.3, -0.2, 0.5]);
    s.bodies[0].omega.y = f64::NAN;
    assert_eq!(
        accelerations(&scene, &s).unwrap_err(),
        AnalysisError::NonFinite { body: Some("link0"), field: "omega" }
    );
    let mut s = bent_chain([0.3, -0.2, 0.5]);
    s.t = f64::NAN;
    assert_eq!(velocities(&scene, &mut s).unwrap_err(), AnalysisError::NonFinite { body: None, field: "t" });
    let mut s = bent_chain([0.3, -0.2, 0.5]);
    s.bodies[0].p = joint_runtime::nalgebra::Vector4::zeros();
    assert_eq!(
        assemble(&scene, &mut s, &AssemblyOptions::default()).unwrap_err(),
        AnalysisError::ZeroQuaternion { body: "link0" }
    );
}

/// One rod (length 1) whose top is held at the origin and whose bottom is held 5 m
/// below it: impossible.
struct StretchedLayout;
impl Layout<1> for StretchedLayout {
    const BODIES: [&'static str; 1] = ["rod"];
    const BLOCKS: &'static [RowBlock] = &[block("top", 0, 3), block("bottom", 3, 3)];
}

#[test]
fn impossible_configuration_is_a_clear_error() {
    let scene: Hand<StretchedLayout, 1, 6, 6> = Hand {
        parts: vec![
            Box::new(Grounded::<_, 3>(GroundBall { rho1: Vector3::zeros(), rho2: up() }, 0)),
            Box::new(Grounded::<_, 3>(GroundBall { rho1: Vector3::new(0.0, 0.0, -5.0), rho2: -up() }, 0)),
        ],
        inertias: [rod()],
        gravity: Vector3::zeros(),
        layout: PhantomData,
    };
    let mut s = SystemState {
        bodies: [OmegaBody::from_rotation(
            Vector3::new(0.1, 0.0, -0.5),
            &UnitQuaternion::identity(),
            Vector3::zeros(),
            Vector3::zeros(),
        )],
        t: 0.0,
    };
    let e = assemble(&scene, &mut s, &AssemblyOptions::default()).unwrap_err();
    let msg = e.to_string();
    println!("{msg}");
    match e {
        AnalysisError::NoProgress { residual, worst, .. } | AnalysisError::NotConverged { residual, worst, .. } => {
            assert!(residual > 1.0);
            let w = worst.0[0].unwrap();
            assert!(w.row.joint == "top" || w.row.joint == "bottom");
        }
        other => panic!("unexpected {other:?}"),
    }
    assert!(msg.contains("top") || msg.contains("bottom"));

    // Too few iterations is `NotConverged`, naming the worst rows.
    let scene = chain();
    let mut s = bent_chain([0.3, -0.2, 0.5]);
    perturb(&mut s);
    let e = assemble(&scene, &mut s, &AssemblyOptions { max_iterations: 1, ..AssemblyOptions::default() }).unwrap_err();
    println!("{e}");
    assert!(matches!(e, AnalysisError::NotConverged { iterations: 1, .. }));
}

/// A pendulum on a hinge about the ground z axis, driven to the angle θ(t): no
/// degree of freedom left. The centre of mass is 1 m from the hinge along body x.
struct DrivenLayout;
impl Layout<1> for DrivenLayout {
    const BODIES: [&'static str; 1] = ["crank"];
    const BLOCKS: &'static [RowBlock] = &[block("hinge", 0, 5), block("motor", 5, 1)];
}

#[test]
fn driven_pendulum_velocities_and_accelerations_match_closed_form() {
    let drive = Sinusoid { offset: 0.2, amplitude: 0.5, frequency: 2.0, phase: 0.3 };
    let scene: Hand<DrivenLayout, 1, 6, 6> = Hand {
        parts: vec![
            Box::new(Grounded::<_, 5>(GroundHinge { rho1: Vector3::zeros(), rho2: Vector3::new(-1.0, 0.0, 0.0) }, 0)),
            Box::new(Grounded::<_, 1>(Motor { theta: drive }, 0)),
        ],
        inertias: [rod()],
        gravity: Vector3::zeros(),
        layout: PhantomData,
    };
    for t in [0.0, 0.4, 1.1, 2.5] {
        let d = joint_runtime::TimeFunction::eval(&drive, t);
        let (th, w, al) = (d.value, d.rate, d.accel);
        // Start 4° off, slightly displaced.
        let q = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), th + 4f64.to_radians());
        let mut s = SystemState {
            bodies: [OmegaBody::from_rotation(Vector3::new(0.9, 0.1, 0.02), &q, Vector3::zeros(), Vector3::zeros())],
            t,
        };
        let a = assemble(&scene, &mut s, &AssemblyOptions::default()).unwrap();
        let (c, sn) = (th.cos(), th.sin());
        let b = s.bodies[0];
        assert!((b.r - Vector3::new(c, sn, 0.0)).norm() < 1e-12, "t = {t}: r = {}", b.r);
        velocities(&scene, &mut s).unwrap();
        let b = s.bodies[0];
        let rdot = Vector3::new(-sn, c, 0.0) * w;
        assert!((b.rdot - rdot).norm() < 1e-12, "ṙ {} vs {}", b.rdot, rdot);
        assert!((b.omega - Vector3::new(0.0, 0.0, w)).norm() < 1e-12);
        let acc = accelerations(&scene, &s).unwrap();
        let rddot = Vector3::new(-sn, c, 0.0) * al - Vector3::new(c, sn, 0.0) * (w * w);
        let got = acc.vdot.fixed_rows::<3>(0).into_owned();
        assert!((got - rddot).norm() < 1e-11, "r̈ {got} vs {rddot}");
        assert!((acc.vdot.fixed_rows::<3>(3) - Vector3::new(0.0, 0.0, al)).norm() < 1e-11);
        assert!(acc.redundant.is_empty());
        println!(
            "driven pendulum t = {t}: assembled in {} its; |ṙ err| = {:.1e}, |r̈ err| = {:.1e}",
            a.iterations,
            (b.rdot - rdot).norm(),
            (got - rddot).norm()
        );
    }
}
