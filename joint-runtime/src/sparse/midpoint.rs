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

use super::SparseSimulation;
use super::alpha::{add_mass, add_rows, add_stiffness, missing, spring_blocks, times_update};
use super::kkt::Kkt;
use super::second_order::{RowTerm, SecondOrderLayout};
use super::simulation::SparseDynamics;
use super::solver::j_mul;
use crate::analysis::{AnalysisError, velocity_vector};
use crate::dynamics::{
    AppliedLoads, ModifiedNewton, NewtonMatrix, energy_balance, mass_times, midpoint_end, midpoint_state,
    midpoint_work, update_blocks,
};
use crate::scene::{Scene, SparseJacobian, SystemState};

/// The midpoint's state, its dynamics and its Jacobian's values at one `w`.
struct Midpoint<const NB: usize, const NV: usize, const M: usize, const NNZ: usize> {
    state: SystemState<NB>,
    dynamics: SparseDynamics<NV, M>,
    values: [f64; NNZ],
}

impl<S, L, const NB: usize, const NV: usize, const M: usize, const NNZ: usize>
    SparseSimulation<'_, S, L, NB, NV, M, NNZ>
where
    S: Scene<NB, NV, M> + SparseJacobian<NB, NNZ>,
    L: AppliedLoads<NB>,
{
    /// One step of the implicit midpoint rule from `y0` (normalised, its rule
    /// of redundant rows just factorised, its accelerations `vdot`); returns
    /// the state, Newton iterations and iteration matrices built.
    #[inline(never)]
    pub(super) fn step_midpoint(
        &mut self,
        y0: &SystemState<NB>,
        vdot: &SVector<f64, NV>,
        h: f64,
    ) -> Result<(SystemState<NB>, usize, usize), AnalysisError> {
        let v0 = velocity_vector::<NB, NV>(y0);
        // Explicit predictor.
        let mut w = v0 + vdot * (0.5 * h);
        let (mut r, mut mid) = self.midpoint_residual(y0, &v0, &w, h)?;
        let mut newton = ModifiedNewton::new(&self.options);
        loop {
            newton.next()?;
            if newton.stale() {
                self.midpoint_matrix(&mid, &w, h)?;
                newton.built();
            }
            let dw = self.midpoint_solve(&mid.values, &r)?;
            w += dw;
            (r, mid) = self.midpoint_residual(y0, &v0, &w, h)?;
            if newton.converged(dw.norm(), 1.0 + w.norm())? {
                break;
            }
        }
        let end = midpoint_end(y0, &v0, &w, h);
        let constraint_power = -mid.dynamics.lambda.dot(&j_mul::<S, NB, NNZ, NV, M>(&mid.values, &w));
        let work = midpoint_work::<L, NB, NV>(&mut self.loads, &self.inertias, &mid.state, constraint_power, h);
        energy_balance(&self.energy(y0), &self.energy(&end), work)?;
        let (iterations, matrices) = newton.counts();
        Ok((end, iterations, matrices))
    }

    /// `R = w − v_n − (h/2) a(q_n ⊕ (h/2) w, w)` under the step's rule, and the
    /// midpoint it was evaluated at.
    fn midpoint_residual(
        &mut self,
        y0: &SystemState<NB>,
        v0: &SVector<f64, NV>,
        w: &SVector<f64, NV>,
        h: f64,
    ) -> Result<(SVector<f64, NV>, Midpoint<NB, NV, M, NNZ>), AnalysisError> {
        let state = midpoint_state(y0, w, h);
        let dynamics = self.solve(&state, true, false)?;
        let values = self.scene.jacobian_values(&state);
        Ok((w - v0 - dynamics.vdot * (0.5 * h), Midpoint { state, dynamics, values }))
    }

    /// Assembles and factorises the saddle-point Newton matrix at the midpoint
    /// `mid` of the velocity `w` (see the module docs).
    fn midpoint_matrix(
        &mut self,
        mid: &Midpoint<NB, NV, M, NNZ>,
        w: &SVector<f64, NV>,
        h: f64,
    ) -> Result<(), AnalysisError> {
        let t = update_blocks::<NB, NV>(w, 0.5 * h);
        let quarter = 0.25 * h * h;
        let dropped = self.solver.factor.dropped();
        let by_differences = self.options.newton_matrix == NewtonMatrix::FiniteDifferences;
        let stabilisation = self.options.stabilisation.coefficients();
        let ws = self.alpha.as_mut().ok_or(AnalysisError::BadOption { name: "integrator" })?;
        let (state, d) = (&mid.state, &mid.dynamics);
        // ∂(J a)/∂q + 2α ∂(J v)/∂q in one: J u is linear in u.
        let u = d.vdot + velocity_vector::<NB, NV>(state) * (2.0 * stabilisation.0);
        ws.fill_terms(self.scene, state, &d.lambda, &u, by_differences)?;
        let kkt = &mut ws.kkt;
        kkt.clear();
        // (h²/4)(K − Q_q), times T; then M − (h/2) Q_v; then J with its terms, and Jᵀ.
        add_stiffness(kkt, &ws.layout, &ws.terms, quarter)?;
        for s in self.springs {
            spring_blocks(kkt, s, state, false, -quarter)?;
        }
        ws.user.add_blocks::<L, NB, NV>(kkt, &mut self.loads, state, false, -quarter)?;
        times_update(kkt, &ws.body_pairs, &t)?;
        for s in self.springs {
            spring_blocks(kkt, s, state, true, -0.5 * h)?;
        }
        ws.user.add_blocks::<L, NB, NV>(kkt, &mut self.loads, state, true, -0.5 * h)?;
        add_mass(kkt, &self.inertias, state, 1.0, 0.5 * h)?;
        add_rows::<S, NB, NNZ>(kkt, &mid.values, &ws.row_joint, dropped, &[Matrix3::identity(); NB])?;
        let rows = RowTerms { layout: &ws.layout, terms: &ws.terms, row_joint: &ws.row_joint, dropped, stabilisation };
        add_row_terms::<S, NB, NNZ>(kkt, &rows, &mid.values, &t, (quarter, 0.5 * h))?;
        ws.kkt.factor().map_err(AnalysisError::from)
    }

    /// The Newton correction `δw` for the residual `r`: the saddle-point
    /// matrix solved for `[−M R; −J R]` (zero on the dropped rows).
    fn midpoint_solve(&mut self, values: &[f64; NNZ], r: &SVector<f64, NV>) -> Result<SVector<f64, NV>, AnalysisError> {
        let (mr, jr) = (mass_times(&self.inertias, r), j_mul::<S, NB, NNZ, NV, M>(values, r));
        let dropped = self.solver.factor.dropped();
        let ws = self.alpha.as_mut().ok_or(AnalysisError::BadOption { name: "integrator" })?;
        for (out, x) in ws.rhs.iter_mut().zip(mr.iter()) {
            *out = -x;
        }
        for (row, x) in jr.iter().enumerate() {
            if let Some(out) = ws.rhs.get_mut(NV + row) {
                *out = if dropped.binary_search(&row).is_ok() { 0.0 } else { -x };
            }
        }
        ws.kkt.solve(&mut ws.rhs);
        let dw = SVector::<f64, NV>::from_column_slice(&ws.rhs[..NV]);
        if !dw.iter().all(|x| x.is_finite()) {
            return Err(AnalysisError::NonFiniteOutput { quantity: "Newton correction", row: None });
        }
        Ok(dw)
    }
}

