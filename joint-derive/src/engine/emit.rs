//! From nodes to Rust: straight-line code in arena order.
//!
//! A node used once is written inline in its user; a node used more than once
//! gets a `let`, named by its hint or `t<n>` in order of appearance. Parentheses
//! are written exactly where Rust's precedence would otherwise change the
//! evaluation order, so the printed code evaluates the graph's operations in the
//! graph's order, bit for bit.

use std::collections::{BTreeSet, HashMap};

use proc_macro2::{Ident, Span, TokenStream};
use quote::{format_ident, quote};

use super::graph::{Graph, Id, Node, VarId};

/// How the scalar type is spelled in generated code.
#[derive(Clone)]
pub struct ScalarTy {
    /// The type (`T` or `f64`).
    pub ty: TokenStream,
    /// The runtime crate path (`::joint_runtime`).
    pub krate: TokenStream,
    /// The impl is for `f64` itself: constants are plain literals.
    pub concrete_f64: bool,
}

/// What [`emit`] produced for one function.
pub struct Emitted {
    /// The `let` statements.
    pub body: TokenStream,
    /// One expression per requested output.
    pub outputs: Vec<TokenStream>,
    /// Variables the statements read (bind exactly these).
    pub used_vars: BTreeSet<VarId>,
    /// Binary `+ - *` operations.
    pub ops: usize,
}

/// The nodes the outputs need, in arena order.
pub fn reachable(g: &Graph, outputs: &[Id]) -> Vec<Id> {
    let mut live = vec![false; g.len()];
    for &o in outputs {
        live[o.index()] = true;
    }
    for i in (0..g.len()).rev() {
        if !live[i] {
            continue;
        }
        match g.node(Id(i as u32)) {
            Node::Add(a, b) | Node::Sub(a, b) | Node::Mul(a, b) => {
                live[a.index()] = true;
                live[b.index()] = true;
            }
            Node::Neg(a) | Node::Sin(a) | Node::Cos(a) => live[a.index()] = true,
            Node::Const(_) | Node::Var(_) => {}
        }
    }
    (0..g.len()).filter(|&i| live[i]).map(|i| Id(i as u32)).collect()
}

const ATOM: u8 = 4;

/// Emits the computation of `outputs`.
pub fn emit(g: &Graph, outputs: &[Id], scalar: &ScalarTy) -> Emitted {
    let nodes = reachable(g, outputs);
    let mut uses: HashMap<Id, usize> = HashMap::new();
    for &id in &nodes {
        match g.node(id) {
            Node::Add(a, b) | Node::Sub(a, b) | Node::Mul(a, b) => {
                *uses.entry(a).or_default() += 1;
                *uses.entry(b).or_default() += 1;
            }
            Node::Neg(a) | Node::Sin(a) | Node::Cos(a) => *uses.entry(a).or_default() += 1,
            Node::Const(_) | Node::Var(_) => {}
        }
    }
    for &o in outputs {
        *uses.entry(o).or_default() += 1;
    }

    let ty = &scalar.ty;
    let krate = &scalar.krate;
    // Expression and precedence of every node emitted so far.
    let mut exprs: HashMap<Id, (TokenStream, u8)> = HashMap::new();
    let mut body = TokenStream::new();
    let mut used_vars = BTreeSet::new();
    let mut taken: HashMap<String, usize> = HashMap::new();
    let mut counter = 0usize;
    let mut ops = 0usize;
    let mut consts: std::collections::BTreeMap<u64, Ident> = std::collections::BTreeMap::new();

    for &id in &nodes {
        let node = g.node(id);
        let paren = |e: &(TokenStream, u8), min: u8| -> TokenStream {
            let (t, p) = e;
            if *p >= min { t.clone() } else { quote!((#t)) }
        };
        let (expr, prec) = match node {
            Node::Const(bits) => {
                // Bound once per magnitude in the prologue; the sign is free.
                let v = f64::from_bits(bits);
                let name = consts.entry(v.abs().to_bits()).or_insert_with(|| const_name(v.abs())).clone();
                if v < 0.0 { (quote!(-#name), 3) } else { (quote!(#name), ATOM) }
            }
            Node::Var(v) => {
                used_vars.insert(v);
                let name = Ident::new(&g.vars()[v.0 as usize].name, Span::call_site());
                (quote!(#name), ATOM)
            }
            Node::Add(a, b) => {
                ops += 1;
                let (l, r) = (paren(&exprs[&a], 1), paren(&exprs[&b], 2));
                (quote!(#l + #r), 1)
            }
            Node::Sub(a, b) => {
                ops += 1;
                let (l, r) = (paren(&exprs[&a], 1), paren(&exprs[&b], 2));
                (quote!(#l - #r), 1)
            }
            Node::Mul(a, b) => {
                ops += 1;
                let (l, r) = (paren(&exprs[&a], 2), paren(&exprs[&b], 3));
                (quote!(#l * #r), 2)
            }
            Node::Neg(a) => {
                let x = paren(&exprs[&a], 3);
                (quote!(-#x), 3)
            }
            Node::Sin(a) => {
                let x = paren(&exprs[&a], 1);
                (quote!(<#ty as #krate::__private::SimdComplexField>::simd_sin(#x)), ATOM)
            }
            Node::Cos(a) => {
                let x = paren(&exprs[&a], 1);
                (quote!(<#ty as #krate::__private::SimdComplexField>::simd_cos(#x)), ATOM)
            }
        };
        let shared = uses.get(&id).copied().unwrap_or(0) > 1;
        let bind = shared && prec < ATOM;
        if bind {
            let base = match g.hint_of(id) {
                Some(h) => h.to_string(),
                None => {
                    counter += 1;
                    format!("t{counter}")
                }
            };
            let n = taken.entry(base.clone()).or_insert(0);
            *n += 1;
            let name = if *n == 1 { format_ident!("{}", base) } else { format_ident!("{}_{}", base, *n) };
            body.extend(quote!(let #name = #expr;));
            exprs.insert(id, (quote!(#name), ATOM));
        } else {
            exprs.insert(id, (expr, prec));
        }
    }
    let mut prologue = TokenStream::new();
    for (bits, name) in &consts {
        let lit = proc_macro2::Literal::f64_suffixed(f64::from_bits(*bits));
        let value =
            if scalar.concrete_f64 { quote!(#lit) } else { quote!(#krate::__private::convert::<f64, #ty>(#lit)) };
        prologue.extend(quote!(let #name: #ty = #value;));
    }
    prologue.extend(body);
    let body = prologue;
    let outputs = outputs.iter().map(|o| exprs[o].0.clone()).collect();
    Emitted { body, outputs, used_vars, ops }
}

fn const_name(v: f64) -> Ident {
    match v {
        0.0 => format_ident!("zero"),
        0.5 => format_ident!("half"),
        1.0 => format_ident!("one"),
        2.0 => format_ident!("two"),
        4.0 => format_ident!("four"),
        _ => {
            let s = format!("{v:e}").replace(['.', '-', '+'], "_");
            format_ident!("k_{}", s)
        }
    }
}
