//! The linearised dynamics of a tree about a state, for a
//! controller's design (LQR, pole placement) or a stability check:
//! `ẋ = A x + B u` in the tree's increments `x = (δq, δv)`, `δq` on the
//! joints' own group (`q ⊕ δq`, [`Tree::displace`](super::Tree::displace):
//! a quaternion turned in its own frame, a free joint's offset moved in its
//! child's axes), `u` the joint forces.
//!
//! `A = [[Λ(v), I], [A_q, A_v]]`: `Λ(v)` is the increments' own rate, exact
//! (zero for angles and slides; `−[ω']×` for a quaternion turned by ω' in
//! its own frame; for a free joint also `−[ω']× δ − [u]× δθ` for its
//! offset); `A_q`, `A_v` are the forward dynamics' exact derivatives
//! ([`forward_dynamics_derivatives`](super::TreeSimulation::forward_dynamics_derivatives))
//! where the tree has no loops but couplings, no springs and no user
//! loads; central differences of the forward dynamics otherwise (the
//! springs' and the user's loads included).
//! `B = [0; M⁻¹]`, exact (`v̇` is affine in the joint forces). The outputs
//! are dense matrices (they allocate); the allocation-free form is
//! `forward_dynamics_derivatives` itself, whose blocks these are.
//!
//! With loops (or a file's couplings) the accelerations are the
//! constrained ones, `B` their columns (differences of an affine map), and
//! the linearisation is taken to the minimal coordinates of the absolute
//! path: `δq` in the null space `N` of the closure rows' `J`, `δv` in it
//! corrected by `∂(J v + Φ_t)/∂q` (by central differences), `basis` the map
//! back.

use nalgebra::{DMatrix, SMatrix, SVector};

use alloc::boxed::Box;

use super::{
    ForwardDerivatives, InverseDerivatives, StepJacobian, StepWork, TreeError, TreeJointKind, TreeScene,
    TreeSimulation, TreeState,
};

/// The largest step workspace `transition` puts on the stack for the exact
/// Jacobian (256 KiB: a tree of about 32 freedoms); larger trees difference.
const EXACT_WORK: usize = 256 << 10;
use crate::dynamics::{AppliedLoads, Integrator, Linearisation};

/// The central differences' step, scaled by `1 + |x|` of the coordinate or
/// velocity it moves: near the cube root of ε, the best balance of their
/// truncation and round-off.
const STEP: f64 = 1e-5;

impl<
    S: TreeScene<NB, NQ, NV, NC>,
    L: AppliedLoads<NB>,
    const NB: usize,
    const NQ: usize,
    const NV: usize,
    const NC: usize,
