//! Generalised-α on the sparse path: the dense method's equations
//! (`dynamics/generalised_alpha.rs`) with its iteration matrix
//!
//! ```text
//! [ S    Jᵀ ]   S = c₁ M + h (K − Q_q) T − c₂ Q_v
//! [ J T  0  ]
//! ```
//!
//! assembled block by block on the pattern the scene fixes (bodies, joints,
//! springs) and factorised by [`Kkt`]: time and memory in proportion to the
//! scene. `K` comes from the scene's sparse second-order terms
//! ([`Scene::second_order_values`], or their differences, `differences.rs`,
//! for a scene without them); `Q_q`, `Q_v` are the gyroscopic terms and
//! the spring-dampers', exact; the user loads' on the pattern's blocks, by
//! their own derivative or differences, several bodies at a time
//! (`loads.rs`). Redundant rows are held at
//! `δλ = 0` as identity rows, the rule of the step's start.

#[cfg(feature = "alloc")]
use alloc::vec::Vec;

use nalgebra::{Matrix3, SVector, Vector3};

use super::AbsoluteSimulation;
use super::buf::{Boxed, at_rest, boxed_with, zero_state, zeros};
use super::differences::{DifferenceTerms, DifferenceWork};
use super::kkt::{Block, Kkt, KktStorage, NodeVector};
use super::loads::{LoadColouring, body_pairs};
use super::second_order::{SecondOrderLayout, TermStorage};
use super::simulation::with_taken;
use super::solver::{jt_mul_into, non_finite};
use crate::analysis::{AnalysisError, check_output, velocity_vector_into};
use crate::dynamics::{
    AlphaHistory, AppliedLoads, Attachment, Coefficients, Iterate, ModifiedNewton, NewtonMatrix, SpringDamper,
    mass_times_into, spring_column, update_blocks_into,
};
use crate::scene::{RowBlock, Scene, SparseJacobian, SystemState};

/// What the sparse implicit integrators keep between steps (generalised-α
/// here, the midpoint rule in `midpoint.rs`, on the same pattern): the
/// saddle-point matrix and its factor, the second-order terms, the colourings
/// of their differences and of the user loads, and scratch; arrays of the
/// scene's sizes (the derive's), made once.
#[derive(Clone, Debug)]
pub(super) struct AlphaWorkspace<K, Tm, const NB: usize, const NV: usize, const M: usize, const NNZ: usize> {
    /// The matrix, in the scene's arrays (`SparseJacobian::Kkt`) unless
    /// springs couple bodies no joint joins.
    pub(super) kkt: Kkt<f64, K>,
    pub(super) layout: SecondOrderLayout<'static>,
    /// The second-order terms (`SparseJacobian::Terms`).
    pub(super) terms: Tm,
    pub(super) rhs: NodeVector<f64, NV, M>,
    /// Per row: its joint node and the row within the joint.
    pub(super) row_joint: [(usize, usize); M],
    pub(super) history: Option<AlphaHistory<NB, NV, M>>,
    /// The terms by differences, for scenes without generated ones, and
    /// their scratch.
    differences: DifferenceTerms<NB>,
    difference_work: Boxed<DifferenceWork<NB, NV, M, NNZ>>,
    /// The colouring of the user loads' derivatives.
    pub(super) user: LoadColouring<NB>,
}

