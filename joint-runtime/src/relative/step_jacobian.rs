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
//! (MuJoCo's default: `v₁ = v + h q̈`, `q₁ = q ⊕ h v₁`).
//!
//! Coordinates and their changes are in the tree's increments at both ends
//! ([`Tree::displace`](super::Tree::displace),
//! [`Tree::difference`](super::Tree::difference)): `q₀ ⊕ δq₀` at the start,
//! `q₁ ⊕ δq₁` at the end. RK4 moves a quaternion as its four numbers
//! (`ṗ = ½ p ⊗ (0, ω')`) and renormalises it after the step, and the chain
//! rule follows it there (`tangent.rs`: the increments' map to the
//! coordinates and back, the rates' and the normalisation's derivatives);
//! the semi-implicit Euler step turns it by `exp(h ω₁)`, whose derivative
//! is the rotation group's right Jacobian. A tree with springs or user
//! loads gets [`TreeError::Loaded`] (the tree's own dynamics only), and
//! [`transition`](super::TreeSimulation::transition) differences its step.
//! Where rows hold, the stages' constrained dynamics carry their exact
//! derivatives, and a projected RK4 step's projection is differentiated
//! along its own iterations (`projected.rs`).

use nalgebra::{Matrix3, SMatrix, SVector, Vector3};

use super::tangent::three;
use super::{ForwardDerivatives, InverseDerivatives, TreeError, TreeJointKind, TreeScene, TreeSimulation, TreeState};

type Block<const NV: usize> = SMatrix<f64, NV, NV>;

/// A stage's `q̈` and its derivatives `∂q̈/∂(q, v, τ)`.
type Rate<'a, const NV: usize> = (&'a SVector<f64, NV>, &'a Block<NV>, &'a Block<NV>, &'a Block<NV>);

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
}

/// A stage's derivative with respect to the step's inputs: its coordinates
/// (`NQ` rows) and velocities (`NV` rows) against the start's increments,
/// velocities and the joint forces (`NV` columns each).
#[derive(Clone, Copy, Debug)]
struct Chain<const NQ: usize, const NV: usize> {
    q: [SMatrix<f64, NQ, NV>; 3],
    v: [SMatrix<f64, NV, NV>; 3],
}

impl<const NQ: usize, const NV: usize> Chain<NQ, NV> {
    fn zeros() -> Self {
        Chain { q: [SMatrix::zeros(); 3], v: [SMatrix::zeros(); 3] }
    }

    /// `self = base + c · rate`.
    fn set(&mut self, base: &Self, c: f64, rate: &Self) {
        for g in 0..3 {
            self.q[g] = base.q[g] + rate.q[g] * c;
            self.v[g] = base.v[g] + rate.v[g] * c;
        }
    }

    /// `self += c · rate`.
    fn add(&mut self, c: f64, rate: &Self) {
        for g in 0..3 {
            self.q[g] += rate.q[g] * c;
            self.v[g] += rate.v[g] * c;
        }
    }
}

/// What a step's Jacobian needs beside its output: each stage's
/// derivatives and the chain's running products (the caller's, so that a
/// controller makes them once and nothing of the tree's size is on the
/// stack per call).
#[derive(Clone, Copy, Debug)]
pub struct StepWork<const NQ: usize, const NV: usize> {
    pub(super) inverse: InverseDerivatives<NV>,
    pub(super) forward: ForwardDerivatives<NV>,
    start: Chain<NQ, NV>,
    stage: Chain<NQ, NV>,
    rate: Chain<NQ, NV>,
    sum: Chain<NQ, NV>,
}

impl<const NQ: usize, const NV: usize> StepWork<NQ, NV> {
    /// Zeros, ready for any number of calls.
    pub fn new() -> Self {
        StepWork {
            inverse: InverseDerivatives::zeros(),
            forward: ForwardDerivatives::zeros(),
            start: Chain::zeros(),
            stage: Chain::zeros(),
            rate: Chain::zeros(),
            sum: Chain::zeros(),
        }
    }
}

impl<const NQ: usize, const NV: usize> Default for StepWork<NQ, NV> {
    fn default() -> Self {
        Self::new()
    }
}

