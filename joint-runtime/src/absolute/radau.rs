//! Radau IIA on the sparse path: the dense method (`dynamics/radau.rs`, the
//! same driver through its [`RadauHost`] trait) with its real and complex
//! stage systems on the saddle-point pattern of the other implicit
//! integrators, factorised by [`Kkt`] over real and complex entries.
//!
//! The dense step solves `(μ − [[0, I], [A_q, A_v]]) (x, y) = (r, s)`
//! through `(μ² I − μ A_v − A_q) x = s + (μ − A_v) r`, `y = μ x − r`, with
//! `A_q`, `A_v` full (every acceleration depends on every state through `λ`).
//! Keeping `δλ` as an unknown, as the midpoint rule does, and dividing by
//! `μ²`, the same `x` solves
//!
//! ```text
//! [ M − (Q_q − K)/μ² − Q_v/μ               Jᵀ ] [ x  ]   [ M u − Q_v r / μ² ]
//! [ J − (∂γ̂/∂q − ∂(J a)/∂q)/μ² − ∂γ̂/∂v/μ   0  ] [ δμ ] = [ J u − ∂γ̂/∂v r / μ² ]
//! ```
//!
//! with `u = s/μ² + r/μ`: the matrix `P₀ + P₁/μ + P₂/μ²` of three real
//! matrices on one pattern, assembled once per Jacobian (at the step's start,
//! kept across steps by RADAU5's rule as on the dense path), combined and
//! factorised at `μ = γ̂/h` (real) and `μ = (α + iβ)/h` (complex) at every
//! step: `O(N)` a factorisation where the dense path's are `O(NV³)`. `P₁`'s
//! product with `r` gives the right-hand side's `Q_v r`, `∂γ̂/∂v r` terms.
//! The terms are the scene's second-order terms (or their differences), the
//! springs' and the gyroscopic ones, exact, and the user loads' on the
//! pattern (`loads.rs`).

use nalgebra::{Complex, Matrix3, SVector};

use super::AbsoluteSimulation;
use super::alpha::{add_mass, add_rows, add_stiffness, spring_blocks};
use super::buf::{Boxed, at_rest, boxed_with, zero_state, zeros};
use super::kkt::{Kkt, KktEntry, KktStorage, NodeVector};
use super::midpoint::{RowTerms, add_row_terms};
use super::second_order::TermStorage;
use super::solver::j_mul_into;
use crate::analysis::{AnalysisError, velocity_vector_into};
use crate::dynamics::radau::{ALPHA, BETA, Bodies, GAMMA, RadauHistory, RadauHost};
use crate::dynamics::{AppliedLoads, NewtonMatrix, mass_times_into};
use crate::scene::{Scene, SparseJacobian, SystemState};

/// Radau's matrices on the pattern and the scratch of their solves,
/// allocated at the first Radau step.
#[derive(Clone, Debug)]
pub(super) struct RadauWorkspace<R, C, const NV: usize, const M: usize, const NNZ: usize> {
    /// `P₀`, `P₁`, `P₂` at the Jacobian's state.
    parts: [Kkt<f64, R>; 3],
    real: Kkt<f64, R>,
    complex: Kkt<Complex<f64>, C>,
    /// `J` at the Jacobian's state, and the rows its rule dropped (the
    /// first `dropped_len`).
    values: [f64; NNZ],
    dropped: [usize; M],
    dropped_len: usize,
    rhs: NodeVector<f64, NV, M>,
    complex_rhs: NodeVector<Complex<f64>, NV, M>,
    product: NodeVector<f64, NV, M>,
}

impl<R, C, const NV: usize, const M: usize, const NNZ: usize> RadauWorkspace<R, C, NV, M, NNZ>
where
    R: KktStorage<f64>,
    C: KktStorage<Complex<f64>>,
{
    /// On generalised-α's pattern, boxed (with `alloc`) and written in the
    /// heap (`buf`; each matrix's arrays are boxes of their own).
    pub(super) fn boxed(pattern: &Kkt<f64, R>) -> Result<Boxed<Self>, AnalysisError> {
        let bad = |_| crate::absolute::solver::non_finite("scene structure");
        let parts = [pattern.like().map_err(bad)?, pattern.like().map_err(bad)?, pattern.like().map_err(bad)?];
        let (real, complex) = (pattern.like().map_err(bad)?, pattern.like().map_err(bad)?);
        Ok(boxed_with(|| RadauWorkspace {
            parts,
            real,
            complex,
            values: const { [0.0; NNZ] },
            dropped: const { [0; M] },
            dropped_len: 0,
            rhs: const { NodeVector::repeat(0.0) },
            complex_rhs: const { NodeVector::repeat(Complex::new(0.0, 0.0)) },
            product: const { NodeVector::repeat(0.0) },
        }))
    }

    /// `P₁ r` by node (bodies' rows, then joints'), into `product`.
    fn p1_times(&mut self, r: &SVector<f64, NV>) {
        self.rhs.fill(0.0);
        for (o, x) in self.rhs.head.iter_mut().zip(r.iter()) {
            *o = *x;
        }
        self.parts[1].times(&self.rhs, &mut self.product);
    }
}

