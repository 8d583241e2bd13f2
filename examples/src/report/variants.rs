//! The evaluation level of the report: Φ, J and γ of one joint computed five
//! ways, each timed and checked against the 60-digit conformance vectors in the
//! same run.
//!
//! | variant | Φ | J | γ |
//! |---|---|---|---|
//! | generated f64 | `evaluate` | `evaluate` | `evaluate` |
//! | generated f32 | `evaluate` at f32 | | |
//! | hand-written | [`super::handwritten`] (nalgebra, f64) | | |
//! | num-dual | real part | dual parts of Φ (one direction per velocity column) | `−Φ̈` along the exact trajectory (`Dual2_64`) |
//! | central differences | generated `phi` | `(Φ(+h) − Φ(−h)) / 2h` per column | `−(Φ(h) − 2Φ(0) + Φ(−h)) / h²` along the trajectory |
//!
//! For `euler` a velocity column is a coordinate (`J = ∂Φ/∂q`). For the ω and
//! relative formulations it is a direction of motion: `r + ṙ t` for a
//! translational column, `q(ω t) ⊗ p0` (ω in the reference frame:
//! `omega_inertial`, `relative_b1`) or `p0 ⊗ q(ω' t)` (ω' in the moving body:
//! `omega_body`, `relative_b2`) for a rotational one. num-dual seeds the tangent of
//! that trajectory, `q ≈ [1, ω t / 2]`, which is exact to first order; central
//! differences use the exact rotation by ±h about each axis (its quaternion
//! computed once per step size). γ is minus the second derivative of Φ along the
//! trajectory with every velocity held (`CONVENTIONS.md`: `J v̇ = γ` with
//! `v̇ = 0`); the second central difference is the central difference of the
//! central-difference `J v` (steps h/2 … folded into one).
//!
//! Errors are the conformance test's units, worst `|error| / (ε · scale)` over the
//! cases ([`joint_tests::conformance::case_error`]); f32 in units of
//! `ε₃₂ · scale` (`ε₃₂ = 2⁻²³`). Times are the median ns per evaluation of Φ, J
//! and γ together over the same states, with a calibrated repetition count.

use std::hint::black_box;
use std::time::Instant;

use joint_runtime::Joint;
use joint_runtime::nalgebra::{Const, SMatrix, SVector, SimdRealField, U1, Vector3, Vector4};
use joint_tests::conformance::{self, EPS, Output, VectorFile, case_error};
use joint_tests::joints;
use joint_tests::trajectory::{BODY, Coords, Euler, Form, OmegaBodyF, OmegaInertial, RelB1, RelB2, Rot, along};
use joint_tests::trajectory::{lift, quat_mul};
use num_dual::{Derivative, Dual2_64, DualSVec64};

use super::counting::{Counted, ToCounted, count};
use super::handwritten;

/// `ε₃₂ = 2⁻²³`, the unit of the f32 errors.
pub const EPS32: f64 = f32::EPSILON as f64;

/// The central-difference step sizes of the sweep, from coarse to fine.
pub const FD_STEPS: [f64; 9] = [1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10];

/// The joints and formulations measured, in report order.
pub const GROUPS: [(&str, &str); 16] = [
    ("universal", "euler"),
    ("universal", "omega_inertial"),
    ("universal", "omega_body"),
    ("universal", "relative_b1"),
    ("universal", "relative_b2"),
    ("universal_translational", "euler"),
    ("universal_translational", "omega_inertial"),
    ("universal_translational", "omega_body"),
    ("universal_translational", "relative_b1"),
    ("universal_translational", "relative_b2"),
    ("spherical", "euler"),
    ("spherical", "omega_body"),
    ("revolute", "euler"),
    ("revolute", "omega_body"),
    ("translational", "euler"),
    ("translational", "omega_body"),
];

// ---------------------------------------------------------------------------
// Cases: parameters and coordinates read from the vectors.
// ---------------------------------------------------------------------------

/// Every parameter a measured joint can have (unused ones stay zero).
#[derive(Clone, Copy, Debug)]
pub struct Params<T> {
    /// `s` (B1).
    pub s: Vector3<T>,
    /// `h` (B2).
    pub h: Vector3<T>,
    /// `b` (B1).
    pub b: Vector3<T>,
    /// `c` (B1).
    pub c: Vector3<T>,
    /// `f` (B1).
    pub f: Vector3<T>,
    /// `g` (B1).
    pub g: Vector3<T>,
    /// `k` (B2).
    pub k: Vector3<T>,
    /// `rho1` (B1).
    pub rho1: Vector3<T>,
    /// `rho2` (B2).
    pub rho2: Vector3<T>,
}

impl From<&conformance::Params> for Params<f64> {
    /// A case's parameters; a missing one is zero.
    fn from(p: &conformance::Params) -> Self {
        let v = |x: Option<[f64; 3]>| x.map_or_else(Vector3::zeros, Vector3::from);
        Params {
            s: v(p.s),
            h: v(p.h),
            b: v(p.b),
            c: v(p.c),
            f: v(p.f),
            g: v(p.g),
            k: v(p.k),
            rho1: v(p.rho1),
            rho2: v(p.rho2),
        }
    }
}

impl Params<f64> {
    /// The parameters converted to the scalar `T`.
    pub fn lift<T: SimdRealField + Copy>(&self) -> Params<T> {
        let l = |v: &Vector3<f64>| v.map(lift::<T>);
        Params {
            s: l(&self.s),
            h: l(&self.h),
            b: l(&self.b),
            c: l(&self.c),
            f: l(&self.f),
            g: l(&self.g),
            k: l(&self.k),
            rho1: l(&self.rho1),
            rho2: l(&self.rho2),
        }
    }
}

/// One conformance case, prepared for the variants.
#[derive(Clone, Debug)]
pub struct Case<'a> {
    /// The case as read (id, expected values and scales).
    pub source: &'a conformance::Case,
    /// The joint's parameters.
    pub params: Params<f64>,
    /// The state.
    pub coords: Coords<f64>,
}

impl<'a> Case<'a> {
    /// Prepares `source`.
    ///
    /// # Errors
    /// The state is incomplete (see [`conformance::State::coords`]).
    pub fn new(source: &'a conformance::Case) -> Result<Self, String> {
        let coords = source.state.coords().map_err(|e| format!("{}: {e}", source.id))?;
        Ok(Case { source, params: Params::from(&source.params), coords })
    }
}

// ---------------------------------------------------------------------------
// Errors.
// ---------------------------------------------------------------------------

