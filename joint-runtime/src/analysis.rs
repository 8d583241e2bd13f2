//! Kinematic analyses of any [`Scene`]: assembly (position analysis), velocity
//! analysis and acceleration analysis.
//!
//! All three solve underdetermined or redundant linear systems `J x = b` in the
//! minimum-norm sense, `x = Jᵀ y` with `(J Jᵀ) y = b`, factorising the Gram matrix
//! with the rank-revealing [`PivotedCholesky`]. Rows it drops as dependent are
//! *redundant* and are reported by joint name (via [`Scene::BLOCKS`]) in a
//! [`RowList`]; they receive no correction of their own, which is right when the
//! redundant rows are consistent with the others (a duplicated joint) and shows up
//! as a residual otherwise.
//!
//! Everything here works on fixed-size nalgebra types: no allocation, no panic on
//! bad input (NaN, infinities, zero quaternions, impossible configurations all
//! return an [`AnalysisError`]).
//!
//! Orientation updates stay on the rotation group: a velocity-level increment
//! `Δθ'` (body components, the `ω'` columns of `J`) moves `p ← p ⊗ q(Δθ')` with
//! `q(θ) = [cos(|θ|/2), sin(|θ|/2) θ/|θ|]` (scalar first), then `p` is renormalised.
//! Because `A(p ⊗ q) = A(p) A(q)`, this is the increment whose first-order effect
//! the `omega_body` Jacobian describes.

// The error type is returned by value: without an allocator it cannot be boxed,
// and it carries the three worst rows by design.

use core::fmt;

use nalgebra::{Matrix3, SMatrix, SVector, Vector3, Vector4};

use crate::linalg::{DEFAULT_RANK_TOLERANCE, LinalgError, PivotedCholesky};
use crate::scene::{Scene, SystemState};

/// One constraint row, located in its joint.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub struct RowInfo {
    /// The row in the system.
    pub row: u32,
    /// The row within its joint.
    pub joint_row: u32,
    /// The joint that owns it (`""` if no [`RowBlock`](crate::RowBlock) covers it).
    pub joint: &'static str,
}

impl RowInfo {
    const EMPTY: RowInfo = RowInfo { row: 0, joint: "", joint_row: 0 };

    fn of<S, const NB: usize, const NV: usize, const M: usize>(row: usize) -> Self
    where
        S: Scene<NB, NV, M>,
    {
        // Row counts are fixed-size matrix dimensions: far below u32::MAX.
        let narrow = |x: usize| u32::try_from(x).unwrap_or(u32::MAX);
        match S::block_of(row) {
            Some(b) => RowInfo { row: narrow(row), joint: b.name, joint_row: narrow(row - b.start) },
            None => RowInfo { row: narrow(row), joint: "", joint_row: 0 },
        }
    }
}

impl fmt::Display for RowInfo {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "row {} (joint `{}`, row {})", self.row, self.joint, self.joint_row)
    }
}

/// A set of at most `M` rows in increasing order, without allocation (e.g. the
/// redundant rows of a system of `M` constraints).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RowList<const M: usize> {
    rows: [RowInfo; M],
    len: usize,
}

impl<const M: usize> Default for RowList<M> {
    fn default() -> Self {
        RowList { rows: [RowInfo::EMPTY; M], len: 0 }
    }
}

impl<const M: usize> RowList<M> {
    pub(crate) fn from_rows<S, const NB: usize, const NV: usize>(rows: &[usize]) -> Self
    where
        S: Scene<NB, NV, M>,
    {
        let mut list = RowList::default();
        for &r in rows.iter().take(M) {
            // Insertion in increasing row order (after equal rows): the new row
            // goes into the first slot holding a larger row, and every later
            // entry moves up one slot, the last into the free slot `len`
            // (`len < M`: at most `M` rows are taken). Written as one pass over
            // the slots so that no index can be out of range.
            let len = list.len;
            let mut carried = RowInfo::of::<S, NB, NV, M>(r);
            let mut shifting = false;
            for (k, slot) in list.rows.iter_mut().enumerate().take(len + 1) {
                shifting = shifting || k == len || slot.row as usize > r;
                if shifting {
                    core::mem::swap(slot, &mut carried);
                }
            }
            list.len = (len + 1).min(M);
        }
        list
    }

