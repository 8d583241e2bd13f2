//! Time functions for driven joints: value, rate and acceleration at time `t`.
//!
//! A driver's generated code calls [`TimeFunction::eval`] once per evaluation at
//! the state's `t` and uses the three numbers in Φ, Φ_t and γ (whose time terms
//! `−2Φ_qt q̇ − Φ_tt` need the rate and the acceleration). Any type can drive a
//! joint: implement the trait, or pass a closure `|t| Drive { .. }`.

use core::f64::consts::PI;

/// A time function's value, rate and acceleration at one instant. It is itself a
/// time function (frozen at that instant), which is how tests feed given values.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Drive {
    /// θ(t) (an angle in radians, or a length).
    pub value: f64,
    /// θ̇(t).
    pub rate: f64,
    /// θ̈(t).
    pub accel: f64,
}

/// A prescribed motion θ(t) with its first two derivatives.
pub trait TimeFunction {
    /// Value, rate and acceleration at `t`.
    fn eval(&self, t: f64) -> Drive;
}

impl TimeFunction for Drive {
    fn eval(&self, _t: f64) -> Drive {
        *self
    }
}

impl<F: Fn(f64) -> Drive> TimeFunction for F {
    fn eval(&self, t: f64) -> Drive {
        self(t)
    }
}

/// θ(t) = value.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Constant(pub f64);

impl TimeFunction for Constant {
    fn eval(&self, _t: f64) -> Drive {
        Drive { value: self.0, rate: 0.0, accel: 0.0 }
    }
}

/// θ(t) = start + rate · t: a motor at constant speed.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Ramp {
    /// θ(0).
    pub start: f64,
    /// θ̇.
    pub rate: f64,
}

impl TimeFunction for Ramp {
    fn eval(&self, t: f64) -> Drive {
        Drive { value: self.start + self.rate * t, rate: self.rate, accel: 0.0 }
    }
}

/// θ(t) = Σ c_i tⁱ (coefficients from the constant term up), by Horner's rule.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Polynomial<const N: usize>(#[cfg_attr(feature = "serde", serde(with = "crate::serde_array"))] pub [f64; N]);

impl<const N: usize> TimeFunction for Polynomial<N> {
    fn eval(&self, t: f64) -> Drive {
        let (mut v, mut d, mut dd) = (0.0, 0.0, 0.0);
        for &c in self.0.iter().rev() {
            dd = dd * t + 2.0 * d;
            d = d * t + v;
            v = v * t + c;
        }
        Drive { value: v, rate: d, accel: dd }
    }
}

/// θ(t) = offset + amplitude · sin(frequency · t + phase), frequency in rad/s.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Sinusoid {
    /// Mean value.
    pub offset: f64,
    /// Amplitude.
    pub amplitude: f64,
    /// Angular frequency (rad/s).
    pub frequency: f64,
    /// Phase (rad).
    pub phase: f64,
}

impl TimeFunction for Sinusoid {
    fn eval(&self, t: f64) -> Drive {
        let x = self.frequency * t + self.phase;
        let (s, c) = (libm::sin(x), libm::cos(x));
        let w = self.frequency;
        Drive {
            value: self.offset + self.amplitude * s,
            rate: self.amplitude * w * c,
            accel: -self.amplitude * w * w * s,
        }
    }
}

/// The shape of a [`SmoothStep`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
pub enum Profile {
    /// `u − sin(2πu)/2π`: zero rate and acceleration at both ends.
    Cycloidal,
    /// `10u³ − 15u⁴ + 6u⁵`: zero rate and acceleration at both ends.
    Quintic,
}

/// A rest-to-rest move from `from` at `t0` to `to` at `t1`, constant outside.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct SmoothStep {
    /// Value before `t0`.
    pub from: f64,
    /// Value after `t1`.
    pub to: f64,
    /// Start of the move.
    pub t0: f64,
    /// End of the move (`t1 > t0`).
    pub t1: f64,
    /// Shape of the move.
    pub profile: Profile,
}

