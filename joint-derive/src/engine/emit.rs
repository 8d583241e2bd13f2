//! From nodes to Rust: straight-line code in arena order.
//!
//! Only the nodes a function's outputs reach are printed (dead nodes are
//! removed per function). A node used once is written inline in its user; a
//! node used more than once gets a `let`, named by its hint from the code that
//! made it (`a1_12`, `s_n_x`, `d_y`) or `t<n>` in order of appearance.
//! Parentheses are written exactly where Rust's precedence would otherwise
//! change the evaluation order, so the printed code evaluates the graph's
//! operations in the graph's order, bit for bit (up to the sign of a zero, see
//! [`Ex`]). Negations are pushed inward (`−(a − b)` is printed `b − a`, exact
//! in IEEE arithmetic), and each constant's magnitude is one `let`, converted
//! to the scalar once. The output is deterministic: arena order, never a hash
//! map's. Past 2 000 `let`s a function binds one tuple per level of the graph
//! instead: rustc's debug info recurses once per nested scope, and one `let`
//! per value crashed it on a 160-body chain. `OpCount` counts operations
//! incrementally, so that the derive can choose between alternatives and split
//! or stop at its size limits.

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
            Node::Neg(a) | Node::Sin(a) | Node::Cos(a) | Node::Sqrt(a) => live[a.index()] = true,
            Node::Const(_) | Node::Var(_) => {}
        }
    }
    (0..g.len()).filter(|&i| live[i]).map(|i| Id(i as u32)).collect()
}

/// Binary operations needed by `outputs` (shared nodes counted once).
pub fn count_ops(g: &Graph, outputs: &[Id]) -> usize {
    OpCount::new(g).add(outputs)
}

/// Binary operations of a growing set of outputs (shared nodes counted once),
/// counted incrementally: linear in the graph over all additions, where
/// recounting the union each time would be quadratic.
#[derive(Clone)]
pub struct OpCount<'g> {
    g: &'g Graph,
    live: Vec<bool>,
    ops: usize,
}

impl<'g> OpCount<'g> {
    /// Nothing counted yet.
    pub fn new(g: &'g Graph) -> Self {
        OpCount { g, live: vec![false; g.len()], ops: 0 }
    }

    /// The nodes `outputs` need that are not counted yet, and their operations.
    fn new_nodes(&self, outputs: &[Id]) -> (std::collections::HashSet<Id>, usize) {
        let mut seen = std::collections::HashSet::new();
        let mut stack: Vec<Id> = outputs.to_vec();
        let mut extra = 0;
        while let Some(id) = stack.pop() {
            if self.live[id.index()] || !seen.insert(id) {
                continue;
            }
            match self.g.node(id) {
                Node::Add(a, b) | Node::Sub(a, b) | Node::Mul(a, b) | Node::Div(a, b) => {
                    extra += 1;
                    stack.extend([a, b]);
                }
                Node::Neg(a) | Node::Sin(a) | Node::Cos(a) | Node::Sqrt(a) => stack.push(a),
                Node::Const(_) | Node::Var(_) => {}
            }
        }
        (seen, extra)
    }

    /// Operations `outputs` would add.
    pub fn extra(&self, outputs: &[Id]) -> usize {
        self.new_nodes(outputs).1
    }

    /// Counts `outputs`; returns the total.
    pub fn add(&mut self, outputs: &[Id]) -> usize {
        let (seen, extra) = self.new_nodes(outputs);
        for id in seen {
            self.live[id.index()] = true;
        }
        self.ops += extra;
        self.ops
    }
}

const ATOM: u8 = 4;

/// Beyond this many `let`s in one function, they are grouped by level (small
/// scenes keep one `let` per value: the grouping cost a 3-body scene 3 % per
/// step; rustc crashed at a few thousand nested scopes).
const GROUP_ABOVE: usize = 2_000;

/// A node as printed: the expression and its precedence (1 `+ −`, 2 `×`, 3 unary
/// minus, 4 atom), and the same for its negation. Negations are pushed into the
/// printed expression (`−(a − b)` as `b − a`), which IEEE arithmetic makes exact
/// up to the sign of a zero result.
struct Ex {
    pos: (TokenStream, u8),
    neg: (TokenStream, u8),
    /// The latest `let` it reads: its level (0 for inputs and constants).
    level: u32,
}

