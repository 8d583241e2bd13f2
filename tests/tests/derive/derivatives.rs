//! Independent derivative checks of the code `#[derive(Joint)]` generates.
//!
//! * J against num-dual: `euler` J = ∂Φ/∂q column by column; every formulation
//!   J v = dΦ/dt along an exact trajectory with constant velocities.
//! * γ against the second derivative along that trajectory (`Dual2_64`, exact) and
//!   against a central finite difference of J v (`Φ̈ = −γ` when `v̇ = 0`).
//! * `evaluate` against the separate `phi`, `jacobian`, `gamma`.
//! * Constant-folded, grounded and `SlidingFrame` variants against the general code.
//! * f32 and `WideF64x4` scalars against f64.
//!
//! The trajectories, states and comparisons are [`joint_tests::trajectory`]'s.

use joint_runtime::nalgebra::{SVector, Scalar, SimdRealField, SimdValue, Vector3};
use joint_runtime::{Joint, OneBody, SlidingFrame, perpendicular_pair};
use joint_tests::second_order::{joint_by_duals, joint_generated};
use joint_tests::trajectory::{
    BODY, Coords, Euler, Flat, Form, OmegaBodyF, OmegaInertial, RelB1, RelB2, along, bitwise, close, coords_from,
    matvec, max_abs,
};
use joint_tests::vector_views;
use num_dual::{Dual2_64, Dual64};
use proptest::prelude::*;
use proptest::strategy::ValueTree;
use proptest::test_runner::TestCaseError;
use simba::simd::WideF64x4;

type Res = Result<(), TestCaseError>;
/// A passed check with the size of what it compared (for the non-vacuity tests).
type Mag = Result<f64, TestCaseError>;

/// `s, h, b, c, rho1, rho2`.
type Params<T> = Flat<T, 18>;

vector_views! {
    /// Named views of [`Params`].
    trait ParamViews for 18 { s = 0, h = 3, b = 6, c = 9, rho1 = 12, rho2 = 15 }
}

/// Four f64 arrays as one array of `WideF64x4` lanes.
fn lanes<const N: usize>(xs: [&Flat<f64, N>; 4]) -> Flat<WideF64x4, N> {
    Flat(core::array::from_fn(|i| {
        let mut w = WideF64x4::splat(0.0);
        for (l, x) in xs.iter().enumerate() {
            w.replace(l, x.0[i]);
        }
        w
    }))
}

// ---------------------------------------------------------------------------
// Joint declarations.
// ---------------------------------------------------------------------------

/// Builds a joint struct from the parameter array.
trait Make<T> {
    fn make(p: &Params<T>) -> Self;
}

/// A derived joint together with its formulation, for every scalar.
trait Family<const R: usize, const C: usize> {
    type F: Form<C>;
    type J<T: SimdRealField + Copy>: Joint<T, R, C, State = <Self::F as Form<C>>::State<T>> + Make<T>;
}

macro_rules! joint {
    ($name:ident, [$($attr:tt)*], [$($p:ident),*]) => {
        #[derive(Joint, Clone, Debug)]
        #[joint($($attr)*)]
        struct $name<T> {
            $($p: Vector3<T>),*
        }
        impl<T: SimdRealField + Copy> Make<T> for $name<T> {
            fn make(p: &Params<T>) -> Self {
                $name { $($p: p.$p()),* }
            }
        }
    };
}

macro_rules! family {
    ($name:ident, $kind:ident, $form:ident, $F:ty, $r:literal, $c:literal, [$($p:ident),*]) => {
        joint!($name, [$kind, formulation = $form, second_order], [$($p),*]);
        impl Family<$r, $c> for $name<f64> {
            type F = $F;
            type J<T: SimdRealField + Copy> = $name<T>;
        }
    };
}

family!(SphEuler, spherical, euler, Euler, 3, 14, [rho1, rho2]);
family!(SphOmegaI, spherical, omega_inertial, OmegaInertial, 3, 12, [rho1, rho2]);
family!(SphOmegaB, spherical, omega_body, OmegaBodyF, 3, 12, [rho1, rho2]);
family!(SphRelB1, spherical, relative_b1, RelB1, 3, 6, [rho1, rho2]);
family!(SphRelB2, spherical, relative_b2, RelB2, 3, 6, [rho1, rho2]);

family!(UniEuler, universal, euler, Euler, 4, 14, [s, h, rho1, rho2]);
family!(UniOmegaI, universal, omega_inertial, OmegaInertial, 4, 12, [s, h, rho1, rho2]);
family!(UniOmegaB, universal, omega_body, OmegaBodyF, 4, 12, [s, h, rho1, rho2]);
family!(UniRelB1, universal, relative_b1, RelB1, 4, 6, [s, h, rho1, rho2]);
family!(UniRelB2, universal, relative_b2, RelB2, 4, 6, [s, h, rho1, rho2]);

family!(UtEuler, universal_translational, euler, Euler, 3, 14, [s, h, b, c, rho1, rho2]);
family!(UtOmegaI, universal_translational, omega_inertial, OmegaInertial, 3, 12, [s, h, b, c, rho1, rho2]);
family!(UtOmegaB, universal_translational, omega_body, OmegaBodyF, 3, 12, [s, h, b, c, rho1, rho2]);
family!(UtRelB1, universal_translational, relative_b1, RelB1, 3, 6, [s, h, b, c, rho1, rho2]);
family!(UtRelB2, universal_translational, relative_b2, RelB2, 3, 6, [s, h, b, c, rho1, rho2]);

