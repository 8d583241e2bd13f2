//! The exact Jacobian of one step, by the chain rule through its stages:
//! what an iLQR or DDP backward pass and an extended Kalman filter
//! propagate. `(q₁, v₁) = step(q₀, v₀, τ)` with `τ` held over the step;
//! [`StepJacobian`] holds `∂(q₁, v₁)/∂(q₀, v₀)` and `∂(q₁, v₁)/∂τ` by
//! blocks (`2 NV × 2 NV` and `2 NV × NV` as `NV × NV` blocks: stable Rust
//! cannot size an array `2 NV`).
//!
//! Each stage's rate `k = (v, q̈(q, v, τ))` has the Jacobian
//! `[[0, I, 0], [∂q̈/∂q, ∂q̈/∂v, M⁻¹]]` from
//! [`forward_dynamics_derivatives`](super::TreeSimulation::forward_dynamics_derivatives),
//! and a stage's state `x + c h k` carries `I + c h ∂k/∂x` forward: four
//! derivative evaluations for RK4, one for the semi-implicit Euler step
//! (MuJoCo's default: `v₁ = v + h q̈`, `q₁ = q + h v₁`). Exact for trees
//! whose coordinates are their freedoms (revolute, prismatic, cylindrical,
//! planar, universal and fixed joints: `q̇ = v`, what fixed-base arms are);
//! a tree with a spherical or free joint (whose step renormalises its
//! quaternions) gets [`TreeError::NotEuclidean`], and
//! [`transition`](super::TreeSimulation::transition) differences its step.

use nalgebra::{SMatrix, SVector};

use super::{ForwardDerivatives, InverseDerivatives, TreeError, TreeScene, TreeSimulation, TreeState};

type Block<const NV: usize> = SMatrix<f64, NV, NV>;

/// One step's Jacobian by blocks: `q_q = ∂q₁/∂q₀`, `q_v = ∂q₁/∂v₀`,
/// `q_tau = ∂q₁/∂τ`, and the same of `v₁`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepJacobian<const NV: usize> {
    /// `∂q₁/∂q₀`.
    pub q_q: Block<NV>,
    /// `∂q₁/∂v₀`.
    pub q_v: Block<NV>,
    /// `∂q₁/∂τ`.
    pub q_tau: Block<NV>,
    /// `∂v₁/∂q₀`.
    pub v_q: Block<NV>,
    /// `∂v₁/∂v₀`.
    pub v_v: Block<NV>,
    /// `∂v₁/∂τ`.
    pub v_tau: Block<NV>,
}

impl<const NV: usize> StepJacobian<NV> {
    /// All zero.
    pub fn zeros() -> Self {
        let z = Block::<NV>::zeros();
        StepJacobian { q_q: z, q_v: z, q_tau: z, v_q: z, v_v: z, v_tau: z }
    }

    /// The whole `2 NV × 3 NV` matrix `[A B]` (rows `q₁` then `v₁`; columns
    /// `q₀`, `v₀`, `τ`), entry by entry: `(row, column)`.
    pub fn entry(&self, row: usize, column: usize) -> f64 {
        let (r, c) = (row % NV, column % NV);
        let block = match (row / NV, column / NV) {
            (0, 0) => &self.q_q,
            (0, 1) => &self.q_v,
            (0, 2) => &self.q_tau,
            (1, 0) => &self.v_q,
            (1, 1) => &self.v_v,
            (1, 2) => &self.v_tau,
            _ => return 0.0,
        };
        block.get((r, c)).copied().unwrap_or(0.0)
    }

    /// `self += w · rate` (a stage's rate derivative into the sum).
    fn add_scaled(&mut self, w: f64, rate: &StepJacobian<NV>) {
        let pairs = [
            (&mut self.q_q, &rate.q_q),
            (&mut self.q_v, &rate.q_v),
            (&mut self.q_tau, &rate.q_tau),
            (&mut self.v_q, &rate.v_q),
            (&mut self.v_v, &rate.v_v),
            (&mut self.v_tau, &rate.v_tau),
        ];
        for (a, b) in pairs {
            a.zip_apply(b, |x, y| *x += w * y);
        }
    }

