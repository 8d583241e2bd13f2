//! The first derivatives of a tree's dynamics, exact: what a controller
//! that linearises its robot every tick (iLQR, DDP, MPC, an extended Kalman
//! filter) calls.
//!
//! The derive writes `∂τ/∂q` and `∂τ/∂v` of the inverse dynamics as one
//! straight line ([`TreeScene::inverse_dynamics_derivatives_into`], asked
//! for with `#[scene(second_order)]`): the engine's forward-mode derivative
//! of the generated Newton–Euler algorithm, each column folded to the joints
//! its freedom moves. The forward dynamics' follow from them (Carpentier and
//! Mansard, RSS 2018): `M q̈ + b(q, v) = τ` gives
//! `∂q̈/∂x = −M⁻¹ ∂τ/∂x` at `v̇ = q̈`, and `∂q̈/∂τ = M⁻¹`.
//!
//! `∂/∂q` is taken in the tangent space: one column per freedom (`NV`,
//! not `NQ`), along [`Tree::displace`](super::Tree::displace), `q ⊕ ε e_i`:
//! an angle or a slide moved by `ε`; a spherical joint's quaternion turned
//! by `ε` about its own (child) axis `i`, `p ⊗ exp(ε e_i / 2)`; a free
//! joint's offset moved along its child's axis `i`, then its quaternion
//! turned as a spherical one's. This is Pinocchio's convention for its
//! spherical and free-flyer joints (`pinocchio::integrate`, a motion in the
//! joint's local frame) to first order, which is all a first derivative
//! sees; the tests hold the two to Pinocchio's analytical derivatives.
//!
//! Every output is a fixed-size nalgebra matrix the caller owns; nothing is
//! allocated and nothing panics (the factorisation below is by hand and
//! refuses a mass matrix that is not positive definite).

use nalgebra::{SMatrix, SVector};

use super::{TreeError, TreeScene, TreeState};

/// The inverse dynamics and its first derivatives at one state:
/// `τ(q, v, v̇)`, `∂τ/∂q` (tangent columns), `∂τ/∂v` and `∂τ/∂v̇ = M`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InverseDerivatives<const NV: usize> {
    /// The joint forces `τ(q, v, v̇)`.
    pub tau: SVector<f64, NV>,
    /// `∂τ/∂q`: column `i` along freedom `i` of the tangent space.
    pub d_q: SMatrix<f64, NV, NV>,
    /// `∂τ/∂v` (joint damping included).
    pub d_v: SMatrix<f64, NV, NV>,
    /// `∂τ/∂v̇`: the mass matrix `M(q)` (armature included).
    pub d_a: SMatrix<f64, NV, NV>,
}

impl<const NV: usize> InverseDerivatives<NV> {
    /// All zero.
    pub fn zeros() -> Self {
        InverseDerivatives {
            tau: SVector::zeros(),
            d_q: SMatrix::zeros(),
            d_v: SMatrix::zeros(),
            d_a: SMatrix::zeros(),
        }
    }
}

/// The forward dynamics and its first derivatives at one state:
/// `q̈(q, v, τ)`, `∂q̈/∂q` (tangent columns), `∂q̈/∂v` and `∂q̈/∂τ = M⁻¹`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ForwardDerivatives<const NV: usize> {
    /// The accelerations `q̈ = v̇`.
    pub qdd: SVector<f64, NV>,
    /// `∂q̈/∂q`: column `i` along freedom `i` of the tangent space.
    pub d_q: SMatrix<f64, NV, NV>,
    /// `∂q̈/∂v`.
    pub d_v: SMatrix<f64, NV, NV>,
    /// `∂q̈/∂τ`: the inverse mass matrix `M⁻¹`.
    pub d_tau: SMatrix<f64, NV, NV>,
}

impl<const NV: usize> ForwardDerivatives<NV> {
    /// All zero.
    pub fn zeros() -> Self {
        ForwardDerivatives {
            qdd: SVector::zeros(),
            d_q: SMatrix::zeros(),
            d_v: SMatrix::zeros(),
            d_tau: SMatrix::zeros(),
        }
    }
}

