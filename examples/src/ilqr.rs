//! iLQR (Li and Todorov, 2004; Tassa, Erez and Todorov, 2012) on a tree
//! scene's exact step Jacobians: what the derivatives are for.
//!
//! The plant is one RK4 step of the scene under joint forces held over the
//! step; its Jacobian `[A B]` is
//! [`TreeSimulation::rk4_step_jacobian`](joint_runtime::relative::TreeSimulation::rk4_step_jacobian)
//! (exact, by the chain rule through the stages), or, for comparison, central
//! differences of [`step_with`](joint_runtime::relative::TreeSimulation::step_with)
//! (`2 (2 NV + NU)` more steps per knot). The cost is quadratic about a
//! target state: `Σ ½ (xₖ − x*)ᵀ Q (xₖ − x*) + ½ uₖᵀ R uₖ` and a terminal
//! `½ (x_N − x*)ᵀ Q_f (x_N − x*)`. Each iteration linearises the trajectory,
//! runs the Riccati-like backward pass (Levenberg–Marquardt regularisation
//! on `Q_uu`), and rolls the feedback policy `u = ū + α k + K (x − x̄)` out
//! with a backtracking line search that accepts only a lower cost.
//!
//! The controls act through `actuation` (`τ = P u`, `NV × NU`): the Panda's
//! nine joints, or the acrobot's elbow alone. Matrices of the controller's own
//! size are nalgebra's dynamic ones: the scene's derivatives are fixed-size
//! and allocation-free, the controller around them here is not.

use std::time::Instant;

use joint_runtime::nalgebra::{DMatrix, DVector, SVector};
use joint_runtime::relative::{StepJacobian, StepWork, TreeError, TreeScene, TreeSimulation, TreeState};

/// How the step's Jacobian is obtained.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Derivatives {
    /// The exact chain rule through the RK4 stages.
    Exact,
    /// Central differences of the step (the way without `second_order`).
    Differences,
}

/// A reaching or swing-up problem.
#[derive(Clone, Debug)]
pub struct Problem<const NV: usize> {
    /// The start (at rest or moving).
    pub start: TreeState<NV, NV>,
    /// The target coordinates and rates.
    pub target: (SVector<f64, NV>, SVector<f64, NV>),
    /// `τ = P u`: `NV × NU`.
    pub actuation: DMatrix<f64>,
    /// The step (s) and the number of knots.
    pub h: f64,
    /// Knots of the horizon.
    pub knots: usize,
    /// Diagonal of `Q` (coordinates, then rates), of `Q_f`, and of `R`.
    pub q: DVector<f64>,
    /// Terminal weights.
    pub q_final: DVector<f64>,
    /// Control weights.
    pub r: DVector<f64>,
    /// The first guess of the controls (one per knot).
    pub guess: Vec<DVector<f64>>,
}

/// One iteration's record.
#[derive(Clone, Copy, Debug)]
pub struct Iteration {
    /// The cost after the iteration.
    pub cost: f64,
    /// The line search's accepted step (0: none accepted).
    pub alpha: f64,
    /// Seconds spent on the step Jacobians this iteration.
    pub derivative_seconds: f64,
    /// Seconds for the whole iteration.
    pub seconds: f64,
}

/// What a solve returns.
#[derive(Clone, Debug)]
pub struct Solution<const NV: usize> {
    /// The cost of the first guess.
    pub initial_cost: f64,
    /// One record per iteration.
    pub iterations: Vec<Iteration>,
    /// The optimised states (knots + 1) and controls (knots).
    pub states: Vec<TreeState<NV, NV>>,
    /// The optimised controls.
    pub controls: Vec<DVector<f64>>,
}

impl<const NV: usize> Solution<NV> {
    /// The last cost.
    pub fn cost(&self) -> f64 {
        self.iterations.last().map_or(self.initial_cost, |i| i.cost)
    }
}

/// `x − x*` as one vector (coordinates, then rates).
fn error<const NV: usize>(state: &TreeState<NV, NV>, target: &(SVector<f64, NV>, SVector<f64, NV>)) -> DVector<f64> {
    DVector::from_iterator(2 * NV, (state.q - target.0).iter().chain((state.v - target.1).iter()).copied())
}

