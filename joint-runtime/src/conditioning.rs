//! How far a mechanism is from a singular configuration.
//!
//! A joint's own rows can lose rank (the [`Singularity`](crate::Singularity)
//! measures), but many singularities belong to the mechanism: a Cardan shaft bent
//! by 90° has every joint's rows in full rank, yet its system Jacobian loses a
//! rank at the phase where the output would have to turn infinitely fast. Such a
//! configuration is a drop in the rank of `J` below `NV − dof`, where `dof` is
//! the mechanism's mobility (0 for a fully driven mechanism). [`conditioning`]
//! measures it with the singular values of `J`: the measure is `σ_k / σ_1` with
//! `k = NV − dof`, the smallest singular value that must not vanish, relative to
//! the largest. It is 1 for a perfectly conditioned system and tends to zero at
//! the singularity; near it a velocity or acceleration analysis loses about
//! `log10(1 / measure)` digits to the conditioning of the problem (not to the
//! generated code), and at it the analyses return
//! [`AnalysisError::Inconsistent`] naming the rows (a driver that can no longer
//! be followed) rather than a velocity.
//!
//! The singular values come from the one-sided Jacobi method (Hestenes):
//! plane rotations orthogonalise the columns of `J` until every pair is
//! orthogonal to working precision; the column norms are then the singular
//! values, each to high *relative* accuracy, which is what a measure near zero
//! needs (forming `JᵀJ` would square the condition number). Fixed-size, no
//! allocation, at most [`MAX_SWEEPS`] sweeps of `NV (NV − 1) / 2` rotations.
//!
//! `J` mixes translational columns (`ṙ`, length per time) and rotational ones
//! (`ω'`, per time): the measure depends on the unit of length, like any
//! condition number of a mixed-unit matrix. Compare it along one mechanism, not
//! across mechanisms.

use nalgebra::{SMatrix, SVector};

use crate::analysis::{AnalysisError, check_output, check_state};
use crate::scene::{Scene, SystemState};

/// Sweeps allowed before [`singular_values`] stops (each sweep rotates every
/// pair of columns once; convergence is quadratic, 6 to 10 sweeps are typical).
pub const MAX_SWEEPS: usize = 40;

/// The singular values of a matrix with at least as many rows as columns, in
/// decreasing order (`M < N` leaves `N − M` zeros at the end).
///
/// A non-finite entry gives NaN singular values (use [`conditioning`] on a
/// scene for a named error).
///
/// ```
/// use joint_runtime::conditioning::singular_values;
/// use joint_runtime::nalgebra::Matrix3x2;
///
/// // Columns (3, 0, 4) and (0, 2, 0): orthogonal, norms 5 and 2.
/// let s = singular_values(&Matrix3x2::new(3.0, 0.0, 0.0, 2.0, 4.0, 0.0));
/// assert!((s[0] - 5.0).abs() < 1e-15 && (s[1] - 2.0).abs() < 1e-15);
/// ```
pub fn singular_values<const M: usize, const N: usize>(a: &SMatrix<f64, M, N>) -> SVector<f64, N> {
    let mut w = *a;
    for _ in 0..MAX_SWEEPS {
        let mut rotated = false;
        for p in 0..N {
            for q in p + 1..N {
                let (cp, cq) = (w.column(p).clone_owned(), w.column(q).clone_owned());
                let (alpha, beta, gamma) = (cp.norm_squared(), cq.norm_squared(), cp.dot(&cq));
                // Orthogonal to working precision (or a zero column): no rotation.
                if gamma.abs() <= f64::EPSILON * libm::sqrt(alpha * beta) || gamma == 0.0 {
                    continue;
                }
                rotated = true;
                // The rotation that zeroes the pair's off-diagonal entry of WᵀW,
                // with the smaller angle (|t| ≤ 1) for stability.
                let zeta = (beta - alpha) / (2.0 * gamma);
                let t = libm::copysign(1.0, zeta) / (zeta.abs() + libm::sqrt(1.0 + zeta * zeta));
                let c = 1.0 / libm::sqrt(1.0 + t * t);
                let s = c * t;
                w.set_column(p, &(cp * c - cq * s));
                w.set_column(q, &(cp * s + cq * c));
            }
        }
        if !rotated {
            break;
        }
    }
    let mut sigma = SVector::<f64, N>::from_fn(|j, _| w.column(j).norm());
    // Insertion sort, decreasing (N is small; no allocation).
    for i in 1..N {
        let mut j = i;
        while j > 0 && sigma[j - 1] < sigma[j] {
            sigma.swap_rows(j - 1, j);
            j -= 1;
        }
    }
    sigma
}

