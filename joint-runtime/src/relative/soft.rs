//! MuJoCo's soft equalities: an MJCF file's `connect`, `weld` and `joint`
//! equalities as MuJoCo 4.0 holds them, which is not as ideal rows.
//!
//! MuJoCo makes every equality row `i` a spring-damper in the constraint
//! space: its forces `f` solve `(J M⁻¹ Jᵀ + R) f = a_ref − J q̈₀`, with
//! `q̈₀` the tree's own accelerations, `a_ref` the row's reference
//! acceleration and `q̈ = q̈₀ + M⁻¹ Jᵀ f`. Its
//! numbers, each as MuJoCo's `engine_core_constraint.c` makes it:
//!
//! - `r`: the row's residual (`Φ`; a `connect`'s anchor apart, a `weld`'s
//!   too and then its quaternion error times `torquescale`, a `joint`'s
//!   `q₁ − q₁⁰ − poly(q₂ − q₂⁰)`). Row signs and an orthogonal change of a
//!   `connect`'s axes leave `q̈` unchanged (its three rows share `R` and the
//!   impedance reads their norm), so the derive's rows serve as they are.
//! - `a_ref = −B (J v) − K imp r + γ`: MuJoCo 4.0 takes a `connect`'s and
//!   a `weld`'s `J̇ v` out of its reference (`mj_Jdotv`), which is the
//!   rows' `γ`.
//! - `imp(x)` from `solimp = (d₀, d_w, width, mid, power)`: `d₀` at zero
//!   residual, `d_w` past `width`, a two-piece power curve between; its
//!   argument the norm of a `connect`'s three rows (a `weld`'s six), a
//!   `joint`'s signed row.
//! - `R = max(10⁻¹⁵, (1 − imp)/imp · dA)`, `dA` the "diagonal
//!   approximation": the inverse weights of the bodies (`connect`: each
//!   body's translational `body_invweight0`, the mean diagonal of
//!   `J_c M⁻¹ J_cᵀ` at its centre of mass; a `weld`'s orientation rows the
//!   rotational one) or freedoms (`joint`:
//!   `dof_invweight0 = (M⁻¹)ᵢᵢ`), all at the file's reference configuration
//!   ([`Softness::new`], once per simulation).
//! - `K`, `B` from `solref`: `(τ, ζ)` gives `K = 1/(d_w τ ζ)²`,
//!   `B = 2/(d_w τ)`; negative numbers `(−k, −b)` give `K = k/d_w²`,
//!   `B = b/d_w`. The derive raises `τ` to twice the file's timestep and
//!   clamps `solimp` as MuJoCo does.
//!
//! MuJoCo's Newton solver minimises a quadratic on such rows, so its `q̈`
//! is this one to round-off. The derivatives differentiate the same
//! equations: `R` and `a_ref` through `imp(r(q))`, `a_ref` through `J v`
//! ([`Softness::derivative_rows`]).

use nalgebra::{SMatrix, SVector};

use super::topology::{Tree, TreeError};
use super::{ClosureRows, TreeScene};
use crate::SecondOrder;

/// MuJoCo's smallest number (`mjMINVAL`), where it floors `R`, `K`, `B`.
const MINVAL: f64 = 1e-15;

/// Whose inverse weights make a soft equality's `dA` (MuJoCo's
/// `diagApprox`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum InverseWeight {
    /// A `connect`: the translational inverse weight of each of its two
    /// MuJoCo bodies, each a body of the scene with that MuJoCo body's
    /// centre of mass in the scene body's frame, or `None` for the world
    /// (and a body welded to it: weight zero).
    Bodies([Option<(usize, [f64; 3])>; 2]),
    /// A `weld`: the same bodies' translational inverse weights on its
    /// first three rows, their rotational ones (`body_invweight0`'s second,
    /// the mean diagonal of `J_ω M⁻¹ J_ωᵀ`) on its orientation rows.
    Weld([Option<(usize, [f64; 3])>; 2]),
    /// A `joint`: the inverse weight of each joint's freedom (its index
    /// among the tree's freedoms), `None` where the equality names one joint.
    Freedoms([Option<usize>; 2]),
}

