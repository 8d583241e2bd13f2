//! `rows(spherical, dot1(s, h))` against the catalogue `universal`, the constant
//! angle of the README and the cable whose length is a time function.

use super::*;

macro_rules! universal_pair {
    ($user:ident, $cat:ident, $form:ident) => {
        #[derive(Joint, Clone, Debug)]
        #[joint(rows(spherical, dot1(s, h)), formulation = $form, second_order)]
        pub(crate) struct $user<T> {
            #[joint(body1)]
            s: Vector3<T>,
            #[joint(body2)]
            h: Vector3<T>,
            rho1: Vector3<T>,
            rho2: Vector3<T>,
        }
        #[derive(Joint, Clone, Debug)]
        #[joint(universal, formulation = $form, second_order)]
        pub(crate) struct $cat<T> {
            pub(crate) s: Vector3<T>,
            pub(crate) h: Vector3<T>,
            pub(crate) rho1: Vector3<T>,
            pub(crate) rho2: Vector3<T>,
        }
        impl<T: SimdRealField + Copy> $user<T> {
            fn new(p: &Params<T>) -> Self {
                $user { s: p.s(), h: p.h(), rho1: p.rho1(), rho2: p.rho2() }
            }
        }
        impl<T: SimdRealField + Copy> $cat<T> {
            pub(crate) fn new(p: &Params<T>) -> Self {
                $cat { s: p.s(), h: p.h(), rho1: p.rho1(), rho2: p.rho2() }
            }
        }
    };
}
universal_pair!(UserUniE, UniE, euler);
universal_pair!(UserUniOI, UniOI, omega_inertial);
universal_pair!(UserUniOB, UniOB, omega_body);
universal_pair!(UserUniR1, UniR1, relative_b1);
universal_pair!(UserUniR2, UniR2, relative_b2);

/// Two joints give bitwise the same `evaluate` (and `phi`, `jacobian`, `gamma`, `phi_t`).
pub(crate) fn same_bits<A, B, S, const R: usize, const C: usize>(what: &str, a: &A, b: &B, s: &S) -> Res
where
    A: Joint<f64, R, C, State = S>,
    B: Joint<f64, R, C, State = S>,
{
    let (ea, eb) = (a.evaluate(s), b.evaluate(s));
    bitwise(&format!("{what}: evaluate().phi"), ea.phi.as_slice(), eb.phi.as_slice())?;
    bitwise(&format!("{what}: evaluate().jacobian"), ea.jacobian.as_slice(), eb.jacobian.as_slice())?;
    bitwise(&format!("{what}: evaluate().gamma"), ea.gamma.as_slice(), eb.gamma.as_slice())?;
    bitwise(&format!("{what}: phi"), a.phi(s).as_slice(), b.phi(s).as_slice())?;
    bitwise(&format!("{what}: jacobian"), a.jacobian(s).as_slice(), b.jacobian(s).as_slice())?;
    bitwise(&format!("{what}: gamma"), a.gamma(s).as_slice(), b.gamma(s).as_slice())?;
    bitwise(&format!("{what}: phi_t"), a.phi_t(s).as_slice(), b.phi_t(s).as_slice())?;
    Ok(())
}

proptest! {
    #![proptest_config(config())]
    #[test]
    fn spherical_dot1_rows_are_bitwise_universal(k in case(false), u in coords(true)) {
        let (c, p, t) = (&k.c, &k.p, k.t0);
        same_bits("euler", &UserUniE::new(p), &UniE::new(p), &Euler::build(c, t))?;
        same_bits("omega_inertial", &UserUniOI::new(p), &UniOI::new(p), &OmegaInertial::build(&u, t))?;
        same_bits("omega_body", &UserUniOB::new(p), &UniOB::new(p), &OmegaBodyF::build(&u, t))?;
        same_bits("relative_b1", &UserUniR1::new(p), &UniR1::new(p), &RelB1::build(&u, t))?;
        same_bits("relative_b2", &UserUniR2::new(p), &UniR2::new(p), &RelB2::build(&u, t))?;
    }
}

