//! The first derivatives of a tree's inverse dynamics, written out
//! (`TreeScene::inverse_dynamics_derivatives_into`): `∂τ/∂q` and `∂τ/∂v` of
//! the recursive Newton–Euler graph (`aba::newton_euler`), by the engine's
//! forward-mode derivative along each freedom, so that nobody writes a
//! chain rule by hand.
//!
//! `∂/∂q` is taken in the tangent space, one column per freedom (`NV`, not
//! `NQ`): along `q ⊕ ε e_i`, the runtime's `Tree::displace` (an angle or a
//! slide moved by `ε`; a quaternion turned by `ε` about its own axis `i`,
//! `ṗ = ½ p ⊗ (0, e_i)`; a free joint's offset moved along its child's
//! axis `i`, `ṙ = R e_i`), which is Pinocchio's convention to first order.
//! A direction's derivative of a node that does not depend on it folds to
//! zero as it is made, so each column costs the joints the freedom moves
//! (its subtree on the way down, its path to the root on the way up):
//! the sparsity Carpentier and Mansard's recursion exploits by hand.
//! The forward dynamics' derivatives follow in the runtime as
//! `∂q̈/∂x = −M⁻¹ ∂τ/∂x` at `v̇ = q̈` (`relative/derivatives.rs`).
//!
//! The same again, forward mode twice, gives the second derivatives of
//! `λᵀ τ` that a DDP backward pass contracts
//! (`inverse_dynamics_second_derivatives_into`), each direction's rules and
//! memo shared by every column it takes. The first derivatives are written up
//! to 8 000 operations (`FIRST_LIMIT`), where they beat the runtime's
//! recursion, which serves every other tree; the second up to 40 000
//! (`LIMIT`), and their graph is not even built where the first took more
//! than a quarter of that (they cost at least four times as much).

use proc_macro2::TokenStream;
use quote::{format_ident, quote};

use crate::engine::diff::TimeRules;
use crate::engine::emit::emit;
use crate::engine::graph::{Graph, Id};
use crate::front::scene::SceneDecl;
use crate::front::tree::TreeKind;
use crate::generate::krate;
use crate::tree::aba::{
    Builder, Joint, NewtonEuler, bindings, kind_offsets, newton_euler, pattern, scalar, used_names,
};

/// Operations above which the first derivatives are not written and the
/// runtime's recursion (`relative/recursion.rs`) runs instead: measured on three
/// robots (same run, medians), the straight line took 0.79 of the
/// recursion's time on the UR5 (4 609 operations), 1.05 on the floating
/// Solo12 (16 961) and 1.59 on the Panda (12 860), whose nine freedoms in
/// one chain make the forward mode's columns long.
pub const FIRST_LIMIT: usize = 8_000;

/// Operations above which the second derivatives are not written (nothing
/// runs: `TreeError::NotDerived`); a crate's build time grows with it.
pub const LIMIT: usize = 40_000;

/// The second derivatives cost at least this many times the first (UR5
/// 4.6, floating Solo12 4.2, Panda 6.8): above [`LIMIT`] over this, their
/// graph is not built at all.
const SECOND_OVER_FIRST: usize = 4;

/// The rules of one tangent direction: freedom `i` of the tree moved by one
/// unit, every other coordinate held (`q`: the graph's coordinates).
fn direction(b: &mut Builder, joints: &[Joint], q: &[Id], i: usize) -> TimeRules {
    let mut rules = TimeRules::new();
    let (qa, va) = kind_offsets(joints.iter().map(|j| j.kind));
    let Some(k) = (0..joints.len()).find(|&k| va[k] <= i && i < va[k] + joints[k].kind.sizes().1) else {
        return rules;
    };
    let (at, f) = (qa[k], i - va[k]);
    let one = b.g.constant(1.0);
    match joints[k].kind {
        TreeKind::Spherical => turn(b, &mut rules, &q[at..at + 4], f),
        TreeKind::Free if f >= 3 => turn(b, &mut rules, &q[at + 3..at + 7], f - 3),
        TreeKind::Free => {
            // The offset moves along the child's axis `f`: `R e_f`, parent components.
            let r = b.quaternion_matrix(&q[at + 3..at + 7]);
            for (c, row) in r.iter().enumerate() {
                rules.set_var(&b.g, q[at + c], row[f]);
            }
        }
        // Angles and slides: the coordinate is the freedom.
        _ => rules.set_var(&b.g, q[at + f], one),
    }
    rules
}