/// The trajectory's cost.
fn cost<const NV: usize>(p: &Problem<NV>, states: &[TreeState<NV, NV>], controls: &[DVector<f64>]) -> f64 {
    let quadratic =
        |e: &DVector<f64>, w: &DVector<f64>| 0.5 * e.iter().zip(w.iter()).map(|(e, w)| w * e * e).sum::<f64>();
    let running: f64 =
        states.iter().zip(controls).map(|(s, u)| quadratic(&error(s, &p.target), &p.q) + quadratic(u, &p.r)).sum();
    running + states.last().map_or(0.0, |s| quadratic(&error(s, &p.target), &p.q_final))
}

/// A tree scene's RK4 plant.
struct Plant<'s, 'a, S, const NB: usize, const NV: usize> {
    sim: &'s mut TreeSimulation<'a, S, NB, NV, NV>,
    work: StepWork<NV, NV>,
    jacobian: StepJacobian<NV>,
}

impl<S: TreeScene<NB, NV, NV>, const NB: usize, const NV: usize> Plant<'_, '_, S, NB, NV> {
    fn step(
        &mut self,
        state: &TreeState<NV, NV>,
        tau: &SVector<f64, NV>,
        h: f64,
    ) -> Result<TreeState<NV, NV>, TreeError> {
        let mut next = *state;
        self.sim.step_with(&mut next, h, tau)?;
        Ok(next)
    }

    /// `[A B_τ]` of one step at `state`: `2 NV × 3 NV`.
    fn jacobian(
        &mut self,
        state: &TreeState<NV, NV>,
        tau: &SVector<f64, NV>,
        h: f64,
        how: Derivatives,
    ) -> Result<DMatrix<f64>, TreeError> {
        let mut out = DMatrix::<f64>::zeros(2 * NV, 3 * NV);
        match how {
            Derivatives::Exact => {
                let mut end = *state;
                self.sim.rk4_step_jacobian(&mut end, h, tau, &mut self.work, &mut self.jacobian)?;
                for r in 0..2 * NV {
                    for c in 0..3 * NV {
                        out[(r, c)] = self.jacobian.entry(r, c);
                    }
                }
            }
            Derivatives::Differences => {
                for c in 0..3 * NV {
                    let eps = 1e-6 * (1.0 + if c < NV { state.q[c].abs() } else { 0.0 });
                    let moved = |sign: f64| {
                        let (mut s, mut t) = (*state, *tau);
                        match c / NV {
                            0 => s.q[c] += sign * eps,
                            1 => s.v[c - NV] += sign * eps,
                            _ => t[c - 2 * NV] += sign * eps,
                        }
                        (s, t)
                    };
                    let ((s1, t1), (s2, t2)) = (moved(1.0), moved(-1.0));
                    let (a, b) = (self.step(&s1, &t1, h)?, self.step(&s2, &t2, h)?);
                    for r in 0..NV {
                        out[(r, c)] = (a.q[r] - b.q[r]) / (2.0 * eps);
                        out[(NV + r, c)] = (a.v[r] - b.v[r]) / (2.0 * eps);
                    }
                }
            }
        }
        Ok(out)
    }
}

/// A backward pass's result: each knot's feed-forward `k` and gains `K`.
struct Policy {
    feed: Vec<DVector<f64>>,
    gains: Vec<DMatrix<f64>>,
}

/// The rollout of `controls` (with the policy's feedback about the
/// `reference` states and its feed-forward scaled by `alpha`), or `None` if a
/// step fails.
fn rollout<S: TreeScene<NB, NV, NV>, const NB: usize, const NV: usize>(
    plant: &mut Plant<'_, '_, S, NB, NV>,
    p: &Problem<NV>,
    controls: &[DVector<f64>],
    policy: Option<(&[TreeState<NV, NV>], &Policy, f64)>,
) -> Option<(Vec<TreeState<NV, NV>>, Vec<DVector<f64>>)> {
    let mut states = vec![p.start];
    let mut used = Vec::with_capacity(p.knots);
    for k in 0..p.knots {
        let x = states[k];
        let mut u = controls[k].clone();
        if let Some((reference, policy, alpha)) = policy {
            let dx = error(&x, &(reference[k].q, reference[k].v));
            u += &policy.feed[k] * alpha + &policy.gains[k] * dx;
        }
        let tau = SVector::<f64, NV>::from_iterator((&p.actuation * &u).iter().copied());
        let next = plant.step(&x, &tau, p.h).ok()?;
        if !next.q.iter().chain(next.v.iter()).all(|v| v.is_finite() && v.abs() < 1e6) {
            return None;
        }
        states.push(next);
        used.push(u);
    }
    Some((states, used))
}

