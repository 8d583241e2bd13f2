//! Counting the arithmetic of hand-written code.
//!
//! [`HandScalar`] is what nalgebra's matrix and vector arithmetic needs of a
//! scalar, plus a way to write constants; the hand-written joints of
//! [`handwritten`](super::handwritten) run on any of its implementations. One of
//! them, [`Counted`], is an `f64` whose binary `+`, `−`, `×`, `÷` (and their
//! assign forms) each add one to a thread-local counter, while negation is free:
//! the rule by which the derive counts its generated code (`Joint::OPS`). Run a
//! computation under [`count`] to learn how many operations it did:
//!
//! ```
//! use joint_examples::report::counting::{Counted, count};
//!
//! let (x, ops) = count(|| Counted::new(2.0) * Counted::new(3.0) + Counted::new(1.0));
//! assert_eq!((x.value(), ops), (7.0, 2));
//! ```

use std::cell::Cell;
use std::fmt;
use std::ops::{Add, AddAssign, Div, DivAssign, Mul, MulAssign, Neg, Sub, SubAssign};

use joint_runtime::nalgebra::{Scalar, Vector3, Vector4};
use joint_runtime::{EulerBody, OmegaBody, RelativeState, TwoBodies};
use num_traits::{One, Zero};

/// The scalars hand-written nalgebra code runs on: nalgebra's requirements for
/// matrix and vector arithmetic (`Scalar`, `Zero`, `One`, the closed arithmetic
/// operators and their assign forms, negation) and a conversion from `f64` for
/// constants such as the 2 in `A = (e0² − eᵀe) I + 2 e eᵀ + 2 e0 ẽ`.
pub trait HandScalar:
    Scalar
    + Copy
    + Zero
    + One
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + AddAssign
    + SubAssign
    + MulAssign
    + DivAssign
    + Neg<Output = Self>
{
    /// The constant `x` in this scalar (rounded for `f32`).
    fn from_f64(x: f64) -> Self;
}

impl HandScalar for f64 {
    fn from_f64(x: f64) -> Self {
        x
    }
}

impl HandScalar for f32 {
    fn from_f64(x: f64) -> Self {
        x as f32
    }
}

thread_local! {
    static OPERATIONS: Cell<usize> = const { Cell::new(0) };
}

fn tick() {
    OPERATIONS.with(|n| n.set(n.get() + 1));
}

/// Runs `f` and returns its result with the number of binary `+`, `−`, `×`, `÷`
/// that [`Counted`] values did on this thread meanwhile (negations are free).
/// Calls nest: an inner `count` sees only its own operations, the outer one all.
pub fn count<R>(f: impl FnOnce() -> R) -> (R, usize) {
    let before = OPERATIONS.with(Cell::get);
    let result = f();
    let after = OPERATIONS.with(Cell::get);
    (result, after - before)
}

/// An `f64` that counts its arithmetic: each binary `+`, `−`, `×`, `÷` (and
/// `+=`, `−=`, `×=`, `÷=`) adds one to a thread-local counter read by [`count`].
///
/// Free: negation (it folds into the next operation, as in the derive's count),
/// comparisons, conversions, and a product with the literal `one()` that
/// nalgebra's generic matrix products multiply by (`y = α A x + β y` with
/// `α = β = 1`): the compiler removes those at `f64`, so counting them would
/// charge hand-written nalgebra code for work it never does. A product with a
/// *value* that happens to be 1 (an axis `[0, 1, 0]`) counts as usual.
#[derive(Clone, Copy, Default)]
pub struct Counted {
    value: f64,
    /// Made by `One::one()` (or its negation): multiplying by it is free.
    literal_one: bool,
}

impl Counted {
    /// Wraps `x`.
    pub const fn new(x: f64) -> Self {
        Counted { value: x, literal_one: false }
    }

    /// The wrapped value.
    pub const fn value(self) -> f64 {
        self.value
    }
}

impl PartialEq for Counted {
    fn eq(&self, other: &Self) -> bool {
        self.value == other.value
    }
}