/// One of a file's equalities as MuJoCo softens it (the scene's `SOFT`,
/// written by the derive for an MJCF file read without `equality = hard`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SoftEquality {
    /// Its block among the scene's `CLOSURES`.
    pub block: usize,
    /// `solref`: time constant and damping ratio (the time constant at
    /// least twice the file's timestep, as MuJoCo raises it), or negative
    /// stiffness and damping.
    pub solref: [f64; 2],
    /// `solimp`: `d₀`, `d_width`, `width`, `midpoint`, `power`, clamped as
    /// MuJoCo clamps them.
    pub solimp: [f64; 5],
    /// Whose inverse weights make its `dA`.
    pub weight: InverseWeight,
}

/// A scene's soft rows, fixed once per simulation: which rows are soft and
/// each one's `dA`, `K`, `B` (zero on the ideal rows).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Softness<const NC: usize> {
    pub(crate) soft: [bool; NC],
    /// Each soft row's equality (its index in the scene's `SOFT`).
    equality: [usize; NC],
    diag: [f64; NC],
    stiffness: [f64; NC],
    damping: [f64; NC],
}

/// A soft row's terms at one state: `R`, `a_ref`, and what their
/// derivatives take.
pub(crate) struct SoftTerms<const NC: usize> {
    /// `R` (zero on the ideal rows).
    pub(crate) regularisation: [f64; NC],
    /// `a_ref` (zero on the ideal rows).
    pub(crate) reference: SVector<f64, NC>,
    /// Each row's block impedance.
    imp: [f64; NC],
    /// `∂imp/∂rᵢ` of row `i`'s block.
    imp_r: [f64; NC],
}

impl<const NC: usize> Softness<NC> {
    /// No soft rows.
    pub(crate) const fn none() -> Self {
        Softness { soft: [false; NC], equality: [0; NC], diag: [0.0; NC], stiffness: [0.0; NC], damping: [0.0; NC] }
    }

    /// `scene`'s soft rows on `tree`: `dA` from `M⁻¹` and the bodies'
    /// Jacobians at the reference configuration (MuJoCo's `mj_setConst`).
    pub(crate) fn new<S, const NB: usize, const NQ: usize, const NV: usize>(
        tree: &Tree<NB, NQ, NV>,
    ) -> Result<Self, TreeError>
    where
        S: TreeScene<NB, NQ, NV, NC>,
    {
        let mut out = Self::none();
        if S::SOFT.is_empty() {
            return Ok(out);
        }
        let q = tree.zero_state().q;
        let mut m = SMatrix::<f64, NV, NV>::zeros();
        tree.mass_matrix_into(&q, &mut m);
        let singular = TreeError::Singular { joint: tree.joints.first().map_or("", |j| j.name) };
        let minv = nalgebra::Cholesky::new(m).ok_or(singular)?.inverse();
        // A body's translational and rotational inverse weights at its
        // MuJoCo body's centre: point_jacobian's rows are `[ω; ṗ]`.
        let body = |end: Option<(usize, [f64; 3])>| {
            let (b, p) = end?;
            let j = tree.point_jacobian(&q, b, &p.into())?;
            let a = j * minv * j.transpose();
            Some([(a[(3, 3)] + a[(4, 4)] + a[(5, 5)]) / 3.0, (a[(0, 0)] + a[(1, 1)] + a[(2, 2)]) / 3.0])
        };
        let bodies = |ends: [Option<(usize, [f64; 3])>; 2]| {
            let [a, b] = ends.map(|end| body(end).unwrap_or([0.0; 2]));
            [a[0] + b[0], a[1] + b[1]]
        };
        let freedom = |f: Option<usize>| f.filter(|&f| f < NV).map(|f| minv[(f, f)]);
        for (n, e) in S::SOFT.iter().enumerate() {
            let Some(block) = S::CLOSURES.get(e.block) else { continue };
            // Each row's weight: a weld's orientation rows (its last three) their own.
            let [translation, rotation] = match e.weight {
                InverseWeight::Bodies(ends) => [bodies(ends)[0]; 2],
                InverseWeight::Weld(ends) => bodies(ends),
                InverseWeight::Freedoms(ends) => [ends.iter().map(|&f| freedom(f).unwrap_or(0.0)).sum::<f64>(); 2],
            };
            let (stiffness, damping) = reference_gains(e);
            for r in (block.start..block.start + block.rows).filter(|&r| r < NC) {
                out.soft[r] = true;
                out.equality[r] = n;
                out.diag[r] = if r - block.start < 3 { translation } else { rotation };
                out.stiffness[r] = stiffness;
                out.damping[r] = damping;
            }
        }
        Ok(out)
    }