// ---------------------------------------------------------------------------
// Strategies and comparison helpers.
// ---------------------------------------------------------------------------

const CASES: u32 = 64;

fn config() -> ProptestConfig {
    // No regression files: this suite must not write into the source tree.
    // `PROPTEST_CASES` overrides the case count (for longer soak runs).
    let cases = std::env::var("PROPTEST_CASES").ok().and_then(|n| n.parse().ok()).unwrap_or(CASES);
    ProptestConfig { cases, failure_persistence: None, ..ProptestConfig::default() }
}

/// Random coordinates and velocities in [-2, 2]; Euler parameters made unit when `unit`.
fn coords(unit: bool) -> impl Strategy<Value = Coords<f64>> {
    prop::collection::vec(-2.0f64..2.0, 34).prop_map(move |v| coords_from(&v, unit))
}

fn params() -> impl Strategy<Value = Params<f64>> {
    prop::collection::vec(-2.0f64..2.0, 18).prop_map(|v| Flat(core::array::from_fn(|i| v[i])))
}

/// Eight fixed random cases (deterministic seed).
fn samples(unit: bool) -> Vec<(Coords<f64>, Params<f64>)> {
    let mut runner = proptest::test_runner::TestRunner::deterministic();
    let strategy = (coords(unit), params());
    (0..8).map(|_| strategy.new_tree(&mut runner).expect("strategy").current()).collect()
}

/// [`joint_tests::trajectory::magnitude`] over the coordinates and parameters.
fn magnitude(c: &Coords<f64>, p: &Params<f64>, f: impl Fn(&Coords<f64>, &Params<f64>) -> Vec<f64>) -> Vec<f64> {
    joint_tests::trajectory::magnitude(&(*c, *p), |(c, p), flip| (c.map(&mut *flip), p.map(flip)), |(c, p)| f(c, p))
}

fn state<Fa: Family<R, C>, const R: usize, const C: usize, T: SimdRealField + Copy>(
    c: &Coords<T>,
) -> <Fa::F as Form<C>>::State<T> {
    <Fa::F as Form<C>>::build(c, 0.0)
}

fn make<Fa: Family<R, C>, const R: usize, const C: usize, T: SimdRealField + Copy>(p: &Params<T>) -> Fa::J<T> {
    <Fa::J<T> as Make<T>>::make(p)
}

/// [`magnitude`] of J v.
fn jv_magnitude<Fa: Family<R, C>, const R: usize, const C: usize>(c: &Coords<f64>, p: &Params<f64>) -> Vec<f64> {
    magnitude(c, p, |c, p| {
        let jac = make::<Fa, R, C, f64>(p).jacobian(&state::<Fa, R, C, f64>(c));
        matvec(&jac, &<Fa::F as Form<C>>::velocity(c)).as_slice().to_vec()
    })
}

/// [`magnitude`] of γ.
fn gamma_magnitude<Fa: Family<R, C>, const R: usize, const C: usize>(c: &Coords<f64>, p: &Params<f64>) -> Vec<f64> {
    magnitude(c, p, |c, p| make::<Fa, R, C, f64>(p).gamma(&state::<Fa, R, C, f64>(c)).as_slice().to_vec())
}

/// The one case where γ is identically zero: the relative spherical joint, Φ = δ, linear in δ.
fn gamma_vanishes<Fa: Family<R, C>, const R: usize, const C: usize>() -> bool {
    <Fa::J<f64> as Joint<f64, R, C>>::KIND == "spherical" && C == 6
}

// ---------------------------------------------------------------------------
// The properties.
// ---------------------------------------------------------------------------

/// `euler`: J = ∂Φ/∂q, one `Dual64` seed per coordinate `[r1, p1, r2, p2]`.
fn check_partials<Fa: Family<R, 14, F = Euler>, const R: usize>(c0: &Coords<f64>, p: &Params<f64>) -> Mag {
    let jac = make::<Fa, R, 14, f64>(p).jacobian(&state::<Fa, R, 14, f64>(c0));
    let mag =
        magnitude(c0, p, |c, p| make::<Fa, R, 14, f64>(p).jacobian(&state::<Fa, R, 14, f64>(c)).as_slice().to_vec());
    let jd = make::<Fa, R, 14, Dual64>(&p.map(Dual64::from_re));
    let mut nonzero = 0;
    for k in 0..14 {
        let mut c = c0.map(Dual64::from_re);
        c.0[BODY * (k / 7) + k % 7].eps = 1.0;
        let d = jd.phi(&state::<Fa, R, 14, Dual64>(&c)).map(|x| x.eps);
        nonzero += d.iter().filter(|x| x.abs() > 1e-9).count();
        let col: Vec<f64> = jac.column(k).iter().copied().collect();
        let what = format!("euler J column {k} vs ∂Φ/∂q{k} (num-dual)");
        close(&what, &col, d.as_slice(), R, 1e-12, &mag[k * R..(k + 1) * R])?;
    }
    Ok(nonzero as f64)
}