    /// The rows.
    pub fn as_slice(&self) -> &[RowInfo] {
        self.rows.get(..self.len).unwrap_or(&[])
    }

    /// Number of rows.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Whether any row belongs to the joint `name`.
    pub fn contains_joint(&self, name: &str) -> bool {
        self.as_slice().iter().any(|r| r.joint == name)
    }
}

/// A sequence of its rows (only those in the list).
#[cfg(feature = "serde")]
impl<const M: usize> serde::Serialize for RowList<M> {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_seq(self.as_slice())
    }
}

impl<const M: usize> fmt::Display for RowList<M> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, r) in self.as_slice().iter().enumerate() {
            if i > 0 {
                f.write_str(", ")?;
            }
            write!(f, "{r}")?;
        }
        Ok(())
    }
}

/// A row and its residual value.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub struct RowResidual {
    /// Where the row is.
    pub row: RowInfo,
    /// Its residual (Φ for assembly, `J x − b` for the linear analyses).
    pub value: f64,
}

/// The (up to) three rows with the largest residuals, largest first.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub struct WorstRows(pub [Option<RowResidual>; 3]);

impl WorstRows {
    pub(crate) fn of<S, const NB: usize, const NV: usize, const M: usize>(residual: &SVector<f64, M>) -> Self
    where
        S: Scene<NB, NV, M>,
    {
        let mut worst = [None::<RowResidual>; 3];
        for (i, &v) in residual.iter().enumerate() {
            let a = libm::fabs(v);
            if a.is_nan() || a > 0.0 {
                let cand = RowResidual { row: RowInfo::of::<S, NB, NV, M>(i), value: v };
                let mut slot = 3;
                for (k, w) in worst.iter().enumerate() {
                    let beats = match w {
                        None => true,
                        Some(w) => a.is_nan() || a > libm::fabs(w.value),
                    };
                    if beats {
                        slot = k;
                        break;
                    }
                }
                if slot < 3 {
                    let mut k = 2;
                    while k > slot {
                        worst[k] = worst[k - 1];
                        k -= 1;
                    }
                    worst[slot] = Some(cand);
                }
            }
        }
        WorstRows(worst)
    }
}

impl fmt::Display for WorstRows {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut first = true;
        for r in self.0.iter().flatten() {
            if !first {
                f.write_str("; ")?;
            }
            first = false;
            write!(f, "{} = {:.3e}", r.row, r.value)?;
        }
        if first {
            f.write_str("none")?;
        }
        Ok(())
    }
}

/// Why an analysis (or a dynamics step) failed. The state is left at the last
/// accepted iterate.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub enum AnalysisError {
    /// An input is NaN or infinite.
    NonFinite {
        /// The body (from [`Scene::BODIES`]), or `None` for the time.
        body: Option<&'static str>,
        /// The field: `"r"`, `"p"`, `"rdot"`, `"omega"` or `"t"`.
        field: &'static str,
    },
    /// A body's Euler parameters are zero (no orientation to normalise).
    ZeroQuaternion {
        /// The body.
        body: &'static str,
    },
    /// The scene produced a non-finite value (e.g. a NaN joint parameter).
    NonFiniteOutput {
        /// `"Φ"`, `"Φ_t"`, `"J"`, `"γ"`, `"forces"` or `"accelerations"`.
        quantity: &'static str,
        /// The first offending row, when the quantity has rows.
        row: Option<RowInfo>,
    },
    /// Newton's method ran out of iterations.
    NotConverged {
        /// Final ‖Φ‖₂.
        residual: f64,
        /// Iterations taken.
        iterations: usize,
        /// The rows whose residual is largest.
        worst: WorstRows,
    },
    /// Newton's method made no progress: no step along the minimum-norm
    /// direction reduced ‖Φ‖ (a singular Jacobian, or an impossible configuration
    /// whose least-squares residual is not zero).
    NoProgress {
        /// ‖Φ‖₂ where it stopped.
        residual: f64,
        /// Iterations taken.
        iterations: usize,
        /// The rows whose residual is largest.
        worst: WorstRows,
    },
    /// A linear analysis (velocity, acceleration, λ) has no solution: redundant
    /// rows contradict the others.
    Inconsistent {
        /// What was solved.
        analysis: Analysis,
        /// ‖J x − b‖₂.
        residual: f64,
        /// The rows whose residual is largest.
        worst: WorstRows,
    },
    /// `NV` is not `6 NB`.
    Dimensions {
        /// Bodies.
        nb: usize,
        /// Velocity columns.
        nv: usize,
    },
    /// A body's mass is not positive and finite, or its inertia tensor is not
    /// invertible.
    BadInertia {
        /// The body.
        body: &'static str,
    },
    /// An option is out of range (a step size that is not positive and finite, ...).
    BadOption {
        /// The option.
        name: &'static str,
    },
    /// The implicit integrator's Newton iteration did not converge.
    ImplicitNotConverged {
        /// Iterations taken.
        iterations: usize,
        /// Last ‖Δv‖₂.
        correction: f64,
    },
    /// A factorisation failed (the implicit integrator's iteration matrix is singular).
    Linalg(LinalgError),
}