/// Worst errors over a set of cases, in units of `ε · scale` of the variant's
/// precision.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Errors {
    /// Φ.
    pub phi: f64,
    /// J.
    pub jacobian: f64,
    /// γ.
    pub gamma: f64,
    /// Entries whose scale is 0 (zero for every input) that came out nonzero:
    /// the conformance test rejects them outright; here they are measured against
    /// 1/64 of the largest scale of their row (J) or vector (Φ, γ) and counted.
    pub inexact_zeros: usize,
}

impl Errors {
    /// The worst of Φ, J and γ.
    pub fn worst(&self) -> f64 {
        self.phi.max(self.jacobian).max(self.gamma)
    }

    /// The worse of each part.
    pub fn max(&self, other: &Errors) -> Errors {
        Errors {
            phi: self.phi.max(other.phi),
            jacobian: self.jacobian.max(other.jacobian),
            gamma: self.gamma.max(other.gamma),
            inexact_zeros: self.inexact_zeros + other.inexact_zeros,
        }
    }

    /// Every part multiplied by `f` (a change of unit).
    pub fn scaled(&self, f: f64) -> Errors {
        Errors { phi: self.phi * f, jacobian: self.jacobian * f, gamma: self.gamma * f, ..*self }
    }
}

/// Moves nonzero entries of zero scale out of `got` into `(units, count)`.
fn take_zeros(got: &mut [f64], scale: &[f64], reference: f64) -> (f64, usize) {
    let (mut worst, mut count) = (0.0f64, 0);
    for (g, s) in got.iter_mut().zip(scale) {
        if *s == 0.0 && *g != 0.0 {
            let units = if g.is_finite() { g.abs() / (EPS * reference.max(f64::MIN_POSITIVE)) } else { f64::INFINITY };
            worst = worst.max(units);
            count += 1;
            *g = 0.0;
        }
    }
    (worst, count)
}

/// The errors of one case's output, Φ, J and γ separately, each through
/// [`case_error`] with the other two parts replaced by the expected values.
pub fn errors(case: &conformance::Case, got: &Output) -> Result<Errors, String> {
    let (want, scale) = (&case.expected, &case.scale);
    let mut got = got.clone();
    let biggest = |xs: &[f64]| xs.iter().copied().fold(0.0, f64::max) / 64.0;
    let (zphi, nphi) = take_zeros(&mut got.phi, &scale.phi, biggest(&scale.phi));
    let (zgamma, ngamma) = take_zeros(&mut got.gamma, &scale.gamma, biggest(&scale.gamma));
    let (mut zjac, mut njac) = (0.0f64, 0);
    for (row, srow) in got.jacobian.iter_mut().zip(&scale.jacobian) {
        let (z, n) = take_zeros(row, srow, biggest(srow));
        zjac = zjac.max(z);
        njac += n;
    }
    let part = |phi: &[f64], jacobian: &[Vec<f64>], gamma: &[f64]| {
        let o = Output { id: got.id.clone(), phi: phi.to_vec(), jacobian: jacobian.to_vec(), gamma: gamma.to_vec() };
        case_error(case, &o)
    };
    Ok(Errors {
        phi: part(&got.phi, &want.jacobian, &want.gamma)?.max(zphi),
        jacobian: part(&want.phi, &got.jacobian, &want.gamma)?.max(zjac),
        gamma: part(&want.phi, &want.jacobian, &got.gamma)?.max(zgamma),
        inexact_zeros: nphi + njac + ngamma,
    })
}

/// The worst errors of `outputs` against `cases` (in case order).
pub fn worst_errors(cases: &[Case], outputs: &[Output]) -> Result<Errors, String> {
    let mut worst = Errors::default();
    for (case, out) in cases.iter().zip(outputs) {
        worst = worst.max(&errors(case.source, out).map_err(|e| format!("{}: {e}", case.source.id))?);
    }
    Ok(worst)
}

/// An [`Output`] from Φ, J and γ in any scalar convertible to f64.
pub fn output<T: Copy, const R: usize, const C: usize>(
    id: &str,
    phi: &SVector<T, R>,
    jacobian: &SMatrix<T, R, C>,
    gamma: &SVector<T, R>,
    to_f64: impl Fn(T) -> f64,
) -> Output {
    Output {
        id: id.to_string(),
        phi: phi.iter().map(|&x| to_f64(x)).collect(),
        jacobian: (0..R).map(|r| (0..C).map(|c| to_f64(jacobian[(r, c)])).collect()).collect(),
        gamma: gamma.iter().map(|&x| to_f64(x)).collect(),
    }
}

// ---------------------------------------------------------------------------
// Timing.
// ---------------------------------------------------------------------------

/// Median ns per state of `once` (which evaluates `states` states): the
/// repetition count is doubled until a sample takes 3 ms, then 15 samples.
pub fn median_ns(states: usize, mut once: impl FnMut()) -> f64 {
    median_ns_interleaved(states, &mut [&mut once])[0]
}

/// [`median_ns`] of several computations whose samples alternate, so that a
/// change of the machine's load (other processes) affects them alike: each is
/// calibrated to 3 ms a sample, then 15 rounds take one sample of each in turn.
pub fn median_ns_interleaved(states: usize, fs: &mut [&mut dyn FnMut()]) -> Vec<f64> {
    let iters: Vec<usize> = fs
        .iter_mut()
        .map(|f| {
            let mut iters = 1usize;
            loop {
                let t = Instant::now();
                for _ in 0..iters {
                    f();
                }
                if t.elapsed().as_secs_f64() > 3e-3 || iters > 1 << 24 {
                    break iters;
                }
                iters *= 2;
            }
        })
        .collect();
    let mut samples = vec![Vec::with_capacity(15); fs.len()];
    for _ in 0..15 {
        for ((f, &n), out) in fs.iter_mut().zip(&iters).zip(&mut samples) {
            let t = Instant::now();
            for _ in 0..n {
                f();
            }
            out.push(t.elapsed().as_secs_f64() * 1e9 / (n * states.max(1)) as f64);
        }
    }
    samples
        .into_iter()
        .map(|mut s| {
            s.sort_by(f64::total_cmp);
            s[s.len() / 2]
        })
        .collect()
}

// ---------------------------------------------------------------------------
// The joints: generated and hand-written types of each group.
// ---------------------------------------------------------------------------