/// `ṗ = ½ p ⊗ (0, e_f)` for the quaternion `p = (w, x, y, z)`: turned about
/// its own (child) axis `f`.
fn turn(b: &mut Builder, rules: &mut TimeRules, p: &[Id], f: usize) {
    let (w, e) = (p[0], [p[1], p[2], p[3]]);
    let half = b.g.constant(0.5);
    // (½ p ⊗ (0, e_f)) = ½ (−e_f, w e_f + e × e_f)
    let neg = b.g.neg(e[f]);
    let scalar = b.g.mul(half, neg);
    rules.set_var(&b.g, p[0], scalar);
    for r in 0..3 {
        // (e × e_f)_r = ε_{r a f} e_a: the one `a` that is neither r nor f.
        let mut x = if r == f { w } else { b.g.zero() };
        if r != f {
            let a = 3 - r - f;
            let sign = if (r + 1) % 3 == a { 1.0 } else { -1.0 };
            let s = b.g.constant(sign);
            let t = b.g.mul(s, e[a]);
            x = b.g.add(x, t);
        }
        let value = b.g.mul(half, x);
        rules.set_var(&b.g, p[r + 1], value);
    }
}

/// `∂τ/∂q` (tangent columns) and `∂τ/∂v`, column by column, on `b`'s graph.
pub(crate) fn columns(b: &mut Builder, joints: &[Joint], rnea: &NewtonEuler) -> (Vec<Vec<Id>>, Vec<Vec<Id>>) {
    let nv = rnea.v.len();
    let mut by_q = Vec::with_capacity(nv);
    for i in 0..nv {
        let mut rules = direction(b, joints, &rnea.q, i);
        by_q.push(rnea.tau.iter().map(|&t| rules.dt(&mut b.g, t)).collect());
    }
    let mut by_v = Vec::with_capacity(nv);
    let one = b.g.constant(1.0);
    for &vi in &rnea.v {
        let mut rules = TimeRules::new();
        rules.set_var(&b.g, vi, one);
        by_v.push(rnea.tau.iter().map(|&t| rules.dt(&mut b.g, t)).collect());
    }
    (by_q, by_v)
}

/// A straight line's `let`s (its inputs bound from the method's arguments)
/// and its outputs; above its limit, its operation count.
struct Written {
    prelude: TokenStream,
    outputs: std::vec::IntoIter<TokenStream>,
    ops: usize,
}

