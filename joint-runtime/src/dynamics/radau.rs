//! Radau IIA of order 5 on the Lie group ([`Integrator::RadauIIA`] and
//! [`Adaptive::RadauIIA`]): three implicit stages, stiffly accurate and
//! L-stable, so a stiff spring's mode is damped out at any `h ω` while the
//! slow motion is followed to fifth order (Hairer & Wanner, *Solving ODEs II*,
//! IV.5 and IV.8; the transformation and the error estimate are those of
//! their RADAU5).
//!
//! # The equations
//!
//! On the index-1 equations `q̇ = v` (on the group), `v̇ = a(q, v, t)`, the
//! stage unknowns are increments from the step's start `(q_n, v_n)`: per
//! stage `i` a position increment `U_i` (`q_i = q_n ⊕ U_i`: `r += U_r`,
//! `p ← p ⊗ q(U_θ)`, as every integrator here) and a velocity increment
//! `W_i` (`v_i = v_n + W_i`). On the group the position increments obey
//! `U̇ = J_r(U)⁻¹ v` per body (the rotation's right Jacobian, so that
//! `d/dt (p_n ⊗ q(U)) = p ⊗ (0, ω')/2`; Munthe-Kaas's method), which keeps the
//! order. The collocation equations are `Z = h (A ⊗ I) F(Z)` with
//! `Z_i = (U_i, W_i)`, `F(Z_i) = (J_r(U_i)⁻¹ v_i, a(q_i, v_i, t_n + c_i h))`.
//!
//! # Newton
//!
//! Simplified Newton with the Jacobian `[[0, I], [A_q, A_v]]` of the first-order
//! system at the step's start (`A_q = ∂a/∂q`, `A_v = ∂a/∂v` from the
//! generated second-order terms, `newton_matrix.rs`, or forward differences
//! for a scene without them). The transformation `T⁻¹ A⁻¹ T =
//! diag(γ̂, [[α, −β], [β, α]])` splits the `6 NV` equations into one real and
//! one complex system, and the structure of a second-order system reduces
//! each to `NV` unknowns:
//! `(μ − [[0, I], [A_q, A_v]]) (x, y) = (r, s)` is
//! `(μ² I − μ A_v − A_q) x = s + (μ − A_v) r`, `y = μ x − r`, for
//! `μ = γ̂/h` (real, [`Lu`]) and `μ = (α + iβ)/h` (complex `Lu`). Two `NV × NV`
//! factorisations a step, three evaluations of the dynamics a Newton
//! iteration. The step ends at the last stage (`c₃ = 1`); projection follows,
//! as for every integrator.
//!
//! # Error estimate
//!
//! RADAU5's: `e = (γ̂/h − J)⁻¹ (f(y_n) + Σ d_i Z_i / h)` (an embedded
//! third-order solution, `e = O(h⁴)`), and when `‖e‖ > 1` the estimate again
//! with `f(y_n + e)` in place of `f(y_n)`, which removes the stiff
//! components' overestimate. Its norm is the root mean square over the
//! position increments (translations scaled by the positions, rotations by
//! one radian) and the velocities, as generalised-α's.
//!
//! As in RADAU5 the tolerance is mapped to `rtol' = 0.1 rtol^(2/3)`,
//! `atol' = rtol' atol / rtol`: the estimate is the embedded third-order
//! solution's error, far above the fifth-order solution's at tight
//! tolerances, and the mapping makes the global error follow the tolerance
//! asked for.
//!
//! Newton starts from the last step's collocation polynomial extrapolated
//! (when the step starts where the last one was accepted), and stops when the
//! correction, or the remaining error its contraction `θ` predicts,
//! `θ/(1 − θ) ‖ΔZ‖`, is within the bound: at fixed steps
//! [`SimulationOptions::newton_tolerance`](super::SimulationOptions) relative
//! to `1 + ‖Z‖` (as the other implicit integrators); at error-controlled
//! steps `κ = max(10 ε / rtol', min(0.03, √rtol'))` in the error norm
//! (Hairer's choice): the iteration need not be more exact than the step. A
//! contraction `θ ≥ 1` fails the step (the error control retries smaller).
//! The Jacobian is evaluated again at each step unless the step retries from
//! the same state or the last iteration contracted by `θ ≤ 10⁻³` (RADAU5's
//! rule); the two factorisations are made at every step.
//!
//! # Limits
//!
//! The index-1 equations leave the stage positions free to leave `Φ = 0`
//! during the iteration. A stiff spring on a link that turns over the step
//! couples that drift, through the turned spring direction, to its stiff
//! mode, and no single Jacobian serves all three stages: on the stiff press
//! of `report/stiff.md` (10⁷ N/m rams on links turning at up to 20 rad/s)
//! Newton takes 7–16 iterations a step at h = 5 ms and does not converge at
//! 10 ms, where it converges in 4–6 with the springs removed. Neither a
//! Jacobian at a later stage nor a first-order drift stabilisation of the
//! positions changed that. An index-3 variant (stage positions held on
//! `Φ = 0`, the multipliers as stage unknowns, a real and a complex
//! saddle-point system by Schur complements) converged there at 20 ms steps,
//! but its third-order velocities, through the rams' dampers, cut the
//! positions' order to 1.9 (5.7e-9 m at 50 steps, 1.3e-10 at 400) and made
//! its error control erratic, so it was not kept; the index-2 (GGL) form
//! would keep fifth-order velocities. The error control shrinks such steps
//! until Newton converges.

use nalgebra::{Complex, SMatrix, SVector, Vector3};

