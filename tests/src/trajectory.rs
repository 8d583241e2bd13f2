//! Exact trajectories for the derivative tests (`tests/derive/derivatives.rs`,
//! `tests/derive/catalogue/`): flat coordinate arrays generic over the scalar (f64,
//! f32, num-dual, SIMD lanes), their motion with constant velocities in every
//! formulation, the state types built from them, and the comparisons the tests
//! make.
//!
//! Everything is generic over `T: SimdRealField + Copy`, so a dual number in `t`
//! passed to [`along`] gives the exact time derivatives of whatever the generated
//! code computes from the state.

use core::fmt;

use joint_runtime::nalgebra::{SMatrix, SVector, SimdRealField, Vector3, Vector4, convert};
use joint_runtime::{EulerBody, OmegaBody, RelativeState, TwoBodies};

// ---------------------------------------------------------------------------
// Flat storage of coordinates and parameters, generic over the scalar.
// ---------------------------------------------------------------------------

/// A fixed array of numbers with named views (coordinates or joint parameters).
#[derive(Clone, Copy, Debug)]
pub struct Flat<T, const N: usize>(pub [T; N]);

/// Per body (17 numbers): `x` (r or δ) 0..3, `p` 3..7, `xd` 7..10, `w` (ω) 10..13, `pd` (ṗ) 13..17.
/// Relative formulations read body 0 only (`δ, p_rel, δ̇, ω_rel`).
pub type Coords<T> = Flat<T, 34>;

/// The numbers per body in [`Coords`].
pub const BODY: usize = 17;

impl<T: Copy, const N: usize> Flat<T, N> {
    /// Every number through `f`.
    pub fn map<U>(&self, f: impl FnMut(T) -> U) -> Flat<U, N> {
        Flat(self.0.map(f))
    }
    /// The three numbers from offset `o`.
    pub fn v3(&self, o: usize) -> Vector3<T>
    where
        T: SimdRealField,
    {
        Vector3::new(self.0[o], self.0[o + 1], self.0[o + 2])
    }
    /// The four numbers from offset `o`.
    pub fn v4(&self, o: usize) -> Vector4<T>
    where
        T: SimdRealField,
    {
        Vector4::new(self.0[o], self.0[o + 1], self.0[o + 2], self.0[o + 3])
    }
    /// Overwrites the numbers from offset `o` with `values`.
    pub fn set(&mut self, o: usize, values: &[T]) {
        self.0[o..o + values.len()].copy_from_slice(values);
    }
}

impl<T: SimdRealField + Copy> Coords<T> {
    /// Position `r` (or `δ`) of body `b`.
    pub fn x(&self, b: usize) -> Vector3<T> {
        self.v3(BODY * b)
    }
    /// Euler parameters of body `b`.
    pub fn p(&self, b: usize) -> Vector4<T> {
        self.v4(BODY * b + 3)
    }
    /// Velocity `ṙ` (or `δ̇`) of body `b`.
    pub fn xd(&self, b: usize) -> Vector3<T> {
        self.v3(BODY * b + 7)
    }
    /// Angular velocity ω of body `b`.
    pub fn w(&self, b: usize) -> Vector3<T> {
        self.v3(BODY * b + 10)
    }
    /// Euler parameter rates `ṗ` of body `b`.
    pub fn pd(&self, b: usize) -> Vector4<T> {
        self.v4(BODY * b + 13)
    }
}