impl<K, Tm, const NB: usize, const NV: usize, const M: usize, const NNZ: usize> AlphaWorkspace<K, Tm, NB, NV, M, NNZ>
where
    K: KktStorage<f64>,
    Tm: TermStorage,
{
    /// The pattern of `scene` with `springs`, boxed (with `alloc`) and
    /// written in the heap (`buf`).
    ///
    /// # Errors
    /// [`AnalysisError::NonFiniteOutput`] for a structure the derive's sizes
    /// do not fit; without `alloc`, [`AnalysisError::BadOption`] for springs
    /// between bodies no joint joins (their pattern is found at run time).
    pub(super) fn boxed<S: Scene<NB, NV, M> + SparseJacobian<NB, NNZ>>(
        springs: &[crate::dynamics::SpringDamper],
    ) -> Result<Boxed<Self>, AnalysisError> {
        let bad = |_| non_finite("scene structure");
        // The derive's pattern couples the bodies each joint joins; a spring
        // between other bodies needs one found at run time.
        let joined = |(a, b): (usize, usize)| {
            S::BLOCK_BODIES.iter().any(|p| *p == [Some(a), Some(b)] || *p == [Some(b), Some(a)])
        };
        let kkt = if body_pairs(&[], springs).all(joined) {
            let rows = |j: usize| S::BLOCKS.get(j).map(|b| b.rows);
            Kkt::fixed(rows, S::BLOCK_BODIES, (S::KKT_ORDER, S::KKT_STARTS, S::KKT_BELOW)).map_err(bad)?
        } else {
            grown::<K, NB>(S::BLOCKS, S::BLOCK_BODIES, springs)?
        };
        let (layout, terms) = (SecondOrderLayout::new(S::BLOCKS, S::BLOCK_BODIES), Tm::zeroed());
        if terms.values().len() != layout.len() {
            return Err(non_finite("scene structure"));
        }
        let mut ws = boxed_with(|| AlphaWorkspace {
            kkt,
            terms,
            layout,
            rhs: const { NodeVector::repeat(0.0) },
            row_joint: const { [(0, 0); M] },
            user: LoadColouring::new(S::BLOCK_BODIES, springs),
            history: None,
            differences: DifferenceTerms::new(S::BLOCK_BODIES),
            difference_work: DifferenceWork::boxed(),
        });
        for (k, block) in S::BLOCKS.iter().enumerate() {
            for r in 0..block.rows {
                if let Some(x) = ws.row_joint.get_mut(block.start + r) {
                    *x = (NB + k, r);
                }
            }
        }
        Ok(ws)
    }

    /// The second-order terms at `state` (`λ`, and `u` of `∂(J u)/∂q`) into
    /// `terms`: the scene's generated ones, or central differences of its `J`,
    /// `γ` and `Φ_t` when it has none or `by_differences` asks for them.
    pub(super) fn fill_terms<S: Scene<NB, NV, M> + SparseJacobian<NB, NNZ>>(
        &mut self,
        scene: &S,
        state: &SystemState<NB>,
        lambda: &SVector<f64, M>,
        u: &SVector<f64, NV>,
        by_differences: bool,
    ) -> Result<(), AnalysisError> {
        let terms = self.terms.values_mut();
        if (by_differences || !scene.second_order_values(state, lambda, u, terms))
            && !self.differences.values_in(scene, state, (lambda, u), terms, &mut self.difference_work)
        {
            return Err(missing());
        }
        Ok(())
    }

    /// Blocks of the factor (its memory, in 6 × 6 blocks).
    pub(super) fn blocks(&self) -> usize {
        self.kkt.blocks()
    }
}

/// The saddle-point pattern of a scene whose `springs` couple bodies no
/// joint joins: found at run time, in vectors.
#[cfg(feature = "alloc")]
fn grown<K: KktStorage<f64>, const NB: usize>(
    blocks: &[RowBlock],
    joint_bodies: &[[Option<usize>; 2]],
    springs: &[SpringDamper],
) -> Result<Kkt<f64, K>, AnalysisError> {
    let rows: Vec<usize> = blocks.iter().map(|b| b.rows).collect();
    let pairs = body_pairs(joint_bodies, springs).map(|(a, b)| (a.min(b), a.max(b)));
    let mut couplings: Vec<(usize, usize)> = pairs.collect();
    couplings.sort_unstable();
    couplings.dedup();
    Kkt::grown(NB, &rows, joint_bodies, &couplings).map_err(|_| non_finite("scene structure"))
}

/// Without `alloc` a pattern cannot be found at run time: such springs are
/// refused with the implicit integrators.
#[cfg(not(feature = "alloc"))]
fn grown<K: KktStorage<f64>, const NB: usize>(
    _: &[RowBlock],
    _: &[[Option<usize>; 2]],
    _: &[SpringDamper],
) -> Result<Kkt<f64, K>, AnalysisError> {
    Err(AnalysisError::BadOption { name: "springs (between bodies no joint joins, implicit integrators need `alloc`)" })
}

