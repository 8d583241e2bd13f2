//! Constant and `AxisFrame` axes against the general joint with the vectors of
//! `perpendicular_pair`.

use super::user_rows::same_bits;
use super::*;

/// Every output within `64 ε · (1 + max)` (constants fold in a different order).
fn same_numbers<A, B, S, const R: usize, const C: usize>(what: &str, a: &A, b: &B, s: &S) -> Res
where
    A: Joint<f64, R, C, State = S>,
    B: Joint<f64, R, C, State = S>,
{
    let (ea, eb) = (a.evaluate(s), b.evaluate(s));
    let tol = 64.0 * f64::EPSILON;
    close(&format!("{what}: phi"), ea.phi.as_slice(), eb.phi.as_slice(), tol, &[])?;
    close(&format!("{what}: jacobian"), ea.jacobian.as_slice(), eb.jacobian.as_slice(), tol, &[])?;
    close(&format!("{what}: gamma"), ea.gamma.as_slice(), eb.gamma.as_slice(), tol, &[])?;
    close(&format!("{what}: phi_t"), a.phi_t(s).as_slice(), b.phi_t(s).as_slice(), tol, &[])?;
    close(&format!("{what}: gamma()"), a.gamma(s).as_slice(), eb.gamma.as_slice(), tol, &[])?;
    Ok(())
}

#[derive(Joint)]
#[joint(revolute, formulation = omega_body, axis1 = [0, 0, 1], axis2 = [0, 0, 1])]
struct RevAxis<T> {
    rho1: Vector3<T>,
    rho2: Vector3<T>,
}

#[derive(Joint)]
#[joint(revolute, formulation = omega_body, axis2 = [0, 0, 1])]
struct RevFrame<T> {
    axis1: AxisFrame<T>,
    rho1: Vector3<T>,
    rho2: Vector3<T>,
}

#[derive(Joint)]
#[joint(revolute, formulation = euler, axis1 = [1, 2, 2], axis2 = [0.6, 0, 0.8])]
struct RevAxisSkew<T> {
    rho1: Vector3<T>,
    rho2: Vector3<T>,
}

#[derive(Joint)]
#[joint(revolute, formulation = euler)]
struct RevFrames<T> {
    axis1: AxisFrame<T>,
    axis2: AxisFrame<T>,
    rho1: Vector3<T>,
    rho2: Vector3<T>,
}

#[derive(Joint)]
#[joint(translational, formulation = omega_inertial)]
struct TransAxis2<T> {
    f: Vector3<T>,
    g: Vector3<T>,
    axis2: AxisFrame<T>,
    rho1: Vector3<T>,
    rho2: Vector3<T>,
}

#[derive(Joint)]
#[joint(translational, formulation = relative_b2, axis1 = [0, 1, 0], axis2 = [1, 1, 0])]
struct TransConst<T> {
    rho1: Vector3<T>,
    rho2: Vector3<T>,
}

#[derive(Joint)]
#[joint(rotational_driver, formulation = omega_body, axis1 = [0, 0, 1], axis2 = [0, 0, 1])]
struct MotorAxis<F> {
    theta: F,
}

/// `p` with `f, g` from `perpendicular_pair(axis1)` and `h, k` from `axis2`
/// (`h = axis2`, `k` = the pair's vector `k_part`, 0 or 1).
fn with_axes(p: &Params<f64>, axis1: Vector3<f64>, axis2: Vector3<f64>, k_part: usize) -> Params<f64> {
    let (f, g) = perpendicular_pair(&axis1).expect("axis1");
    let pair2 = perpendicular_pair(&axis2).expect("axis2");
    let mut p = *p;
    p.set(0, f.as_slice());
    p.set(3, g.as_slice());
    p.set(6, axis2.as_slice());
    p.set(9, if k_part == 0 { pair2.0 } else { pair2.1 }.as_slice());
    p
}

/// A random axis from the parameters' `n` slot, kept away from zero.
fn some_axis(p: &Params<f64>) -> Vector3<f64> {
    let a = p.n();
    if a.norm() > 0.1 { a } else { Vector3::new(0.3, -0.5, 0.8) }
}

#[test]
fn perpendicular_pair_of_z() {
    let (b, c) = perpendicular_pair(&Vector3::<f64>::z()).unwrap();
    assert_eq!((b, c), (Vector3::y(), -Vector3::x()));
}