/// What [`add_row_terms`] reads: the second-order terms (with
/// `u = a + 2α v`), each row's joint, the dropped rows and Baumgarte's
/// `(α, β)` (zeros without stabilisation).
pub(super) struct RowTerms<'a> {
    pub(super) layout: &'a SecondOrderLayout,
    pub(super) terms: &'a [f64],
    pub(super) row_joint: &'a [(usize, usize)],
    pub(super) dropped: &'a [usize],
    pub(super) stabilisation: (f64, f64),
}

/// Adds `c_q (∂(J u)/∂q − ∂γ̂/∂q) T − c_v ∂γ̂/∂v` to each kept row's blocks
/// over its joint's bodies (`T` on the rotation columns; the midpoint rule's
/// `c_q = h²/4`, `c_v = h/2`), with the stabilised
/// `γ̂ = γ − 2α (J v + Φ_t) − β² Φ`: `∂γ̂/∂q` adds `−2α ∂Φ_t/∂q − β² J` (the
/// `∂(J v)/∂q` part is in `u`), `∂γ̂/∂v` adds `−2α J`.
pub(super) fn add_row_terms<S: SparseJacobian<NB, NNZ>, const NB: usize, const NNZ: usize>(
    kkt: &mut Kkt,
    rows: &RowTerms<'_>,
    values: &[f64; NNZ],
    t: &[Matrix3<f64>; NB],
    (cq, cv): (f64, f64),
) -> Result<(), AnalysisError> {
    let (alpha, beta) = rows.stabilisation;
    for (r, &(joint, local)) in rows.row_joint.iter().enumerate() {
        if rows.dropped.binary_search(&r).is_ok() {
            continue;
        }
        let entries = |term| rows.layout.row(rows.terms, term, r).ok_or_else(missing);
        let ((bodies, ja), (_, gq), (_, gv), (_, pt)) = (
            entries(RowTerm::JacobianQ)?,
            entries(RowTerm::GammaQ)?,
            entries(RowTerm::GammaV)?,
            entries(RowTerm::PhiTQ)?,
        );
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
                cq * (ja[at] - gq[at] + 2.0 * alpha * pt[at] + beta * beta * j.get(at).copied().unwrap_or(0.0))
            };
            let jr = t.get(b).copied().unwrap_or_else(Matrix3::identity);
            let row = kkt.block_mut(joint, b).ok_or_else(missing)?;
            for k in 0..6 {
                let dq = if k < 3 { q(k) } else { (0..3).map(|m| q(3 + m) * jr[(m, k - 3)]).sum() };
                let dv = cv * (2.0 * alpha * j.get(6 * i + k).copied().unwrap_or(0.0) - gv[6 * i + k]);
                row[6 * local + k] += dq + dv;
            }
        }
    }
    Ok(())
}
