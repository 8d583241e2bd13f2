//! Code generation shared by both derives: one table of the generated methods
//! ([`METHODS`]) drives the `Joint` impl, the `Scene` impl and both fallback
//! stubs, and [`lints`] is the one place for hygiene attributes. Adding a
//! generated function is one row of the table (and the trait method it implements).
//!
//! Generated code names every item by its absolute path from `::joint_runtime`
//! (`krate`) or `::core`: the traits and types by their public paths, helpers
//! that are not API only through the runtime's hidden `__private`, nalgebra
//! through its re-export, so that a user needs one dependency and no import.
//! The lints deny panics, `unwrap` and indexing in what is generated. A scene's
//! second-order terms past about 8 000 operations are split, joint by joint,
//! into `#[inline(never)]` helpers that each rebuild only their own bodies'
//! rotation matrices (`PART_OPS`): a 160-body tree's terms took rustc 104 s
//! and 3 GB in one function, 34 s and 0.8 GB in parts.

use std::collections::BTreeSet;

use proc_macro2::{Ident, Literal, TokenStream};
use quote::{format_ident, quote};

use crate::engine::Id;
use crate::engine::emit::{self, ScalarTy};
use crate::engine::graph::VarId;
use crate::front::resolve::FieldShape;
use crate::lower::{Derived, Read};
use crate::second_order::{SecondOrderNodes, SparseNodes};

/// What a generated method returns.
#[derive(Clone, Copy)]
enum Returns {
    /// `SVector<S, ROWS>`.
    Rows,
    /// `SMatrix<S, ROWS, COLS>`, column-major.
    Matrix,
    /// `Evaluation { phi, jacobian, gamma }`.
    Evaluation,
}

/// A generated method: its name (also its field in `Ops`), its outputs and
/// what it returns.
pub struct Method {
    name: &'static str,
    outputs: fn(&Derived) -> Vec<Id>,
    returns: Returns,
}

/// J's entries in column-major order.
fn jacobian_columns(d: &Derived) -> Vec<Id> {
    let cols = d.kinematics.velocities.len();
    (0..cols).flat_map(|c| d.jacobian.iter().map(move |row| row[c])).collect()
}

/// Every method of `Joint` and `Scene` the derives generate, in trait order.
pub const METHODS: [Method; 5] = [
    Method { name: "phi", outputs: |d| d.phi.clone(), returns: Returns::Rows },
    Method { name: "phi_t", outputs: |d| d.phi_t.clone(), returns: Returns::Rows },
    Method { name: "jacobian", outputs: jacobian_columns, returns: Returns::Matrix },
    Method { name: "gamma", outputs: |d| d.gamma.clone(), returns: Returns::Rows },
    Method {
        name: "evaluate",
        outputs: |d| [d.phi.clone(), jacobian_columns(d), d.gamma.clone()].concat(),
        returns: Returns::Evaluation,
    },
];

/// The attributes every generated impl carries: derived code, silent under
/// the user's lints, and proven panic-free by clippy's where it matters.
pub fn lints() -> TokenStream {
    quote! {
        #[automatically_derived]
        #[allow(clippy::all, clippy::pedantic, dead_code, unused_variables, non_snake_case)]
        #[deny(clippy::panic, clippy::unwrap_used, clippy::indexing_slicing)]
    }
}

/// The runtime crate, as generated code names it.
pub fn krate() -> TokenStream {
    quote!(::joint_runtime)
}

/// What the generated methods take and return.
pub struct Signature {
    /// The state type (`Self::State`, `SystemState<3>`).
    pub state: TokenStream,
    /// The scalar type.
    pub scalar: TokenStream,
    /// Rows of Φ.
    pub rows: usize,
    /// Velocity columns of J.
    pub cols: usize,
    /// Statements every method starts with.
    pub prelude: TokenStream,
}

