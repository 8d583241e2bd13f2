//! Independent numeric checks of the whole joint catalogue, the drivers' time
//! terms, user-written rows, axis parameters and singularity measures.
//!
//! * Every catalogue joint in every formulation: Φ against an independent nalgebra
//!   reference of `CONVENTIONS.md`; `evaluate` against `phi`, `jacobian`, `gamma`;
//!   `J v + Φ_t = dΦ/dt` along an exact trajectory (num-dual `Dual64` in t); γ = −Φ̈
//!   with constant v (`Dual2_64`, exact) and against a central difference of
//!   `J v + Φ_t` along the trajectory *including time*; in `euler`, J = ∂Φ/∂q.
//! * Drivers: Φ_t against ∂Φ/∂t (num-dual) and a central difference in the state's
//!   time; the time terms `−2Φ_qt q̇ − Φ_tt` of γ isolated and checked by differences.
//! * User rows (`rows(...)`), axis parameters (`axis1`, `axis2`, `AxisFrame`) and the
//!   `Singularity` measures against closed forms.
//!
//! # How a time function meets a dual-number trajectory
//!
//! The generated code reads a driver's time function once, at `state.t` (an `f64`),
//! and converts value, rate and acceleration to the scalar `T`: the time function
//! cannot carry a dual part. Φ, however, depends on the time function's value θ
//! only through `(cos θ, sin θ)` (rotational driver: `Φ = a(q) cos θ − b(q) sin θ`),
//! through `x` (translational driver: `Φ = c(q) − x`) or through `l²` (the cable:
//! `Φ = |d|² − l²`), with coefficient functions of q alone. So the oracle evaluates
//! the *generated* `phi` along the dual trajectory `q(τ)` with the time function
//! frozen at chosen values (θ = 0 and θ = −π/2 give `a(q(τ))` and `b(q(τ))` exactly
//! up to one rounding of `cos(−π/2) ≈ 6e−17`; x = 0 and l = 0 give `c` and `|d|²`),
//! and recombines them with a dual θ(t0 + τ) computed from the same polynomial
//! `θ(t) = c0 + c1 t + c2 t²` that the joint reads through
//! [`joint_runtime::Polynomial`] at `state.t = t0`. Value, rate and acceleration the
//! generated code reads are therefore exactly the derivatives of the dual θ. The
//! decomposition itself is checked by the independent reference Φ at arbitrary θ.
//! Finite differences in the state's time (a [`Sinusoid`]) check the same
//! quantities without this decomposition.

use core::f64::consts::FRAC_PI_2;

use joint_runtime::nalgebra::{Matrix3, SVector, SimdRealField, UnitQuaternion, Vector3, Vector4};
use joint_runtime::{
    AxisFrame, Drive, Formulation, Joint, OmegaBody, Polynomial, Singularity, Sinusoid, TimeFunction, TwoBodies,
    perpendicular_pair, rotation_matrix,
};
use joint_tests::trajectory::{
    BODY, Coords, Euler, Flat, Form, OmegaBodyF, OmegaInertial, RelB1, RelB2, along, at_rest, coords_from, lift,
    matvec, max_abs, quat_mul,
};
use joint_tests::vector_views;
use num_dual::{Dual2_64, Dual64};
use proptest::prelude::*;
use proptest::strategy::ValueTree;
use proptest::test_runner::TestCaseError;

type Res = Result<(), TestCaseError>;

/// `f, g, h, k, n, s, rho1, rho2` (three each) and one scalar (a length, an angle).
type Params<T> = Flat<T, 25>;

vector_views! {
    /// Named views of [`Params`].
    trait ParamViews for 25 { f = 0, g = 3, h = 6, k = 9, n = 12, s = 15, rho1 = 18, rho2 = 21 }; scalar sc = 24
}

// ---------------------------------------------------------------------------
// Time functions.
// ---------------------------------------------------------------------------

/// The time functions the tests drive joints with (one type, so that one struct
/// instantiation serves every check).
#[derive(Clone, Copy, Debug)]
enum Tf {
    /// `θ(t) = c0 + c1 t + c2 t²` through the runtime's `Polynomial`.
    Poly(Polynomial<3>),
    /// The runtime's `Sinusoid` (smooth, for finite differences in t).
    Sine(Sinusoid),
    /// A frozen value, rate and acceleration (ignores t).
    Frozen(Drive),
}

