//! The implicit midpoint rule on the sparse path, with its exact Newton
//! matrix in saddle-point form.
//!
//! The dense rule (`dynamics/newton_matrix.rs`) forms `∂R/∂w = I − (h/2) ∂a/∂w`
//! of the residual `R(w) = w − v_n − (h/2) a(q_n ⊕ (h/2) w, w)`: dense, since
//! every acceleration depends on every velocity through `λ`. Keeping `δλ` as
//! an unknown instead, the linearised equations of motion at the midpoint,
//! with `δa = (2/h)(δw + R)` for the Newton step and scaled by `h/2`, are
//!
//! ```text
//! [ M + (h²/4)(K − Q_q) T − (h/2) Q_v              Jᵀ ] [ δw ]   [ −M R ]
//! [ J + (h²/4)(∂(J a)/∂q − ∂γ/∂q) T − (h/2) ∂γ/∂v   0 ] [ δμ ] = [ −J R ]
//! ```
//!
//! (`δμ = (h/2) δλ`, `T` the right Jacobians of the rotation update
//! `q_n ⊕ (h/2) w`): generalised-α's pattern exactly, bodies and joints as
//! nodes, so the same [`Kkt`](super::kkt::Kkt) factorises it. `K`,
//! `∂(J a)/∂q`, `∂γ/∂q` and `∂γ/∂v` are the scene's sparse second-order terms
//! (with `u = a`; or their differences, `differences.rs`); with Baumgarte
//! stabilisation the second row takes the stabilised `γ̂`'s derivatives, as
//! the dense matrix does. `Q_q`, `Q_v` are the spring-dampers' and the
//! gyroscopic terms, exact, and the user loads' on the pattern (`loads.rs`).
//! Redundant rows are
//! held at `δμ = 0`, the rule of the step's start. Newton is modified as on
//! the dense path: the matrix is rebuilt only when convergence slows.

use nalgebra::{Matrix3, SVector};

use super::AbsoluteSimulation;
use super::alpha::{add_mass, add_rows, add_stiffness, missing, spring_blocks, times_update};
use super::buf::{Boxed, at_rest, boxed_with, zero_state, zeros};
use super::kkt::{Kkt, KktStorage};
use super::second_order::{RowTerm, SecondOrderLayout, TermStorage};
use super::simulation::Accelerations;
use super::simulation::with_taken;
use super::solver::j_mul_into;
use crate::analysis::{AnalysisError, velocity_vector_into};
use crate::dynamics::{
    AppliedLoads, ModifiedNewton, NewtonMatrix, energy_balance, mass_times_into, midpoint_end_into,
    midpoint_state_into, update_blocks_into,
};
use crate::scene::{Scene, SparseJacobian, SystemState};

/// The midpoint's state, its dynamics and its Jacobian's values at one `w`.
struct Midpoint<const NB: usize, const NV: usize, const M: usize, const NNZ: usize> {
    state: SystemState<NB>,
    dynamics: Accelerations<NV, M>,
    values: [f64; NNZ],
}

/// The midpoint rule's iterate: the start's velocities `v0`, the midpoint
/// velocity `w`, the residual `R`, the correction `δw` and the midpoint.
/// Boxed, made with the implicit integrators' pattern (in `new`, or at the
/// first implicit step of a simulation made for RK4) and kept: a step's
/// frames hold no vector of the scene's size but its end.
pub(super) struct MidpointWork<const NB: usize, const NV: usize, const M: usize, const NNZ: usize> {
    /// The step's start (normalised), its accelerations, and its end.
    y0: SystemState<NB>,
    a0: SVector<f64, NV>,
    end: SystemState<NB>,
    v0: SVector<f64, NV>,
    w: SVector<f64, NV>,
    r: SVector<f64, NV>,
    dw: SVector<f64, NV>,
    mid: Midpoint<NB, NV, M, NNZ>,
    /// Scratch: `u` of the second-order terms (and the end's velocities,
    /// the midpoint's), `M R` (and the user's forces), `J R` (and `J w`),
    /// the rotation updates `T`.
    u: SVector<f64, NV>,
    mr: SVector<f64, NV>,
    jr: SVector<f64, M>,
    t: [Matrix3<f64>; NB],
}

