//! The first derivatives of a tree's dynamics, exact: what a controller
//! that linearises its robot every tick (iLQR, DDP, MPC, an extended Kalman
//! filter) calls.
//!
//! Every tree has `∂τ/∂q` and `∂τ/∂v` of its inverse dynamics, two ways
//! with the same numbers: Carpentier and Mansard's recursion in the
//! ground's frame (`recursion.rs`), and, where a scene asks
//! (`#[scene(second_order)]`) and its tree is small, one straight line the
//! derive writes ([`TreeScene::inverse_dynamics_derivatives_into`]: the
//! engine's forward-mode derivative of the generated Newton–Euler
//! algorithm, each column folded to the joints its freedom moves), faster
//! there (the UR5's takes 0.79 of the recursion's time; past 8 000
//! operations the recursion is as fast or faster, and the derive writes
//! none). The forward dynamics' follow (Carpentier and Mansard, RSS 2018):
//! `M q̈ + b(q, v) = τ` gives `∂q̈/∂x = −M⁻¹ ∂τ/∂x` at `v̇ = q̈`, and
//! `∂q̈/∂τ = M⁻¹`.
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

/// Second derivatives of the inverse dynamics contracted with a vector
/// `λ` (one per freedom), at one state: what a DDP backward pass needs.
/// With `s = λᵀ τ(q, v, v̇)`: `d_qq[(i, j)] = ∂/∂q_j (∂s/∂q_i)`,
/// `d_qv[(i, j)] = ∂²s/∂q_i ∂v_j`, `d_vv[(i, j)] = ∂²s/∂v_i ∂v_j`. The
/// `q` directions are the tangent ones of [`InverseDerivatives::d_q`],
/// taken in turn (first `i`, then `j` at the moved point): on the rotation
/// group `d_qq` is not symmetric in general, Pinocchio's convention for
/// its second-order derivatives.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SecondDerivatives<const NV: usize> {
    /// `∂/∂q_j (∂(λᵀτ)/∂q_i)` at `(i, j)`.
    pub d_qq: SMatrix<f64, NV, NV>,
    /// `∂²(λᵀτ)/∂q_i ∂v_j` at `(i, j)`.
    pub d_qv: SMatrix<f64, NV, NV>,
    /// `∂²(λᵀτ)/∂v_i ∂v_j` at `(i, j)` (symmetric).
    pub d_vv: SMatrix<f64, NV, NV>,
}