use super::adaptive::{Timed, Tolerance, increment_error};
use super::{displaced_into, newton_done};
use crate::absolute::buf::{Boxed, at_rest, boxed_with, zero_state, zeros};
use crate::analysis::{AnalysisError, velocity_vector_into};
use crate::linalg::Lu;
use crate::scene::SystemState;

#[cfg(doc)]
use super::{Adaptive, Integrator};

/// The stages' times `c_i = (4 ∓ √6)/10, 1`.
const C: [f64; 3] = [0.1550510257216822, 0.6449489742783178, 1.0];
/// Radau IIA(5)'s matrix `A` (for the tests; the step uses its transformation).
#[cfg(test)]
const A: [[f64; 3]; 3] = [
    [0.19681547722366044, -0.06553542585019839, 0.02377097434822015],
    [0.3944243147390873, 0.29207341166522843, -0.04154875212599793],
    [0.37640306270046725, 0.5124858261884216, 0.1111111111111111],
];
/// `T`: `T⁻¹ A⁻¹ T = diag(γ̂, [[α, −β], [β, α]])` (RADAU5's; 40-digit
/// eigenvectors of `A⁻¹`, checked by a test).
const T: [[f64; 3]; 3] = [
    [0.09123239487089294, -0.1412552950209542, -0.030029194105147424],
    [0.241717932707107, 0.20412935229379994, 0.3829421127572619],
    [0.966048182615093, 1.0, 0.0],
];
/// `T⁻¹`.
const TI: [[f64; 3]; 3] = [
    [4.325579890063155, 0.3391992518158099, 0.5417705399358749],
    [-4.178718591551905, -0.3276828207610624, 0.47662355450055044],
    [-0.5028726349457869, 2.571926949855605, -0.5960392048282249],
];
/// The real eigenvalue of `A⁻¹`.
pub(crate) const GAMMA: f64 = 3.637834252744496;
/// The complex pair `α ± iβ` of `A⁻¹`.
pub(crate) const ALPHA: f64 = 2.681082873627752;
pub(crate) const BETA: f64 = 3.0504301992474105;
/// The error estimate's weights `d_i = −(13 + 7√6)/3, (−13 + 7√6)/3, −1/3`.
const D: [f64; 3] = [-10.048809399827416, 1.382142733160749, -1.0 / 3.0];

pub(crate) type Stages<const NV: usize> = [SVector<f64, NV>; 3];

/// What one Radau step did.
pub(crate) struct RadauStep {
    pub(crate) iterations: usize,
    pub(crate) matrices: usize,
    pub(crate) evaluations: usize,
    /// The error norm (0 at fixed steps).
    pub(crate) error: f64,
}

/// The last step's stages, from which the next step's Newton iteration starts
/// (the collocation polynomial extrapolated, as RADAU5), if the next step
/// starts where this one was accepted; and the Jacobian it used (`J`: the
/// dense path's matrices, or nothing where the host keeps them).
#[derive(Clone, Copy, Debug)]
pub(crate) struct RadauHistory<Y, const NV: usize, J> {
    /// The accepted (projected) end of the step, once `accepted`.
    end: Y,
    accepted: bool,
    h: f64,
    zu: Stages<NV>,
    zv: Stages<NV>,
    /// The state the Jacobian was evaluated at, and the largest contraction
    /// of the last Newton iteration that used it (infinite after a failure).
    at: Y,
    theta: f64,
    jacobian: J,
}

/// The group a Radau step moves on: its state, `y0 ⊕ u` with velocities `v`,
/// the rates `U̇` of the position increments, and the error norm of a step's
/// increments. The bodies' states ([`Bodies`]) and a tree's joint
/// coordinates (`relative/radau.rs`) are two such groups.
pub(crate) trait RadauGroup<const NV: usize> {
    /// The state a step advances.
    type State: Timed + PartialEq;
    /// `y0 ⊕ u` (the positions), with velocities `v`, at `t`, into `out`.
    fn displaced_into(
        &self,
        y0: &Self::State,
        u: &SVector<f64, NV>,
        v: &SVector<f64, NV>,
        t: f64,
        out: &mut Self::State,
    );
    /// The state's velocities, into `out`.
    fn velocity_into(&self, y: &Self::State, out: &mut SVector<f64, NV>);
    /// `U̇` at the increment `u` with velocities `v`, into `out`.
    fn position_rates_into(&self, u: &SVector<f64, NV>, v: &SVector<f64, NV>, out: &mut SVector<f64, NV>);
    /// The error norm of the position increments `e` and velocity
    /// increments `ev` of a step from `y0` to `y1`.
    fn increment_error(
        &self,
        y0: &Self::State,
        y1: &Self::State,
        e: &SVector<f64, NV>,
        ev: &SVector<f64, NV>,
        tolerance: Tolerance,
    ) -> f64;
}

/// The bodies' states as a [`RadauGroup`]: each body's increment is its
/// translation and its rotation vector in its own frame.
pub(crate) struct Bodies<const NB: usize>;

impl<const NB: usize, const NV: usize> RadauGroup<NV> for Bodies<NB> {
    type State = SystemState<NB>;

    fn displaced_into(
        &self,
        y0: &SystemState<NB>,
        u: &SVector<f64, NV>,
        v: &SVector<f64, NV>,
        t: f64,
        out: &mut SystemState<NB>,
    ) {
        displaced_into(y0, u, 1.0, v, t, out);
    }

    fn velocity_into(&self, y: &SystemState<NB>, out: &mut SVector<f64, NV>) {
        velocity_vector_into(y, out);
    }

    fn position_rates_into(&self, u: &SVector<f64, NV>, v: &SVector<f64, NV>, out: &mut SVector<f64, NV>) {
        body_position_rates_into(u, v, out);
    }