> TreeSimulation<'_, S, NB, NQ, NV, NC, L>
{
    /// The linearisation about `state` under joint forces `tau` (held): the
    /// module's `A` and `B` (`2 NV × 2 NV`, `2 NV × NV`, the inputs the
    /// joint forces); `basis` the identity and `freedoms` `NV` for a tree
    /// without loops, else the minimal coordinates on its loops (the
    /// module's). [`Linearisation::eigenvalues`] gives its poles.
    ///
    /// ```
    /// use joint_runtime::Scene;
    /// use joint_runtime::nalgebra::SVector;
    /// use joint_runtime::relative::{TreeSimulation, TreeState};
    ///
    /// /// A bar of 1 m pinned at its end about y, hanging at θ = π/2.
    /// #[derive(Scene)]
    /// #[scene(gravity = [0, 0, -9.81])]
    /// #[body(bar, mass = 1.0, inertia = [0.001, 0.08, 0.08])]
    /// #[joint(pin = revolute(ground, bar), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0, 0, 0], rho2 = [-0.5, 0, 0])]
    /// struct Bar;
    ///
    /// let mut sim = TreeSimulation::new(&Bar)?;
    /// let hanging = TreeState { q: SVector::from([std::f64::consts::FRAC_PI_2]), v: SVector::zeros(), t: 0.0 };
    /// let lin = sim.linearise(&hanging, &SVector::zeros())?;
    /// // It swings at ω² = m g (l/2) / (I + m (l/2)²).
    /// let omega = (9.81 * 0.5 / (0.08 + 0.25f64)).sqrt();
    /// for e in lin.eigenvalues().unwrap() {
    ///     assert!((e.im.abs() - omega).abs() < 1e-8 && e.re.abs() < 1e-8);
    /// }
    /// # Ok::<(), joint_runtime::relative::TreeError>(())
    /// ```
    pub fn linearise(&mut self, state: &TreeState<NQ, NV>, tau: &SVector<f64, NV>) -> Result<Linearisation, TreeError> {
        if self.soft.any() && !self.soft.all() {
            return Err(TreeError::NotOffered {
                what: "linearising a scene whose soft equalities share it with ideal rows",
                instead: "read the file's equalities as ideal rows (`equality = hard`), or linearise without the \
                          ideal rows",
            });
        }
        let n = NV;
        let mut a = DMatrix::<f64>::zeros(2 * n, 2 * n);
        self.tree().increment_rates(&state.v, &mut a);
        for i in 0..n {
            a[(i, n + i)] = 1.0;
        }
        if !self.loaded() {
            match self.exact(state, tau, a.clone()) {
                // Closures past the derive's limit: differences below.
                Err(TreeError::NotDerived) => {}
                result => return result,
            }
        }
        for i in 0..n {
            let h = STEP * (1.0 + libm::fabs(state.v[i]));
            let dv = SVector::<f64, NV>::from_fn(|r, _| if r == i { h } else { 0.0 });
            let moved = |sign: f64| TreeState { v: state.v + dv * sign, ..*state };
            let column =
                (self.forward_dynamics(&moved(1.0), tau)? - self.forward_dynamics(&moved(-1.0), tau)?) / (2.0 * h);
            a.view_mut((n, n + i), (n, 1)).copy_from(&column);
            let h = STEP;
            let dq = SVector::<f64, NV>::from_fn(|r, _| if r == i { h } else { 0.0 });
            let turned = |sign: f64| TreeState { q: self.tree().displaced(&state.q, &(dq * sign)), ..*state };
            let (plus, minus) = (turned(1.0), turned(-1.0));
            let column = (self.forward_dynamics(&plus, tau)? - self.forward_dynamics(&minus, tau)?) / (2.0 * h);
            a.view_mut((n, i), (n, 1)).copy_from(&column);
        }
        if NC > 0 && !self.soft.all() {
            return self.on_loops(state, tau, a);
        }
        let mut b = DMatrix::<f64>::zeros(2 * n, n);
        if NC > 0 {
            // Soft rows only: no loops to reduce to, `B` as the loops' is.
            b.view_mut((n, 0), (n, n)).copy_from(&self.tau_columns(state, tau)?);
        } else {
            let mut m = SMatrix::<f64, NV, NV>::zeros();
            self.mass_matrix_into(&state.q, &mut m);
            let joint = self.tree().joints.first().map_or("", |j| j.name);
            let minv = nalgebra::Cholesky::new(m).ok_or(TreeError::Singular { joint })?.inverse();
            b.view_mut((n, 0), (n, n)).copy_from(&minv);
        }
        if !a.iter().chain(b.iter()).all(|x| x.is_finite()) {
            return Err(TreeError::NonFinite);
        }
        let basis = DMatrix::identity(2 * n, 2 * n);
        Ok(Linearisation { a: a.clone(), b: b.clone(), basis, freedoms: n, full: a, full_b: b })
    }

    /// `A`'s lower blocks and `B` from the exact derivatives (`a` holds
    /// the upper blocks).
    fn exact(
        &mut self,
        state: &TreeState<NQ, NV>,
        tau: &SVector<f64, NV>,
        mut a: DMatrix<f64>,
    ) -> Result<Linearisation, TreeError> {
        let n = NV;
        let mut work = Box::new(InverseDerivatives::<NV>::zeros());
        let mut d = Box::new(ForwardDerivatives::<NV>::zeros());
        self.forward_dynamics_derivatives(state, tau, &mut work, &mut d)?;
        a.view_mut((n, 0), (n, n)).copy_from(&d.d_q);
        a.view_mut((n, n), (n, n)).copy_from(&d.d_v);
        if NC > 0 && !self.soft.all() {
            // `∂(J v + Φ_t)/∂q` from the closures' second-order terms.
            let rows = self.closure_rows(state);
            let j = DMatrix::from_iterator(NC, NV, rows.jacobian.iter().copied());
            let b = DMatrix::from_iterator(NV, NV, d.d_tau.iter().copied());
            let rate = self.closure_rate_q(state)?;
            let moved = DMatrix::from_iterator(NC, NV, rate.iter().copied());
            return crate::dynamics::linear::reduce(a, &j, &moved, b).map_err(|_| TreeError::NonFinite);
        }
        let mut b = DMatrix::<f64>::zeros(2 * n, n);
        b.view_mut((n, 0), (n, n)).copy_from(&d.d_tau);
        let basis = DMatrix::identity(2 * n, 2 * n);
        Ok(Linearisation { a: a.clone(), b: b.clone(), basis, freedoms: n, full: a, full_b: b })
    }

    /// `∂v̇/∂τ` of the constrained accelerations: `v̇` is affine in `τ`, so
    /// differences of a unit step are exact to round-off.
    fn tau_columns(&mut self, state: &TreeState<NQ, NV>, tau: &SVector<f64, NV>) -> Result<DMatrix<f64>, TreeError> {
        let mut out = DMatrix::<f64>::zeros(NV, NV);
        for i in 0..NV {
            let push = SVector::<f64, NV>::from_fn(|r, _| if r == i { 1.0 } else { 0.0 });
            let column =
                (self.forward_dynamics(state, &(tau + push))? - self.forward_dynamics(state, &(tau - push))?) / 2.0;
            out.set_column(i, &column);
        }
        Ok(out)
    }

    /// The full linearisation `full` taken to the loops' minimal
    /// coordinates: `B`'s columns the constrained accelerations' own
    /// (`v̇` is affine in `τ`: differences of a unit step are exact to
    /// round-off), `∂(J v + Φ_t)/∂q` by central differences along each
    /// increment.
    fn on_loops(
        &mut self,
        state: &TreeState<NQ, NV>,
        tau: &SVector<f64, NV>,
        full: DMatrix<f64>,
    ) -> Result<Linearisation, TreeError> {
        let a_u = self.tau_columns(state, tau)?;
        let rows = self.closure_rows(state);
        let j = DMatrix::from_iterator(NC, NV, rows.jacobian.iter().copied());
        let mut moved = DMatrix::<f64>::zeros(NC, NV);
        for i in 0..NV {
            let dq = SVector::<f64, NV>::from_fn(|r, _| if r == i { STEP } else { 0.0 });
            let rate = |sign: f64| {
                let at = TreeState { q: self.tree().displaced(&state.q, &(dq * sign)), ..*state };
                let rows = self.closure_rows(&at);
                rows.jacobian * state.v + rows.phi_t
            };
            moved.set_column(i, &((rate(1.0) - rate(-1.0)) / (2.0 * STEP)));
        }
        crate::dynamics::linear::reduce(full, &j, &moved, a_u).map_err(|_| TreeError::NonFinite)
    }
}