/// J v = dΦ/dt along the exact trajectory (`Dual64` in t).
fn check_jv<Fa: Family<R, C>, const R: usize, const C: usize>(c0: &Coords<f64>, p: &Params<f64>) -> Mag {
    let rot = <Fa::F as Form<C>>::ROT;
    let j = make::<Fa, R, C, f64>(p);
    let s0 = state::<Fa, R, C, f64>(&along(c0, rot, 0.0));
    let jv = matvec(&j.jacobian(&s0), &<Fa::F as Form<C>>::velocity(c0));
    let jd = make::<Fa, R, C, Dual64>(&p.map(Dual64::from_re));
    let t = Dual64::from_re(0.0).derivative();
    let phi = jd.phi(&state::<Fa, R, C, Dual64>(&along(c0, rot, t)));
    let (re, rate) = (phi.map(|x| x.re), phi.map(|x| x.eps));
    close("Φ on the trajectory at t = 0", re.as_slice(), j.phi(&s0).as_slice(), R, 1e-14, &[])?;
    close("J v vs dΦ/dt (num-dual)", jv.as_slice(), rate.as_slice(), R, 1e-12, &jv_magnitude::<Fa, R, C>(c0, p))?;
    Ok(max_abs(rate.as_slice()))
}

/// Φ̈ = −γ along the trajectory with constant v (`Dual2_64` in t, exact).
fn check_gamma_dual<Fa: Family<R, C>, const R: usize, const C: usize>(c0: &Coords<f64>, p: &Params<f64>) -> Mag {
    let rot = <Fa::F as Form<C>>::ROT;
    let j = make::<Fa, R, C, f64>(p);
    let s0 = state::<Fa, R, C, f64>(&along(c0, rot, 0.0));
    let gamma = j.gamma(&s0);
    let jd = make::<Fa, R, C, Dual2_64>(&p.map(Dual2_64::from_re));
    let t = Dual2_64::from_re(0.0).derivative();
    let phi = jd.phi(&state::<Fa, R, C, Dual2_64>(&along(c0, rot, t)));
    let jv = matvec(&j.jacobian(&s0), &<Fa::F as Form<C>>::velocity(c0));
    let rate = phi.map(|x| x.v1);
    close("J v vs dΦ/dt (Dual2)", jv.as_slice(), rate.as_slice(), R, 1e-12, &jv_magnitude::<Fa, R, C>(c0, p))?;
    let minus_acc = phi.map(|x| -x.v2);
    if gamma_vanishes::<Fa, R, C>() {
        prop_assert!(
            gamma.iter().chain(minus_acc.iter()).all(|&x| x == 0.0),
            "γ = {:?}, −Φ̈ = {:?}: expected 0",
            gamma,
            minus_acc
        );
    }
    let mag = gamma_magnitude::<Fa, R, C>(c0, p);
    close("γ vs −Φ̈ (num-dual Dual2)", gamma.as_slice(), minus_acc.as_slice(), R, 1e-12, &mag)?;
    Ok(max_abs(minus_acc.as_slice()))
}

/// γ = −d(J v)/dt by a central difference of J(q(t)) v at t = ±h.
fn check_gamma_fd<Fa: Family<R, C>, const R: usize, const C: usize>(c0: &Coords<f64>, p: &Params<f64>) -> Mag {
    let rot = <Fa::F as Form<C>>::ROT;
    let h = 1e-5;
    let j = make::<Fa, R, C, f64>(p);
    let v = <Fa::F as Form<C>>::velocity(c0);
    let jv_at = |t: f64| matvec(&j.jacobian(&state::<Fa, R, C, f64>(&along(c0, rot, t))), &v);
    let fd = (jv_at(h) - jv_at(-h)) / (2.0 * h);
    let gamma = j.gamma(&state::<Fa, R, C, f64>(c0));
    let mag = gamma_magnitude::<Fa, R, C>(c0, p);
    close("γ vs −(J(h) v − J(−h) v)/2h", gamma.as_slice(), (-fd).as_slice(), R, 1e-6, &mag)?;
    Ok(max_abs(fd.as_slice()))
}

/// `evaluate` gives the same numbers as `phi`, `jacobian` and `gamma`, bitwise.
fn check_evaluate<Fa: Family<R, C>, const R: usize, const C: usize>(c0: &Coords<f64>, p: &Params<f64>) -> Res {
    let j = make::<Fa, R, C, f64>(p);
    let s = state::<Fa, R, C, f64>(c0);
    let e = j.evaluate(&s);
    bitwise("evaluate().phi vs phi()", e.phi.as_slice(), j.phi(&s).as_slice(), R)?;
    bitwise("evaluate().jacobian vs jacobian()", e.jacobian.as_slice(), j.jacobian(&s).as_slice(), R)?;
    bitwise("evaluate().gamma vs gamma()", e.gamma.as_slice(), j.gamma(&s).as_slice(), R)?;
    // Φ_t is zero for these undriven joints.
    prop_assert!(j.phi_t(&s).iter().all(|&x| x == 0.0), "phi_t of an undriven joint is not zero");
    Ok(())
}