/// iLQR from `problem.guess` for at most `iterations`, with the step's
/// Jacobian obtained `how`.
///
/// # Errors
/// A step or a Jacobian that fails along the first guess's trajectory.
pub fn solve<S: TreeScene<NB, NV, NV>, const NB: usize, const NV: usize>(
    sim: &mut TreeSimulation<'_, S, NB, NV, NV>,
    problem: &Problem<NV>,
    iterations: usize,
    how: Derivatives,
) -> Result<Solution<NV>, TreeError> {
    let p = problem;
    let nu = p.actuation.ncols();
    let mut plant = Plant { sim, work: StepWork::new(), jacobian: StepJacobian::zeros() };
    let (mut states, mut controls) = rollout(&mut plant, p, &p.guess, None).ok_or(TreeError::NonFinite)?;
    let initial_cost = cost(p, &states, &controls);
    let mut current = initial_cost;
    let mut mu = 1e-6;
    let mut record = Vec::new();
    for _ in 0..iterations {
        let started = Instant::now();
        // The plant's Jacobians along the trajectory: A (2 NV × 2 NV), B = B_τ P.
        let mut linear = Vec::with_capacity(p.knots);
        for k in 0..p.knots {
            let tau = SVector::<f64, NV>::from_iterator((&p.actuation * &controls[k]).iter().copied());
            let j = plant.jacobian(&states[k], &tau, p.h, how)?;
            let a = j.columns(0, 2 * NV).into_owned();
            let b = j.columns(2 * NV, NV) * &p.actuation;
            linear.push((a, b));
        }
        let derivative_seconds = started.elapsed().as_secs_f64();
        // Backward pass, retried with more regularisation if Q_uu is not positive definite.
        let policy = loop {
            match backward(p, &states, &controls, &linear, mu, nu) {
                Some(policy) => break policy,
                None => mu = (mu * 10.0).max(1e-6),
            }
            if mu > 1e10 {
                break Policy {
                    feed: vec![DVector::zeros(nu); p.knots],
                    gains: vec![DMatrix::zeros(nu, 2 * NV); p.knots],
                };
            }
        };
        let mut accepted = 0.0;
        for alpha in [1.0, 0.5, 0.25, 0.125, 0.0625, 0.03125, 0.015625] {
            if let Some((s, u)) = rollout(&mut plant, p, &controls, Some((&states, &policy, alpha))) {
                let c = cost(p, &s, &u);
                if c < current {
                    (states, controls, current, accepted) = (s, u, c, alpha);
                    break;
                }
            }
        }
        mu = if accepted > 0.0 { (mu / 4.0).max(1e-9) } else { mu * 10.0 };
        let seconds = started.elapsed().as_secs_f64();
        record.push(Iteration { cost: current, alpha: accepted, derivative_seconds, seconds });
        if accepted == 0.0 && mu > 1e8 {
            break;
        }
    }
    Ok(Solution { initial_cost, iterations: record, states, controls })
}

/// The feed-forward `k` and gains `K` of every knot, `None` if a `Q_uu`
/// is not positive definite at regularisation `mu`.
fn backward<const NV: usize>(
    p: &Problem<NV>,
    states: &[TreeState<NV, NV>],
    controls: &[DVector<f64>],
    linear: &[(DMatrix<f64>, DMatrix<f64>)],
    mu: f64,
    nu: usize,
) -> Option<Policy> {
    let n = 2 * NV;
    let last = &states[p.knots];
    let mut vx = error(last, &p.target).component_mul(&p.q_final);
    let mut vxx = DMatrix::from_diagonal(&p.q_final);
    let (mut feed, mut gains) = (vec![DVector::zeros(nu); p.knots], vec![DMatrix::zeros(nu, n); p.knots]);
    for k in (0..p.knots).rev() {
        let (a, b) = &linear[k];
        let lx = error(&states[k], &p.target).component_mul(&p.q);
        let lu = controls[k].component_mul(&p.r);
        let qx = lx + a.transpose() * &vx;
        let qu = lu + b.transpose() * &vx;
        let vxx_a = &vxx * a;
        let vxx_b = &vxx * b;
        let qxx = DMatrix::from_diagonal(&p.q) + a.transpose() * &vxx_a;
        let quu = DMatrix::from_diagonal(&p.r) + b.transpose() * &vxx_b;
        let qux = b.transpose() * &vxx_a;
        let regularised = &quu + DMatrix::identity(nu, nu) * mu;
        let chol = regularised.cholesky()?;
        let kff = -chol.solve(&qu);
        let kfb = -chol.solve(&qux);
        vx = &qx + kfb.transpose() * &quu * &kff + kfb.transpose() * &qu + qux.transpose() * &kff;
        let v = &qxx + kfb.transpose() * &quu * &kfb + kfb.transpose() * &qux + qux.transpose() * &kfb;
        vxx = (&v + v.transpose()) * 0.5;
        feed[k] = kff;
        gains[k] = kfb;
    }
    Some(Policy { feed, gains })
}

