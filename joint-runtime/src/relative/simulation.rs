//! Stepping a tree: classical RK4 on `(q, v)`, each spherical joint's
//! quaternion integrated as four numbers (`ṗ = ½ p ⊗ (0, ω')`, fourth order)
//! and renormalised after the step. With closures (loops), each stage solves
//! `M v̇ + b = τ + Jᵀλ`, `J v̇ = γ` on the closure rows, and the step ends
//! with the mass-metric projection of `q` onto `Φ = 0` and of `v` onto
//! `J v + Φ_t = 0`, as the absolute `Simulation` does.

use core::cell::Cell;

use nalgebra::{Quaternion, SMatrix, SVector, UnitQuaternion, Vector3, Vector6};

use super::implicit_rules::{AlphaMemory, KeptMatrix};
use super::radau::TreeRadauHistory;
use super::soft::Softness;
use super::tangent::{get, put_quaternion, put_three, quaternion_at, set, three, unit_at};
use super::topology::{Tree, TreeError};
use super::{TreeJointKind, TreeScene, TreeState};
use crate::SystemState;
use crate::dynamics::adaptive::{A, AdaptiveSteps, C, E, StepError, Timed, integrate};
use crate::dynamics::{
    Adaptive, AppliedLoads, Attachment, Energy, IntegrationReport, Integrator, Loads, NoLoads, SimulationOptions,
    SpringDamper, Stabilisation, StepReport, Tolerance,
};
use crate::linalg::PivotedCholesky;

/// Newton iterations of [`TreeSimulation::assemble`].
const ASSEMBLY_ITERATIONS: usize = 50;

/// The tolerance on the largest closure row a projection ends below, its
/// Newton iterations, and the round-off floor it accepts (`1e3 ×` the
/// tolerance, as the absolute `Simulation`'s).
pub(super) type Projection = (f64, usize, f64);

/// The constrained accelerations `v̇`, the rows' forces `λ` and the pivot
/// order of their factor (none without rows).
pub(super) type Constrained<const NV: usize, const NC: usize> =
    (SVector<f64, NV>, SVector<f64, NC>, Option<PivotedCholesky<NC>>);

/// What closing the loops did: Newton iterations, `‖Φ‖₂` and
/// `‖J v + Φ_t‖₂` at the end.
pub(super) type Closed = (usize, f64, f64);

/// The simulation of a relative-coordinate scene: the scene (its generated
/// articulated-body algorithm and closure rows, where the derive wrote them)
/// and its tree, checked once; user loads `L` (the absolute
/// [`Simulation`](crate::dynamics::Simulation)'s [`AppliedLoads`]: forces
/// and torques on the bodies, from the bodies' state) and springs.
#[derive(Clone, Debug)]
pub struct TreeSimulation<'a, S, const NB: usize, const NQ: usize, const NV: usize, const NC: usize = 0, L = NoLoads> {
    pub(super) scene: &'a S,
    tree: Tree<NB, NQ, NV>,
    /// Spring-dampers between body points (their forces as joint forces).
    springs: &'a [SpringDamper],
    /// The user's loads, called with the bodies' state at every evaluation.
    loads: L,
    /// The integrator (RK4), stabilisation, projection and rank tolerance.
    options: SimulationOptions,
    /// The state the last step ended at (projected): a start that is not
    /// must have its loops closed.
    last: Cell<Option<TreeState<NQ, NV>>>,
    /// The scene's soft rows (a file's equalities as MuJoCo holds them),
    /// fixed at the reference configuration.
    pub(super) soft: Softness<NC>,
    /// The implicit rules' last Newton matrix, factorised, and the step
    /// length it was built for: the next step of that length starts from
    /// it (`implicit_rules.rs`).
    pub(super) newton: Option<(f64, KeptMatrix<NV, NC>)>,
    /// What generalised-α's last step carries to the next.
    pub(super) alpha: Option<AlphaMemory<NQ, NV, NC>>,
    /// What Radau IIA's last step carries to the next: its stages and
    /// Jacobian (`radau.rs`).
    pub(super) radau: Option<TreeRadauHistory<NQ, NV>>,
}

/// `M⁻¹ Jᵀ` and the rank-revealing factor of `J M⁻¹ Jᵀ` at one state: its
/// dropped rows are the redundant closure rows.
pub(super) struct Saddle<const NV: usize, const NC: usize> {
    pub(super) minv_jt: SMatrix<f64, NV, NC>,
    pub(super) factor: PivotedCholesky<NC>,
}

impl<const NV: usize, const NC: usize> Saddle<NV, NC> {
    /// `M⁻¹ Jᵀ (J M⁻¹ Jᵀ)⁺ r`: the mass-metric correction for the rows' residual `r`.
    pub(super) fn correction(&self, r: &SVector<f64, NC>) -> SVector<f64, NV> {
        self.minv_jt * self.factor.solve(r)
    }
}

impl<'a, S: TreeScene<NB, NQ, NV, NC>, const NB: usize, const NQ: usize, const NV: usize, const NC: usize>
    TreeSimulation<'a, S, NB, NQ, NV, NC>
{
    /// The simulation of `scene`; refused when its tree is not valid
    /// ([`TreeError`]: inertias, axes, order).
    pub fn new(scene: &'a S) -> Result<Self, TreeError> {
        let options = SimulationOptions::default();
        let last = Cell::new(None);
        let tree = Tree::of(scene)?;
        let soft = Softness::new::<S, NB, NQ, NV>(&tree)?;
        Ok(TreeSimulation {
            scene,
            tree,
            springs: &[],
            loads: NoLoads,
            options,
            last,
            soft,
            newton: None,
            alpha: None,
            radau: None,
        })
    }
}

impl<
    'a,
    S: TreeScene<NB, NQ, NV, NC>,
    L: AppliedLoads<NB>,
    const NB: usize,
    const NQ: usize,
    const NV: usize,
    const NC: usize,