/// Generalised-α's history, iterate and Newton vectors, boxed and made with
/// the implicit integrators' pattern: a step's frames hold none of them.
pub(super) struct AlphaWork<const NB: usize, const NV: usize, const M: usize, const NNZ: usize> {
    /// The step's start (normalised).
    y0: SystemState<NB>,
    /// The step's end (projected in place).
    end: SystemState<NB>,
    past: AlphaHistory<NB, NV, M>,
    v0: SVector<f64, NV>,
    it: Iterate<NB, NV, M>,
    x: SVector<f64, NV>,
    dlambda: SVector<f64, M>,
    values: [f64; NNZ],
    phi: SVector<f64, M>,
    /// The residual's parts: `Q`, `M v̇`, `Jᵀ λ`; and the rotation updates `T`.
    q: SVector<f64, NV>,
    mass: SVector<f64, NV>,
    jt: SVector<f64, NV>,
    t: [Matrix3<f64>; NB],
}

impl<const NB: usize, const NV: usize, const M: usize, const NNZ: usize> AlphaWork<NB, NV, M, NNZ> {
    /// Zeros, states at rest and identity updates; written in the heap
    /// (`buf`).
    pub(super) fn new() -> Boxed<Self> {
        let mut w = boxed_with(|| {
            const {
                AlphaWork {
                    y0: zero_state(),
                    end: zero_state(),
                    past: AlphaHistory::zeros(),
                    v0: zeros(),
                    it: Iterate::zeros(),
                    x: zeros(),
                    dlambda: zeros(),
                    values: [0.0; NNZ],
                    phi: zeros(),
                    q: zeros(),
                    mass: zeros(),
                    jt: zeros(),
                    t: [zeros(); NB],
                }
            }
        });
        let AlphaWork { y0, end, past, it, t, .. } = &mut *w;
        for state in [y0, end, &mut past.state, &mut it.state] {
            at_rest(state);
        }
        t.fill(Matrix3::identity());
        w
    }
}

/// `block (6 × 6) += s · x` for the 3 × 3 `x` at `(r, c)`.
fn add3(block: &mut Block, r: usize, c: usize, x: &Matrix3<f64>, s: f64) {
    for i in 0..3 {
        for j in 0..3 {
            block[6 * (r + i) + c + j] += s * x[(i, j)];
        }
    }
}

impl<S, L, const NB: usize, const NV: usize, const M: usize, const NNZ: usize>
    AbsoluteSimulation<'_, S, L, NB, NV, M, NNZ>
