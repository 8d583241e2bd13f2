//! Damped Newton on Φ = 0: assembly and the projection step of the dynamics.

use super::{
    AnalysisError, AssemblyOptions, WorstRows, apply_increment, check_output, check_state, normalise_orientations,
};
use nalgebra::SVector;

use crate::absolute::buf::{at_rest, zero_state, zeros};
use crate::scene::{Scene, SystemState};

/// Damped Newton's vectors (Φ, the right-hand side `−Φ`, a trial's Φ, the
/// direction, a trial state) and a velocity: where a simulation keeps them
/// (boxed with its workspace), none is in a Newton step's frame.
#[derive(Clone, Debug)]
pub(crate) struct NewtonWork<const NB: usize, const NV: usize, const M: usize> {
    pub(crate) phi: SVector<f64, M>,
    pub(crate) b: SVector<f64, M>,
    pub(crate) p: SVector<f64, M>,
    pub(crate) delta: SVector<f64, NV>,
    pub(crate) v: SVector<f64, NV>,
    pub(crate) trial: SystemState<NB>,
}

impl<const NB: usize, const NV: usize, const M: usize> NewtonWork<NB, NV, M> {
    /// Zeros, and a state at rest.
    pub(crate) fn new() -> Self {
        let mut w = Self::zeros();
        at_rest(&mut w.trial);
        w
    }

    /// Zeros, the trial state's Euler parameters too: a constant, for a
    /// workspace made in the heap (`absolute::buf`), which then puts the
    /// trial state at rest.
    pub(crate) const fn zeros() -> Self {
        NewtonWork { phi: zeros(), b: zeros(), p: zeros(), delta: zeros(), v: zeros(), trial: zero_state() }
    }
}

/// What Newton asks of a linear solver: a step, and at the end only the
/// factorisation (no step nobody uses), whose redundant rows the solver keeps.
pub(crate) trait Directions<const NB: usize, const NV: usize, const M: usize> {
    /// `Δ` with `J Δ = b` at `state`, of minimum norm in the metric, into
    /// `delta` (`b` is the solver's to overwrite).
    fn step(
        &mut self,
        state: &SystemState<NB>,
        b: &mut SVector<f64, M>,
        delta: &mut SVector<f64, NV>,
    ) -> Result<(), AnalysisError>;
    /// Factorises at the converged `state` (its redundant rows, kept by the solver).
    fn factor_at(&mut self, state: &SystemState<NB>) -> Result<(), AnalysisError>;
}

/// Damped Newton on Φ = 0 (the dense and the sparse assembly and projection):
/// `direction(state, b)` solves `J Δ = b` (minimum norm) and lists the rows
/// its factorisation dropped; the step is `α Δ` with `α = 1, ½, ¼, …` until
/// ‖Φ‖ decreases (Armijo).
pub(crate) fn damped_newton<S, const NB: usize, const NV: usize, const M: usize>(
    scene: &S,
    state: &mut SystemState<NB>,
    options: &AssemblyOptions,
    directions: &mut impl Directions<NB, NV, M>,
    work: &mut NewtonWork<NB, NV, M>,
) -> Result<(usize, f64), AnalysisError>
where
    S: Scene<NB, NV, M>,
{
    check_state::<S, NB, NV, M>(state, false)?;
    if options.tolerance.is_nan() || options.tolerance < 0.0 {
        return Err(AnalysisError::BadOption { name: "tolerance" });
    }
    if !(options.min_step > 0.0 && options.min_step <= 1.0) {
        return Err(AnalysisError::BadOption { name: "min_step" });
    }
    normalise_orientations::<S, NB, NV, M>(state)?;
    work.phi = scene.phi(state);
    check_output::<S, NB, NV, M, 1>("Φ", &work.phi)?;
    let mut norm = work.phi.norm();
    let mut iterations = 0;
    loop {
        if norm <= options.tolerance {
            directions.factor_at(state)?;
            return Ok((iterations, norm));
        }
        if iterations >= options.max_iterations {
            return Err(AnalysisError::NotConverged {
                residual: norm,
                iterations,
                worst: WorstRows::of::<S, NB, NV, M>(&work.phi),
            });
        }
        for (b, p) in work.b.as_mut_slice().iter_mut().zip(work.phi.as_slice().iter()) {
            *b = -p;
        }
        directions.step(state, &mut work.b, &mut work.delta)?;
        let mut alpha = 1.0;
        loop {
            work.trial.clone_from(state);
            apply_increment(&mut work.trial, &work.delta, alpha);
            work.p = scene.phi(&work.trial);
            let n = work.p.norm();
            // Armijo on ‖Φ‖ (the Gauss-Newton direction decreases it at rate 1).
            if n.is_finite() && n <= (1.0 - 1e-4 * alpha) * norm {
                state.clone_from(&work.trial);
                work.phi.copy_from(&work.p);
                norm = n;
                break;
            }
            alpha *= 0.5;
            if alpha < options.min_step {
                return Err(AnalysisError::NoProgress {
                    residual: norm,
                    iterations,
                    worst: WorstRows::of::<S, NB, NV, M>(&work.phi),
                });
            }
        }
        iterations += 1;
    }
}