> TreeSimulation<'a, S, NB, NQ, NV, NC, L>
{
    /// The same simulation with the user's `loads` acting: the absolute
    /// `Simulation`'s [`AppliedLoads`] (a closure `FnMut(&SystemState,
    /// &mut Loads)` will do), called with the bodies' state at every
    /// evaluation; each body's force and torque enter as the joint forces
    /// `Jᵀ [A τ'; f]` of its centre of mass (its wrench carried to the root). The
    /// same closure drives both coordinate choices of a scene.
    pub fn with_loads<L2: AppliedLoads<NB>>(self, loads: L2) -> TreeSimulation<'a, S, NB, NQ, NV, NC, L2> {
        let TreeSimulation { scene, tree, springs, options, last, soft, .. } = self;
        TreeSimulation { scene, tree, springs, loads, options, last, soft, newton: None, alpha: None, radau: None }
    }

    /// The same simulation with `options` (the absolute `Simulation`'s):
    /// the integrator ([`Integrator::Rk4`], [`Integrator::ImplicitMidpoint`],
    /// [`Integrator::GeneralisedAlpha`] with its spectral radius, or
    /// [`Integrator::RadauIIA`]; the implicit ones with their Newton
    /// options: `implicit_rules.rs`, `radau.rs`),
    /// `stabilisation` (Baumgarte on the closure rows),
    /// `projection` (`None`: the loops are not projected after a step; the
    /// tolerance bounds the largest closure row) and `rank_tolerance` (the
    /// redundant closure rows) are honoured.
    ///
    /// # Errors
    /// [`TreeError::BadOption`] naming the option: a non-finite or negative
    /// Baumgarte coefficient, a projection, rank or Newton tolerance that
    /// is not positive and finite, no Newton iterations, a spectral radius
    /// outside `[0, 1]`.
    pub fn with_options(mut self, options: SimulationOptions) -> Result<Self, TreeError> {
        let positive = |x: f64| x.is_finite() && x > 0.0;
        if !positive(options.newton_tolerance) || options.newton_max_iterations == 0 {
            return Err(TreeError::BadOption { name: "newton_tolerance" });
        }
        if !(0.0..=1.0).contains(&options.spectral_radius) {
            return Err(TreeError::BadOption { name: "spectral_radius" });
        }
        if let Stabilisation::Baumgarte { alpha, beta } = options.stabilisation
            && !(alpha.is_finite() && beta.is_finite() && alpha >= 0.0 && beta >= 0.0)
        {
            return Err(TreeError::BadOption { name: "stabilisation" });
        }
        if options.projection.is_some_and(|p| !positive(p.tolerance)) {
            return Err(TreeError::BadOption { name: "projection" });
        }
        if !positive(options.rank_tolerance) {
            return Err(TreeError::BadOption { name: "rank_tolerance" });
        }
        self.options = options;
        (self.newton, self.alpha, self.radau) = (None, None, None);
        Ok(self)
    }

    /// The options in force.
    pub fn options(&self) -> &SimulationOptions {
        &self.options
    }

    /// The joint coordinates and velocities of the bodies' `system` state
    /// (each joint's inverse kinematics, [`Tree::tree_state`]), refused when
    /// a joint's bodies are apart or turned in a way it does not allow, or a
    /// loop is open, by more than the projection's round-off floor (`1e3 ×`
    /// its tolerance; 1e-9 without projection): a start off its joints is
    /// reported by the joint's name, never moved silently
    /// ([`TreeSimulation::assemble`] closes loops on request).
    pub fn state_of(&self, system: &SystemState<NB>) -> Result<TreeState<NQ, NV>, TreeError> {
        let (_, _, floor) = self.projection();
        let state = self.tree.tree_state(system, floor)?;
        self.closed_to(&state, floor)?;
        Ok(state)
    }

    /// Every loop of `state` closed to `floor` (its largest row), or
    /// [`TreeError::NotAssembled`] naming the joint of the largest.
    fn closed_to(&self, state: &TreeState<NQ, NV>, floor: f64) -> Result<(), TreeError> {
        if NC == 0 {
            return Ok(());
        }
        let phi = self.held_rows(state).phi;
        let misfit = phi.amax();
        if misfit.is_nan() || misfit > floor {
            return Err(TreeError::NotAssembled { joint: closing_joint::<S, NB, NQ, NV, NC>(phi.iamax()), misfit });
        }
        Ok(())
    }

    /// Each body's pose and velocity at `state` (the forward kinematics,
    /// [`Tree::system_state`]): what recording, drawing and comparing with
    /// the absolute path take.
    pub fn system_state(&self, state: &TreeState<NQ, NV>) -> SystemState<NB> {
        self.tree.system_state(state)
    }

    /// Kinetic, gravitational and elastic energy at `state` (the absolute
    /// `Simulation`'s [`Energy`], the springs' included).
    pub fn energy(&self, state: &TreeState<NQ, NV>) -> Energy {
        let system = self.tree.system_state(state);
        let energy = crate::dynamics::energy(&self.tree.mass, &self.tree.gravity, self.springs, &system);
        let gravity = energy.gravity + self.tree.compensation_energy(&system);
        Energy { gravity, elastic: energy.elastic + self.tree.spring_energy(&state.q), ..energy }
    }

    /// The step's projection: the options' tolerance and iterations, or
    /// none (no iterations, the default floor).
    pub(super) fn projection(&self) -> Projection {
        match self.options.projection {
            Some(p) => (p.tolerance, p.max_iterations, 1e3 * p.tolerance),
            None => (1e-12, 0, 1e-9),
        }
    }

    /// The same simulation with `springs` acting (the absolute
    /// `Simulation`'s [`SpringDamper`]s: tension `k (L − L₀) + c L̇` along the
    /// line between two points), each entering the dynamics as the joint
    /// forces `Jₚᵀ f` of its two ends (their wrenches carried to the root). Refused when
    /// an end names a body the scene does not have.
    pub fn with_springs(mut self, springs: &'a [SpringDamper]) -> Result<Self, TreeError> {
        for (spring, s) in springs.iter().enumerate() {
            for end in [&s.a, &s.b] {
                if matches!(end, Attachment::Body { body, .. } if *body >= NB) {
                    return Err(TreeError::Attachment { spring });
                }
            }
        }
        self.springs = springs;
        (self.newton, self.alpha, self.radau) = (None, None, None);
        Ok(self)
    }

    /// Whether springs or the user's loads act (beyond the tree's own
    /// dynamics: gravity, armature, damping).
    pub(super) fn loaded(&self) -> bool {
        !(self.springs.is_empty() && L::NONE)
    }

    /// The springs' and the user's loads as joint forces (zero without
    /// either): their wrenches on the bodies carried to the root.
    pub(super) fn applied_forces(&mut self, state: &TreeState<NQ, NV>) -> SVector<f64, NV> {
        if self.springs.is_empty() && L::NONE {
            return SVector::zeros();
        }
        let external = self.body_wrenches(state);
        self.tree.wrench_forces(&state.q, &external)
    }

    /// The springs' and the user's loads on each joint's child, in its link
    /// frame (moment about the joint point); zero without either.
    pub(super) fn body_wrenches(&mut self, state: &TreeState<NQ, NV>) -> [Vector6<f64>; NB] {
        let mut out = [Vector6::zeros(); NB];
        if self.springs.is_empty() && L::NONE {
            return out;
        }
        let system = self.tree.system_state(state);
        let poses = self.tree.link_poses(&state.q);
        let mut joint_of = [None; NB];
        for (k, j) in self.tree.joints.iter().enumerate() {
            if let Some(slot) = joint_of.get_mut(j.child) {
                *slot = Some(k);
            }
        }
        let joints = &self.tree.joints;
        let mut add = |body: usize, point: Vector3<f64>, force: Vector3<f64>, torque: Vector3<f64>| {
            // Every index through `get`: the steps stay in the no-panic proof.
            let k = joint_of.get(body).copied().flatten();
            if let (Some((turn, _)), Some(joint), Some(slot)) =
                (k.and_then(|k| poses.get(k)), k.and_then(|k| joints.get(k)), k.and_then(|k| out.get_mut(k)))
            {
                let f = turn.inverse() * force;
                let n = (point - joint.rho_child).cross(&f) + torque;
                *slot += Vector6::new(n.x, n.y, n.z, f.x, f.y, f.z);
            }
        };
        spring_ends(self.springs, &system, |body, point, force| add(body, point, force, Vector3::zeros()));
        if !L::NONE {
            let mut loads = Loads::default();
            self.loads.apply(&system, &mut loads);
            for body in 0..NB {
                add(body, Vector3::zeros(), loads.force[body], loads.torque[body]);
            }
        }
        out
    }

    /// `v̇` under joint forces `tau`, the closures' forces included: the
    /// tree's own dynamics ([`TreeSimulation::tree_dynamics`]) corrected by
    /// `M⁻¹ Jᵀ λ` with `J M⁻¹ Jᵀ λ = γ − J v̇_tree` (redundant closure rows
    /// dropped by the pivoted factor).
    pub fn forward_dynamics(
        &mut self,
        state: &TreeState<NQ, NV>,
        tau: &SVector<f64, NV>,
    ) -> Result<SVector<f64, NV>, TreeError> {
        Ok(self.constrained(state, tau, None)?.0)
    }

    /// The constrained `v̇` and the pivot order of its factor; `order` fixes
    /// which rows are dropped (the later stages of a step keep the first's).
    #[inline(always)]
    pub(super) fn constrained(
        &mut self,
        state: &TreeState<NQ, NV>,
        tau: &SVector<f64, NV>,
        order: Option<&PivotedCholesky<NC>>,
    ) -> Result<(SVector<f64, NV>, Option<PivotedCholesky<NC>>), TreeError> {
        let (vdot, _, factor) = self.constrained_forces(state, tau, order)?;
        Ok((vdot, factor))
    }

    /// [`constrained`](Self::constrained) with the rows' forces `λ`
    /// (`M v̇ + b = τ + Jᵀλ`; zero without rows).
    #[inline(always)]
    pub(super) fn constrained_forces(
        &mut self,
        state: &TreeState<NQ, NV>,
        tau: &SVector<f64, NV>,
        order: Option<&PivotedCholesky<NC>>,
    ) -> Result<Constrained<NV, NC>, TreeError> {
        let applied = tau + self.applied_forces(state);
        let free = self.tree_dynamics(state, &applied)?;
        if NC == 0 {
            return Ok((free, SVector::zeros(), None));
        }
        let rows = self.scene.closure_rows(state, &self.tree.geometry);
        let soft = self.soft.any().then(|| self.soft.terms::<S, NB, NQ, NV>(&rows, &state.v));
        let regularisation = soft.as_ref().map(|t| &t.regularisation);
        let saddle = self.saddle(&state.q, &rows.jacobian, order, regularisation)?;
        let mut gamma = match self.options.stabilisation {
            Stabilisation::None => rows.gamma,
            Stabilisation::Baumgarte { alpha, beta } => {
                let phi_dot = rows.jacobian * state.v + rows.phi_t;
                rows.gamma - phi_dot * (2.0 * alpha) - rows.phi * (beta * beta)
            }
        };
        // A soft row's target is MuJoCo's reference acceleration, not `γ`.
        if let Some(terms) = &soft {
            self.soft.target(terms, &mut gamma);
        }
        let lambda = saddle.factor.solve(&(gamma - rows.jacobian * free));
        Ok((free + saddle.minv_jt * lambda, lambda, Some(saddle.factor)))
    }

    /// `M⁻¹ Jᵀ` and the factor of `J M⁻¹ Jᵀ + R` (in `order`'s pivots when
    /// given; `R` the soft rows' `regularisation`, none for ideal rows).
    pub(super) fn saddle(
        &self,
        q: &SVector<f64, NQ>,
        jacobian: &SMatrix<f64, NC, NV>,
        order: Option<&PivotedCholesky<NC>>,
        regularisation: Option<&[f64; NC]>,
    ) -> Result<Saddle<NV, NC>, TreeError> {
        let mut m = SMatrix::<f64, NV, NV>::zeros();
        self.mass_matrix_into(q, &mut m);
        if !m.iter().all(|x| x.is_finite()) {
            return Err(TreeError::NonFinite);
        }
        // `M` is positive definite for a valid tree (`Tree::new` checks every
        // inertia): a plain Cholesky, all columns of `Jᵀ` solved at once.
        let Some(mass) = nalgebra::Cholesky::new(m) else {
            let joint = self.tree.joints.first().map_or("", |j| j.name);
            return Err(TreeError::Singular { joint });
        };
        let minv_jt = mass.solve(&jacobian.transpose());
        let mut s = jacobian * minv_jt;
        for (r, x) in regularisation.into_iter().flatten().enumerate() {
            s[(r, r)] += x;
        }
        let factor = match order {
            Some(f) => PivotedCholesky::with_order(&s, f.permutation(), f.rank(), self.options.rank_tolerance),
            None => PivotedCholesky::new(&s, self.options.rank_tolerance),
        }
        .map_err(|_| TreeError::NonFinite)?;
        Ok(Saddle { minv_jt, factor })
    }

    /// The closure rows at `state` (none for a tree without loops): `Φ`,
    /// `J`, `γ`, `Φ_t`, generated by the derive.
    pub fn closure_rows(&self, state: &TreeState<NQ, NV>) -> super::ClosureRows<NC, NV> {
        self.scene.closure_rows(state, &self.tree.geometry)
    }

    /// The closure rows that hold, the soft rows zero: what closing the
    /// loops and checking a start read (MuJoCo's soft rows are never
    /// projected).
    pub(super) fn held_rows(&self, state: &TreeState<NQ, NV>) -> super::ClosureRows<NC, NV> {
        let mut rows = self.scene.closure_rows(state, &self.tree.geometry);
        if self.soft.any() {
            let held = self.soft.soft.map(|s| !s);
            super::constrained::mask_rows(&held, &mut rows.jacobian);
            for (r, _) in self.soft.soft.iter().enumerate().filter(|(_, s)| **s) {
                (rows.phi[r], rows.gamma[r], rows.phi_t[r]) = (0.0, 0.0, 0.0);
            }
        }
        rows
    }

    /// Closes the loops after a step: `q` onto `Φ(q, t) = 0` by simplified
    /// Newton in the mass metric (one factor), then `v` onto
    /// `J v + Φ_t = 0` with that factor.
    fn project(&self, state: &mut TreeState<NQ, NV>, velocities: bool) -> Result<Closed, TreeError> {
        match self.options.projection {
            Some(_) => self.close(state, self.projection(), (false, velocities)),
            None => Ok((0, 0.0, 0.0)),
        }
    }

    /// A state on its loops near `guess`: Newton in the mass metric from the
    /// guess's coordinates (each step the smallest in that metric; refactored
    /// every iteration, up to 50), then the velocities projected onto
    /// `J v + Φ_t = 0`. Refused by the closing joint's name when the loops do
    /// not close to 1e-9.
    pub fn assemble(&self, guess: &TreeState<NQ, NV>) -> Result<TreeState<NQ, NV>, TreeError> {
        let mut state = *guess;
        self.tree.normalise(&mut state.q);
        let (tolerance, _, floor) = self.projection();
        self.close(&mut state, (tolerance, ASSEMBLY_ITERATIONS, floor), (true, true))?;
        Ok(state)
    }

    /// Newton on `Φ(q, t) = 0` (`refactor`: full, else simplified), then,
    /// with `velocities`, the velocity projection with the last factor.
    pub(super) fn close(
        &self,
        state: &mut TreeState<NQ, NV>,
        (tolerance, iterations, floor): Projection,
        (refactor, velocities): (bool, bool),
    ) -> Result<Closed, TreeError> {
        if NC == 0 {
            return Ok((0, 0.0, 0.0));
        }
        if self.soft.all() {
            return Ok((0, 0.0, 0.0));
        }
        let mut rows = self.held_rows(state);
        let mut saddle = self.saddle(&state.q, &rows.jacobian, None, None)?;
        let mut done = 0;
        for _ in 0..iterations {
            if rows.phi.amax() <= tolerance {
                break;
            }
            done += 1;
            let dq = -saddle.correction(&rows.phi);
            self.tree.displace(&mut state.q, &dq);
            rows = self.held_rows(state);
            if refactor {
                saddle = self.saddle(&state.q, &rows.jacobian, None, None)?;
            }
        }
        if !rows.phi.iter().chain(rows.jacobian.iter()).all(|x| x.is_finite()) {
            return Err(TreeError::NonFinite);
        }
        let misfit = rows.phi.amax();
        if misfit > floor {
            return Err(TreeError::Closure { joint: closing_joint::<S, NB, NQ, NV, NC>(rows.phi.iamax()), misfit });
        }
        // The factor is the first iterate's when Newton moved `q` without
        // refactoring: one more solve on the residual it leaves takes
        // `J v + Φ_t` from O(|δq| |drift|) to round-off.
        let mut drift = rows.jacobian * state.v + rows.phi_t;
        let solves = match (velocities, done > 0 && !refactor) {
            (false, _) => 0,
            (true, true) => 2,
            (true, false) => 1,
        };
        for _ in 0..solves {
            let correction = saddle.correction(&drift);
            state.v -= correction;
            drift -= rows.jacobian * correction;
        }
        Ok((done, rows.phi.norm(), drift.norm()))
    }

    /// The tree's own `v̇` under joint forces `tau`, closures left out: the
    /// scene's generated articulated-body algorithm where the derive wrote
    /// one, the tree's recursion otherwise (and when the generated one is not
    /// finite, so that a singular articulated inertia is named by its joint).
    // Inlined into its callers (as `Tree::forward_dynamics` is): out of line,
    // LTO left it without `nounwind`, and the steps kept a landing pad.
    #[inline(always)]
    pub fn tree_dynamics(
        &self,
        state: &TreeState<NQ, NV>,
        tau: &SVector<f64, NV>,
    ) -> Result<SVector<f64, NV>, TreeError> {
        match self.generated_dynamics(state, tau) {
            (_, Some(out)) => Ok(out),
            (held, None) => self.tree.forward_dynamics(state, &held),
        }
    }

    /// `tau` with the gravity compensation's joint forces added (a joint
    /// force like the applied ones), and the derive's articulated-body
    /// algorithm's `v̇` under them where it wrote one and it is finite.
    pub(super) fn generated_dynamics(
        &self,
        state: &TreeState<NQ, NV>,
        tau: &SVector<f64, NV>,
    ) -> (SVector<f64, NV>, Option<SVector<f64, NV>>) {
        let held = self.tree.compensation_forces(&state.q).map_or(*tau, |g| tau + g);
        let mut out = SVector::<f64, NV>::zeros();
        let (q, v, t) = (&state.q.data.0[0], &state.v.data.0[0], &held.data.0[0]);
        let written = self.scene.forward_dynamics_into(self.tree.geometry(), q, v, t, &mut out.data.0[0])
            && out.iter().all(|x| x.is_finite());
        (held, written.then_some(out))
    }

    /// The tree: its recursions, energy and conversions.
    pub fn tree(&self) -> &Tree<NB, NQ, NV> {
        &self.tree
    }

    /// The joint forces `τ(q, v, v̇)` (gravity included): the scene's
    /// generated recursive Newton–Euler algorithm where the derive wrote one,
    /// the tree's recursion otherwise.
    pub fn inverse_dynamics(&self, state: &TreeState<NQ, NV>, vdot: &SVector<f64, NV>) -> SVector<f64, NV> {
        let mut out = SVector::<f64, NV>::zeros();
        let (q, v, a) = (&state.q.data.0[0], &state.v.data.0[0], &vdot.data.0[0]);
        if !self.scene.inverse_dynamics_into(self.tree.geometry(), q, v, a, &mut out.data.0[0]) {
            out = self.tree.inverse_dynamics(state, vdot);
        }
        match self.tree.compensation_forces(&state.q) {
            Some(held) => out - held,
            None => out,
        }
    }

    /// The mass matrix `M(q)` into `out`: the scene's generated
    /// composite-rigid-body algorithm where the derive wrote one, the tree's
    /// recursion otherwise.
    pub fn mass_matrix_into(&self, q: &SVector<f64, NQ>, out: &mut SMatrix<f64, NV, NV>) {
        if !self.scene.mass_matrix_into(self.tree.geometry(), &q.data.0[0], &mut out.data.0) {
            self.tree.mass_matrix_into(q, out);
        }
    }

    /// One RK4 step of length `h` with no joint forces: what the projection
    /// did in the [`StepReport`] (no Newton iterations: RK4 is explicit).
    pub fn step(&mut self, state: &mut TreeState<NQ, NV>, h: f64) -> Result<StepReport, TreeError> {
        self.step_with(state, h, &SVector::zeros())
    }

    /// One step of length `h` under joint forces `tau`, held over the step
    /// (a controller's zero-order hold), by the options' integrator: RK4
    /// (the default), the implicit midpoint rule, generalised-α
    /// (`implicit_rules.rs`) or Radau IIA (`radau.rs`), the implicit ones'
    /// Newton counts in the report. The state is left unchanged on error:
    /// [`TreeError::Diverged`] when the step is too long for the dynamics'
    /// stiffness (its end past [`DIVERGED`] or a later stage's dynamics
    /// failing), [`TreeError::NotConverged`] when an implicit rule's
    /// Newton iteration does not converge.
    // Inlined into `step` and its callers: out of line, LTO left it without
    // `nounwind` (nothing in it unwinds), a landing pad in every caller.
    #[inline(always)]
    pub fn step_with(
        &mut self,
        state: &mut TreeState<NQ, NV>,
        h: f64,
        tau: &SVector<f64, NV>,
    ) -> Result<StepReport, TreeError> {
        if !(h.is_finite() && tau.iter().all(|x| x.is_finite())) {
            return Err(TreeError::NonFinite);
        }
        self.check_closed(state)?;
        match self.options.integrator {
            Integrator::ImplicitMidpoint | Integrator::GeneralisedAlpha => {
                return self.implicit_rule_step(state, h, tau);
            }
            Integrator::RadauIIA => return self.radau_step(state, h, tau),
            _ => {}
        }
        // Every stage drops the closure rows the first dropped: a redundant
        // row switching between stages would break the method's order.
        let (v1, first) = self.constrained(state, tau, None)?;
        let q1 = self.tree.coordinate_rates(&state.q, &state.v);
        // The later stages in one loop, so that the dynamics have one call
        // site (a closure called three times was left without `nounwind` by
        // LTO, a landing pad the no-panic proof counts).
        let mut stages = [(q1, v1); 4];
        for (i, c) in [(1, 0.5), (2, 0.5), (3, 1.0)] {
            let (Some(&(dq, dv)), t) = (stages.get(i - 1), state.t + c * h) else { break };
            let at = TreeState { q: state.q + dq * (c * h), v: state.v + dv * (c * h), t };
            let rates = self.tree.coordinate_rates(&at.q, &at.v);
            // A later stage's failure where the first's dynamics held: divergence.
            let (vdot, _) = self.constrained(&at, tau, first.as_ref()).map_err(|e| e.at_stage(t))?;
            if let Some(slot) = stages.get_mut(i) {
                *slot = (rates, vdot);
            }
        }
        let [_, (q2, v2), (q3, v3), (q4, v4)] = stages;
        let mut next = TreeState {
            q: state.q + (q1 + (q2 + q3) * 2.0 + q4) * (h / 6.0),
            v: state.v + (v1 + (v2 + v3) * 2.0 + v4) * (h / 6.0),
            t: state.t + h,
        };
        let (projection_iterations, constraint_residual, velocity_residual) = self.finish(&mut next)?;
        *state = next;
        Ok(StepReport { projection_iterations, constraint_residual, velocity_residual, ..StepReport::default() })
    }

    /// A step's end: quaternions back to unit length, loops closed, every
    /// number finite.
    pub(super) fn finish(&self, next: &mut TreeState<NQ, NV>) -> Result<Closed, TreeError> {
        self.finish_with(next, true)
    }

    /// [`finish`](Self::finish), the velocities projected only with
    /// `velocities` (index-3 generalised-α leaves its own: projecting them
    /// raised its error on the press fiftyfold, `implicit_rules/index3.rs`).
    pub(super) fn finish_with(&self, next: &mut TreeState<NQ, NV>, velocities: bool) -> Result<Closed, TreeError> {
        self.tree.normalise(&mut next.q);
        let closed = self.project(next, velocities).map_err(|e| e.at_stage(next.t))?;
        diverged(next)?;
        self.last.set(Some(*next));
        Ok(closed)
    }

    /// A start the last step did not end at must have its loops closed to
    /// the projection's round-off floor: a step projects its end, never its
    /// start (without projection, or without loops, nothing is checked).
    fn check_closed(&self, state: &TreeState<NQ, NV>) -> Result<(), TreeError> {
        if NC == 0 || self.options.projection.is_none() || self.last.get() == Some(*state) {
            return Ok(());
        }
        self.closed_to(state, self.projection().2)
    }

    /// Advances `state` to `t_end` with error-controlled steps, as the
    /// absolute `AbsoluteSimulation::integrate` does (the same driver: step-size
    /// rule, error norm, [`IntegrationReport`]) on `(q, v)`, each accepted
    /// step's quaternions renormalised and its loops closed as
    /// [`TreeSimulation::step`] does. `method` is
    /// [`Adaptive::DormandPrince`], [`Adaptive::RadauIIA`] (RADAU5's
    /// error estimate and step-size rule, `radau.rs`) or
    /// [`Adaptive::GeneralisedAlpha`] (Géradin and Cardona's estimate, as
    /// the absolute engine's; its ρ∞ from the options, `implicit_rules.rs`).
    /// No joint
    /// forces: a controller's act through
    /// [`with_loads`](TreeSimulation::with_loads) or
    /// [`step_with`](TreeSimulation::step_with). The state is left at the
    /// last accepted step on error.
    ///
    /// ```
    /// use joint_runtime::Scene;
    /// use joint_runtime::dynamics::{Adaptive, Tolerance};
    /// use joint_runtime::relative::TreeSimulation;
    ///
    /// #[derive(Scene)]
    /// #[scene(gravity = [0, 0, -9.81])]
    /// #[body(bar, mass = 1.0, inertia = [0.001, 0.0833, 0.0833])]
    /// #[joint(pin = revolute(ground, bar), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0, 0, 0], rho2 = [-0.5, 0, 0])]
    /// struct Pendulum;
    ///
    /// let mut sim = TreeSimulation::new(&Pendulum)?;
    /// let mut state: PendulumTreeState = sim.tree().zero_state();
    /// let report = sim.integrate(&mut state, 2.0, Adaptive::DormandPrince, Tolerance { rtol: 1e-9, atol: 1e-9 })?;
    /// assert!(state.t == 2.0 && report.accepted > 10);
    /// # Ok::<(), joint_runtime::relative::TreeError>(())
    /// ```
    pub fn integrate(
        &mut self,
        state: &mut TreeState<NQ, NV>,
        t_end: f64,
        method: Adaptive,
        tolerance: Tolerance,
    ) -> Result<IntegrationReport, TreeError> {
        integrate(self, state, t_end, method, tolerance)
    }
}