where
    S: Scene<NB, NV, M> + SparseJacobian<NB, NNZ>,
    L: AppliedLoads<NB>,
{
    /// One step of generalised-α from `y0` (normalised, its rule of redundant
    /// rows just factorised); returns the state, Newton iterations and
    /// iteration matrices built.
    #[inline(never)]
    pub(super) fn step_alpha(
        &mut self,
        y0: &SystemState<NB>,
        h: f64,
        continuing: bool,
        start: (SVector<f64, NV>, SVector<f64, M>),
    ) -> Result<(SystemState<NB>, usize, usize), AnalysisError> {
        let c = Coefficients::checked(self.options.spectral_radius)?;
        // Made with the implicit pattern (`alpha_workspace`).
        with_taken(
            self,
            |s| &mut s.alpha_work,
            |sim, w| {
                w.y0 = *y0;
                sim.alpha_past(w, continuing, (&start.0, &start.1));
                sim.alpha_newton(w, h, c).map(|(i, m)| (w.it.state, i, m))
            },
        )
    }

    /// A generalised-α step from `state` (checked, normalised and solved
    /// at into the boxed work), projected, into `state`: no state or vector
    /// of the scene's size in this frame or those it calls.
    pub(super) fn alpha_in_work(
        &mut self,
        state: &mut SystemState<NB>,
        h: f64,
        continuing: bool,
        report: &mut crate::dynamics::StepReport,
    ) -> Result<(), AnalysisError> {
        let c = Coefficients::checked(self.options.spectral_radius)?;
        with_taken(self, |s| &mut s.alpha_work, |sim, w| sim.alpha_started(w, state, h, continuing, c, report))
    }

    /// [`alpha_in_work`](Self::alpha_in_work) on the taken-out work `w`.
    fn alpha_started(
        &mut self,
        w: &mut AlphaWork<NB, NV, M, NNZ>,
        state: &mut SystemState<NB>,
        h: f64,
        continuing: bool,
        c: Coefficients,
        report: &mut crate::dynamics::StepReport,
    ) -> Result<(), AnalysisError> {
        self.begin(state, &mut w.y0)?;
        self.alpha_past(w, continuing, self.solved());
        (report.newton_iterations, report.newton_matrices) = self.alpha_newton(w, h, c)?;
        w.end.clone_from(&w.it.state);
        self.finish(&mut w.end, report)?;
        state.clone_from(&w.end);
        Ok(())
    }

    /// The history the step from `w.y0` goes on from, into `w.past`: the
    /// last step's if `continuing` (and kept), else the start's `(v̇, λ)`.
    fn alpha_past(
        &self,
        w: &mut AlphaWork<NB, NV, M, NNZ>,
        continuing: bool,
        (vdot, lambda): (&SVector<f64, NV>, &SVector<f64, M>),
    ) {
        match (continuing, self.alpha.as_deref().and_then(|w| w.history.as_ref())) {
            (true, Some(past)) => w.past.set(&past.state, (&past.vdot, &past.a), &past.lambda),
            _ => w.past.set(&w.y0, (vdot, vdot), lambda),
        }
    }

    /// Generalised-α's Newton iteration from `w.y0` and the history in
    /// `w.past` on the iterate and vectors of `w`: the end in `w.it.state`;
    /// returns the Newton iterations and iteration matrices built.
    fn alpha_newton(
        &mut self,
        w: &mut AlphaWork<NB, NV, M, NNZ>,
        h: f64,
        c: Coefficients,
    ) -> Result<(usize, usize), AnalysisError> {
        velocity_vector_into(&w.y0, &mut w.v0);
        c.predicted_into(&w.past, &mut w.it.a);
        w.it.lambda.copy_from(&w.past.lambda);
        w.it.follow(&w.y0, &w.v0, &w.past, h, c);
        let mut newton = ModifiedNewton::new(&self.options);
        loop {
            newton.next()?;
            self.alpha_residual(w)?;
            if newton.stale() {
                self.alpha_matrix(w, h, c)?;
                newton.built();
            }
            self.alpha_solve(&w.phi, h, &mut w.x, &mut w.dlambda)?;
            w.it.correct(&w.y0, &w.v0, &w.past, &w.x, &w.dlambda, h, c);
            if newton.converged(w.x.norm(), 1.0 + w.it.dq.norm())? {
                break;
            }
        }
        if let Some(a) = self.alpha.as_deref_mut() {
            match &mut a.history {
                Some(past) => w.it.history_into(past),
                None => {
                    w.it.history_into(&mut w.past);
                    first_history(&mut a.history, &w.past);
                }
            }
        }
        Ok(newton.counts())
    }

    /// `M v̇ + Jᵀ λ − Q` into the workspace's right-hand side; the Jacobian's
    /// values and `Φ` at the iterate into `w.values` and `w.phi`.
    #[inline(never)]
    fn alpha_residual(&mut self, w: &mut AlphaWork<NB, NV, M, NNZ>) -> Result<(), AnalysisError> {
        self.scene.jacobian_values_into(&w.it.state, &mut w.values);
        if !w.values.iter().all(|x| x.is_finite()) {
            return Err(non_finite("J"));
        }
        w.phi = self.scene.phi(&w.it.state);
        check_output::<S, NB, NV, M, 1>("Φ", &w.phi)?;
        self.forces_into(&w.it.state, &mut w.q);
        mass_times_into(&self.inertias, &w.it.vdot, &mut w.mass);
        jt_mul_into::<S, NB, NNZ>(&w.values, w.it.lambda.as_slice(), w.jt.as_mut_slice());
        let ws = self.alpha.as_deref_mut().ok_or(AnalysisError::BadOption { name: "integrator" })?;
        let parts = w.mass.as_slice().iter().zip(w.jt.as_slice().iter()).zip(w.q.as_slice().iter());
        for (r, ((m, j), q)) in ws.rhs.head.iter_mut().zip(parts) {
            *r = m + j - q;
        }
        if !ws.rhs.head.iter().all(|x| x.is_finite()) {
            return Err(non_finite("forces"));
        }
        Ok(())
    }

    /// Solves the iteration matrix for the residual in the workspace and
    /// `r2 = Φ`: the correction `(x, δλ)`, written into `x` and `dlambda`.
    #[inline(never)]
    fn alpha_solve(
        &mut self,
        r2: &SVector<f64, M>,
        h: f64,
        x: &mut SVector<f64, NV>,
        dlambda: &mut SVector<f64, M>,
    ) -> Result<(), AnalysisError> {
        let dropped = self.solver.factor.dropped();
        let w = self.alpha.as_deref_mut().ok_or(AnalysisError::BadOption { name: "integrator" })?;
        for (r, (o, x)) in w.rhs.tail.iter_mut().zip(r2.iter()).enumerate() {
            *o = if dropped.binary_search(&r).is_ok() { 0.0 } else { x / h };
        }
        w.kkt.solve(&mut w.rhs);
        for (o, &v) in x.iter_mut().zip(&w.rhs.head) {
            *o = v;
        }
        for (o, &v) in dlambda.iter_mut().zip(&w.rhs.tail) {
            *o = v;
        }
        Ok(())
    }

    /// Assembles and factorises the iteration matrix at the iterate.
    #[inline(never)]
    fn alpha_matrix(
        &mut self,
        w: &mut AlphaWork<NB, NV, M, NNZ>,
        h: f64,
        c: Coefficients,
    ) -> Result<(), AnalysisError> {
        update_blocks_into(&w.it.dq, h, &mut w.t);
        let (it, t) = (&w.it, &w.t);
        let by_differences = self.options.newton_matrix == NewtonMatrix::FiniteDifferences;
        let ws = self.alpha.as_deref_mut().ok_or(AnalysisError::BadOption { name: "integrator" })?;
        ws.fill_terms(self.scene, &it.state, &it.lambda, &it.v, by_differences)?;
        let kkt = &mut ws.kkt;
        kkt.clear();
        // h (K − Q_q), then times T on the right; then c₁ M − c₂ Q_v; then J T and Jᵀ.
        add_stiffness(kkt, &ws.layout, ws.terms.values(), h)?;
        for s in self.springs {
            spring_blocks(kkt, s, &it.state, false, -h)?;
        }
        ws.user.add_blocks::<L, NV>(kkt, &mut self.loads, self.springs, &it.state, false, -h)?;
        times_update(kkt, NB, t)?;
        for s in self.springs {
            spring_blocks(kkt, s, &it.state, true, -c.gamma / c.beta)?;
        }
        ws.user.add_blocks::<L, NV>(kkt, &mut self.loads, self.springs, &it.state, true, -c.gamma / c.beta)?;
        add_mass(kkt, &self.inertias, &it.state, c.mass_factor(h), c.gamma / c.beta)?;
        add_rows::<S, NB, NNZ>(kkt, &w.values, &ws.row_joint, self.solver.factor.dropped(), t)?;
        ws.kkt.factor().map_err(AnalysisError::from)
    }
}