impl TimeFunction for Tf {
    fn eval(&self, t: f64) -> Drive {
        match self {
            Tf::Poly(p) => p.eval(t),
            Tf::Sine(s) => s.eval(t),
            Tf::Frozen(d) => d.eval(t),
        }
    }
}

fn frozen(value: f64) -> Tf {
    Tf::Frozen(Drive { value, rate: 0.0, accel: 0.0 })
}

/// `c0 + c1 t + c2 t²` in any scalar (the dual twin of `Polynomial([c0, c1, c2])`).
fn poly_at<T: SimdRealField + Copy>(c: &[f64; 3], t: T) -> T {
    lift::<T>(c[0]) + t * (lift::<T>(c[1]) + t * lift::<T>(c[2]))
}

/// How Φ depends on the value θ of the joint's time function (see the module docs).
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum TimeKind {
    /// Not driven.
    None,
    /// `Φ = c(q) − θ` (translational driver).
    Linear,
    /// `Φ = c(q) − θ²` (the cable of user rows).
    Square,
    /// `Φ = a(q) cos θ − b(q) sin θ` (rotational driver).
    Trig,
}

// ---------------------------------------------------------------------------
// Joint declarations.
// ---------------------------------------------------------------------------

/// A derived joint in one formulation, for every scalar.
trait Family<const R: usize, const C: usize> {
    type F: Form<C>;
    /// The joint kind (or the name of a user-written joint) for the reference Φ.
    const NAME: &'static str;
    const TIME: TimeKind;
    type J<T: SimdRealField + Copy>: Joint<T, R, C, State = <Self::F as Form<C>>::State<T>>;
    fn make<T: SimdRealField + Copy>(p: &Params<T>, tf: Tf) -> Self::J<T>;
}

macro_rules! family {
    // Vector parameters only.
    ($fam:ident, $name:ident, $kind:ident, $form:ident, $F:ty, $r:literal, $c:literal, [$($p:ident),*]) => {
        #[derive(Joint, Clone, Debug)]
        #[joint($kind, formulation = $form, second_order)]
        pub(crate) struct $name<T> {
            $($p: Vector3<T>),*
        }
        impl<T: SimdRealField + Copy> $name<T> {
            pub(crate) fn new(p: &Params<T>) -> Self {
                $name { $($p: p.$p()),* }
            }
        }
        pub(crate) struct $fam;
        impl Family<$r, $c> for $fam {
            type F = $F;
            const NAME: &'static str = stringify!($kind);
            const TIME: TimeKind = TimeKind::None;
            type J<T: SimdRealField + Copy> = $name<T>;
            fn make<T: SimdRealField + Copy>(p: &Params<T>, _: Tf) -> $name<T> {
                $name::new(p)
            }
        }
    };
    // With a scalar parameter (read from the scalar slot).
    ($fam:ident, $name:ident, $kind:ident, $form:ident, $F:ty, $r:literal, $c:literal, [$($p:ident),*], scalar $sc:ident) => {
        #[derive(Joint, Clone, Debug)]
        #[joint($kind, formulation = $form, second_order)]
        pub(crate) struct $name<T> {
            $($p: Vector3<T>,)*
            $sc: T,
        }
        impl<T: SimdRealField + Copy> $name<T> {
            pub(crate) fn new(p: &Params<T>) -> Self {
                $name { $($p: p.$p(),)* $sc: p.sc() }
            }
        }
        pub(crate) struct $fam;
        impl Family<$r, $c> for $fam {
            type F = $F;
            const NAME: &'static str = stringify!($kind);
            const TIME: TimeKind = TimeKind::None;
            type J<T: SimdRealField + Copy> = $name<T>;
            fn make<T: SimdRealField + Copy>(p: &Params<T>, _: Tf) -> $name<T> {
                $name::new(p)
            }
        }
    };
    // A driver: a time-function field of the struct's second type parameter.
    ($fam:ident, $name:ident, $kind:ident, $form:ident, $F:ty, $r:literal, $c:literal, [$($p:ident),*], time $tf:ident $tk:ident) => {
        #[derive(Joint, Clone, Debug)]
        #[joint($kind, formulation = $form, second_order)]
        pub(crate) struct $name<T, F> {
            $($p: Vector3<T>,)*
            $tf: F,
        }
        pub(crate) struct $fam;
        impl Family<$r, $c> for $fam {
            type F = $F;
            const NAME: &'static str = stringify!($kind);
            const TIME: TimeKind = TimeKind::$tk;
            type J<T: SimdRealField + Copy> = $name<T, Tf>;
            fn make<T: SimdRealField + Copy>(p: &Params<T>, tf: Tf) -> $name<T, Tf> {
                $name { $($p: p.$p(),)* $tf: tf }
            }
        }
    };
}