impl Signature {
    fn returns(&self, returns: Returns) -> TokenStream {
        let (k, s) = (krate(), &self.scalar);
        let (r, c) = (Literal::usize_unsuffixed(self.rows), Literal::usize_unsuffixed(self.cols));
        match returns {
            Returns::Rows => quote!(#k::__private::SVector<#s, #r>),
            Returns::Matrix => quote!(#k::__private::SMatrix<#s, #r, #c>),
            Returns::Evaluation => quote!(#k::Evaluation<#s, #r, #c>),
        }
    }

    /// The methods of [`METHODS`]: printed, or, for a stub, bodies that are
    /// never run (the crate does not compile).
    pub fn methods(&self, printed: Option<&Printed>) -> TokenStream {
        let (state, prelude) = (&self.state, &self.prelude);
        let methods = METHODS.iter().enumerate().map(|(i, m)| {
            let (name, returns) = (format_ident!("{}", m.name), self.returns(m.returns));
            match printed {
                Some(p) => {
                    let (body, value) = &p.bodies[i];
                    quote! {
                        #[inline]
                        fn #name(&self, state: &#state) -> #returns { #prelude #body #value }
                    }
                }
                None => quote!(fn #name(&self, state: &#state) -> #returns { loop {} }),
            }
        });
        quote!(#(#methods)*)
    }
}

/// The `second_order` method of `Joint` and `Scene` (their default returns
/// `None`) and its operation count.
pub fn second_order_method(sig: &Signature, printed: &Printed, nodes: &SecondOrderNodes) -> (TokenStream, usize) {
    let (body, outs, ops) = printed.emit(&nodes.all());
    let (k, s, state, prelude) = (krate(), &sig.scalar, &sig.state, &sig.prelude);
    let (rows, cols) = (sig.rows, sig.cols);
    let (r, c) = (Literal::usize_unsuffixed(rows), Literal::usize_unsuffixed(cols));
    let (stiffness, rest) = outs.split_at(cols * cols);
    let (jacobian_q, rest) = rest.split_at(rows * cols);
    let (gamma_q, rest) = rest.split_at(rows * cols);
    let (gamma_v, phi_t_q) = rest.split_at(rows * cols);
    let (stiffness, jacobian_q) = (matrix_tokens(stiffness, cols), matrix_tokens(jacobian_q, rows));
    let (gamma_q, gamma_v) = (matrix_tokens(gamma_q, rows), matrix_tokens(gamma_v, rows));
    let phi_t_q = matrix_tokens(phi_t_q, rows);
    let method = quote! {
        #[inline]
        fn second_order(
            &self,
            state: &#state,
            lambda: &#k::__private::SVector<#s, #r>,
            u: &#k::__private::SVector<#s, #c>,
        ) -> ::core::option::Option<#k::SecondOrder<#s, #r, #c>> {
            #prelude
            #body
            ::core::option::Option::Some(#k::SecondOrder { stiffness: #stiffness, jacobian_q: #jacobian_q, gamma_q: #gamma_q, gamma_v: #gamma_v, phi_t_q: #phi_t_q })
        }
    };
    (method, ops)
}

/// A scene's `second_order_values` (the `Scene` default returns `false`): the
/// sparse blocks of [`second_order::derive`](crate::second_order::derive),
/// written entry by entry into the caller's slice (a large scene's blocks would
/// not fit in a returned array on the stack); `false` when the slice is not
/// exactly their length. Returns the method, the inherent helpers it calls
/// (its parts, when there are several; see [`PART_OPS`]) and its operation count.
pub fn second_order_values_method(
    sig: &Signature,
    printed: &Printed,
    sparse: &SparseNodes,
) -> (TokenStream, TokenStream, usize) {
    let (k, state, prelude) = (krate(), &sig.state, &sig.prelude);
    let (r, c, len) = (
        Literal::usize_unsuffixed(sig.rows),
        Literal::usize_unsuffixed(sig.cols),
        Literal::usize_unsuffixed(sparse.nodes.len()),
    );
    let args = quote! {
        state: &#state,
        lambda: &#k::__private::SVector<f64, #r>,
        u: &#k::__private::SVector<f64, #c>,
    };
    let parts = parts(&printed.d.kinematics.g, sparse);
    let mut total = 0;
    let mut bodies = parts.iter().map(|part| {
        let (body, outs, ops) = printed.emit(&part.iter().map(|&i| sparse.nodes[i]).collect::<Vec<_>>());
        total += ops;
        let writes = part.iter().zip(outs).map(|(&i, e)| {
            let i = Literal::usize_unsuffixed(i);
            quote!(out[#i] = #e;)
        });
        quote!(#prelude #body #(#writes)*)
    });
    let (calls, helpers) = if parts.len() == 1 {
        (bodies.next().unwrap_or_default(), TokenStream::new())
    } else {
        let (mut calls, mut helpers) = (TokenStream::new(), TokenStream::new());
        for (i, body) in bodies.enumerate() {
            let name = format_ident!("__second_order_values_{}", i);
            calls.extend(quote!(self.#name(state, lambda, u, out);));
            helpers.extend(quote! {
                #[doc(hidden)]
                #[inline(never)]
                fn #name(&self, #args out: &mut [f64; #len]) { #body }
            });
        }
        (calls, helpers)
    };
    let method = quote! {
        #[inline]
        fn second_order_values(&self, #args out: &mut [f64]) -> bool {
            let out: &mut [f64; #len] = match ::core::convert::TryFrom::try_from(out) {
                ::core::result::Result::Ok(out) => out,
                ::core::result::Result::Err(_) => return false,
            };
            #calls
            true
        }
    };
    (method, helpers, total)
}

/// About the most operations one generated function of a scene's second-order
/// terms holds: past it they are split, joint by joint, into functions of
/// about this size. rustc's MIR passes and LLVM grow faster than linearly in
/// one straight-line function whose values live across all of it (a 160-body
/// tree's terms in one function: 104 s and 3 GB of rustc); apart, each part
/// rebuilds only its own bodies' rotation matrices.
const PART_OPS: usize = 8_000;

/// The entries of `sparse` in parts of about [`PART_OPS`] operations, whole
/// joints each, in joint order.
fn parts(g: &crate::engine::graph::Graph, sparse: &SparseNodes) -> Vec<Vec<usize>> {
    let mut parts = Vec::new();
    let (mut part, mut count, mut ops) = (Vec::new(), emit::OpCount::new(g), 0);
    for joint in &sparse.joints {
        let nodes: Vec<Id> = joint.iter().map(|&i| sparse.nodes[i]).collect();
        if !part.is_empty() && ops + count.extra(&nodes) > PART_OPS {
            parts.push(std::mem::take(&mut part));
            count = emit::OpCount::new(g);
        }
        ops = count.add(&nodes);
        part.extend(joint);
    }
    if !part.is_empty() || parts.is_empty() {
        parts.push(part);
    }
    parts
}

/// `const OPS: Ops = Ops { phi: .., .. }`, zero for a stub.
pub fn ops_const(printed: Option<&Printed>) -> TokenStream {
    let k = krate();
    let fields = METHODS.iter().enumerate().map(|(i, m)| {
        let (name, n) = (format_ident!("{}", m.name), Literal::usize_unsuffixed(printed.map_or(0, |p| p.ops[i])));
        quote!(#name: #n)
    });
    quote!(const OPS: #k::Ops = #k::Ops { #(#fields),* };)
}

/// The printed methods of a derivation, in [`METHODS`] order.
pub struct Printed<'a> {
    d: &'a Derived,
    sty: ScalarTy,
    /// Each method's statements and returned value.
    pub bodies: Vec<(TokenStream, TokenStream)>,
    /// Each method's operation count.
    pub ops: Vec<usize>,
}

impl Printed<'_> {
    /// Statements, output expressions and operation count for `outputs`.
    pub fn emit(&self, outputs: &[Id]) -> (TokenStream, Vec<TokenStream>, usize) {
        let e = emit::emit(&self.d.kinematics.g, outputs, &self.sty);
        let bind = bindings(self.d, &e.used_vars, &self.sty);
        let body = e.body;
        (quote!(#bind #body), e.outputs, e.ops)
    }

    /// "phi 12, phi_t 0, ..." for docs.
    pub fn ops_text(&self) -> String {
        METHODS.iter().zip(&self.ops).map(|(m, n)| format!("{} {n}", m.name)).collect::<Vec<_>>().join(", ")
    }
}

/// For a large scene, the dense methods written over the sparse ones: a
/// straight-line dense Jacobian would grow with `M × NV` (460 000 literal
/// entries for a 160-body chain) and rustc's time and memory with it.
pub struct FromSparse {
    /// The body of `jacobian`: a scatter of the nonzero entries.
    pub jacobian: TokenStream,
    /// The body of `evaluate`: `phi`, `jacobian` and `gamma`.
    pub evaluate: TokenStream,
    /// Their operation counts.
    pub ops: [usize; 2],
}

/// Prints every method of [`METHODS`] for a derivation (the dense ones over
/// the sparse ones when `large` is given).
pub fn print<'a>(d: &'a Derived, sty: &ScalarTy, large: Option<&FromSparse>) -> Printed<'a> {
    let mut p = Printed { d, sty: sty.clone(), bodies: Vec::new(), ops: Vec::new() };
    let rows = d.phi.len();
    for m in &METHODS {
        if let Some(f) = large {
            let written = match m.returns {
                Returns::Matrix => Some((&f.jacobian, f.ops[0])),
                Returns::Evaluation => Some((&f.evaluate, f.ops[1])),
                Returns::Rows => None,
            };
            if let Some((value, ops)) = written {
                p.bodies.push((TokenStream::new(), value.clone()));
                p.ops.push(ops);
                continue;
            }
        }
        let (body, outs, ops) = p.emit(&(m.outputs)(d));
        let value = match m.returns {
            Returns::Rows => vector_tokens(&outs),
            Returns::Matrix => matrix_tokens(&outs, rows),
            Returns::Evaluation => {
                let (phi, rest) = outs.split_at(rows);
                let (jac, gamma) = rest.split_at(rows * d.kinematics.velocities.len());
                let (phi, jac, gamma) = (vector_tokens(phi), matrix_tokens(jac, rows), vector_tokens(gamma));
                let k = krate();
                quote!(#k::Evaluation { phi: #phi, jacobian: #jac, gamma: #gamma })
            }
        };
        p.bodies.push((body, value));
        p.ops.push(ops);
    }
    p
}

/// A printer that has printed no method yet (for functions beside them).
pub fn print_none<'a>(d: &'a Derived, sty: &ScalarTy) -> Printed<'a> {
    Printed { d, sty: sty.clone(), bodies: Vec::new(), ops: Vec::new() }
}

/// `SVector` from its entries.
pub(crate) fn vector_tokens(outs: &[TokenStream]) -> TokenStream {
    let k = krate();
    quote!(#k::__private::SMatrix::from_data(#k::__private::ArrayStorage([[#(#outs),*]])))
}

/// `SMatrix` from its entries in column-major order.
pub(crate) fn matrix_tokens(outs: &[TokenStream], rows: usize) -> TokenStream {
    let k = krate();
    let columns = outs.chunks(rows.max(1)).map(|c| quote!([#(#c),*]));
    quote!(#k::__private::SMatrix::from_data(#k::__private::ArrayStorage([#(#columns),*])))
}

/// The name of a variable node the function reads, if it reads it.
fn used_name(d: &Derived, used: &BTreeSet<VarId>, node: Id) -> Option<Ident> {
    let g = &d.kinematics.g;
    g.as_var(node).filter(|v| used.contains(v)).map(|v| format_ident!("{}", g.vars()[v.0 as usize].name))
}

/// `[[a, _, c]]`: a pattern for the nodes a function reads, if any.
fn pattern(d: &Derived, used: &BTreeSet<VarId>, nodes: &[Id]) -> Option<TokenStream> {
    let names: Vec<Option<Ident>> = nodes.iter().map(|&n| used_name(d, used, n)).collect();
    if names.iter().all(Option::is_none) {
        return None;
    }
    let names = names.iter().map(|n| n.as_ref().map_or_else(|| quote!(_), |n| quote!(#n)));
    Some(quote!([[#(#names),*]]))
}

/// `let` statements that read exactly the inputs a function uses.
fn bindings(d: &Derived, used: &BTreeSet<VarId>, sty: &ScalarTy) -> TokenStream {
    let mut out = TokenStream::new();
    for b in &d.bindings {
        out.extend(match &b.read {
            Read::Constant(expr) => constant_binding(d, used, b.nodes[0], expr, sty),
            Read::Field { member, shape: FieldShape::Time, .. } => time_binding(d, used, &b.nodes, member, sty),
            Read::Field { member, .. } if b.nodes.len() == 1 => match used_name(d, used, b.nodes[0]) {
                Some(id) => quote!(let #id = self.#member;),
                None => TokenStream::new(),
            },
            Read::Field { member, part, .. } => match pattern(d, used, &b.nodes) {
                Some(p) if part.is_empty() => quote!(let #p = self.#member.data.0;),
                Some(p) => {
                    let part = format_ident!("{}", part);
                    quote!(let #p = self.#member.#part.data.0;)
                }
                None => TokenStream::new(),
            },
        });
    }
    let mut reads = Vec::new();
    for input in &d.kinematics.inputs {
        if let Some(p) = pattern(d, used, &input.vars) {
            let path = input.path.iter().map(|s| match s.parse::<usize>() {
                Ok(i) => {
                    let i = Literal::usize_unsuffixed(i);
                    quote!([#i])
                }
                Err(_) => {
                    let f = format_ident!("{}", s);
                    quote!(.#f)
                }
            });
            let root = format_ident!("{}", input.root);
            reads.push((p, quote!(#root #(#path)*.data.0)));
        }
    }
    // Past a few dozen inputs (a scene of many bodies) one `let` reads them
    // all: each `let` opens a scope, and rustc's debug info recurses per scope.
    if reads.len() > INPUT_LETS {
        let (patterns, values): (Vec<_>, Vec<_>) = reads.into_iter().unzip();
        out.extend(quote!(let (#(#patterns),*) = (#(#values),*);));
    } else {
        out.extend(reads.into_iter().map(|(p, v)| quote!(let #p = #v;)));
    }
    out
}

/// Beyond this many input reads in one function, they are one `let`.
const INPUT_LETS: usize = 64;

/// A named constant's value, converted to the scalar (an `f64` expression the
/// compiler folds).
fn constant_binding(d: &Derived, used: &BTreeSet<VarId>, node: Id, expr: &syn::Expr, sty: &ScalarTy) -> TokenStream {
    let Some(name) = used_name(d, used, node) else { return TokenStream::new() };
    let (ty, k, value) = (&sty.ty, &sty.krate, named_f64(expr));
    if sty.concrete_f64 {
        quote!(let #name: f64 = #value;)
    } else {
        quote!(let #name: #ty = #k::__private::convert::<f64, #ty>(#value);)
    }
}

/// A number that names constants, as an `f64` block: every use reads it the
/// same way, so a constant of the wrong type gives one compiler error, at the
/// user's token.
pub fn named_f64(expr: &syn::Expr) -> TokenStream {
    quote!({ let value: f64 = #expr; value })
}

/// One call of the time function per evaluation, at the state's time.
fn time_binding(d: &Derived, used: &BTreeSet<VarId>, nodes: &[Id], member: &Ident, sty: &ScalarTy) -> TokenStream {
    let names: Vec<Option<Ident>> = nodes.iter().map(|&n| used_name(d, used, n)).collect();
    if names.iter().all(Option::is_none) {
        return TokenStream::new();
    }
    let drive = format_ident!("{}_drive", member);
    let (ty, k) = (&sty.ty, &sty.krate);
    let mut out = quote!(let #drive = #k::TimeFunction::eval(&self.#member, state.t););
    for (name, field) in names.iter().zip(["value", "rate", "accel"]) {
        if let Some(name) = name {
            let field = format_ident!("{}", field);
            out.extend(quote!(let #name: #ty = #k::__private::convert::<f64, #ty>(#drive.#field);));
        }
    }
    out
}