impl<const NB: usize, const NV: usize, const M: usize, const NNZ: usize> MidpointWork<NB, NV, M, NNZ> {
    /// Zeros, states at rest and identity updates; written in the heap
    /// (`buf`).
    pub(super) fn new() -> Boxed<Self> {
        let mut w = boxed_with(|| {
            const {
                let dynamics = Accelerations { vdot: zeros(), lambda: zeros() };
                MidpointWork {
                    y0: zero_state(),
                    a0: zeros(),
                    end: zero_state(),
                    v0: zeros(),
                    w: zeros(),
                    r: zeros(),
                    dw: zeros(),
                    mid: Midpoint { state: zero_state(), dynamics, values: [0.0; NNZ] },
                    u: zeros(),
                    mr: zeros(),
                    jr: zeros(),
                    t: [zeros(); NB],
                }
            }
        });
        let MidpointWork { y0, end, mid, t, .. } = &mut *w;
        for state in [y0, end, &mut mid.state] {
            at_rest(state);
        }
        t.fill(Matrix3::identity());
        w
    }
}

impl<S, L, const NB: usize, const NV: usize, const M: usize, const NNZ: usize>
    AbsoluteSimulation<'_, S, L, NB, NV, M, NNZ>
where
    S: Scene<NB, NV, M> + SparseJacobian<NB, NNZ>,
    L: AppliedLoads<NB>,
{
    /// One step of the implicit midpoint rule from `y0` (normalised, its rule
    /// of redundant rows just factorised, its accelerations `vdot`); returns
    /// the state, Newton iterations and iteration matrices built (the
    /// state-transition Jacobian's nominal step, `linear.rs`).
    #[cfg(feature = "alloc")]
    #[inline(never)]
    pub(super) fn step_midpoint(
        &mut self,
        y0: &SystemState<NB>,
        vdot: &SVector<f64, NV>,
        h: f64,
    ) -> Result<(SystemState<NB>, usize, usize), AnalysisError> {
        // Made with the implicit pattern (`alpha_workspace`): no constructor
        // (and its temporaries) in this frame.
        with_taken(
            self,
            |s| &mut s.midpoint,
            |sim, m| {
                m.y0.clone_from(y0);
                m.a0.copy_from(vdot);
                sim.midpoint_newton(m, h).map(|(i, n)| (m.end, i, n))
            },
        )
    }

    /// An implicit midpoint step from `state` (checked, normalised and
    /// solved at into the boxed work), projected, into `state`: no state or
    /// vector of the scene's size in this frame.
    pub(super) fn midpoint_in_work(
        &mut self,
        state: &mut SystemState<NB>,
        h: f64,
        report: &mut crate::dynamics::StepReport,
    ) -> Result<(), AnalysisError> {
        with_taken(self, |s| &mut s.midpoint, |sim, m| sim.midpoint_started(m, state, h, report))
    }

    /// [`midpoint_in_work`](Self::midpoint_in_work) on the taken-out work `m`.
    fn midpoint_started(
        &mut self,
        m: &mut MidpointWork<NB, NV, M, NNZ>,
        state: &mut SystemState<NB>,
        h: f64,
        report: &mut crate::dynamics::StepReport,
    ) -> Result<(), AnalysisError> {
        self.begin(state, &mut m.y0)?;
        m.a0.copy_from(self.solved().0);
        (report.newton_iterations, report.newton_matrices) = self.midpoint_newton(m, h)?;
        self.finish(&mut m.end, report)?;
        state.clone_from(&m.end);
        Ok(())
    }

    /// The midpoint rule's Newton iteration from `m.y0` (accelerations
    /// `m.a0`) on the iterate `m`, then the step's end into `m.end`, checked
    /// against the energy balance. Returns the Newton iterations and
    /// iteration matrices built.
    fn midpoint_newton(
        &mut self,
        m: &mut MidpointWork<NB, NV, M, NNZ>,
        h: f64,
    ) -> Result<(usize, usize), AnalysisError> {
        velocity_vector_into(&m.y0, &mut m.v0);
        // Explicit predictor.
        for ((w, v), a) in m.w.as_mut_slice().iter_mut().zip(m.v0.as_slice().iter()).zip(m.a0.as_slice().iter()) {
            *w = v + a * (0.5 * h);
        }
        self.midpoint_residual(m, h)?;
        let mut newton = ModifiedNewton::new(&self.options);
        loop {
            newton.next()?;
            if newton.stale() {
                self.midpoint_matrix(m, h)?;
                newton.built();
            }
            self.midpoint_solve(m)?;
            m.w += &m.dw;
            self.midpoint_residual(m, h)?;
            if newton.converged(m.dw.norm(), 1.0 + m.w.norm())? {
                break;
            }
        }
        self.midpoint_end(m, h)?;
        Ok(newton.counts())
    }

    /// The step's end from the converged iterate into `m.end`, refused if it
    /// gains energy no work explains (a spurious Newton solution). In a frame
    /// of its own, apart from the iteration's.
    #[inline(never)]
    fn midpoint_end(&mut self, m: &mut MidpointWork<NB, NV, M, NNZ>, h: f64) -> Result<(), AnalysisError> {
        midpoint_end_into(&m.y0, &m.v0, &m.w, h, &mut m.u, &mut m.end);
        // The work of `dynamics::midpoint_work`: the user's loads and the
        // constraint forces at the midpoint.
        j_mul_into::<S, NB, NNZ>(&m.mid.values, m.w.as_slice(), m.jr.as_mut_slice());
        let constraint_power = -m.mid.dynamics.lambda.dot(&m.jr);
        self.user_forces_into(&m.mid.state, &mut m.mr);
        velocity_vector_into(&m.mid.state, &mut m.u);
        let work = h * (m.mr.dot(&m.u) + constraint_power);
        energy_balance(&self.energy(&m.y0), &self.energy(&m.end), work)
    }

    /// `R = w − v_n − (h/2) a(q_n ⊕ (h/2) w, w)` under the step's rule, and the
    /// midpoint it was evaluated at, into `m`.
    #[inline(never)]
    fn midpoint_residual(&mut self, m: &mut MidpointWork<NB, NV, M, NNZ>, h: f64) -> Result<(), AnalysisError> {
        midpoint_state_into(&m.y0, &m.w, h, &mut m.mid.state);
        self.solve_in_work(&m.mid.state, true, false)?;
        let (vdot, lambda) = self.solved();
        m.mid.dynamics.vdot.copy_from(vdot);
        m.mid.dynamics.lambda.copy_from(lambda);
        self.scene.jacobian_values_into(&m.mid.state, &mut m.mid.values);
        let vdot = &m.mid.dynamics.vdot;
        for (((r, w), v), a) in m.r.iter_mut().zip(m.w.iter()).zip(m.v0.iter()).zip(vdot.iter()) {
            *r = w - v - a * (0.5 * h);
        }
        Ok(())
    }

    /// Assembles and factorises the saddle-point Newton matrix at the midpoint
    /// `m.mid` of the velocity `m.w` (see the module docs).
    #[inline(never)]
    fn midpoint_matrix(&mut self, m: &mut MidpointWork<NB, NV, M, NNZ>, h: f64) -> Result<(), AnalysisError> {
        update_blocks_into(&m.w, 0.5 * h, &mut m.t);
        let quarter = 0.25 * h * h;
        let dropped = self.solver.factor.dropped();
        let by_differences = self.options.newton_matrix == NewtonMatrix::FiniteDifferences;
        let stabilisation = self.options.stabilisation.coefficients();
        let ws = self.alpha.as_deref_mut().ok_or(AnalysisError::BadOption { name: "integrator" })?;
        let (state, d) = (&m.mid.state, &m.mid.dynamics);
        // ∂(J a)/∂q + 2α ∂(J v)/∂q in one: J u is linear in u.
        velocity_vector_into(state, &mut m.u);
        for (u, a) in m.u.as_mut_slice().iter_mut().zip(d.vdot.as_slice().iter()) {
            *u = a + *u * (2.0 * stabilisation.0);
        }
        ws.fill_terms(self.scene, state, &d.lambda, &m.u, by_differences)?;
        let kkt = &mut ws.kkt;
        kkt.clear();
        // (h²/4)(K − Q_q), times T; then M − (h/2) Q_v; then J with its terms, and Jᵀ.
        add_stiffness(kkt, &ws.layout, ws.terms.values(), quarter)?;
        for s in self.springs {
            spring_blocks(kkt, s, state, false, -quarter)?;
        }
        ws.user.add_blocks::<L, NV>(kkt, &mut self.loads, self.springs, state, false, -quarter)?;
        times_update(kkt, NB, &m.t)?;
        for s in self.springs {
            spring_blocks(kkt, s, state, true, -0.5 * h)?;
        }
        ws.user.add_blocks::<L, NV>(kkt, &mut self.loads, self.springs, state, true, -0.5 * h)?;
        add_mass(kkt, &self.inertias, state, 1.0, 0.5 * h)?;
        // J itself on the velocity columns (no rotation update: an empty `T`).
        add_rows::<S, NB, NNZ>(kkt, &m.mid.values, &ws.row_joint, dropped, &[])?;
        let rows = RowTerms { layout: ws.layout, terms: ws.terms.values(), dropped, stabilisation };
        add_row_terms::<S, NB, NNZ>(kkt, &rows, &m.mid.values, &m.t, (quarter, 0.5 * h))?;
        ws.kkt.factor().map_err(AnalysisError::from)
    }

    /// The Newton correction `δw` for the residual `m.r` into `m.dw`: the
    /// saddle-point matrix solved for `[−M R; −J R]` (zero on the dropped rows).
    #[inline(never)]
    fn midpoint_solve(&mut self, m: &mut MidpointWork<NB, NV, M, NNZ>) -> Result<(), AnalysisError> {
        mass_times_into(&self.inertias, &m.r, &mut m.mr);
        j_mul_into::<S, NB, NNZ>(&m.mid.values, m.r.as_slice(), m.jr.as_mut_slice());
        let dropped = self.solver.factor.dropped();
        let ws = self.alpha.as_deref_mut().ok_or(AnalysisError::BadOption { name: "integrator" })?;
        for (out, x) in ws.rhs.head.iter_mut().zip(m.mr.as_slice().iter()) {
            *out = -x;
        }
        for (row, (out, x)) in ws.rhs.tail.iter_mut().zip(m.jr.as_slice().iter()).enumerate() {
            *out = if dropped.binary_search(&row).is_ok() { 0.0 } else { -x };
        }
        ws.kkt.solve(&mut ws.rhs);
        for (d, &x) in m.dw.as_mut_slice().iter_mut().zip(ws.rhs.head.iter()) {
            *d = x;
        }
        if !m.dw.as_slice().iter().all(|x| x.is_finite()) {
            return Err(AnalysisError::NonFiniteOutput { quantity: "Newton correction", row: None });
        }
        Ok(())
    }
}

