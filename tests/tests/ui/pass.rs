use joint_runtime::nalgebra::{Scalar, Vector3};
use joint_runtime::{Joint, SlidingFrame};

/// The declaration of the brief: `rho2` from a field with another name.
#[derive(Joint)]
#[joint(universal, formulation = omega_body, s = [0, 0, 1])]
struct Cardan<T> {
    h: Vector3<T>,
    rho1: Vector3<T>,
    #[joint(rho2)]
    point: Vector3<T>,
}

/// Every parameter constant (arithmetic on numbers folded), grounded body 1, a
/// field that is not a parameter.
#[derive(Joint)]
#[joint(spherical, formulation = euler, ground = body1, rho1 = [0, 0, 2.0 * (0.125 + 0.125)], rho2 = [-1.0 / 1.0, 0, 0])]
struct Ball<T> {
    #[joint(skip)]
    label: &'static str,
    #[joint(skip)]
    mass: T,
}

/// The sliding direction from a run-time `SlidingFrame` field.
#[derive(Joint)]
#[joint(universal_translational, formulation = relative_b1, s = [1, 0, 0], h = [0, 1, 0])]
struct TwoAngle<T: Scalar> {
    d: SlidingFrame<T>,
    rho1: Vector3<T>,
    rho2: Vector3<T>,
}

/// A constant sliding direction, and a `SlidingFrame` field under another name.
#[derive(Joint)]
#[joint(universal_translational, formulation = omega_inertial, ground = body2, d = [0, 0, 1])]
struct TwoAngleConst<T> {
    s: Vector3<T>,
    h: Vector3<T>,
    rho1: Vector3<T>,
    rho2: Vector3<T>,
}

#[derive(Joint)]
#[joint(universal_translational, formulation = relative_b2)]
struct TwoAngleTagged {
    s: Vector3<f64>,
    h: Vector3<f64>,
    #[joint(d)]
    slide: SlidingFrame<f64>,
}

fn main() {
    let _ = Cardan { h: Vector3::<f64>::z(), rho1: Vector3::zeros(), point: Vector3::zeros() };
    let _ = Ball::<f64> { label: "ball", mass: 1.0 };
    let _ =
        TwoAngle::<f64> { d: SlidingFrame::new(Vector3::z()).unwrap(), rho1: Vector3::zeros(), rho2: Vector3::zeros() };
    let _ = TwoAngleConst::<f64> { s: Vector3::x(), h: Vector3::y(), rho1: Vector3::zeros(), rho2: Vector3::zeros() };
    let _ = TwoAngleTagged { s: Vector3::x(), h: Vector3::y(), slide: SlidingFrame::new(Vector3::z()).unwrap() };
}