#[test]
fn user_joints_are_custom() {
    assert_eq!(<UserUniOB<f64> as Joint<f64, 4, 12>>::KIND, "custom");
    assert_eq!(<UniOB<f64> as Joint<f64, 4, 12>>::KIND, "universal");
    assert_eq!(<ConstantAngleOI<f64> as Joint<f64, 1, 12>>::KIND, "custom");
    assert_eq!(<Cable<f64, Tf> as Joint<f64, 1, 14>>::KIND, "custom");
}

// Simbody's ConstantAngle, `rows(dot(s, h) - cos(alpha))`, in every formulation.
macro_rules! constant_angle {
    ($fam:ident, $name:ident, $form:ident, $F:ty, $c:literal) => {
        #[derive(Joint, Clone, Debug)]
        #[joint(rows(dot(s, h) - cos(alpha)), formulation = $form, second_order)]
        pub(crate) struct $name<T> {
            #[joint(body1)]
            s: Vector3<T>,
            #[joint(body2)]
            h: Vector3<T>,
            alpha: T,
        }
        pub(crate) struct $fam;
        impl Family<1, $c> for $fam {
            type F = $F;
            const NAME: &'static str = "constant_angle";
            const TIME: TimeKind = TimeKind::None;
            type J<T: SimdRealField + Copy> = $name<T>;
            fn make<T: SimdRealField + Copy>(p: &Params<T>, _: Tf) -> $name<T> {
                $name { s: p.s(), h: p.h(), alpha: p.sc() }
            }
        }
    };
}
constant_angle!(CaE, ConstantAngleE, euler, Euler, 14);
constant_angle!(CaOI, ConstantAngleOI, omega_inertial, OmegaInertial, 12);
constant_angle!(CaOB, ConstantAngleOB, omega_body, OmegaBodyF, 12);
constant_angle!(CaR1, ConstantAngleR1, relative_b1, RelB1, 6);
constant_angle!(CaR2, ConstantAngleR2, relative_b2, RelB2, 6);
properties!(constant_angle_euler, CaE, 1, 14, false, partials);
properties!(constant_angle_omega_inertial, CaOI, 1, 12, true);
properties!(constant_angle_omega_body, CaOB, 1, 12, true);
properties!(constant_angle_relative_b1, CaR1, 1, 6, true);
properties!(constant_angle_relative_b2, CaR2, 1, 6, true);

proptest! {
    #![proptest_config(config())]
    /// Φ = (A1 s)·(A2 h) − cos α, written out with `rotation_matrix` (unit p).
    #[test]
    fn constant_angle_phi_by_hand(c in coords(true), s in prop::array::uniform3(-2.0f64..2.0),
                                  h in prop::array::uniform3(-2.0f64..2.0), alpha in -3.0f64..3.0) {
        let (s, h) = (Vector3::from(s), Vector3::from(h));
        let j = ConstantAngleOI { s, h, alpha };
        let (a1, a2) = (rotation_matrix(&c.p(0)), rotation_matrix(&c.p(1)));
        let want = (a1 * s).dot(&(a2 * h)) - alpha.cos();
        let got = j.phi(&OmegaInertial::build(&c, 0.0))[0];
        prop_assert!((got - want).abs() <= 1e-14 * (1.0 + s.norm() * h.norm()), "Φ = {got:e}, expected {want:e}");
    }
}

