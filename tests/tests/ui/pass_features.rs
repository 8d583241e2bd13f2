//! The features of the full catalogue: drivers with a closure and a `Ramp`,
//! axis-based parameters (constant and `AxisFrame` field), and user-written rows.

use joint_runtime::nalgebra::Vector3;
use joint_runtime::{AxisFrame, Drive, Joint, Ramp};

/// A motor whose angle is a closure of time.
#[derive(Joint)]
#[joint(rotational_driver, formulation = omega_body)]
struct Motor<T, F> {
    f: Vector3<T>,
    g: Vector3<T>,
    k: Vector3<T>,
    theta: F,
}

/// A linear actuator driven by a ramp, constant direction.
#[derive(Joint)]
#[joint(translational_driver, formulation = euler, h = [1, 0, 0])]
struct Actuator<T> {
    rho1: Vector3<T>,
    rho2: Vector3<T>,
    x: Ramp,
}

/// A hinge given by its two axes as constants.
#[derive(Joint)]
#[joint(revolute, formulation = omega_body, axis1 = [0, 0, 1], axis2 = [0, 0, 1])]
struct Hinge<T> {
    rho1: Vector3<T>,
    rho2: Vector3<T>,
}

/// A hinge whose axis in body 1 is an `AxisFrame` field.
#[derive(Joint)]
#[joint(revolute, formulation = omega_inertial)]
struct HingeField<T> {
    axis1: AxisFrame<T>,
    h: Vector3<T>,
    rho1: Vector3<T>,
    rho2: Vector3<T>,
}

/// A planar joint whose plane is given by its normal `axis1`.
#[derive(Joint)]
#[joint(planar, formulation = relative_b1, axis1 = [0, 1, 0])]
struct Slider<T> {
    h: Vector3<T>,
}

/// Simbody's ConstantAngle.
#[derive(Joint)]
#[joint(rows(dot(s, h) - cos(alpha)), formulation = omega_body)]
struct ConstantAngle<T> {
    #[joint(body1)]
    s: Vector3<T>,
    #[joint(body2)]
    h: Vector3<T>,
    alpha: T,
}

/// A cable whose length is a time function.
#[derive(Joint)]
#[joint(rows(norm2(d) - l * l), formulation = euler)]
struct Cable<T, F> {
    rho1: Vector3<T>,
    rho2: Vector3<T>,
    #[joint(time)]
    l: F,
}

/// A universal joint written as rows, with constant yokes and a constant angle.
#[derive(Joint)]
#[joint(rows(spherical, dot1(s, h)), formulation = omega_body, body1(s = [0, 1, 0]), body2(h = [0, 0, 1]))]
struct Cardan<T> {
    rho1: Vector3<T>,
    rho2: Vector3<T>,
}

/// A constant angle given in the attribute.
#[derive(Joint)]
#[joint(rows(dot(s, h) - cos(alpha)), formulation = relative_b2, alpha = 0.3)]
struct Bent<T> {
    #[joint(body1)]
    s: Vector3<T>,
    #[joint(body2)]
    h: Vector3<T>,
}

fn main() {
    let _ = Motor {
        f: Vector3::<f64>::x(),
        g: Vector3::y(),
        k: Vector3::x(),
        theta: |t: f64| Drive { value: 2.0 * t, rate: 2.0, accel: 0.0 },
    };
    let _ = Actuator { rho1: Vector3::<f64>::zeros(), rho2: Vector3::zeros(), x: Ramp { start: 0.0, rate: 0.1 } };
    let _ = Hinge { rho1: Vector3::<f64>::zeros(), rho2: Vector3::zeros() };
    let _ = HingeField {
        axis1: AxisFrame::new(Vector3::<f64>::z()).unwrap(),
        h: Vector3::z(),
        rho1: Vector3::zeros(),
        rho2: Vector3::zeros(),
    };
    let _ = Slider { h: Vector3::<f64>::y() };
    let _ = ConstantAngle { s: Vector3::<f64>::z(), h: Vector3::z(), alpha: 0.3 };
    let _ = Cable { rho1: Vector3::<f64>::zeros(), rho2: Vector3::x(), l: Ramp { start: 2.0, rate: -0.1 } };
    let _ = Cardan { rho1: Vector3::<f64>::zeros(), rho2: Vector3::zeros() };
    let _ = Bent { s: Vector3::<f64>::z(), h: Vector3::z() };
    assert_eq!(<ConstantAngle<f64> as Joint<f64, 1, 12>>::KIND, "custom");
}