/// The start's dynamics a Radau step's stages keep (solved at `at`), and
/// the sparse host's vectors: `u` (real, or the complex one's real and
/// imaginary parts), `M u` and `J u` of each. Boxed with the workspace.
#[derive(Clone, Debug)]
pub(super) struct RadauScratch<const NB: usize, const NV: usize, const M: usize> {
    at: SystemState<NB>,
    solved: bool,
    vdot: SVector<f64, NV>,
    lambda: SVector<f64, M>,
    u: SVector<f64, NV>,
    ui: SVector<f64, NV>,
    mass: SVector<f64, NV>,
    mass_i: SVector<f64, NV>,
    j: SVector<f64, M>,
    j_i: SVector<f64, M>,
}

impl<const NB: usize, const NV: usize, const M: usize> RadauScratch<NB, NV, M> {
    /// Zeros (the start's state at rest), boxed (with `alloc`) and written
    /// in the heap (`buf`); no start solved.
    pub(super) fn boxed() -> Boxed<Self> {
        let mut w = boxed_with(|| {
            const {
                RadauScratch {
                    at: zero_state(),
                    solved: false,
                    vdot: zeros(),
                    lambda: zeros(),
                    u: zeros(),
                    ui: zeros(),
                    mass: zeros(),
                    mass_i: zeros(),
                    j: zeros(),
                    j_i: zeros(),
                }
            }
        });
        at_rest(&mut w.at);
        w
    }

    /// The dynamics `(vdot, lambda)` solved at `at`, as the step's start.
    pub(super) fn start(&mut self, at: &SystemState<NB>, vdot: &SVector<f64, NV>, lambda: &SVector<f64, M>) {
        self.at.clone_from(at);
        self.vdot.copy_from(vdot);
        self.lambda.copy_from(lambda);
        self.solved = true;
    }
}

impl<S, L, const NB: usize, const NV: usize, const M: usize, const NNZ: usize> RadauHost<NV>
    for AbsoluteSimulation<'_, S, L, NB, NV, M, NNZ>