/// A measured joint and formulation: the generated type at every scalar, its
/// formulation's trajectories, and its hand-written counterpart.
pub trait Family<const R: usize, const C: usize> {
    /// The joint kind as in the vectors.
    const JOINT: &'static str;
    /// The formulation as in the vectors.
    const FORM: &'static str;
    /// The formulation's state type and trajectories.
    type F: Form<C>;
    /// The derived type (`joint_tests::joints`) at the scalar `T`.
    type G<T: SimdRealField + Copy>: Joint<T, R, C, State = <Self::F as Form<C>>::State<T>>;
    /// The derived joint with the parameters `p`.
    fn generated<T: SimdRealField + Copy>(p: &Params<T>) -> Self::G<T>;
    /// The hand-written implementation over `cases`: outputs, ns per evaluation
    /// and its operation count; `None` while there is none.
    fn hand(cases: &[Case], progress: &mut dyn FnMut(&str)) -> Option<Result<HandResult, String>>;
}

/// What the hand-written implementation of a group gave.
pub struct HandResult {
    /// Outputs in case order.
    pub outputs: Vec<Output>,
    /// Evaluates every case once (for timing, beside the generated code).
    pub once: Box<dyn FnMut()>,
    /// Binary + − × ÷ in one evaluation (counted on `Counted` scalars).
    pub ops: usize,
}

macro_rules! family {
    ($name:ident, $joint:literal, $form:literal, $F:ty, $r:literal, $c:literal, [$($p:ident),*] $(, $hand:ident)?) => {
        impl Family<$r, $c> for joints::$name<f64> {
            const JOINT: &'static str = $joint;
            const FORM: &'static str = $form;
            type F = $F;
            type G<T: SimdRealField + Copy> = joints::$name<T>;
            fn generated<T: SimdRealField + Copy>(p: &Params<T>) -> joints::$name<T> {
                joints::$name { $($p: p.$p),* }
            }
            fn hand(cases: &[Case], progress: &mut dyn FnMut(&str)) -> Option<Result<HandResult, String>> {
                family!(@hand $name, $F, $r, $c, [$($p),*], cases, progress $(, $hand)?)
            }
        }
    };
    (@hand $name:ident, $F:ty, $r:literal, $c:literal, [$($p:ident),*], $cases:ident, $progress:ident) => {{
        let _ = ($cases, $progress);
        None
    }};
    (@hand $name:ident, $F:ty, $r:literal, $c:literal, [$($p:ident),*], $cases:ident, $progress:ident, hand) => {{
        $progress(&format!("{}/{}: hand-written", Self::JOINT, Self::FORM));
        Some(hand_result::<$F, handwritten::$name<f64>, handwritten::$name<Counted>, $r, $c>(
            $cases,
            |p| handwritten::$name { $($p: p.$p),* },
            |p| handwritten::$name { $($p: p.$p.map(Counted::new)),* },
        ))
    }};
}

family!(UniversalEuler, "universal", "euler", Euler, 4, 14, [s, h, rho1, rho2], hand);
family!(UniversalOmegaInertial, "universal", "omega_inertial", OmegaInertial, 4, 12, [s, h, rho1, rho2], hand);
family!(UniversalOmegaBody, "universal", "omega_body", OmegaBodyF, 4, 12, [s, h, rho1, rho2], hand);
family!(UniversalRelativeB1, "universal", "relative_b1", RelB1, 4, 6, [s, h, rho1, rho2], hand);
family!(UniversalRelativeB2, "universal", "relative_b2", RelB2, 4, 6, [s, h, rho1, rho2], hand);
family!(UniversalTranslationalEuler, "universal_translational", "euler", Euler, 3, 14, [s, h, b, c, rho1, rho2], hand);
family!(
    UniversalTranslationalOmegaInertial,
    "universal_translational",
    "omega_inertial",
    OmegaInertial,
    3,
    12,
    [s, h, b, c, rho1, rho2],
    hand
);
family!(
    UniversalTranslationalOmegaBody,
    "universal_translational",
    "omega_body",
    OmegaBodyF,
    3,
    12,
    [s, h, b, c, rho1, rho2],
    hand
);
family!(
    UniversalTranslationalRelativeB1,
    "universal_translational",
    "relative_b1",
    RelB1,
    3,
    6,
    [s, h, b, c, rho1, rho2],
    hand
);
family!(
    UniversalTranslationalRelativeB2,
    "universal_translational",
    "relative_b2",
    RelB2,
    3,
    6,
    [s, h, b, c, rho1, rho2],
    hand
);
family!(SphericalEuler, "spherical", "euler", Euler, 3, 14, [rho1, rho2], hand);
family!(SphericalOmegaBody, "spherical", "omega_body", OmegaBodyF, 3, 12, [rho1, rho2], hand);
family!(RevoluteEuler, "revolute", "euler", Euler, 5, 14, [f, g, h, rho1, rho2], hand);
family!(RevoluteOmegaBody, "revolute", "omega_body", OmegaBodyF, 5, 12, [f, g, h, rho1, rho2], hand);
family!(TranslationalEuler, "translational", "euler", Euler, 5, 14, [f, g, h, k, rho1, rho2], hand);
family!(TranslationalOmegaBody, "translational", "omega_body", OmegaBodyF, 5, 12, [f, g, h, k, rho1, rho2], hand);

/// Runs a hand-written implementation over `cases`: `make` builds it from the
/// parameters at f64, `make_counted` at [`Counted`]; the states are the
/// formulation's ([`Form::build`]), converted with [`ToCounted`] for the count.
pub fn hand_result<F, H, HC, const R: usize, const C: usize>(
    cases: &[Case],
    make: impl Fn(&Params<f64>) -> H,
    make_counted: impl Fn(&Params<f64>) -> HC,
) -> Result<HandResult, String>
where
    F: Form<C>,
    H: Joint<f64, R, C, State = F::State<f64>> + 'static,
    F::State<f64>: ToCounted<Counted = HC::State> + 'static,
    HC: Joint<Counted, R, C>,
{
    let prepared: Vec<_> = cases.iter().map(|c| (make(&c.params), F::build(&c.coords, 0.0))).collect();
    let outputs = cases
        .iter()
        .zip(&prepared)
        .map(|(c, (j, s))| {
            let e = j.evaluate(s);
            output(&c.source.id, &e.phi, &e.jacobian, &e.gamma, |x| x)
        })
        .collect();
    let once = Box::new(move || {
        for (j, s) in &prepared {
            black_box(j.evaluate(black_box(s)));
        }
    });
    // Straight-line code: the count is the same at every state; take the largest
    // over the cases all the same.
    let mut ops = 0;
    for c in cases {
        let (j, s) = (make_counted(&c.params), F::build(&c.coords, 0.0).to_counted());
        ops = ops.max(count(|| j.evaluate(&s)).1);
    }
    Ok(HandResult { outputs, once, ops })
}

// ---------------------------------------------------------------------------
// num-dual and central differences.
// ---------------------------------------------------------------------------