impl<const NQ: usize, const NV: usize> Timed for TreeState<NQ, NV> {
    fn time(&self) -> f64 {
        self.t
    }
    fn set_time(&mut self, t: f64) {
        self.t = t;
    }
}

/// Beyond this, a state's number is not a robot's (rad, m, their rates):
/// MuJoCo's `mjMAXVAL`, where it too calls a simulation unstable.
pub const DIVERGED: f64 = 1e10;

/// [`TreeError::NonFinite`] unless `state` and every one of `more` (joint
/// forces, accelerations, multipliers) are finite: what every call that
/// takes a state checks first.
pub(crate) fn finite_inputs<const NQ: usize, const NV: usize>(
    state: &TreeState<NQ, NV>,
    more: &[&[f64]],
) -> Result<(), TreeError> {
    let finite = crate::linalg::finite;
    if finite(state.q.as_slice()) && finite(state.v.as_slice()) && more.iter().all(|m| finite(m)) {
        Ok(())
    } else {
        Err(TreeError::NonFinite)
    }
}

/// [`TreeError::Diverged`] for a step's end past [`DIVERGED`] or not finite.
pub(crate) fn diverged<const NQ: usize, const NV: usize>(next: &TreeState<NQ, NV>) -> Result<(), TreeError> {
    // `!(x <= bound)`: NaN fails too.
    if next.q.iter().chain(next.v.iter()).all(|x| libm::fabs(*x) <= DIVERGED) {
        Ok(())
    } else {
        Err(TreeError::Diverged { t: next.t })
    }
}

