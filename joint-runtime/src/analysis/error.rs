//! What can go wrong in an analysis or a dynamics step.

// The error type is returned by value: without an allocator it cannot be boxed,
// and it carries the three worst rows by design.

use core::fmt;

use super::{RowInfo, WorstRows};
use crate::linalg::LinalgError;

/// Why an analysis (or a dynamics step) failed. The state is left at the last
/// accepted iterate.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub enum AnalysisError {
    /// An input is NaN or infinite.
    NonFinite {
        /// The body (from [`Scene::BODIES`](crate::Scene::BODIES)), or `None` for the time.
        body: Option<&'static str>,
        /// The field: `"r"`, `"p"`, `"rdot"`, `"omega"` or `"t"`.
        field: &'static str,
    },
    /// A body's Euler parameters are zero (no orientation to normalise).
    ZeroQuaternion {
        /// The body.
        body: &'static str,
    },
    /// The scene produced a non-finite value (e.g. a NaN joint parameter).
    NonFiniteOutput {
        /// `"Φ"`, `"Φ_t"`, `"J"`, `"γ"`, `"forces"` or `"accelerations"`.
        quantity: &'static str,
        /// The first offending row, when the quantity has rows.
        row: Option<RowInfo>,
    },
    /// Newton's method ran out of iterations.
    NotConverged {
        /// Final ‖Φ‖₂.
        residual: f64,
        /// Iterations taken.
        iterations: usize,
        /// The rows whose residual is largest.
        worst: WorstRows,
    },
    /// Newton's method made no progress: no step along the minimum-norm
    /// direction reduced ‖Φ‖ (a singular Jacobian, or an impossible configuration
    /// whose least-squares residual is not zero).
    NoProgress {
        /// ‖Φ‖₂ where it stopped.
        residual: f64,
        /// Iterations taken.
        iterations: usize,
        /// The rows whose residual is largest.
        worst: WorstRows,
    },
    /// A step's start is off its joints by more than the projection's
    /// round-off floor (`1e3 ×` its tolerance): the step would move it onto
    /// them unasked. Assemble the start first
    /// ([`assemble`](crate::analysis::assemble)).
    NotAssembled {
        /// ‖Φ‖₂ at the start.
        residual: f64,
        /// The rows whose residual is largest.
        worst: WorstRows,
    },
    /// A linear analysis (velocity, acceleration, λ) has no solution: redundant
    /// rows contradict the others.
    Inconsistent {
        /// What was solved.
        analysis: Analysis,
        /// ‖J x − b‖₂.
        residual: f64,
        /// The rows whose residual is largest.
        worst: WorstRows,
    },
    /// `NV` is not `6 NB`.
    Dimensions {
        /// Bodies.
        nb: usize,
        /// Velocity columns.
        nv: usize,
    },
    /// A body's mass properties are not a rigid body's
    /// ([`BodyInertia::is_physical`](crate::BodyInertia::is_physical): a mass
    /// that is not positive and finite, a tensor that is not symmetric, or
    /// principal moments that are not positive or break the triangle
    /// inequality).
    BadInertia {
        /// The body.
        body: &'static str,
    },
    /// An option is out of range (a step size that is not positive and finite, ...).
    BadOption {
        /// The option.
        name: &'static str,
    },
    /// A step or `integrate` asked for an integrator whose workspace the
    /// simulation has not made: `AbsoluteSimulation::new` makes the configured
    /// integrator's, `AbsoluteSimulation::prepare` another's (a step never builds
    /// one, so it never allocates).
    NotPrepared {
        /// The integrator, in words ("Radau IIA").
        integrator: &'static str,
        /// Its option, as Rust writes it (`Integrator::RadauIIA`).
        option: &'static str,
    },
    /// The implicit integrator's Newton iteration did not converge.
    ImplicitNotConverged {
        /// Iterations taken.
        iterations: usize,
        /// Last ‖Δv‖₂.
        correction: f64,
    },
    /// A factorisation failed (the implicit integrator's iteration matrix is singular).
    Linalg(LinalgError),
    /// What was asked for needs the scene's generated second-order terms, and
    /// the scene was derived without `#[scene(second_order)]`.
    NoSecondOrder {
        /// What needed them.
        needed_by: &'static str,
    },
    /// Error-controlled steps shrank below `1e-14 (1 + |t|)`, or took ten
    /// million steps: the tolerance cannot be met from here.
    StepTooSmall {
        /// The time reached.
        t: f64,
        /// The step size last tried.
        step: f64,
    },
    /// An implicit step's Newton iteration converged to a solution that gains
    /// more energy than the work done on the mechanism allows: a spurious
    /// solution of the integrator's equations, far from the motion (the step
    /// is too large for them). The state is left unchanged; a smaller step
    /// (or an integrator for stiff problems) follows the motion.
    SpuriousSolution {
        /// The energy gained beyond the work done (J).
        gain: f64,
        /// The scale the gain was compared with (J): the kinetic and elastic
        /// energy at the step's start, the size of the work done and the
        /// change of gravitational energy.
        scale: f64,
    },
    /// An eigenvalue or singular value iteration did not converge.
    NoConvergence {
        /// The decomposition.
        decomposition: &'static str,
    },
}