impl fmt::Display for AnalysisError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            AnalysisError::NonFinite { body: Some(b), field } => {
                write!(f, "non-finite input: field `{field}` of body `{b}` is NaN or infinite")
            }
            AnalysisError::NonFinite { body: None, field } => {
                write!(f, "non-finite input: `{field}` is NaN or infinite")
            }
            AnalysisError::ZeroQuaternion { body } => write!(f, "body `{body}` has zero Euler parameters"),
            AnalysisError::NonFiniteOutput { quantity, row: Some(r) } => {
                write!(f, "the scene's {quantity} is not finite at {r}")
            }
            AnalysisError::NonFiniteOutput { quantity, row: None } => write!(f, "the scene's {quantity} is not finite"),
            AnalysisError::NotConverged { residual, iterations, worst } => write!(
                f,
                "assembly did not converge: |Φ| = {residual:.3e} after {iterations} iterations; largest residuals: {worst}"
            ),
            AnalysisError::NoProgress { residual, iterations, worst } => write!(
                f,
                "assembly made no progress (singular Jacobian or impossible configuration): |Φ| = {residual:.3e} \
                 after {iterations} iterations; largest residuals: {worst}"
            ),
            AnalysisError::Inconsistent { analysis, residual, worst } => write!(
                f,
                "{analysis} analysis: redundant constraints are inconsistent, residual {residual:.3e}; largest: {worst}"
            ),
            AnalysisError::Dimensions { nb, nv } => {
                write!(f, "a scene of {nb} bodies needs {} velocity columns, not {nv}", 6 * nb)
            }
            AnalysisError::BadInertia { body } => {
                write!(f, "body `{body}` has a non-positive mass or a singular inertia tensor")
            }
            AnalysisError::BadOption { name } => write!(f, "option `{name}` is out of range"),
            AnalysisError::ImplicitNotConverged { iterations, correction } => write!(
                f,
                "implicit integrator: Newton did not converge in {iterations} iterations (last correction {correction:.3e})"
            ),
            // The factorisation's own message is `source()`'s (the API guidelines:
            // a wrapped error is either shown or returned, not both).
            AnalysisError::Linalg(_) => {
                f.write_str("a factorisation failed (a singular or non-finite iteration matrix)")
            }
        }
    }
}

impl core::error::Error for AnalysisError {
    fn source(&self) -> Option<&(dyn core::error::Error + 'static)> {
        match self {
            AnalysisError::Linalg(e) => Some(e),
            _ => None,
        }
    }
}

impl From<LinalgError> for AnalysisError {
    fn from(e: LinalgError) -> Self {
        AnalysisError::Linalg(e)
    }
}

/// Options of [`assemble`] (and of the projection step of [`crate::dynamics`]).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[non_exhaustive]
#[cfg_attr(feature = "serde", serde(default))]
pub struct AssemblyOptions {
    /// Converged when ‖Φ‖₂ ≤ `tolerance`.
    pub tolerance: f64,
    /// Newton iterations allowed.
    pub max_iterations: usize,
    /// Relative pivot tolerance of the rank-revealing factorisation.
    pub rank_tolerance: f64,
    /// Smallest step fraction the backtracking line search tries before
    /// reporting [`AnalysisError::NoProgress`].
    pub min_step: f64,
}