/// `M⁻¹` of a symmetric positive definite `m` into `out` by `M = L Lᵀ`
/// (by hand: no allocation, no panic), `None` unless every pivot is
/// positive and finite. `L⁻¹` is formed in place of `L`, then
/// `M⁻¹ = L⁻ᵀ L⁻¹`: `n³/2` multiplications in all.
pub(crate) fn spd_inverse<const N: usize>(m: &SMatrix<f64, N, N>, out: &mut SMatrix<f64, N, N>) -> Option<()> {
    // Column-major storage: `a[c][r]` is entry (r, c); L in the lower triangle.
    let mut a = m.data.0;
    for j in 0..N {
        let mut d = a[j][j];
        for column in &a[..j] {
            d -= column[j] * column[j];
        }
        if !(d > 0.0 && d.is_finite()) {
            return None;
        }
        let d = libm::sqrt(d);
        a[j][j] = d;
        for i in j + 1..N {
            let mut s = a[j][i];
            for column in &a[..j] {
                s -= column[i] * column[j];
            }
            a[j][i] = s / d;
        }
    }
    // L⁻¹, lower triangular, column by column: L x = e_j.
    let mut inv = [[0.0_f64; N]; N];
    for (j, column) in inv.iter_mut().enumerate() {
        for i in j..N {
            let mut s = if i == j { 1.0 } else { 0.0 };
            for k in j..i {
                s -= a[k][i] * column[k];
            }
            column[i] = s / a[i][i];
        }
    }
    // (L⁻ᵀ L⁻¹)_rc = Σ_{k ≥ max(r, c)} L⁻¹_kr L⁻¹_kc.
    let o = &mut out.data.0;
    for c in 0..N {
        for r in c..N {
            let mut s = 0.0;
            for (x, y) in inv[r][r..].iter().zip(&inv[c][r..]) {
                s += x * y;
            }
            o[c][r] = s;
            o[r][c] = s;
        }
    }
    Some(())
}

impl<
    S: TreeScene<NB, NQ, NV, NC>,
    L: crate::dynamics::AppliedLoads<NB>,
    const NB: usize,
    const NQ: usize,
    const NV: usize,
    const NC: usize,