/// What [`add_row_terms`] reads: the second-order terms (with
/// `u = a + 2α v`) in their layout, the dropped rows and Baumgarte's
/// `(α, β)` (zeros without stabilisation).
pub(super) struct RowTerms<'a> {
    pub(super) layout: SecondOrderLayout<'static>,
    pub(super) terms: &'a [f64],
    pub(super) dropped: &'a [usize],
    pub(super) stabilisation: (f64, f64),
}

/// Adds `c_q (∂(J u)/∂q − ∂γ̂/∂q) T − c_v ∂γ̂/∂v` to each kept row's blocks
/// over its joint's bodies (`T` on the rotation columns; the midpoint rule's
/// `c_q = h²/4`, `c_v = h/2`), with the stabilised
/// `γ̂ = γ − 2α (J v + Φ_t) − β² Φ`: `∂γ̂/∂q` adds `−2α ∂Φ_t/∂q − β² J` (the
/// `∂(J v)/∂q` part is in `u`), `∂γ̂/∂v` adds `−2α J`.
pub(super) fn add_row_terms<S: SparseJacobian<NB, NNZ>, const NB: usize, const NNZ: usize>(
    kkt: &mut Kkt<f64, impl KktStorage<f64>>,
    rows: &RowTerms<'_>,
    values: &[f64; NNZ],
    t: &[Matrix3<f64>],
    (cq, cv): (f64, f64),
) -> Result<(), AnalysisError> {
    let (alpha, beta) = rows.stabilisation;
    let layout = rows.layout;
    let section = |term| layout.section_start(term);
    let starts = [RowTerm::JacobianQ, RowTerm::GammaQ, RowTerm::GammaV, RowTerm::PhiTQ].map(section);
    for joint_terms in layout.joints() {
        let (bodies, w, joint) = (joint_terms.bodies, joint_terms.bodies.width(), NB + joint_terms.index);
        let bodies = bodies.as_slice();
        for (local, r) in joint_terms.rows.clone().enumerate() {
            if rows.dropped.binary_search(&r).is_ok() {
                continue;
            }
            let at = joint_terms.section + local * w;
            let entries = |start: usize| rows.terms.get(start + at..start + at + w).ok_or_else(missing);
            let [ja, gq, gv, pt] = [entries(starts[0])?, entries(starts[1])?, entries(starts[2])?, entries(starts[3])?];
            let c = [cq, cv, alpha, beta];
            add_row::<S, NB, NNZ>(kkt, (r, joint, local), bodies, [ja, gq, gv, pt], (values, t), c)?;
        }
    }
    Ok(())
}