proptest! {
    #![proptest_config(config())]
    #[test]
    fn revolute_constant_axes(k in case(true)) {
        let z = Vector3::z();
        let general = revolute::JointOb::new(&with_axes(&k.p, z, z, 0));
        let s = OmegaBodyF::build(&k.c, k.t0);
        let constant = RevAxis { rho1: k.p.rho1(), rho2: k.p.rho2() };
        same_numbers("revolute axis1 = axis2 = z vs f, g = pair(z), h = z", &constant, &general, &s)?;
        let frame = RevFrame { axis1: AxisFrame::new(z).unwrap(), rho1: k.p.rho1(), rho2: k.p.rho2() };
        same_numbers("revolute axis1: AxisFrame(z) vs constant axis1 = z", &frame, &constant, &s)?;
    }

    #[test]
    fn revolute_skew_constant_axes_and_frames(k in case(false)) {
        let (a1, a2) = (Vector3::new(1.0, 2.0, 2.0), Vector3::new(0.6, 0.0, 0.8));
        let general = revolute::JointE::new(&with_axes(&k.p, a1, a2, 0));
        let s = Euler::build(&k.c, k.t0);
        let constant = RevAxisSkew { rho1: k.p.rho1(), rho2: k.p.rho2() };
        same_numbers("revolute skew constant axes vs general", &constant, &general, &s)?;
        let frames = RevFrames {
            axis1: AxisFrame::new(a1).unwrap(), axis2: AxisFrame::new(a2).unwrap(),
            rho1: k.p.rho1(), rho2: k.p.rho2(),
        };
        same_numbers("revolute AxisFrame fields vs constant axes", &frames, &constant, &s)?;
        // Random axes through frames against the general joint, bitwise: the
        // frame's parts are exactly the vectors the general joint is given.
        let (r1, r2) = (some_axis(&k.p), k.p.s() + Vector3::new(0.0, 0.0, 3.0));
        let frames = RevFrames {
            axis1: AxisFrame::new(r1).unwrap(), axis2: AxisFrame::new(r2).unwrap(),
            rho1: k.p.rho1(), rho2: k.p.rho2(),
        };
        same_bits("revolute AxisFrame(random) vs general", &frames, &revolute::JointE::new(&with_axes(&k.p, r1, r2, 0)), &s)?;
    }

    #[test]
    fn translational_axis2_gives_h_and_the_second_vector(k in case(true)) {
        let a2 = some_axis(&k.p);
        let frame = TransAxis2 { f: k.p.f(), g: k.p.g(), axis2: AxisFrame::new(a2).unwrap(), rho1: k.p.rho1(), rho2: k.p.rho2() };
        let mut general = with_axes(&k.p, Vector3::z(), a2, 1);
        general.set(0, k.p.f().as_slice());
        general.set(3, k.p.g().as_slice());
        let s = OmegaInertial::build(&k.c, k.t0);
        same_bits("translational axis2: AxisFrame vs h = axis, k = c", &frame, &translational::JointOi::new(&general), &s)?;
        let (a1, a2) = (Vector3::new(0.0, 1.0, 0.0), Vector3::new(1.0, 1.0, 0.0));
        let constant = TransConst { rho1: k.p.rho1(), rho2: k.p.rho2() };
        let s = RelB2::build(&k.c, k.t0);
        same_numbers("translational constant axis1, axis2 vs general (k = second)", &constant,
                     &translational::JointR2::new(&with_axes(&k.p, a1, a2, 1)), &s)?;
    }

    /// `axis2` of a rotational driver gives `k` = the pair's first vector, so that
    /// with B2 turned by α about the common axis Φ = sin(α − θ).
    #[test]
    fn rotational_driver_axes(k in case(true), alpha in -3.0f64..3.0, theta in -3.0f64..3.0) {
        let z = Vector3::z();
        let tf = Tf::Frozen(Drive { value: theta, rate: k.poly[1], accel: k.poly[2] });
        let motor = MotorAxis { theta: tf };
        let s = OmegaBodyF::build(&k.c, k.t0);
        same_numbers("rotational_driver axes vs f, g = pair(z), k = first", &motor,
                     &rotational_driver::Ob::make(&with_axes(&k.p, z, z, 0), tf), &s)?;
        let mut c = k.c;
        let q1 = c.p(0);
        let turn = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), alpha);
        let q2 = quat_mul(&q1, &Vector4::new(turn.w, turn.i, turn.j, turn.k));
        c.set(BODY + 3, q2.as_slice());
        let phi = Joint::<f64, 1, 12>::phi(&motor, &OmegaBodyF::build(&c, k.t0))[0];
        prop_assert!((phi - (alpha - theta).sin()).abs() < 1e-14, "Φ = {phi:e}, sin(α − θ) = {:e}", (alpha - theta).sin());
    }
}