/// The Panda from its URDF file, fingers independent: iLQR's plant (its
/// exact derivatives are the runtime's recursion at this size). The
/// recording uses [`crate::panda::Panda`], the same tree in both coordinate
/// choices.
#[derive(joint_runtime::Scene)]
#[scene(gravity = [0, 0, -9.81], urdf = "../tests/data/robots/panda.urdf", mimic = independent)]
pub struct PandaArm;

/// An acrobot: a double pendulum of two 1 m bars about `y` whose shoulder
/// is free and whose elbow alone is driven; hanging at `θ₁ = π/2`, upright
/// at `θ₁ = −π/2` (`θ₂ = 0`: the bars in line).
#[derive(joint_runtime::Scene)]
#[scene(gravity = [0, 0, -9.81], coordinates = both, second_order)]
#[body(upper, mass = 1.0, inertia = [0.001, 0.0833, 0.0833])]
#[body(lower, mass = 1.0, inertia = [0.001, 0.0833, 0.0833])]
#[joint(shoulder = revolute(ground, upper), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0, 0, 0], rho2 = [-0.5, 0, 0])]
#[joint(elbow = revolute(upper, lower), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0.5, 0, 0], rho2 = [-0.5, 0, 0])]
pub struct Acrobot;

/// The Panda from `READY` at rest to `TARGET` at rest in 1 s (100 knots of
/// 10 ms), every joint driven, starting from gravity compensation at `READY`.
pub fn panda_problem(sim: &TreeSimulation<'_, PandaArm, 9, 9, 9>) -> Problem<9> {
    let start = TreeState { q: SVector::from(crate::panda::READY), v: SVector::zeros(), t: 0.0 };
    let hold = sim.inverse_dynamics(&start, &SVector::zeros());
    let weights = |q: f64, v: f64| DVector::from_fn(18, |i, _| if i < 9 { q } else { v });
    Problem {
        start,
        target: (SVector::from(crate::panda::TARGET), SVector::zeros()),
        actuation: DMatrix::identity(9, 9),
        h: 0.01,
        knots: 100,
        q: weights(1.0, 0.01),
        q_final: weights(1e5, 1e3),
        r: DVector::from_element(9, 1e-3),
        guess: vec![DVector::from_iterator(9, hold.iter().copied()); 100],
    }
}

/// The acrobot's swing-up: from hanging at rest to upright at rest in 4 s
/// (400 knots of 10 ms), the elbow's torque the only control.
pub fn acrobot_problem() -> Problem<2> {
    use std::f64::consts::FRAC_PI_2;
    let start = TreeState { q: SVector::from([FRAC_PI_2, 0.0]), v: SVector::zeros(), t: 0.0 };
    let knots = 400;
    Problem {
        start,
        target: (SVector::from([-FRAC_PI_2, 0.0]), SVector::zeros()),
        actuation: DMatrix::from_column_slice(2, 1, &[0.0, 1.0]),
        h: 0.01,
        knots,
        q: DVector::from_column_slice(&[0.01, 0.01, 0.001, 0.001]),
        q_final: DVector::from_column_slice(&[1e4, 1e4, 1e3, 1e3]),
        r: DVector::from_element(1, 1e-2),
        // A small push to start from: hanging still is a critical point of the cost's first guess.
        guess: (0..knots).map(|k| DVector::from_element(1, if k < 50 { 1.0 } else { 0.0 })).collect(),
    }
}