/// The first history of generalised-α (none kept before): made once, in a
/// frame of its own.
#[cold]
#[inline(never)]
fn first_history<const NB: usize, const NV: usize, const M: usize>(
    history: &mut Option<AlphaHistory<NB, NV, M>>,
    past: &AlphaHistory<NB, NV, M>,
) {
    // Copied from a place (the boxed work's), not built in this frame.
    *history = Some(*past);
}

/// A pattern the scene's structure should have had.
pub(super) fn missing() -> AnalysisError {
    non_finite("scene structure")
}

/// `h K`: each joint's stiffness block onto its body pairs.
pub(super) fn add_stiffness(
    kkt: &mut Kkt<f64, impl KktStorage<f64>>,
    layout: &SecondOrderLayout<'_>,
    terms: &[f64],
    h: f64,
) -> Result<(), AnalysisError> {
    for (bodies, block) in layout.stiffness(terms) {
        let bodies = bodies.as_slice();
        let n = 6 * bodies.len();
        for (i, &a) in bodies.iter().enumerate() {
            for (j, &b) in bodies.iter().enumerate() {
                let out = kkt.block_mut(a, b).ok_or_else(missing)?;
                for r in 0..6 {
                    for col in 0..6 {
                        out[6 * r + col] += h * block.get((6 * i + r) * n + 6 * j + col).copied().unwrap_or(0.0);
                    }
                }
            }
        }
    }
    Ok(())
}

/// Every body-body block `(a, b)` of the pattern (of the `bodies` body
/// nodes; fill blocks, still zero, included) times `T_b` on the right (`T_b`
/// the right Jacobian of body `b`'s rotation update on its rotation columns).
pub(super) fn times_update(
    kkt: &mut Kkt<f64, impl KktStorage<f64>>,
    bodies: usize,
    t: &[Matrix3<f64>],
) -> Result<(), AnalysisError> {
    kkt.for_each_body_block(bodies, |_, b, out| {
        let jr = t.get(b).copied().unwrap_or_else(Matrix3::identity);
        for r in 0..6 {
            let row = [3, 4, 5].map(|k| out[6 * r + k]);
            for k in 0..3 {
                out[6 * r + 3 + k] = row[0] * jr[(0, k)] + row[1] * jr[(1, k)] + row[2] * jr[(2, k)];
            }
        }
    });
    Ok(())
}

