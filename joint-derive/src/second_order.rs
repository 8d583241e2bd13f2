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
//!
//! Only a declaration that asks for them gets them (the traits' defaults
//! return nothing), so nobody else compiles them. A scene also gets them in a
//! sparse layout (`second_order_values`): each joint's stiffness block over its
//! bodies' columns and each row's terms over its joint's columns, the
//! gradients taken along those directions only, so that the derivation and
//! the code grow with the rows rather than with `M × NV`. Above 20 000
//! Jacobian entries only that layout is written, and past 8 000 operations
//! `generate` splits its code into parts, joint by joint.

use std::ops::Range;

use crate::engine::{Id, TimeRules, grad};
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

/// What every second-order term is taken with: the method's arguments `λ`
/// and `u`, a direction variable per velocity column and the rules of the
/// derivative along it.
struct Along {
    lambda: Vec<Id>,
    u: Vec<Id>,
    directions: Vec<Id>,
    rules: TimeRules,
    velocities: Vec<Id>,
}

impl Along {
    /// Reads `λ` from `lambda` and `u` from `u` (arguments of the generated method).
    fn new(d: &mut Derived) -> Self {
        let (m, nv) = (d.phi.len(), d.kinematics.velocities.len());
        let k = &mut d.kinematics;
        let lambda = k.argument("lambda", m);
        let u = k.argument("u", nv);
        let (directions, rules) = k.direction_rules();
        Along { lambda, u, directions, rules, velocities: k.velocities.clone() }
    }

    /// The gradient in the directions of columns `cols` of the derivative of
    /// `f` along `δ`: row `f` of a `∂/∂q`.
    fn q(&mut self, k: &mut Kinematics, f: Id, cols: &[usize]) -> Vec<Id> {
        let df = self.rules.dt(&mut k.g, f);
        grad(&mut k.g, df, &pick(&self.directions, cols))
    }
}

/// `all[c]` for each `c` of `cols`.
fn pick(all: &[Id], cols: &[usize]) -> Vec<Id> {
    cols.iter().map(|&c| all[c]).collect()
}

/// The terms a declaration asked for: dense matrices, sparse blocks or both.
pub struct Terms {
    /// The dense matrices (`second_order`).
    pub dense: Option<SecondOrderNodes>,
    /// A scene's sparse blocks ([`derive_sparse`]'s layout).
    pub sparse: Option<SparseNodes>,
}

/// A scene's second-order terms in the sparse layout, with the entries that
/// belong to each joint: a joint's entries depend only on its own bodies, so
/// they can be computed apart from the other joints'.
pub struct SparseNodes {
    /// Every entry, in the layout's order.
    pub nodes: Vec<Id>,
    /// Each joint's entries: positions in `nodes`.
    pub joints: Vec<Vec<usize>>,
}

/// Derives the second-order terms of `d`: dense when `dense`, and in the
/// sparse layout for `joints` (each joint's rows and bodies) when given.
pub fn derive(d: &mut Derived, dense: bool, joints: Option<&[(Range<usize>, Vec<usize>)]>) -> Terms {
    let mut along = Along::new(d);
    Terms {
        dense: dense.then(|| derive_dense(d, &mut along)),
        sparse: joints.map(|joints| derive_sparse(d, &mut along, joints)),
    }
}

fn derive_dense(d: &mut Derived, along: &mut Along) -> SecondOrderNodes {
    let (m, nv) = (d.phi.len(), d.kinematics.velocities.len());
    let all: Vec<usize> = (0..nv).collect();
    let k = &mut d.kinematics;
    let (j, gamma, phi_t) = (&d.jacobian, &d.gamma, &d.phi_t);
    let (lambda, u, velocities) = (along.lambda.clone(), along.u.clone(), along.velocities.clone());
    let mut q = |k: &mut Kinematics, n: usize, root: &dyn Fn(&mut Kinematics, usize) -> Id| {
        let rows: Vec<Vec<Id>> = (0..n)
            .map(|i| {
                let f = root(k, i);
                along.q(k, f, &all)
            })
            .collect();
        column_major(&rows, nv)
    };
    // Row c of K: the gradient in δ of the derivative of (Jᵀλ)_c along δ.
    let stiffness = q(k, nv, &|k, c| weighted(k, (0..m).map(|i| (lambda[i], j[i][c]))));
    let jacobian_q = q(k, m, &|k, i| weighted(k, (0..nv).map(|c| (u[c], j[i][c]))));
    let gamma_q = q(k, m, &|_, i| gamma[i]);
    let phi_t_q = q(k, m, &|_, i| phi_t[i]);
    let gamma_v_rows: Vec<Vec<Id>> = gamma.iter().map(|&g| grad(&mut k.g, g, &velocities)).collect();
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

/// The second-order terms of a scene in its sparse layout (the runtime's
/// `absolute::SecondOrderLayout`): each joint's stiffness block over the columns
/// of the bodies it connects (row-major, `6n × 6n` for `n` bodies), then, row
/// by row, `∂(J u)/∂q`, `∂γ/∂q`, `∂γ/∂v` and `∂Φ_t/∂q` over the columns of the
/// row's joint. A row touches only its joint's bodies, so nothing outside these
/// blocks can be nonzero: entries grow with the rows, not with `M × NV`, and
/// each gradient is taken over its joint's directions only.
fn derive_sparse(d: &mut Derived, along: &mut Along, joints: &[(Range<usize>, Vec<usize>)]) -> SparseNodes {
    let k = &mut d.kinematics;
    let (j, gamma, phi_t) = (&d.jacobian, &d.gamma, &d.phi_t);
    let mut stiffness = Vec::new();
    let mut rows: [Vec<(usize, Id)>; 4] = Default::default();
    for (joint, (range, bodies)) in joints.iter().enumerate() {
        let cols: Vec<usize> = bodies.iter().flat_map(|b| 6 * b..6 * b + 6).collect();
        for &c in &cols {
            let f = weighted(k, range.clone().map(|i| (along.lambda[i], j[i][c])));
            stiffness.extend(along.q(k, f, &cols).into_iter().map(|n| (joint, n)));
        }
        for i in range.clone() {
            let ju = weighted(k, cols.iter().map(|&c| (along.u[c], j[i][c])));
            let tagged = |v: Vec<Id>| v.into_iter().map(move |n| (joint, n));
            rows[0].extend(tagged(along.q(k, ju, &cols)));
            rows[1].extend(tagged(along.q(k, gamma[i], &cols)));
            rows[2].extend(tagged(grad(&mut k.g, gamma[i], &pick(&along.velocities, &cols))));
            rows[3].extend(tagged(along.q(k, phi_t[i], &cols)));
        }
    }
    let mut out = SparseNodes { nodes: Vec::new(), joints: vec![Vec::new(); joints.len()] };
    for (joint, n) in stiffness.into_iter().chain(rows.into_iter().flatten()) {
        out.joints[joint].push(out.nodes.len());
        out.nodes.push(n);
    }
    out
}
