//! Deterministic random states for the batch tests and the batch benchmark:
//! splitmix64, so a seed gives the same states on every machine without a
//! dependency.

use joint_runtime::nalgebra::{Vector3, Vector4};
use joint_runtime::{EulerBody, OmegaBody, RelativeState};

/// splitmix64; [`Rng::next`] is uniform in [−1, 1).
pub struct Rng(pub u64);

impl Rng {
    /// The next number, uniform in [−1, 1) (53 random bits).
    #[allow(clippy::should_implement_trait)] // not an iterator: it never ends
    pub fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    }
    /// A vector with entries uniform in [−scale, scale).
    pub fn v3(&mut self, scale: f64) -> Vector3<f64> {
        Vector3::new(self.next(), self.next(), self.next()) * scale
    }
    /// Four entries uniform in [−1, 1).
    pub fn v4(&mut self) -> Vector4<f64> {
        Vector4::new(self.next(), self.next(), self.next(), self.next())
    }
    /// Unit Euler parameters (rejecting draws too near zero to normalise well).
    pub fn unit(&mut self) -> Vector4<f64> {
        loop {
            let p = self.v4();
            if p.norm() > 0.1 {
                return p.normalize();
            }
        }
    }
    /// A body of the ω formulations: position within 2 m, speeds to 3 m/s and 10 rad/s.
    pub fn omega_body(&mut self) -> OmegaBody<f64> {
        OmegaBody { r: self.v3(2.0), p: self.unit(), rdot: self.v3(3.0), omega: self.v3(10.0) }
    }
    /// A body of `euler`: Euler parameters up to 20 % off the unit sphere and
    /// rates off its tangent (the generated code takes any).
    pub fn euler_body(&mut self) -> EulerBody<f64> {
        EulerBody { r: self.v3(2.0), p: self.unit() * (1.0 + 0.2 * self.next()), rdot: self.v3(3.0), pdot: self.v4() }
    }
    /// A relative state at time `t`.
    pub fn relative(&mut self, t: f64) -> RelativeState<f64> {
        RelativeState { delta: self.v3(1.0), p: self.unit(), delta_dot: self.v3(3.0), omega: self.v3(10.0), t }
    }
    /// `n` values of `f`.
    pub fn states<S>(&mut self, n: usize, mut f: impl FnMut(&mut Rng) -> S) -> Vec<S> {
        (0..n).map(|_| f(self)).collect()
    }
}