/// f32 agrees with f64 (evaluated at the same, f32-rounded, inputs) to ~1e-5.
fn check_f32<Fa: Family<R, C>, const R: usize, const C: usize>(c0: &Coords<f64>, p: &Params<f64>) -> Res {
    let (c32, p32) = (c0.map(|x| x as f32), p.map(|x| x as f32));
    let (c64, p64) = (c32.map(f64::from), p32.map(f64::from));
    let j32 = make::<Fa, R, C, f32>(&p32);
    let s32 = state::<Fa, R, C, f32>(&c32);
    let j64 = make::<Fa, R, C, f64>(&p64);
    let s64 = state::<Fa, R, C, f64>(&c64);
    let up = |v: &[f32]| v.iter().map(|&x| f64::from(x)).collect::<Vec<f64>>();
    let e32 = j32.evaluate(&s32);
    let e64 = j64.evaluate(&s64);
    let tol = 1e-5;
    let mag = |k: usize| {
        magnitude(&c64, &p64, |c, p| {
            let e = make::<Fa, R, C, f64>(p).evaluate(&state::<Fa, R, C, f64>(c));
            [e.phi.as_slice(), e.jacobian.as_slice(), e.gamma.as_slice()][k].to_vec()
        })
    };
    let separate = [j32.phi(&s32).as_slice(), j32.jacobian(&s32).as_slice(), j32.gamma(&s32).as_slice()].map(up);
    let fused = [e32.phi.as_slice(), e32.jacobian.as_slice(), e32.gamma.as_slice()].map(up);
    let want = [e64.phi.as_slice(), e64.jacobian.as_slice(), e64.gamma.as_slice()];
    for (k, name) in ["phi", "jacobian", "gamma"].into_iter().enumerate() {
        let m = mag(k);
        close(&format!("f32 {name}"), &separate[k], want[k], R, tol, &m)?;
        close(&format!("f32 evaluate().{name}"), &fused[k], want[k], R, tol, &m)?;
    }
    Ok(())
}

/// Four different states and joints in the lanes of `WideF64x4`: each lane equals the scalar f64 result bitwise.
fn check_wide<Fa: Family<R, C>, const R: usize, const C: usize>(cs: &[Coords<f64>; 4], ps: &[Params<f64>; 4]) -> Res {
    let jw = make::<Fa, R, C, WideF64x4>(&lanes([&ps[0], &ps[1], &ps[2], &ps[3]]));
    let sw = state::<Fa, R, C, WideF64x4>(&lanes([&cs[0], &cs[1], &cs[2], &cs[3]]));
    let (phi, jac, gamma, e) = (jw.phi(&sw), jw.jacobian(&sw), jw.gamma(&sw), jw.evaluate(&sw));
    for l in 0..4 {
        let j = make::<Fa, R, C, f64>(&ps[l]);
        let s = state::<Fa, R, C, f64>(&cs[l]);
        let lane = |x: &WideF64x4| x.extract(l);
        let what = |f: &str| format!("WideF64x4 lane {l} {f}");
        bitwise(&what("phi"), phi.map(|x| lane(&x)).as_slice(), j.phi(&s).as_slice(), R)?;
        bitwise(&what("jacobian"), jac.map(|x| lane(&x)).as_slice(), j.jacobian(&s).as_slice(), R)?;
        bitwise(&what("gamma"), gamma.map(|x| lane(&x)).as_slice(), j.gamma(&s).as_slice(), R)?;
        let e64 = j.evaluate(&s);
        bitwise(&what("evaluate().phi"), e.phi.map(|x| lane(&x)).as_slice(), e64.phi.as_slice(), R)?;
        bitwise(&what("evaluate().jacobian"), e.jacobian.map(|x| lane(&x)).as_slice(), e64.jacobian.as_slice(), R)?;
        bitwise(&what("evaluate().gamma"), e.gamma.map(|x| lane(&x)).as_slice(), e64.gamma.as_slice(), R)?;
    }
    Ok(())
}

/// The generated second-order terms against num-dual over the generated J
/// and γ ([`joint_tests::second_order::joint_by_duals`]), to 256 ε times the
/// monomial scale; returns the largest entry compared.
fn check_second_order<Fa: Family<R, C>, const R: usize, const C: usize>(c: &Coords<f64>, p: &Params<f64>) -> Mag {
    let lambda = SVector::<f64, R>::from_fn(|i, _| 1.0 + p.0[(7 * i + 2) % 18]);
    let u = SVector::<f64, C>::from_fn(|i, _| c.0[(5 * i + 3) % 34]);
    let generated = |c: &Coords<f64>, p: &Params<f64>| {
        joint_generated(&make::<Fa, R, C, f64>(p), &state::<Fa, R, C, f64>(c), &lambda, &u)
    };
    let jd = make::<Fa, R, C, Dual64>(&p.map(Dual64::from_re));
    let want = joint_by_duals::<Fa::F, _, R, C>(&jd, c, 0.0, &lambda, &u);
    let mag = magnitude(c, p, generated);
    let what = format!("{} second-order terms vs num-dual", <Fa::J<f64> as Joint<f64, R, C>>::KIND);
    close(&what, &generated(c, p), &want, C, 256.0 * f64::EPSILON, &mag)?;
    Ok(max_abs(&want))
}