    /// `I + c · rate` on the state's columns, `c · rate` on `τ`'s: a
    /// stage's state `x + c k` differentiated.
    fn stage(&mut self, c: f64, rate: &StepJacobian<NV>) {
        *self = StepJacobian::zeros();
        self.q_q.fill_with_identity();
        self.v_v.fill_with_identity();
        self.add_scaled(c, rate);
    }
}

/// What a step's Jacobian needs beside its output: each stage's
/// derivatives and the chain's running products (the caller's, so that a
/// controller makes them once and nothing of the tree's size is on the
/// stack per call).
#[derive(Clone, Copy, Debug)]
pub struct StepWork<const NV: usize> {
    inverse: InverseDerivatives<NV>,
    forward: ForwardDerivatives<NV>,
    stage: StepJacobian<NV>,
    rate: StepJacobian<NV>,
}

impl<const NV: usize> StepWork<NV> {
    /// Zeros, ready for any number of calls.
    pub fn new() -> Self {
        StepWork {
            inverse: InverseDerivatives::zeros(),
            forward: ForwardDerivatives::zeros(),
            stage: StepJacobian::zeros(),
            rate: StepJacobian::zeros(),
        }
    }
}

impl<const NV: usize> Default for StepWork<NV> {
    fn default() -> Self {
        Self::new()
    }
}