/// `exp(φ)`'s rotation matrix and the right Jacobian `J_r(φ)` of the
/// rotation group: `exp(φ + δ) = exp(φ) exp(J_r(φ) δ)` to first order.
fn exp_and_right_jacobian(phi: Vector3<f64>) -> (Matrix3<f64>, Matrix3<f64>) {
    let angle = phi.norm();
    let k = phi.cross_matrix();
    let k2 = k * k;
    // (1 − cos θ)/θ² and (θ − sin θ)/θ³, by their series near zero.
    let (a, b, s) = if angle < 1e-4 {
        let t2 = angle * angle;
        (0.5 - t2 / 24.0, 1.0 / 6.0 - t2 / 120.0, 1.0 - t2 / 6.0)
    } else {
        let (sin, cos) = (libm::sin(angle), libm::cos(angle));
        ((1.0 - cos) / (angle * angle), (angle - sin) / (angle * angle * angle), sin / angle)
    };
    let rotation = Matrix3::identity() + k * s + k2 * a;
    let right = Matrix3::identity() - k * a + k2 * b;
    (rotation, right)
}

impl<
    S: TreeScene<NB, NQ, NV, NC>,
    L: crate::dynamics::AppliedLoads<NB>,
    const NB: usize,
    const NQ: usize,
    const NV: usize,
    const NC: usize,
