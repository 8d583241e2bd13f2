//! Constrained dynamics on a tree: `q̈` and the closures' and contacts' forces
//! `λ` for the rows active at this call, and their exact derivatives, what a
//! legged robot's MPC calls at every node (Crocoddyl's contact dynamics).
//!
//! `M q̈ + b(q, v) = τ + Jᵀλ` and `J q̈ = γ̃` on the active rows
//! ([`ActiveRows`]: a mask over the closures' blocks, chosen per call, no
//! rebuild), with `γ̃` Baumgarte's when the simulation's options ask
//! (`γ − 2α (J v + Φ_t) − β² Φ`; a contact has no `Φ`). The solve is the
//! range-space one: `M` factorised, `Y = M⁻¹ Jᵀ`, the Delassus matrix
//! `S = J Y` factorised with pivots (rows that depend on others to the
//! options' rank tolerance dropped, so a planar loop closed by a point, or
//! redundant contacts, keep an exact `q̈` and give the dropped rows no force);
//! an inactive row gets the identity in `S` and no force. Where the tree
//! branches (a floating base with legs) `M = Lᵀ D L` along the tree
//! (Featherstone's LTDL, `factor.rs`): no fill-in, and `J`'s rows go through
//! `L⁻ᵀ` all at once as contiguous `axpy`s; on a chain, where the factor has
//! no zeros to skip, a dense `M⁻¹` is faster (measured on the kit's cases,
//! see the guide's "Contacts and closed loops"). Decision: a range-space
//! solve rather than a constrained articulated-body pass, because the
//! derivatives need `M⁻¹` and `S⁻¹` anyway, where that pass gives `q̈` alone.
//!
//! The derivatives differentiate the KKT system itself. With `F = ID(q, v,
//! q̈) − τ − Jᵀλ = 0` and `G = J q̈ − γ̃ = 0`, for each input `x`:
//! `M dq̈ − Jᵀ dλ = K dq − ∂ID/∂x + ∂τ/∂x` (`K = ∂(Jᵀλ)/∂q`) and
//! `J dq̈ = ∂γ̃/∂x − ∂(J q̈)/∂x`. So with `P = M⁻¹ − Y S⁻¹ Yᵀ` and
//! `C = Y S⁻¹`: `dq̈ = P r₁ + C r₂`, `dλ = S⁻¹ (r₂ − Yᵀ r₁)`. The second-order
//! terms `K`, `∂(J u)/∂q`, `∂γ/∂q`, `∂γ/∂v` are the derive's
//! ([`TreeScene::closure_second_order`]), the inverse dynamics' derivatives
//! the tree's own: nothing is differenced. `∂/∂q` is in the tangent space
//! (the tree's [`displace`](super::TreeSimulation::displace)), as every
//! other derivative of the tree.

use nalgebra::{SMatrix, SVector};

use super::factor::{FreedomTree, MassFactor};
use super::simulation::finite_inputs;
use super::soft::SoftTerms;
use super::{InverseDerivatives, StepJacobian, TreeError, TreeScene, TreeSimulation, TreeState};
use crate::SecondOrder;
use crate::dynamics::Stabilisation;
use crate::linalg::{PivotedCholesky, finite, gemm};

/// Which of a scene's closure blocks hold at this call: bit `b` is block
/// `b` of [`TreeScene::CLOSURES`] (a loop's joint, a file's coupling, a
/// `#[contact]`). Up to 64 blocks.
///
/// ```
/// use joint_runtime::relative::ActiveRows;
///
/// let trot = ActiveRows::none().with(0).with(3);
/// assert!(trot.holds(3) && !trot.holds(1));
/// assert_eq!(trot.without(3), ActiveRows::none().with(0));
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ActiveRows(pub u64);

impl ActiveRows {
    /// Every block.
    pub const fn all() -> Self {
        ActiveRows(u64::MAX)
    }

    /// No block: the tree's own dynamics.
    pub const fn none() -> Self {
        ActiveRows(0)
    }

    /// These blocks and block `block` too.
    pub const fn with(self, block: usize) -> Self {
        if block < 64 { ActiveRows(self.0 | 1 << block) } else { self }
    }

    /// These blocks but block `block`.
    pub const fn without(self, block: usize) -> Self {
        if block < 64 { ActiveRows(self.0 & !(1 << block)) } else { self }
    }

