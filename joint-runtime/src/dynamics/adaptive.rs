//! Error-controlled variable steps: [`AbsoluteSimulation::integrate`](super::AbsoluteSimulation::integrate) advances a state
//! to a given time with steps chosen so that each step's local error estimate
//! meets `rtol`, `atol` (Hairer, Nørsett & Wanner, *Solving ODEs I*, II.4).
//!
//! - [`Adaptive::DormandPrince`]: the explicit Dormand–Prince 5(4) pair on the
//!   same Lie-group stages as RK4 (`ṗ = ½ p ⊗ (0, ω')`, `p` renormalised where
//!   the scene is evaluated); the error is the difference of the embedded
//!   fourth-order solution, the step advances with the fifth-order one
//!   (local extrapolation). Seven evaluations a step (the first-same-as-last
//!   stage is not reused: projection moves the state between steps).
//! - [`Adaptive::GeneralisedAlpha`]: the implicit index-3 generalised-α of
//!   [`Integrator::GeneralisedAlpha`](super::Integrator) with the local error
//!   estimate of Géradin & Cardona (*Flexible Multibody Dynamics*, 2001, §7.4),
//!   `e = (β − 1/6) h² (a_{n+1} − a_n)`, the leading term of its position error,
//!   with `(γ − ½) h (a_{n+1} − a_n)` for the velocities. That velocity term
//!   is `O(h²)` (the α-relation cancels it over the steps, which a local
//!   estimate cannot see), so it dominates at small steps and the step size
//!   follows `err^(-1/2)`. The global error follows the tolerance in
//!   proportion, at about 14 × it on the double pendulum over 0.5 s
//!   (Dormand–Prince: 2–6 ×).
//!
//! The error norm is the root mean square of `e_i / (atol + rtol · |y_i|)`
//! over positions and (Dormand–Prince) velocities; a step is accepted when it
//! is at most 1, and the next step is `h (0.9 / err)^(1/(p+1))`, between 0.2
//! and 5 times the last (`p + 1` the order of the estimate in `h`: 5, or 2).
//! A step whose stages, Newton iteration or projection fail, or whose
//! estimate is not finite, is retried at a quarter of its size.

use nalgebra::{SVector, Vector3};

use super::{Integrator, Rate, advance};
use crate::analysis::{AnalysisError, velocity_vector};
use crate::scene::SystemState;

/// The error-controlled integrators of [`AbsoluteSimulation::integrate`](super::AbsoluteSimulation::integrate).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
#[non_exhaustive]
pub enum Adaptive {
    /// Explicit Dormand–Prince 5(4), for problems that are not stiff.
    DormandPrince,
    /// Implicit generalised-α with its local error estimate, for stiff ones.
    GeneralisedAlpha,
    /// Implicit Radau IIA of order 5 with RADAU5's error estimate, for stiff
    /// problems at tight tolerances (`radau.rs`; on the sparse path
    /// its stage systems on the saddle-point pattern, `sparse/radau.rs`).
    RadauIIA,
}

impl Adaptive {
    /// The fixed-step integrator whose history an accepted step follows.
    pub(crate) fn integrator(self) -> Integrator {
        match self {
            Adaptive::DormandPrince => Integrator::Rk4,
            Adaptive::GeneralisedAlpha => Integrator::GeneralisedAlpha,
            Adaptive::RadauIIA => Integrator::RadauIIA,
        }
    }
}

/// The local error asked of each step.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Tolerance {
    /// Relative tolerance.
    pub rtol: f64,
    /// Absolute tolerance (metres, radians, and per second for velocities).
    pub atol: f64,
}

/// What one [`AbsoluteSimulation::integrate`](super::AbsoluteSimulation::integrate) did.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[non_exhaustive]
pub struct IntegrationReport {
    /// Steps accepted.
    pub accepted: usize,
    /// Steps rejected (error too large, or Newton did not converge).
    pub rejected: usize,
    /// Evaluations of the constrained dynamics (Dormand–Prince's stages).
    pub evaluations: usize,
    /// Newton iterations (generalised-α).
    pub newton_iterations: usize,
    /// Iteration matrices built and factorised (generalised-α).
    pub newton_matrices: usize,
    /// The last accepted step size.
    pub last_step: f64,
}

/// Steps allowed to one [`AbsoluteSimulation::integrate`](super::AbsoluteSimulation::integrate).
const MAX_STEPS: usize = 10_000_000;