/// Bodies and columns per body of a formulation with `C` columns.
fn layout(c: usize) -> (usize, usize) {
    if c == 6 { (1, 6) } else { (2, c / 2) }
}

/// The coordinates with one dual direction per velocity column: `q + ε` for
/// `euler`; `r + ε_ṙ` and `[1, ε_ω / 2] ⊗ p0` or `p0 ⊗ [1, ε_ω / 2]` (the tangent of
/// the exact rotation) for the others.
fn seeded<const C: usize>(c0: &Coords<f64>, rot: Rot) -> Coords<DualSVec64<C>> {
    let mut c = c0.map(DualSVec64::<C>::from_re);
    let (bodies, per) = layout(C);
    let seed = |x: f64, column: usize, weight: f64| {
        DualSVec64::<C>::new(x, Derivative::derivative_generic(Const::<C>, U1, column) * weight)
    };
    for b in 0..bodies {
        for i in 0..3 {
            c.0[BODY * b + i] = seed(c0.0[BODY * b + i], per * b + i, 1.0);
        }
        match rot {
            Rot::Line => {
                for i in 0..4 {
                    c.0[BODY * b + 3 + i] = seed(c0.0[BODY * b + 3 + i], per * b + 3 + i, 1.0);
                }
            }
            Rot::Left | Rot::Right => {
                let dq = Vector4::new(
                    DualSVec64::from_re(1.0),
                    seed(0.0, per * b + 3, 0.5),
                    seed(0.0, per * b + 4, 0.5),
                    seed(0.0, per * b + 5, 0.5),
                );
                let p0 = c.p(b);
                let p = if rot == Rot::Left { quat_mul(&dq, &p0) } else { quat_mul(&p0, &dq) };
                c.set(BODY * b + 3, p.as_slice());
            }
        }
    }
    c
}

/// Φ, J and γ by forward-mode AD of the generated `phi`: one `DualSVec64<C>`
/// pass for Φ and J, one `Dual2_64` pass along the trajectory for γ.
pub fn num_dual_eval<Fa: Family<R, C>, const R: usize, const C: usize>(
    jd: &Fa::G<DualSVec64<C>>,
    j2: &Fa::G<Dual2_64>,
    c0: &Coords<f64>,
) -> (SVector<f64, R>, SMatrix<f64, R, C>, SVector<f64, R>) {
    let rot = <Fa::F as Form<C>>::ROT;
    let d = jd.phi(&<Fa::F as Form<C>>::build(&seeded::<C>(c0, rot), 0.0));
    let phi = SVector::<f64, R>::from_fn(|i, _| d[i].re);
    let mut jac = SMatrix::<f64, R, C>::zeros();
    for i in 0..R {
        if let Some(eps) = &d[i].eps.0 {
            for k in 0..C {
                jac[(i, k)] = eps[k];
            }
        }
    }
    let t = Dual2_64::from_re(0.0).derivative();
    let d2 = j2.phi(&<Fa::F as Form<C>>::build(&along(c0, rot, t), 0.0));
    let gamma = SVector::<f64, R>::from_fn(|i, _| -d2[i].v2);
    (phi, jac, gamma)
}

/// The rotations by `+h` and `−h` about each axis, as quaternions.
pub type AxisTurns = [[Vector4<f64>; 2]; 3];

/// [`AxisTurns`] for the step `h` (computed once per step, outside the timing).
pub fn axis_turns(h: f64) -> AxisTurns {
    let (s, c) = (0.5 * h).sin_cos();
    core::array::from_fn(|axis| {
        [1.0, -1.0].map(|sign| {
            let mut q = Vector4::new(c, 0.0, 0.0, 0.0);
            q[1 + axis] = sign * s;
            q
        })
    })
}

/// Φ, J and γ by central differences of the generated `phi` with step `h`:
/// `2C + 3` evaluations of Φ.
pub fn central_differences<Fa: Family<R, C>, const R: usize, const C: usize>(
    j: &Fa::G<f64>,
    c0: &Coords<f64>,
    h: f64,
    turns: &AxisTurns,
) -> (SVector<f64, R>, SMatrix<f64, R, C>, SVector<f64, R>) {
    let rot = <Fa::F as Form<C>>::ROT;
    let phi_at = |c: &Coords<f64>| j.phi(&<Fa::F as Form<C>>::build(c, 0.0));
    let (bodies, per) = layout(C);
    let mut jac = SMatrix::<f64, R, C>::zeros();
    for b in 0..bodies {
        for k in 0..per {
            let moved = |side: usize| {
                let mut c = *c0;
                if rot == Rot::Line || k < 3 {
                    c.0[BODY * b + k] += if side == 0 { h } else { -h };
                } else {
                    let (p0, dq) = (c0.p(b), &turns[k - 3][side]);
                    let p = if rot == Rot::Left { quat_mul(dq, &p0) } else { quat_mul(&p0, dq) };
                    c.set(BODY * b + 3, p.as_slice());
                }
                phi_at(&c)
            };
            let column = (moved(0) - moved(1)) / (2.0 * h);
            jac.set_column(per * b + k, &column);
        }
    }
    let phi = phi_at(c0);
    let (plus, minus) = (phi_at(&along(c0, rot, h)), phi_at(&along(c0, rot, -h)));
    let gamma = -(plus - phi * 2.0 + minus) / (h * h);
    (phi, jac, gamma)
}

// ---------------------------------------------------------------------------
// Measuring a group.
// ---------------------------------------------------------------------------

/// Time and errors of one variant of one group.
#[derive(Clone, Debug)]
pub struct Measured {
    /// Median ns per evaluation of Φ, J and γ together.
    pub ns: f64,
    /// Worst errors over the cases, in `ε · scale` of the variant's precision.
    pub errors: Errors,
    /// `ε` of the variant's precision (`EPS` or [`EPS32`]).
    pub unit: f64,
}

impl Measured {
    /// The worst error relative to the scale (units × ε).
    pub fn relative(&self) -> f64 {
        self.errors.worst() * self.unit
    }
}

/// Everything measured for one joint and formulation.
#[derive(Clone, Debug)]
pub struct GroupResult {
    /// The joint kind.
    pub joint: String,
    /// The formulation.
    pub form: String,
    /// Number of cases (vectors and hard vectors).
    pub cases: usize,
    /// Generated `evaluate`, f64.
    pub generated: Measured,
    /// Generated `evaluate`, f32 (errors in `ε₃₂ · scale`).
    pub generated_f32: Measured,
    /// The hand-written implementation, once it exists.
    pub hand: Option<Measured>,
    /// num-dual.
    pub num_dual: Measured,
    /// Central differences at each step of [`FD_STEPS`] (the time does not
    /// depend on the step).
    pub fd: Vec<(f64, Measured)>,
    /// Operation counts of the generated functions.
    pub ops: joint_runtime::Ops,
    /// Operations of the hand-written evaluation.
    pub hand_ops: Option<usize>,
}