    /// The blocks named `names` among `blocks` (a scene's `CLOSURES`), `None`
    /// if one is not there.
    pub fn named(blocks: &[crate::RowBlock], names: &[&str]) -> Option<Self> {
        let mut out = ActiveRows::none();
        for name in names {
            out = out.with(blocks.iter().position(|b| b.name == *name)?);
        }
        Some(out)
    }

    /// Whether block `block` holds.
    pub const fn holds(self, block: usize) -> bool {
        block < 64 && self.0 & (1 << block) != 0
    }

    /// Row `r`'s mask over `blocks`: whether it holds.
    fn row_mask<const NC: usize>(self, blocks: &[crate::RowBlock]) -> [bool; NC] {
        let mut out = [false; NC];
        for (b, block) in blocks.iter().enumerate() {
            if self.holds(b) {
                for r in block.start..block.start + block.rows {
                    if let Some(x) = out.get_mut(r) {
                        *x = true;
                    }
                }
            }
        }
        out
    }
}

/// The constrained dynamics at one state: `q̈` and the rows' forces `λ` (zero
/// on inactive and dropped rows), and their first derivatives, `∂/∂q` in
/// tangent columns.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ConstrainedDerivatives<const NV: usize, const NC: usize> {
    /// `q̈`.
    pub qdd: SVector<f64, NV>,
    /// `λ`, in the closures' row order: a point contact's force on its first
    /// end, a frame's wrench `[force; torque]` about its point, in the
    /// contact's axes; a joint's row forces.
    pub lambda: SVector<f64, NC>,
    /// `∂q̈/∂q`.
    pub d_q: SMatrix<f64, NV, NV>,
    /// `∂q̈/∂v`.
    pub d_v: SMatrix<f64, NV, NV>,
    /// `∂q̈/∂τ`.
    pub d_tau: SMatrix<f64, NV, NV>,
    /// `∂λ/∂q`.
    pub lambda_q: SMatrix<f64, NC, NV>,
    /// `∂λ/∂v`.
    pub lambda_v: SMatrix<f64, NC, NV>,
    /// `∂λ/∂τ`.
    pub lambda_tau: SMatrix<f64, NC, NV>,
    /// How many rows held (active and not dropped as dependent).
    pub rank: usize,
}

impl<const NV: usize, const NC: usize> ConstrainedDerivatives<NV, NC> {
    /// All zero.
    pub fn zeros() -> Self {
        ConstrainedDerivatives {
            qdd: SVector::zeros(),
            lambda: SVector::zeros(),
            d_q: SMatrix::zeros(),
            d_v: SMatrix::zeros(),
            d_tau: SMatrix::zeros(),
            lambda_q: SMatrix::zeros(),
            lambda_v: SMatrix::zeros(),
            lambda_tau: SMatrix::zeros(),
            rank: 0,
        }
    }
}

/// The solve's pieces that the derivatives reuse.
pub(super) struct Kkt<'a, const NV: usize, const NC: usize> {
    /// `J` with inactive rows zero.
    pub(super) jacobian: SMatrix<f64, NC, NV>,
    /// `Y = M⁻¹ Jᵀ` (zero unless [`with_y`](Self::with_y)).
    pub(super) y: SMatrix<f64, NV, NC>,
    /// Whether the solve fills `y`: the derivatives and impacts read it,
    /// the forward dynamics need only `Y λ` (one solve, where `Y` is `NC`).
    pub(super) with_y: bool,
    /// `S = J Y` (inactive rows: a pivot of their own).
    pub(super) delassus: SMatrix<f64, NC, NC>,
    /// `S`, pivoted.
    pub(super) factor: PivotedCholesky<NC>,
    /// `M`, factorised.
    pub(super) mass: MassFactor<'a, NV>,
    /// Which rows hold.
    pub(super) mask: [bool; NC],
    /// `Φ` at the state (what the soft rows' derivatives read).
    pub(super) phi: SVector<f64, NC>,
    /// The soft rows' `R` and `a_ref` (`None` without soft rows).
    pub(super) soft: Option<SoftTerms<NC>>,
}

impl<'a, const NV: usize, const NC: usize> Kkt<'a, NV, NC> {
    /// Room for the solve over `tree`'s freedoms, filled in place by
    /// `TreeSimulation::delassus` (a few kilobytes: built where they stay,
    /// not returned through the calls).
    pub(super) fn new(tree: &'a FreedomTree<NV>) -> Self {
        Kkt {
            jacobian: SMatrix::zeros(),
            y: SMatrix::zeros(),
            with_y: true,
            delassus: SMatrix::zeros(),
            factor: PivotedCholesky::empty(),
            mass: MassFactor::new(tree),
            mask: [false; NC],
            phi: SVector::zeros(),
            soft: None,
        }
    }