impl TreeError {
    /// A stage's failure after a start that held: the step diverged.
    pub(super) fn at_stage(self, t: f64) -> Self {
        match self {
            TreeError::NonFinite | TreeError::Singular { .. } => TreeError::Diverged { t },
            other => other,
        }
    }
}

impl StepError for TreeError {
    fn bad_option(name: &'static str) -> Self {
        TreeError::BadOption { name }
    }
    fn step_too_small(t: f64, step: f64) -> Self {
        TreeError::StepTooSmall { t, step }
    }
    fn non_finite_estimate() -> Self {
        TreeError::NonFinite
    }
    fn retried(&self) -> bool {
        matches!(
            self,
            TreeError::NonFinite
                | TreeError::Closure { .. }
                | TreeError::Singular { .. }
                | TreeError::Diverged { .. }
                | TreeError::NotConverged { .. }
        )
    }
}

impl<
    S: TreeScene<NB, NQ, NV, NC>,
    L: AppliedLoads<NB>,
    const NB: usize,
    const NQ: usize,
    const NV: usize,
    const NC: usize,
> AdaptiveSteps for TreeSimulation<'_, S, NB, NQ, NV, NC, L>
{
    type State = TreeState<NQ, NV>;
    type Error = TreeError;

    fn check_start(&self, state: &TreeState<NQ, NV>) -> Result<(), TreeError> {
        let finite = state.q.iter().chain(state.v.iter()).all(|x| x.is_finite()) && state.t.is_finite();
        if !finite {
            return Err(TreeError::NonFinite);
        }
        self.check_closed(state)
    }

    /// Radau IIA (`radau.rs`), or Dormand–Prince on `(q, v)`.
    fn trial(
        &mut self,
        y0: &TreeState<NQ, NV>,
        h: f64,
        method: Adaptive,
        tolerance: Tolerance,
        report: &mut IntegrationReport,
    ) -> Result<(TreeState<NQ, NV>, f64), TreeError> {
        match method {
            Adaptive::RadauIIA => {
                let (end, step) = self.radau_trial(y0, h, &SVector::zeros(), Some(tolerance))?;
                report.newton_iterations += step.iterations;
                report.newton_matrices += step.matrices;
                report.evaluations += step.evaluations;
                Ok((end, step.error))
            }
            Adaptive::GeneralisedAlpha => self.alpha_trial(y0, h, tolerance, report),
            _ => self.dormand_prince_trial(y0, h, tolerance, report),
        }
    }

    fn accept(&mut self, next: TreeState<NQ, NV>, method: Adaptive) -> Result<TreeState<NQ, NV>, TreeError> {
        let mut next = next;
        match method {
            // Its trial projected the end, where its memory continues.
            Adaptive::GeneralisedAlpha => {}
            Adaptive::RadauIIA => {
                self.finish(&mut next)?;
                self.radau_accepted(&next);
            }
            _ => {
                self.finish(&mut next)?;
            }
        }
        Ok(next)
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
    /// Dormand–Prince on `(q, v)`: seven stages (the later six dropping the
    /// closure rows the first dropped), the fifth-order state, and the root
    /// mean square of the embedded error over `q` and `v`.
    fn dormand_prince_trial(
        &mut self,
        y0: &TreeState<NQ, NV>,
        h: f64,
        tolerance: Tolerance,
        report: &mut IntegrationReport,
    ) -> Result<(TreeState<NQ, NV>, f64), TreeError> {
        let tau = SVector::<f64, NV>::zeros();
        let (v1, first) = self.constrained(y0, &tau, None)?;
        let mut k = [(self.tree.coordinate_rates(&y0.q, &y0.v), v1); 7];
        let mut y = *y0;
        for (i, row) in A.iter().enumerate() {
            y = TreeState { t: y0.t + C[i] * h, ..*y0 };
            for (&(dq, dv), &a) in k.iter().zip(row.iter()) {
                y.q += dq * (h * a);
                y.v += dv * (h * a);
            }
            if let Some(slot) = k.get_mut(i + 1) {
                *slot = (self.tree.coordinate_rates(&y.q, &y.v), self.constrained(&y, &tau, first.as_ref())?.0);
            }
        }
        report.evaluations += 7;
        let (mut eq, mut ev) = (SVector::<f64, NQ>::zeros(), SVector::<f64, NV>::zeros());
        for (&(dq, dv), &w) in k.iter().zip(E.iter()) {
            eq += dq * (h * w);
            ev += dv * (h * w);
        }
        let squared = |e: f64, a: f64, b: f64| {
            let x = e / (tolerance.atol + tolerance.rtol * libm::fabs(a).max(libm::fabs(b)));
            x * x
        };
        let sum: f64 = (0..NQ).map(|i| squared(eq[i], y0.q[i], y.q[i])).sum::<f64>()
            + (0..NV).map(|i| squared(ev[i], y0.v[i], y.v[i])).sum::<f64>();
        Ok((y, libm::sqrt(sum / (NQ + NV).max(1) as f64)))
    }
}

impl<const NB: usize, const NQ: usize, const NV: usize> Tree<NB, NQ, NV> {
    /// `q̇(q, v)`: `θ̇ = v` at a revolute joint, `ṗ = ½ p ⊗ (0, ω')` at a
    /// spherical one; a free joint's offset moves at `R(p) u`.
    pub fn coordinate_rates(&self, q: &SVector<f64, NQ>, v: &SVector<f64, NV>) -> SVector<f64, NQ> {
        let mut out = SVector::<f64, NQ>::zeros();
        for (k, j) in self.joints.iter().enumerate() {
            let (qa, va) = (self.q_at[k], self.v_at[k]);
            match j.kind {
                TreeJointKind::Spherical => spin(q, v, (qa, va), &mut out),
                TreeJointKind::Free => {
                    put_three(&mut out, qa, &(unit_at(q, qa + 3) * three(v, va)));
                    spin(q, v, (qa + 3, va + 3), &mut out);
                }
                kind => {
                    for i in 0..kind.freedoms() {
                        set(&mut out, qa + i, get(v, va + i));
                    }
                }
            }
        }
        out
    }

    /// `q ⊕ δ` in place: each joint's coordinates moved along the
    /// velocity-shaped `δ` (an angle added; a quaternion turned by `δθ` in
    /// its own frame, `p ⊗ exp(δθ / 2)`).
    pub fn displace(&self, q: &mut SVector<f64, NQ>, delta: &SVector<f64, NV>) {
        for (k, j) in self.joints.iter().enumerate() {
            let (qa, va) = (self.q_at[k], self.v_at[k]);
            match j.kind {
                TreeJointKind::Spherical => turn(q, delta, (qa, va)),
                TreeJointKind::Free => {
                    let moved = three(q, qa) + unit_at(q, qa + 3) * three(delta, va);
                    put_three(q, qa, &moved);
                    turn(q, delta, (qa + 3, va + 3));
                }
                kind => {
                    for i in 0..kind.freedoms() {
                        set(q, qa + i, get(q, qa + i) + get(delta, va + i));
                    }
                }
            }
        }
    }

    /// `q ⊕ δ` but with each free joint's offset turned by the rotation
    /// of `mid` rather than `q`'s: the implicit midpoint rule's end,
    /// `r₁ = r₀ + R_½ h w`, second order where the start's rotation
    /// (`q ⊕ h w`) is first.
    pub(super) fn displace_through(&self, q: &mut SVector<f64, NQ>, delta: &SVector<f64, NV>, mid: &SVector<f64, NQ>) {
        let start = *q;
        self.displace(q, delta);
        for (k, j) in self.joints.iter().enumerate() {
            if j.kind == TreeJointKind::Free {
                let (qa, va) = (self.q_at[k], self.v_at[k]);
                let moved = three(&start, qa) + unit_at(mid, qa + 3) * three(delta, va);
                put_three(q, qa, &moved);
            }
        }
    }

    /// `q ⊕ δ`.
    pub fn displaced(&self, q: &SVector<f64, NQ>, delta: &SVector<f64, NV>) -> SVector<f64, NQ> {
        let mut out = *q;
        self.displace(&mut out, delta);
        out
    }

    /// `b ⊖ a`: the velocity-shaped increment `δ` with `b = a ⊕ δ`
    /// ([`Tree::displace`] undone): coordinates subtracted, a quaternion's
    /// turn `log(a⁻¹ b)` in its own frame (under half a turn), a free
    /// joint's offset in its child's axes at `a`. What an estimator's or a
    /// linearisation's increments are measured in.
    pub fn difference(&self, a: &SVector<f64, NQ>, b: &SVector<f64, NQ>) -> SVector<f64, NV> {
        let mut out = SVector::<f64, NV>::zeros();
        let unit = |q: &SVector<f64, NQ>, at: usize| super::kinematics::unit(&q.fixed_rows::<4>(at).into_owned());
        let turn = |at: usize| (unit(a, at).inverse() * unit(b, at)).scaled_axis();
        for (k, j) in self.joints.iter().enumerate() {
            let (qa, va) = (self.q_at[k], self.v_at[k]);
            match j.kind {
                TreeJointKind::Spherical => out.fixed_rows_mut::<3>(va).copy_from(&turn(qa)),
                TreeJointKind::Free => {
                    let offset = unit(a, qa + 3).inverse() * (b.fixed_rows::<3>(qa) - a.fixed_rows::<3>(qa));
                    out.fixed_rows_mut::<3>(va).copy_from(&offset);
                    out.fixed_rows_mut::<3>(va + 3).copy_from(&turn(qa + 3));
                }
                kind => {
                    for i in 0..kind.freedoms() {
                        out[va + i] = b[qa + i] - a[qa + i];
                    }
                }
            }
        }
        out
    }

    /// Every quaternion (spherical and free joints') back to unit length.
    pub fn normalise(&self, q: &mut SVector<f64, NQ>) {
        for (k, j) in self.joints.iter().enumerate() {
            if let Some(at) = j.kind.quaternion() {
                let at = self.q_at[k] + at;
                let p = quaternion_at(q, at);
                let n = p.norm();
                if n > 0.0 {
                    put_quaternion(q, at, &(p / n));
                }
            }
        }
    }
}

/// `ṗ = ½ p ⊗ (0, ω')` of the quaternion at `q[qa..]` turned by `v[va..]`, into `out`.
fn spin<const NQ: usize, const NV: usize>(
    q: &SVector<f64, NQ>,
    v: &SVector<f64, NV>,
    (qa, va): (usize, usize),
    out: &mut SVector<f64, NQ>,
) {
    let d = quaternion_at(q, qa) * Quaternion::from_imag(three(v, va)) * 0.5;
    put_quaternion(out, qa, &d);
}

/// The quaternion at `q[qa..]` turned by `δ[va..]` in its own frame: `p ⊗ exp(δθ / 2)`.
fn turn<const NQ: usize, const NV: usize>(
    q: &mut SVector<f64, NQ>,
    delta: &SVector<f64, NV>,
    (qa, va): (usize, usize),
) {
    let d = (unit_at(q, qa) * UnitQuaternion::from_scaled_axis(three(delta, va))).into_inner();
    put_quaternion(q, qa, &d);
}

/// The closing joint whose rows hold closure row `row`.
fn closing_joint<S: TreeScene<NB, NQ, NV, NC>, const NB: usize, const NQ: usize, const NV: usize, const NC: usize>(
    row: usize,
) -> &'static str {
    S::CLOSURES.iter().find(|b| (b.start..b.start + b.rows).contains(&row)).map_or("", |b| b.name)
}