impl Default for AssemblyOptions {
    fn default() -> Self {
        AssemblyOptions { tolerance: 1e-12, max_iterations: 25, rank_tolerance: DEFAULT_RANK_TOLERANCE, min_step: 1e-4 }
    }
}

/// Options are `#[non_exhaustive]` (more will come); set them from the defaults:
/// `AssemblyOptions::default().with_tolerance(1e-10)`.
impl AssemblyOptions {
    /// Sets [`tolerance`](Self::tolerance).
    pub const fn with_tolerance(mut self, tolerance: f64) -> Self {
        self.tolerance = tolerance;
        self
    }
    /// Sets [`max_iterations`](Self::max_iterations).
    pub const fn with_max_iterations(mut self, max_iterations: usize) -> Self {
        self.max_iterations = max_iterations;
        self
    }
    /// Sets [`rank_tolerance`](Self::rank_tolerance).
    pub const fn with_rank_tolerance(mut self, rank_tolerance: f64) -> Self {
        self.rank_tolerance = rank_tolerance;
        self
    }
    /// Sets [`min_step`](Self::min_step).
    pub const fn with_min_step(mut self, min_step: f64) -> Self {
        self.min_step = min_step;
        self
    }
}

/// The result of [`assemble`].
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
#[non_exhaustive]
pub struct Assembly<const M: usize> {
    /// Newton iterations taken (0 if the configuration was already assembled).
    pub iterations: usize,
    /// Final ‖Φ‖₂.
    pub residual: f64,
    /// Rows found redundant at the final configuration.
    pub redundant: RowList<M>,
}

/// The result of [`velocities`].
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
#[non_exhaustive]
pub struct VelocityAnalysis<const M: usize> {
    /// ‖J v + Φ_t‖₂ after the solve.
    pub residual: f64,
    /// Redundant rows.
    pub redundant: RowList<M>,
}

/// The result of [`accelerations`].
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
#[non_exhaustive]
pub struct AccelerationAnalysis<const NV: usize, const M: usize> {
    /// `v̇ = [r̈_0, ω̇'_0, r̈_1, ...]`: the minimum-norm solution of `J v̇ = γ`.
    pub vdot: SVector<f64, NV>,
    /// ‖J v̇ − γ‖₂.
    pub residual: f64,
    /// Redundant rows.
    pub redundant: RowList<M>,
}

// ---------------------------------------------------------------------------
// Shared helpers (also used by `dynamics`).

/// Inverse mass of one body: `1/m` and `J'⁻¹`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct InverseMass {
    pub(crate) inv_mass: f64,
    pub(crate) inv_inertia: Matrix3<f64>,
}

/// The metric of a minimum-norm solve: Euclidean, or the inverse mass matrix
/// (`x = W Jᵀ y`, `(J W Jᵀ) y = b`: the solution closest in kinetic energy).
pub(crate) type Metric<'a, const NB: usize> = Option<&'a [InverseMass; NB]>;

pub(crate) fn check_dims<const NB: usize, const NV: usize>() -> Result<(), AnalysisError> {
    if NV == 6 * NB { Ok(()) } else { Err(AnalysisError::Dimensions { nb: NB, nv: NV }) }
}

/// Checks the positions (and, if `velocities`, the velocities) and the time.
pub(crate) fn check_state<S, const NB: usize, const NV: usize, const M: usize>(
    state: &SystemState<NB>,
    velocities: bool,
) -> Result<(), AnalysisError>
where
    S: Scene<NB, NV, M>,
{
    check_dims::<NB, NV>()?;
    for (i, b) in state.bodies.iter().enumerate() {
        let body = Some(S::BODIES.get(i).copied().unwrap_or(""));
        if !b.r.iter().all(|x| x.is_finite()) {
            return Err(AnalysisError::NonFinite { body, field: "r" });
        }
        if !b.p.iter().all(|x| x.is_finite()) {
            return Err(AnalysisError::NonFinite { body, field: "p" });
        }
        if velocities && !b.rdot.iter().all(|x| x.is_finite()) {
            return Err(AnalysisError::NonFinite { body, field: "rdot" });
        }
        if velocities && !b.omega.iter().all(|x| x.is_finite()) {
            return Err(AnalysisError::NonFinite { body, field: "omega" });
        }
    }
    if !state.t.is_finite() {
        return Err(AnalysisError::NonFinite { body: None, field: "t" });
    }
    Ok(())
}