    /// Room for the forward dynamics alone: `y` is not filled where the
    /// tree has more freedoms than rows (a floating robot on its feet: the
    /// one solve for `M⁻¹ Jᵀ λ` costs less than `Y`'s `NC` columns; on a
    /// four-bar's three freedoms and three rows `Y` is the cheaper, 0.36
    /// against 0.43 µs).
    pub(super) fn forward(tree: &'a FreedomTree<NV>) -> Self {
        let mut kkt = Kkt::new(tree);
        kkt.with_y = NC >= NV;
        kkt
    }

    /// `M⁻¹ Jᵀ λ`: `Y λ`, or one solve where `Y` was not filled.
    pub(super) fn velocity_jump(&self, lambda: &SVector<f64, NC>) -> SVector<f64, NV> {
        match self.with_y {
            true => self.y * lambda,
            false => self.mass.solve(&(self.jacobian.transpose() * lambda)),
        }
    }

    /// The rows that hold and were kept (inactive rows are pivots of their own).
    pub(super) fn rank(&self) -> usize {
        let inactive = self.mask.iter().filter(|on| !**on).count();
        self.factor.rank().saturating_sub(inactive)
    }
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
    /// `q̈` and `λ` at `state` under joint forces `tau` with the rows of
    /// `active` holding, into `out.qdd` and `out.lambda` (the derivatives
    /// untouched). The tree's own
    /// dynamics: [`TreeError::Loaded`] with springs or user loads.
    /// Allocation-free.
    ///
    /// ```
    /// use joint_runtime::Scene;
    /// use joint_runtime::nalgebra::SVector;
    /// use joint_runtime::relative::{ActiveRows, ConstrainedDerivatives, TreeSimulation, TreeState};
    ///
    /// /// A bar pinned at one end about y, its other end held by a point contact.
    /// #[derive(Scene)]
    /// #[scene(gravity = [0, 0, -9.81])]
    /// #[body(bar, mass = 2.0, inertia = [0.001, 0.1, 0.1])]
    /// #[joint(pin = revolute(ground, bar), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0, 0, 0], rho2 = [-0.5, 0, 0])]
    /// #[contact(tip = point(bar), at = [0.5, 0, 0])]
    /// struct Propped;
    ///
    /// let sim = TreeSimulation::new(&Propped)?;
    /// let state = TreeState { q: SVector::from([0.0]), v: SVector::from([0.0]), t: 0.0 };
    /// let mut out = ConstrainedDerivatives::zeros();
    /// sim.constrained_dynamics(&state, &SVector::zeros(), ActiveRows::all(), &mut out)?;
    /// // Held at both ends, the bar stays: the tip carries half its weight, upwards.
    /// assert!(out.qdd[0].abs() < 1e-12);
    /// assert!((out.lambda[2] - 9.81).abs() < 1e-12);
    /// # Ok::<(), joint_runtime::relative::TreeError>(())
    /// ```
    pub fn constrained_dynamics(
        &self,
        state: &TreeState<NQ, NV>,
        tau: &SVector<f64, NV>,
        active: ActiveRows,
        out: &mut ConstrainedDerivatives<NV, NC>,
    ) -> Result<(), TreeError> {
        let mut kkt = Kkt::forward(&self.tree().freedoms);
        self.solve_kkt(state, tau, active, out, &mut kkt)
    }