/// The generated second-order terms on every conformance state of these
/// three joints (`vectors.json` and `hard.json`, the repository's copies).
#[test]
fn second_order_on_the_conformance_states() {
    let mut checked = 0;
    for file in ["vectors.json", "hard.json"] {
        for case in joint_tests::conformance::vectors(file).cases {
            let c = case.state.coords().unwrap_or_else(|e| panic!("{}: {e}", case.id));
            let q = &case.params;
            let mut p = Flat([0.0; 18]);
            for (o, x) in [(0, q.s), (3, q.h), (6, q.b), (9, q.c), (12, q.rho1), (15, q.rho2)] {
                p.set(o, &x.unwrap_or([0.0; 3]));
            }
            macro_rules! dispatch {
                ($($joint:literal => [$e:ident, $oi:ident, $ob:ident, $r1:ident, $r2:ident; $r:literal]),*) => {
                    match (case.joint.as_str(), case.formulation.as_str()) {
                        $(
                            ($joint, "euler") => check_second_order::<$e<f64>, $r, 14>(&c, &p),
                            ($joint, "omega_inertial") => check_second_order::<$oi<f64>, $r, 12>(&c, &p),
                            ($joint, "omega_body") => check_second_order::<$ob<f64>, $r, 12>(&c, &p),
                            ($joint, "relative_b1") => check_second_order::<$r1<f64>, $r, 6>(&c, &p),
                            ($joint, "relative_b2") => check_second_order::<$r2<f64>, $r, 6>(&c, &p),
                        )*
                        _ => continue,
                    }
                };
            }
            let result = dispatch!(
                "spherical" => [SphEuler, SphOmegaI, SphOmegaB, SphRelB1, SphRelB2; 3],
                "universal" => [UniEuler, UniOmegaI, UniOmegaB, UniRelB1, UniRelB2; 4],
                "universal_translational" => [UtEuler, UtOmegaI, UtOmegaB, UtRelB1, UtRelB2; 3]
            );
            result.unwrap_or_else(|e| panic!("{}: {e}", case.id));
            checked += 1;
        }
    }
    println!("second-order terms checked on {checked} conformance states");
    assert!(checked >= 15, "{checked} cases");
}

macro_rules! properties {
    ($module:ident, $fam:ty, $r:literal, $c:literal, unit = $unit:literal) => {
        mod $module {
            use super::*;
            proptest! {
                #![proptest_config(config())]
                #[test]
                fn jv_is_dphi_dt(c in coords($unit), p in params()) {
                    check_jv::<$fam, $r, $c>(&c, &p)?;
                }
                #[test]
                fn gamma_is_minus_phi_ddot_dual2(c in coords($unit), p in params()) {
                    check_gamma_dual::<$fam, $r, $c>(&c, &p)?;
                }
                #[test]
                fn gamma_is_finite_difference_of_jv(c in coords($unit), p in params()) {
                    check_gamma_fd::<$fam, $r, $c>(&c, &p)?;
                }
                #[test]
                fn evaluate_matches_separate_functions(c in coords($unit), p in params()) {
                    check_evaluate::<$fam, $r, $c>(&c, &p)?;
                }
                #[test]
                fn f32_matches_f64(c in coords($unit), p in params()) {
                    check_f32::<$fam, $r, $c>(&c, &p)?;
                }
                #[test]
                fn second_order_matches_dual(c in coords($unit), p in params()) {
                    check_second_order::<$fam, $r, $c>(&c, &p)?;
                }
                #[test]
                fn wide_f64x4_lanes_match_f64(
                    cs in prop::array::uniform4(coords($unit)),
                    ps in prop::array::uniform4(params()),
                ) {
                    check_wide::<$fam, $r, $c>(&cs, &ps)?;
                }
            }

            /// The compared quantities are not trivially zero (γ is, exactly, for the
            /// relative spherical joint, which the checks assert).
            #[test]
            fn checks_are_not_vacuous() {
                for (c, p) in samples($unit) {
                    let rate = check_jv::<$fam, $r, $c>(&c, &p).unwrap();
                    let acc = check_gamma_dual::<$fam, $r, $c>(&c, &p).unwrap();
                    let fd = check_gamma_fd::<$fam, $r, $c>(&c, &p).unwrap();
                    let second = check_second_order::<$fam, $r, $c>(&c, &p).unwrap();
                    assert!(rate > 1e-3, "dΦ/dt = 0");
                    assert!((second == 0.0) == gamma_vanishes::<$fam, $r, $c>(), "second-order terms = {second:e}");
                    if gamma_vanishes::<$fam, $r, $c>() {
                        assert!(acc == 0.0 && fd < 1e-9, "Φ̈ = {acc:e}, FD = {fd:e}: expected 0");
                    } else {
                        assert!(acc > 1e-3 && fd > 1e-3, "Φ̈ = {acc:e}, FD = {fd:e}");
                    }
                }
            }
        }
    };
}

properties!(spherical_euler, SphEuler<f64>, 3, 14, unit = false);
properties!(spherical_omega_inertial, SphOmegaI<f64>, 3, 12, unit = true);
properties!(spherical_omega_body, SphOmegaB<f64>, 3, 12, unit = true);
properties!(spherical_relative_b1, SphRelB1<f64>, 3, 6, unit = true);
properties!(spherical_relative_b2, SphRelB2<f64>, 3, 6, unit = true);
properties!(universal_euler, UniEuler<f64>, 4, 14, unit = false);
properties!(universal_omega_inertial, UniOmegaI<f64>, 4, 12, unit = true);
properties!(universal_omega_body, UniOmegaB<f64>, 4, 12, unit = true);
properties!(universal_relative_b1, UniRelB1<f64>, 4, 6, unit = true);
properties!(universal_relative_b2, UniRelB2<f64>, 4, 6, unit = true);
properties!(universal_translational_euler, UtEuler<f64>, 3, 14, unit = false);
properties!(universal_translational_omega_inertial, UtOmegaI<f64>, 3, 12, unit = true);
properties!(universal_translational_omega_body, UtOmegaB<f64>, 3, 12, unit = true);
properties!(universal_translational_relative_b1, UtRelB1<f64>, 3, 6, unit = true);
properties!(universal_translational_relative_b2, UtRelB2<f64>, 3, 6, unit = true);