impl fmt::Display for AnalysisError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            AnalysisError::NonFinite { body: Some(b), field } => {
                write!(f, "non-finite input: field `{field}` of body `{b}` is NaN or infinite")
            }
            AnalysisError::NonFinite { body: None, field } => {
                write!(f, "non-finite input: `{field}` is NaN or infinite")
            }
            AnalysisError::ZeroQuaternion { body } => write!(f, "body `{body}` has zero Euler parameters"),
            AnalysisError::NonFiniteOutput { quantity, row: Some(r) } => {
                write!(f, "the scene's {quantity} is not finite at {r}")
            }
            AnalysisError::NonFiniteOutput { quantity, row: None } => write!(f, "the scene's {quantity} is not finite"),
            AnalysisError::NotConverged { residual, iterations, worst } => write!(
                f,
                "assembly did not converge: |Φ| = {residual:.3e} after {iterations} iterations; largest residuals: {worst}"
            ),
            AnalysisError::NoProgress { residual, iterations, worst } => write!(
                f,
                "assembly made no progress (singular Jacobian or impossible configuration): |Φ| = {residual:.3e} \
                 after {iterations} iterations; largest residuals: {worst}"
            ),
            AnalysisError::NotAssembled { residual, worst } => write!(
                f,
                "the step's start is off its joints (|Φ| = {residual:.3e}; largest residuals: {worst}): assemble it \
                 first (`analysis::assemble`)"
            ),
            AnalysisError::Inconsistent { analysis, residual, worst } => write!(
                f,
                "{analysis} analysis: redundant constraints are inconsistent, residual {residual:.3e}; largest: {worst}"
            ),
            AnalysisError::Dimensions { nb, nv } => {
                write!(f, "a scene of {nb} bodies needs {} velocity columns, not {nv}", 6 * nb)
            }
            AnalysisError::BadInertia { body } => {
                write!(
                    f,
                    "body `{body}` has mass properties no rigid body has: a mass that is not positive, or principal \
                     moments that are not positive or of which one exceeds the sum of the other two"
                )
            }
            AnalysisError::BadOption { name } => write!(f, "option `{name}` is out of range"),
            AnalysisError::NotPrepared { integrator, option } => {
                write!(
                    f,
                    "no workspace for {integrator}: this simulation was made for another integrator; make it with \
                     `SimulationOptions::default().with_integrator({option})`, or call `prepare({option})` once \
                     before (a step never allocates, so it never builds one)"
                )
            }
            AnalysisError::ImplicitNotConverged { iterations, correction } => write!(
                f,
                "implicit integrator: Newton did not converge in {iterations} iterations (last correction {correction:.3e})"
            ),
            AnalysisError::NoSecondOrder { needed_by } => {
                write!(f, "{needed_by} needs the scene's second-order terms; derive it with `#[scene(second_order)]`")
            }
            AnalysisError::StepTooSmall { t, step } => {
                write!(f, "error-controlled steps stopped at t = {t}: step {step:.3e} too small for the tolerance")
            }
            AnalysisError::SpuriousSolution { gain, scale } => write!(
                f,
                "the implicit step's solution gains {gain:.3e} J beyond the work done (against {scale:.3e} J in motion): \
                 a spurious solution, the step is too large"
            ),
            AnalysisError::NoConvergence { decomposition } => write!(f, "the {decomposition} did not converge"),
            // The factorisation's own message is `source()`'s (the API guidelines:
            // a wrapped error is either shown or returned, not both).
            AnalysisError::Linalg(_) => {
                f.write_str("a factorisation failed (a singular or non-finite iteration matrix)")
            }
        }
    }
}

impl core::error::Error for AnalysisError {
    fn source(&self) -> Option<&(dyn core::error::Error + 'static)> {
        match self {
            AnalysisError::Linalg(e) => Some(e),
            _ => None,
        }
    }
}

impl From<LinalgError> for AnalysisError {
    fn from(e: LinalgError) -> Self {
        AnalysisError::Linalg(e)
    }
}

/// Which linear problem an [`AnalysisError::Inconsistent`] comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
#[non_exhaustive]
pub enum Analysis {
    /// Velocity analysis, `J v = −Φ_t`.
    Velocity,
    /// Acceleration analysis, `J v̇ = γ`.
    Acceleration,
    /// Forward dynamics.
    Dynamics,
}

impl core::fmt::Display for Analysis {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Analysis::Velocity => "velocity",
            Analysis::Acceleration => "acceleration",
            Analysis::Dynamics => "dynamics",
        })
    }
}
