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
        #[joint($kind, formulation = $form)]
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
        #[joint($kind, formulation = $form)]
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
        #[joint($kind, formulation = $form)]
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

/// `rows(spherical, dot1(s, h))` against the catalogue `universal`, the constant
/// angle of the README and the cable whose length is a time function.
pub(crate) mod user_rows {
    use super::*;

    macro_rules! universal_pair {
        ($user:ident, $cat:ident, $form:ident) => {
            #[derive(Joint, Clone, Debug)]
            #[joint(rows(spherical, dot1(s, h)), formulation = $form)]
            pub(crate) struct $user<T> {
                #[joint(body1)]
                s: Vector3<T>,
                #[joint(body2)]
                h: Vector3<T>,
                rho1: Vector3<T>,
                rho2: Vector3<T>,
            }
            #[derive(Joint, Clone, Debug)]
            #[joint(universal, formulation = $form)]
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
            #[joint(rows(dot(s, h) - cos(alpha)), formulation = $form)]
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
    #[joint(rows(norm2(d) - l * l), formulation = euler)]
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
}

// ---------------------------------------------------------------------------
// Axis parameters.
// ---------------------------------------------------------------------------

/// Constant and `AxisFrame` axes against the general joint with the vectors of
/// `perpendicular_pair`.
mod axes {
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
}

// ---------------------------------------------------------------------------
// Singularity measures.
// ---------------------------------------------------------------------------

/// The generated measures against closed forms written with nalgebra.
mod singularity {
    use super::user_rows::{UniOB, UniOI, UniR2};
    use super::*;

    /// `(A1, A2, d)` of an absolute state (unit p) or a relative one (`A1 = I`).
    fn frames(c: &Coords<f64>, p: &Params<f64>, relative: bool) -> (Matrix3<f64>, Matrix3<f64>, Vector3<f64>) {
        if relative {
            (Matrix3::identity(), rotation_matrix(&c.p(0)), c.x(0))
        } else {
            let (a1, a2) = (rotation_matrix(&c.p(0)), rotation_matrix(&c.p(1)));
            (a1, a2, c.x(1) + a2 * p.rho2() - c.x(0) - a1 * p.rho1())
        }
    }

    fn sine_sq(a: Vector3<f64>, b: Vector3<f64>) -> f64 {
        a.cross(&b).norm_squared() / (a.norm_squared() * b.norm_squared())
    }

    fn check(what: &str, got: f64, want: f64) -> Res {
        prop_assert!(
            (got - want).abs() <= 1e-12 * (1.0 + want.abs()) && (-1e-12..=1.0 + 1e-12).contains(&got),
            "{what}: measure {got:e}, closed form {want:e}"
        );
        Ok(())
    }

    /// A joint and a state, probed for a `Singularity` impl at run time (autoref
    /// specialisation), so that a joint the README says has a measure but whose impl
    /// is missing fails a test instead of the whole file's compilation.
    #[allow(dead_code)] // Read only through `HasMeasure`, unused while no probed joint has a measure.
    struct Probe<'a, J, S, const R: usize, const C: usize>(&'a J, &'a S);

    #[allow(dead_code)] // As `Probe`.
    trait HasMeasure {
        fn measure_of(&self) -> Option<f64>;
    }
    impl<J: Singularity<f64, R, C, State = S>, S, const R: usize, const C: usize> HasMeasure for Probe<'_, J, S, R, C> {
        fn measure_of(&self) -> Option<f64> {
            Some(self.0.singularity(self.1))
        }
    }

    proptest! {
        #![proptest_config(config())]
        /// universal: sin² of the angle between A1 s and A2 h.
        #[test]
        fn universal_is_sine_squared(k in case(true)) {
            let (s, h) = (k.p.s(), k.p.h());
            for (rel, got) in [
                (false, UniOI::new(&k.p).singularity(&OmegaInertial::build(&k.c, k.t0))),
                (false, UniOB::new(&k.p).singularity(&OmegaBodyF::build(&k.c, k.t0))),
                (true, UniR2::new(&k.p).singularity(&RelB2::build(&k.c, k.t0))),
            ] {
                let (a1, a2, _) = frames(&k.c, &k.p, rel);
                check("universal", got, sine_sq(a1 * s, a2 * h))?;
            }
        }

        /// revolute (and the other `f, g, h` joints): cos² of the angle between A2 h and A1 (f × g).
        #[test]
        fn axis_alignment_is_cosine_squared(k in case(true)) {
            let (f, g, h) = (k.p.f(), k.p.g(), k.p.h());
            let cos_sq = |a1: Matrix3<f64>, a2: Matrix3<f64>| {
                let (n, h) = (a1 * f.cross(&g), a2 * h);
                let c = n.dot(&h);
                c * c / (n.norm_squared() * h.norm_squared())
            };
            let (a1, a2, _) = frames(&k.c, &k.p, false);
            let want = cos_sq(a1, a2);
            let s = OmegaBodyF::build(&k.c, k.t0);
            check("revolute omega_body", revolute::JointOb::new(&k.p).singularity(&s), want)?;
            check("cylindrical omega_body", cylindrical::JointOb::new(&k.p).singularity(&s), want)?;
            check("parallel omega_body", parallel::JointOb::new(&k.p).singularity(&s), want)?;
            let (a1, a2, _) = frames(&k.c, &k.p, true);
            check("revolute relative_b1", revolute::JointR1::new(&k.p).singularity(&RelB1::build(&k.c, k.t0)), cos_sq(a1, a2))?;
            // planar: the same measure, `n` playing no part.
            let (a1, a2, _) = frames(&k.c, &k.p, false);
            check("planar omega_inertial", planar::JointOi::new(&k.p).singularity(&OmegaInertial::build(&k.c, k.t0)), cos_sq(a1, a2))?;
        }

        /// translational, fixed: det[A1f × A2h, A1g × A2h, A1f × A2k]² / (|f|⁴ |g|² |h|⁴ |k|²).
        #[test]
        fn rotation_lock_is_normalised_determinant(k in case(true)) {
            let (f, g, h, kk) = (k.p.f(), k.p.g(), k.p.h(), k.p.k());
            let (a1, a2, _) = frames(&k.c, &k.p, false);
            let (f1, g1, h2, k2) = (a1 * f, a1 * g, a2 * h, a2 * kk);
            let det = f1.cross(&h2).dot(&g1.cross(&h2).cross(&f1.cross(&k2)));
            let want = det * det / (f.norm_squared().powi(2) * g.norm_squared() * h.norm_squared().powi(2) * kk.norm_squared());
            let s = OmegaInertial::build(&k.c, k.t0);
            check("translational", translational::JointOi::new(&k.p).singularity(&s), want)?;
            check("fixed", fixed::JointOi::new(&k.p).singularity(&s), want)?;
        }

        /// distance: |d|² / L² (README); see [`measure_of`] for how a missing impl fails.
        #[test]
        fn distance_is_separation_over_length(k in case(true)) {
            let mut p = k.p;
            p.0[24] = 0.5 + p.0[24].abs();
            let (_, _, d) = frames(&k.c, &p, false);
            let got = Probe::<_, _, 1, 12>(&distance::JointOb::new(&p), &OmegaBodyF::build(&k.c, k.t0)).measure_of();
            let want = d.norm_squared() / (p.sc() * p.sc());
            prop_assert!(got.is_some(), "distance (omega_body) has no `Singularity` impl; the README promises |d|²/L² = {want:e}");
            let got = got.unwrap_or(f64::NAN);
            prop_assert!((got - want).abs() <= 1e-12 * (1.0 + want), "distance: {got:e} vs {want:e}");
            let got = Probe::<_, _, 1, 6>(&distance::JointR1::new(&p), &RelB1::build(&k.c, k.t0)).measure_of().unwrap_or(f64::NAN);
            let want = k.c.x(0).norm_squared() / (p.sc() * p.sc());
            prop_assert!((got - want).abs() <= 1e-12 * (1.0 + want), "distance relative_b1: {got:e} vs {want:e}");
        }
    }

    /// The nominal geometry gives 1.
    #[test]
    fn nominal_geometry_gives_one() {
        let mut p: Params<f64> = Flat([0.0; 25]);
        // f = x, g = y (B1), h = z, k = y (B2), s = y: orthonormal, nominal.
        p.set(0, &[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0, 0.0]);
        p.set(15, &[0.0, 1.0, 0.0]);
        p.0[24] = 2.0;
        let mut c: Coords<f64> = Flat([0.0; 34]);
        c.0[3] = 1.0;
        c.0[BODY + 3] = 1.0;
        c.set(BODY, &[2.0, 0.0, 0.0]);
        let s = OmegaInertial::build(&c, 0.0);
        let one = |x: f64| (x - 1.0).abs() < 1e-15;
        assert!(one(revolute::JointOi::new(&p).singularity(&s)));
        assert!(one(translational::JointOi::new(&p).singularity(&s)));
        assert!(one(fixed::JointOi::new(&p).singularity(&s)));
        assert!(one(planar::JointOi::new(&p).singularity(&s)));
        assert!(one(perpendicular::JointOi::new(&p).singularity(&s)));
        assert!(
            Probe::<_, _, 1, 12>(&distance::JointOi::new(&p), &s).measure_of().is_none_or(one),
            "distance at |d| = L"
        );
        let mut u = p;
        u.set(6, &[0.0, 0.0, 1.0]);
        assert!(one(UniOI::new(&u).singularity(&s)));
        assert!(!<UniOI<f64> as Singularity<f64, 4, 12>>::ZERO_WHEN.is_empty());
    }

    /// A Cardan joint (README): yokes `s = y` on shaft 1, `h = z` on shaft 2, both
    /// shafts along x, joint point between them. Shaft 1 turned by ψ1 about x, shaft 2
    /// bent by β about z and turned by ψ2 about its own axis.
    fn cardan(beta: f64, psi1: f64, psi2: f64) -> (UniOB<f64>, TwoBodies<OmegaBody<f64>>) {
        let joint = UniOB {
            s: Vector3::y(),
            h: Vector3::z(),
            rho1: Vector3::new(0.5, 0.0, 0.0),
            rho2: Vector3::new(-0.5, 0.0, 0.0),
        };
        let q1 = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), psi1);
        let q2 = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), beta)
            * UnitQuaternion::from_axis_angle(&Vector3::x_axis(), psi2);
        let r2 = Vector3::new(0.5, 0.0, 0.0) - q2 * joint.rho2;
        let b1 = OmegaBody::from_rotation(Vector3::zeros(), &q1, Vector3::zeros(), Vector3::zeros());
        let b2 = OmegaBody::from_rotation(r2, &q2, Vector3::zeros(), Vector3::zeros());
        (joint, TwoBodies::new(b1, b2))
    }

    /// On an assembled Cardan (Φ = 0: tan ψ2 = tan ψ1 / cos β) the yokes stay
    /// perpendicular whatever the bend, so sin² of their angle is 1 even as β → 90°:
    /// the measure sees the rank of this joint's own rows (which a 90° bend does not
    /// reduce; J keeps its smallest singular value), not the mechanism's transmission
    /// singularity. The README's "(zero at a 90° shaft bend)" does not hold for an
    /// assembled joint (reported).
    #[test]
    fn assembled_cardan_bend_keeps_measure_one() {
        for beta_deg in [0.0f64, 30.0, 80.0, 89.0, 89.9] {
            for psi1 in [0.0f64, 0.4, 1.2, 2.5] {
                let beta = beta_deg.to_radians();
                let psi2 = f64::atan2(psi1.sin(), psi1.cos() * beta.cos());
                let (joint, state) = cardan(beta, psi1, psi2);
                let phi = joint.phi(&state);
                assert!(phi.norm() < 1e-14, "β = {beta_deg}°, ψ1 = {psi1}: Φ = {phi:?}");
                let m = joint.singularity(&state);
                assert!((m - 1.0).abs() < 1e-14, "β = {beta_deg}°, ψ1 = {psi1}: measure {m}");
                let sv = joint.jacobian(&state).svd(false, false).singular_values;
                assert!(sv.min() > 0.3, "β = {beta_deg}°: smallest singular value of J {}", sv.min());
            }
        }
    }

    /// Where the measure does go to 0: the yokes turned towards each other. Shaft 2
    /// turned by β about the shaft axis from the straight, assembled Cardan, so that
    /// `A2 h = (0, −sin β, cos β)` and the angle between the yokes is 90° − β:
    /// measure = sin²(90° − β) = cos²β, and Φ's dot-1 row = −sin β.
    #[test]
    fn yokes_turned_towards_each_other_give_cos_squared() {
        let mut last = 1.0;
        for beta_deg in [0.0f64, 45.0, 80.0, 89.0, 89.9, 89.99] {
            let beta = beta_deg.to_radians();
            let (joint, state) = cardan(0.0, 0.0, beta);
            let m = joint.singularity(&state);
            let want = beta.cos().powi(2);
            assert!((m - want).abs() <= 1e-15 + 1e-12 * want, "β = {beta_deg}°: measure {m:e}, cos²β = {want:e}");
            assert!(m <= last, "not decreasing at β = {beta_deg}°");
            last = m;
            assert!((joint.phi(&state)[3] + beta.sin()).abs() < 1e-15);
        }
        assert!(last < 1e-7);
    }

    /// revolute: B2 tilted by β about an axis perpendicular to the joint axis (h = z
    /// in B2, f = x, g = y in B1): measure = cos²β → 0 as h falls into the f, g plane.
    #[test]
    fn revolute_tilt_gives_cos_squared() {
        let mut p: Params<f64> = Flat([0.0; 25]);
        p.set(0, &[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]);
        for beta_deg in [0.0f64, 80.0, 89.0, 89.9] {
            let beta = beta_deg.to_radians();
            let q2 = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), beta);
            let b1 = OmegaBody::from_rotation(
                Vector3::zeros(),
                &UnitQuaternion::identity(),
                Vector3::zeros(),
                Vector3::zeros(),
            );
            let b2 = OmegaBody::from_rotation(Vector3::zeros(), &q2, Vector3::zeros(), Vector3::zeros());
            let m = revolute::JointOb::new(&p).singularity(&TwoBodies::new(b1, b2));
            let want = beta.cos().powi(2);
            assert!((m - want).abs() <= 1e-15 + 1e-12 * want, "β = {beta_deg}°: measure {m:e}, cos²β = {want:e}");
        }
    }
}