impl<S: TreeScene<NB, NQ, NV>, L: AppliedLoads<NB>, const NB: usize, const NQ: usize, const NV: usize>
    TreeSimulation<'_, S, NB, NQ, NV, 0, L>
{
    /// One step of `state` under joint forces `tau` (as
    /// [`step_with`](TreeSimulation::step_with), by the options' integrator) and its state-transition
    /// Jacobian `Φ` (`2 NV × 2 NV`): `(δq₁, δv₁) = Φ (δq₀, δv₀)` in the
    /// increments of [`linearise`](TreeSimulation::linearise) at the start
    /// and at the end ([`Tree::difference`](super::Tree::difference)), what
    /// an extended Kalman filter or an MPC propagates. Exact where the
    /// tree's exact step Jacobian is
    /// ([`rk4_step_jacobian`](TreeSimulation::rk4_step_jacobian): no
    /// springs or user loads), its workspace fits the stack (up to
    /// about 32 freedoms: 240 NV² bytes) and the integrator is RK4; by central differences of the step (`4 NV` more
    /// steps, about 1e-8 of the entries) elsewhere. On error `state` is
    /// unchanged.
    pub fn transition(
        &mut self,
        state: &mut TreeState<NQ, NV>,
        h: f64,
        tau: &SVector<f64, NV>,
    ) -> Result<DMatrix<f64>, TreeError> {
        let start = *state;
        // The exact Jacobian is RK4's: another integrator's step is differenced.
        if size_of::<StepWork<NQ, NV>>() <= EXACT_WORK && self.options().integrator == Integrator::Rk4 {
            let (mut work, mut j, mut end) = (StepWork::new(), StepJacobian::zeros(), start);
            match self.rk4_step_jacobian(&mut end, h, tau, &mut work, &mut j) {
                Ok(()) => {
                    *state = end;
                    return Ok(DMatrix::from_fn(2 * NV, 2 * NV, |r, c| j.entry(r, c)));
                }
                // Springs or loads: the step is differenced below.
                Err(TreeError::Loaded) => {}
                Err(e) => return Err(e),
            }
        }
        let mut end = start;
        self.step_with(&mut end, h, tau)?;
        let n = NV;
        let mut phi = DMatrix::<f64>::zeros(2 * n, 2 * n);
        for i in 0..2 * n {
            let eps = if i < n { STEP } else { STEP * (1.0 + libm::fabs(start.v[i - n])) };
            // The step from the start moved by ±eps along increment `i`,
            // measured from the unmoved step's end.
            let mut moved = |sign: f64| -> Result<(SVector<f64, NV>, SVector<f64, NV>), TreeError> {
                let mut s = start;
                let e = SVector::<f64, NV>::from_fn(|r, _| if r == i % n { sign * eps } else { 0.0 });
                if i < n {
                    s.q = self.tree().displaced(&start.q, &e);
                } else {
                    s.v += e;
                }
                self.step_with(&mut s, h, tau)?;
                Ok((self.tree().difference(&end.q, &s.q), s.v - end.v))
            };
            let ((q1, v1), (q2, v2)) = (moved(1.0)?, moved(-1.0)?);
            phi.view_mut((0, i), (n, 1)).copy_from(&((q1 - q2) / (2.0 * eps)));
            phi.view_mut((n, i), (n, 1)).copy_from(&((v1 - v2) / (2.0 * eps)));
        }
        if !phi.iter().all(|x| x.is_finite()) {
            return Err(TreeError::NonFinite);
        }
        *state = end;
        Ok(phi)
    }
}