    fn increment_error(
        &self,
        y0: &SystemState<NB>,
        y1: &SystemState<NB>,
        e: &SVector<f64, NV>,
        ev: &SVector<f64, NV>,
        tolerance: Tolerance,
    ) -> f64 {
        increment_error(y0, y1, e, ev, tolerance)
    }
}

/// The state a host's steps advance.
pub(crate) type StateOf<H, const NV: usize> = <<H as RadauHost<NV>>::Group as RadauGroup<NV>>::State;

/// What the Radau step needs of a simulation (the absolute one, a tree's,
/// and the tests' dense reference): its group, the accelerations under the
/// step's rule for redundant rows, the Jacobian of the index-1 equations,
/// and the real and complex stage systems `(μ − [[0, I], [A_q, A_v]]) (x, y)
/// = (r, s)` factorised and solved.
pub(crate) trait RadauHost<const NV: usize> {
    /// The group the steps move on.
    type Group: RadauGroup<NV>;
    /// The Jacobian's matrices, where the host keeps them in the history.
    type Jacobian: Copy;
    /// The two factorised systems of one step.
    type Factors;
    /// The host's error.
    type Error;
    /// The driver's own failures (Newton not converging) in the host's terms.
    fn error(e: AnalysisError) -> Self::Error;
    /// The group.
    fn group(&self) -> &Self::Group;
    /// Newton's iteration cap and tolerance at fixed steps.
    fn newton_limits(&self) -> (usize, f64);
    /// Whether error-controlled steps stop Newton at RADAU5's `κ` in the
    /// error norm (else at the fixed steps' tolerance).
    fn scaled_stop(&self) -> bool {
        true
    }
    /// The history, kept between steps.
    fn history(&mut self) -> &mut Option<RadauHistory<StateOf<Self, NV>, NV, Self::Jacobian>>;
    /// The accelerations at the step's start `y0` (whose rule the stages
    /// keep), into `out`.
    fn start(&mut self, y0: &StateOf<Self, NV>, out: &mut SVector<f64, NV>) -> Result<(), Self::Error>;
    /// The accelerations at a stage, under the rule of the start, into `out`.
    fn accelerations(&mut self, state: &StateOf<Self, NV>, out: &mut SVector<f64, NV>) -> Result<(), Self::Error>;
    /// The Jacobian at the start `y0`, and the dynamics evaluations spent.
    fn jacobian(&mut self, y0: &StateOf<Self, NV>) -> Result<(Self::Jacobian, usize), Self::Error>;
    /// Factorises the two systems of a step `h` on `jacobian`.
    fn factor(&mut self, jacobian: &Self::Jacobian, h: f64) -> Result<Self::Factors, Self::Error>;
    /// `(γ̂/h − [[0, I], [A_q, A_v]])⁻¹ (r, s)` for `rs = (r, s)`, into
    /// `xy = (x, y)`.
    fn solve_real(
        &mut self,
        factors: &Self::Factors,
        rs: (&SVector<f64, NV>, &SVector<f64, NV>),
        xy: (&mut SVector<f64, NV>, &mut SVector<f64, NV>),
    );
    /// The same at `μ = (α + iβ)/h` for `(r₂ + i r₃, s₂ + i s₃)`: the real and
    /// imaginary parts of `x` into `x`, of `y` into `y`.
    #[allow(clippy::type_complexity)]
    fn solve_complex(
        &mut self,
        factors: &Self::Factors,
        r: (&SVector<f64, NV>, &SVector<f64, NV>),
        s: (&SVector<f64, NV>, &SVector<f64, NV>),
        x: (&mut SVector<f64, NV>, &mut SVector<f64, NV>),
        y: (&mut SVector<f64, NV>, &mut SVector<f64, NV>),
    );
}

/// A Radau step's states and vectors: the start, the end and a stage's
/// state, the start's rates, the stages `Z` and their transforms `W`, the
/// rates `F` (then the residuals), the corrections in both bases, and the
/// estimate's vectors. The sparse simulation keeps it boxed, so a step's
/// frames hold none of the scene's size.
#[derive(Clone, Debug)]
pub(crate) struct RadauWork<Y, const NV: usize> {
    y0: Y,
    y1: Y,
    stage: Y,
    v0: SVector<f64, NV>,
    a0: SVector<f64, NV>,
    v: SVector<f64, NV>,
    a: SVector<f64, NV>,
    zu: Stages<NV>,
    zv: Stages<NV>,
    wu: Stages<NV>,
    wv: Stages<NV>,
    fu: Stages<NV>,
    fv: Stages<NV>,
    du: Stages<NV>,
    dv: Stages<NV>,
    dzu: Stages<NV>,
    dzv: Stages<NV>,
    pu: SVector<f64, NV>,
    pv: SVector<f64, NV>,
    eu: SVector<f64, NV>,
    ev: SVector<f64, NV>,
    r: SVector<f64, NV>,
    s: SVector<f64, NV>,
}

impl<Y: Copy, const NV: usize> RadauWork<Y, NV> {
    /// The step's start, where [`step_radau_in`] reads it.
    pub(crate) fn start_mut(&mut self) -> &mut Y {
        &mut self.y0
    }

    /// The step's end, where [`step_radau_in`] leaves it.
    pub(crate) fn end_mut(&mut self) -> &mut Y {
        &mut self.y1
    }