#[test]
fn euler_jacobian_checks_are_not_vacuous() {
    for (c, p) in samples(false) {
        assert!(check_partials::<SphEuler<f64>, 3>(&c, &p).unwrap() >= 3.0);
        assert!(check_partials::<UniEuler<f64>, 4>(&c, &p).unwrap() >= 4.0);
        assert!(check_partials::<UtEuler<f64>, 3>(&c, &p).unwrap() >= 3.0);
    }
}

proptest! {
    #![proptest_config(config())]
    #[test]
    fn spherical_euler_jacobian_is_dphi_dq(c in coords(false), p in params()) {
        check_partials::<SphEuler<f64>, 3>(&c, &p)?;
    }
    #[test]
    fn universal_euler_jacobian_is_dphi_dq(c in coords(false), p in params()) {
        check_partials::<UniEuler<f64>, 4>(&c, &p)?;
    }
    #[test]
    fn universal_translational_euler_jacobian_is_dphi_dq(c in coords(false), p in params()) {
        check_partials::<UtEuler<f64>, 3>(&c, &p)?;
    }
}

// ---------------------------------------------------------------------------
// Constant-folded, grounded and sliding-frame variants against the general code.
// ---------------------------------------------------------------------------

/// The outputs of `phi`, `jacobian`, `gamma` and `evaluate`, flattened (Jacobian column-major).
fn outputs<J: Joint<f64, R, C>, const R: usize, const C: usize>(j: &J, s: &J::State) -> [Vec<f64>; 6] {
    let e = j.evaluate(s);
    [
        j.phi(s).as_slice().to_vec(),
        j.jacobian(s).as_slice().to_vec(),
        j.gamma(s).as_slice().to_vec(),
        e.phi.as_slice().to_vec(),
        e.jacobian.as_slice().to_vec(),
        e.gamma.as_slice().to_vec(),
    ]
}

const OUTPUT_NAMES: [&str; 6] =
    ["phi", "jacobian", "gamma", "evaluate().phi", "evaluate().jacobian", "evaluate().gamma"];

/// The tolerance for variants that may fold constants in a different order: a few ulp of the scale.
const FOLD_TOL: f64 = 8.0 * f64::EPSILON;

/// Compares two sets of outputs entry by entry within `FOLD_TOL · (1 + max(max, mag))`.
fn same_outputs(what: &str, got: &[Vec<f64>; 6], want: &[Vec<f64>; 6], rows: usize, mag: &[Vec<f64>; 6]) -> Res {
    for (k, name) in OUTPUT_NAMES.iter().enumerate() {
        close(&format!("{what}: {name}"), &got[k], &want[k], rows, FOLD_TOL, &mag[k])?;
    }
    Ok(())
}

/// A variant `G` of the family `Fa` with the same state type gives the same numbers.
fn check_variant<Fa: Family<R, C>, G, const R: usize, const C: usize>(
    what: &str,
    c: &Coords<f64>,
    general: &Params<f64>,
    variant: &G,
) -> Mag
where
    G: Joint<f64, R, C, State = <Fa::F as Form<C>>::State<f64>>,
{
    let s = state::<Fa, R, C, f64>(c);
    let want = outputs(&make::<Fa, R, C, f64>(general), &s);
    let mag: [Vec<f64>; 6] = core::array::from_fn(|k| {
        magnitude(c, general, |c, p| outputs(&make::<Fa, R, C, f64>(p), &state::<Fa, R, C, f64>(c))[k].clone())
    });
    same_outputs(what, &outputs(variant, &s), &want, R, &mag)?;
    Ok(max_abs(&want[2]).min(max_abs(&want[1])))
}

/// A property test of one variant against the general joint, plus a deterministic
/// check that what it compares (min of max |γ|, max |J|) is not trivially zero.
macro_rules! variant_test {
    ($name:ident, $unit:literal, |$c:ident, $p:ident| $body:block) => {
        mod $name {
            use super::*;
            fn check(c: &Coords<f64>, p: &Params<f64>) -> Mag {
                let ($c, $p) = (*c, *p);
                $body
            }
            proptest! {
                #![proptest_config(config())]
                #[test]
                fn matches_general(c in coords($unit), p in params()) {
                    check(&c, &p)?;
                }
            }
            #[test]
            fn not_vacuous() {
                for (c, p) in samples($unit) {
                    assert!(check(&c, &p).unwrap() > 1e-3);
                }
            }
        }
    };
}

// universal with `s = [0, 0, 1], h = [1, 0, 0]` folded in.
joint!(UniConstEuler, [universal, formulation = euler, s = [0, 0, 1], h = [1, 0, 0]], [rho1, rho2]);
joint!(UniConstOmegaI, [universal, formulation = omega_inertial, s = [0, 0, 1], h = [1, 0, 0]], [rho1, rho2]);
joint!(UniConstOmegaB, [universal, formulation = omega_body, s = [0, 0, 1], h = [1, 0, 0]], [rho1, rho2]);
joint!(UniConstRelB1, [universal, formulation = relative_b1, s = [0, 0, 1], h = [1, 0, 0]], [rho1, rho2]);
joint!(UniConstRelB2, [universal, formulation = relative_b2, s = [0, 0, 1], h = [1, 0, 0]], [rho1, rho2]);

/// `p` with `s = [0, 0, 1]` and `h = [1, 0, 0]`.
fn with_cardan_axes(p: &Params<f64>) -> Params<f64> {
    let mut p = *p;
    p.set(0, &[0.0, 0.0, 1.0, 1.0, 0.0, 0.0]);
    p
}

