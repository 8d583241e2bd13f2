//! The index-3 generalised-α method on the rotation group (Chung & Hulbert
//! 1993; Arnold & Brüls 2007; Brüls & Cardona 2010), with the exact iteration
//! matrix.
//!
//! With the pseudo-acceleration `a` and the step's increment `Δq`:
//!
//! ```text
//! q_{n+1} = q_n ⊕ h Δq,          Δq = v_n + h (½ − β) a_n + h β a_{n+1}
//! v_{n+1} = v_n + h (1 − γ) a_n + h γ a_{n+1}
//! (1 − α_m) a_{n+1} + α_m a_n = (1 − α_f) v̇_{n+1} + α_f v̇_n
//! M v̇_{n+1} + Jᵀ λ_{n+1} = Q(q_{n+1}, v_{n+1}, t_{n+1}),     Φ(q_{n+1}, t_{n+1}) = 0
//! ```
//!
//! The parameters come from the spectral radius at infinity ρ∞
//! ([`SimulationOptions::spectral_radius`](super::SimulationOptions)):
//! `α_m = (2ρ∞ − 1)/(ρ∞ + 1)`, `α_f = ρ∞/(ρ∞ + 1)`, `γ = ½ + α_f − α_m`,
//! `β = ¼ (γ + ½)²`: second order, unconditionally stable, high frequencies
//! damped to ρ∞ per step (1: none, 0: annihilated in one step).
//!
//! Newton corrects `Δq` by `x` and `λ` by `δλ`; then `δq = h T x` (`T` the
//! right Jacobian of the rotation update), `δv = (γ/β) x`,
//! `δv̇ = (1 − α_m)/((1 − α_f) h β) x`, and the iteration matrix is
//!
//! ```text
//! [ S   Jᵀ ]   S = c₁ M + h (K − Q_q) T − c₂ Q_v,   K = ∂(Jᵀλ)/∂q (generated)
//! [ J T  0 ]   c₁ = (1 − α_m)/((1 − α_f) h β),   c₂ = γ/β
//! ```
//!
//! solved by its Schur complement `J T S⁻¹ Jᵀ` (`NV + M` is not a stable const
//! generic), with the step's redundant rows held at `δλ = 0` (the rule of the
//! other integrators, from `J M⁻¹ Jᵀ`). A scene without generated terms gets
//! `K` by differences of `Jᵀλ`.

use nalgebra::SVector;

use crate::absolute::buf::{zero_state, zeros};
use crate::analysis::{AnalysisError, apply_increment, set_velocities};
use crate::scene::SystemState;

/// What a step of generalised-α carries to the next: the acceleration, the
/// pseudo-acceleration and the multipliers, with the state the step handed
/// back (a step from any other state starts the method afresh).
#[derive(Clone, Copy, Debug)]
pub(crate) struct AlphaHistory<const NB: usize, const NV: usize, const M: usize> {
    pub(crate) state: SystemState<NB>,
    pub(crate) vdot: SVector<f64, NV>,
    pub(crate) a: SVector<f64, NV>,
    pub(crate) lambda: SVector<f64, M>,
}

impl<const NB: usize, const NV: usize, const M: usize> AlphaHistory<NB, NV, M> {
    /// Zeros, the state's Euler parameters too: a constant, for a
    /// workspace made in the heap (`absolute::buf`).
    pub(crate) const fn zeros() -> Self {
        AlphaHistory { state: zero_state(), vdot: zeros(), a: zeros(), lambda: zeros() }
    }

    /// Written over, field by field (no history in the caller's frame).
    pub(crate) fn set(
        &mut self,
        state: &SystemState<NB>,
        (vdot, a): (&SVector<f64, NV>, &SVector<f64, NV>),
        lambda: &SVector<f64, M>,
    ) {
        self.state.clone_from(state);
        self.vdot.copy_from(vdot);
        self.a.copy_from(a);
        self.lambda.copy_from(lambda);
    }
}

/// The method's coefficients for ρ∞.
#[derive(Clone, Copy)]
pub(crate) struct Coefficients {
    pub(crate) alpha_m: f64,
    pub(crate) alpha_f: f64,
    pub(crate) gamma: f64,
    pub(crate) beta: f64,
}

/// Newmark's β and γ of generalised-α for the spectral radius `rho`.
pub(super) fn newmark(rho: f64) -> (f64, f64) {
    let c = Coefficients::new(rho);
    (c.beta, c.gamma)
}

impl Coefficients {
    /// The coefficients for ρ∞ = `rho`.
    ///
    /// # Errors
    /// [`AnalysisError::BadOption`] for `rho` outside `[0, 1]`.
    pub(crate) fn checked(rho: f64) -> Result<Self, AnalysisError> {
        if !(0.0..=1.0).contains(&rho) {
            return Err(AnalysisError::BadOption { name: "spectral_radius" });
        }
        Ok(Coefficients::new(rho))
    }