impl PartialOrd for Counted {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        self.value.partial_cmp(&other.value)
    }
}

impl fmt::Debug for Counted {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Debug::fmt(&self.value, f)
    }
}

impl fmt::Display for Counted {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(&self.value, f)
    }
}

impl From<f64> for Counted {
    fn from(x: f64) -> Self {
        Counted::new(x)
    }
}

/// The counted result of `a op b`; `free` when the compiler would remove it.
fn counted(value: f64, free: bool) -> Counted {
    if !free {
        tick();
    }
    Counted::new(value)
}

macro_rules! counted_op {
    ($Op:ident, $op:ident, $OpAssign:ident, $op_assign:ident, $sym:tt, $free:expr) => {
        impl $Op for Counted {
            type Output = Counted;
            fn $op(self, rhs: Counted) -> Counted {
                let free: fn(&Counted, &Counted) -> bool = $free;
                counted(self.value $sym rhs.value, free(&self, &rhs))
            }
        }

        impl $OpAssign for Counted {
            fn $op_assign(&mut self, rhs: Counted) {
                *self = *self $sym rhs;
            }
        }
    };
}

counted_op!(Add, add, AddAssign, add_assign, +, |_, _| false);
counted_op!(Sub, sub, SubAssign, sub_assign, -, |_, _| false);
counted_op!(Mul, mul, MulAssign, mul_assign, *, |a, b| a.literal_one || b.literal_one);
counted_op!(Div, div, DivAssign, div_assign, /, |_, _| false);

impl Neg for Counted {
    type Output = Counted;
    fn neg(self) -> Counted {
        Counted { value: -self.value, literal_one: self.literal_one }
    }
}

impl Zero for Counted {
    fn zero() -> Self {
        Counted::new(0.0)
    }

    fn is_zero(&self) -> bool {
        self.value == 0.0
    }
}

impl One for Counted {
    fn one() -> Self {
        Counted { value: 1.0, literal_one: true }
    }
}

impl HandScalar for Counted {
    fn from_f64(x: f64) -> Self {
        Counted::new(x)
    }
}

/// A state (or any input) at `f64`, turned into the same thing at [`Counted`].
pub trait ToCounted {
    /// The same type over [`Counted`].
    type Counted;
    /// The same values, counting from now on.
    fn to_counted(&self) -> Self::Counted;
}

impl ToCounted for Vector3<f64> {
    type Counted = Vector3<Counted>;
    fn to_counted(&self) -> Vector3<Counted> {
        self.map(Counted::new)
    }
}

impl ToCounted for Vector4<f64> {
    type Counted = Vector4<Counted>;
    fn to_counted(&self) -> Vector4<Counted> {
        self.map(Counted::new)
    }
}

impl ToCounted for EulerBody<f64> {
    type Counted = EulerBody<Counted>;
    fn to_counted(&self) -> EulerBody<Counted> {
        EulerBody {
            r: self.r.to_counted(),
            p: self.p.to_counted(),
            rdot: self.rdot.to_counted(),
            pdot: self.pdot.to_counted(),
        }
    }
}

impl ToCounted for OmegaBody<f64> {
    type Counted = OmegaBody<Counted>;
    fn to_counted(&self) -> OmegaBody<Counted> {
        OmegaBody {
            r: self.r.to_counted(),
            p: self.p.to_counted(),
            rdot: self.rdot.to_counted(),
            omega: self.omega.to_counted(),
        }
    }
}

impl<B: ToCounted> ToCounted for TwoBodies<B> {
    type Counted = TwoBodies<B::Counted>;
    fn to_counted(&self) -> TwoBodies<B::Counted> {
        TwoBodies { body1: self.body1.to_counted(), body2: self.body2.to_counted(), t: self.t }
    }
}

impl ToCounted for RelativeState<f64> {
    type Counted = RelativeState<Counted>;
    fn to_counted(&self) -> RelativeState<Counted> {
        RelativeState {
            delta: self.delta.to_counted(),
            p: self.p.to_counted(),
            delta_dot: self.delta_dot.to_counted(),
            omega: self.omega.to_counted(),
            t: self.t,
        }
    }
}