/// `c₁ M − c₂ Q_v` of the gyroscopic term, body by body.
pub(super) fn add_mass<const NB: usize>(
    kkt: &mut Kkt<f64, impl KktStorage<f64>>,
    inertias: &[crate::scene::BodyInertia; NB],
    state: &SystemState<NB>,
    c1: f64,
    c2: f64,
) -> Result<(), AnalysisError> {
    for (b, (inertia, body)) in inertias.iter().zip(&state.bodies).enumerate() {
        let out = kkt.block_mut(b, b).ok_or_else(missing)?;
        add3(out, 0, 0, &Matrix3::identity(), c1 * inertia.mass);
        add3(out, 3, 3, &inertia.inertia, c1);
        // ∂(−ω' × J ω')/∂ω' = (J ω')~ − ω̃' J.
        let w: Vector3<f64> = body.omega;
        add3(out, 3, 3, &((inertia.inertia * w).cross_matrix() - w.cross_matrix() * inertia.inertia), -c2);
    }
    Ok(())
}

/// `J T` (the joints' rows) and `Jᵀ` (their columns) from the Jacobian's
/// values, the `dropped` rows held as identity rows.
pub(super) fn add_rows<S: SparseJacobian<NB, NNZ>, const NB: usize, const NNZ: usize>(
    kkt: &mut Kkt<f64, impl KktStorage<f64>>,
    values: &[f64; NNZ],
    row_joint: &[(usize, usize)],
    dropped: &[usize],
    t: &[Matrix3<f64>],
) -> Result<(), AnalysisError> {
    for (r, (window, &(joint, local))) in S::ROW_STARTS.windows(2).zip(row_joint).enumerate() {
        if dropped.binary_search(&r).is_ok() {
            if let Some(x) = kkt.block_mut(joint, joint).ok_or_else(missing)?.get_mut(6 * local + local) {
                *x = 1.0;
            }
            continue;
        }
        for (&col, &v) in S::COLUMNS.iter().zip(values.iter()).take(window[1]).skip(window[0]) {
            let (b, k) = (col / 6, col % 6);
            if let Some(x) = kkt.block_mut(b, joint).ok_or_else(missing)?.get_mut(6 * k + local) {
                *x = v;
            }
            let row = kkt.block_mut(joint, b).ok_or_else(missing)?;
            if k < 3 {
                if let Some(x) = row.get_mut(6 * local + k) {
                    *x = v;
                }
            } else {
                let jr = t.get(b).copied().unwrap_or_else(Matrix3::identity);
                for l in 0..3 {
                    if let Some(x) = row.get_mut(6 * local + 3 + l) {
                        *x += v * jr[(k - 3, l)];
                    }
                }
            }
        }
    }
    Ok(())
}

/// Adds `scale ×` a spring-damper's `∂Q/∂q` (`velocity` false) or `∂Q/∂v`
/// on the blocks of its bodies.
pub(super) fn spring_blocks<const NB: usize>(
    kkt: &mut Kkt<f64, impl KktStorage<f64>>,
    spring: &crate::dynamics::SpringDamper,
    state: &SystemState<NB>,
    velocity: bool,
    scale: f64,
) -> Result<(), AnalysisError> {
    let mut ends: [Option<usize>; 2] = [spring.a, spring.b].map(|e| match e {
        Attachment::Body { body, .. } => Some(body),
        Attachment::Ground(_) => None,
    });
    if ends[0] == ends[1] {
        ends[1] = None;
    }
    for &b in ends.iter().flatten() {
        for k in 0..6 {
            let loads = spring_column::<NB>(spring, state, 6 * b + k, velocity);
            for &a in ends.iter().flatten() {
                let (Some(f), Some(t)) = (loads.force.get(a), loads.torque.get(a)) else { continue };
                let out = kkt.block_mut(a, b).ok_or_else(missing)?;
                for i in 0..3 {
                    out[6 * i + k] += scale * f[i];
                    out[6 * (3 + i) + k] += scale * t[i];
                }
            }
        }
    }
    Ok(())
}