/// [`add_row_terms`] for row `r`, row `local` of joint node `joint`, whose
/// terms over `bodies`' columns are `[∂(J u)/∂q, ∂γ/∂q, ∂γ/∂v, ∂Φ_t/∂q]`,
/// with `J`'s values and the rotation updates, and `[c_q, c_v, α, β]`.
fn add_row<S: SparseJacobian<NB, NNZ>, const NB: usize, const NNZ: usize>(
    kkt: &mut Kkt<f64, impl KktStorage<f64>>,
    (r, joint, local): (usize, usize, usize),
    bodies: &[usize],
    [ja, gq, gv, pt]: [&[f64]; 4],
    (values, t): (&[f64; NNZ], &[Matrix3<f64>]),
    [cq, cv, alpha, beta]: [f64; 4],
) -> Result<(), AnalysisError> {
    // The row of J over the joint's bodies' columns.
    let mut j = [0.0; 12];
    if let (Some(&a), Some(&e)) = (S::ROW_STARTS.get(r), S::ROW_STARTS.get(r + 1)) {
        for (&c, &v) in S::COLUMNS.iter().zip(values).take(e).skip(a) {
            if let Some(x) = bodies.iter().position(|&b| b == c / 6).and_then(|i| j.get_mut(6 * i + c % 6)) {
                *x = v;
            }
        }
    }
    for (i, &b) in bodies.iter().enumerate() {
        let q = |k: usize| {
            let at = 6 * i + k;
            let e = |x: &[f64]| x.get(at).copied().unwrap_or(0.0);
            cq * (e(ja) - e(gq) + 2.0 * alpha * e(pt) + beta * beta * e(&j))
        };
        let jr = t.get(b).copied().unwrap_or_else(Matrix3::identity);
        let row = kkt.block_mut(joint, b).ok_or_else(missing)?;
        for k in 0..6 {
            let dq = if k < 3 { q(k) } else { (0..3).map(|m| q(3 + m) * jr[(m, k - 3)]).sum() };
            let dv = cv
                * (2.0 * alpha * j.get(6 * i + k).copied().unwrap_or(0.0) - gv.get(6 * i + k).copied().unwrap_or(0.0));
            if let Some(x) = row.get_mut(6 * local + k) {
                *x += dq + dv;
            }
        }
    }
    Ok(())
}