impl<const NV: usize> SecondDerivatives<NV> {
    /// All zero.
    pub fn zeros() -> Self {
        SecondDerivatives { d_qq: SMatrix::zeros(), d_qv: SMatrix::zeros(), d_vv: SMatrix::zeros() }
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
    /// `M`), exact: the straight line the derive wrote where the scene
    /// asked (`#[scene(second_order)]`) and its tree is small, the runtime's
    /// recursion otherwise (the module). Allocation-free.
    ///
    /// The tree's own dynamics: closures, springs and the user's loads are
    /// not in `τ` (as in [`inverse_dynamics`](Self::inverse_dynamics)).
    /// [`TreeError::NonFinite`] for a state that is not finite.
    ///
    /// ```
    /// use joint_runtime::Scene;
    /// use joint_runtime::nalgebra::SVector;
    /// use joint_runtime::relative::{InverseDerivatives, TreeSimulation, TreeState};
    ///
    /// /// A bar of 1 m pinned at its end about y.
    /// #[derive(Scene)]
    /// #[scene(gravity = [0, 0, -9.81], second_order)]
    /// #[body(bar, mass = 2.0, inertia = [0.001, 0.1, 0.1])]
    /// #[joint(pin = revolute(ground, bar), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0, 0, 0], rho2 = [-0.5, 0, 0])]
    /// struct Bar;
    ///
    /// let sim = TreeSimulation::new(&Bar)?;
    /// let state = TreeState { q: SVector::from([0.3]), v: SVector::from([1.0]), t: 0.0 };
    /// let mut d = InverseDerivatives::zeros();
    /// sim.inverse_dynamics_derivatives(&state, &SVector::zeros(), &mut d)?;
    /// // The centre at height −l sin θ (z up, the bar along x at θ = 0), so
    /// // τ = (I + m l²) θ̈ − m g l cos θ: ∂τ/∂θ = m g l sin θ, ∂τ/∂θ̇ = 0, M = I + m l².
    /// let (m, g, l) = (2.0, 9.81, 0.5);
    /// assert!((d.d_q[(0, 0)] - m * g * l * 0.3f64.sin()).abs() < 1e-12);
    /// assert_eq!(d.d_v[(0, 0)], 0.0);
    /// assert!((d.d_a[(0, 0)] - (0.1 + m * l * l)).abs() < 1e-12);
    /// # Ok::<(), joint_runtime::relative::TreeError>(())
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
    pub(super) fn derivatives_at(
        &self,
        state: &TreeState<NQ, NV>,
        vdot: &SVector<f64, NV>,
        out: &mut InverseDerivatives<NV>,
    ) -> Result<(), TreeError> {
        super::simulation::finite_inputs(state, &[vdot.as_slice()])?;
        if !S::DERIVATIVES {
            self.tree().recursive_derivatives(state, vdot, out);
        } else {
            let (q, v, a) = (&state.q.data.0[0], &state.v.data.0[0], &vdot.data.0[0]);
            if !self.scene.inverse_dynamics_derivatives_into(self.tree().geometry(), q, v, a, out) {
                return Err(TreeError::NotDerived);
            }
        }
        self.tree().subtract_compensation(&state.q, out);
        Ok(())
    }

    /// The inverse dynamics' second derivatives at `state` and
    /// accelerations `vdot`, contracted with `lambda` ([`SecondDerivatives`]),
    /// exact, from the code the derive wrote (`#[scene(second_order)]`, for
    /// trees small enough: [`TreeError::NotDerived`] otherwise).
    /// Allocation-free.
    pub fn inverse_dynamics_second_derivatives(
        &self,
        state: &TreeState<NQ, NV>,
        vdot: &SVector<f64, NV>,
        lambda: &SVector<f64, NV>,
        out: &mut SecondDerivatives<NV>,
    ) -> Result<(), TreeError> {
        super::simulation::finite_inputs(state, &[vdot.as_slice(), lambda.as_slice()])?;
        let (q, v, a, l) = (&state.q.data.0[0], &state.v.data.0[0], &vdot.data.0[0], &lambda.data.0[0]);
        if !self.scene.inverse_dynamics_second_derivatives_into(self.tree().geometry(), q, v, a, l, out) {
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
    /// The derivatives of [`forward_dynamics`](Self::forward_dynamics):
    /// the tree's own dynamics (gravity, armature, damping) and, with
    /// closures (loops, couplings, contacts, every one holding), the
    /// constrained accelerations, Baumgarte's terms included
    /// ([`constrained_dynamics_derivatives`](Self::constrained_dynamics_derivatives),
    /// which also gives the forces and takes an active set). Errors as
    /// [`inverse_dynamics_derivatives`](Self::inverse_dynamics_derivatives);
    /// [`TreeError::NotDerived`] where the derive did not write the
    /// closures' second-order terms, [`TreeError::Loaded`] with
    /// springs or user loads, [`TreeError::Singular`] if the mass matrix is
    /// not positive definite.
    pub fn forward_dynamics_derivatives(
        &self,
        state: &TreeState<NQ, NV>,
        tau: &SVector<f64, NV>,
        work: &mut InverseDerivatives<NV>,
        out: &mut ForwardDerivatives<NV>,
    ) -> Result<(), TreeError> {
        super::simulation::finite_inputs(state, &[tau.as_slice()])?;
        if NC > 0 {
            return self.coupled(state, tau, work, out);
        }
        // q̈ = M⁻¹ (τ − b): the factor is wanted anyway, and the bias is one
        // Newton–Euler pass, cheaper than the articulated-body algorithm.
        self.mass_matrix_into(&state.q, &mut work.d_a);
        let joint = self.tree().joints.first().map_or("", |j| j.name);
        spd_inverse(&work.d_a, &mut out.d_tau).ok_or(TreeError::Singular { joint })?;
        let bias = self.inverse_dynamics(state, &SVector::zeros());
        out.d_tau.mul_to(&(tau - bias), &mut out.qdd);
        if self.loaded() {
            return Err(TreeError::Loaded);
        }
        self.derivatives_at(state, &out.qdd, work)?;
        out.d_tau.mul_to(&work.d_q, &mut out.d_q);
        out.d_tau.mul_to(&work.d_v, &mut out.d_v);
        out.d_q.neg_mut();
        out.d_v.neg_mut();
        if !(crate::linalg::finite(out.d_q.as_slice()) && crate::linalg::finite(out.d_v.as_slice())) {
            return Err(TreeError::NonFinite);
        }
        Ok(())
    }

    /// The constrained accelerations' derivatives, every closure row
    /// holding: [`constrained_dynamics_derivatives`](Self::constrained_dynamics_derivatives)
    /// with [`ActiveRows::all`](super::ActiveRows::all), its `λ` left out.
    fn coupled(
        &self,
        state: &TreeState<NQ, NV>,
        tau: &SVector<f64, NV>,
        work: &mut InverseDerivatives<NV>,
        out: &mut ForwardDerivatives<NV>,
    ) -> Result<(), TreeError> {
        let mut all = super::ConstrainedDerivatives::zeros();
        self.constrained_dynamics_derivatives(state, tau, super::ActiveRows::all(), work, &mut all)?;
        *out = ForwardDerivatives { qdd: all.qdd, d_q: all.d_q, d_v: all.d_v, d_tau: all.d_tau };
        Ok(())
    }
}
