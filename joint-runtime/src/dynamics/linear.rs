//! Linearisation of a scene's constrained dynamics about a state, and the
//! state-transition Jacobian of an implicit midpoint step (feature `alloc`:
//! the number of freedoms is known only at run time, and `2 NV` is not a
//! stable const generic), from the generated second-order terms
//! (`#[scene(second_order)]`).
//!
//! About a state `(q, v)`, increments `δq` (on the group: `δr` inertial, `δθ'`
//! in body components, `p ⊗ q(δθ')`) and `δv` obey
//!
//! ```text
//! d/dt δq = Λ(v) δq + δv          Λ = blockdiag(0, −ω̃'_i)   (the group's own motion)
//! d/dt δv = A_q δq + A_v δv + A_u δu
//! ```
//!
//! where `A_q`, `A_v` (and `A_u` for generalised-force inputs) come from
//! differentiating `M a + Jᵀ λ = Q`, `J a = γ` (the Newton matrix's pieces,
//! `newton_matrix.rs`). Motions that stay on the constraints keep
//! `J δq = 0` and `J δv + (∂(J v)/∂q + ∂Φ_t/∂q) δq = 0`: with `N` an
//! orthonormal basis of J's null space (the `n` freedoms), `δq = N z` and
//! `δv = N w + V z` with `V = −J⁺ (∂(J v)/∂q + ∂Φ_t/∂q) N`. In the minimal
//! coordinates `x = (z, w)` the linearised dynamics is `ẋ = A x + B u`, the
//! full one projected on the constraints' tangent space with the basis frozen
//! at the state. At an equilibrium the full linearisation leaves that space
//! invariant and `A` is exact; along a motion the space turns with the state,
//! and [`Linearisation::full`] (in the `2 NV` increments) is the one to
//! propagate. Redundant rows do not count: J's rank decides `n`.

use alloc::vec::Vec;

use nalgebra::{Complex, DMatrix, SVector};

use super::newton_matrix::update_blocks;
use crate::analysis::{AnalysisError, check_state};
use crate::scene::{Scene, SystemState};

/// Singular values of J below this fraction of the largest count as zero.
const NULL_TOLERANCE: f64 = 1e-9;
/// Iterations allowed to nalgebra's SVD and Schur decompositions (0: until converged).
const DECOMPOSITION_ITERATIONS: usize = 0;

/// The linearised dynamics `ẋ = A x + B u` of a scene about a state, in the
/// minimal coordinates `x = (z, w)` of [`AbsoluteSimulation::linearise`](super::AbsoluteSimulation::linearise).
#[derive(Clone, Debug, PartialEq)]
pub struct Linearisation {
    /// The state matrix, `2n × 2n` (`n` freedoms).
    pub a: DMatrix<f64>,
    /// The input matrix, `2n × k` for `k` input columns.
    pub b: DMatrix<f64>,
    /// The coordinates: `(δq, δv) = T x`, `2 NV × 2n`.
    pub basis: DMatrix<f64>,
    /// The number of freedoms `n` (velocity columns less J's rank).
    pub freedoms: usize,
    /// The full linearisation in the increments `(δq, δv)`, `2 NV × 2 NV`:
    /// `[[Λ(v), I], [A_q, A_v]]`.
    pub full: DMatrix<f64>,
    /// The full input matrix, `2 NV × k`: `[0; A_u]`.
    pub full_b: DMatrix<f64>,
}

impl Linearisation {
    /// The eigenvalues of [`a`](Self::a) (real parts are growth rates, imaginary
    /// parts angular frequencies), in the order nalgebra's Schur form gives.
    ///
    /// # Errors
    /// [`AnalysisError::NoConvergence`] if the Schur iteration fails.
    pub fn eigenvalues(&self) -> Result<Vec<Complex<f64>>, AnalysisError> {
        let schur = nalgebra::linalg::Schur::try_new(self.a.clone(), f64::EPSILON, DECOMPOSITION_ITERATIONS)
            .ok_or(AnalysisError::NoConvergence { decomposition: "Schur decomposition" })?;
        Ok(schur.complex_eigenvalues().iter().copied().collect())
    }
}

/// The linearisation from the accelerations' derivatives `a_q`, `a_v`
/// (`NV × NV`) and `a_u` (`NV × k`, one column an input) at a state of
/// velocities `v`, its Jacobian `j` and `moved = ∂(J v)/∂q + ∂Φ_t/∂q`
/// (`M × NV`): the minimal coordinates of the module docs.
pub(crate) fn minimal<const NB: usize>(
    v: &[f64],
    a_q: &DMatrix<f64>,
    a_v: &DMatrix<f64>,
    j: &DMatrix<f64>,
    moved: &DMatrix<f64>,
    a_u: DMatrix<f64>,
) -> Result<Linearisation, AnalysisError> {
    reduce(full_matrix::<NB>(v, a_q, a_v), j, moved, a_u)
}

