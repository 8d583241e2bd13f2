//! The exact iteration matrix of the implicit midpoint rule, from the scene's
//! generated second-order terms (`#[scene(second_order)]`).
//!
//! The midpoint residual is `R(w) = w − v_n − (h/2) a(q_½, w, t_½)` with
//! `q_½ = q_n ⊕ (h/2) w`. Differentiating the equations of motion
//! `M a + Jᵀ λ = Q`, `J a = γ` at the midpoint along `(δq, δv)`:
//!
//! ```text
//! M δa + Jᵀ δλ = Q_q δq + Q_v δv − K δq                  K = ∂(Jᵀλ)/∂q
//! J δa          = (γ_q − ∂(J a)/∂q) δq + γ_v δv
//! ```
//!
//! with `δq = (h/2) T δw` (`T` the right Jacobian of the rotation update,
//! per body `J_r(φ)` with `φ = (h/2) ω'`, the identity for the translation)
//! and `δv = δw`; then `∂R/∂w = I − (h/2) ∂a/∂w`. One factorisation of
//! `J M⁻¹ Jᵀ` (under the step's rule for redundant rows, as the accelerations
//! themselves) serves every column. `K`, `∂(J a)/∂q`, `γ_q` and `γ_v` are
//! generated; `Q_q` and `Q_v` come from `force_derivatives.rs` (exact but for
//! user loads that give no derivative of their own).
//!
//! With Baumgarte stabilisation `γ − 2α (J v + Φ_t) − β² Φ`, the matrix adds
//! `−2α (∂(J v)/∂q + ∂Φ_t/∂q) − β² J` in `δq` and `−2α J` in `δv`.
//! [`Tangent`] holds these pieces at one state; the linearisation
//! (`dynamics/linear.rs`) uses them too.

use nalgebra::{Matrix3, SVector, Vector3};

#[cfg(feature = "alloc")]
/// The rotation blocks of `∂(q_n ⊕ s w)/∂w` as increments at the result,
/// `J_r(s ω')` per body (`p ⊗ q(φ)` moves by `J_r(φ) δφ` in body components);
/// the translation blocks are the identity. Both are scaled by `s` in
/// [`times_update`].
pub(crate) fn update_blocks<const NB: usize, const NV: usize>(w: &SVector<f64, NV>, s: f64) -> [Matrix3<f64>; NB] {
    core::array::from_fn(|b| update_block(w, s, b))
}

/// Body `b`'s block of [`update_blocks`].
fn update_block<const NV: usize>(w: &SVector<f64, NV>, s: f64, b: usize) -> Matrix3<f64> {
    let at = |k: usize| w.get(6 * b + 3 + k).copied().unwrap_or(0.0) * s;
    right_jacobian(&Vector3::new(at(0), at(1), at(2)))
}

/// [`update_blocks`] into `out` (a workspace's, one block per body).
pub(crate) fn update_blocks_into<const NV: usize>(w: &SVector<f64, NV>, s: f64, out: &mut [Matrix3<f64>]) {
    for (b, o) in out.iter_mut().enumerate() {
        *o = update_block(w, s, b);
    }
}

/// The right Jacobian of SO(3): `I − (1 − cos θ)/θ² φ̃ + (θ − sin θ)/θ³ φ̃²`,
/// with the series of its coefficients near θ = 0.
pub(super) fn right_jacobian(phi: &Vector3<f64>) -> Matrix3<f64> {
    let theta2 = phi.norm_squared();
    let (a, b) = if theta2 < 1e-8 {
        (0.5 - theta2 / 24.0, 1.0 / 6.0 - theta2 / 120.0)
    } else {
        let theta = libm::sqrt(theta2);
        ((1.0 - libm::cos(theta)) / theta2, (theta - libm::sin(theta)) / (theta2 * theta))
    };
    let k = phi.cross_matrix();
    Matrix3::identity() - k * a + k * k * b
}