/// One catalogue joint in all five formulations, each with its property tests.
macro_rules! catalogue_joint {
    ($module:ident, $kind:ident, $r:literal, [$($p:ident),*] $(, $($extra:tt)+)?) => {
        pub(crate) mod $module {
            use super::*;
            family!(E, JointE, $kind, euler, Euler, $r, 14, [$($p),*] $(, $($extra)+)?);
            family!(Oi, JointOi, $kind, omega_inertial, OmegaInertial, $r, 12, [$($p),*] $(, $($extra)+)?);
            family!(Ob, JointOb, $kind, omega_body, OmegaBodyF, $r, 12, [$($p),*] $(, $($extra)+)?);
            family!(R1, JointR1, $kind, relative_b1, RelB1, $r, 6, [$($p),*] $(, $($extra)+)?);
            family!(R2, JointR2, $kind, relative_b2, RelB2, $r, 6, [$($p),*] $(, $($extra)+)?);
            properties!(euler, E, $r, 14, false, partials);
            properties!(omega_inertial, Oi, $r, 12, true);
            properties!(omega_body, Ob, $r, 12, true);
            properties!(relative_b1, R1, $r, 6, true);
            properties!(relative_b2, R2, $r, 6, true);
        }
    };
}

// ---------------------------------------------------------------------------
// Strategies, comparisons.
// ---------------------------------------------------------------------------

const CASES: u32 = 32;

fn config() -> ProptestConfig {
    // No regression files: this suite must not write into the source tree.
    // `PROPTEST_CASES` overrides the case count (for longer soak runs).
    let cases = std::env::var("PROPTEST_CASES").ok().and_then(|n| n.parse().ok()).unwrap_or(CASES);
    ProptestConfig { cases, failure_persistence: None, ..ProptestConfig::default() }
}

/// One random case: coordinates and velocities, parameters, the state's time, a
/// quadratic time function (for the num-dual checks) and a sinusoid (for differences).
#[derive(Clone, Copy, Debug)]
struct Case {
    c: Coords<f64>,
    p: Params<f64>,
    t0: f64,
    poly: [f64; 3],
    sine: Sinusoid,
}

impl Case {
    fn poly_tf(&self) -> Tf {
        Tf::Poly(Polynomial(self.poly))
    }
    fn sine_tf(&self) -> Tf {
        Tf::Sine(self.sine)
    }
}

/// Random coordinates and velocities in [-2, 2]; Euler parameters made unit when `unit`.
fn coords(unit: bool) -> impl Strategy<Value = Coords<f64>> {
    prop::collection::vec(-2.0f64..2.0, 34).prop_map(move |v| coords_from(&v, unit))
}

fn case(unit: bool) -> impl Strategy<Value = Case> {
    (
        coords(unit),
        prop::collection::vec(-2.0f64..2.0, 25),
        -1.0f64..1.0,
        prop::array::uniform3(-1.5f64..1.5),
        (-1.0f64..1.0, 0.5f64..1.5, 0.5f64..3.0, -3.0f64..3.0),
    )
        .prop_map(|(c, p, t0, poly, (offset, amplitude, frequency, phase))| Case {
            c,
            p: Flat(core::array::from_fn(|i| p[i])),
            t0,
            poly,
            sine: Sinusoid { offset, amplitude, frequency, phase },
        })
}

/// Four fixed random cases (deterministic seed).
fn samples(unit: bool) -> Vec<Case> {
    let mut runner = proptest::test_runner::TestRunner::deterministic();
    let strategy = case(unit);
    (0..4).map(|_| strategy.new_tree(&mut runner).expect("strategy").current()).collect()
}

/// [`joint_tests::trajectory::magnitude`] over the case's coordinates and parameters.
fn magnitude(k: &Case, f: impl Fn(&Case) -> Vec<f64>) -> Vec<f64> {
    joint_tests::trajectory::magnitude(k, |k, flip| Case { c: k.c.map(&mut *flip), p: k.p.map(flip), ..*k }, f)
}

/// [`joint_tests::trajectory::close`] of a vector (or one column).
fn close(what: &str, got: &[f64], want: &[f64], tol: f64, mag: &[f64]) -> Res {
    Ok(joint_tests::trajectory::close(what, got, want, got.len().max(1), tol, mag)?)
}