impl GroupResult {
    /// The central-difference step with the smallest worst error, and its result.
    pub fn best_fd(&self) -> (f64, &Measured) {
        let best =
            self.fd.iter().min_by(|a, b| a.1.errors.worst().total_cmp(&b.1.errors.worst())).expect("at least one step");
        (best.0, &best.1)
    }
}

/// Measures every variant of the family `Fa` over `cases`.
pub fn measure<Fa: Family<R, C>, const R: usize, const C: usize>(
    cases: &[Case],
    progress: &mut dyn FnMut(&str),
) -> Result<GroupResult, String> {
    let n = cases.len();
    let name = format!("{}/{}", Fa::JOINT, Fa::FORM);
    let build = |c: &Coords<f64>| <Fa::F as Form<C>>::build(c, 0.0);

    // Generated, f64.
    progress(&format!("{name}: generated f64"));
    let g64: Vec<_> = cases.iter().map(|c| (Fa::generated::<f64>(&c.params), build(&c.coords))).collect();
    let outputs: Vec<Output> = cases
        .iter()
        .zip(&g64)
        .map(|(c, (j, s))| {
            let e = j.evaluate(s);
            output(&c.source.id, &e.phi, &e.jacobian, &e.gamma, |x| x)
        })
        .collect();
    let generated_errors = worst_errors(cases, &outputs)?;
    let mut time_generated = || {
        for (j, s) in &g64 {
            black_box(j.evaluate(black_box(s)));
        }
    };

    // Hand-written, timed in alternation with the generated code.
    let (generated, hand, hand_ops) = match Fa::hand(cases, progress) {
        None => (Measured { errors: generated_errors, ns: median_ns(n, time_generated), unit: EPS }, None, None),
        Some(r) => {
            let mut r = r?;
            let errors = worst_errors(cases, &r.outputs)?;
            let ns = median_ns_interleaved(n, &mut [&mut time_generated, &mut r.once]);
            (
                Measured { errors: generated_errors, ns: ns[0], unit: EPS },
                Some(Measured { ns: ns[1], errors, unit: EPS }),
                Some(r.ops),
            )
        }
    };

    progress(&format!("{name}: generated f32"));
    let generated_f32 = measure_f32::<Fa, R, C>(cases)?;
    progress(&format!("{name}: num-dual"));
    let num_dual = measure_num_dual::<Fa, R, C>(cases)?;
    // Central differences: errors at every step, the time once (it does not
    // depend on the step).
    progress(&format!("{name}: central differences"));
    let fd = measure_fd::<Fa, R, C>(cases)?;

    Ok(GroupResult {
        joint: Fa::JOINT.to_string(),
        form: Fa::FORM.to_string(),
        cases: n,
        generated,
        generated_f32,
        hand,
        num_dual,
        fd,
        ops: <Fa::G<f64> as Joint<f64, R, C>>::OPS,
        hand_ops,
    })
}

/// The generated code in `f32`: its errors in units of `f32`'s epsilon.
fn measure_f32<Fa: Family<R, C>, const R: usize, const C: usize>(cases: &[Case]) -> Result<Measured, String> {
    let n = cases.len();
    let g32: Vec<_> = cases
        .iter()
        .map(|c| (Fa::generated::<f32>(&c.params.lift()), <Fa::F as Form<C>>::build(&c.coords.map(lift::<f32>), 0.0)))
        .collect();
    let outputs: Vec<Output> = cases
        .iter()
        .zip(&g32)
        .map(|(c, (j, s))| {
            let e = j.evaluate(s);
            output(&c.source.id, &e.phi, &e.jacobian, &e.gamma, f64::from)
        })
        .collect();
    Ok(Measured {
        errors: worst_errors(cases, &outputs)?.scaled(EPS / EPS32),
        ns: median_ns(n, || {
            for (j, s) in &g32 {
                black_box(j.evaluate(black_box(s)));
            }
        }),
        unit: EPS32,
    })
}

/// num-dual's derivatives of the generated Φ.
fn measure_num_dual<Fa: Family<R, C>, const R: usize, const C: usize>(cases: &[Case]) -> Result<Measured, String> {
    let n = cases.len();
    let duals: Vec<_> = cases
        .iter()
        .map(|c| {
            (Fa::generated::<DualSVec64<C>>(&c.params.lift()), Fa::generated::<Dual2_64>(&c.params.lift()), c.coords)
        })
        .collect();
    let outputs: Vec<Output> = cases
        .iter()
        .zip(&duals)
        .map(|(c, (jd, j2, c0))| {
            let (p, j, g) = num_dual_eval::<Fa, R, C>(jd, j2, c0);
            output(&c.source.id, &p, &j, &g, |x| x)
        })
        .collect();
    Ok(Measured {
        errors: worst_errors(cases, &outputs)?,
        ns: median_ns(n, || {
            for (jd, j2, c0) in &duals {
                black_box(num_dual_eval::<Fa, R, C>(black_box(jd), j2, black_box(c0)));
            }
        }),
        unit: EPS,
    })
}

/// Central differences of the generated Φ at each of [`FD_STEPS`].
fn measure_fd<Fa: Family<R, C>, const R: usize, const C: usize>(
    cases: &[Case],
) -> Result<Vec<(f64, Measured)>, String> {
    let n = cases.len();
    let plain: Vec<_> = cases.iter().map(|c| (Fa::generated::<f64>(&c.params), c.coords)).collect();
    let mut fd = Vec::new();
    let mut fd_ns = None;
    for &h in &FD_STEPS {
        let turns = axis_turns(h);
        let outputs: Vec<Output> = cases
            .iter()
            .zip(&plain)
            .map(|(c, (j, c0))| {
                let (p, jac, g) = central_differences::<Fa, R, C>(j, c0, h, &turns);
                output(&c.source.id, &p, &jac, &g, |x| x)
            })
            .collect();
        let ns = *fd_ns.get_or_insert_with(|| {
            median_ns(n, || {
                for (j, c0) in &plain {
                    black_box(central_differences::<Fa, R, C>(black_box(j), black_box(c0), h, &turns));
                }
            })
        });
        fd.push((h, Measured { ns, errors: worst_errors(cases, &outputs)?, unit: EPS }));
    }
    Ok(fd)
}