    /// The constrained dynamics and their exact first derivatives at
    /// `state`, `tau`, `active` into `out` (the module's method); `work`
    /// holds the inverse dynamics' derivatives on the way. Errors as
    /// [`constrained_dynamics`](Self::constrained_dynamics), and
    /// [`TreeError::NotDerived`] where the derive did not write the
    /// closures' second-order terms (past its operation limit).
    /// Allocation-free.
    pub fn constrained_dynamics_derivatives(
        &self,
        state: &TreeState<NQ, NV>,
        tau: &SVector<f64, NV>,
        active: ActiveRows,
        work: &mut InverseDerivatives<NV>,
        out: &mut ConstrainedDerivatives<NV, NC>,
    ) -> Result<(), TreeError> {
        let mut kkt = Kkt::new(&self.tree().freedoms);
        self.solve_kkt(state, tau, active, out, &mut kkt)?;
        let (alpha, beta) = self.gains();
        self.derivatives_at(state, &out.qdd, work)?;
        let u = out.qdd + state.v * (2.0 * alpha);
        let second = self.second_order_at(state, &out.lambda, &u)?;
        // r₁ = K − ∂ID/∂q (q), −∂ID/∂v (v), I (τ); r₂ on the active rows.
        let mut r1_q = second.stiffness;
        r1_q -= &work.d_q;
        let mut r2_q = second.gamma_q - second.jacobian_q - second.phi_t_q * (2.0 * alpha);
        let mut r2_v = second.gamma_v - kkt.jacobian * (2.0 * alpha);
        if beta != 0.0 {
            // −β² ∂Φ/∂q = −β² J on a loop's rows; a contact has no Φ.
            let positioned = Self::POSITIONED;
            for r in (0..NC).filter(|&r| positioned[r]) {
                let row = kkt.jacobian.row(r) * (beta * beta);
                let mut target = r2_q.row_mut(r);
                target -= row;
            }
        }
        if let Some(terms) = &kkt.soft {
            // MuJoCo's rows: a_ref through J v, R and a_ref through imp(Φ).
            let jv_q = self.second_order_at(state, &SVector::zeros(), &state.v)?.jacobian_q;
            let at = (&kkt.phi, &kkt.jacobian);
            self.soft.derivative_rows(terms, at, &out.lambda, (&second, &jv_q, alpha), &mut r2_q, &mut r2_v);
        }
        mask_rows(&kkt.mask, &mut r2_q);
        mask_rows(&kkt.mask, &mut r2_v);
        // S⁻¹ once (its pseudo-inverse over the kept rows), then products:
        // Cᵀ = S⁻¹ Yᵀ, dλ = S⁻¹ r₂ − Cᵀ r₁, dq̈ = M⁻¹ r₁ + Y dλ.
        // In place, no temporaries: the products are most of this tail.
        let mut minv = SMatrix::<f64, NV, NV>::zeros();
        kkt.mass.inverse_into(&mut minv);
        let sinv = kkt.factor.inverse();
        let mut ct = SMatrix::<f64, NC, NV>::zeros();
        gemm(&mut ct, 1.0, &sinv, &kkt.y.transpose(), 0.0);
        gemm(&mut out.lambda_q, 1.0, &sinv, &r2_q, 0.0);
        gemm(&mut out.lambda_q, -1.0, &ct, &r1_q, 1.0);
        gemm(&mut out.d_q, 1.0, &minv, &r1_q, 0.0);
        gemm(&mut out.d_q, 1.0, &kkt.y, &out.lambda_q, 1.0);
        gemm(&mut out.lambda_v, 1.0, &sinv, &r2_v, 0.0);
        gemm(&mut out.lambda_v, 1.0, &ct, &work.d_v, 1.0);
        gemm(&mut out.d_v, -1.0, &minv, &work.d_v, 0.0);
        gemm(&mut out.d_v, 1.0, &kkt.y, &out.lambda_v, 1.0);
        out.lambda_tau = -ct;
        out.d_tau = minv;
        gemm(&mut out.d_tau, -1.0, &kkt.y, &ct, 1.0);
        let all = [out.d_q.as_slice(), out.d_v.as_slice(), out.lambda_q.as_slice(), out.lambda_v.as_slice()];
        if !all.iter().all(|m| finite(m)) {
            return Err(TreeError::NonFinite);
        }
        Ok(())
    }