/// Named vector views (and optionally one scalar) of a parameter array
/// `Flat<T, N>`, as a local trait: `vector_views!(trait Views for N { s = 0, h = 3 }; scalar sc = 6)`.
#[macro_export]
macro_rules! vector_views {
    ($(#[$m:meta])* trait $name:ident for $n:literal { $($view:ident = $o:literal),* $(,)? } $(; scalar $sc:ident = $so:literal)?) => {
        $(#[$m])*
        trait $name<T> {
            $(fn $view(&self) -> ::joint_runtime::nalgebra::Vector3<T>;)*
            $(fn $sc(&self) -> T;)?
        }
        impl<T: ::joint_runtime::nalgebra::SimdRealField + Copy> $name<T> for $crate::trajectory::Flat<T, $n> {
            $(fn $view(&self) -> ::joint_runtime::nalgebra::Vector3<T> {
                self.v3($o)
            })*
            $(fn $sc(&self) -> T {
                self.0[$so]
            })?
        }
    };
}

/// `x` converted to the scalar `T`.
pub fn lift<T: SimdRealField>(x: f64) -> T {
    convert(x)
}

/// Coordinates from 34 numbers; with `unit`, each body's Euler parameters are
/// normalised (or the identity where they are nearly zero).
pub fn coords_from(v: &[f64], unit: bool) -> Coords<f64> {
    let mut c = Flat(core::array::from_fn(|i| v[i]));
    if unit {
        for b in 0..2 {
            let p = c.p(b);
            let n = p.norm();
            let p = if n > 1e-3 { p / n } else { Vector4::new(1.0, 0.0, 0.0, 0.0) };
            c.set(BODY * b + 3, p.as_slice());
        }
    }
    c
}

/// The coordinates with every velocity set to zero (the trajectory stands still).
pub fn at_rest(c: &Coords<f64>) -> Coords<f64> {
    let mut c = *c;
    for b in 0..2 {
        c.set(BODY * b + 7, &[0.0; 10]);
    }
    c
}

// ---------------------------------------------------------------------------
// Exact trajectories with constant velocities.
// ---------------------------------------------------------------------------

/// How the Euler parameters move along the trajectory.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Rot {
    /// `p(t) = p0 + ṗ t` (euler; p need not be unit).
    Line,
    /// `p(t) = q(ω t) ⊗ p0` (ω in the reference frame: omega_inertial, relative_b1).
    Left,
    /// `p(t) = p0 ⊗ q(ω t)` (ω in the moving body: omega_body, relative_b2).
    Right,
}

/// Hamilton product, scalar first.
pub fn quat_mul<T: SimdRealField + Copy>(a: &Vector4<T>, b: &Vector4<T>) -> Vector4<T> {
    Vector4::new(
        a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
        a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
        a[0] * b[2] + a[2] * b[0] + a[3] * b[1] - a[1] * b[3],
        a[0] * b[3] + a[3] * b[0] + a[1] * b[2] - a[2] * b[1],
    )
}

/// The unit quaternion of the rotation vector `w t` (`w` constant, `t` the variable).
pub fn exp_rot<T: SimdRealField + Copy>(w: &Vector3<f64>, t: T) -> Vector4<T> {
    let n = w.norm();
    if n == 0.0 {
        return Vector4::new(lift(1.0), lift(0.0), lift(0.0), lift(0.0));
    }
    let half = lift::<T>(0.5 * n) * t;
    let (s, c) = (half.simd_sin(), half.simd_cos());
    Vector4::new(c, s * lift(w.x / n), s * lift(w.y / n), s * lift(w.z / n))
}

/// The coordinates at time `t` along the trajectory through `c0` with its (constant) velocities.
pub fn along<T: SimdRealField + Copy>(c0: &Coords<f64>, rot: Rot, t: T) -> Coords<T> {
    let mut c = c0.map(lift::<T>);
    for b in 0..2 {
        let (x, xd, p0, pd) = (c.x(b), c.xd(b), c.p(b), c.pd(b));
        let x = [x[0] + xd[0] * t, x[1] + xd[1] * t, x[2] + xd[2] * t];
        let p = match rot {
            Rot::Line => Vector4::new(p0[0] + pd[0] * t, p0[1] + pd[1] * t, p0[2] + pd[2] * t, p0[3] + pd[3] * t),
            Rot::Left => quat_mul(&exp_rot(&c0.w(b), t), &p0),
            Rot::Right => quat_mul(&p0, &exp_rot(&c0.w(b), t)),
        };
        c.set(BODY * b, &x);
        c.set(BODY * b + 3, p.as_slice());
    }
    c
}

/// `c` with its velocities replaced by the velocity vector `v` of a
/// formulation of `C` columns: 14 (`euler`: `ṙ, ṗ` per body), 12 (the ω
/// formulations: `ṙ, ω` per body) or 6 (the relative ones: `δ̇, ω`).
pub fn with_velocity<T: SimdRealField + Copy, const C: usize>(c: &Coords<T>, v: &SVector<T, C>) -> Coords<T> {
    let mut c = *c;
    let bodies = if C == 6 { 1 } else { 2 };
    let per = C / bodies;
    for b in 0..bodies {
        let o = per * b;
        c.set(BODY * b + 7, &[v[o], v[o + 1], v[o + 2]]);
        let rest: Vec<T> = (3..per).map(|i| v[o + i]).collect();
        c.set(BODY * b + if per == 7 { 13 } else { 10 }, &rest);
    }
    c
}

// ---------------------------------------------------------------------------
// Formulations: state types, trajectories, velocity vectors.
// ---------------------------------------------------------------------------

/// A formulation with `C` velocity columns: how its rotations move, its state
/// type and its velocity vector.
pub trait Form<const C: usize> {
    /// How the Euler parameters move along the exact trajectory.
    const ROT: Rot;
    /// The joint state of the formulation.
    type State<T: SimdRealField + Copy>;
    /// The state at the coordinates `c` and time `t`.
    fn build<T: SimdRealField + Copy>(c: &Coords<T>, t: f64) -> Self::State<T>;
    /// The velocity vector `v` (J v = dΦ/dt for an undriven joint).
    fn velocity(c: &Coords<f64>) -> SVector<f64, C>;
}

/// `euler`: `ṙ, ṗ` per body.
pub struct Euler;
/// `omega_inertial`: `ṙ, ω` per body, ω in the inertial frame.
pub struct OmegaInertial;
/// `omega_body`: `ṙ, ω'` per body, ω' in the body frame.
pub struct OmegaBodyF;
/// `relative_b1`: `δ̇, ω_rel` in B1.
pub struct RelB1;
/// `relative_b2`: `δ̇, ω_rel` in B2.
pub struct RelB2;

fn euler_body<T: SimdRealField + Copy>(c: &Coords<T>, b: usize) -> EulerBody<T> {
    EulerBody { r: c.x(b), p: c.p(b), rdot: c.xd(b), pdot: c.pd(b) }
}
fn omega_body<T: SimdRealField + Copy>(c: &Coords<T>, b: usize) -> OmegaBody<T> {
    OmegaBody { r: c.x(b), p: c.p(b), rdot: c.xd(b), omega: c.w(b) }
}
fn relative<T: SimdRealField + Copy>(c: &Coords<T>, t: f64) -> RelativeState<T> {
    RelativeState { delta: c.x(0), p: c.p(0), delta_dot: c.xd(0), omega: c.w(0), t }
}
fn omega_velocity(c: &Coords<f64>) -> SVector<f64, 12> {
    SVector::from_column_slice(&[c.xd(0).as_slice(), c.w(0).as_slice(), c.xd(1).as_slice(), c.w(1).as_slice()].concat())
}
fn relative_velocity(c: &Coords<f64>) -> SVector<f64, 6> {
    SVector::from_column_slice(&[c.xd(0).as_slice(), c.w(0).as_slice()].concat())
}

impl Form<14> for Euler {
    const ROT: Rot = Rot::Line;
    type State<T: SimdRealField + Copy> = TwoBodies<EulerBody<T>>;
    fn build<T: SimdRealField + Copy>(c: &Coords<T>, t: f64) -> Self::State<T> {
        TwoBodies { body1: euler_body(c, 0), body2: euler_body(c, 1), t }
    }
    fn velocity(c: &Coords<f64>) -> SVector<f64, 14> {
        SVector::from_column_slice(
            &[c.xd(0).as_slice(), c.pd(0).as_slice(), c.xd(1).as_slice(), c.pd(1).as_slice()].concat(),
        )
    }
}

/// The two ω formulations and the two relative ones differ only in [`Form::ROT`].
macro_rules! form {
    ($form:ty, $c:literal, $rot:ident, $state:ty, |$co:ident, $t:ident| $build:expr, $velocity:ident) => {
        impl Form<$c> for $form {
            const ROT: Rot = Rot::$rot;
            type State<T: SimdRealField + Copy> = $state;
            fn build<T: SimdRealField + Copy>($co: &Coords<T>, $t: f64) -> Self::State<T> {
                $build
            }
            fn velocity(c: &Coords<f64>) -> SVector<f64, $c> {
                $velocity(c)
            }
        }
    };
}

form!(
    OmegaInertial,
    12,
    Left,
    TwoBodies<OmegaBody<T>>,
    |c, t| TwoBodies { body1: omega_body(c, 0), body2: omega_body(c, 1), t },
    omega_velocity
);
form!(
    OmegaBodyF,
    12,
    Right,
    TwoBodies<OmegaBody<T>>,
    |c, t| TwoBodies { body1: omega_body(c, 0), body2: omega_body(c, 1), t },
    omega_velocity
);
form!(RelB1, 6, Left, RelativeState<T>, |c, t| relative(c, t), relative_velocity);
form!(RelB2, 6, Right, RelativeState<T>, |c, t| relative(c, t), relative_velocity);

// ---------------------------------------------------------------------------
// Comparisons.
// ---------------------------------------------------------------------------

/// The largest absolute value (0 for none).
pub fn max_abs(xs: &[f64]) -> f64 {
    xs.iter().fold(0.0, |m, x| m.max(x.abs()))
}

/// `J v`, summed in column order.
pub fn matvec<const R: usize, const C: usize>(j: &SMatrix<f64, R, C>, v: &SVector<f64, C>) -> SVector<f64, R> {
    SVector::from_fn(|i, _| (0..C).map(|k| j[(i, k)] * v[k]).sum())
}

/// The magnitude of each output of `f` at the inputs' absolute values: the largest
/// `|f|` over the case `x` and 16 fixed patterns of flipped signs, `flipped(x, flip)`
/// passing every number of the case that may change sign through `flip` (unit Euler
/// parameters stay unit). The monomial scale of `CONVENTIONS.md` depends on the
/// inputs' absolute values only, so this is a lower bound of it that is not fooled
/// by a cancellation at one particular point.
pub fn magnitude<X>(
    x: &X,
    flipped: impl Fn(&X, &mut dyn FnMut(f64) -> f64) -> X,
    f: impl Fn(&X) -> Vec<f64>,
) -> Vec<f64> {
    let mut m: Vec<f64> = f(x).iter().map(|y| y.abs()).collect();
    let mut seed = 0x9E37_79B9_7F4A_7C15_u64;
    let mut flip = |y: f64| {
        seed = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
        if seed >> 63 == 1 { -y } else { y }
    };
    for _ in 0..16 {
        for (mi, y) in m.iter_mut().zip(f(&flipped(x, &mut flip))) {
            *mi = mi.max(y.abs());
        }
    }
    m
}

/// A failed comparison, with its message (a `std::error::Error`, so that `?`
/// turns it into a proptest failure).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Mismatch(pub String);

impl fmt::Display for Mismatch {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for Mismatch {}

/// Every entry `i` of `got` within `tol · (1 + max(max |got|, max |want|, mag[i]))`
/// of `want` (`mag` may be shorter, missing entries count 0); `rows` names matrix
/// entries (column-major).
pub fn close(what: &str, got: &[f64], want: &[f64], rows: usize, tol: f64, mag: &[f64]) -> Result<(), Mismatch> {
    if got.len() != want.len() {
        return Err(Mismatch(format!("{what}: lengths differ ({} and {})", got.len(), want.len())));
    }
    let common = max_abs(want).max(max_abs(got));
    for (i, (g, w)) in got.iter().zip(want).enumerate() {
        let scale = 1.0 + common.max(mag.get(i).copied().unwrap_or(0.0));
        if !(g.is_finite() && w.is_finite() && (g - w).abs() <= tol * scale) {
            return Err(Mismatch(format!(
                "{what} entry ({}, {}): got {g:e}, expected {w:e}, |diff| = {:e} > {tol:e} · {scale:e}",
                i % rows,
                i / rows,
                (g - w).abs(),
            )));
        }
    }
    Ok(())
}

/// Bitwise equality (`+0.0` and `−0.0` count as different); `rows` as in [`close`].
pub fn bitwise(what: &str, got: &[f64], want: &[f64], rows: usize) -> Result<(), Mismatch> {
    if got.len() != want.len() {
        return Err(Mismatch(format!("{what}: lengths differ ({} and {})", got.len(), want.len())));
    }
    for (i, (g, w)) in got.iter().zip(want).enumerate() {
        if g.to_bits() != w.to_bits() {
            return Err(Mismatch(format!("{what} entry ({}, {}): {g:e} and {w:e} differ bitwise", i % rows, i / rows)));
        }
    }
    Ok(())
}