impl<const NB: usize, const NQ: usize, const NV: usize> super::Tree<NB, NQ, NV> {
    /// `Λ(v)` into the top-left `NV × NV` block of `a`: how the increments
    /// `δq` move by themselves at velocities `v` (see the module docs).
    fn increment_rates(&self, v: &SVector<f64, NV>, a: &mut DMatrix<f64>) {
        let skew =
            |x: [f64; 3]| [(0, 1, -x[2]), (0, 2, x[1]), (1, 0, x[2]), (1, 2, -x[0]), (2, 0, -x[1]), (2, 1, x[0])];
        let mut put = |at: (usize, usize), x: [f64; 3], sign: f64| {
            for (r, c, value) in skew(x) {
                a[(at.0 + r, at.1 + c)] += sign * value;
            }
        };
        for (k, j) in self.joints.iter().enumerate() {
            let va = self.v_at[k];
            let three = |at: usize| [v[at], v[at + 1], v[at + 2]];
            match j.kind {
                TreeJointKind::Spherical => put((va, va), three(va), -1.0),
                TreeJointKind::Free => {
                    let (u, w) = (three(va), three(va + 3));
                    put((va, va), w, -1.0);
                    put((va, va + 3), u, -1.0);
                    put((va + 3, va + 3), w, -1.0);
                }
                _ => {}
            }
        }
    }
}