/// Each spring end's force on its body in the bodies' state `system`:
/// `(body, point in the body from its centre, force in inertial
/// components)`.
fn spring_ends<const NB: usize>(
    springs: &[SpringDamper],
    system: &SystemState<NB>,
    mut each: impl FnMut(usize, Vector3<f64>, Vector3<f64>),
) {
    let end = |at: &Attachment| match *at {
        Attachment::Ground(p) => (p, nalgebra::Vector3::zeros(), None),
        Attachment::Body { body, point } => {
            // `with_springs` refused bodies out of range: the default is
            // never used, and the step keeps no panic path.
            let b = system.bodies.get(body).copied().unwrap_or_default();
            let arm = b.rotation() * point;
            (b.r + arm, b.rdot + (b.rotation() * b.omega).cross(&arm), Some((body, point)))
        }
    };
    for s in springs {
        let ((pa, va, ba), (pb, vb, bb)) = (end(&s.a), end(&s.b));
        let (d, length) = (pb - pa, (pb - pa).norm());
        if length < 1e-12 {
            continue;
        }
        let u = d / length;
        let tension = s.stiffness * (length - s.rest_length) + s.damping * u.dot(&(vb - va));
        for (at, sign) in [(ba, 1.0), (bb, -1.0)] {
            if let Some((body, point)) = at {
                each(body, point, u * (sign * tension));
            }
        }
    }
}
