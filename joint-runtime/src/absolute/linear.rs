//! [`AbsoluteSimulation::linearise`] and [`AbsoluteSimulation::transition`]: the
//! dense path's linearisation and state-transition Jacobian
//! (`dynamics/linear.rs`, whose module docs give the equations) from the
//! block factor and the scene's sparse second-order terms.
//!
//! Both outputs are dense (`2n × 2n`, `2 NV × 2 NV`), so their pieces are
//! dense matrices on the heap rather than on the stack: `∂a/∂q` and `∂a/∂v`
//! column by column, each column one solve on the factor of `J M⁻¹ Jᵀ` the
//! dynamics at the state left, under the same rule for redundant rows. The
//! second-order terms are scattered from the sparse layout
//! ([`SecondOrderLayout`]); `∂Q/∂q` and `∂Q/∂v` are the dense path's columns
//! (user loads by their own derivative or by differences, springs and the
//! gyroscopic term exact). The work is `O(NV²)` solves' worth for the
//! linearisation and an `NV × NV` LU for the transition: what their outputs'
//! size costs anyway.

use alloc::vec;

use nalgebra::{DMatrix, SVector};

use super::AbsoluteSimulation;
use super::second_order::{RowTerm, SecondOrderLayout};
use super::simulation::Accelerations;
use super::solver::{j_mul, jt_mul};
use crate::analysis::{AnalysisError, apply_metric, velocity_vector};
use crate::dynamics::linear::{check_inputs, minimal, transition_matrix, update_times};
use crate::dynamics::{AppliedLoads, Linearisation, force_column, midpoint_state, update_blocks};
use crate::scene::{Scene, SparseJacobian, SystemState};

/// The linearised equations of motion at one state, dense: `δa` along any
/// `(δq, δv)` is [`AbsoluteSimulation::accelerations`] of
/// `R1 = R1q δq + R1v δv` and `R2 = R2q δq + R2v δv` (as the dense path's
/// `Tangent`).
struct DenseTangent {
    /// `Q_q − K`, `NV × NV`.
    r1q: DMatrix<f64>,
    /// `Q_v`, `NV × NV`.
    r1v: DMatrix<f64>,
    /// `∂(γ̂ − J a)/∂q`, `γ̂` the stabilised right-hand side, `M × NV`.
    r2q: DMatrix<f64>,
    /// `∂γ̂/∂v`, `M × NV`.
    r2v: DMatrix<f64>,
}

impl<S, L, const NB: usize, const NV: usize, const M: usize, const NNZ: usize>
    AbsoluteSimulation<'_, S, L, NB, NV, M, NNZ>