/// Normalises every body's Euler parameters.
pub(crate) fn normalise_orientations<S, const NB: usize, const NV: usize, const M: usize>(
    state: &mut SystemState<NB>,
) -> Result<(), AnalysisError>
where
    S: Scene<NB, NV, M>,
{
    for (i, b) in state.bodies.iter_mut().enumerate() {
        let n = b.p.norm();
        if n.is_nan() || n <= 1e-150 || !n.is_finite() {
            return Err(AnalysisError::ZeroQuaternion { body: S::BODIES.get(i).copied().unwrap_or("") });
        }
        b.p /= n;
    }
    Ok(())
}

pub(crate) fn check_output<S, const NB: usize, const NV: usize, const M: usize, const C: usize>(
    quantity: &'static str,
    x: &SMatrix<f64, M, C>,
) -> Result<(), AnalysisError>
where
    S: Scene<NB, NV, M>,
{
    for i in 0..M {
        for j in 0..C {
            if !x[(i, j)].is_finite() {
                return Err(AnalysisError::NonFiniteOutput { quantity, row: Some(RowInfo::of::<S, NB, NV, M>(i)) });
            }
        }
    }
    Ok(())
}

/// Scalar-first quaternion product `p ⊗ q`.
pub(crate) fn quat_mul(p: &Vector4<f64>, q: &Vector4<f64>) -> Vector4<f64> {
    let (p0, pv) = (p[0], Vector3::new(p[1], p[2], p[3]));
    let (q0, qv) = (q[0], Vector3::new(q[1], q[2], q[3]));
    let s = p0 * q0 - pv.dot(&qv);
    let v = qv * p0 + pv * q0 + pv.cross(&qv);
    Vector4::new(s, v.x, v.y, v.z)
}

/// The unit quaternion of the rotation vector `θ`: `[cos(|θ|/2), sin(|θ|/2) θ/|θ|]`.
pub(crate) fn quat_exp(theta: &Vector3<f64>) -> Vector4<f64> {
    let a = theta.norm();
    let half = 0.5 * a;
    // sin(a/2)/a, with its series near zero.
    let k = if a < 1e-4 { 0.5 - a * a / 48.0 } else { libm::sin(half) / a };
    Vector4::new(libm::cos(half), k * theta.x, k * theta.y, k * theta.z)
}

/// `p ⊗ q(θ)`, renormalised.
pub(crate) fn rotate_body(p: &Vector4<f64>, theta: &Vector3<f64>) -> Vector4<f64> {
    let q = quat_mul(p, &quat_exp(theta));
    let n = q.norm();
    if n > 0.0 { q / n } else { *p }
}

/// Moves every body by `scale × Δ` (Δ = [Δr_0, Δθ'_0, Δr_1, ...]).
pub(crate) fn apply_increment<const NB: usize, const NV: usize>(
    state: &mut SystemState<NB>,
    delta: &SVector<f64, NV>,
    scale: f64,
) {
    for (i, b) in state.bodies.iter_mut().enumerate() {
        if 6 * i + 6 > NV {
            break;
        }
        let dr = Vector3::new(delta[6 * i], delta[6 * i + 1], delta[6 * i + 2]);
        let dth = Vector3::new(delta[6 * i + 3], delta[6 * i + 4], delta[6 * i + 5]);
        b.r += dr * scale;
        b.p = rotate_body(&b.p, &(dth * scale));
    }
}

/// The bodies' velocities `[ṙ_0, ω'_0, ...]`.
pub(crate) fn velocity_vector<const NB: usize, const NV: usize>(state: &SystemState<NB>) -> SVector<f64, NV> {
    let mut v = SVector::<f64, NV>::zeros();
    for (i, b) in state.bodies.iter().enumerate() {
        if 6 * i + 6 > NV {
            break;
        }
        v.fixed_rows_mut::<3>(6 * i).copy_from(&b.rdot);
        v.fixed_rows_mut::<3>(6 * i + 3).copy_from(&b.omega);
    }
    v
}