/// Measures every group of [`GROUPS`] over the cases of `docs` (the vectors
/// files), reporting each step through `progress`.
pub fn measure_all(docs: &[VectorFile], progress: &mut dyn FnMut(&str)) -> Result<Vec<GroupResult>, String> {
    let all: Vec<&conformance::Case> = docs.iter().flat_map(|d| &d.cases).collect();
    let mut results = Vec::new();
    for (i, (joint, form)) in GROUPS.iter().enumerate() {
        let cases = all
            .iter()
            .filter(|c| c.joint == *joint && c.formulation == *form)
            .map(|c| Case::new(c))
            .collect::<Result<Vec<_>, _>>()?;
        if cases.is_empty() {
            return Err(format!("no cases for {joint}/{form}"));
        }
        let mut step = |what: &str| progress(&format!("[{}/{}] {what}", i + 1, GROUPS.len()));
        let r = match (*joint, *form) {
            ("universal", "euler") => measure::<joints::UniversalEuler<f64>, 4, 14>(&cases, &mut step),
            ("universal", "omega_inertial") => measure::<joints::UniversalOmegaInertial<f64>, 4, 12>(&cases, &mut step),
            ("universal", "omega_body") => measure::<joints::UniversalOmegaBody<f64>, 4, 12>(&cases, &mut step),
            ("universal", "relative_b1") => measure::<joints::UniversalRelativeB1<f64>, 4, 6>(&cases, &mut step),
            ("universal", "relative_b2") => measure::<joints::UniversalRelativeB2<f64>, 4, 6>(&cases, &mut step),
            ("universal_translational", "euler") => {
                measure::<joints::UniversalTranslationalEuler<f64>, 3, 14>(&cases, &mut step)
            }
            ("universal_translational", "omega_inertial") => {
                measure::<joints::UniversalTranslationalOmegaInertial<f64>, 3, 12>(&cases, &mut step)
            }
            ("universal_translational", "omega_body") => {
                measure::<joints::UniversalTranslationalOmegaBody<f64>, 3, 12>(&cases, &mut step)
            }
            ("universal_translational", "relative_b1") => {
                measure::<joints::UniversalTranslationalRelativeB1<f64>, 3, 6>(&cases, &mut step)
            }
            ("universal_translational", "relative_b2") => {
                measure::<joints::UniversalTranslationalRelativeB2<f64>, 3, 6>(&cases, &mut step)
            }
            ("spherical", "euler") => measure::<joints::SphericalEuler<f64>, 3, 14>(&cases, &mut step),
            ("spherical", "omega_body") => measure::<joints::SphericalOmegaBody<f64>, 3, 12>(&cases, &mut step),
            ("revolute", "euler") => measure::<joints::RevoluteEuler<f64>, 5, 14>(&cases, &mut step),
            ("revolute", "omega_body") => measure::<joints::RevoluteOmegaBody<f64>, 5, 12>(&cases, &mut step),
            ("translational", "euler") => measure::<joints::TranslationalEuler<f64>, 5, 14>(&cases, &mut step),
            ("translational", "omega_body") => measure::<joints::TranslationalOmegaBody<f64>, 5, 12>(&cases, &mut step),
            _ => unreachable!("every group of GROUPS has a row"),
        }?;
        results.push(r);
    }
    Ok(results)
}

// ---------------------------------------------------------------------------
// Tables.
// ---------------------------------------------------------------------------

/// A time in ns, to about three significant digits.
pub fn fmt_ns(ns: f64) -> String {
    if ns >= 100.0 { format!("{ns:.0}") } else { format!("{ns:.1}") }
}

/// An error in units of `ε · scale`: fixed point below 1000, else scientific.
pub fn fmt_err(e: f64) -> String {
    if !e.is_finite() {
        "∞".into()
    } else if e < 1000.0 {
        format!("{e:.1}")
    } else {
        format!("{e:.1e}")
    }
}

fn fmt_ratio(r: f64) -> String {
    if !r.is_finite() {
        "∞".into()
    } else if r >= 1e4 {
        format!("{r:.1e}")
    } else if r >= 10.0 {
        format!("{r:.0}")
    } else {
        format!("{r:.2}")
    }
}

fn verdict(ok: bool) -> &'static str {
    if ok { "✓" } else { "**MISS**" }
}

/// `joint / formulation` label of a row.
fn row_name(g: &GroupResult) -> String {
    format!("`{}` | `{}`", g.joint, g.form)
}

/// The main table: time and worst error (Φ, J, γ together) of each variant per
/// joint and formulation.
pub fn main_table(results: &[GroupResult]) -> String {
    let mut s = String::from(
        "| joint | formulation | generated f64 | generated f32 (ε₃₂) | hand-written | num-dual | central differences, best h |\n\
         |---|---|---|---|---|---|---|\n",
    );
    let cell = |m: &Measured| format!("{} ns · {}", fmt_ns(m.ns), fmt_err(m.errors.worst()));
    for g in results {
        let (h, fd) = g.best_fd();
        s += &format!(
            "| {} | {} | {} | {} | {} | {} ({h:.0e}) |\n",
            row_name(g),
            cell(&g.generated),
            cell(&g.generated_f32),
            g.hand.as_ref().map_or("—".into(), cell),
            cell(&g.num_dual),
            cell(fd),
        );
    }
    s
}

/// The targets per joint and formulation, each marked ✓ or **MISS**.
pub fn targets_table(results: &[GroupResult]) -> String {
    let mut s = String::from(
        "| joint | formulation | × faster than num-dual (≥ 3) | × faster than central diff. (≥ 5) | × faster than hand-written (≥ 1) | ops generated / hand-written (≤ 1) | best-FD error ÷ generated error (≥ 10⁶) | J alone: best-FD-for-J error ÷ generated | f32 worst (≤ 256 ε₃₂) |\n\
         |---|---|---|---|---|---|---|---|---|\n",
    );
    for g in results {
        let gen_ns = g.generated.ns;
        let ad = g.num_dual.ns / gen_ns;
        let (_, fd) = g.best_fd();
        let fdr = fd.ns / gen_ns;
        let hand = match &g.hand {
            Some(h) => {
                let r = h.ns / gen_ns;
                format!("{} {}", fmt_ratio(r), verdict(r >= 1.0))
            }
            None => "— (none)".into(),
        };
        let ops = match g.hand_ops {
            Some(o) => format!("{} / {} {}", g.ops.evaluate, o, verdict(g.ops.evaluate <= o)),
            None => format!("{} / —", g.ops.evaluate),
        };
        let err_ratio = fd.errors.worst() / g.generated.errors.worst();
        let best_j = g.fd.iter().map(|(_, m)| m.errors.jacobian).fold(f64::INFINITY, f64::min);
        let j_ratio = best_j / g.generated.errors.jacobian;
        let f32w = g.generated_f32.errors.worst();
        s += &format!(
            "| {} | {} {} | {} {} | {hand} | {ops} | {} {} | {}{} | {} {} |\n",
            row_name(g),
            fmt_ratio(ad),
            verdict(ad >= 3.0),
            fmt_ratio(fdr),
            verdict(fdr >= 5.0),
            fmt_ratio(err_ratio),
            verdict(err_ratio >= 1e6),
            fmt_ratio(j_ratio),
            if j_ratio >= 1e6 { "" } else { " (< 10⁶)" },
            fmt_err(f32w),
            verdict(f32w <= 256.0),
        );
    }
    s
}