/// [`joint_tests::trajectory::bitwise`] of flattened outputs.
fn bitwise(what: &str, got: &[f64], want: &[f64]) -> Res {
    Ok(joint_tests::trajectory::bitwise(what, got, want, got.len().max(1))?)
}

fn state<Fa: Family<R, C>, const R: usize, const C: usize, T: SimdRealField + Copy>(
    c: &Coords<T>,
    t: f64,
) -> <Fa::F as Form<C>>::State<T> {
    <Fa::F as Form<C>>::build(c, t)
}

fn velocity<Fa: Family<R, C>, const R: usize, const C: usize>(c: &Coords<f64>) -> SVector<f64, C> {
    <Fa::F as Form<C>>::velocity(c)
}

fn joint<Fa: Family<R, C>, const R: usize, const C: usize>(p: &Params<f64>, tf: Tf) -> Fa::J<f64> {
    Fa::make(p, tf)
}

fn relative_form<Fa: Family<R, C>, const R: usize, const C: usize>() -> bool {
    matches!(<Fa::J<f64> as Joint<f64, R, C>>::FORMULATION, Formulation::RelativeB1 | Formulation::RelativeB2)
}

/// Joints whose Φ is linear in the relative coordinates (γ ≡ 0 there).
fn linear_in_relative<Fa: Family<R, C>, const R: usize, const C: usize>() -> bool {
    relative_form::<Fa, R, C>() && matches!(Fa::NAME, "point_on_line" | "point_in_plane")
}

// ---------------------------------------------------------------------------
// The reference Φ (nalgebra, straight from CONVENTIONS.md) and the dual oracle.
// ---------------------------------------------------------------------------

/// Φ of joint `name` at the coordinates, with the time function's value `theta`.
fn reference_phi(name: &str, relative: bool, c: &Coords<f64>, p: &Params<f64>, theta: f64) -> Vec<f64> {
    let (a1, a2, d) = if relative {
        (Matrix3::identity(), rotation_matrix(&c.p(0)), c.x(0))
    } else {
        let (a1, a2) = (rotation_matrix(&c.p(0)), rotation_matrix(&c.p(1)));
        (a1, a2, c.x(1) + a2 * p.rho2() - c.x(0) - a1 * p.rho1())
    };
    let dot1 = |a: Vector3<f64>, b: Vector3<f64>| (a1 * a).dot(&(a2 * b));
    let dot2 = |a: Vector3<f64>| (a1 * a).dot(&d);
    let sph = vec![d.x, d.y, d.z];
    let (f, g, h, k, n, s) = (p.f(), p.g(), p.h(), p.k(), p.n(), p.s());
    let rows = |mut head: Vec<f64>, tail: &[f64]| {
        head.extend_from_slice(tail);
        head
    };
    match name {
        "universal" => rows(sph, &[dot1(s, h)]),
        "revolute" => rows(sph, &[dot1(f, h), dot1(g, h)]),
        "cylindrical" => vec![dot1(f, h), dot1(g, h), dot2(f), dot2(g)],
        "translational" => vec![dot1(f, h), dot1(g, h), dot2(f), dot2(g), dot1(f, k)],
        "fixed" => rows(sph, &[dot1(f, h), dot1(g, h), dot1(f, k)]),
        "planar" => vec![dot1(f, h), dot1(g, h), dot2(n)],
        "point_on_line" => vec![dot2(f), dot2(g)],
        "point_in_plane" => vec![dot2(n)],
        "parallel" => vec![dot1(f, h), dot1(g, h)],
        "perpendicular" => vec![dot1(s, h)],
        "distance" => vec![d.dot(&d) - p.sc() * p.sc()],
        "rotational_driver" => vec![dot1(g, k) * theta.cos() - dot1(f, k) * theta.sin()],
        "translational_driver" => vec![dot2(h) - theta],
        "constant_angle" => vec![dot1(s, h) - p.sc().cos()],
        "cable" => vec![d.dot(&d) - theta * theta],
        other => panic!("no reference for `{other}`"),
    }
}

