//! From nodes to Rust: straight-line code in arena order.
//!
//! A node used once is written inline in its user; a node used more than once
//! gets a `let`, named by its hint or `t<n>` in order of appearance. Parentheses
//! are written exactly where Rust's precedence would otherwise change the
//! evaluation order, so the printed code evaluates the graph's operations in the
//! graph's order, bit for bit (up to the sign of a zero, see [`Ex`]).

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
            Node::Add(a, b) | Node::Sub(a, b) | Node::Mul(a, b) | Node::Div(a, b) => {
                live[a.index()] = true;
                live[b.index()] = true;
            }
            Node::Neg(a) | Node::Sin(a) | Node::Cos(a) => live[a.index()] = true,
            Node::Const(_) | Node::Var(_) => {}
        }
    }
    (0..g.len()).filter(|&i| live[i]).map(|i| Id(i as u32)).collect()
}

/// Binary operations needed by `outputs` (shared nodes counted once).
pub fn count_ops(g: &Graph, outputs: &[Id]) -> usize {
    reachable(g, outputs)
        .into_iter()
        .filter(|&id| matches!(g.node(id), Node::Add(..) | Node::Sub(..) | Node::Mul(..) | Node::Div(..)))
        .count()
}

const ATOM: u8 = 4;

/// A node as printed: the expression and its precedence (1 `+ −`, 2 `×`, 3 unary
/// minus, 4 atom), and the same for its negation. Negations are pushed into the
/// printed expression (`−(a − b)` as `b − a`), which IEEE arithmetic makes exact
/// up to the sign of a zero result.
struct Ex {
    pos: (TokenStream, u8),
    neg: (TokenStream, u8),
}