    /// One semi-implicit Euler step under the constrained dynamics with the
    /// rows of `active` holding — `v₁ = v + h q̈(q, v, τ)`, `q₁ = q ⊕ h v₁`,
    /// as [`euler_step_jacobian`](Self::euler_step_jacobian) takes it and
    /// as Crocoddyl integrates contact dynamics — and its exact Jacobian
    /// into `out`; `dynamics` holds `q̈`, `λ` and their derivatives at the
    /// step's start (what a contact MPC's node needs besides: the forces
    /// for friction cones). No projection: the rows hold at the
    /// acceleration level (with the options' Baumgarte gains), as in a
    /// shooting node. Errors as
    /// [`constrained_dynamics_derivatives`](Self::constrained_dynamics_derivatives),
    /// and [`TreeError::NonFinite`] for an `h` that is not finite; on error
    /// `state` is unchanged. Allocation-free.
    ///
    /// ```
    /// use joint_runtime::Scene;
    /// use joint_runtime::nalgebra::SVector;
    /// use joint_runtime::relative::{
    ///     ActiveRows, ConstrainedDerivatives, InverseDerivatives, StepJacobian, TreeSimulation, TreeState,
    /// };
    ///
    /// /// A bar pinned at one end about y, its other end on a point contact.
    /// #[derive(Scene)]
    /// #[scene(gravity = [0, 0, -9.81])]
    /// #[body(bar, mass = 2.0, inertia = [0.001, 0.1, 0.1])]
    /// #[joint(pin = revolute(ground, bar), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0, 0, 0], rho2 = [-0.5, 0, 0])]
    /// #[contact(tip = point(bar), at = [0.5, 0, 0])]
    /// struct Propped;
    ///
    /// let sim = TreeSimulation::new(&Propped)?;
    /// let mut state = TreeState { q: SVector::from([0.0]), v: SVector::from([0.0]), t: 0.0 };
    /// let (mut work, mut dynamics) = (InverseDerivatives::zeros(), ConstrainedDerivatives::zeros());
    /// let mut jacobian = StepJacobian::zeros();
    /// let tau = SVector::from([1.0]);
    /// sim.constrained_euler_step_jacobian(&mut state, 0.01, &tau, ActiveRows::all(), &mut work, &mut dynamics, &mut jacobian)?;
    /// // Held, the bar does not answer a torque; the contact takes it (1 N·m over 1 m).
    /// assert!(jacobian.v_tau[(0, 0)].abs() < 1e-12 && state.v[0].abs() < 1e-12);
    /// assert!((dynamics.lambda_tau[(2, 0)] - 1.0).abs() < 1e-12);
    /// # Ok::<(), joint_runtime::relative::TreeError>(())
    /// ```
    #[allow(clippy::too_many_arguments)]
    pub fn constrained_euler_step_jacobian(
        &self,
        state: &mut TreeState<NQ, NV>,
        h: f64,
        tau: &SVector<f64, NV>,
        active: ActiveRows,
        work: &mut InverseDerivatives<NV>,
        dynamics: &mut ConstrainedDerivatives<NV, NC>,
        out: &mut StepJacobian<NV>,
    ) -> Result<(), TreeError> {
        if !h.is_finite() {
            return Err(TreeError::NonFinite);
        }
        self.constrained_dynamics_derivatives(state, tau, active, work, dynamics)?;
        let d = &*dynamics;
        self.euler_chain(state, h, (&d.qdd, &d.d_q, &d.d_v, &d.d_tau), out)
    }

    /// `∂(J v + Φ_t)/∂q` at `state`: how the rows' velocity moves with the
    /// coordinates (what a linearisation's reduction to the loops' own
    /// coordinates takes).
    // The linearisation's alone, which needs `alloc`: without it, unused.
    #[cfg(feature = "alloc")]
    pub(super) fn closure_rate_q(&self, state: &TreeState<NQ, NV>) -> Result<SMatrix<f64, NC, NV>, TreeError> {
        let second = self.second_order_at(state, &SVector::zeros(), &state.v)?;
        Ok(second.jacobian_q + second.phi_t_q)
    }

    /// Baumgarte's `(α, β)`, zero without stabilisation.
    fn gains(&self) -> (f64, f64) {
        match self.options().stabilisation {
            Stabilisation::None => (0.0, 0.0),
            Stabilisation::Baumgarte { alpha, beta } => (alpha, beta),
        }
    }

    /// The closures' second-order terms: the derive's, or zero for rows
    /// linear in the coordinates (a file's couplings) past its limit.
    pub(super) fn second_order_at(
        &self,
        state: &TreeState<NQ, NV>,
        lambda: &SVector<f64, NC>,
        u: &SVector<f64, NV>,
    ) -> Result<SecondOrder<f64, NC, NV>, TreeError> {
        if let Some(second) = self.scene.closure_second_order(state, &self.tree().geometry, lambda, u) {
            return Ok(second);
        }
        if !S::LINEAR_CLOSURES {
            return Err(TreeError::NotDerived);
        }
        Ok(SecondOrder {
            stiffness: SMatrix::zeros(),
            jacobian_q: SMatrix::zeros(),
            gamma_q: SMatrix::zeros(),
            gamma_v: SMatrix::zeros(),
            phi_t_q: SMatrix::zeros(),
        })
    }