/// `outputs` of `b`'s graph written out; `inputs` are `(prefix, argument,
/// count)`: the graph's inputs `prefix_i` read from `*argument`.
fn write(b: &Builder, outputs: &[Id], inputs: &[(&str, &str, usize)], limit: usize) -> Result<Written, usize> {
    let emitted = emit(&b.g, outputs, &scalar());
    if emitted.ops > limit {
        return Err(emitted.ops);
    }
    let used = used_names(&b.g, &emitted);
    let binds = bindings(b, &used);
    let reads = inputs.iter().map(|&(prefix, argument, count)| {
        let (pattern, argument) = (pattern(&used, prefix, count), format_ident!("{argument}"));
        quote!(let #pattern = *#argument;)
    });
    let body = emitted.body;
    let prelude = quote!(#(#reads)* #(#binds)* #body);
    Ok(Written { prelude, outputs: emitted.outputs.into_iter(), ops: emitted.ops })
}

impl Written {
    /// The next `NV × NV` outputs as a matrix, column by column.
    fn matrix(&mut self, nv: usize) -> TokenStream {
        let p = quote!(::joint_runtime::__private);
        let columns: Vec<TokenStream> = (0..nv)
            .map(|_| {
                let column: Vec<TokenStream> = self.outputs.by_ref().take(nv).collect();
                quote!([#(#column),*])
            })
            .collect();
        quote!(#p::SMatrix::from_data(#p::ArrayStorage([#(#columns),*])))
    }
}

/// `fn inverse_dynamics_derivatives_into`, or nothing above [`FIRST_LIMIT`];
/// with its operation count either way.
pub fn method(s: &SceneDecl, joints: &[Joint], nq: usize, nv: usize) -> (Option<TokenStream>, usize) {
    let mut b = Builder::new(Graph::new());
    let rnea = newton_euler(&mut b, s, joints, nq, nv);
    let (by_q, by_v) = columns(&mut b, joints, &rnea);
    let mut outputs = rnea.tau.clone();
    outputs.extend(by_q.iter().flatten());
    outputs.extend(by_v.iter().flatten());
    let mut w = match write(&b, &outputs, &[("q", "q", nq), ("v", "v", nv), ("a", "vdot", nv)], FIRST_LIMIT) {
        Ok(w) => w,
        Err(ops) => return (None, ops),
    };
    let tau: Vec<TokenStream> = w.outputs.by_ref().take(nv).collect();
    let (dq, dv) = (w.matrix(nv), w.matrix(nv));
    let doc = format!(
        " The inverse dynamics' derivatives written out (forward mode on the Newton–Euler graph): {} operations.",
        w.ops
    );
    let (k, nb, prelude) = (krate(), s.bodies.len(), w.prelude);
    let p = quote!(#k::__private);
    let method = quote! {
        const DERIVATIVES: bool = true;
        #[doc = #doc]
        #[inline]
        fn inverse_dynamics_derivatives_into(
            &self,
            geometry: &#k::relative::TreeGeometry<#nb>,
            q: &[f64; #nq],
            v: &[f64; #nv],
            vdot: &[f64; #nv],
            out: &mut #k::relative::InverseDerivatives<#nv>,
        ) -> bool {
            #prelude
            out.tau = #p::SVector::from_data(#p::ArrayStorage([[#(#tau),*]]));
            out.d_q = #dq;
            out.d_v = #dv;
            true
        }
    };
    (Some(method), w.ops)
}

/// `fn inverse_dynamics_second_derivatives_into`: with `s = λᵀ τ`, the
/// second derivatives `∂²s/∂q_j ∂q_i` (the derivative along `q_j` of the
/// tangent column `i`: iterated directions, not symmetric on the rotation
/// group), `∂²s/∂q_i ∂v_j` and `∂²s/∂v_j ∂v_i`, what a DDP backward pass
/// contracts; each rule set's memo shared by every column it takes.
/// Nothing above [`LIMIT`], nor where the first derivatives took `first`
/// operations, more than [`LIMIT`] over [`SECOND_OVER_FIRST`].
pub fn second_method(s: &SceneDecl, joints: &[Joint], (nq, nv): (usize, usize), first: usize) -> Option<TokenStream> {
    if first * SECOND_OVER_FIRST > LIMIT {
        return None;
    }
    let mut b = Builder::new(Graph::new());
    let rnea = newton_euler(&mut b, s, joints, nq, nv);
    let lambda: Vec<Id> = (0..nv).map(|i| b.g.param(format!("lambda_{i}"))).collect();
    let terms: Vec<Id> = lambda.iter().zip(&rnea.tau).map(|(&l, &t)| b.g.mul(l, t)).collect();
    let contracted = b.g.sum(&terms);
    let mut by_q: Vec<TimeRules> = (0..nv).map(|i| direction(&mut b, joints, &rnea.q, i)).collect();
    let one = b.g.constant(1.0);
    let mut by_v: Vec<TimeRules> = rnea
        .v
        .iter()
        .map(|&vi| {
            let mut rules = TimeRules::new();
            rules.set_var(&b.g, vi, one);
            rules
        })
        .collect();
    let first_q: Vec<Id> = by_q.iter_mut().map(|r| r.dt(&mut b.g, contracted)).collect();
    let first_v: Vec<Id> = by_v.iter_mut().map(|r| r.dt(&mut b.g, contracted)).collect();
    let mut outputs = Vec::with_capacity(3 * nv * nv);
    // Column j of each: the derivative along direction j.
    for (on_q, firsts) in [(true, &first_q), (false, &first_q), (false, &first_v)] {
        let rules = if on_q { &mut by_q } else { &mut by_v };
        for r in rules.iter_mut() {
            for &f in firsts {
                outputs.push(r.dt(&mut b.g, f));
            }
        }
    }
    let inputs = [("q", "q", nq), ("v", "v", nv), ("a", "vdot", nv), ("lambda", "lambda", nv)];
    let mut w = write(&b, &outputs, &inputs, LIMIT).ok()?;
    let (qq, qv, vv) = (w.matrix(nv), w.matrix(nv), w.matrix(nv));
    let doc = format!(
        " The contracted second derivatives of the inverse dynamics written out (forward mode twice): {} operations.",
        w.ops
    );
    let (k, nb, prelude) = (krate(), s.bodies.len(), w.prelude);
    Some(quote! {
        #[doc = #doc]
        #[inline]
        fn inverse_dynamics_second_derivatives_into(
            &self,
            geometry: &#k::relative::TreeGeometry<#nb>,
            q: &[f64; #nq],
            v: &[f64; #nv],
            vdot: &[f64; #nv],
            lambda: &[f64; #nv],
            out: &mut #k::relative::SecondDerivatives<#nv>,
        ) -> bool {
            #prelude
            out.d_qq = #qq;
            out.d_qv = #qv;
            out.d_vv = #vv;
            true
        }
    })
}