where
    S: Scene<NB, NV, M> + SparseJacobian<NB, NNZ>,
    L: AppliedLoads<NB>,
{
    /// The linearised dynamics about `state` (which should satisfy the
    /// constraints: assemble it first), with `inputs` the generalised-force
    /// direction of each input (`NV × k`, columns laid out as `Q`: forces
    /// inertial, torques in body components; `k = 0` for none), in the minimal
    /// coordinates of [`Linearisation`](crate::dynamics::Linearisation); each
    /// column one solve on the block factor.
    ///
    /// # Errors
    /// [`AnalysisError::NoSecondOrder`] for a scene derived without
    /// `second_order`, [`AnalysisError::BadOption`] if `inputs` does not have
    /// `NV` rows, non-finite inputs, failures of the dynamics or of the SVD
    /// of J.
    ///
    /// ```
    /// use joint_runtime::dynamics::{NoLoads, Simulation, SimulationOptions};
    /// use joint_runtime::nalgebra::{DMatrix, UnitQuaternion, Vector3};
    /// use joint_runtime::{OmegaBody, Scene, SystemState};
    ///
    /// #[derive(Scene)]
    /// #[scene(coordinates = absolute, gravity = [0, 0, -9.81], second_order)]
    /// #[body(link, mass = 1.0, inertia = [0.0833, 0.0833, 0.001])]
    /// #[joint(hinge = revolute(ground, link), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0, 0, 0], rho2 = [0, 0, 0.5])]
    /// struct Pendulum;
    ///
    /// let rest = UnitQuaternion::identity();
    /// let link = OmegaBody::from_rotation(Vector3::new(0.0, 0.0, -0.5), &rest, Vector3::zeros(), Vector3::zeros());
    /// let hanging = SystemState { bodies: [link], t: 0.0 };
    /// let mut sim = Simulation::new(&Pendulum, NoLoads, &[], SimulationOptions::default())?;
    /// let lin = sim.linearise(&hanging, &DMatrix::zeros(6, 0))?;
    /// // One freedom, swinging at ω² = m g l / (I + m l²).
    /// assert_eq!(lin.freedoms, 1);
    /// let omega = (9.81 * 0.5 / (0.0833 + 0.25f64)).sqrt();
    /// for e in lin.eigenvalues()? {
    ///     assert!((e.im.abs() - omega).abs() < 1e-9 && e.re.abs() < 1e-9);
    /// }
    /// # Ok::<(), joint_runtime::analysis::AnalysisError>(())
    /// ```
    pub fn linearise(
        &mut self,
        state: &SystemState<NB>,
        inputs: &DMatrix<f64>,
    ) -> Result<Linearisation, AnalysisError> {
        check_inputs::<S, NB, NV, M>(state, inputs)?;
        let needed = AnalysisError::NoSecondOrder { needed_by: "the linearisation" };
        let d = self.solve(state, false, true)?;
        let t = self.dense_tangent(state, &d, needed)?;
        let (a_q, a_v) = (self.accelerations(&t.r1q, &t.r2q), self.accelerations(&t.r1v, &t.r2v));
        let a_u = self.accelerations(inputs, &DMatrix::zeros(M, inputs.ncols()));
        // `∂(J v)/∂q + ∂Φ_t/∂q`: the terms again with `u = v`.
        let v = velocity_vector::<NB, NV>(state);
        let layout = SecondOrderLayout::new(S::BLOCKS, S::BLOCK_BODIES);
        let mut terms = vec![0.0; layout.len()];
        if !self.scene.second_order_values(state, &d.lambda, &v, &mut terms) {
            return Err(needed);
        }
        let mut moved = DMatrix::zeros(M, NV);
        scatter_rows(&mut moved, &layout, &terms, &[(RowTerm::JacobianQ, 1.0), (RowTerm::PhiTQ, 1.0)]);
        minimal::<NB>(v.as_slice(), &a_q, &a_v, &self.dense_jacobian(state), &moved, a_u)
    }

    /// One step of the implicit midpoint rule from `state` (without
    /// projection, whatever the options say) and its state-transition
    /// Jacobian, exact: `(δq₁, δv₁) = Φ (δq₀, δv₀)` in the increments of
    /// [`Linearisation`](crate::dynamics::Linearisation) (`2 NV × 2 NV`), what
    /// an extended Kalman filter or an MPC propagates (the equations are in
    /// `dynamics/linear.rs`). The step is the midpoint rule's, whatever the
    /// configured integrator.
    ///
    /// # Errors
    /// [`AnalysisError::NoSecondOrder`] for a scene derived without
    /// `second_order`; as [`AbsoluteSimulation::step`] otherwise. On error `state` is
    /// unchanged.
    pub fn transition(&mut self, state: &mut SystemState<NB>, h: f64) -> Result<DMatrix<f64>, AnalysisError> {
        if !(h > 0.0 && h.is_finite()) {
            return Err(AnalysisError::BadOption { name: "step size" });
        }
        self.alpha_workspace()?;
        let (y0, d0) = self.step_start(state)?;
        let (y1, _, _) = self.step_midpoint(&y0, &d0.vdot, h)?;
        let w = (velocity_vector::<NB, NV>(&y0) + velocity_vector::<NB, NV>(&y1)) * 0.5;
        let mid = midpoint_state(&y0, &w, h);
        // The midpoint's dynamics under the step's rule, as the step's own.
        let d = self.solve(&mid, true, false)?;
        let needed = AnalysisError::NoSecondOrder { needed_by: "the state-transition Jacobian" };
        let t = self.dense_tangent(&mid, &d, needed)?;
        // ∂R/∂w = I − (h/2) ∂a/∂w with δq = (h/2) T δw, δv = δw.
        let turn = update_times::<NB>(&update_blocks::<NB, NV>(&w, 0.5 * h), 0.5 * h, NV);
        let (r1, r2) = (&t.r1q * &turn + &t.r1v, &t.r2q * &turn + &t.r2v);
        let r_w = DMatrix::identity(NV, NV) - self.accelerations(&r1, &r2) * (0.5 * h);
        let a_q = self.accelerations(&t.r1q, &t.r2q);
        let phi = transition_matrix::<NB, NV>(&w, h, r_w, &a_q)?;
        *state = y1;
        if let Some(ws) = self.alpha.as_deref_mut() {
            ws.history = None;
        }
        Ok(phi)
    }

    /// The linearised equations of motion at `state`, whose dynamics `d` the
    /// factor was just left holding; `needed` when the scene has no
    /// second-order terms.
    fn dense_tangent(
        &mut self,
        state: &SystemState<NB>,
        d: &Accelerations<NV, M>,
        needed: AnalysisError,
    ) -> Result<DenseTangent, AnalysisError> {
        let (alpha, beta) = self.options.stabilisation.coefficients();
        // ∂(J a)/∂q + 2α ∂(J v)/∂q in one: J u is linear in u.
        let u = d.vdot + velocity_vector::<NB, NV>(state) * (2.0 * alpha);
        let layout = SecondOrderLayout::new(S::BLOCKS, S::BLOCK_BODIES);
        let mut terms = vec![0.0; layout.len()];
        if !self.scene.second_order_values(state, &d.lambda, &u, &mut terms) {
            return Err(needed);
        }
        let (mut r1q, mut r1v) = (DMatrix::zeros(NV, NV), DMatrix::zeros(NV, NV));
        for c in 0..NV {
            let mut at = |velocity| force_column(&mut self.loads, self.springs, &self.inertias, state, c, velocity);
            let (q, v): (SVector<f64, NV>, SVector<f64, NV>) = (at(false), at(true));
            r1q.set_column(c, &q);
            r1v.set_column(c, &v);
        }
        for (bodies, block) in layout.stiffness(&terms) {
            let bodies = bodies.as_slice();
            let n = 6 * bodies.len();
            for (i, &a) in bodies.iter().enumerate() {
                for (j, &b) in bodies.iter().enumerate() {
                    for (r, c) in (0..6).flat_map(|r| (0..6).map(move |c| (r, c))) {
                        let k = block.get((6 * i + r) * n + 6 * j + c).copied().unwrap_or(0.0);
                        if let Some(x) = r1q.get_mut((6 * a + r, 6 * b + c)) {
                            *x -= k;
                        }
                    }
                }
            }
        }
        let (mut r2q, mut r2v) = (DMatrix::zeros(M, NV), DMatrix::zeros(M, NV));
        scatter_rows(
            &mut r2q,
            &layout,
            &terms,
            &[(RowTerm::GammaQ, 1.0), (RowTerm::JacobianQ, -1.0), (RowTerm::PhiTQ, -2.0 * alpha)],
        );
        scatter_rows(&mut r2v, &layout, &terms, &[(RowTerm::GammaV, 1.0)]);
        if alpha != 0.0 || beta != 0.0 {
            let j = self.dense_jacobian(state);
            r2q -= &j * (beta * beta);
            r2v -= j * (2.0 * alpha);
        }
        Ok(DenseTangent { r1q, r1v, r2q, r2v })
    }

    /// `δa` for the right-hand sides `r1` (`NV × K`) and `r2` (`M × K`), on
    /// the factor as the last dynamics left it: `δa = X − M⁻¹ Jᵀ δλ` with
    /// `X = M⁻¹ r1` and `(J M⁻¹ Jᵀ) δλ = J X − r2` (zero on dropped rows).
    fn accelerations(&mut self, r1: &DMatrix<f64>, r2: &DMatrix<f64>) -> DMatrix<f64> {
        let mut out = DMatrix::zeros(NV, r1.ncols());
        for (k, (c1, c2)) in r1.column_iter().zip(r2.column_iter()).enumerate() {
            let x = apply_metric::<NB, NV>(Some(&*self.inverse), &SVector::from_iterator(c1.iter().copied()));
            let mut b = j_mul::<S, NB, NNZ, NV, M>(self.solved_values(), &x);
            for (bi, r) in b.iter_mut().zip(c2.iter()) {
                *bi -= r;
            }
            self.solver.solve(b.as_mut_slice());
            let jt = jt_mul::<S, NB, NNZ, NV, M>(self.solved_values(), &b);
            out.set_column(k, &(x - apply_metric::<NB, NV>(Some(&*self.inverse), &jt)));
        }
        out
    }

    /// `J` at `state`, dense (`M × NV`), from its nonzero entries.
    fn dense_jacobian(&self, state: &SystemState<NB>) -> DMatrix<f64> {
        let values = self.scene.jacobian_values(state);
        let mut j = DMatrix::zeros(M, NV);
        for (r, w) in S::ROW_STARTS.windows(2).enumerate() {
            for (&c, &v) in S::COLUMNS.iter().zip(&values).take(w[1]).skip(w[0]) {
                if let Some(x) = j.get_mut((r, c)) {
                    *x = v;
                }
            }
        }
        j
    }
}

/// Adds `Σ scale × term` over each row's entries (its joint's bodies'
/// columns) to the dense `M × NV` matrix `out`.
fn scatter_rows(out: &mut DMatrix<f64>, layout: &SecondOrderLayout<'_>, terms: &[f64], parts: &[(RowTerm, f64)]) {
    for joint in layout.joints() {
        let (bodies, w) = (joint.bodies.as_slice(), joint.bodies.width());
        for (local, r) in joint.rows.clone().enumerate() {
            for &(term, scale) in parts {
                let at = layout.section_start(term) + joint.section + local * w;
                let Some(entries) = terms.get(at..at + w) else { continue };
                for (i, &b) in bodies.iter().enumerate() {
                    for k in 0..6 {
                        if let (Some(x), Some(&e)) = (out.get_mut((r, 6 * b + k)), entries.get(6 * i + k)) {
                            *x += scale * e;
                        }
                    }
                }
            }
        }
    }
}