/// Φ, J and γ errors of each variant separately.
pub fn error_table(results: &[GroupResult]) -> String {
    let mut s = String::from(
        "| joint | formulation | generated f64 Φ / J / γ | f32 Φ / J / γ (ε₃₂) | hand-written Φ / J / γ | num-dual J / γ | central diff. J / γ (best h) | inexact zeros (num-dual, FD best) |\n\
         |---|---|---|---|---|---|---|---|\n",
    );
    let three = |e: &Errors| format!("{} / {} / {}", fmt_err(e.phi), fmt_err(e.jacobian), fmt_err(e.gamma));
    for g in results {
        let (h, fd) = g.best_fd();
        s += &format!(
            "| {} | {} | {} | {} | {} / {} | {} / {} ({h:.0e}) | {}, {} |\n",
            row_name(g),
            three(&g.generated.errors),
            three(&g.generated_f32.errors),
            g.hand.as_ref().map_or("—".into(), |m| three(&m.errors)),
            fmt_err(g.num_dual.errors.jacobian),
            fmt_err(g.num_dual.errors.gamma),
            fmt_err(fd.errors.jacobian),
            fmt_err(fd.errors.gamma),
            g.num_dual.errors.inexact_zeros,
            fd.errors.inexact_zeros,
        );
    }
    s
}

/// Central differences: the J and γ errors at every step of [`FD_STEPS`].
pub fn fd_table(results: &[GroupResult]) -> String {
    let mut s = String::from("| joint | formulation |");
    for h in FD_STEPS {
        s += &format!(" h = {h:.0e} |");
    }
    s += "\n|---|---|";
    s += &"---|".repeat(FD_STEPS.len());
    s += "\n";
    for g in results {
        s += &format!("| {} |", row_name(g));
        for (_, m) in &g.fd {
            s += &format!(" {} / {} |", fmt_err(m.errors.jacobian), fmt_err(m.errors.gamma));
        }
        s += "\n";
    }
    s
}

/// Operation counts: each generated function (`Joint::OPS`) and the
/// hand-written evaluation (counted on `Counted` scalars).
pub fn ops_table(results: &[GroupResult]) -> String {
    let mut s = String::from(
        "| joint | formulation | generated `phi` | `jacobian` | `gamma` | `evaluate` | hand-written evaluation | generated / hand-written |\n\
         |---|---|---|---|---|---|---|---|\n",
    );
    for g in results {
        let (hand, ratio) = match g.hand_ops {
            Some(o) => (o.to_string(), format!("{:.2}", g.ops.evaluate as f64 / o as f64)),
            None => ("—".into(), "—".into()),
        };
        s += &format!(
            "| {} | {} | {} | {} | {} | {hand} | {ratio} |\n",
            row_name(g),
            g.ops.phi,
            g.ops.jacobian,
            g.ops.gamma,
            g.ops.evaluate
        );
    }
    s
}

/// Misses of the targets, one line each (empty when every target is met).
pub fn misses(results: &[GroupResult]) -> Vec<String> {
    let mut out = Vec::new();
    for g in results {
        let name = format!("{}/{}", g.joint, g.form);
        let gen_ns = g.generated.ns;
        let (h, fd) = g.best_fd();
        let ad = g.num_dual.ns / gen_ns;
        if ad < 3.0 {
            out.push(format!("{name}: only {ad:.2}× faster than num-dual (target 3×)"));
        }
        let fdr = fd.ns / gen_ns;
        if fdr < 5.0 {
            out.push(format!("{name}: only {fdr:.2}× faster than central differences (target 5×)"));
        }
        match (&g.hand, g.hand_ops) {
            (Some(hm), Some(ops)) => {
                if hm.ns < gen_ns {
                    out.push(format!(
                        "{name}: hand-written is faster ({} ns against {} ns)",
                        fmt_ns(hm.ns),
                        fmt_ns(gen_ns)
                    ));
                }
                if g.ops.evaluate > ops {
                    out.push(format!("{name}: {} operations against the hand-written {ops}", g.ops.evaluate));
                }
            }
            _ => out.push(format!("{name}: no hand-written implementation to compare with")),
        }
        let r = fd.errors.worst() / g.generated.errors.worst();
        if r < 1e6 {
            out.push(format!("{name}: error only {r:.1e}× below central differences at h = {h:.0e} (target 10⁶)"));
        }
        let f32w = g.generated_f32.errors.worst();
        if f32w > 256.0 {
            out.push(format!("{name}: f32 error {f32w:.1} ε₃₂·scale (target 256)"));
        }
    }
    out
}

// ---------------------------------------------------------------------------
// Figures.
// ---------------------------------------------------------------------------

/// Short joint names for the point labels.
fn short(joint: &str) -> &'static str {
    match joint {
        "universal" => "U",
        "universal_translational" => "UT",
        "spherical" => "S",
        "revolute" => "R",
        "translational" => "T",
        _ => "?",
    }
}

/// Short formulation names for the point labels.
fn short_form(form: &str) -> &'static str {
    match form {
        "euler" => "e",
        "omega_inertial" => "ωi",
        "omega_body" => "ωb",
        "relative_b1" => "r1",
        "relative_b2" => "r2",
        _ => "?",
    }
}

/// The variants of the figures: name and its measurement in a group.
fn figure_variants(g: &GroupResult) -> Vec<(&'static str, Option<&Measured>)> {
    vec![
        ("generated f64", Some(&g.generated)),
        ("generated f32", Some(&g.generated_f32)),
        ("hand-written", g.hand.as_ref()),
        ("num-dual", Some(&g.num_dual)),
        ("central differences (best h)", Some(g.best_fd().1)),
    ]
}