impl<S: TreeScene<NB, NQ, NV>, L: crate::dynamics::AppliedLoads<NB>, const NB: usize, const NQ: usize, const NV: usize>
    TreeSimulation<'_, S, NB, NQ, NV, 0, L>
{
    /// Refuses what the chain rule here does not cover.
    fn check_euclidean(&self, state: &TreeState<NQ, NV>, h: f64, tau: &SVector<f64, NV>) -> Result<(), TreeError> {
        if !S::DERIVATIVES {
            return Err(TreeError::NotDerived);
        }
        if NQ != NV || self.tree().joints.iter().any(|j| j.kind.quaternion().is_some()) || self.loaded() {
            return Err(TreeError::NotEuclidean);
        }
        let numbers = state.q.iter().chain(state.v.iter()).chain(tau.iter());
        if !(h.is_finite() && numbers.copied().all(f64::is_finite)) {
            return Err(TreeError::NonFinite);
        }
        Ok(())
    }

    /// The rate `(v, q̈)` at `(q, v)` and its derivative `rate` (given
    /// `stage`, the derivative of the stage's state): the chain rule's link.
    fn rate_at(
        &self,
        (q, v): (&SVector<f64, NV>, &SVector<f64, NV>),
        tau: &SVector<f64, NV>,
        work: &mut StepWork<NV>,
    ) -> Result<SVector<f64, NV>, TreeError> {
        let mut state = TreeState::<NQ, NV> { q: SVector::zeros(), v: *v, t: 0.0 };
        state.q.iter_mut().zip(q.iter()).for_each(|(a, b)| *a = *b);
        self.forward_dynamics_derivatives(&state, tau, &mut work.inverse, &mut work.forward)?;
        let (f, s, r) = (&work.forward, &work.stage, &mut work.rate);
        // d(v)/dx is the stage's v rows; d(q̈)/dx = A_q D_q + A_v D_v (+ M⁻¹ on τ).
        r.q_q = s.v_q;
        r.q_v = s.v_v;
        r.q_tau = s.v_tau;
        f.d_q.mul_to(&s.q_q, &mut r.v_q);
        r.v_q.gemm(1.0, &f.d_v, &s.v_q, 1.0);
        f.d_q.mul_to(&s.q_v, &mut r.v_v);
        r.v_v.gemm(1.0, &f.d_v, &s.v_v, 1.0);
        f.d_q.mul_to(&s.q_tau, &mut r.v_tau);
        r.v_tau.gemm(1.0, &f.d_v, &s.v_tau, 1.0);
        r.v_tau += f.d_tau;
        Ok(f.qdd)
    }

    /// One classical RK4 step of `state` under joint forces `tau` (as
    /// [`step_with`](Self::step_with) takes it on a tree without loops,
    /// springs or loads) and its exact Jacobian into `out`, by the chain
    /// rule through the four stages: `4` forward-dynamics derivatives.
    /// Allocation-free; on error `state` is unchanged.
    ///
    /// Needs the derive's derivatives (`#[scene(second_order)]`:
    /// [`TreeError::NotDerived`]) and coordinates that are the freedoms
    /// ([`TreeError::NotEuclidean`]: the module's).
    pub fn rk4_step_jacobian(
        &self,
        state: &mut TreeState<NQ, NV>,
        h: f64,
        tau: &SVector<f64, NV>,
        work: &mut StepWork<NV>,
        out: &mut StepJacobian<NV>,
    ) -> Result<(), TreeError> {
        self.check_euclidean(state, h, tau)?;
        let q0 = SVector::<f64, NV>::from_iterator(state.q.iter().copied());
        let v0 = state.v;
        *out = StepJacobian::zeros();
        out.q_q.fill_with_identity();
        out.v_v.fill_with_identity();
        work.stage = *out;
        let (mut dq, mut dv) = (SVector::<f64, NV>::zeros(), SVector::<f64, NV>::zeros());
        let (mut kq, mut kv) = (v0, SVector::<f64, NV>::zeros());
        for (c, w) in [(0.0, 1.0), (0.5, 2.0), (0.5, 2.0), (1.0, 1.0)] {
            if c > 0.0 {
                let rate = work.rate;
                work.stage.stage(c * h, &rate);
            }
            let (q, v) = (q0 + kq * (c * h), v0 + kv * (c * h));
            kv = self.rate_at((&q, &v), tau, work)?;
            kq = v;
            dq += kq * w;
            dv += kv * w;
            out.add_scaled(w * h / 6.0, &work.rate);
        }
        self.finish_euclidean(state, q0 + dq * (h / 6.0), v0 + dv * (h / 6.0), h)
    }

    /// One semi-implicit (symplectic) Euler step, MuJoCo's default
    /// integrator: `v₁ = v + h q̈(q, v, τ)`, `q₁ = q + h v₁`, and its exact
    /// Jacobian into `out` (one forward-dynamics derivative). What a user
    /// compares with MuJoCo's `mjd_transitionFD` compares like with like.
    /// Allocation-free; on error `state` is unchanged. Errors as
    /// [`rk4_step_jacobian`](Self::rk4_step_jacobian).
    pub fn euler_step_jacobian(
        &self,
        state: &mut TreeState<NQ, NV>,
        h: f64,
        tau: &SVector<f64, NV>,
        work: &mut StepWork<NV>,
        out: &mut StepJacobian<NV>,
    ) -> Result<(), TreeError> {
        self.check_euclidean(state, h, tau)?;
        let q0 = SVector::<f64, NV>::from_iterator(state.q.iter().copied());
        let v0 = state.v;
        let qdd = self.rate_at_start(state, tau, work)?;
        let f = &work.forward;
        out.v_q = f.d_q * h;
        out.v_v = f.d_v * h;
        for i in 0..NV {
            out.v_v[(i, i)] += 1.0;
        }
        out.v_tau = f.d_tau * h;
        out.q_q = out.v_q * h;
        for i in 0..NV {
            out.q_q[(i, i)] += 1.0;
        }
        out.q_v = out.v_v * h;
        out.q_tau = out.v_tau * h;
        let v1 = v0 + qdd * h;
        self.finish_euclidean(state, q0 + v1 * h, v1, h)
    }

    /// The forward dynamics' derivatives at the step's start.
    fn rate_at_start(
        &self,
        state: &TreeState<NQ, NV>,
        tau: &SVector<f64, NV>,
        work: &mut StepWork<NV>,
    ) -> Result<SVector<f64, NV>, TreeError> {
        self.forward_dynamics_derivatives(state, tau, &mut work.inverse, &mut work.forward)?;
        Ok(work.forward.qdd)
    }

    /// The step's end into `state`, once it is finite.
    fn finish_euclidean(
        &self,
        state: &mut TreeState<NQ, NV>,
        q: SVector<f64, NV>,
        v: SVector<f64, NV>,
        h: f64,
    ) -> Result<(), TreeError> {
        if !(q.iter().chain(v.iter()).all(|x| x.is_finite())) {
            return Err(TreeError::NonFinite);
        }
        state.q.iter_mut().zip(q.iter()).for_each(|(a, b)| *a = *b);
        state.v = v;
        state.t += h;
        Ok(())
    }
}