    /// Whether any row is soft.
    pub(crate) fn any(&self) -> bool {
        self.soft.iter().any(|s| *s)
    }

    /// Whether every row is soft (and there is one).
    pub(crate) fn all(&self) -> bool {
        NC > 0 && self.soft.iter().all(|s| *s)
    }

    /// The soft rows' targets (`a_ref`) into `target`, the ideal rows' left.
    pub(crate) fn target(&self, terms: &SoftTerms<NC>, target: &mut SVector<f64, NC>) {
        for (r, _) in self.soft.iter().enumerate().filter(|(_, s)| **s) {
            target[r] = terms.reference[r];
        }
    }

    /// `R` and `a_ref` at the rows' state (`rows.phi`, `J v`), each soft
    /// block's impedance from its residual's norm.
    pub(crate) fn terms<S, const NB: usize, const NQ: usize, const NV: usize>(
        &self,
        rows: &ClosureRows<NC, NV>,
        v: &SVector<f64, NV>,
    ) -> SoftTerms<NC>
    where
        S: TreeScene<NB, NQ, NV, NC>,
    {
        let mut out =
            SoftTerms { regularisation: [0.0; NC], reference: SVector::zeros(), imp: [0.0; NC], imp_r: [0.0; NC] };
        let velocity = rows.jacobian * v;
        for e in S::SOFT {
            let Some(block) = S::CLOSURES.get(e.block) else { continue };
            let range = block.start..(block.start + block.rows).min(NC);
            // A connect's impedance reads its rows' norm; a joint's its signed row.
            let signed = block.rows == 1;
            let norm = libm::sqrt(range.clone().map(|r| rows.phi[r] * rows.phi[r]).sum::<f64>());
            let pos = if signed { range.clone().map(|r| rows.phi[r]).sum::<f64>() } else { norm };
            let (imp, imp_pos) = impedance(&e.solimp, pos);
            for r in range {
                out.imp[r] = imp;
                out.imp_r[r] = match (signed, norm > 0.0) {
                    (true, _) => imp_pos,
                    (false, true) => imp_pos * rows.phi[r] / norm,
                    (false, false) => 0.0,
                };
                out.regularisation[r] = ((1.0 - imp) * self.diag[r] / imp).max(MINVAL);
                // MuJoCo 4.0 takes `J̇ v` out of a connect's reference (`mj_Jdotv`):
                // `γ`, zero on a joint's linear row.
                out.reference[r] =
                    -self.damping[r] * velocity[r] - self.stiffness[r] * imp * rows.phi[r] + rows.gamma[r];
            }
        }
        out
    }