    /// Zeros, every state `y`.
    pub(crate) const fn at(y: Y) -> Self {
        let z = [zeros(); 3];
        RadauWork {
            y0: y,
            y1: y,
            stage: y,
            v0: zeros(),
            a0: zeros(),
            v: zeros(),
            a: zeros(),
            zu: z,
            zv: z,
            wu: z,
            wv: z,
            fu: z,
            fv: z,
            du: z,
            dv: z,
            dzu: z,
            dzv: z,
            pu: zeros(),
            pv: zeros(),
            eu: zeros(),
            ev: zeros(),
            r: zeros(),
            s: zeros(),
        }
    }
}

impl<const NB: usize, const NV: usize> RadauWork<SystemState<NB>, NV> {
    /// Zeros at states at rest (the dense path's, on its stack).
    #[cfg(feature = "__dense_reference")]
    pub(crate) fn new() -> Self {
        let mut w = const { Self::zeros() };
        w.states_at_rest();
        w
    }

    /// Zeros at states at rest, boxed (with `alloc`) and written in the
    /// heap (`absolute::buf`).
    pub(crate) fn boxed() -> Boxed<Self> {
        let mut w = boxed_with(|| const { Self::zeros() });
        w.states_at_rest();
        w
    }

    /// Zeros, the states' Euler parameters too: a constant.
    const fn zeros() -> Self {
        Self::at(zero_state())
    }

    fn states_at_rest(&mut self) {
        for state in [&mut self.y0, &mut self.y1, &mut self.stage] {
            at_rest(state);
        }
    }
}

/// RADAU5's bound on the contraction below which the next step keeps the
/// Jacobian: the iteration barely notices the change of state.
const KEEP_JACOBIAN: f64 = 1e-3;

/// When the simplified Newton iteration stops (see the module documentation).
#[derive(Clone, Copy)]
enum Stop {
    /// Fixed steps: the correction relative to `1 + ‖Z‖`.
    Relative(f64),
    /// Error-controlled steps: `κ` in the error norm at the step's start.
    Scaled { kappa: f64, tolerance: Tolerance },
}

/// One Radau IIA step from the normalised `state`; with a `tolerance`,
/// Newton stops as the error control needs and the step's error norm is
/// estimated. The stages are kept in the host's history (not yet accepted).
/// Every vector lives in `w`, written in place (the same operations as
/// sums of whole vectors, entry by entry).
pub(crate) fn step_radau<H: RadauHost<NV>, const NV: usize>(
    host: &mut H,
    w: &mut RadauWork<StateOf<H, NV>, NV>,
    state: &mut StateOf<H, NV>,
    h: f64,
    tolerance: Option<Tolerance>,
) -> Result<RadauStep, H::Error> {
    w.y0.clone_from(state);
    let step = step_radau_in(host, w, h, tolerance)?;
    state.clone_from(&w.y1);
    Ok(step)
}

/// [`step_radau`] from the start in the work ([`RadauWork::start_mut`]), its
/// end left there ([`RadauWork::end_mut`]).
pub(crate) fn step_radau_in<H: RadauHost<NV>, const NV: usize>(
    host: &mut H,
    w: &mut RadauWork<StateOf<H, NV>, NV>,
    h: f64,
    tolerance: Option<Tolerance>,
) -> Result<RadauStep, H::Error> {
    host.group().velocity_into(&w.y0, &mut w.v0);
    host.start(&w.y0, &mut w.a0)?;
    starting_values(host.history().as_ref(), w, h);
    let mut step = RadauStep { iterations: 0, matrices: 1, evaluations: 1, error: 0.0 };
    // A retry from the same state, or a last iteration that converged fast.
    let keep = matches!(host.history(), Some(past) if past.at == w.y0 || past.theta <= KEEP_JACOBIAN);
    let fresh = if keep {
        None
    } else {
        // No usable history while the host's matrices change.
        if let Some(past) = host.history() {
            past.forget();
        }
        let (jacobian, evaluations) = host.jacobian(&w.y0)?;
        step.evaluations += evaluations;
        Some(jacobian)
    };
    // Kept before Newton runs: a step that fails retries on it from the
    // same state, and no other step keeps it (θ infinite until Newton
    // converges).
    let Some(jacobian) = pending(host.history(), w, h, fresh) else {
        return Err(H::error(AnalysisError::BadOption { name: "Radau history" }));
    };
    let factors = host.factor(&jacobian, h)?;
    // RADAU5's mapping: the estimate is of the embedded third-order
    // solution, far above the fifth-order one's error at tight tolerances.
    let tolerance = tolerance.map(|t| {
        let rtol = 0.1 * libm::pow(t.rtol, 2.0 / 3.0);
        Tolerance { rtol, atol: rtol * t.atol / t.rtol }
    });
    let (max_iterations, newton_tolerance) = host.newton_limits();
    let stop = match tolerance {
        Some(t) if host.scaled_stop() => {
            let kappa = (10.0 * f64::EPSILON / t.rtol).max(libm::sqrt(t.rtol).min(0.03));
            Stop::Scaled { kappa, tolerance: t }
        }
        _ => Stop::Relative(newton_tolerance),
    };
    let newton = Newton { h, stop, max_iterations };
    let theta = radau_newton(host, w, &newton, &factors, &mut step)?;
    if let Some(past) = host.history() {
        for k in 0..3 {
            past.zu[k].copy_from(&w.zu[k]);
            past.zv[k].copy_from(&w.zv[k]);
        }
        past.theta = theta;
    }
    add_into(&w.v0, &w.zv[2], &mut w.v);
    host.group().displaced_into(&w.y0, &w.zu[2], &w.v, w.y0.time() + h, &mut w.y1);
    if let Some(tol) = tolerance {
        step.error = radau_estimate(host, w, h, &factors, tol, &mut step)?;
    }
    Ok(step)
}

