//! A stiff tree at its own step: the linearly implicit Euler step in the
//! tree's increments, its Newton matrix from the exact derivatives of the
//! dynamics (`derivatives.rs`), not from differences.
//!
//! Backward Euler, `v₁ = v₀ + h f(q₁, v₁)`, `q₁ = q₀ ⊕ h v₁`, with `f` the
//! accelerations under the joint forces `τ(q, v)`, linearised about the
//! step's start, gives one linear solve. Written with the mass matrix
//! rather than its inverse (differentiating `ID(q, v, q̈) = τ(q, v)`:
//! `M δq̈ = −K_q δq − K_v δv`, `K = ∂ID/∂x − ∂τ/∂x` at `q̈₀`), it is
//! `(M + h K_v + h² K_q) Δv = h M q̈₀ − h² K_q v₀`, `v₁ = v₀ + Δv`: no
//! `M⁻¹` and no `n × n` products, only the inverse dynamics' derivatives,
//! the mass matrix and one LU factor (the same step as
//! `(I − h A_v − h² A_q) Δv = h (q̈₀ + h A_q v₀)` with the forward
//! dynamics' `A = ∂q̈/∂x + M⁻¹ ∂τ/∂x`, multiplied through by `M`). It is
//! exact for linear dynamics and stable for every `h` where they are
//! (L-stable: a stiff mode is damped out, not amplified), first order in
//! `h`; MuJoCo's `implicit` integrator is the same idea for its damping.
//! What makes a robot stiff is usually its controller (high PD gains) or
//! its joints' damping: the first enters as the forces' gains
//! ([`ForceGains`]), the second is in the dynamics' derivatives already.

use nalgebra::{SMatrix, SVector};

use super::{StepWork, TreeError, TreeScene, TreeSimulation, TreeState};
use crate::dynamics::AppliedLoads;
use crate::linalg::Lu;

/// How the joint forces change with the state over a step, `τ(q ⊕ δq, v +
/// δv) ≈ τ + d_q δq + d_v δv`: a controller's gains (for a PD law
/// `τ = −Kp (q − q*) − Kd (v − v*)`, `d_q = −Kp`, `d_v = −Kd`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ForceGains<const NV: usize> {
    /// `∂τ/∂q`, tangent columns.
    pub d_q: SMatrix<f64, NV, NV>,
    /// `∂τ/∂v`.
    pub d_v: SMatrix<f64, NV, NV>,
}

impl<const NV: usize> ForceGains<NV> {
    /// Forces that do not change over the step (held, as `step_with` holds them).
    pub fn zeros() -> Self {
        ForceGains { d_q: SMatrix::zeros(), d_v: SMatrix::zeros() }
    }

    /// A PD law's, joint by joint: `d_q = −diag(kp)`, `d_v = −diag(kd)`.
    pub fn pd(kp: &SVector<f64, NV>, kd: &SVector<f64, NV>) -> Self {
        ForceGains { d_q: SMatrix::from_diagonal(&(-kp)), d_v: SMatrix::from_diagonal(&(-kd)) }
    }
}

impl<
    S: TreeScene<NB, NQ, NV, NC>,
    L: AppliedLoads<NB>,
    const NB: usize,
    const NQ: usize,
    const NV: usize,
    const NC: usize,