/// Writes `[ṙ_0, ω'_0, ...]` into the bodies.
pub(crate) fn set_velocities<const NB: usize, const NV: usize>(state: &mut SystemState<NB>, v: &SVector<f64, NV>) {
    for (i, b) in state.bodies.iter_mut().enumerate() {
        if 6 * i + 6 > NV {
            break;
        }
        b.rdot = v.fixed_rows::<3>(6 * i).into_owned();
        b.omega = v.fixed_rows::<3>(6 * i + 3).into_owned();
    }
}

/// `W x` for the block-diagonal metric (identity when `None`).
pub(crate) fn apply_metric<const NB: usize, const NV: usize>(
    metric: Metric<'_, NB>,
    x: &SVector<f64, NV>,
) -> SVector<f64, NV> {
    let Some(w) = metric else { return *x };
    let mut y = *x;
    for (i, m) in w.iter().enumerate() {
        if 6 * i + 6 > NV {
            break;
        }
        let f = x.fixed_rows::<3>(6 * i) * m.inv_mass;
        let t = m.inv_inertia * x.fixed_rows::<3>(6 * i + 3);
        y.fixed_rows_mut::<3>(6 * i).copy_from(&f);
        y.fixed_rows_mut::<3>(6 * i + 3).copy_from(&t);
    }
    y
}

/// `J W` for the block-diagonal metric.
pub(crate) fn jacobian_times_metric<const NB: usize, const NV: usize, const M: usize>(
    metric: Metric<'_, NB>,
    j: &SMatrix<f64, M, NV>,
) -> SMatrix<f64, M, NV> {
    let Some(w) = metric else { return *j };
    let mut out = *j;
    for (i, m) in w.iter().enumerate() {
        if 6 * i + 6 > NV {
            break;
        }
        for r in 0..M {
            for c in 0..3 {
                out[(r, 6 * i + c)] = j[(r, 6 * i + c)] * m.inv_mass;
            }
            // Row block times the symmetric J'⁻¹.
            for c in 0..3 {
                let mut s = 0.0;
                for k in 0..3 {
                    s += j[(r, 6 * i + 3 + k)] * m.inv_inertia[(k, c)];
                }
                out[(r, 6 * i + 3 + c)] = s;
            }
        }
    }
    out
}

/// Minimum-norm solution (in the metric) of `J x = b`: `x = W Jᵀ y`,
/// `(J W Jᵀ) y = b`. Returns `x`, `y` and the factorisation.
pub(crate) fn min_norm<const NB: usize, const NV: usize, const M: usize>(
    j: &SMatrix<f64, M, NV>,
    b: &SVector<f64, M>,
    metric: Metric<'_, NB>,
    rank_tolerance: f64,
) -> Result<(SVector<f64, NV>, SVector<f64, M>, PivotedCholesky<M>), AnalysisError> {
    let jw = jacobian_times_metric(metric, j);
    let gram = jw * j.transpose();
    let chol = PivotedCholesky::new(&gram, rank_tolerance)?;
    let y = chol.solve(b);
    let x = jw.transpose() * y;
    Ok((x, y, chol))
}

/// Which linear problem an [`AnalysisError::Inconsistent`] comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
#[non_exhaustive]
pub enum Analysis {
    /// Velocity analysis, `J v = −Φ_t`.
    Velocity,
    /// Acceleration analysis, `J v̇ = γ`.
    Acceleration,
    /// Forward dynamics.
    Dynamics,
}

impl core::fmt::Display for Analysis {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Analysis::Velocity => "velocity",
            Analysis::Acceleration => "acceleration",
            Analysis::Dynamics => "dynamics",
        })
    }
}

/// Solves `J x = b` (minimum norm), checks consistency, lists redundant rows.
pub(crate) fn solve_linear<S, const NB: usize, const NV: usize, const M: usize>(
    analysis: Analysis,
    j: &SMatrix<f64, M, NV>,
    b: &SVector<f64, M>,
    metric: Metric<'_, NB>,
    rank_tolerance: f64,
) -> Result<(SVector<f64, NV>, f64, RowList<M>), AnalysisError>
where
    S: Scene<NB, NV, M>,
{
    let (x, _, chol) = min_norm(j, b, metric, rank_tolerance)?;
    let r = j * x - b;
    let residual = r.norm();
    if !residual.is_finite() {
        return Err(AnalysisError::NonFiniteOutput { quantity: "accelerations", row: None });
    }
    // Consistent up to round-off: relative to the sizes of b and of J x.
    let scale = 1.0 + b.norm() + j.norm() * x.norm();
    if residual > 1e-9 * scale {
        return Err(AnalysisError::Inconsistent { analysis, residual, worst: WorstRows::of::<S, NB, NV, M>(&r) });
    }
    Ok((x, residual, RowList::from_rows::<S, NB, NV>(chol.dropped())))
}