impl<Y: Timed, const NV: usize, J> RadauHistory<Y, NV, J> {
    /// The step was accepted at `state` (projected): the next step starts
    /// from its stages if it starts there.
    pub(crate) fn accept(&mut self, state: &Y) {
        self.end.clone_from(state);
        self.accepted = true;
    }

    /// Made unusable (as no history): no later step keeps its Jacobian or
    /// starts from its stages until a step writes it again.
    fn forget(&mut self) {
        self.accepted = false;
        self.at.set_time(f64::NAN);
        self.theta = f64::INFINITY;
    }
}

/// The pending history of a step from `w.y0` of size `h` (its starting
/// stages, θ infinite, not accepted), written over `history` in place: with
/// the `fresh` Jacobian evaluated at `w.y0`, or keeping the one it has.
/// Returns the Jacobian (`None`: no history and none fresh, which the caller
/// never asks).
fn pending<J: Copy, Y: Timed, const NV: usize>(
    history: &mut Option<RadauHistory<Y, NV, J>>,
    w: &RadauWork<Y, NV>,
    h: f64,
    fresh: Option<J>,
) -> Option<J> {
    match history {
        Some(past) => {
            if let Some(jacobian) = fresh {
                past.at.clone_from(&w.y0);
                past.jacobian = jacobian;
            }
            past.accepted = false;
            past.h = h;
            for k in 0..3 {
                past.zu[k].copy_from(&w.zu[k]);
                past.zv[k].copy_from(&w.zv[k]);
            }
            past.theta = f64::INFINITY;
            Some(past.jacobian)
        }
        None => {
            let jacobian = fresh?;
            first_history(history, w, h, jacobian);
            Some(jacobian)
        }
    }
}

/// A simulation's first Radau history, once, in a frame of its own.
#[cold]
#[inline(never)]
fn first_history<J, Y: Timed, const NV: usize>(
    history: &mut Option<RadauHistory<Y, NV, J>>,
    w: &RadauWork<Y, NV>,
    h: f64,
    jacobian: J,
) {
    let (end, accepted, theta) = (w.y0, false, f64::INFINITY);
    *history = Some(RadauHistory { end, accepted, h, zu: w.zu, zv: w.zv, at: w.y0, theta, jacobian });
}

/// The stages Newton starts from, into `w.zu`, `w.zv`: the last accepted
/// step's collocation polynomial extrapolated to this step if it ended at
/// `w.y0`, else positions moving at the start's velocities.
fn starting_values<J, Y: PartialEq, const NV: usize>(
    history: Option<&RadauHistory<Y, NV, J>>,
    w: &mut RadauWork<Y, NV>,
    h: f64,
) {
    match history {
        Some(past) if past.accepted && past.end == w.y0 => {
            let grow = h / past.h;
            for ((c, zu), zv) in C.iter().zip(w.zu.iter_mut()).zip(w.zv.iter_mut()) {
                let l = collocation_weights(1.0 + c * grow);
                let weights = [l[0], l[1], l[2] - 1.0];
                combine_into(&weights, &past.zu, zu);
                combine_into(&weights, &past.zv, zv);
            }
        }
        _ => {
            for (i, c) in C.iter().enumerate() {
                for (z, v) in w.zu[i].as_mut_slice().iter_mut().zip(w.v0.as_slice().iter()) {
                    *z = v * (c * h);
                }
                w.zv[i].fill(0.0);
            }
        }
    }
}

/// What one step's Newton iteration is about.
struct Newton {
    h: f64,
    stop: Stop,
    max_iterations: usize,
}

/// Simplified Newton on the transformed stage equations from the stages in
/// `w`; leaves the converged stages there and returns the largest
/// contraction seen.
fn radau_newton<H: RadauHost<NV>, const NV: usize>(
    host: &mut H,
    w: &mut RadauWork<StateOf<H, NV>, NV>,
    newton: &Newton,
    factors: &H::Factors,
    step: &mut RadauStep,
) -> Result<f64, H::Error> {
    let Newton { h, stop, max_iterations } = *newton;
    mix_into(&TI, &w.zu, &mut w.wu);
    mix_into(&TI, &w.zv, &mut w.wv);
    let (mut last, mut contraction) = (f64::INFINITY, 0.0f64);
    loop {
        if step.iterations >= max_iterations {
            return Err(H::error(AnalysisError::ImplicitNotConverged {
                iterations: step.iterations,
                correction: last,
            }));
        }
        // F at the stages, transformed: G = (T⁻¹ ⊗ I) F(Z), into `dz` (free here).
        for (i, c) in C.iter().enumerate() {
            let RadauWork { y0, stage, v0, v, zu, zv, fu, fv, .. } = &mut *w;
            let (Some(zu), Some(zv), Some(fu), Some(fv)) = (zu.get(i), zv.get(i), fu.get_mut(i), fv.get_mut(i)) else {
                continue;
            };
            add_into(v0, zv, v);
            host.group().displaced_into(y0, zu, v, y0.time() + c * h, stage);
            host.accelerations(stage, fv)?;
            host.group().position_rates_into(zu, v, fu);
        }
        step.evaluations += 3;
        mix_into(&TI, &w.fu, &mut w.dzu);
        mix_into(&TI, &w.fv, &mut w.dzv);
        // Residuals G − h⁻¹ Λ W, solved block by block.
        residual_in_place(&mut w.dzu, &w.wu, h);
        residual_in_place(&mut w.dzv, &w.wv, h);
        {
            let RadauWork { dzu: ru, dzv: rv, du, dv, .. } = &mut *w;
            let ([du0, du1, du2], [dv0, dv1, dv2]) = (du, dv);
            host.solve_real(factors, (&ru[0], &rv[0]), (du0, dv0));
            host.solve_complex(factors, (&ru[1], &ru[2]), (&rv[1], &rv[2]), (du1, du2), (dv1, dv2));
        }
        for k in 0..3 {
            w.wu[k] += &w.du[k];
            w.wv[k] += &w.dv[k];
        }
        mix_into(&T, &w.wu, &mut w.zu);
        mix_into(&T, &w.wv, &mut w.zv);
        step.iterations += 1;
        mix_into(&T, &w.du, &mut w.dzu);
        mix_into(&T, &w.dv, &mut w.dzv);
        let (size, bound) = match stop {
            Stop::Relative(tolerance) => (euclidean(&w.dzu, &w.dzv), tolerance * (1.0 + euclidean(&w.zu, &w.zv))),
            Stop::Scaled { kappa, tolerance } => (stage_norm(host.group(), &w.y0, &w.dzu, &w.dzv, tolerance), kappa),
        };
        let theta = size / last;
        if step.iterations >= 2 {
            contraction = contraction.max(theta);
        }
        // Converged when the correction, or the remaining error its
        // contraction predicts (θ/(1 − θ) of it), is within the bound; at
        // fixed steps also at the round-off floor, where θ may exceed 1.
        let floor = match stop {
            Stop::Relative(tolerance) => newton_done(size, last, bound / tolerance, tolerance),
            Stop::Scaled { .. } => size <= 1e-2 * bound,
        };
        if floor || (step.iterations >= 2 && theta < 1.0 && theta / (1.0 - theta) * size <= bound) {
            return Ok(contraction);
        }
        if !size.is_finite() || (step.iterations >= 2 && theta >= 1.0) {
            return Err(H::error(AnalysisError::ImplicitNotConverged {
                iterations: step.iterations,
                correction: size,
            }));
        }
        last = size;
    }
}

