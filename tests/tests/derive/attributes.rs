//! Attribute values a person writes: arithmetic on numbers (folded by the
//! derive) gives exactly the code of the numbers written out; named constants
//! (emitted for the compiler to fold) give the same values within rounding: the
//! derive cannot fold what it cannot read, so products of constants are
//! rounded in another order.

use joint_runtime::nalgebra::Vector3;
use joint_runtime::{Evaluation, Joint, OmegaBody, Scene, TwoBodies};
use joint_tests::random::Rng;
use joint_tests::scenes::hanging_rods;

const RA: f64 = 0.007;

mod consts {
    pub const D: f64 = 0.25;
    pub const G: f64 = 9.81;
}

/// Named constants and arithmetic, in vectors and in a length.
#[derive(Joint)]
#[joint(distance, formulation = omega_body, rho1 = [RA - 0.00092, 0, -consts::D], rho2 = [2.0 * RA, 1.5, -RA], length = 3.0 * consts::D)]
struct Named;

/// Arithmetic on literals only: folded by the derive, as Rust folds `RA - 0.00092`.
#[derive(Joint)]
#[joint(distance, formulation = omega_body, rho1 = [0.007 - 0.00092, 0, -0.25], rho2 = [2.0 * 0.007, 1.5, -0.007], length = 3.0 * 0.25)]
struct Folded;

/// The numbers written out (each one the double Rust's arithmetic gives).
#[derive(Joint)]
#[joint(distance, formulation = omega_body, rho1 = [0.00608, 0, -0.25], rho2 = [0.014, 1.5, -0.007], length = 0.75)]
struct Literal;

fn flat<const R: usize, const C: usize>(e: &Evaluation<f64, R, C>) -> Vec<u64> {
    e.phi.iter().chain(e.jacobian.iter()).chain(e.gamma.iter()).map(|x| x.to_bits()).collect()
}

/// Every output within `256 ε` of the largest in its evaluation: the
/// conformance rule, as γ sums terms far larger than itself (ω² |ρ| |d|),
/// whose rounding in another order shows at a few ε of those terms.
#[track_caller]
fn close<const R: usize, const C: usize>(got: &Evaluation<f64, R, C>, want: &Evaluation<f64, R, C>) {
    let all =
        |e: &Evaluation<f64, R, C>| -> Vec<f64> { e.phi.iter().chain(&e.jacobian).chain(&e.gamma).copied().collect() };
    let (got, want) = (all(got), all(want));
    let scale = want.iter().fold(1.0f64, |m, x| m.max(x.abs()));
    for (g, w) in got.iter().zip(&want) {
        assert!((g - w).abs() <= 256.0 * f64::EPSILON * scale, "{g:e} against {w:e} (scale {scale:e})");
    }
}

#[test]
fn a_joint_with_named_constants_is_the_joint_with_their_values() {
    assert_eq!(RA - 0.00092, 0.00608, "the literal stands for Rust's difference");
    let mut rng = Rng(11);
    for _ in 0..50 {
        let state = TwoBodies { body1: rng.omega_body(), body2: rng.omega_body(), t: 0.0 };
        let want = Joint::<f64, 1, 12>::evaluate(&Literal, &state);
        close(&Joint::<f64, 1, 12>::evaluate(&Named, &state), &want);
        assert_eq!(flat(&Joint::<f64, 1, 12>::evaluate(&Folded, &state)), flat(&want));
    }
}

#[test]
fn a_joint_with_named_constants_reads_them_in_any_scalar() {
    let mut rng = Rng(12);
    let b = |rng: &mut Rng| {
        let b = rng.omega_body();
        OmegaBody { r: b.r.cast::<f32>(), p: b.p.cast(), rdot: b.rdot.cast(), omega: b.omega.cast() }
    };
    let state = TwoBodies { body1: b(&mut rng), body2: b(&mut rng), t: 0.0 };
    let (named, literal) = (Joint::<f32, 1, 12>::phi(&Named, &state), Joint::<f32, 1, 12>::phi(&Literal, &state));
    assert!((named[0] - literal[0]).abs() <= 8.0 * f32::EPSILON * literal[0].abs().max(1.0), "{named} {literal}");
}

/// A pendulum whose data are named constants.
#[derive(Scene)]
#[scene(coordinates = absolute, gravity = [0, 0, -consts::G])]
#[body(rod, mass = 2.0 * RA, inertia = [RA, RA, consts::D / 40.0])]
#[joint(hinge = revolute(ground, rod), axis1 = [1, 0, 0], axis2 = [1, 0, 0], rho1 = [0, 0, 0], rho2 = [0, 0, consts::D + 0.25])]
struct NamedPendulum;

/// The same pendulum with the numbers written out.
#[derive(Scene)]
#[scene(coordinates = absolute, gravity = [0, 0, -9.81])]
#[body(rod, mass = 0.014, inertia = [0.007, 0.007, 0.00625])]
#[joint(hinge = revolute(ground, rod), axis1 = [1, 0, 0], axis2 = [1, 0, 0], rho1 = [0, 0, 0], rho2 = [0, 0, 0.5])]
struct LiteralPendulum;

#[test]
fn a_scene_with_named_constants_is_the_scene_with_their_values() {
    let state: NamedPendulumState = hanging_rods([0.3]);
    close(&NamedPendulum.evaluate(&state), &LiteralPendulum.evaluate(&state));
    assert_eq!(NamedPendulum.gravity(), Vector3::new(0.0, 0.0, -9.81));
    let (named, literal) = (NamedPendulum.inertias()[0], LiteralPendulum.inertias()[0]);
    assert_eq!((named.mass, named.inertia), (literal.mass, literal.inertia));
    let mut points = Vec::new();
    NamedPendulum.joint_points(&mut |p| points.push(p.point));
    assert_eq!(points, [Vector3::zeros(), Vector3::new(0.0, 0.0, 0.5)]);
}

/// A box of principal moments (1, 3, 3.5) turned 45° about z: its tensor in
/// the body's axes has `ixx = iyy = 2` and the entry `ixy = (1 − 3)/2 = −1`
/// (`−∫ x y dm`: the box's long extent along (1, 1, 0)/√2 puts positive
/// `x y` mass there). Six entries are the tensor's, in that order.
#[derive(Scene)]
#[scene(coordinates = absolute, gravity = [0, 0, -9.81])]
#[body(turned, mass = 2.0, inertia = [2, 2, 3.5, -1, 0, 0])]
#[joint(pin = spherical(ground, turned), rho1 = [0, 0, 0], rho2 = [0, 0, 1])]
struct TurnedBox;

#[test]
fn six_inertia_entries_are_the_tensors_with_ixy_second_to_last_three() {
    let body = TurnedBox.inertias()[0];
    assert_eq!(body.principal_moments(), [1.0, 3.0, 3.5]);
    // The smallest moment's axis: (1, 1, 0)/√2, where the box is long.
    let long = Vector3::new(1.0, 1.0, 0.0) / 2f64.sqrt();
    assert!((body.inertia * long - long).norm() < 1e-15);
    let across = Vector3::new(1.0, -1.0, 0.0) / 2f64.sqrt();
    assert!((body.inertia * across - across * 3.0).norm() < 1e-15);
    assert!(body.is_physical());
}