where
    S: Scene<NB, NV, M> + SparseJacobian<NB, NNZ>,
    L: AppliedLoads<NB>,
{
    type Group = Bodies<NB>;
    type Error = AnalysisError;
    /// The matrices live in the workspace.
    type Jacobian = ();
    /// The step `h` the workspace's systems were factorised for.
    type Factors = f64;

    fn error(e: AnalysisError) -> AnalysisError {
        e
    }

    fn group(&self) -> &Bodies<NB> {
        &Bodies
    }

    fn newton_limits(&self) -> (usize, f64) {
        (self.options.newton_max_iterations, self.options.newton_tolerance)
    }

    fn history(&mut self) -> &mut Option<RadauHistory<SystemState<NB>, NV, ()>> {
        &mut self.radau_history
    }

    fn start(&mut self, y0: &SystemState<NB>, out: &mut SVector<f64, NV>) -> Result<(), AnalysisError> {
        self.radau_start_ready(y0)?;
        let sc = self.radau_scratch.as_deref().ok_or(AnalysisError::BadOption { name: "integrator" })?;
        out.copy_from(&sc.vdot);
        Ok(())
    }

    fn accelerations(&mut self, state: &SystemState<NB>, out: &mut SVector<f64, NV>) -> Result<(), AnalysisError> {
        self.solve_in_work(state, true, false)?;
        out.copy_from(self.solved().0);
        Ok(())
    }

    /// `P₀`, `P₁`, `P₂` at `y0` (see the module docs).
    fn jacobian(&mut self, y0: &SystemState<NB>) -> Result<((), usize), AnalysisError> {
        self.radau_start_ready(y0)?;
        let stabilisation = self.options.stabilisation.coefficients();
        let by_differences = self.options.newton_matrix == NewtonMatrix::FiniteDifferences;
        let bad = || AnalysisError::BadOption { name: "integrator" };
        let (Some(ws), Some(radau), Some(sc)) =
            (self.alpha.as_deref_mut(), self.radau.as_deref_mut(), self.radau_scratch.as_deref_mut())
        else {
            return Err(bad());
        };
        self.scene.jacobian_values_into(y0, &mut radau.values);
        let values = &radau.values;
        // u = a + 2α v (as the midpoint rule's).
        velocity_vector_into(y0, &mut sc.u);
        for (u, a) in sc.u.as_mut_slice().iter_mut().zip(sc.vdot.as_slice().iter()) {
            *u = a + *u * (2.0 * stabilisation.0);
        }
        ws.fill_terms(self.scene, y0, &sc.lambda, &sc.u, by_differences)?;
        let from = self.solver.factor.dropped();
        radau.dropped_len = from.len().min(M);
        for (d, &f) in radau.dropped.iter_mut().zip(from) {
            *d = f;
        }
        let dropped = radau.dropped.get(..radau.dropped_len).unwrap_or(&[]);
        // No rotation update: the blocks as they are (an empty `t`).
        let identity: &[Matrix3<f64>] = &[];
        let rows = RowTerms { layout: ws.layout, terms: ws.terms.values(), dropped, stabilisation };
        let [p0, p1, p2] = &mut radau.parts;
        for p in [&mut *p0, &mut *p1, &mut *p2] {
            p.clear();
        }
        // P₀ = [M, Jᵀ; J, 0].
        add_mass(p0, &self.inertias, y0, 1.0, 0.0)?;
        add_rows::<S, NB, NNZ>(p0, values, &ws.row_joint, dropped, identity)?;
        // P₁ = [−Q_v, 0; −∂γ̂/∂v, 0].
        add_mass(p1, &self.inertias, y0, 0.0, 1.0)?;
        for s in self.springs {
            spring_blocks(p1, s, y0, true, -1.0)?;
        }
        ws.user.add_blocks::<L, NV>(p1, &mut self.loads, self.springs, y0, true, -1.0)?;
        add_row_terms::<S, NB, NNZ>(p1, &rows, values, identity, (0.0, 1.0))?;
        // P₂ = [K − Q_q, 0; ∂(J a)/∂q − ∂γ̂/∂q, 0].
        add_stiffness(p2, &ws.layout, ws.terms.values(), 1.0)?;
        for s in self.springs {
            spring_blocks(p2, s, y0, false, -1.0)?;
        }
        ws.user.add_blocks::<L, NV>(p2, &mut self.loads, self.springs, y0, false, -1.0)?;
        add_row_terms::<S, NB, NNZ>(p2, &rows, values, identity, (1.0, 0.0))?;
        Ok(((), 1))
    }

    fn factor(&mut self, _: &(), h: f64) -> Result<f64, AnalysisError> {
        let radau = self.radau.as_deref_mut().ok_or(AnalysisError::BadOption { name: "integrator" })?;
        let [p0, p1, p2] = &radau.parts;
        let inverse = h / GAMMA;
        radau.real.combine(&[(p0, 1.0), (p1, inverse), (p2, inverse * inverse)]);
        radau.real.factor()?;
        let inverse = Complex::new(h, 0.0) / Complex::new(ALPHA, BETA);
        let one = Complex::new(1.0, 0.0);
        radau.complex.combine(&[(p0, one), (p1, inverse), (p2, inverse * inverse)]);
        radau.complex.factor()?;
        Ok(h)
    }

    fn solve_real(
        &mut self,
        &h: &f64,
        (r, s): (&SVector<f64, NV>, &SVector<f64, NV>),
        (x, y): (&mut SVector<f64, NV>, &mut SVector<f64, NV>),
    ) {
        let mu = GAMMA / h;
        let (Some(radau), Some(sc)) = (self.radau.as_deref_mut(), self.radau_scratch.as_deref_mut()) else {
            x.fill(0.0);
            y.fill(0.0);
            return;
        };
        for (u, (s, r)) in sc.u.as_mut_slice().iter_mut().zip(s.as_slice().iter().zip(r.as_slice().iter())) {
            *u = s / (mu * mu) + r / mu;
        }
        mass_times_into(&self.inertias, &sc.u, &mut sc.mass);
        j_mul_into::<S, NB, NNZ>(&radau.values, sc.u.as_slice(), sc.j.as_mut_slice());
        radau.p1_times(r);
        let scale = 1.0 / (mu * mu);
        for (i, (o, p)) in radau.rhs.iter_mut().zip(radau.product.iter()).enumerate() {
            let base = if i < NV { sc.mass.get(i) } else { sc.j.get(i - NV) };
            *o = base.copied().unwrap_or(0.0) + p * scale;
        }
        zero_dropped(&mut radau.rhs, radau.dropped.get(..radau.dropped_len).unwrap_or(&[]));
        radau.real.solve(&mut radau.rhs);
        for ((x, y), (v, r)) in
            x.as_mut_slice().iter_mut().zip(y.as_mut_slice().iter_mut()).zip(radau.rhs.iter().zip(r.as_slice().iter()))
        {
            *x = *v;
            *y = v * mu - r;
        }
    }

    fn solve_complex(
        &mut self,
        &h: &f64,
        (r2, r3): (&SVector<f64, NV>, &SVector<f64, NV>),
        (s2, s3): (&SVector<f64, NV>, &SVector<f64, NV>),
        (xr, xi): (&mut SVector<f64, NV>, &mut SVector<f64, NV>),
        (yr, yi): (&mut SVector<f64, NV>, &mut SVector<f64, NV>),
    ) {
        let mu = Complex::new(ALPHA, BETA) / h;
        let (i1, i2) = (mu.inv(), (mu * mu).inv());
        let (Some(radau), Some(sc)) = (self.radau.as_deref_mut(), self.radau_scratch.as_deref_mut()) else {
            for v in [xr, xi, yr, yi] {
                v.fill(0.0);
            }
            return;
        };
        // u = s/μ² + r/μ, its real and imaginary parts.
        let rs = r2.as_slice().iter().zip(r3.as_slice().iter()).zip(s2.as_slice().iter().zip(s3.as_slice().iter()));
        for ((ur, ui), ((&r2, &r3), (&s2, &s3))) in
            sc.u.as_mut_slice().iter_mut().zip(sc.ui.as_mut_slice().iter_mut()).zip(rs)
        {
            let u = Complex::new(s2, s3) * i2 + Complex::new(r2, r3) * i1;
            (*ur, *ui) = (u.re, u.im);
        }
        mass_times_into(&self.inertias, &sc.u, &mut sc.mass);
        mass_times_into(&self.inertias, &sc.ui, &mut sc.mass_i);
        j_mul_into::<S, NB, NNZ>(&radau.values, sc.u.as_slice(), sc.j.as_mut_slice());
        j_mul_into::<S, NB, NNZ>(&radau.values, sc.ui.as_slice(), sc.j_i.as_mut_slice());
        radau.p1_times(r2);
        for (o, p) in radau.complex_rhs.iter_mut().zip(radau.product.iter()) {
            *o = Complex::new(*p, 0.0) * i2;
        }
        radau.p1_times(r3);
        for (i, (o, p)) in radau.complex_rhs.iter_mut().zip(radau.product.iter()).enumerate() {
            let (re, im) =
                if i < NV { (sc.mass.get(i), sc.mass_i.get(i)) } else { (sc.j.get(i - NV), sc.j_i.get(i - NV)) };
            let base = Complex::new(re.copied().unwrap_or(0.0), im.copied().unwrap_or(0.0));
            *o += base + Complex::new(0.0, *p) * i2;
        }
        zero_dropped(&mut radau.complex_rhs, radau.dropped.get(..radau.dropped_len).unwrap_or(&[]));
        radau.complex.solve(&mut radau.complex_rhs);
        let outs = xr
            .as_mut_slice()
            .iter_mut()
            .zip(xi.as_mut_slice().iter_mut())
            .zip(yr.as_mut_slice().iter_mut().zip(yi.as_mut_slice().iter_mut()));
        for (((xr, xi), (yr, yi)), (x, (&r2, &r3))) in
            outs.zip(radau.complex_rhs.iter().zip(r2.as_slice().iter().zip(r3.as_slice().iter())))
        {
            let y = x * mu - Complex::new(r2, r3);
            (*xr, *xi, *yr, *yi) = (x.re, x.im, y.re, y.im);
        }
    }
}

impl<S, L, const NB: usize, const NV: usize, const M: usize, const NNZ: usize>
    AbsoluteSimulation<'_, S, L, NB, NV, M, NNZ>
where
    S: Scene<NB, NV, M> + SparseJacobian<NB, NNZ>,
    L: AppliedLoads<NB>,
{
    /// The dynamics at the step's start `y0` under its rule in the scratch:
    /// those the step's start solved (the factor still holds them), or
    /// solved here.
    fn radau_start_ready(&mut self, y0: &SystemState<NB>) -> Result<(), AnalysisError> {
        if !self.radau_scratch.as_deref().is_some_and(|sc| sc.solved && sc.at == *y0) {
            self.solve_in_work(y0, true, false)?;
            self.remember_radau_start(y0);
        }
        Ok(())
    }
}

/// Zeros the dropped rows' entries of a right-hand side by node.
fn zero_dropped<T: KktEntry, const NV: usize, const M: usize>(rhs: &mut NodeVector<T, NV, M>, dropped: &[usize]) {
    for &row in dropped {
        if let Some(o) = rhs.tail.get_mut(row) {
            *o = T::zero();
        }
    }
}