/// Damped Newton on Φ = 0 with minimum-norm steps in the metric.
pub(crate) fn newton<S, const NB: usize, const NV: usize, const M: usize>(
    scene: &S,
    state: &mut SystemState<NB>,
    options: &AssemblyOptions,
    metric: Metric<'_, NB>,
) -> Result<Assembly<M>, AnalysisError>
where
    S: Scene<NB, NV, M>,
{
    check_state::<S, NB, NV, M>(state, false)?;
    if options.tolerance.is_nan() || options.tolerance < 0.0 {
        return Err(AnalysisError::BadOption { name: "tolerance" });
    }
    if !(options.min_step > 0.0 && options.min_step <= 1.0) {
        return Err(AnalysisError::BadOption { name: "min_step" });
    }
    normalise_orientations::<S, NB, NV, M>(state)?;
    let mut phi = scene.phi(state);
    check_output::<S, NB, NV, M, 1>("Φ", &phi)?;
    let mut norm = phi.norm();
    let mut iterations = 0;
    loop {
        let j = scene.jacobian(state);
        check_output::<S, NB, NV, M, NV>("J", &j)?;
        if norm <= options.tolerance {
            let (_, _, chol) = min_norm(&j, &phi, metric, options.rank_tolerance)?;
            return Ok(Assembly {
                iterations,
                residual: norm,
                redundant: RowList::from_rows::<S, NB, NV>(chol.dropped()),
            });
        }
        if iterations >= options.max_iterations {
            return Err(AnalysisError::NotConverged {
                residual: norm,
                iterations,
                worst: WorstRows::of::<S, NB, NV, M>(&phi),
            });
        }
        let (delta, _, _) = min_norm(&j, &(-phi), metric, options.rank_tolerance)?;
        let mut alpha = 1.0;
        loop {
            let mut trial = *state;
            apply_increment(&mut trial, &delta, alpha);
            let p = scene.phi(&trial);
            let n = p.norm();
            // Armijo on ‖Φ‖ (the Gauss-Newton direction decreases it at rate 1).
            if n.is_finite() && n <= (1.0 - 1e-4 * alpha) * norm {
                *state = trial;
                phi = p;
                norm = n;
                break;
            }
            alpha *= 0.5;
            if alpha < options.min_step {
                return Err(AnalysisError::NoProgress {
                    residual: norm,
                    iterations,
                    worst: WorstRows::of::<S, NB, NV, M>(&phi),
                });
            }
        }
        iterations += 1;
    }
}

// ---------------------------------------------------------------------------
// Public analyses.

/// Assembles the mechanism: moves `state`'s positions and orientations onto
/// Φ = 0 by damped Newton from a rough configuration.
///
/// Each iteration solves `J Δ = −Φ` in the minimum-norm least-squares sense
/// (`Δ = Jᵀ y`, `(J Jᵀ) y = −Φ` by [`PivotedCholesky`]), then tries `r += α Δr`,
/// `p ← p ⊗ q(α Δθ')` for `α = 1, ½, ¼, …` until ‖Φ‖₂ decreases (Armijo). The
/// Euler parameters are normalised first (a rough `p` need not be unit).
/// Velocities and time are not touched.
///
/// # Errors
/// [`AnalysisError::NonFinite`] names the body and field of a NaN/infinite
/// position input; [`AnalysisError::NotConverged`] after `max_iterations`;
/// [`AnalysisError::NoProgress`] when no step reduces ‖Φ‖ (singular or
/// impossible). Both name the rows with the largest residuals. On error `state`
/// holds the last accepted iterate.
pub fn assemble<S, const NB: usize, const NV: usize, const M: usize>(
    scene: &S,
    state: &mut SystemState<NB>,
    options: &AssemblyOptions,
) -> Result<Assembly<M>, AnalysisError>
where
    S: Scene<NB, NV, M>,
{
    newton(scene, state, options, None)
}