#[cfg(test)]
mod tests {
    use joint_runtime::nalgebra::{Matrix3, Vector3};

    use super::*;

    fn c(x: f64) -> Counted {
        Counted::new(x)
    }

    #[test]
    fn each_binary_operation_counts_one_and_negation_none() {
        let ((), n) = count(|| {
            let _ = c(1.0) + c(2.0);
            let _ = c(1.0) - c(2.0);
            let _ = c(1.0) * c(2.0);
            let _ = c(1.0) / c(2.0);
        });
        assert_eq!(n, 4);
        let ((), n) = count(|| {
            let mut x = c(1.0);
            x += c(2.0);
            x -= c(0.5);
            x *= c(4.0);
            x /= c(2.0);
            assert_eq!(x.value(), 5.0);
        });
        assert_eq!(n, 4);
        let (x, n) = count(|| -(-c(3.0)));
        assert_eq!((x.value(), n), (3.0, 0));
        let (_, n) = count(|| (Counted::zero(), Counted::one(), Counted::from_f64(2.0), c(1.0) < c(2.0)));
        assert_eq!(n, 0);
    }

    #[test]
    fn values_are_those_of_f64() {
        let (a, b) = (0.1f64, 0.7f64);
        assert_eq!((c(a) * c(b) + c(a) / c(b) - c(b)).value(), a * b + a / b - b);
    }

    #[test]
    fn counts_nest_and_start_from_zero() {
        let ((inner, x), outer) = count(|| {
            let (x, inner) = count(|| c(1.0) + c(1.0));
            (inner, x * c(3.0))
        });
        assert_eq!((inner, outer, x.value()), (1, 2, 6.0));
        assert_eq!(count(|| ()).1, 0);
    }

    #[test]
    fn nalgebra_arithmetic_runs_and_is_counted() {
        let u = Vector3::new(c(1.0), c(2.0), c(3.0));
        let v = Vector3::new(c(-1.0), c(0.5), c(2.0));
        let (w, n) = count(|| u.cross(&v));
        assert_eq!(w, Vector3::new(c(2.5), c(-5.0), c(2.5)));
        assert_eq!(n, 9, "three products and a difference per component");
        let (s, n) = count(|| u + v);
        assert_eq!((s, n), (Vector3::new(c(0.0), c(2.5), c(5.0)), 3));
        let (d, n) = count(|| u.dot(&v));
        assert_eq!(d.value(), 6.0);
        assert!((5..=6).contains(&n), "a dot product of 3-vectors: {n} operations");
        let m = Matrix3::from_fn(|i, j| c((i * 3 + j) as f64));
        let (mv, n) = count(|| m * u);
        assert_eq!(mv, Vector3::new(c(8.0), c(26.0), c(44.0)));
        assert_eq!(n, 15, "3×3 times a vector: nine products, six sums");
        let (_, n) = count(|| m * m);
        assert_eq!(n, 45, "3×3 times 3×3");
        let (_, n) = count(|| u.transpose() * m);
        assert_eq!(n, 15, "a row times 3×3");
    }

    #[test]
    fn products_with_the_literal_one_are_free_but_not_with_a_value_one() {
        let x = c(0.3);
        let (y, n) = count(|| Counted::one() * x * -Counted::one());
        assert_eq!((y.value(), n), (-0.3, 0));
        let (y, n) = count(|| c(1.0) * x);
        assert_eq!((y.value(), n), (0.3, 1));
        let (y, n) = count(|| Counted::one() + x);
        assert_eq!((y.value(), n), (1.3, 1));
        let (y, n) = count(|| (Counted::one() * x) * x);
        assert_eq!((y.value(), n), (0.3 * 0.3, 1), "a product's result is a value");
    }

    #[test]
    fn the_counter_is_per_thread() {
        let ((), here) = count(|| {
            std::thread::spawn(|| c(1.0) + c(2.0)).join().expect("thread runs");
        });
        assert_eq!(here, 0);
    }
}