    /// `c₁ = (1 − α_m)/((1 − α_f) h β)`, the mass's factor in the iteration matrix.
    pub(crate) fn mass_factor(&self, h: f64) -> f64 {
        (1.0 - self.alpha_m) / ((1.0 - self.alpha_f) * h * self.beta)
    }

    /// [`predicted`](Self::predicted) into `out`, entry by entry (the same
    /// operations, so the same bits).
    pub(crate) fn predicted_into<const NB: usize, const NV: usize, const M: usize>(
        &self,
        past: &AlphaHistory<NB, NV, M>,
        out: &mut SVector<f64, NV>,
    ) {
        for ((o, v), a) in out.as_mut_slice().iter_mut().zip(past.vdot.as_slice().iter()).zip(past.a.as_slice().iter())
        {
            *o = (v - a * self.alpha_m) / (1.0 - self.alpha_m);
        }
    }

    fn new(rho: f64) -> Self {
        let alpha_m = (2.0 * rho - 1.0) / (rho + 1.0);
        let alpha_f = rho / (rho + 1.0);
        let gamma = 0.5 + alpha_f - alpha_m;
        Coefficients { alpha_m, alpha_f, gamma, beta: 0.25 * (gamma + 0.5) * (gamma + 0.5) }
    }
}

/// The unknowns of one step and what follows from them.
pub(crate) struct Iterate<const NB: usize, const NV: usize, const M: usize> {
    pub(crate) dq: SVector<f64, NV>,
    pub(crate) a: SVector<f64, NV>,
    pub(crate) v: SVector<f64, NV>,
    pub(crate) vdot: SVector<f64, NV>,
    pub(crate) lambda: SVector<f64, M>,
    pub(crate) state: SystemState<NB>,
}

impl<const NB: usize, const NV: usize, const M: usize> Iterate<NB, NV, M> {
    /// Zeros, as [`AlphaHistory::zeros`].
    pub(crate) const fn zeros() -> Self {
        Iterate { dq: zeros(), a: zeros(), v: zeros(), vdot: zeros(), lambda: zeros(), state: zero_state() }
    }

    /// The state and rates that follow from the pseudo-acceleration `self.a`
    /// (multipliers `self.lambda`), written over `self`: no vector in the
    /// caller's frame.
    pub(crate) fn follow(
        &mut self,
        y0: &SystemState<NB>,
        v0: &SVector<f64, NV>,
        past: &AlphaHistory<NB, NV, M>,
        h: f64,
        c: Coefficients,
    ) {
        let (q, v, d) = (h * (0.5 - c.beta), h * (1.0 - c.gamma), 1.0 - c.alpha_f);
        let outputs = self.dq.iter_mut().zip(self.v.iter_mut()).zip(self.vdot.iter_mut());
        let inputs = self.a.iter().zip(past.a.iter()).zip(v0.iter().zip(past.vdot.iter()));
        for (((dq, vel), vdot), ((&a, &pa), (&v0, &pv))) in outputs.zip(inputs) {
            *dq = v0 + pa * q + a * (h * c.beta);
            *vel = v0 + pa * v + a * (h * c.gamma);
            *vdot = (a * (1.0 - c.alpha_m) + pa * c.alpha_m - pv * c.alpha_f) / d;
        }
        self.state = *y0;
        apply_increment(&mut self.state, &self.dq, h);
        set_velocities(&mut self.state, &self.v);
        self.state.t = y0.t + h;
    }

    /// The iterate after the Newton correction `(x, δλ)`, written over `self`.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn correct(
        &mut self,
        y0: &SystemState<NB>,
        v0: &SVector<f64, NV>,
        past: &AlphaHistory<NB, NV, M>,
        x: &SVector<f64, NV>,
        dlambda: &SVector<f64, M>,
        h: f64,
        c: Coefficients,
    ) {
        let s = h * c.beta;
        for (a, x) in self.a.iter_mut().zip(x.iter()) {
            *a -= x / s;
        }
        self.lambda -= dlambda;
        self.follow(y0, v0, past, h, c);
    }

    /// [`history`](Self::history) written over `out`.
    pub(crate) fn history_into(&self, out: &mut AlphaHistory<NB, NV, M>) {
        out.set(&self.state, (&self.vdot, &self.a), &self.lambda);
    }
}

/// [`mass_times`] into `y` (entries past the bodies copied from `x`).
pub(crate) fn mass_times_into<const NB: usize, const NV: usize>(
    inertias: &[crate::scene::BodyInertia; NB],
    x: &SVector<f64, NV>,
    y: &mut SVector<f64, NV>,
) {
    y.copy_from(x);
    for (b, inertia) in inertias.iter().enumerate() {
        if 6 * b + 6 > NV {
            break;
        }
        let w = nalgebra::Vector3::new(x[6 * b + 3], x[6 * b + 4], x[6 * b + 5]);
        let r = inertia.inertia * w;
        for k in 0..3 {
            y[6 * b + k] = x[6 * b + k] * inertia.mass;
            y[6 * b + 3 + k] = r[k];
        }
    }
}