/// Φ along the exact trajectory at `t0 + τ` from the generated `phi` (module docs):
/// `move_q` lets the coordinates move with their velocities, `move_t` lets the time
/// function move along θ(t0 + τ).
fn phi_path<Fa: Family<R, C>, const R: usize, const C: usize, T: SimdRealField + Copy>(
    k: &Case,
    tau: T,
    move_q: bool,
    move_t: bool,
) -> SVector<T, R> {
    let c0 = if move_q { k.c } else { at_rest(&k.c) };
    let s = state::<Fa, R, C, T>(&along(&c0, <Fa::F as Form<C>>::ROT, tau), k.t0);
    let p = k.p.map(lift::<T>);
    let at = |value: f64| Fa::make(&p, frozen(value)).phi(&s);
    let theta: T =
        if move_t { poly_at(&k.poly, lift::<T>(k.t0) + tau) } else { lift(Polynomial(k.poly).eval(k.t0).value) };
    match Fa::TIME {
        TimeKind::None => at(0.0),
        TimeKind::Linear => at(0.0).map(|x| x - theta),
        TimeKind::Square => at(0.0).map(|x| x - theta * theta),
        TimeKind::Trig => {
            let a = at(0.0);
            let c = lift::<T>((-FRAC_PI_2).cos());
            // Φ(−π/2) = a cos(−π/2) + b.
            let b = at(-FRAC_PI_2).zip_map(&a, |m, a| m - a * c);
            let (ct, st) = (theta.simd_cos(), theta.simd_sin());
            a.zip_map(&b, |a, b| a * ct - b * st)
        }
    }
}

// ---------------------------------------------------------------------------
// The checks.
// ---------------------------------------------------------------------------

/// Φ equals the nalgebra reference; `evaluate` equals the separate functions
/// bitwise; Φ_t is zero for a joint that is not driven.
fn check_phi<Fa: Family<R, C>, const R: usize, const C: usize>(k: &Case) -> Res {
    let j = joint::<Fa, R, C>(&k.p, k.poly_tf());
    let s = state::<Fa, R, C, f64>(&k.c, k.t0);
    let theta = Polynomial(k.poly).eval(k.t0).value;
    let phi = j.phi(&s);
    let want = reference_phi(Fa::NAME, relative_form::<Fa, R, C>(), &k.c, &k.p, theta);
    let mag = magnitude(k, |k| {
        reference_phi(Fa::NAME, relative_form::<Fa, R, C>(), &k.c, &k.p, theta).iter().map(|x| x.abs()).collect()
    });
    close(&format!("{} Φ vs nalgebra reference", Fa::NAME), phi.as_slice(), &want, 1e-13, &mag)?;
    let e = j.evaluate(&s);
    bitwise("evaluate().phi vs phi()", e.phi.as_slice(), phi.as_slice())?;
    bitwise("evaluate().jacobian vs jacobian()", e.jacobian.as_slice(), j.jacobian(&s).as_slice())?;
    bitwise("evaluate().gamma vs gamma()", e.gamma.as_slice(), j.gamma(&s).as_slice())?;
    if Fa::TIME == TimeKind::None {
        prop_assert!(j.phi_t(&s).iter().all(|&x| x == 0.0), "phi_t of an undriven joint is not zero");
    }
    Ok(())
}

/// [`magnitude`] of J v and of γ (time function `tf`).
fn jv_gamma_magnitude<Fa: Family<R, C>, const R: usize, const C: usize>(k: &Case, tf: Tf) -> (Vec<f64>, Vec<f64>) {
    let f = |k: &Case| {
        let j = joint::<Fa, R, C>(&k.p, tf);
        let s = state::<Fa, R, C, f64>(&k.c, k.t0);
        let jv = matvec(&j.jacobian(&s), &velocity::<Fa, R, C>(&k.c)) + j.phi_t(&s);
        [jv.as_slice(), j.gamma(&s).as_slice()].concat()
    };
    let m = magnitude(k, f);
    (m[..R].to_vec(), m[R..].to_vec())
}

/// `J v + Φ_t = dΦ/dt`, `Φ_t = ∂Φ/∂t`, `J v = ∂Φ/∂q q̇` (`Dual64` in τ); returns max |dΦ/dt|.
fn check_velocity<Fa: Family<R, C>, const R: usize, const C: usize>(k: &Case) -> Result<f64, TestCaseError> {
    let j = joint::<Fa, R, C>(&k.p, k.poly_tf());
    let s0 = state::<Fa, R, C, f64>(&k.c, k.t0);
    let jv = matvec(&j.jacobian(&s0), &velocity::<Fa, R, C>(&k.c));
    let phi_t = j.phi_t(&s0);
    let (mag, _) = jv_gamma_magnitude::<Fa, R, C>(k, k.poly_tf());
    let tau = Dual64::from_re(0.0).derivative();
    let full = phi_path::<Fa, R, C, Dual64>(k, tau, true, true);
    let name = Fa::NAME;
    close(
        &format!("{name} Φ on the oracle's path at τ = 0"),
        full.map(|x| x.re).as_slice(),
        j.phi(&s0).as_slice(),
        1e-13,
        &[],
    )?;
    let rate = full.map(|x| x.eps);
    close(&format!("{name} J v + Φ_t vs dΦ/dt (num-dual)"), (jv + phi_t).as_slice(), rate.as_slice(), 1e-12, &mag)?;
    let q_only = phi_path::<Fa, R, C, Dual64>(k, tau, true, false).map(|x| x.eps);
    close(&format!("{name} J v vs ∂Φ/∂q q̇ (num-dual, θ frozen)"), jv.as_slice(), q_only.as_slice(), 1e-12, &mag)?;
    let t_only = phi_path::<Fa, R, C, Dual64>(k, tau, false, true).map(|x| x.eps);
    close(&format!("{name} Φ_t vs ∂Φ/∂t (num-dual, q frozen)"), phi_t.as_slice(), t_only.as_slice(), 1e-12, &mag)?;
    Ok(max_abs(rate.as_slice()))
}