    /// `q̈` and `λ`, and the factors the derivatives reuse.
    #[inline(always)]
    fn solve_kkt(
        &self,
        state: &TreeState<NQ, NV>,
        tau: &SVector<f64, NV>,
        active: ActiveRows,
        out: &mut ConstrainedDerivatives<NV, NC>,
        kkt: &mut Kkt<'_, NV, NC>,
    ) -> Result<(), TreeError> {
        let (free, r) = self.kkt_system(state, tau, active, kkt)?;
        out.lambda = kkt.factor.solve(&r);
        out.qdd = free + kkt.velocity_jump(&out.lambda);
        out.rank = kkt.rank();
        if !out.qdd.iter().chain(out.lambda.iter()).all(|x| x.is_finite()) {
            return Err(TreeError::NonFinite);
        }
        Ok(())
    }

    /// The KKT system at `state` into `kkt`, and the tree's own `q̈` and
    /// the right side `S λ = γ̃ − J q̈_free` (zero on inactive rows).
    #[inline(always)]
    pub(super) fn kkt_system(
        &self,
        state: &TreeState<NQ, NV>,
        tau: &SVector<f64, NV>,
        active: ActiveRows,
        kkt: &mut Kkt<'_, NV, NC>,
    ) -> Result<(SVector<f64, NV>, SVector<f64, NC>), TreeError> {
        finite_inputs(state, &[tau.as_slice()])?;
        if self.loaded() {
            return Err(TreeError::Loaded);
        }
        let bias = self.inverse_dynamics(state, &SVector::zeros());
        let rows = self.closure_rows(state);
        let (alpha, beta) = self.gains();
        let mut gamma = rows.gamma - (rows.jacobian * state.v + rows.phi_t) * (2.0 * alpha) - rows.phi * (beta * beta);
        kkt.phi = rows.phi;
        kkt.soft = self.soft.any().then(|| self.soft.terms::<S, NB, NQ, NV>(&rows, &state.v));
        if let Some(terms) = &kkt.soft {
            self.soft.target(terms, &mut gamma);
        }
        self.delassus(state, &rows.jacobian, active, kkt)?;
        let free = kkt.mass.solve(&(tau - bias));
        let gamma = SVector::<f64, NC>::from_fn(|r, _| if kkt.mask[r] { gamma[r] } else { 0.0 });
        let r = gamma - kkt.jacobian * free;
        Ok((free, r))
    }

    /// `M` factorised (along the tree where it branches, dense on a chain)
    /// and the Delassus matrix `S = J M⁻¹ Jᵀ` of the active rows of
    /// `jacobian` factorised (an inactive row: zero in `J`, the identity in
    /// `S`), into `kkt`; the soft rows' `R` (`kkt.soft`) on its diagonal.
    #[inline(always)]
    pub(super) fn delassus(
        &self,
        state: &TreeState<NQ, NV>,
        jacobian: &SMatrix<f64, NC, NV>,
        active: ActiveRows,
        kkt: &mut Kkt<'_, NV, NC>,
    ) -> Result<(), TreeError> {
        let mut m = SMatrix::<f64, NV, NV>::zeros();
        self.mass_matrix_into(&state.q, &mut m);
        let singular = TreeError::Singular { joint: self.tree().joints.first().map_or("", |j| j.name) };
        kkt.mass.factorise(&m).ok_or(singular)?;
        kkt.mask = active.row_mask::<NC>(S::CLOSURES);
        kkt.jacobian = *jacobian;
        mask_rows(&kkt.mask, &mut kkt.jacobian);
        kkt.mass.delassus_into(&kkt.jacobian, kkt.with_y.then_some(&mut kkt.y), &mut kkt.delassus);
        let mask = &kkt.mask;
        let largest = (0..NC).filter(|&r| mask[r]).map(|r| kkt.delassus[(r, r)]).fold(0.0, f64::max);
        let largest = if largest > 0.0 { largest } else { 1.0 };
        for (r, &on) in mask.iter().enumerate() {
            if !on && r < NC {
                kkt.delassus[(r, r)] = largest;
            }
        }
        if let Some(terms) = &kkt.soft {
            for (r, x) in terms.regularisation.iter().enumerate().filter(|&(r, _)| mask[r]) {
                kkt.delassus[(r, r)] += x;
            }
        }
        kkt.factor =
            PivotedCholesky::new(&kkt.delassus, self.options().rank_tolerance).map_err(|_| TreeError::NonFinite)?;
        Ok(())
    }
}

/// Rows that do not hold set to zero (their forces and equations drop out).
pub(super) fn mask_rows<const NC: usize, const C: usize>(mask: &[bool; NC], m: &mut SMatrix<f64, NC, C>) {
    for (r, &on) in mask.iter().enumerate() {
        if !on {
            m.row_mut(r).fill(0.0);
        }
    }
}