/// Dormand–Prince's stage coefficients `a_ij` (row `i` for stage `i + 1`).
pub(crate) const A: [&[f64]; 6] = [
    &[1.0 / 5.0],
    &[3.0 / 40.0, 9.0 / 40.0],
    &[44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0],
    &[19372.0 / 6561.0, -25360.0 / 2187.0, 64448.0 / 6561.0, -212.0 / 729.0],
    &[9017.0 / 3168.0, -355.0 / 33.0, 46732.0 / 5247.0, 49.0 / 176.0, -5103.0 / 18656.0],
    &[35.0 / 384.0, 0.0, 500.0 / 1113.0, 125.0 / 192.0, -2187.0 / 6784.0, 11.0 / 84.0],
];
/// The stages' times `c_i` (stage 1 at 0).
pub(crate) const C: [f64; 6] = [1.0 / 5.0, 3.0 / 10.0, 4.0 / 5.0, 8.0 / 9.0, 1.0, 1.0];
/// Fifth-order weights less the embedded fourth-order ones.
pub(crate) const E: [f64; 7] =
    [71.0 / 57600.0, 0.0, -71.0 / 16695.0, 71.0 / 1920.0, -17253.0 / 339200.0, 22.0 / 525.0, -1.0 / 40.0];

/// A state the driver advances: its time.
pub(crate) trait Timed: Copy {
    /// The time.
    fn time(&self) -> f64;
    /// Sets the time (the last step lands exactly on `t_end`).
    fn set_time(&mut self, t: f64);
}

impl<const NB: usize> Timed for SystemState<NB> {
    fn time(&self) -> f64 {
        self.t
    }
    fn set_time(&mut self, t: f64) {
        self.t = t;
    }
}