> TreeSimulation<'_, S, NB, NQ, NV, NC, L>
{
    /// One linearly implicit Euler step of length `h` from `state` under
    /// joint forces `tau` (their value at the step's start) changing with
    /// the state by `gains` (the module): for stiff trees at the step their
    /// files or controllers ask for, where RK4 would need a far smaller one.
    /// Allocation-free; `work` holds the derivatives on the way. On error
    /// `state` is unchanged.
    ///
    /// Trees without springs or user loads (as the exact derivatives:
    /// [`TreeError::Loaded`]), and with no loops but a file's couplings
    /// (`<mimic>`, `<equality joint>`: rows `J q = c` linear in the
    /// coordinates; other loops get [`TreeError::NotDerived`]). A coupled
    /// tree's step is the same with the rows' forces `Jᵀ μ` beside it and
    /// `J v₁ = −Φ(q₀)/h`, so that the rows hold exactly at the step's end
    /// (`Φ(q₁) = 0`: they are linear); its start is the constrained
    /// accelerations. [`TreeError::Singular`] if the Newton matrix is (or,
    /// coupled, `J N⁻¹ Jᵀ`: redundant couplings), [`TreeError::Diverged`]
    /// if the step leaves the finite range.
    ///
    /// ```
    /// use joint_runtime::Scene;
    /// use joint_runtime::nalgebra::SVector;
    /// use joint_runtime::relative::{ForceGains, StepWork, TreeSimulation};
    ///
    /// /// A light bar on a hinge, held at 0.5 rad by a stiff PD law.
    /// #[derive(Scene)]
    /// #[scene(gravity = [0, 0, -9.81])]
    /// #[body(bar, mass = 0.1, inertia = [0.0001, 0.002, 0.002])]
    /// #[joint(pin = revolute(ground, bar), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0, 0, 0], rho2 = [-0.1, 0, 0])]
    /// struct Bar;
    ///
    /// let sim = TreeSimulation::new(&Bar)?;
    /// let (kp, kd) = (SVector::from([1e4]), SVector::from([1e2]));
    /// let gains = ForceGains::pd(&kp, &kd);
    /// let (mut state, mut work) = (sim.tree().zero_state(), StepWork::new());
    /// for _ in 0..500 {
    ///     let tau = kp.component_mul(&(SVector::from([0.5]) - state.q)) - kd.component_mul(&state.v);
    ///     sim.implicit_step_with(&mut state, 2e-3, &tau, &gains, &mut work)?;
    /// }
    /// // 1 s at h = 2 ms, where the damping's own time constant is 3e-5 s.
    /// assert!((state.q[0] - 0.5).abs() < 1e-3 && state.v[0].abs() < 1e-6);
    /// # Ok::<(), joint_runtime::relative::TreeError>(())
    /// ```
    pub fn implicit_step_with(
        &self,
        state: &mut TreeState<NQ, NV>,
        h: f64,
        tau: &SVector<f64, NV>,
        gains: &ForceGains<NV>,
        work: &mut StepWork<NQ, NV>,
    ) -> Result<(), TreeError> {
        self.check_step(state, h, tau)?;
        if self.soft.any() {
            return Err(TreeError::NotOffered {
                what: "the linearly implicit step on a file's soft equalities (it holds every row)",
                instead: "step with `step` (RK4), or read the file's equalities as ideal rows (`equality = hard`)",
            });
        }
        if NC > 0 && !S::LINEAR_CLOSURES {
            return Err(TreeError::NotDerived);
        }
        let d = &mut work.inverse;
        self.mass_matrix_into(&state.q, &mut d.d_a);
        let qdd = self.start_accelerations(state, tau, &d.d_a)?;
        self.derivatives_at(state, &qdd, d)?;
        // K = ∂ID/∂x − ∂τ/∂x, formed in place of the inverse dynamics' own.
        d.d_q -= gains.d_q;
        d.d_v -= gains.d_v;
        let newton: SMatrix<f64, NV, NV> = d.d_a + d.d_v * h + d.d_q * (h * h);
        let rhs = d.d_a * qdd * h - d.d_q * state.v * (h * h);
        let joint = self.tree().joints().first().map_or("", |j| j.name);
        let lu = Lu::new(&newton).map_err(|_| TreeError::Singular { joint })?;
        let delta = self.held(state, h, &lu, lu.solve(&rhs))?;
        let v = state.v + delta;
        let mut q = state.q;
        self.tree().displace(&mut q, &(v * h));
        let next = TreeState { q, v, t: state.t + h };
        super::simulation::diverged(&next)?;
        *state = next;
        Ok(())
    }

    /// The start's `q̈₀` (where the derivatives are taken): the derive's
    /// articulated-body code where it wrote one, else `M⁻¹ (τ − b)` by an LU
    /// factor of `m`, the mass matrix (the tree's own recursion stays out of
    /// the step: its indices are data, the step is proved panic-free); on a
    /// coupled tree, the constrained accelerations (the rows' forces held
    /// to `J q̈ = 0`, as [`held`](Self::held) holds the step).
    fn start_accelerations(
        &self,
        state: &TreeState<NQ, NV>,
        tau: &SVector<f64, NV>,
        m: &SMatrix<f64, NV, NV>,
    ) -> Result<SVector<f64, NV>, TreeError> {
        let joint = self.tree().joints().first().map_or("", |j| j.name);
        let lu = Lu::new(m).map_err(|_| TreeError::Singular { joint })?;
        let free = match self.generated_dynamics(state, tau) {
            (_, Some(out)) if NC == 0 => return Ok(out),
            _ => lu.solve(&(tau - self.inverse_dynamics(state, &SVector::zeros()))),
        };
        if NC == 0 {
            return Ok(free);
        }
        let j = self.closure_rows(state).jacobian;
        self.with_row_forces(&lu, &j, free, &(-(j * free)), joint)
    }

    /// A coupled tree's velocity change held to its rows: `x` (the change
    /// without their forces, `N x = r`) plus `N⁻¹ Jᵀ μ` with `μ` such that
    /// `J v₁ = −Φ(q₀)/h` (the rows hold exactly at the step's end; `J` is
    /// constant). `x` itself where there are no rows.
    fn held(
        &self,
        state: &TreeState<NQ, NV>,
        h: f64,
        lu: &Lu<NV>,
        x: SVector<f64, NV>,
    ) -> Result<SVector<f64, NV>, TreeError> {
        if NC == 0 {
            return Ok(x);
        }
        let rows = self.closure_rows(state);
        let wanted = -(rows.phi / h) - rows.jacobian * (state.v + x);
        let joint = self.tree().joints().first().map_or("", |j| j.name);
        self.with_row_forces(lu, &rows.jacobian, x, &wanted, joint)
    }

    /// `x + A⁻¹ Jᵀ μ` with `J A⁻¹ Jᵀ μ = wanted` (`lu`: `A`'s factor): the
    /// change that the rows' forces make so that `J` of it moves by `wanted`.
    fn with_row_forces(
        &self,
        lu: &Lu<NV>,
        j: &SMatrix<f64, NC, NV>,
        x: SVector<f64, NV>,
        wanted: &SVector<f64, NC>,
        joint: &'static str,
    ) -> Result<SVector<f64, NV>, TreeError> {
        let mut y = SMatrix::<f64, NV, NC>::zeros();
        for (r, mut column) in y.column_iter_mut().enumerate() {
            column.copy_from(&lu.solve(&j.row(r).transpose()));
        }
        let schur = Lu::new(&(j * y)).map_err(|_| TreeError::Singular { joint })?;
        Ok(x + y * schur.solve(wanted))
    }
}