/// The minimal coordinates of a full linearisation `full` (`2 NV × 2 NV`,
/// in whatever increments) under constraints of Jacobian `j` and
/// `moved = ∂(J v)/∂q + ∂Φ_t/∂q` in those increments; `a_u` the inputs'
/// columns of `v̇`.
pub(crate) fn reduce(
    full: DMatrix<f64>,
    j: &DMatrix<f64>,
    moved: &DMatrix<f64>,
    a_u: DMatrix<f64>,
) -> Result<Linearisation, AnalysisError> {
    let nv = full.nrows() / 2;
    let (null, pinv) = null_space(j)?;
    let n = null.ncols();
    let correction = -(&pinv * moved * &null);
    let mut basis = DMatrix::zeros(2 * nv, 2 * n);
    basis.view_mut((0, 0), (nv, n)).copy_from(&null);
    basis.view_mut((nv, 0), (nv, n)).copy_from(&correction);
    basis.view_mut((nv, n), (nv, n)).copy_from(&null);
    // The left inverse: z = Nᵀ δq, w = Nᵀ (δv − V z).
    let nt = null.transpose();
    let mut left = DMatrix::zeros(2 * n, 2 * nv);
    left.view_mut((0, 0), (n, nv)).copy_from(&nt);
    left.view_mut((n, 0), (n, nv)).copy_from(&(-(&nt * &correction * &nt)));
    left.view_mut((n, nv), (n, nv)).copy_from(&nt);
    let a = &left * &full * &basis;
    let mut full_b = DMatrix::zeros(2 * nv, a_u.ncols());
    full_b.view_mut((nv, 0), (nv, a_u.ncols())).copy_from(&a_u);
    let b = &left * &full_b;
    if !(a.iter().all(|x| x.is_finite()) && b.iter().all(|x| x.is_finite())) {
        return Err(AnalysisError::NonFiniteOutput { quantity: "linearisation", row: None });
    }
    Ok(Linearisation { a, b, basis, freedoms: n, full, full_b })
}

/// The linearisation's checks: a finite `state` and `NV` rows of `inputs`.
pub(crate) fn check_inputs<S: Scene<NB, NV, M>, const NB: usize, const NV: usize, const M: usize>(
    state: &SystemState<NB>,
    inputs: &DMatrix<f64>,
) -> Result<(), AnalysisError> {
    check_state::<S, NB, NV, M>(state, true)?;
    if inputs.nrows() != NV {
        return Err(AnalysisError::BadOption { name: "inputs (NV rows)" });
    }
    Ok(())
}

/// `[[Λ(v), I], [A_q, A_v]]`, `2 NV × 2 NV`.
fn full_matrix<const NB: usize>(v: &[f64], a_q: &DMatrix<f64>, a_v: &DMatrix<f64>) -> DMatrix<f64> {
    let nv = v.len();
    let mut full = DMatrix::zeros(2 * nv, 2 * nv);
    full.view_mut((0, nv), (nv, nv)).fill_with_identity();
    for b in 0..NB {
        let o = 6 * b + 3;
        let Some(w) = v.get(o..o + 3) else { break };
        let w = nalgebra::Vector3::new(w[0], w[1], w[2]);
        full.view_mut((o, o), (3, 3)).copy_from(&(-w.cross_matrix()));
    }
    full.view_mut((nv, 0), (nv, nv)).copy_from(a_q);
    full.view_mut((nv, nv), (nv, nv)).copy_from(a_v);
    full
}