    /// The soft rows of the KKT derivatives' second block: with `f` the
    /// rows' forces, row `i` of `∂/∂q` is `∂a_ref,ᵢ/∂q − ∂(J q̈)ᵢ/∂q −
    /// fᵢ ∂Rᵢ/∂q`, of `∂/∂v` it is `∂a_ref,ᵢ/∂v`. `second` holds
    /// `∂(J u)/∂q` at the `u` the caller took (`q̈ + 2α v`, `alpha` its
    /// Baumgarte gain) and `∂γ/∂(q, v)`, `jv_q` is `∂(J v)/∂q`; the ideal
    /// rows are left as they are.
    pub(crate) fn derivative_rows<const NV: usize>(
        &self,
        terms: &SoftTerms<NC>,
        (phi, jacobian): (&SVector<f64, NC>, &SMatrix<f64, NC, NV>),
        f: &SVector<f64, NC>,
        (second, jv_q, alpha): (&SecondOrder<f64, NC, NV>, &SMatrix<f64, NC, NV>, f64),
        r2_q: &mut SMatrix<f64, NC, NV>,
        r2_v: &mut SMatrix<f64, NC, NV>,
    ) {
        // Entry by entry on indices the loops bound: nothing here can panic.
        for i in 0..NC {
            if !self.soft[i] {
                continue;
            }
            // ∂imp/∂q of row i's block: Σ over the block's rows of ∂imp/∂rⱼ Jⱼ.
            let mut imp_q = [0.0; NV];
            for j in (0..NC).filter(|&j| self.soft[j] && self.equality[j] == self.equality[i]) {
                for (c, x) in imp_q.iter_mut().enumerate() {
                    *x += jacobian[(j, c)] * terms.imp_r[j];
                }
            }
            let (imp, k, b) = (terms.imp[i], self.stiffness[i], self.damping[i]);
            let r_imp = if (1.0 - imp) * self.diag[i] / imp > MINVAL { -self.diag[i] / (imp * imp) } else { 0.0 };
            let through_imp = k * phi[i] + f[i] * r_imp;
            for (c, x) in imp_q.iter().enumerate() {
                r2_q[(i, c)] = -k * imp * jacobian[(i, c)] - x * through_imp
                    + jv_q[(i, c)] * (2.0 * alpha - b)
                    + second.gamma_q[(i, c)]
                    - second.jacobian_q[(i, c)];
                r2_v[(i, c)] = second.gamma_v[(i, c)] - jacobian[(i, c)] * b;
            }
        }
    }
}

/// `K`, `B` of an equality's rows from its `solref` (MuJoCo's
/// `mj_makeImpedance`).
fn reference_gains(e: &SoftEquality) -> (f64, f64) {
    let ([t, z], dmax) = (e.solref, e.solimp[1]);
    let k = if t > 0.0 { 1.0 / (dmax * dmax * t * t * z * z).max(MINVAL) } else { -t / (dmax * dmax).max(MINVAL) };
    let b = if z > 0.0 { 2.0 / (dmax * t).max(MINVAL) } else { -z / dmax.max(MINVAL) };
    (k, b)
}

/// MuJoCo's impedance at residual `pos` and its derivative (`getimpedance`,
/// no margin).
fn impedance(solimp: &[f64; 5], pos: f64) -> (f64, f64) {
    let [d0, dw, width, mid, power] = *solimp;
    if d0 == dw || width <= MINVAL {
        return (0.5 * (d0 + dw), 0.0);
    }
    let x = pos / width;
    let (x, sign) = if x < 0.0 { (-x, -1.0) } else { (x, 1.0) };
    if x >= 1.0 || x <= 0.0 {
        return (if x >= 1.0 { dw } else { d0 }, 0.0);
    }
    let pow = |a: f64, b: f64| {
        if b == 1.0 {
            a
        } else if b == 2.0 {
            a * a
        } else {
            libm::pow(a, b)
        }
    };
    let (y, y_x) = if power == 1.0 {
        (x, 1.0)
    } else if x <= mid {
        let a = 1.0 / pow(mid, power - 1.0);
        (a * pow(x, power), power * a * pow(x, power - 1.0))
    } else {
        let b = 1.0 / pow(1.0 - mid, power - 1.0);
        (1.0 - b * pow(1.0 - x, power), power * b * pow(1.0 - x, power - 1.0))
    };
    (d0 + y * (dw - d0), y_x * sign * (dw - d0) / width)
}