/// The README's cable: `rows(norm2(d) - l * l)` with `l` a time function.
#[derive(Joint, Clone, Debug)]
#[joint(rows(norm2(d) - l * l), formulation = euler, second_order)]
pub(crate) struct Cable<T, F> {
    rho1: Vector3<T>,
    rho2: Vector3<T>,
    #[joint(time)]
    l: F,
}
pub(crate) struct CableE;
impl Family<1, 14> for CableE {
    type F = Euler;
    const NAME: &'static str = "cable";
    const TIME: TimeKind = TimeKind::Square;
    type J<T: SimdRealField + Copy> = Cable<T, Tf>;
    fn make<T: SimdRealField + Copy>(p: &Params<T>, tf: Tf) -> Cable<T, Tf> {
        Cable { rho1: p.rho1(), rho2: p.rho2(), l: tf }
    }
}
properties!(cable_euler, CableE, 1, 14, false, partials);

proptest! {
    #![proptest_config(config())]
    /// Φ_t = −2 l l̇ bitwise (a product and a doubling: no rounding freedom), and the
    /// time terms of γ are `−Φ_tt = 2 l̇² + 2 l l̈` (Φ_qt = 0).
    #[test]
    fn cable_time_terms_closed_form(k in case(false)) {
        for tf in [k.poly_tf(), k.sine_tf()] {
            let j = CableE::make(&k.p, tf);
            let s = Euler::build(&k.c, k.t0);
            let Drive { value: l, rate: ld, accel: ldd } = tf.eval(k.t0);
            bitwise("cable Φ_t vs −2 l l̇", j.phi_t(&s).as_slice(), &[-2.0 * l * ld])?;
            let terms = j.gamma(&s) - CableE::make(&k.p, frozen(l)).gamma(&s);
            let want = 2.0 * ld * ld + 2.0 * l * ldd;
            let scale = 1.0 + 2.0 * ld * ld + (2.0 * l * ldd).abs() + j.gamma(&s)[0].abs();
            prop_assert!((terms[0] - want).abs() <= 1e-14 * scale,
                "cable γ time terms {:e}, expected 2 l̇² + 2 l l̈ = {:e}", terms[0], want);
            let d = j.phi(&s)[0] + l * l;
            let (a1, a2) = (rotation_matrix(&k.c.p(0)), rotation_matrix(&k.c.p(1)));
            let sep = k.c.x(1) + a2 * k.p.rho2() - k.c.x(0) - a1 * k.p.rho1();
            prop_assert!((d - sep.norm_squared()).abs() <= 1e-12 * (1.0 + d.abs() + l * l));
        }
    }
}

/// The brief's `Motor<T, F>` with a closure: the same numbers as the frozen drive
/// the closure gives at the state's time, and Φ_t by a difference in time.
#[derive(Joint)]
#[joint(rotational_driver, formulation = euler)]
struct Motor<T, F> {
    f: Vector3<T>,
    g: Vector3<T>,
    k: Vector3<T>,
    theta: F,
}

proptest! {
    #![proptest_config(config())]
    #[test]
    fn motor_with_a_closure(k in case(false)) {
        let (t0, [a, b, c]) = (k.t0, k.poly);
        let theta = move |t: f64| {
            let u = t - t0;
            Drive { value: a + b * u + 0.5 * c * u * u, rate: b + c * u, accel: c }
        };
        let motor = Motor { f: k.p.f(), g: k.p.g(), k: k.p.k(), theta };
        let frozen = rotational_driver::E::make(&k.p, Tf::Frozen(Drive { value: a, rate: b, accel: c }));
        let s = Euler::build(&k.c, t0);
        same_bits("closure vs frozen Drive", &motor, &frozen, &s)?;
        let h = 1e-5;
        let phi = |t: f64| motor.phi(&Euler::build(&k.c, t))[0];
        let fd = (phi(t0 + h) - phi(t0 - h)) / (2.0 * h);
        let phi_t = motor.phi_t(&s)[0];
        prop_assert!((phi_t - fd).abs() <= 1e-6 * (1.0 + phi_t.abs() + k.p.f().norm() * k.p.k().norm() * 16.0),
            "closure motor Φ_t = {phi_t:e}, difference {fd:e}");
    }
}