/// The result of [`conditioning`].
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
#[non_exhaustive]
pub struct Conditioning<const NV: usize> {
    /// `σ_k / σ_1` with `k = NV − dof` (0 if `dof ≥ NV` leaves nothing to
    /// measure, or if `J` is zero): 1 well conditioned, 0 singular.
    pub measure: f64,
    /// The singular values of `J`, decreasing.
    pub singular_values: SVector<f64, NV>,
    /// The numerical rank: singular values above `rank_tolerance · σ_1`.
    pub rank: usize,
}

impl<const NV: usize> Conditioning<NV> {
    /// Whether the rank fell below `NV − dof`: the configuration is singular (to
    /// the tolerance `conditioning` was called with).
    pub fn is_singular(&self, dof: usize) -> bool {
        self.rank < NV.saturating_sub(dof)
    }
}

/// The conditioning of `scene`'s Jacobian at `state`, for a mechanism of
/// mobility `dof` (0 when drivers fix every motion); see the module
/// documentation. `rank_tolerance` is relative to `σ_1` (1e-10 is a good
/// default: the analyses use the same relative tolerance on `J Jᵀ`'s pivots,
/// i.e. on `σ²`).
///
/// # Errors
/// [`AnalysisError::NonFinite`] names a NaN or infinite input;
/// [`AnalysisError::NonFiniteOutput`] a non-finite entry of `J`.
///
/// ```
/// use joint_runtime::conditioning::conditioning;
/// use joint_runtime::nalgebra::{UnitQuaternion, Vector3};
/// use joint_runtime::{OmegaBody, Scene, SystemState};
///
/// /// A link hinged at the origin about y: mobility 1.
/// #[derive(Scene)]
/// #[scene(coordinates = absolute)]
/// #[body(link, mass = 1.0, inertia = [0.0833, 0.0833, 0.001])]
/// #[joint(hinge = revolute(ground, link), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0, 0, 0], rho2 = [0, 0, 0.5])]
/// struct Pendulum;
///
/// let z = Vector3::zeros();
/// let link = OmegaBody::from_rotation(Vector3::new(0.0, 0.0, -0.5), &UnitQuaternion::identity(), z, z);
/// let c = conditioning(&Pendulum, &SystemState { bodies: [link], t: 0.0 }, 1, 1e-10).expect("finite");
/// // Five rows fix five of six velocities: rank 5, well conditioned.
/// assert_eq!(c.rank, 5);
/// assert!(!c.is_singular(1) && c.measure > 0.1);
/// ```
pub fn conditioning<S, const NB: usize, const NV: usize, const M: usize>(
    scene: &S,
    state: &SystemState<NB>,
    dof: usize,
    rank_tolerance: f64,
) -> Result<Conditioning<NV>, AnalysisError>
where
    S: Scene<NB, NV, M>,
{
    check_state::<S, NB, NV, M>(state, false)?;
    let j = scene.jacobian(state);
    check_output::<S, NB, NV, M, NV>("J", &j)?;
    let sigma = if M >= NV {
        singular_values(&j)
    } else {
        // Fewer rows than columns: the singular values of Jᵀ are the same.
        let s = singular_values(&j.transpose());
        SVector::<f64, NV>::from_fn(|i, _| s.get(i).copied().unwrap_or(0.0))
    };
    let largest = sigma.get(0).copied().unwrap_or(0.0);
    let tolerance = if rank_tolerance > 0.0 { rank_tolerance } else { 0.0 };
    let rank = sigma.iter().filter(|&&s| s > tolerance * largest && s > 0.0).count();
    let k = NV.saturating_sub(dof);
    let measure = match (k.checked_sub(1).and_then(|i| sigma.get(i)), largest > 0.0) {
        (Some(&s), true) => s / largest,
        _ => 0.0,
    };
    Ok(Conditioning { measure, singular_values: sigma, rank })
}