/// Velocity analysis: solves `J v = −Φ_t` (minimum norm) at `state`'s
/// configuration and writes every body's `ṙ` and `ω'`. Degrees of freedom not
/// fixed by the constraints (or drivers) get zero velocity; use this on a fully
/// driven mechanism, or to start from rest.
///
/// # Errors
/// Non-finite inputs or outputs; [`AnalysisError::Inconsistent`] when redundant
/// rows contradict the others. Redundant but consistent rows are reported in the
/// result.
pub fn velocities<S, const NB: usize, const NV: usize, const M: usize>(
    scene: &S,
    state: &mut SystemState<NB>,
) -> Result<VelocityAnalysis<M>, AnalysisError>
where
    S: Scene<NB, NV, M>,
{
    velocities_with(scene, state, DEFAULT_RANK_TOLERANCE)
}

/// [`velocities`] with a chosen relative rank tolerance.
pub fn velocities_with<S, const NB: usize, const NV: usize, const M: usize>(
    scene: &S,
    state: &mut SystemState<NB>,
    rank_tolerance: f64,
) -> Result<VelocityAnalysis<M>, AnalysisError>
where
    S: Scene<NB, NV, M>,
{
    check_state::<S, NB, NV, M>(state, false)?;
    let j = scene.jacobian(state);
    check_output::<S, NB, NV, M, NV>("J", &j)?;
    let phi_t = scene.phi_t(state);
    check_output::<S, NB, NV, M, 1>("Φ_t", &phi_t)?;
    let (v, residual, redundant) =
        solve_linear::<S, NB, NV, M>(Analysis::Velocity, &j, &(-phi_t), None, rank_tolerance)?;
    set_velocities(state, &v);
    Ok(VelocityAnalysis { residual, redundant })
}

/// Acceleration analysis: the minimum-norm solution of `J v̇ = γ` at `state`.
///
/// # Errors
/// As [`velocities`].
pub fn accelerations<S, const NB: usize, const NV: usize, const M: usize>(
    scene: &S,
    state: &SystemState<NB>,
) -> Result<AccelerationAnalysis<NV, M>, AnalysisError>
where
    S: Scene<NB, NV, M>,
{
    accelerations_with(scene, state, DEFAULT_RANK_TOLERANCE)
}

/// [`accelerations`] with a chosen relative rank tolerance.
pub fn accelerations_with<S, const NB: usize, const NV: usize, const M: usize>(
    scene: &S,
    state: &SystemState<NB>,
    rank_tolerance: f64,
) -> Result<AccelerationAnalysis<NV, M>, AnalysisError>
where
    S: Scene<NB, NV, M>,
{
    check_state::<S, NB, NV, M>(state, true)?;
    let e = scene.evaluate(state);
    check_output::<S, NB, NV, M, NV>("J", &e.jacobian)?;
    check_output::<S, NB, NV, M, 1>("γ", &e.gamma)?;
    let (vdot, residual, redundant) =
        solve_linear::<S, NB, NV, M>(Analysis::Acceleration, &e.jacobian, &e.gamma, None, rank_tolerance)?;
    Ok(AccelerationAnalysis { vdot, residual, redundant })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quaternion_exponential_composes() {
        let p = Vector4::new(1.0, 0.0, 0.0, 0.0);
        let a = rotate_body(&p, &Vector3::new(0.0, 0.0, 0.3));
        let b = rotate_body(&a, &Vector3::new(0.0, 0.0, 0.4));
        let c = rotate_body(&p, &Vector3::new(0.0, 0.0, 0.7));
        assert!((b - c).norm() < 1e-15);
        assert!(
            (quat_exp(&Vector3::new(1e-6, 0.0, 0.0)) - quat_exp(&Vector3::new(1e-6, 0.0, 0.0)).normalize()).norm()
                < 1e-15
        );
        let a = crate::rotation_matrix(&quat_exp(&Vector3::new(0.0, 0.0, core::f64::consts::FRAC_PI_2)));
        assert!((a * Vector3::x() - Vector3::y()).norm() < 1e-15);
    }
}