/// `G − h⁻¹ Λ W` over `g` in place: `Λ = diag(γ̂, [[α, −β], [β, α]])`.
fn residual_in_place<const NV: usize>(g: &mut Stages<NV>, w: &Stages<NV>, h: f64) {
    let [g0, g1, g2] = g;
    for (g, w) in g0.as_mut_slice().iter_mut().zip(w[0].as_slice().iter()) {
        *g -= w * (GAMMA / h);
    }
    for ((g1, g2), (w1, w2)) in g1
        .as_mut_slice()
        .iter_mut()
        .zip(g2.as_mut_slice().iter_mut())
        .zip(w[1].as_slice().iter().zip(w[2].as_slice().iter()))
    {
        *g1 -= (w1 * ALPHA - w2 * BETA) / h;
        *g2 -= (w1 * BETA + w2 * ALPHA) / h;
    }
}

/// RADAU5's error norm of the step from `w.y0` (its rates `w.v0`, `w.a0`)
/// to `w.y1` with the stage increments `w.zu`, `w.zv` (see the module
/// documentation).
fn radau_estimate<H: RadauHost<NV>, const NV: usize>(
    host: &mut H,
    w: &mut RadauWork<StateOf<H, NV>, NV>,
    h: f64,
    factors: &H::Factors,
    tolerance: Tolerance,
    step: &mut RadauStep,
) -> Result<f64, H::Error> {
    let weigh = |z: &Stages<NV>, out: &mut SVector<f64, NV>| {
        for (o, ((a, b), c)) in out
            .as_mut_slice()
            .iter_mut()
            .zip(z[0].as_slice().iter().zip(z[1].as_slice().iter()).zip(z[2].as_slice().iter()))
        {
            *o = (a * D[0] + b * D[1] + c * D[2]) / h;
        }
    };
    weigh(&w.zu, &mut w.pu);
    weigh(&w.zv, &mut w.pv);
    add_into(&w.v0, &w.pu, &mut w.r);
    add_into(&w.a0, &w.pv, &mut w.s);
    host.solve_real(factors, (&w.r, &w.s), (&mut w.eu, &mut w.ev));
    let err = host.group().increment_error(&w.y0, &w.y1, &w.eu, &w.ev, tolerance);
    if err <= 1.0 {
        return Ok(err);
    }
    // The stiff components' overestimate removed: f at y_n + e.
    add_into(&w.v0, &w.ev, &mut w.v);
    host.group().displaced_into(&w.y0, &w.eu, &w.v, w.y0.time(), &mut w.stage);
    host.accelerations(&w.stage, &mut w.a)?;
    step.evaluations += 1;
    host.group().position_rates_into(&w.eu, &w.v, &mut w.r);
    w.r += &w.pu;
    add_into(&w.a, &w.pv, &mut w.s);
    host.solve_real(factors, (&w.r, &w.s), (&mut w.eu, &mut w.ev));
    Ok(host.group().increment_error(&w.y0, &w.y1, &w.eu, &w.ev, tolerance))
}

/// `out = a + b`, entry by entry.
fn add_into<const NV: usize>(a: &SVector<f64, NV>, b: &SVector<f64, NV>, out: &mut SVector<f64, NV>) {
    for (o, (a, b)) in out.as_mut_slice().iter_mut().zip(a.as_slice().iter().zip(b.as_slice().iter())) {
        *o = a + b;
    }
}

/// The weights of the stages in the collocation polynomial at `s` (in
/// units of the step, 0 at its start where the polynomial is 0):
/// `u(s) = Σ_k ℓ_k(s) Z_k` over the nodes `0, c₁, c₂, 1`.
fn collocation_weights(s: f64) -> [f64; 3] {
    let [c1, c2, c3] = C;
    [
        s * (s - c2) * (s - c3) / (c1 * (c1 - c2) * (c1 - c3)),
        s * (s - c1) * (s - c3) / (c2 * (c2 - c1) * (c2 - c3)),
        s * (s - c1) * (s - c2) / (c3 * (c3 - c1) * (c3 - c2)),
    ]
}

