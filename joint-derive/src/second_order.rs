//! Second-order terms, when a declaration asks for them (`second_order`): the
//! tangent stiffness `K(q, λ) = ∂(Jᵀλ)/∂q`, `∂(J u)/∂q`, `∂γ/∂q`, `∂γ/∂v` and
//! `∂Φ_t/∂q`: what the Newton matrix of an implicit integrator and a
//! linearisation are made of.
//!
//! Each `∂/∂q` is a directional derivative along `δ` on the rotation group
//! ([`Kinematics::direction_rules`]), whose coefficients in `δ` are the matrix:
//! a reverse-mode gradient of an expression linear in `δ`, so the entries come
//! out free of `δ`. They are matrices rather than products with a vector because
//! an iteration matrix needs all of their columns: one evaluation shares the
//! rotation matrices and the rows' intermediates across the columns, where
//! `NV` products would rebuild them `NV` times.

use crate::engine::{Id, grad};
use crate::kinematics::Kinematics;
use crate::lower::Derived;

/// The second-order terms' nodes, each matrix column-major.
pub struct SecondOrderNodes {
    /// `K = ∂(Jᵀλ)/∂q`, `NV × NV`.
    pub stiffness: Vec<Id>,
    /// `∂(J u)/∂q`, `M × NV`.
    pub jacobian_q: Vec<Id>,
    /// `∂γ/∂q`, `M × NV`.
    pub gamma_q: Vec<Id>,
    /// `∂γ/∂v`, `M × NV`.
    pub gamma_v: Vec<Id>,
    /// `∂Φ_t/∂q`, `M × NV` (zero but for drivers).
    pub phi_t_q: Vec<Id>,
}

impl SecondOrderNodes {
    /// Every entry, in the order of the runtime's `SecondOrder` fields.
    pub fn all(&self) -> Vec<Id> {
        [&self.stiffness, &self.jacobian_q, &self.gamma_q, &self.gamma_v, &self.phi_t_q]
            .into_iter()
            .flatten()
            .copied()
            .collect()
    }
}

/// Derives the second-order terms of `d`, reading `λ` from `lambda` and `u`
/// from `u` (arguments of the generated method).
pub fn derive(d: &mut Derived) -> SecondOrderNodes {
    let (m, nv) = (d.phi.len(), d.kinematics.velocities.len());
    let k = &mut d.kinematics;
    let lambda = k.argument("lambda", m);
    let u = k.argument("u", nv);
    let (directions, mut along) = k.direction_rules();
    let velocities = k.velocities.clone();
    let j = &d.jacobian;
    // Row c of K: the gradient in δ of the derivative of (Jᵀλ)_c along δ.
    let stiffness_rows: Vec<Vec<Id>> = (0..nv)
        .map(|c| {
            let f = weighted(k, (0..m).map(|i| (lambda[i], j[i][c])));
            let df = along.dt(&mut k.g, f);
            grad(&mut k.g, df, &directions)
        })
        .collect();
    let jacobian_q_rows: Vec<Vec<Id>> = (0..m)
        .map(|i| {
            let f = weighted(k, (0..nv).map(|c| (u[c], j[i][c])));
            let df = along.dt(&mut k.g, f);
            grad(&mut k.g, df, &directions)
        })
        .collect();
    let gamma_q_rows: Vec<Vec<Id>> = d
        .gamma
        .iter()
        .map(|&gamma| {
            let dg = along.dt(&mut k.g, gamma);
            grad(&mut k.g, dg, &directions)
        })
        .collect();
    let gamma_v_rows: Vec<Vec<Id>> = d.gamma.iter().map(|&gamma| grad(&mut k.g, gamma, &velocities)).collect();
    let phi_t_q_rows: Vec<Vec<Id>> = d
        .phi_t
        .iter()
        .map(|&phi_t| {
            let dp = along.dt(&mut k.g, phi_t);
            grad(&mut k.g, dp, &directions)
        })
        .collect();
    SecondOrderNodes {
        stiffness: column_major(&stiffness_rows, nv),
        jacobian_q: column_major(&jacobian_q_rows, nv),
        gamma_q: column_major(&gamma_q_rows, nv),
        gamma_v: column_major(&gamma_v_rows, nv),
        phi_t_q: column_major(&phi_t_q_rows, nv),
    }
}

/// `Σ w_i x_i` over the pairs whose `x` is not a structural zero.
fn weighted(k: &mut Kinematics, pairs: impl Iterator<Item = (Id, Id)>) -> Id {
    let mut terms = Vec::new();
    for (w, x) in pairs {
        if k.g.as_const(x) != Some(0.0) {
            terms.push(k.g.mul(w, x));
        }
    }
    k.g.sum(&terms)
}

/// Rows of `cols` entries, column by column.
fn column_major(rows: &[Vec<Id>], cols: usize) -> Vec<Id> {
    (0..cols).flat_map(|c| rows.iter().map(move |r| r[c])).collect()
}