/// What the driver says and decides in a simulation's own error type.
pub(crate) trait StepError: Sized {
    /// An option out of range (`tolerance`, `t_end`).
    fn bad_option(name: &'static str) -> Self;
    /// The step fell below round-off, or too many were taken.
    fn step_too_small(t: f64, step: f64) -> Self;
    /// The error estimate is not finite.
    fn non_finite_estimate() -> Self;
    /// A failure a smaller step may not meet (a stage, Newton iteration or
    /// projection that failed; a non-finite estimate).
    fn retried(&self) -> bool;
}

impl StepError for AnalysisError {
    fn bad_option(name: &'static str) -> Self {
        AnalysisError::BadOption { name }
    }
    fn step_too_small(t: f64, step: f64) -> Self {
        AnalysisError::StepTooSmall { t, step }
    }
    fn non_finite_estimate() -> Self {
        AnalysisError::NonFiniteOutput { quantity: "error estimate", row: None }
    }
    fn retried(&self) -> bool {
        matches!(
            self,
            AnalysisError::ImplicitNotConverged { .. }
                | AnalysisError::Linalg(_)
                | AnalysisError::NonFiniteOutput { .. }
                | AnalysisError::NotConverged { .. }
                | AnalysisError::NoProgress { .. }
        )
    }
}

/// What the error-controlled driver needs of a simulation, dense, sparse or
/// a tree's ([`integrate`] is written once over it).
pub(crate) trait AdaptiveSteps {
    /// The state it steps.
    type State: Timed;
    /// Its error.
    type Error: StepError;
    /// The state is one the scene can be evaluated at.
    fn check_start(&self, state: &Self::State) -> Result<(), Self::Error>;
    /// One trial step of `method` from `y0`: the state reached and its error
    /// norm. A step whose error exceeds 1 leaves the integrator's history as
    /// it was.
    fn trial(
        &mut self,
        y0: &Self::State,
        h: f64,
        method: Adaptive,
        tolerance: Tolerance,
        report: &mut IntegrationReport,
    ) -> Result<(Self::State, f64), Self::Error>;
    /// An accepted step's state, projected if the options say so, with
    /// generalised-α's history following it (dropped by Dormand–Prince).
    fn accept(&mut self, next: Self::State, method: Adaptive) -> Result<Self::State, Self::Error>;
}

/// [`AbsoluteSimulation::integrate`](super::AbsoluteSimulation::integrate) on any simulation: the checks, the first step
/// size and the loop of trial steps.
pub(crate) fn integrate<T: AdaptiveSteps>(
    sim: &mut T,
    state: &mut T::State,
    t_end: f64,
    method: Adaptive,
    tolerance: Tolerance,
) -> Result<IntegrationReport, T::Error> {
    let ok = |x: f64| x > 0.0 && x.is_finite();
    if !(ok(tolerance.rtol) && ok(tolerance.atol)) {
        return Err(T::Error::bad_option("tolerance"));
    }
    if !(t_end.is_finite() && t_end >= state.time()) {
        return Err(T::Error::bad_option("t_end"));
    }
    sim.check_start(state)?;
    let mut report = IntegrationReport::default();
    let h = (1e-3 * (t_end - state.time()).max(1e-3)).min(t_end - state.time());
    adaptive_loop(sim, state, t_end, method, tolerance, h, &mut report).map(|()| report)
}

fn adaptive_loop<T: AdaptiveSteps>(
    sim: &mut T,
    state: &mut T::State,
    t_end: f64,
    method: Adaptive,
    tolerance: Tolerance,
    mut h: f64,
    report: &mut IntegrationReport,
) -> Result<(), T::Error> {
    // The estimate's order in h: Dormand–Prince's 4, generalised-α's
    // velocity part O(h²) (see the module docs), Radau IIA's embedded 3.
    let order = match method {
        Adaptive::DormandPrince => 4.0,
        Adaptive::GeneralisedAlpha => 1.0,
        Adaptive::RadauIIA => 3.0,
    };
    while state.time() < t_end {
        let t = state.time();
        if report.accepted + report.rejected >= MAX_STEPS || h < 1e-14 * (1.0 + libm::fabs(t)) {
            return Err(T::Error::step_too_small(t, h));
        }
        // The last step lands on t_end (and a step within 1 % of it is stretched to it).
        let last = t + 1.01 * h >= t_end;
        let step = if last { t_end - t } else { h };
        let accepted = match sim.trial(state, step, method, tolerance, report) {
            Ok((next, err)) if err <= 1.0 => sim.accept(next, method).map(|next| (next, err)),
            Ok((_, err)) if err.is_finite() => {
                report.rejected += 1;
                let factor = (0.9 * libm::pow(err, -1.0 / (order + 1.0))).clamp(0.2, 1.0);
                h = step * factor;
                continue;
            }
            other => other.and(Err(T::Error::non_finite_estimate())),
        };
        match accepted {
            Ok((next, err)) => {
                *state = next;
                if last {
                    state.set_time(t_end);
                }
                report.accepted += 1;
                report.last_step = step;
                h = step * (0.9 * libm::pow(err.max(1e-10), -1.0 / (order + 1.0))).clamp(0.2, 5.0);
            }
            // A failed Newton iteration, stage or projection, or a
            // non-finite estimate: a smaller step.
            Err(e) if e.retried() => {
                report.rejected += 1;
                h = 0.25 * step;
            }
            Err(e) => return Err(e),
        }
    }
    Ok(())
}

/// One Dormand–Prince step from the normalised `y` (its rate `first`; `rate`
/// evaluates a stage under the step's rule of redundant rows): the
/// fifth-order state and the error norm.
pub(crate) fn dormand_prince<const NB: usize, const NV: usize>(
    y: &SystemState<NB>,
    first: Rate<NB, NV>,
    h: f64,
    tolerance: Tolerance,
    report: &mut IntegrationReport,
    mut rate: impl FnMut(&SystemState<NB>) -> Result<Rate<NB, NV>, AnalysisError>,
) -> Result<(SystemState<NB>, f64), AnalysisError> {
    let t0 = y.t;
    let mut k = [first; 7];
    for (i, row) in A.iter().enumerate() {
        let stage = advance(y, k.iter().zip(row.iter().copied()), h, t0 + C[i] * h);
        if let Some(slot) = k.get_mut(i + 1) {
            *slot = rate(&stage)?;
        }
    }
    report.evaluations += 7;
    let y5 = advance(y, k.iter().zip(A[5].iter().copied()), h, t0 + h);
    let err = dormand_prince_error(y, &y5, &k, h, tolerance);
    Ok((y5, err))
}

/// Generalised-α's error norm for a step from `y0` to `y1` whose
/// accelerations changed by `da` (Géradin & Cardona's estimate, see the
/// module docs); adds the step's Newton work to `report`.
#[allow(clippy::too_many_arguments)]
pub(crate) fn alpha_estimate<const NB: usize, const NV: usize>(
    y0: &SystemState<NB>,
    y1: &SystemState<NB>,
    da: &SVector<f64, NV>,
    h: f64,
    spectral_radius: f64,
    tolerance: Tolerance,
    report: &mut IntegrationReport,
    (iterations, matrices): (usize, usize),
) -> f64 {
    report.newton_iterations += iterations;
    report.newton_matrices += matrices;
    let (e, ev) = alpha_error_increments(da, h, spectral_radius);
    increment_error(y0, y1, &e, &ev, tolerance)
}

/// Géradin and Cardona's estimate of a generalised-α step whose
/// pseudo-acceleration changed by `da`: `(β − 1/6) h² da` for the
/// positions, `(γ − ½) h da` for the velocities (both engines' error
/// control; see the module docs).
pub(crate) fn alpha_error_increments<const NV: usize>(
    da: &SVector<f64, NV>,
    h: f64,
    spectral_radius: f64,
) -> (SVector<f64, NV>, SVector<f64, NV>) {
    let (beta, gamma) = super::generalised_alpha::newmark(spectral_radius);
    (da * ((beta - 1.0 / 6.0) * h * h), da * ((gamma - 0.5) * h))
}

/// Dormand–Prince's error norm over `r`, `p` and the velocities.
fn dormand_prince_error<const NB: usize, const NV: usize>(
    y0: &SystemState<NB>,
    y1: &SystemState<NB>,
    k: &[Rate<NB, NV>; 7],
    h: f64,
    tolerance: Tolerance,
) -> f64 {
    let (v0, v1) = (velocity_vector::<NB, NV>(y0), velocity_vector::<NB, NV>(y1));
    let mut sum = 0.0;
    let mut count = 0usize;
    let mut add = |e: f64, a: f64, b: f64| {
        let scale = tolerance.atol + tolerance.rtol * libm::fabs(a).max(libm::fabs(b));
        sum += (e / scale) * (e / scale);
        count += 1;
    };
    for b in 0..NB {
        let (mut er, mut ep) = (Vector3::zeros(), nalgebra::Vector4::zeros());
        for (rate, &w) in k.iter().zip(E.iter()) {
            er += rate.rdot[b] * (h * w);
            ep += rate.pdot[b] * (h * w);
        }
        for i in 0..3 {
            add(er[i], y0.bodies[b].r[i], y1.bodies[b].r[i]);
        }
        for i in 0..4 {
            add(ep[i], y0.bodies[b].p[i], y1.bodies[b].p[i]);
        }
    }
    let mut ev = SVector::<f64, NV>::zeros();
    for (rate, &w) in k.iter().zip(E.iter()) {
        ev += rate.vdot * (h * w);
    }
    for i in 0..NV {
        add(ev[i], v0[i], v1[i]);
    }
    libm::sqrt(sum / count.max(1) as f64)
}

/// The error norm of generalised-α and Radau IIA over the position increments `e` (translations
/// scaled by the positions, rotations by one radian) and the velocities `ev`.
pub(super) fn increment_error<const NB: usize, const NV: usize>(
    y0: &SystemState<NB>,
    y1: &SystemState<NB>,
    e: &SVector<f64, NV>,
    ev: &SVector<f64, NV>,
    tolerance: Tolerance,
) -> f64 {
    let (v0, v1) = (velocity_vector::<NB, NV>(y0), velocity_vector::<NB, NV>(y1));
    let mut sum = 0.0;
    for (b, (x0, x1)) in y0.bodies.iter().zip(y1.bodies.iter()).enumerate() {
        for i in 0..6 {
            let k = 6 * b + i;
            let size = if i < 3 { libm::fabs(x0.r[i]).max(libm::fabs(x1.r[i])) } else { 1.0 };
            let x = e.get(k).copied().unwrap_or(0.0) / (tolerance.atol + tolerance.rtol * size);
            let speed =
                libm::fabs(v0.get(k).copied().unwrap_or(0.0)).max(libm::fabs(v1.get(k).copied().unwrap_or(0.0)));
            let y = ev.get(k).copied().unwrap_or(0.0) / (tolerance.atol + tolerance.rtol * speed);
            sum += x * x + y * y;
        }
    }
    libm::sqrt(sum / (12 * NB).max(1) as f64)
}