/// `out_i = Σ_j m_ij x_j` for each `i`.
fn mix_into<const NV: usize>(m: &[[f64; 3]; 3], x: &Stages<NV>, out: &mut Stages<NV>) {
    for (row, o) in m.iter().zip(out.as_mut_slice().iter_mut()) {
        combine_into(row, x, o);
    }
}

/// `out = Σ_j c_j x_j`, entry by entry (`x₀ c₀ + x₁ c₁ + x₂ c₂`).
fn combine_into<const NV: usize>(c: &[f64; 3], x: &Stages<NV>, out: &mut SVector<f64, NV>) {
    for (o, ((a, b), d)) in out
        .as_mut_slice()
        .iter_mut()
        .zip(x[0].as_slice().iter().zip(x[1].as_slice().iter()).zip(x[2].as_slice().iter()))
    {
        *o = a * c[0] + b * c[1] + d * c[2];
    }
}

/// A body's `U̇` at the increment `u` with velocities `v`, into `out`: `ṙ`
/// for the translations, `J_r(u_θ)⁻¹ ω'` for the rotations.
fn body_position_rates_into<const NV: usize>(u: &SVector<f64, NV>, v: &SVector<f64, NV>, out: &mut SVector<f64, NV>) {
    out.copy_from(v);
    for b in 0..NV / 6 {
        let at = |x: &SVector<f64, NV>, k: usize| x.get(6 * b + 3 + k).copied().unwrap_or(0.0);
        let phi = Vector3::new(at(u, 0), at(u, 1), at(u, 2));
        let omega = Vector3::new(at(v, 0), at(v, 1), at(v, 2));
        let rate = inverse_right_jacobian_times(&phi, &omega);
        for k in 0..3 {
            if let Some(o) = out.get_mut(6 * b + 3 + k) {
                *o = rate[k];
            }
        }
    }
}

/// `J_r(φ)⁻¹ ω = ω + ½ φ × ω + c(θ) φ × (φ × ω)`, `c = (1 − (θ/2) cot(θ/2))/θ²`,
/// by its series below `θ = 0.1` (where the closed form cancels).
pub(crate) fn inverse_right_jacobian_times(phi: &Vector3<f64>, omega: &Vector3<f64>) -> Vector3<f64> {
    let t2 = phi.norm_squared();
    let c = if t2 < 1e-2 {
        1.0 / 12.0 + t2 * (1.0 / 720.0 + t2 * (1.0 / 30_240.0 + t2 / 1_209_600.0))
    } else {
        let t = libm::sqrt(t2);
        (1.0 - 0.5 * t * libm::cos(0.5 * t) / libm::sin(0.5 * t)) / t2
    };
    let pw = phi.cross(omega);
    omega + pw * 0.5 + phi.cross(&pw) * c
}

/// The error norm of the three stages' increments, from `y0`.
fn stage_norm<G: RadauGroup<NV>, const NV: usize>(
    group: &G,
    y0: &G::State,
    u: &Stages<NV>,
    v: &Stages<NV>,
    tolerance: Tolerance,
) -> f64 {
    let sum: f64 = (0..3).map(|i| libm::pow(group.increment_error(y0, y0, &u[i], &v[i], tolerance), 2.0)).sum();
    libm::sqrt(sum / 3.0)
}

/// `‖(u, v)‖₂` over the three stages.
fn euclidean<const NV: usize>(u: &Stages<NV>, v: &Stages<NV>) -> f64 {
    libm::sqrt(u.iter().chain(v.iter()).map(|x| x.norm_squared()).sum::<f64>())
}

/// The two factorised systems of a step `h` on dense `A_q`, `A_v` (the
/// tree's, and the dense reference's): `K(μ) = μ² I − μ A_v − A_q` at
/// `μ = γ̂/h` and at `μ = (α + iβ)/h`.
pub(crate) struct DenseFactors<const NV: usize> {
    h: f64,
    real: Lu<NV>,
    complex: Lu<NV, Complex<f64>>,
    av: SMatrix<f64, NV, NV>,
}

impl<const NV: usize> DenseFactors<NV> {
    pub(crate) fn new(aq: &SMatrix<f64, NV, NV>, av: &SMatrix<f64, NV, NV>, h: f64) -> Result<Self, AnalysisError> {
        let mu = GAMMA / h;
        let real = Lu::new(&(SMatrix::<f64, NV, NV>::identity() * (mu * mu) - av * mu - aq))?;
        let mu = Complex::new(ALPHA, BETA) / h;
        let complex =
            SMatrix::<Complex<f64>, NV, NV>::identity() * (mu * mu) - av.map(real_part) * mu - aq.map(real_part);
        Ok(DenseFactors { h, real, complex: Lu::new(&complex)?, av: *av })
    }

    /// [`solve_real`](Self::solve_real) into `(x, y)`: a host's
    /// [`RadauHost::solve_real`].
    pub(crate) fn solve_real_into(
        &self,
        (r, s): (&SVector<f64, NV>, &SVector<f64, NV>),
        (x, y): (&mut SVector<f64, NV>, &mut SVector<f64, NV>),
    ) {
        (*x, *y) = self.solve_real(r, s);
    }