// universal_translational with the constant sliding direction `d = [0.3, -0.5, 0.8]`.
joint!(UtConstDEuler, [universal_translational, formulation = euler, d = [0.3, -0.5, 0.8]], [s, h, rho1, rho2]);
joint!(UtConstDOmegaB, [universal_translational, formulation = omega_body, d = [0.3, -0.5, 0.8]], [s, h, rho1, rho2]);
joint!(UtConstDRelB1, [universal_translational, formulation = relative_b1, d = [0.3, -0.5, 0.8]], [s, h, rho1, rho2]);

/// `p` with `b, c` from `perpendicular_pair(d)`.
fn with_sliding_direction(p: &Params<f64>, d: &Vector3<f64>) -> Params<f64> {
    let (b, c) = perpendicular_pair(d).expect("nonzero d");
    let mut p = *p;
    p.set(6, b.as_slice());
    p.set(9, c.as_slice());
    p
}

/// universal_translational with a `SlidingFrame<T>` field `d`.
macro_rules! sliding_frame_joint {
    ($name:ident, $form:ident) => {
        #[derive(Joint, Clone, Debug)]
        #[joint(universal_translational, formulation = $form)]
        struct $name<T: Scalar> {
            s: Vector3<T>,
            h: Vector3<T>,
            d: SlidingFrame<T>,
            rho1: Vector3<T>,
            rho2: Vector3<T>,
        }
        impl $name<f64> {
            /// The joint of the parameters `p` sliding along `d`.
            fn new(p: &Params<f64>, d: Vector3<f64>) -> Self {
                let d = SlidingFrame::new(d).expect("nonzero d");
                $name { s: p.s(), h: p.h(), d, rho1: p.rho1(), rho2: p.rho2() }
            }
        }
    };
}

sliding_frame_joint!(UtFrameOmegaB, omega_body);
sliding_frame_joint!(UtFrameEuler, euler);
sliding_frame_joint!(UtFrameRelB2, relative_b2);

/// A random sliding direction (the `b` slot of the parameters), kept away from zero.
fn sliding_direction(p: &Params<f64>) -> Vector3<f64> {
    let d = p.b();
    if d.norm() > 0.1 { d } else { Vector3::new(0.3, -0.5, 0.8) }
}

variant_test!(universal_constant_axes_match_fields_euler, false, |c, p| {
    check_variant::<UniEuler<f64>, _, 4, 14>("const s, h (euler)", &c, &with_cardan_axes(&p), &UniConstEuler::make(&p))
});

variant_test!(universal_constant_axes_match_fields_omega_inertial, true, |c, p| {
    check_variant::<UniOmegaI<f64>, _, 4, 12>(
        "const s, h (omega_inertial)",
        &c,
        &with_cardan_axes(&p),
        &UniConstOmegaI::make(&p),
    )
});

variant_test!(universal_constant_axes_match_fields_omega_body, true, |c, p| {
    check_variant::<UniOmegaB<f64>, _, 4, 12>(
        "const s, h (omega_body)",
        &c,
        &with_cardan_axes(&p),
        &UniConstOmegaB::make(&p),
    )
});

variant_test!(universal_constant_axes_match_fields_relative_b1, true, |c, p| {
    check_variant::<UniRelB1<f64>, _, 4, 6>(
        "const s, h (relative_b1)",
        &c,
        &with_cardan_axes(&p),
        &UniConstRelB1::make(&p),
    )
});

variant_test!(universal_constant_axes_match_fields_relative_b2, true, |c, p| {
    check_variant::<UniRelB2<f64>, _, 4, 6>(
        "const s, h (relative_b2)",
        &c,
        &with_cardan_axes(&p),
        &UniConstRelB2::make(&p),
    )
});

variant_test!(universal_translational_constant_d_matches_perpendicular_pair_euler, false, |c, p| {
    let general = with_sliding_direction(&p, &Vector3::new(0.3, -0.5, 0.8));
    check_variant::<UtEuler<f64>, _, 3, 14>("const d (euler)", &c, &general, &UtConstDEuler::make(&p))
});

variant_test!(universal_translational_constant_d_matches_perpendicular_pair_omega_body, true, |c, p| {
    let general = with_sliding_direction(&p, &Vector3::new(0.3, -0.5, 0.8));
    check_variant::<UtOmegaB<f64>, _, 3, 12>("const d (omega_body)", &c, &general, &UtConstDOmegaB::make(&p))
});

variant_test!(universal_translational_constant_d_matches_perpendicular_pair_relative_b1, true, |c, p| {
    let general = with_sliding_direction(&p, &Vector3::new(0.3, -0.5, 0.8));
    check_variant::<UtRelB1<f64>, _, 3, 6>("const d (relative_b1)", &c, &general, &UtConstDRelB1::make(&p))
});

variant_test!(universal_translational_sliding_frame_field_matches_b_c_euler, false, |c, p| {
    let d = sliding_direction(&p);
    let variant = UtFrameEuler::new(&p, d);
    check_variant::<UtEuler<f64>, _, 3, 14>("SlidingFrame d (euler)", &c, &with_sliding_direction(&p, &d), &variant)
});