/// `γ = −Φ̈` along the trajectory with constant v and θ(t) moving (`Dual2_64`, exact); returns max |Φ̈|.
fn check_gamma_dual<Fa: Family<R, C>, const R: usize, const C: usize>(k: &Case) -> Result<f64, TestCaseError> {
    let j = joint::<Fa, R, C>(&k.p, k.poly_tf());
    let gamma = j.gamma(&state::<Fa, R, C, f64>(&k.c, k.t0));
    let tau = Dual2_64::from_re(0.0).derivative();
    let minus_acc = phi_path::<Fa, R, C, Dual2_64>(k, tau, true, true).map(|x| -x.v2);
    let (_, mag) = jv_gamma_magnitude::<Fa, R, C>(k, k.poly_tf());
    close(&format!("{} γ vs −Φ̈ (num-dual Dual2)", Fa::NAME), gamma.as_slice(), minus_acc.as_slice(), 1e-12, &mag)?;
    if linear_in_relative::<Fa, R, C>() {
        prop_assert!(
            gamma.iter().chain(minus_acc.iter()).all(|&x| x == 0.0),
            "γ = {:?}, −Φ̈ = {:?}: expected exactly 0 (Φ linear in δ)",
            gamma,
            minus_acc
        );
    }
    Ok(max_abs(minus_acc.as_slice()))
}

/// `X(τ) = J(q(τ), t0 + τ) v + Φ_t(q(τ), t0 + τ)` for the time function `tf`;
/// `move_q`, `move_t` as in [`phi_path`].
fn rate_at<Fa: Family<R, C>, const R: usize, const C: usize>(
    k: &Case,
    tf: Tf,
    tau: f64,
    move_q: bool,
    move_t: bool,
    with_phi_t: bool,
) -> SVector<f64, R> {
    let c0 = if move_q { k.c } else { at_rest(&k.c) };
    let mut q = along(&c0, <Fa::F as Form<C>>::ROT, tau);
    // The velocities stay those of the case (at rest only the path is frozen).
    q.set(7, &k.c.0[7..BODY]);
    q.set(BODY + 7, &k.c.0[BODY + 7..]);
    let s = state::<Fa, R, C, f64>(&q, if move_t { k.t0 + tau } else { k.t0 });
    let j = joint::<Fa, R, C>(&k.p, tf);
    let jv = matvec(&j.jacobian(&s), &velocity::<Fa, R, C>(&k.c));
    if with_phi_t { jv + j.phi_t(&s) } else { jv }
}

/// γ = −d(J v + Φ_t)/dt along the trajectory including time, by a central
/// difference with the smooth time function `Sinusoid`; returns max |FD|.
fn check_gamma_fd<Fa: Family<R, C>, const R: usize, const C: usize>(k: &Case) -> Result<f64, TestCaseError> {
    let h = 1e-5;
    let tf = k.sine_tf();
    let x = |t: f64| rate_at::<Fa, R, C>(k, tf, t, true, true, true);
    let fd = (x(h) - x(-h)) / (2.0 * h);
    let gamma = joint::<Fa, R, C>(&k.p, tf).gamma(&state::<Fa, R, C, f64>(&k.c, k.t0));
    let (_, mag) = jv_gamma_magnitude::<Fa, R, C>(k, tf);
    close(
        &format!("{} γ vs −(X(h) − X(−h))/2h, X = J v + Φ_t along (q(t), t)", Fa::NAME),
        gamma.as_slice(),
        (-fd).as_slice(),
        1e-8,
        &mag,
    )?;
    Ok(max_abs(fd.as_slice()))
}