    /// [`solve_complex`](Self::solve_complex) into the real and imaginary
    /// parts of `x` and `y`: a host's [`RadauHost::solve_complex`].
    #[allow(clippy::type_complexity)]
    pub(crate) fn solve_complex_into(
        &self,
        r: (&SVector<f64, NV>, &SVector<f64, NV>),
        s: (&SVector<f64, NV>, &SVector<f64, NV>),
        x: (&mut SVector<f64, NV>, &mut SVector<f64, NV>),
        y: (&mut SVector<f64, NV>, &mut SVector<f64, NV>),
    ) {
        let ((xr, xi), (yr, yi)) = self.solve_complex(r, s);
        (*x.0, *x.1, *y.0, *y.1) = (xr, xi, yr, yi);
    }

    /// `(μ − [[0, I], [A_q, A_v]])⁻¹ (r, s)` at the real `μ = γ̂/h`.
    fn solve_real(&self, r: &SVector<f64, NV>, s: &SVector<f64, NV>) -> (SVector<f64, NV>, SVector<f64, NV>) {
        let mu = GAMMA / self.h;
        let x = self.real.solve(&(s + r * mu - self.av * r));
        (x, x * mu - r)
    }

    /// The same at `μ = (α + iβ)/h` for `(r₂ + i r₃, s₂ + i s₃)`: the real and
    /// imaginary parts of `x`, then of `y`.
    #[allow(clippy::type_complexity)]
    fn solve_complex(
        &self,
        (r2, r3): (&SVector<f64, NV>, &SVector<f64, NV>),
        (s2, s3): (&SVector<f64, NV>, &SVector<f64, NV>),
    ) -> ((SVector<f64, NV>, SVector<f64, NV>), (SVector<f64, NV>, SVector<f64, NV>)) {
        let mu = Complex::new(ALPHA, BETA) / self.h;
        let r = r2.zip_map(r3, Complex::new);
        let ar = (self.av * r2).zip_map(&(self.av * r3), Complex::new);
        let x = self.complex.solve(&(s2.zip_map(s3, Complex::new) + r * mu - ar));
        let y = x * mu - r;
        ((x.map(|z| z.re), x.map(|z| z.im)), (y.map(|z| z.re), y.map(|z| z.im)))
    }
}
/// `x + 0i`.
fn real_part(x: f64) -> Complex<f64> {
    Complex::new(x, 0.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Matrix3;

    fn matrix(m: &[[f64; 3]; 3]) -> Matrix3<f64> {
        Matrix3::from_fn(|i, j| m[i][j])
    }

    #[test]
    fn transformation_diagonalises_the_inverse_of_a() {
        let lambda = matrix(&TI) * matrix(&A).try_inverse().unwrap() * matrix(&T);
        let want = Matrix3::new(GAMMA, 0.0, 0.0, 0.0, ALPHA, -BETA, 0.0, BETA, ALPHA);
        assert!((lambda - want).abs().max() < 1e-13, "{lambda}");
        assert!((matrix(&T) * matrix(&TI) - Matrix3::identity()).abs().max() < 1e-15);
    }

    #[test]
    fn coefficients_are_radau_iia() {
        let s6 = 6f64.sqrt();
        assert!((C[0] - (4.0 - s6) / 10.0).abs() < 1e-16);
        assert!((C[1] - (4.0 + s6) / 10.0).abs() < 1e-16);
        // Row sums are c; the last row is b (stiffly accurate), whose moments are 1/k.
        for (row, c) in A.iter().zip(C) {
            assert!((row.iter().sum::<f64>() - c).abs() < 1e-16);
        }
        for k in 1..=5 {
            let moment: f64 = A[2].iter().zip(C).map(|(b, c)| b * c.powi(k - 1)).sum();
            assert!((moment - 1.0 / f64::from(k)).abs() < 1e-15, "k = {k}");
        }
        assert!((D[0] + (13.0 + 7.0 * s6) / 3.0).abs() < 1e-14 && (D[1] - (-13.0 + 7.0 * s6) / 3.0).abs() < 1e-15);
    }

    #[test]
    fn collocation_weights_interpolate_at_the_nodes() {
        assert_eq!(collocation_weights(0.0), [0.0; 3]);
        for (i, c) in C.iter().enumerate() {
            let w = collocation_weights(*c);
            for (k, wk) in w.iter().enumerate() {
                assert!((wk - f64::from(u8::from(i == k))).abs() < 1e-14, "node {i}, weight {k}: {wk}");
            }
        }
        // Exact for a cubic through 0: u(s) = s³ − s at s = 1.4.
        let u = C.map(|c| c * c * c - c);
        let w = collocation_weights(1.4);
        assert!((w[0] * u[0] + w[1] * u[1] + w[2] * u[2] - (1.4f64.powi(3) - 1.4)).abs() < 1e-13);
    }

    #[test]
    fn inverse_right_jacobian_inverts_the_right_jacobian() {
        let omega = Vector3::new(0.3, -1.2, 0.7);
        for phi in [Vector3::new(1e-9, 0.0, 0.0), Vector3::new(0.03, -0.05, 0.08), Vector3::new(0.9, 0.4, -1.1)] {
            let back = super::super::newton_matrix::right_jacobian(&phi) * inverse_right_jacobian_times(&phi, &omega);
            assert!((back - omega).norm() < 1e-15, "{phi}: {}", (back - omega).norm());
        }
        // Both branches of c(θ) agree where they meet.
        let (a, b) = (Vector3::new(0.0999999, 0.0, 0.0), Vector3::new(0.1000001, 0.0, 0.0));
        let w = Vector3::new(0.0, 1.0, 0.0);
        let (ca, cb) = (inverse_right_jacobian_times(&a, &w), inverse_right_jacobian_times(&b, &w));
        assert!((ca - cb).norm() < 1e-6);
    }
}