variant_test!(universal_translational_sliding_frame_field_matches_b_c_omega_body, true, |c, p| {
    let d = sliding_direction(&p);
    let variant = UtFrameOmegaB::new(&p, d);
    check_variant::<UtOmegaB<f64>, _, 3, 12>(
        "SlidingFrame d (omega_body)",
        &c,
        &with_sliding_direction(&p, &d),
        &variant,
    )
});

variant_test!(universal_translational_sliding_frame_field_matches_b_c_relative_b2, true, |c, p| {
    let d = sliding_direction(&p);
    let variant = UtFrameRelB2::new(&p, d);
    check_variant::<UtRelB2<f64>, _, 3, 6>(
        "SlidingFrame d (relative_b2)",
        &c,
        &with_sliding_direction(&p, &d),
        &variant,
    )
});

// Grounded joints: `ground = body1` keeps body 2's columns, `ground = body2` body 1's.
joint!(UniGround1Euler, [universal, formulation = euler, ground = body1], [s, h, rho1, rho2]);
joint!(UniGround2Euler, [universal, formulation = euler, ground = body2], [s, h, rho1, rho2]);
joint!(UniGround1OmegaI, [universal, formulation = omega_inertial, ground = body1], [s, h, rho1, rho2]);
joint!(UniGround2OmegaI, [universal, formulation = omega_inertial, ground = body2], [s, h, rho1, rho2]);
joint!(UniGround1OmegaB, [universal, formulation = omega_body, ground = body1], [s, h, rho1, rho2]);
joint!(UniGround2OmegaB, [universal, formulation = omega_body, ground = body2], [s, h, rho1, rho2]);
joint!(SphGround1OmegaB, [spherical, formulation = omega_body, ground = body1], [rho1, rho2]);
joint!(UtGround1Euler, [universal_translational, formulation = euler, ground = body1], [s, h, b, c, rho1, rho2]);
joint!(UtGround2OmegaB, [universal_translational, formulation = omega_body, ground = body2], [s, h, b, c, rho1, rho2]);

/// The grounded joint `G` at the free body equals the general joint `Fa` with body
/// `ground` (0 or 1) at `r = 0, p = [1, 0, 0, 0]` and at rest; its Jacobian is the
/// general one's columns of the free body.
fn check_ground<Fa, G, B, const R: usize, const C: usize, const CG: usize>(
    c0: &Coords<f64>,
    p: &Params<f64>,
    ground: usize,
    free_body: impl Fn(&<Fa::F as Form<C>>::State<f64>) -> B,
) -> Mag
where
    Fa: Family<R, C>,
    G: Joint<f64, R, CG, State = OneBody<B>> + Make<f64>,
{
    let mut c = *c0;
    c.set(BODY * ground, &[0.0; BODY]);
    c.0[BODY * ground + 3] = 1.0;
    let general = make::<Fa, R, C, f64>(p);
    let s = state::<Fa, R, C, f64>(&c);
    let grounded = G::make(p);
    let sg = OneBody::new(free_body(&s));
    let first = if ground == 0 { CG } else { 0 };
    let mut want = outputs(&general, &s);
    for k in [1, 4] {
        want[k] = want[k][first * R..(first + CG) * R].to_vec();
    }
    let no_mag: [Vec<f64>; 6] = Default::default();
    same_outputs(&format!("ground = body{}", ground + 1), &outputs(&grounded, &sg), &want, R, &no_mag)?;
    Ok(max_abs(&want[2]).min(max_abs(&want[1])))
}

variant_test!(universal_ground_body1_euler, false, |c, p| {
    check_ground::<UniEuler<f64>, UniGround1Euler<f64>, _, 4, 14, 7>(&c, &p, 0, |s| s.body2)
});

variant_test!(universal_ground_body2_euler, false, |c, p| {
    check_ground::<UniEuler<f64>, UniGround2Euler<f64>, _, 4, 14, 7>(&c, &p, 1, |s| s.body1)
});

variant_test!(universal_ground_body1_omega_inertial, true, |c, p| {
    check_ground::<UniOmegaI<f64>, UniGround1OmegaI<f64>, _, 4, 12, 6>(&c, &p, 0, |s| s.body2)
});

variant_test!(universal_ground_body2_omega_inertial, true, |c, p| {
    check_ground::<UniOmegaI<f64>, UniGround2OmegaI<f64>, _, 4, 12, 6>(&c, &p, 1, |s| s.body1)
});

variant_test!(universal_ground_body1_omega_body, true, |c, p| {
    check_ground::<UniOmegaB<f64>, UniGround1OmegaB<f64>, _, 4, 12, 6>(&c, &p, 0, |s| s.body2)
});

variant_test!(universal_ground_body2_omega_body, true, |c, p| {
    check_ground::<UniOmegaB<f64>, UniGround2OmegaB<f64>, _, 4, 12, 6>(&c, &p, 1, |s| s.body1)
});

variant_test!(spherical_ground_body1_omega_body, true, |c, p| {
    check_ground::<SphOmegaB<f64>, SphGround1OmegaB<f64>, _, 3, 12, 6>(&c, &p, 0, |s| s.body2)
});

variant_test!(universal_translational_ground_body1_euler, false, |c, p| {
    check_ground::<UtEuler<f64>, UtGround1Euler<f64>, _, 3, 14, 7>(&c, &p, 0, |s| s.body2)
});

variant_test!(universal_translational_ground_body2_omega_body, true, |c, p| {
    check_ground::<UtOmegaB<f64>, UtGround2OmegaB<f64>, _, 3, 12, 6>(&c, &p, 1, |s| s.body1)
});