impl TimeFunction for SmoothStep {
    fn eval(&self, t: f64) -> Drive {
        let span = self.t1 - self.t0;
        // A degenerate (or NaN) span is a jump at t0.
        if span.is_nan() || span <= 0.0 || t <= self.t0 {
            return Drive { value: if t <= self.t0 { self.from } else { self.to }, rate: 0.0, accel: 0.0 };
        }
        if t >= self.t1 {
            return Drive { value: self.to, rate: 0.0, accel: 0.0 };
        }
        let u = (t - self.t0) / span;
        let (s, ds, dds) = match self.profile {
            Profile::Cycloidal => {
                let a = 2.0 * PI * u;
                (u - libm::sin(a) / (2.0 * PI), 1.0 - libm::cos(a), 2.0 * PI * libm::sin(a))
            }
            Profile::Quintic => {
                let (u2, u3) = (u * u, u * u * u);
                (
                    u3 * (10.0 - 15.0 * u + 6.0 * u2),
                    30.0 * u2 * (1.0 - 2.0 * u + u2),
                    60.0 * u * (1.0 - 3.0 * u + 2.0 * u2),
                )
            }
        };
        let h = self.to - self.from;
        Drive { value: self.from + h * s, rate: h * ds / span, accel: h * dds / (span * span) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rate and acceleration agree with central differences of the value and rate.
    fn check(f: &dyn TimeFunction, t: f64) {
        let h = 1e-5;
        let (a, b, c) = (f.eval(t - h), f.eval(t), f.eval(t + h));
        let scale = 1.0 + b.value.abs() + b.rate.abs() + b.accel.abs();
        assert!(((c.value - a.value) / (2.0 * h) - b.rate).abs() < 1e-6 * scale, "rate at {t}");
        assert!(((c.rate - a.rate) / (2.0 * h) - b.accel).abs() < 1e-5 * scale, "accel at {t}");
    }

    #[test]
    fn derivatives_match_differences() {
        let fs: [&dyn TimeFunction; 6] = [
            &Constant(0.3),
            &Ramp { start: 0.1, rate: -2.0 },
            &Polynomial([1.0, -2.0, 0.5, 0.25]),
            &Sinusoid { offset: 0.2, amplitude: 1.5, frequency: 3.0, phase: 0.4 },
            &SmoothStep { from: 1.0, to: 3.0, t0: 0.5, t1: 2.0, profile: Profile::Cycloidal },
            &SmoothStep { from: 1.0, to: -3.0, t0: 0.5, t1: 2.0, profile: Profile::Quintic },
        ];
        for f in fs {
            for t in [0.7, 1.1, 1.9] {
                check(f, t);
            }
        }
    }

    #[test]
    fn smooth_steps_rest_at_both_ends() {
        for profile in [Profile::Cycloidal, Profile::Quintic] {
            let s = SmoothStep { from: 1.0, to: 3.0, t0: 0.5, t1: 2.0, profile };
            assert_eq!(s.eval(0.0), Drive { value: 1.0, rate: 0.0, accel: 0.0 });
            assert_eq!(s.eval(2.5), Drive { value: 3.0, rate: 0.0, accel: 0.0 });
            let mid = s.eval(1.25);
            assert!((mid.value - 2.0).abs() < 1e-15 && mid.accel.abs() < 1e-12);
            let near = s.eval(0.5 + 1e-6);
            assert!(near.rate.abs() < 1e-5 && near.accel.abs() < 1e-3);
        }
    }

    #[test]
    fn polynomial_by_hand() {
        let d = Polynomial([1.0, 2.0, 3.0]).eval(2.0);
        assert_eq!(d, Drive { value: 1.0 + 4.0 + 12.0, rate: 2.0 + 12.0, accel: 6.0 });
    }
}
