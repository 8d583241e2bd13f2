//! Generalised-α's steps on the dense path.

use nalgebra::{SMatrix, SVector};

use super::newton_matrix::times_update;
use super::{DenseSimulation, StepRule};
use crate::analysis::{AnalysisError, apply_increment, check_output, velocity_vector};
use crate::dynamics::generalised_alpha::*;
use crate::dynamics::newton_matrix::update_blocks;
use crate::dynamics::{AppliedLoads, ModifiedNewton, generalised_forces};
use crate::linalg::Lu;
use crate::scene::{Scene, SystemState};

impl<S, L, const NB: usize, const NV: usize, const M: usize> DenseSimulation<'_, S, L, NB, NV, M>
where
    S: Scene<NB, NV, M>,
    L: AppliedLoads<NB>,
{
    /// The history at `state`: the one the last step left if the step starts
    /// where that one ended (`continuing`), otherwise accelerations and
    /// multipliers from the dynamics.
    pub(super) fn alpha_history(
        &mut self,
        state: &SystemState<NB>,
        continuing: bool,
        rule: &mut StepRule<M>,
    ) -> Result<AlphaHistory<NB, NV, M>, AnalysisError> {
        if let (true, Some(h)) = (continuing, self.history) {
            return Ok(h);
        }
        let d = self.solve(state, Some(rule))?;
        Ok(AlphaHistory { state: *state, vdot: d.vdot, a: d.vdot, lambda: d.lambda })
    }

    /// One step of generalised-α; returns the Newton iterations and the
    /// iteration matrices built.
    pub(super) fn step_alpha(
        &mut self,
        state: &mut SystemState<NB>,
        h: f64,
        continuing: bool,
        rule: &mut StepRule<M>,
    ) -> Result<(usize, usize), AnalysisError> {
        let c = Coefficients::checked(self.options.spectral_radius)?;
        let y0 = *state;
        let past = self.alpha_history(&y0, continuing, rule)?;
        let v0 = velocity_vector::<NB, NV>(&y0);
        // Predictor: v̇_{n+1} = v̇_n, λ_{n+1} = λ_n.
        let mut it = Iterate::new(&y0, &v0, &past, c.predicted(&past), past.lambda, h, c);
        let mut factor: Option<AlphaMatrix<NV, M>> = None;
        let mut newton = ModifiedNewton::new(&self.options);
        loop {
            newton.next()?;
            let (r1, r2, j) = self.alpha_residual(&it)?;
            let m = match factor.take() {
                Some(m) if !newton.stale() => m,
                _ => {
                    newton.built();
                    self.alpha_matrix(&it, &j, h, c, rule)?
                }
            };
            let (x, dlambda) = m.solve(&j, &r1, &(r2 / h));
            factor = Some(m);
            it.correct(&y0, &v0, &past, &x, &dlambda, h, c);
            if newton.converged(x.norm(), 1.0 + it.dq.norm())? {
                break;
            }
        }
        *state = it.state;
        self.history = Some(it.history());
        Ok(newton.counts())
    }

    /// `M v̇ + Jᵀ λ − Q`, `Φ` and `J` at the iterate.
    #[allow(clippy::type_complexity)]
    fn alpha_residual(
        &mut self,
        it: &Iterate<NB, NV, M>,
    ) -> Result<(SVector<f64, NV>, SVector<f64, M>, SMatrix<f64, M, NV>), AnalysisError> {
        let e = self.scene.evaluate(&it.state);
        check_output::<S, NB, NV, M, NV>("J", &e.jacobian)?;
        check_output::<S, NB, NV, M, 1>("Φ", &e.phi)?;
        let q = generalised_forces(&mut self.loads, self.springs, &self.inertias, &self.gravity, &it.state);
        let r1 = mass_times(&self.inertias, &it.vdot) + e.jacobian.transpose() * it.lambda - q;
        if !r1.iter().all(|x| x.is_finite()) {
            return Err(AnalysisError::NonFiniteOutput { quantity: "forces", row: None });
        }
        Ok((r1, e.phi, e.jacobian))
    }

    /// The iteration matrix at the iterate, factorised.
    fn alpha_matrix(
        &mut self,
        it: &Iterate<NB, NV, M>,
        j: &SMatrix<f64, M, NV>,
        h: f64,
        c: Coefficients,
        rule: &StepRule<M>,
    ) -> Result<AlphaMatrix<NV, M>, AnalysisError> {
        let generated = match self.options.newton_matrix {
            super::NewtonMatrix::Generated => self.scene.second_order(&it.state, &it.lambda, &it.v),
            _ => None,
        };
        let stiffness = match generated {
            Some(second) => second.stiffness,
            None => self.stiffness_by_differences(&it.state, &it.lambda, j),
        };
        let (force_q, force_v) = self.force_derivatives(&it.state);
        let p = update_blocks::<NB, NV>(&it.dq, h);
        let mut s = times_update(&(stiffness - force_q), &p, h) - force_v * (c.gamma / c.beta);
        let c1 = c.mass_factor(h);
        for k in 0..NV {
            let column = mass_times(&self.inertias, &SVector::<f64, NV>::from_fn(|i, _| if i == k { c1 } else { 0.0 }));
            let mut target = s.column_mut(k);
            target += column;
        }
        let jt = times_update(j, &p, 1.0);
        AlphaMatrix::new(&s, &jt, j, rule)
    }

    /// `K = ∂(Jᵀλ)/∂q` by forward differences of the generated J.
    fn stiffness_by_differences(
        &self,
        state: &SystemState<NB>,
        lambda: &SVector<f64, M>,
        j: &SMatrix<f64, M, NV>,
    ) -> SMatrix<f64, NV, NV> {
        let base = j.transpose() * lambda;
        let mut k = SMatrix::<f64, NV, NV>::zeros();
        for col in 0..NV {
            let e = SVector::<f64, NV>::from_fn(|i, _| if i == col { 1.0 } else { 0.0 });
            let mut s = *state;
            apply_increment(&mut s, &e, 1e-7);
            k.set_column(col, &((self.scene.jacobian(&s).transpose() * lambda - base) / 1e-7));
        }
        k
    }
}
/// The factorised iteration matrix: `S` and the Schur complement `J T S⁻¹ Jᵀ`
/// with the redundant rows replaced by identity rows.
pub(super) struct AlphaMatrix<const NV: usize, const M: usize> {
    s: Lu<NV>,
    jt: SMatrix<f64, M, NV>,
    schur: Lu<M>,
    kept: [bool; M],
}