/// A log–log scatter of time (ns per evaluation of Φ, J and γ) against the worst
/// error relative to the scale (`units · ε`, so f32 and f64 share the axis), one
/// colour per variant, each point labelled with its joint (and formulation), for
/// the groups whose formulation is in `forms`. Writes the SVG file `path`.
///
/// # Errors
/// Any I/O or drawing error, as text.
pub fn plot_speed_error(
    results: &[GroupResult],
    forms: &[&str],
    caption: &str,
    path: &std::path::Path,
) -> Result<(), String> {
    use plotters::prelude::*;
    let err = |e: &dyn std::fmt::Display| e.to_string();
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).map_err(|e| format!("creating {}: {e}", dir.display()))?;
    }
    let chosen: Vec<&GroupResult> = results.iter().filter(|g| forms.contains(&g.form.as_str())).collect();
    // An exact result (error 0) is drawn at the floor of the axis.
    let floor = 1e-17;
    let point = |m: &Measured| (m.ns, m.relative().max(floor));
    let (mut x0, mut x1, mut y0, mut y1) = (f64::INFINITY, 0.0f64, f64::INFINITY, 0.0f64);
    for g in &chosen {
        for (_, m) in figure_variants(g) {
            if let Some(m) = m {
                let (x, y) = point(m);
                (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
            }
        }
    }
    if chosen.is_empty() || !(x0.is_finite() && y0.is_finite()) {
        return Err("nothing to plot".into());
    }
    let root = SVGBackend::new(path, (1000, 700)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(caption, ("sans-serif", 24))
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(80)
        .build_cartesian_2d((x0 / 1.6..x1 * 2.5).log_scale(), (y0 / 10.0..y1 * 100.0).log_scale())
        .map_err(|e| err(&e))?;
    chart
        .configure_mesh()
        .x_desc("ns per evaluation of Φ, J and γ (median)")
        .y_desc("worst |error| / scale over the vectors")
        .label_style(("sans-serif", 15))
        .axis_desc_style(("sans-serif", 16))
        .x_label_formatter(&|x| format!("{x:.0}"))
        .y_label_formatter(&|y| format!("{y:.0e}"))
        .draw()
        .map_err(|e| err(&e))?;
    let several_forms = forms.len() > 1;
    for (i, name) in ["generated f64", "generated f32", "hand-written", "num-dual", "central differences (best h)"]
        .iter()
        .enumerate()
    {
        let color = Palette99::pick(i).to_rgba();
        let points: Vec<((f64, f64), String)> = chosen
            .iter()
            .filter_map(|g| {
                let (_, m) = figure_variants(g).into_iter().find(|(n, _)| n == name)?;
                let label = if several_forms {
                    format!("{} {}", short(&g.joint), short_form(&g.form))
                } else {
                    short(&g.joint).to_string()
                };
                Some((point(m?), label))
            })
            .collect();
        if points.is_empty() {
            continue;
        }
        chart
            .draw_series(points.iter().map(|(p, label)| {
                EmptyElement::at(*p)
                    + Circle::new((0, 0), 5, color.filled())
                    + Text::new(label.clone(), (7, -7), ("sans-serif", 12).into_font())
            }))
            .map_err(|e| err(&e))?
            .label(*name)
            .legend(move |(x, y)| Circle::new((x + 10, y), 5, color.filled()));
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 15))
        .position(SeriesLabelPosition::UpperLeft)
        .draw()
        .map_err(|e| err(&e))?;
    root.present().map_err(|e| err(&e))?;
    Ok(())
}

/// The error–step trade-off of central differences: worst J error (left) and γ
/// error (right) in `ε · scale` against the step h, one line per joint and
/// formulation, with the generated code's error for reference (dashed, grey, the
/// largest over the groups). Writes the SVG file `path`.
///
/// # Errors
/// Any I/O or drawing error, as text.
pub fn plot_fd_steps(results: &[GroupResult], path: &std::path::Path) -> Result<(), String> {
    use plotters::prelude::*;
    let err = |e: &dyn std::fmt::Display| e.to_string();
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).map_err(|e| format!("creating {}: {e}", dir.display()))?;
    }
    let root = SVGBackend::new(path, (1400, 650)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let panels = root.split_evenly((1, 2));
    let (hmin, hmax) = (FD_STEPS[FD_STEPS.len() - 1], FD_STEPS[0]);
    for (panel, which) in panels.iter().zip(["J", "γ"]) {
        let pick = |e: &Errors| if which == "J" { e.jacobian } else { e.gamma };
        let floor = 0.1;
        let ys = results.iter().flat_map(|g| g.fd.iter().map(move |(_, m)| m)).map(|m| pick(&m.errors).max(floor));
        let y1 = ys.fold(1.0f64, f64::max);
        let generated = results.iter().map(|g| pick(&g.generated.errors)).fold(0.0f64, f64::max).max(floor);
        let mut chart = ChartBuilder::on(panel)
            .caption(format!("central differences: {which} error against the step"), ("sans-serif", 20))
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(70)
            .build_cartesian_2d((hmin / 2.0..hmax * 2.0).log_scale(), (floor..y1 * 10.0).log_scale())
            .map_err(|e| err(&e))?;
        chart
            .configure_mesh()
            .x_desc("step h")
            .y_desc(format!("worst {which} error (ε·scale)"))
            .label_style(("sans-serif", 13))
            .axis_desc_style(("sans-serif", 15))
            .x_label_formatter(&|x| format!("{x:.0e}"))
            .y_label_formatter(&|y| format!("{y:.0e}"))
            .draw()
            .map_err(|e| err(&e))?;
        for (i, g) in results.iter().enumerate() {
            let color = Palette99::pick(i).to_rgba();
            let points: Vec<(f64, f64)> = g.fd.iter().map(|(h, m)| (*h, pick(&m.errors).max(floor))).collect();
            let series =
                chart.draw_series(LineSeries::new(points.clone(), color.stroke_width(2))).map_err(|e| err(&e))?;
            if which == "J" {
                series
                    .label(format!("{} {}", short(&g.joint), short_form(&g.form)))
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2)));
            }
            chart.draw_series(points.iter().map(|&p| Circle::new(p, 3, color.filled()))).map_err(|e| err(&e))?;
        }
        let grey = RGBColor(120, 120, 120);
        chart
            .draw_series(DashedLineSeries::new(
                vec![(hmin / 2.0, generated), (hmax * 2.0, generated)],
                8,
                5,
                grey.stroke_width(2),
            ))
            .map_err(|e| err(&e))?;
        chart
            .draw_series(std::iter::once(Text::new(
                "generated (worst group)",
                (hmin, generated * 2.0),
                ("sans-serif", 13).into_font(),
            )))
            .map_err(|e| err(&e))?;
        if which == "J" {
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .label_font(("sans-serif", 11))
                .position(SeriesLabelPosition::UpperRight)
                .draw()
                .map_err(|e| err(&e))?;
        }
    }
    root.present().map_err(|e| err(&e))?;
    Ok(())
}