impl Ex {
    fn atom(t: TokenStream, level: u32) -> Self {
        Ex { neg: (quote!(-#t), 3), pos: (t, ATOM), level }
    }
}

fn paren(e: &(TokenStream, u8), min: u8) -> TokenStream {
    let (t, p) = e;
    if *p >= min { t.clone() } else { quote!((#t)) }
}

/// How many times each node is read by the nodes and outputs that need it; a
/// negation is free and never bound, so its uses count as its operand's.
fn count_uses(g: &Graph, nodes: &[Id], outputs: &[Id]) -> HashMap<Id, usize> {
    let mut uses: HashMap<Id, usize> = HashMap::new();
    for &id in nodes {
        match g.node(id) {
            Node::Add(a, b) | Node::Sub(a, b) | Node::Mul(a, b) | Node::Div(a, b) => {
                *uses.entry(a).or_default() += 1;
                *uses.entry(b).or_default() += 1;
            }
            Node::Neg(a) | Node::Sin(a) | Node::Cos(a) | Node::Sqrt(a) => *uses.entry(a).or_default() += 1,
            Node::Const(_) | Node::Var(_) => {}
        }
    }
    for &o in outputs {
        *uses.entry(o).or_default() += 1;
    }
    for &id in nodes.iter().rev() {
        if let Node::Neg(a) = g.node(id) {
            let extra = uses.get(&id).copied().unwrap_or(0).saturating_sub(1);
            *uses.entry(a).or_default() += extra;
        }
    }
    uses
}

/// The state of one emission: every node printed so far, the `let`s, and the
/// names taken.
struct Emitter<'a> {
    g: &'a Graph,
    scalar: &'a ScalarTy,
    /// Every node emitted so far, as itself and as its negation.
    exprs: HashMap<Id, Ex>,
    /// `let`s: level, name, value.
    lets: Vec<(u32, Ident, TokenStream)>,
    used_vars: BTreeSet<VarId>,
    /// Input names are taken: a `let` never shadows an input (a user's scalar
    /// parameter may well be called `two` or `t1`).
    taken: HashMap<String, usize>,
    counter: usize,
    ops: usize,
    /// Constants by magnitude, bound once in the prologue (the sign is free).
    consts: std::collections::BTreeMap<u64, Ident>,
}

/// Emits the computation of `outputs`.
pub fn emit(g: &Graph, outputs: &[Id], scalar: &ScalarTy) -> Emitted {
    let nodes = reachable(g, outputs);
    let uses = count_uses(g, &nodes, outputs);
    let taken = nodes.iter().filter_map(|&id| g.as_var(id)).map(|v| (g.vars()[v.0 as usize].name.clone(), 1)).collect();
    let mut e = Emitter {
        g,
        scalar,
        exprs: HashMap::new(),
        lets: Vec::new(),
        used_vars: BTreeSet::new(),
        taken,
        counter: 0,
        ops: 0,
        consts: Default::default(),
    };
    for &id in &nodes {
        let ex = e.node(id);
        let node = g.node(id);
        let bind = uses.get(&id).copied().unwrap_or(0) > 1
            && matches!(
                node,
                Node::Add(..)
                    | Node::Sub(..)
                    | Node::Mul(..)
                    | Node::Div(..)
                    | Node::Sin(_)
                    | Node::Cos(_)
                    | Node::Sqrt(_)
            );
        let ex = if bind { e.bind(id, ex) } else { ex };
        e.exprs.insert(id, ex);
    }
    let mut body = e.prologue();
    body.extend(e.lets());
    let outputs = outputs.iter().map(|o| e.exprs[o].pos.0.clone()).collect();
    Emitted { body, outputs, used_vars: e.used_vars, ops: e.ops }
}

impl Emitter<'_> {
    /// A fresh name from `base`: `base`, then `base_2`, ...
    fn fresh(&mut self, base: String) -> Ident {
        let n = self.taken.entry(base.clone()).or_insert(0);
        *n += 1;
        if *n == 1 { format_ident!("{}", base) } else { format_ident!("{}_{}", base, *n) }
    }

    /// Operands of + and × are printed with the running sum (or product) on the
    /// left, where Rust needs no parentheses; both orders give the same bits.
    fn ordered(&self, a: Id, b: Id, prec: u8) -> (Id, Id) {
        let (pa, pb) = (self.exprs[&a].pos.1, self.exprs[&b].pos.1);
        if pb == prec && pa != prec { (b, a) } else { (a, b) }
    }

    /// The expression of one node, its operands already emitted.
    fn node(&mut self, id: Id) -> Ex {
        let node = self.g.node(id);
        if matches!(node, Node::Add(..) | Node::Sub(..) | Node::Mul(..) | Node::Div(..)) {
            self.ops += 1;
        }
        match node {
            Node::Const(bits) => self.constant(f64::from_bits(bits)),
            Node::Var(v) => {
                self.used_vars.insert(v);
                let name = Ident::new(&self.g.vars()[v.0 as usize].name, Span::call_site());
                Ex::atom(quote!(#name), 0)
            }
            Node::Add(a, b) => {
                let (a, b) = self.ordered(a, b, 1);
                let (ea, eb) = (&self.exprs[&a], &self.exprs[&b]);
                let (l, r, ln) = (paren(&ea.pos, 1), paren(&eb.pos, 2), paren(&ea.neg, 1));
                // −(a + b) = (−a) − b
                Ex { pos: (quote!(#l + #r), 1), neg: (quote!(#ln - #r), 1), level: ea.level.max(eb.level) }
            }
            Node::Sub(a, b) => {
                let (ea, eb) = (&self.exprs[&a], &self.exprs[&b]);
                let (l, r) = (paren(&ea.pos, 1), paren(&eb.pos, 2));
                let (bl, ar) = (paren(&eb.pos, 1), paren(&ea.pos, 2));
                // −(a − b) = b − a
                Ex { pos: (quote!(#l - #r), 1), neg: (quote!(#bl - #ar), 1), level: ea.level.max(eb.level) }
            }
            Node::Mul(a, b) => {
                let (a, b) = self.ordered(a, b, 2);
                let (ea, eb) = (&self.exprs[&a], &self.exprs[&b]);
                let (l, r, ln) = (paren(&ea.pos, 2), paren(&eb.pos, 3), paren(&ea.neg, 2));
                // −(a · b) = (−a) · b
                Ex { pos: (quote!(#l * #r), 2), neg: (quote!(#ln * #r), 2), level: ea.level.max(eb.level) }
            }
            Node::Div(a, b) => {
                let (ea, eb) = (&self.exprs[&a], &self.exprs[&b]);
                let (l, r, ln) = (paren(&ea.pos, 2), paren(&eb.pos, 3), paren(&ea.neg, 2));
                Ex { pos: (quote!(#l / #r), 2), neg: (quote!(#ln / #r), 2), level: ea.level.max(eb.level) }
            }
            Node::Neg(a) => {
                let ea = &self.exprs[&a];
                Ex { pos: ea.neg.clone(), neg: ea.pos.clone(), level: ea.level }
            }
            Node::Sin(a) | Node::Cos(a) | Node::Sqrt(a) => {
                let (x, level) = (paren(&self.exprs[&a].pos, 1), self.exprs[&a].level);
                let f = match node {
                    Node::Sin(_) => quote!(simd_sin),
                    Node::Cos(_) => quote!(simd_cos),
                    _ => quote!(simd_sqrt),
                };
                let (ty, krate) = (&self.scalar.ty, &self.scalar.krate);
                Ex::atom(quote!(<#ty as #krate::__private::SimdComplexField>::#f(#x)), level)
            }
        }
    }

    /// A constant: bound once per magnitude in the prologue; the sign is free.
    fn constant(&mut self, v: f64) -> Ex {
        let name = match self.consts.get(&v.abs().to_bits()) {
            Some(name) => name.clone(),
            None => {
                let name = self.fresh(const_name(v.abs()).to_string());
                self.consts.insert(v.abs().to_bits(), name.clone());
                name
            }
        };
        let (plain, negated) = ((quote!(#name), ATOM), (quote!(-#name), 3));
        if v < 0.0 { Ex { pos: negated, neg: plain, level: 0 } } else { Ex { pos: plain, neg: negated, level: 0 } }
    }

    /// A `let` for a node used more than once, named by its hint or `t<n>`.
    fn bind(&mut self, id: Id, ex: Ex) -> Ex {
        let base = match self.g.hint_of(id) {
            Some(h) => h.to_string(),
            None => {
                self.counter += 1;
                format!("t{}", self.counter)
            }
        };
        let name = self.fresh(base);
        let level = ex.level + 1;
        self.lets.push((level, name.clone(), ex.pos.0));
        Ex::atom(quote!(#name), level)
    }

    /// The `let`s in order; past [`GROUP_ABOVE`] of them, one `let` per level
    /// (a tuple of the bindings that read only earlier levels): every `let`
    /// opens a scope, and rustc's debug info recurses once per scope (a
    /// 160-body scene's few thousand nested scopes crash it).
    fn lets(&mut self) -> TokenStream {
        let lets = std::mem::take(&mut self.lets);
        if lets.len() <= GROUP_ABOVE {
            return lets.into_iter().map(|(_, name, expr)| quote!(let #name = #expr;)).collect();
        }
        let top = lets.iter().map(|l| l.0).max().unwrap_or(0);
        let mut out = TokenStream::new();
        for level in 1..=top {
            let (names, exprs): (Vec<&Ident>, Vec<&TokenStream>) =
                lets.iter().filter(|l| l.0 == level).map(|(_, n, e)| (n, e)).unzip();
            out.extend(match names.as_slice() {
                [] => TokenStream::new(),
                [name] => quote!(let #name = #(#exprs)*;),
                _ => quote!(let (#(#names),*) = (#(#exprs),*);),
            });
        }
        out
    }

    /// The constants' `let`s, converted once to the scalar.
    fn prologue(&self) -> TokenStream {
        let (ty, krate) = (&self.scalar.ty, &self.scalar.krate);
        let mut prologue = TokenStream::new();
        for (bits, name) in &self.consts {
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
            let value = if self.scalar.concrete_f64 {
                quote!(#lit)
            } else {
                quote!(#krate::__private::convert::<f64, #ty>(#lit))
            };
            prologue.extend(quote!(let #name: #ty = #value;));
        }
        prologue
    }
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