/// Drivers (and the cable): Φ_t against a central difference in the state's time,
/// and the time terms of γ, `γ − γ|frozen = −2Φ_qt q̇ − Φ_tt`, against differences of
/// Φ_t along (q(t), t) plus J v in t alone. Returns the size of the time terms.
fn check_time_terms<Fa: Family<R, C>, const R: usize, const C: usize>(k: &Case) -> Result<f64, TestCaseError> {
    let tf = k.sine_tf();
    let j = joint::<Fa, R, C>(&k.p, tf);
    let s0 = state::<Fa, R, C, f64>(&k.c, k.t0);
    if Fa::TIME == TimeKind::None {
        prop_assert!(j.phi_t(&s0).iter().all(|&x| x == 0.0), "phi_t of an undriven joint is not zero");
        return Ok(0.0);
    }
    let h = 1e-5;
    let (jv_mag, gamma_mag) = jv_gamma_magnitude::<Fa, R, C>(k, tf);
    let name = Fa::NAME;
    // Φ_t by a central difference in the state's time, q fixed.
    let phi_at = |t: f64| j.phi(&state::<Fa, R, C, f64>(&k.c, t));
    let fd = (phi_at(k.t0 + h) - phi_at(k.t0 - h)) / (2.0 * h);
    close(&format!("{name} Φ_t vs (Φ(t + h) − Φ(t − h))/2h"), j.phi_t(&s0).as_slice(), fd.as_slice(), 1e-8, &jv_mag)?;
    // The time terms: γ with the driver moving minus γ with it frozen at its value.
    let d = k.sine.eval(k.t0);
    let gamma_frozen = joint::<Fa, R, C>(&k.p, frozen(d.value)).gamma(&s0);
    let terms = j.gamma(&s0) - gamma_frozen;
    let phi_t_path =
        |t: f64| rate_at::<Fa, R, C>(k, tf, t, true, true, true) - rate_at::<Fa, R, C>(k, tf, t, true, true, false);
    let jv_time = |t: f64| rate_at::<Fa, R, C>(k, tf, t, false, true, false);
    let fd = (phi_t_path(h) - phi_t_path(-h) + jv_time(h) - jv_time(-h)) / (2.0 * h);
    close(
        &format!("{name} γ time terms vs −[d/dt Φ_t(q(t), t) + ∂_t(J) v] by differences"),
        terms.as_slice(),
        (-fd).as_slice(),
        1e-8,
        &gamma_mag,
    )?;
    Ok(max_abs(terms.as_slice()))
}

/// `euler`: J = ∂Φ/∂q, one `Dual64` seed per coordinate `[r1, p1, r2, p2]` (θ at t0).
fn check_partials<Fa: Family<R, 14>, const R: usize>(k: &Case) -> Result<f64, TestCaseError> {
    let jac = joint::<Fa, R, 14>(&k.p, k.poly_tf()).jacobian(&state::<Fa, R, 14, f64>(&k.c, k.t0));
    let mag = magnitude(k, |k| {
        joint::<Fa, R, 14>(&k.p, k.poly_tf()).jacobian(&state::<Fa, R, 14, f64>(&k.c, k.t0)).as_slice().to_vec()
    });
    let jd = Fa::make(&k.p.map(Dual64::from_re), k.poly_tf());
    let mut largest = 0.0f64;
    for col in 0..14 {
        let mut c = k.c.map(Dual64::from_re);
        c.0[BODY * (col / 7) + col % 7].eps = 1.0;
        let d = jd.phi(&state::<Fa, R, 14, Dual64>(&c, k.t0)).map(|x| x.eps);
        largest = largest.max(max_abs(d.as_slice()));
        let got: Vec<f64> = jac.column(col).iter().copied().collect();
        let what = format!("{} euler J column {col} vs ∂Φ/∂q{col} (num-dual)", Fa::NAME);
        close(&what, &got, d.as_slice(), 1e-13, &mag[col * R..(col + 1) * R])?;
    }
    Ok(largest)
}