> TreeSimulation<'_, S, NB, NQ, NV, NC, L>
{
    /// Refuses what the chain rule here does not cover.
    pub(super) fn check_step(
        &self,
        state: &TreeState<NQ, NV>,
        h: f64,
        tau: &SVector<f64, NV>,
    ) -> Result<(), TreeError> {
        if self.loaded() {
            return Err(TreeError::Loaded);
        }
        if !h.is_finite() {
            return Err(TreeError::NonFinite);
        }
        super::simulation::finite_inputs(state, &[tau.as_slice()])?;
        Ok(())
    }

    /// The semi-implicit Euler step from `state` with acceleration `qdd`
    /// and its derivatives, and the step's Jacobian into `out`, by the
    /// chain rule: `v₁ = v + h q̈`, `q₁ = q ⊕ h v₁`.
    pub(super) fn euler_chain(
        &self,
        state: &mut TreeState<NQ, NV>,
        h: f64,
        (qdd, d_q, d_v, d_tau): Rate<'_, NV>,
        out: &mut StepJacobian<NV>,
    ) -> Result<(), TreeError> {
        let v1 = state.v + qdd * h;
        // δv₁ = h A_q δq₀ + (I + h A_v) δv₀ + h B δτ.
        out.v_q = d_q * h;
        out.v_v = d_v * h + SMatrix::<f64, NV, NV>::identity();
        out.v_tau = d_tau * h;
        // δq₁ = (the turn's transport) δq₀ + (its right Jacobian) h δv₁.
        let (transport, right) = self.displace_derivative(&(v1 * h));
        let push = right * h;
        out.q_q = transport + push * out.v_q;
        out.q_v = push * out.v_v;
        out.q_tau = push * out.v_tau;
        let tree = self.tree();
        let mut end = TreeState { q: state.q, v: v1, t: state.t + h };
        tree.displace(&mut end.q, &(v1 * h));
        finish(state, end)
    }

    /// The derivative of `q ⊕ Δ` in increments at both ends:
    /// `δ(q ⊕ Δ) = transport δq + right δΔ`, joint by joint (a turn's
    /// `exp(φ)ᵀ` and the rotation group's right Jacobian; a free joint's
    /// offset moves by `R(p) u`, so `δ₁ = R(φ)ᵀ (δ₀ + δθ₀ × u + δu)`; the
    /// identity on the other freedoms).
    pub(super) fn displace_derivative(&self, delta: &SVector<f64, NV>) -> (Block<NV>, Block<NV>) {
        let (mut transport, mut right) = (Block::<NV>::identity(), Block::<NV>::identity());
        let tree = self.tree();
        for (k, j) in tree.joints.iter().enumerate() {
            let va = tree.v_at[k];
            let turn_at = match j.kind {
                TreeJointKind::Spherical => va,
                TreeJointKind::Free => va + 3,
                _ => continue,
            };
            let (rotation, jr) = exp_and_right_jacobian(three(delta, turn_at));
            let back = rotation.transpose();
            put_block(&mut transport, (turn_at, turn_at), &back);
            put_block(&mut right, (turn_at, turn_at), &jr);
            if j.kind == TreeJointKind::Free {
                let u = three(delta, va);
                put_block(&mut transport, (va, va), &back);
                put_block(&mut transport, (va, va + 3), &(back * -u.cross_matrix()));
                put_block(&mut right, (va, va), &back);
            }
        }
        (transport, right)
    }

    /// Whether the step closes its rows after it: rows that hold (loops,
    /// couplings, contacts) under options that ask for a projection (the
    /// default). MuJoCo's soft rows are never projected.
    fn projects(&self) -> bool {
        NC > 0 && !self.soft.all() && self.options().projection.is_some()
    }

    /// Refuses the semi-implicit Euler step's Jacobian where the step would
    /// project: that step is this Jacobian's alone (no stepping function
    /// projects it), so it is offered as Crocoddyl integrates contact
    /// dynamics, held at the acceleration level, without projection.
    fn unprojected(&self) -> Result<(), TreeError> {
        if self.projects() {
            return Err(TreeError::NotOffered {
                what: "the semi-implicit Euler step Jacobian of a scene whose rows hold and are projected",
                instead: "`SimulationOptions::with_projection(None)` (the rows held at the acceleration level, with \
                          Baumgarte's gains), `constrained_euler_step_jacobian`, or `rk4_step_jacobian` (the \
                          projected RK4 step, exact)",
            });
        }
        Ok(())
    }

    /// The stage's rate `(q̇, q̈)` at `stage` and its derivative into
    /// `work.rate`, given the stage's own derivative `work.stage`.
    fn stage_rate(
        &self,
        stage: &TreeState<NQ, NV>,
        tau: &SVector<f64, NV>,
        work: &mut StepWork<NQ, NV>,
    ) -> Result<(SVector<f64, NQ>, SVector<f64, NV>), TreeError> {
        self.forward_dynamics_derivatives(stage, tau, &mut work.inverse, &mut work.forward)?;
        let tree = self.tree();
        let (f, d, r) = (&work.forward, &work.stage, &mut work.rate);
        let mut increments = SMatrix::<f64, NV, NV>::zeros();
        for g in 0..3 {
            // q̇'s derivative; q̈'s through the increments: A_q T⁺ D_q + A_v D_v.
            tree.rates_along_columns((&stage.q, &stage.v), (&d.q[g], &d.v[g]), &mut r.q[g]);
            tree.increments_of_columns(&stage.q, &d.q[g], &mut increments);
            f.d_q.mul_to(&increments, &mut r.v[g]);
            r.v[g].gemm(1.0, &f.d_v, &d.v[g], 1.0);
        }
        r.v[2] += f.d_tau;
        Ok((tree.coordinate_rates(&stage.q, &stage.v), f.qdd))
    }

    /// One classical RK4 step of `state` under joint forces `tau` (as
    /// [`step_with`](Self::step_with) takes it on a tree without loops,
    /// springs or loads: quaternions moved as four numbers, renormalised at
    /// the end) and its exact Jacobian into `out`, by the chain rule through
    /// the four stages: `4` forward-dynamics derivatives. Allocation-free;
    /// on error `state` is unchanged. A file's soft equalities (MuJoCo's,
    /// never projected) are in the stages' dynamics and their derivatives.
    ///
    /// A scene whose rows hold (loops, couplings, contacts) has its stages'
    /// constrained dynamics differentiated, every row holding, and, where
    /// its options project (the default), the projection that ends
    /// `step_with`'s step too (`projected.rs`: the same simplified Newton
    /// iterations and velocity corrections, differentiated). Its start is
    /// not checked to be closed: the map is smooth off the loops as well.
    /// A tree with springs or user loads gets [`TreeError::Loaded`]. The
    /// step is RK4's whatever the options' integrator (`step_with`'s only
    /// where that is RK4, the default).
    pub fn rk4_step_jacobian(
        &self,
        state: &mut TreeState<NQ, NV>,
        h: f64,
        tau: &SVector<f64, NV>,
        work: &mut StepWork<NQ, NV>,
        out: &mut StepJacobian<NV>,
    ) -> Result<(), TreeError> {
        self.check_step(state, h, tau)?;
        let tree = self.tree();
        // The start's derivative: q moves by T(q₀) δq₀, v by δv₀.
        work.start = Chain::zeros();
        for c in 0..NV {
            let e = SVector::<f64, NV>::from_fn(|r, _| if r == c { 1.0 } else { 0.0 });
            work.start.q[0].set_column(c, &tree.along_increment(&state.q, &e));
        }
        work.start.v[1].fill_with_identity();
        work.sum = work.start;
        let (q0, v0) = (state.q, state.v);
        let (mut dq, mut dv) = (SVector::<f64, NQ>::zeros(), SVector::<f64, NV>::zeros());
        let (mut kq, mut kv) = (SVector::<f64, NQ>::zeros(), SVector::<f64, NV>::zeros());
        for (c, w) in [(0.0, 1.0), (0.5, 2.0), (0.5, 2.0), (1.0, 1.0)] {
            if c == 0.0 {
                work.stage = work.start;
            } else {
                work.stage.set(&work.start, c * h, &work.rate);
            }
            let stage = TreeState { q: q0 + kq * (c * h), v: v0 + kv * (c * h), t: state.t + c * h };
            (kq, kv) = self.stage_rate(&stage, tau, work)?;
            dq += kq * w;
            dv += kv * w;
            work.sum.add(w * h / 6.0, &work.rate);
        }
        let mut end = TreeState { q: q0 + dq * (h / 6.0), v: v0 + dv * (h / 6.0), t: state.t + h };
        // The end renormalised, and measured in its own increments.
        let raw = end.q;
        tree.normalise(&mut end.q);
        let blocks = [(&mut out.q_q, &mut out.v_q), (&mut out.q_v, &mut out.v_v), (&mut out.q_tau, &mut out.v_tau)];
        for (g, (q_block, v_block)) in blocks.into_iter().enumerate() {
            tree.normalised_columns(&raw, &mut work.sum.q[g]);
            tree.increments_of_columns(&end.q, &work.sum.q[g], q_block);
            *v_block = work.sum.v[g];
        }
        if self.projects() {
            self.project_chain(&mut end, &mut work.inverse, out)?;
        }
        finish(state, end)
    }

    /// One semi-implicit (symplectic) Euler step, MuJoCo's default
    /// integrator: `v₁ = v + h q̈(q, v, τ)`, then `q₁ = q ⊕ h v₁` (a
    /// quaternion turned by `exp(h ω₁)` in its own frame), and its exact
    /// Jacobian into `out` (one forward-dynamics derivative). What a user
    /// compares with MuJoCo's `mjd_transitionFD` compares like with like.
    /// Allocation-free; on error `state` is unchanged. Errors as
    /// [`rk4_step_jacobian`](Self::rk4_step_jacobian), and
    /// [`TreeError::NotOffered`] where the rows hold and the options
    /// project (this step has no projection of its own).
    pub fn euler_step_jacobian(
        &self,
        state: &mut TreeState<NQ, NV>,
        h: f64,
        tau: &SVector<f64, NV>,
        work: &mut StepWork<NQ, NV>,
        out: &mut StepJacobian<NV>,
    ) -> Result<(), TreeError> {
        self.check_step(state, h, tau)?;
        self.unprojected()?;
        self.forward_dynamics_derivatives(state, tau, &mut work.inverse, &mut work.forward)?;
        let f = &work.forward;
        self.euler_chain(state, h, (&f.qdd, &f.d_q, &f.d_v, &f.d_tau), out)
    }
}

/// `m[r.., c..] = block` (3 × 3), entries past the matrix dropped: no panic path.
fn put_block<const N: usize>(m: &mut SMatrix<f64, N, N>, (r, c): (usize, usize), block: &Matrix3<f64>) {
    for i in 0..3 {
        for j in 0..3 {
            if let Some(slot) = m.get_mut((r + i, c + j)) {
                *slot = block[(i, j)];
            }
        }
    }
}

/// The step's end into `state`, once it is finite.
fn finish<const NQ: usize, const NV: usize>(
    state: &mut TreeState<NQ, NV>,
    end: TreeState<NQ, NV>,
) -> Result<(), TreeError> {
    if !(end.q.iter().chain(end.v.iter()).all(|x| x.is_finite())) {
        return Err(TreeError::NonFinite);
    }
    *state = end;
    Ok(())
}