impl Ex {
    fn atom(t: TokenStream) -> Self {
        Ex { neg: (quote!(-#t), 3), pos: (t, ATOM) }
    }
}

fn paren(e: &(TokenStream, u8), min: u8) -> TokenStream {
    let (t, p) = e;
    if *p >= min { t.clone() } else { quote!((#t)) }
}

/// Emits the computation of `outputs`.
pub fn emit(g: &Graph, outputs: &[Id], scalar: &ScalarTy) -> Emitted {
    let nodes = reachable(g, outputs);
    let mut uses: HashMap<Id, usize> = HashMap::new();
    for &id in &nodes {
        match g.node(id) {
            Node::Add(a, b) | Node::Sub(a, b) | Node::Mul(a, b) | Node::Div(a, b) => {
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
    // A negation is free and never bound: its uses are its operand's uses.
    for &id in nodes.iter().rev() {
        if let Node::Neg(a) = g.node(id) {
            let extra = uses.get(&id).copied().unwrap_or(0).saturating_sub(1);
            *uses.entry(a).or_default() += extra;
        }
    }

    let ty = &scalar.ty;
    let krate = &scalar.krate;
    // Every node emitted so far, as itself and as its negation.
    let mut exprs: HashMap<Id, Ex> = HashMap::new();
    let mut body = TokenStream::new();
    let mut used_vars = BTreeSet::new();
    // Input names are taken: a `let` never shadows an input (a user's scalar
    // parameter may well be called `two` or `t1`).
    let mut taken: HashMap<String, usize> =
        nodes.iter().filter_map(|&id| g.as_var(id)).map(|v| (g.vars()[v.0 as usize].name.clone(), 1)).collect();
    let mut counter = 0usize;
    let mut ops = 0usize;
    let mut consts: std::collections::BTreeMap<u64, Ident> = std::collections::BTreeMap::new();

    for &id in &nodes {
        let node = g.node(id);
        // Operands of + and × are printed with the running sum (or product) on the
        // left, where Rust needs no parentheses; both orders give the same bits.
        let ordered = |a: Id, b: Id, prec: u8| {
            let (pa, pb) = (exprs[&a].pos.1, exprs[&b].pos.1);
            if pb == prec && pa != prec { (b, a) } else { (a, b) }
        };
        let ex = match node {
            Node::Const(bits) => {
                // Bound once per magnitude in the prologue; the sign is free.
                let v = f64::from_bits(bits);
                let name = consts
                    .entry(v.abs().to_bits())
                    .or_insert_with(|| {
                        let base = const_name(v.abs()).to_string();
                        let n = taken.entry(base.clone()).or_insert(0);
                        *n += 1;
                        if *n == 1 { format_ident!("{}", base) } else { format_ident!("{}_{}", base, *n) }
                    })
                    .clone();
                let (plain, negated) = ((quote!(#name), ATOM), (quote!(-#name), 3));
                if v < 0.0 { Ex { pos: negated, neg: plain } } else { Ex { pos: plain, neg: negated } }
            }
            Node::Var(v) => {
                used_vars.insert(v);
                let name = Ident::new(&g.vars()[v.0 as usize].name, Span::call_site());
                Ex::atom(quote!(#name))
            }
            Node::Add(a, b) => {
                ops += 1;
                let (a, b) = ordered(a, b, 1);
                let (ea, eb) = (&exprs[&a], &exprs[&b]);
                let (l, r, ln) = (paren(&ea.pos, 1), paren(&eb.pos, 2), paren(&ea.neg, 1));
                // −(a + b) = (−a) − b
                Ex { pos: (quote!(#l + #r), 1), neg: (quote!(#ln - #r), 1) }
            }
            Node::Sub(a, b) => {
                ops += 1;
                let (ea, eb) = (&exprs[&a], &exprs[&b]);
                let (l, r) = (paren(&ea.pos, 1), paren(&eb.pos, 2));
                let (bl, ar) = (paren(&eb.pos, 1), paren(&ea.pos, 2));
                // −(a − b) = b − a
                Ex { pos: (quote!(#l - #r), 1), neg: (quote!(#bl - #ar), 1) }
            }
            Node::Mul(a, b) => {
                ops += 1;
                let (a, b) = ordered(a, b, 2);
                let (ea, eb) = (&exprs[&a], &exprs[&b]);
                let (l, r, ln) = (paren(&ea.pos, 2), paren(&eb.pos, 3), paren(&ea.neg, 2));
                // −(a · b) = (−a) · b
                Ex { pos: (quote!(#l * #r), 2), neg: (quote!(#ln * #r), 2) }
            }
            Node::Div(a, b) => {
                ops += 1;
                let (ea, eb) = (&exprs[&a], &exprs[&b]);
                let (l, r, ln) = (paren(&ea.pos, 2), paren(&eb.pos, 3), paren(&ea.neg, 2));
                Ex { pos: (quote!(#l / #r), 2), neg: (quote!(#ln / #r), 2) }
            }
            Node::Neg(a) => {
                let ea = &exprs[&a];
                Ex { pos: ea.neg.clone(), neg: ea.pos.clone() }
            }
            Node::Sin(a) | Node::Cos(a) => {
                let x = paren(&exprs[&a].pos, 1);
                let f = if matches!(node, Node::Sin(_)) { quote!(simd_sin) } else { quote!(simd_cos) };
                Ex::atom(quote!(<#ty as #krate::__private::SimdComplexField>::#f(#x)))
            }
        };
        let shared = uses.get(&id).copied().unwrap_or(0) > 1;
        let bind = shared
            && matches!(
                node,
                Node::Add(..) | Node::Sub(..) | Node::Mul(..) | Node::Div(..) | Node::Sin(_) | Node::Cos(_)
            );
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
            let expr = ex.pos.0;
            body.extend(quote!(let #name = #expr;));
            exprs.insert(id, Ex::atom(quote!(#name)));
        } else {
            exprs.insert(id, ex);
        }
    }
    let mut prologue = TokenStream::new();
    for (bits, name) in &consts {
        let v = f64::from_bits(*bits);
        // A literal must be finite; a constant folded to ∞ or NaN is spelled out.
        let lit = if v.is_finite() {
            let l = proc_macro2::Literal::f64_suffixed(v);
            quote!(#l)
        } else if v.is_nan() {
            quote!(::core::f64::NAN)
        } else {
            quote!(::core::f64::INFINITY)
        };
        let value =
            if scalar.concrete_f64 { quote!(#lit) } else { quote!(#krate::__private::convert::<f64, #ty>(#lit)) };
        prologue.extend(quote!(let #name: #ty = #value;));
    }
    prologue.extend(body);
    let body = prologue;
    let outputs = outputs.iter().map(|o| exprs[o].pos.0.clone()).collect();
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