/// An orthonormal basis of J's null space (`NV × n`) and J's pseudo-inverse
/// (`NV × M`), from one SVD (J padded with zero rows to at least `NV` rows, so
/// that the SVD gives all of `V`).
fn null_space(j: &DMatrix<f64>) -> Result<(DMatrix<f64>, DMatrix<f64>), AnalysisError> {
    let (m, nv) = j.shape();
    let mut padded = DMatrix::zeros(m.max(nv), nv);
    padded.view_mut((0, 0), (m, nv)).copy_from(j);
    let svd = nalgebra::linalg::SVD::try_new(padded, true, true, f64::EPSILON, DECOMPOSITION_ITERATIONS)
        .ok_or(AnalysisError::NoConvergence { decomposition: "singular value decomposition of J" })?;
    let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else {
        return Err(AnalysisError::NoConvergence { decomposition: "singular value decomposition of J" });
    };
    let largest = svd.singular_values.max();
    let kept: Vec<bool> = svd.singular_values.iter().map(|&s| s > NULL_TOLERANCE * largest).collect();
    let null_rows: Vec<usize> = (0..nv).filter(|&i| !kept.get(i).copied().unwrap_or(false)).collect();
    let mut null = DMatrix::zeros(nv, null_rows.len());
    for (c, &i) in null_rows.iter().enumerate() {
        null.set_column(c, &v_t.row(i).transpose());
    }
    let mut pinv = DMatrix::zeros(nv, m);
    for (i, &s) in svd.singular_values.iter().enumerate() {
        if kept.get(i).copied().unwrap_or(false) {
            pinv += v_t.row(i).transpose() * u.column(i).rows(0, m).transpose() / s;
        }
    }
    Ok((null, pinv))
}

/// The state-transition Jacobian of a midpoint step of velocity `w` and size
/// `h` from the Newton matrix `r_w = ∂R/∂w` and the accelerations'
/// derivative `a_q` at the midpoint (both `NV × NV`; see
/// [`AbsoluteSimulation::transition`](super::AbsoluteSimulation::transition)).
pub(crate) fn transition_matrix<const NB: usize, const NV: usize>(
    w: &SVector<f64, NV>,
    h: f64,
    r_w: DMatrix<f64>,
    a_q: &DMatrix<f64>,
) -> Result<DMatrix<f64>, AnalysisError> {
    let (nv, turned) = (NV, update_blocks::<NB, NV>(w, h));
    let w = w.as_slice();
    // R_{q₀} = −(h/2) A_q Ad(−(h/2) ω'), R_{v₀} = −I: ∂w/∂(q₀, v₀) = −R_w⁻¹ R_{(q₀, v₀)}.
    let r_q0 = a_q * transport::<NB>(w, 0.5 * h) * (-0.5 * h);
    let singular = AnalysisError::NoConvergence { decomposition: "LU decomposition of the Newton matrix" };
    let lu = r_w.lu();
    let dw_dq = lu.solve(&(-r_q0)).ok_or(singular)?;
    let dw_dv = lu.solve(&DMatrix::identity(nv, nv)).ok_or(singular)?;
    // h J_r(h ω') per body (h I for the translation).
    let turn = update_times::<NB>(&turned, h, nv);
    let mut phi = DMatrix::zeros(2 * nv, 2 * nv);
    phi.view_mut((0, 0), (nv, nv)).copy_from(&(transport::<NB>(w, h) + &turn * &dw_dq));
    phi.view_mut((0, nv), (nv, nv)).copy_from(&(&turn * &dw_dv));
    phi.view_mut((nv, 0), (nv, nv)).copy_from(&(&dw_dq * 2.0));
    phi.view_mut((nv, nv), (nv, nv)).copy_from(&(dw_dv * 2.0 - DMatrix::identity(nv, nv)));
    if !phi.iter().all(|x| x.is_finite()) {
        return Err(AnalysisError::NonFiniteOutput { quantity: "state-transition Jacobian", row: None });
    }
    Ok(phi)
}

/// `s blockdiag(I, J_r,0, I, J_r,1, ...)`, `nv × nv`.
pub(crate) fn update_times<const NB: usize>(
    rotations: &[nalgebra::Matrix3<f64>; NB],
    s: f64,
    nv: usize,
) -> DMatrix<f64> {
    let mut out = DMatrix::identity(nv, nv) * s;
    for (b, jr) in rotations.iter().enumerate() {
        if 6 * b + 6 > nv {
            break;
        }
        out.view_mut((6 * b + 3, 6 * b + 3), (3, 3)).copy_from(&(jr * s));
    }
    out
}

/// `blockdiag(I, R(s ω'_0)ᵀ, I, ...)`: a body increment at `q` as one at
/// `q ⊕ s w` (`p ⊗ q(δθ) ⊗ q(φ) = p ⊗ q(φ) ⊗ q(R(φ)ᵀ δθ)`).
fn transport<const NB: usize>(w: &[f64], s: f64) -> DMatrix<f64> {
    let nv = w.len();
    let mut t = DMatrix::identity(nv, nv);
    for b in 0..NB {
        let o = 6 * b + 3;
        let Some(x) = w.get(o..o + 3) else { break };
        let r = nalgebra::Rotation3::new(nalgebra::Vector3::new(x[0], x[1], x[2]) * s);
        t.view_mut((o, o), (3, 3)).copy_from(&r.matrix().transpose());
    }
    t
}