> super::TreeSimulation<'_, S, NB, NQ, NV, NC, L>
{
    /// The inverse dynamics' first derivatives at `state` and accelerations
    /// `vdot` into `out` ([`InverseDerivatives`]: `τ`, `∂τ/∂q`, `∂τ/∂v`,
    /// `M`), exact, from the code the derive wrote for the scene
    /// (`#[scene(second_order)]`). Allocation-free.
    ///
    /// The tree's own dynamics: closures, springs and the user's loads are
    /// not in `τ` (as in [`inverse_dynamics`](Self::inverse_dynamics)).
    /// [`TreeError::NotDerived`] where the derive wrote no derivatives (the
    /// scene did not ask, or its tree is past the straight line's limit);
    /// [`TreeError::NonFinite`] for a state that is not finite.
    ///
    /// ```
    /// use joint_runtime::Scene;
    /// use joint_runtime::nalgebra::SVector;
    /// use joint_runtime::tree::{InverseDerivatives, TreeSimulation, TreeState};
    ///
    /// /// A bar of 1 m pinned at its end about y.
    /// #[derive(Scene)]
    /// #[scene(gravity = [0, 0, -9.81], coordinates = relative, second_order)]
    /// #[body(bar, mass = 2.0, inertia = [0.001, 0.1, 0.1])]
    /// #[joint(pin = revolute(ground, bar), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0, 0, 0], rho2 = [-0.5, 0, 0])]
    /// struct Bar;
    ///
    /// let sim = TreeSimulation::new(&Bar)?;
    /// let state = TreeState { q: SVector::from([0.3]), v: SVector::from([1.0]), t: 0.0 };
    /// let mut d = InverseDerivatives::zeros();
    /// sim.inverse_dynamics_derivatives(&state, &SVector::zeros(), &mut d)?;
    /// // τ = (I + m l²) θ̈ − m g l sin θ about y (z up, the bar along x at θ = 0):
    /// // ∂τ/∂θ = −m g l cos θ, ∂τ/∂θ̇ = 0, M = I + m l².
    /// let (m, g, l) = (2.0, 9.81, 0.5);
    /// assert!((d.d_q[(0, 0)] + m * g * l * 0.3f64.cos()).abs() < 1e-12);
    /// assert_eq!(d.d_v[(0, 0)], 0.0);
    /// assert!((d.d_a[(0, 0)] - (0.1 + m * l * l)).abs() < 1e-12);
    /// # Ok::<(), joint_runtime::tree::TreeError>(())
    /// ```
    pub fn inverse_dynamics_derivatives(
        &self,
        state: &TreeState<NQ, NV>,
        vdot: &SVector<f64, NV>,
        out: &mut InverseDerivatives<NV>,
    ) -> Result<(), TreeError> {
        self.derivatives_at(state, vdot, out)?;
        self.mass_matrix_into(&state.q, &mut out.d_a);
        Ok(())
    }

    /// `τ`, `∂τ/∂q`, `∂τ/∂v` into `out` (its `d_a` untouched).
    fn derivatives_at(
        &self,
        state: &TreeState<NQ, NV>,
        vdot: &SVector<f64, NV>,
        out: &mut InverseDerivatives<NV>,
    ) -> Result<(), TreeError> {
        if !(state.q.iter().chain(state.v.iter()).chain(vdot.iter()).all(|x| x.is_finite())) {
            return Err(TreeError::NonFinite);
        }
        let (q, v, a) = (&state.q.data.0[0], &state.v.data.0[0], &vdot.data.0[0]);
        if !self.scene.inverse_dynamics_derivatives_into(self.tree().geometry(), q, v, a, out) {
            return Err(TreeError::NotDerived);
        }
        Ok(())
    }

    /// The forward dynamics' first derivatives at `state` under joint forces
    /// `tau` into `out` ([`ForwardDerivatives`]: `q̈`, `∂q̈/∂q`, `∂q̈/∂v`,
    /// `M⁻¹`), exact: `M⁻¹` by a Cholesky factor of the mass matrix,
    /// `q̈ = M⁻¹ (τ − b(q, v))`, then `∂q̈/∂x = −M⁻¹ ∂τ/∂x` at `v̇ = q̈`.
    /// `work` holds the inverse dynamics' derivatives on the way (the
    /// caller's, so that nothing of the tree's size lives on the stack
    /// twice). Allocation-free.
    ///
    /// The tree's own dynamics (gravity, armature, damping): closures,
    /// springs and the user's loads are left out. Errors as
    /// [`inverse_dynamics_derivatives`](Self::inverse_dynamics_derivatives),
    /// and [`TreeError::Singular`] if the mass matrix is not positive
    /// definite.
    pub fn forward_dynamics_derivatives(
        &self,
        state: &TreeState<NQ, NV>,
        tau: &SVector<f64, NV>,
        work: &mut InverseDerivatives<NV>,
        out: &mut ForwardDerivatives<NV>,
    ) -> Result<(), TreeError> {
        if !S::DERIVATIVES {
            return Err(TreeError::NotDerived);
        }
        let numbers = state.q.iter().chain(state.v.iter()).chain(tau.iter());
        if !numbers.copied().all(f64::is_finite) {
            return Err(TreeError::NonFinite);
        }
        // q̈ = M⁻¹ (τ − b): the factor is wanted anyway, and the bias is one
        // Newton–Euler pass, cheaper than the articulated-body algorithm.
        self.mass_matrix_into(&state.q, &mut work.d_a);
        let joint = self.tree().joints.first().map_or("", |j| j.name);
        spd_inverse(&work.d_a, &mut out.d_tau).ok_or(TreeError::Singular { joint })?;
        let bias = self.inverse_dynamics(state, &SVector::zeros());
        out.d_tau.mul_to(&(tau - bias), &mut out.qdd);
        self.derivatives_at(state, &out.qdd, work)?;
        out.d_tau.mul_to(&work.d_q, &mut out.d_q);
        out.d_tau.mul_to(&work.d_v, &mut out.d_v);
        out.d_q.neg_mut();
        out.d_v.neg_mut();
        if !(out.d_q.iter().chain(out.d_v.iter()).all(|x| x.is_finite())) {
            return Err(TreeError::NonFinite);
        }
        Ok(())
    }
}
