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
    let (j, gamma, phi_t) = (&d.jacobian, &d.gamma, &d.phi_t);
    let mut q = |k: &mut Kinematics, n: usize, root: &dyn Fn(&mut Kinematics, usize) -> Id| {
        let rows: Vec<Vec<Id>> = (0..n)
            .map(|i| {
                let f = root(k, i);
                let df = along.dt(&mut k.g, f);
                grad(&mut k.g, df, &directions)
            })
            .collect();
        column_major(&rows, nv)
    };
    // Row c of K: the gradient in δ of the derivative of (Jᵀλ)_c along δ.
    let stiffness = q(k, nv, &|k, c| weighted(k, (0..m).map(|i| (lambda[i], j[i][c]))));
    let jacobian_q = q(k, m, &|k, i| weighted(k, (0..nv).map(|c| (u[c], j[i][c]))));
    let gamma_q = q(k, m, &|_, i| gamma[i]);
    let gamma_v_rows: Vec<Vec<Id>> = gamma.iter().map(|&g| grad(&mut k.g, g, &velocities)).collect();
    let phi_t_q = q(k, m, &|_, i| phi_t[i]);
    SecondOrderNodes { stiffness, jacobian_q, gamma_q, gamma_v: column_major(&gamma_v_rows, nv), phi_t_q }
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