/// The property tests of one family, and a deterministic check that what they
/// compare is not trivially zero.
macro_rules! properties {
    ($test:ident, $fam:ty, $r:literal, $c:literal, $unit:literal $(, $partials:ident)?) => {
        mod $test {
            use super::*;
            proptest! {
                #![proptest_config(config())]
                #[test]
                fn phi_matches_reference_and_evaluate(k in case($unit)) {
                    check_phi::<$fam, $r, $c>(&k)?;
                }
                #[test]
                fn velocity_is_jv_plus_phi_t(k in case($unit)) {
                    check_velocity::<$fam, $r, $c>(&k)?;
                }
                #[test]
                fn gamma_is_minus_phi_ddot(k in case($unit)) {
                    check_gamma_dual::<$fam, $r, $c>(&k)?;
                    check_gamma_fd::<$fam, $r, $c>(&k)?;
                }
                #[test]
                fn time_terms(k in case($unit)) {
                    check_time_terms::<$fam, $r, $c>(&k)?;
                }
            }
            proptest! {
                #![proptest_config(ProptestConfig { cases: 8, ..config() })]
                #[test]
                fn second_order_matches_dual(k in case($unit)) {
                    second_order::check_second_order::<$fam, $r, $c>(&k)?;
                }
            }
            $(
                proptest! {
                    #![proptest_config(config())]
                    #[test]
                    fn $partials(k in case($unit)) {
                        check_partials::<$fam, $r>(&k)?;
                    }
                }
            )?
            #[test]
            fn not_vacuous() {
                for k in samples($unit) {
                    let rate = check_velocity::<$fam, $r, $c>(&k).unwrap();
                    let acc = check_gamma_dual::<$fam, $r, $c>(&k).unwrap();
                    let fd = check_gamma_fd::<$fam, $r, $c>(&k).unwrap();
                    let time = check_time_terms::<$fam, $r, $c>(&k).unwrap();
                    let second = second_order::check_second_order::<$fam, $r, $c>(&k).unwrap();
                    // Rows linear in the relative coordinates have none.
                    let linear = linear_in_relative::<$fam, $r, $c>()
                        || (relative_form::<$fam, $r, $c>() && <$fam as Family<$r, $c>>::NAME == "translational_driver");
                    assert!(if linear { second == 0.0 } else { second > 1e-3 }, "second-order terms = {second:e}");
                    assert!(rate > 1e-3, "dΦ/dt = {rate:e}");
                    if linear_in_relative::<$fam, $r, $c>() {
                        assert!(acc == 0.0 && fd < 1e-8, "Φ̈ = {acc:e}, FD = {fd:e}: expected 0");
                    } else {
                        assert!(acc > 1e-3 && fd > 1e-3, "Φ̈ = {acc:e}, FD = {fd:e}");
                    }
                    if <$fam as Family<$r, $c>>::TIME != TimeKind::None {
                        assert!(time > 1e-4, "time terms of γ = {time:e}");
                    }
                    $(
                        let _ = stringify!($partials);
                        assert!(check_partials::<$fam, $r>(&k).unwrap() > 1e-3);
                    )?
                }
            }
        }
    };
}

// ---------------------------------------------------------------------------
// The catalogue (spherical, universal and universal_translational are in
// derivatives.rs).
// ---------------------------------------------------------------------------

catalogue_joint!(revolute, revolute, 5, [f, g, h, rho1, rho2]);
catalogue_joint!(cylindrical, cylindrical, 4, [f, g, h, rho1, rho2]);
catalogue_joint!(translational, translational, 5, [f, g, h, k, rho1, rho2]);
catalogue_joint!(fixed, fixed, 6, [f, g, h, k, rho1, rho2]);
catalogue_joint!(planar, planar, 3, [f, g, n, h, rho1, rho2]);
catalogue_joint!(point_on_line, point_on_line, 2, [f, g, rho1, rho2]);
catalogue_joint!(point_in_plane, point_in_plane, 1, [n, rho1, rho2]);
catalogue_joint!(parallel, parallel, 2, [f, g, h]);
catalogue_joint!(perpendicular, perpendicular, 1, [s, h]);
catalogue_joint!(distance, distance, 1, [rho1, rho2], scalar length);
catalogue_joint!(rotational_driver, rotational_driver, 1, [f, g, k], time theta Trig);
catalogue_joint!(translational_driver, translational_driver, 1, [h, rho1, rho2], time x Linear);

// ---------------------------------------------------------------------------
// User-written rows.
// ---------------------------------------------------------------------------

pub(crate) mod user_rows;

// ---------------------------------------------------------------------------
// Axis parameters.
// ---------------------------------------------------------------------------

mod axes;

// ---------------------------------------------------------------------------
// Singularity measures.
// ---------------------------------------------------------------------------

mod singularity;

// ---------------------------------------------------------------------------
// Second-order terms.
// ---------------------------------------------------------------------------

mod second_order;
