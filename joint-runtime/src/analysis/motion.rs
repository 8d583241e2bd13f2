//! Moving a state: increments on the rotation group, velocities in and out of
//! the column vector `[ṙ_0, ω'_0, ...]`, normalised Euler parameters.

use nalgebra::{SVector, Vector3, Vector4};

use super::AnalysisError;
use crate::scene::{Scene, SystemState};

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
    velocity_vector_into(state, &mut v);
    v
}

/// [`velocity_vector`] written into `v` (entries past the bodies zeroed): a
/// workspace's vector rather than one in the caller's frame.
pub(crate) fn velocity_vector_into<const NB: usize, const NV: usize>(
    state: &SystemState<NB>,
    v: &mut SVector<f64, NV>,
) {
    v.fill(0.0);
    for (i, b) in state.bodies.iter().enumerate() {
        if 6 * i + 6 > NV {
            break;
        }
        v.fixed_rows_mut::<3>(6 * i).copy_from(&b.rdot);
        v.fixed_rows_mut::<3>(6 * i + 3).copy_from(&b.omega);
    }
}

/// Writes `[ṙ_0, ω'_0, ...]` into the bodies.
pub(crate) fn set_velocities<const NB: usize, const NV: usize>(state: &mut SystemState<NB>, v: &SVector<f64, NV>) {
    // Six entries a body, matched by pattern: no index to check (the
    // optimiser could not always see `6 i + 6 ≤ NV`; `no-panic-check`).
    for (b, chunk) in state.bodies.iter_mut().zip(v.as_slice().chunks_exact(6)) {
        if let [x, y, z, wx, wy, wz] = *chunk {
            b.rdot = Vector3::new(x, y, z);
            b.omega = Vector3::new(wx, wy, wz);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Vector3, Vector4};

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