impl<const NV: usize, const M: usize> AlphaMatrix<NV, M> {
    fn new(
        s: &SMatrix<f64, NV, NV>,
        jt: &SMatrix<f64, M, NV>,
        j: &SMatrix<f64, M, NV>,
        rule: &StepRule<M>,
    ) -> Result<Self, AnalysisError> {
        let lu = Lu::new(s)?;
        let mut kept = [false; M];
        for &row in rule.order.iter().take(rule.rank) {
            if let Some(k) = kept.get_mut(row) {
                *k = true;
            }
        }
        let mut y = SMatrix::<f64, NV, M>::zeros();
        for (r, row) in j.row_iter().enumerate() {
            y.set_column(r, &lu.solve(&row.transpose()));
        }
        let mut schur = jt * y;
        for (r, &keep) in kept.iter().enumerate() {
            if !keep {
                for c in 0..M {
                    schur[(r, c)] = 0.0;
                    schur[(c, r)] = 0.0;
                }
                schur[(r, r)] = 1.0;
            }
        }
        Ok(AlphaMatrix { s: lu, jt: *jt, schur: Lu::new(&schur)?, kept })
    }

    /// The Newton correction `(x, δλ)` of `S x + Jᵀ δλ = r1`, `J T x = r2`.
    fn solve(
        &self,
        j: &SMatrix<f64, M, NV>,
        r1: &SVector<f64, NV>,
        r2: &SVector<f64, M>,
    ) -> (SVector<f64, NV>, SVector<f64, M>) {
        let s_r1 = self.s.solve(r1);
        let mut rhs = self.jt * s_r1 - r2;
        for (x, &keep) in rhs.iter_mut().zip(self.kept.iter()) {
            if !keep {
                *x = 0.0;
            }
        }
        let dlambda = self.schur.solve(&rhs);
        let x = self.s.solve(&(r1 - j.transpose() * dlambda));
        (x, dlambda)
    }
}

impl Coefficients {
    /// The predictor's pseudo-acceleration (`v̇_{n+1} = v̇_n`).
    pub(crate) fn predicted<const NB: usize, const NV: usize, const M: usize>(
        &self,
        past: &AlphaHistory<NB, NV, M>,
    ) -> SVector<f64, NV> {
        (past.vdot - past.a * self.alpha_m) / (1.0 - self.alpha_m)
    }
}

impl<const NB: usize, const NV: usize, const M: usize> Iterate<NB, NV, M> {
    /// The state and rates that follow from the pseudo-acceleration `a`.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn new(
        y0: &SystemState<NB>,
        v0: &SVector<f64, NV>,
        past: &AlphaHistory<NB, NV, M>,
        a: SVector<f64, NV>,
        lambda: SVector<f64, M>,
        h: f64,
        c: Coefficients,
    ) -> Self {
        let zero = SVector::zeros();
        let mut it = Iterate { dq: zero, a, v: zero, vdot: zero, lambda, state: *y0 };
        it.follow(y0, v0, past, h, c);
        it
    }

    /// What the next step starts from.
    pub(crate) fn history(&self) -> AlphaHistory<NB, NV, M> {
        AlphaHistory { state: self.state, vdot: self.vdot, a: self.a, lambda: self.lambda }
    }
}
/// `M x`.
pub(crate) fn mass_times<const NB: usize, const NV: usize>(
    inertias: &[crate::scene::BodyInertia; NB],
    x: &SVector<f64, NV>,
) -> SVector<f64, NV> {
    let mut y = *x;
    mass_times_into(inertias, x, &mut y);
    y
}
