//! Table-driven tests of the symbolic engine, in the spirit of egg's
//! `tests/math.rs`: one line per rule.
//!
//! Expressions are written as s-expressions over a fixed set of inputs:
//!
//! - states `a b c x y z`, each with a rate `ad bd cd xd yd zd` (also states) and
//!   the rule `d/dt s = sd`; the rates themselves are held (`d/dt sd = 0`);
//! - parameters `p q`;
//! - numbers, and the operators `+ - * / neg sin cos sum` (`-` is binary; `neg`
//!   is unary; `sum` takes any number of terms).
//!
//! The left-hand side of a rule is built with the smart constructors. The
//! right-hand side is either a *shape* (compared structurally with the node the
//! constructors produced, printed back as an s-expression) or a closed form,
//! which is interpreted directly in `f64`, independently of the engine.

// Matrix checks read best with explicit row and column indices.
#![allow(clippy::needless_range_loop)]

use std::collections::HashMap;

use proc_macro2::TokenStream;
use quote::quote;

use super::diff::{TimeRules, grad};
use super::emit::{Emitted, ScalarTy, emit, reachable};
use super::graph::{Graph, Id, Node, VarId};
use crate::kinematics::{self, Formulation, Ground, Kinematics};

// ---------------------------------------------------------------------------
// S-expressions
// ---------------------------------------------------------------------------

#[derive(Clone, Debug, PartialEq)]
enum Sx {
    Atom(String),
    List(Vec<Sx>),
}

fn parse(src: &str) -> Sx {
    let spaced = src.replace('(', " ( ").replace(')', " ) ");
    let mut tokens = spaced.split_whitespace().peekable();
    let sx = parse_tokens(&mut tokens);
    assert!(tokens.next().is_none(), "trailing tokens in {src:?}");
    sx
}

fn parse_tokens<'a>(tokens: &mut std::iter::Peekable<impl Iterator<Item = &'a str>>) -> Sx {
    match tokens.next().expect("unexpected end of s-expression") {
        "(" => {
            let mut items = Vec::new();
            while tokens.peek() != Some(&")") {
                items.push(parse_tokens(tokens));
            }
            tokens.next();
            Sx::List(items)
        }
        ")" => panic!("unexpected `)`"),
        atom => Sx::Atom(atom.to_string()),
    }
}

fn number(atom: &str) -> Option<f64> {
    if atom.starts_with(|c: char| c.is_ascii_digit() || c == '-' || c == '.') { atom.parse().ok() } else { None }
}

/// Prints an s-expression back with numbers in `f64` display form, so that
/// `"2.0"`, `"2"` and `"2e0"` compare equal.
fn normalize(sx: &Sx) -> String {
    match sx {
        Sx::Atom(a) => match number(a) {
            Some(v) => format!("{v}"),
            None => a.clone(),
        },
        Sx::List(items) => format!("({})", items.iter().map(normalize).collect::<Vec<_>>().join(" ")),
    }
}

fn shape(src: &str) -> String {
    normalize(&parse(src))
}

// ---------------------------------------------------------------------------
// A graph with the fixed inputs
// ---------------------------------------------------------------------------

const STATES: [&str; 6] = ["a", "b", "c", "x", "y", "z"];
const PARAMS: [&str; 2] = ["p", "q"];

/// Values of every input at one point.
type Env = HashMap<String, f64>;

fn env() -> Env {
    let values = [
        ("a", 0.7),
        ("b", -1.3),
        ("c", 0.4),
        ("x", 1.1),
        ("y", -0.6),
        ("z", 2.3),
        ("ad", 0.3),
        ("bd", -0.45),
        ("cd", 1.25),
        ("xd", -0.8),
        ("yd", 0.55),
        ("zd", 1.9),
        ("p", 1.7),
        ("q", -0.85),
    ];
    values.iter().map(|&(n, v)| (n.to_string(), v)).collect()
}

/// A second point, for checks that a single lucky point could pass.
fn env2() -> Env {
    let mut e = env();
    for (i, v) in e.values_mut().enumerate() {
        *v = -0.5 * *v + 0.1 * (i as f64 % 3.0);
    }
    e
}

/// `e` moved along the motion `s(t) = s + t sd` (the rates are held).
fn along(e: &Env, t: f64) -> Env {
    let mut moved = e.clone();
    for s in STATES {
        let rate = e[&format!("{s}d")];
        *moved.get_mut(s).unwrap() += t * rate;
    }
    moved
}

fn with(e: &Env, name: &str, value: f64) -> Env {
    let mut moved = e.clone();
    moved.insert(name.to_string(), value);
    moved
}

struct Ctx {
    g: Graph,
    names: HashMap<String, Id>,
    rules: TimeRules,
}

impl Ctx {
    /// States in the order `a b c x y z` (so their ids are in that order), then
    /// their rates, then the parameters.
    fn new() -> Self {
        let mut g = Graph::new();
        let mut names = HashMap::new();
        for s in STATES {
            names.insert(s.to_string(), g.state(s));
        }
        for s in STATES {
            let d = format!("{s}d");
            names.insert(d.clone(), g.state(d));
        }
        for p in PARAMS {
            names.insert(p.to_string(), g.param(p));
        }
        let mut rules = TimeRules::new();
        for s in STATES {
            rules.set_var(&g, names[s], names[&format!("{s}d")]);
        }
        Ctx { g, names, rules }
    }

    fn v(&self, name: &str) -> Id {
        self.names[name]
    }

    fn build(&mut self, src: &str) -> Id {
        self.build_sx(&parse(src))
    }

    fn build_sx(&mut self, sx: &Sx) -> Id {
        match sx {
            Sx::Atom(a) => match number(a) {
                Some(v) => self.g.constant(v),
                None => *self.names.get(a).unwrap_or_else(|| panic!("unknown input {a}")),
            },
            Sx::List(items) => {
                let Sx::Atom(op) = &items[0] else { panic!("operator expected") };
                let args: Vec<Id> = items[1..].iter().map(|s| self.build_sx(s)).collect();
                let g = &mut self.g;
                match (op.as_str(), args.as_slice()) {
                    ("+", &[l, r]) => g.add(l, r),
                    ("-", &[l, r]) => g.sub(l, r),
                    ("*", &[l, r]) => g.mul(l, r),
                    ("/", &[l, r]) => g.div(l, r),
                    ("neg", &[l]) => g.neg(l),
                    ("sin", &[l]) => g.sin(l),
                    ("cos", &[l]) => g.cos(l),
                    ("sum", terms) => g.sum(terms),
                    _ => panic!("bad operator {op} with {} operands", args.len()),
                }
            }
        }
    }

    /// The structure of a node as an s-expression.
    fn show(&self, id: Id) -> String {
        match self.g.node(id) {
            Node::Const(bits) => format!("{}", f64::from_bits(bits)),
            Node::Var(v) => self.g.vars()[v.0 as usize].name.clone(),
            Node::Add(l, r) => format!("(+ {} {})", self.show(l), self.show(r)),
            Node::Sub(l, r) => format!("(- {} {})", self.show(l), self.show(r)),
            Node::Mul(l, r) => format!("(* {} {})", self.show(l), self.show(r)),
            Node::Div(l, r) => format!("(/ {} {})", self.show(l), self.show(r)),
            Node::Neg(l) => format!("(neg {})", self.show(l)),
            Node::Sin(l) => format!("(sin {})", self.show(l)),
            Node::Sqrt(l) => format!("(sqrt {})", self.show(l)),
            Node::Cos(l) => format!("(cos {})", self.show(l)),
        }
    }

    fn eval(&self, id: Id, e: &Env) -> f64 {
        eval_in(&self.g, id, e)
    }

    fn dt(&mut self, id: Id) -> Id {
        self.rules.dt(&mut self.g, id)
    }
}

/// Evaluates a node with the inputs looked up by name (a missing input panics,
/// which catches a dependency that should not be there).
fn eval_in(g: &Graph, id: Id, e: &Env) -> f64 {
    g.eval(id, &|v: VarId| {
        let name = &g.vars()[v.0 as usize].name;
        *e.get(name).unwrap_or_else(|| panic!("no value for {name}"))
    })
}

/// Direct `f64` interpretation of an s-expression: the reference the engine is
/// checked against.
fn interpret(sx: &Sx, e: &Env) -> f64 {
    match sx {
        Sx::Atom(a) => number(a).unwrap_or_else(|| e[a]),
        Sx::List(items) => {
            let Sx::Atom(op) = &items[0] else { panic!("operator expected") };
            let args: Vec<f64> = items[1..].iter().map(|s| interpret(s, e)).collect();
            match (op.as_str(), args.as_slice()) {
                ("+", &[l, r]) => l + r,
                ("-", &[l, r]) => l - r,
                ("*", &[l, r]) => l * r,
                ("/", &[l, r]) => l / r,
                ("neg", &[l]) => -l,
                ("sin", &[l]) => l.sin(),
                ("cos", &[l]) => l.cos(),
                ("sum", terms) => terms.iter().sum(),
                _ => panic!("bad operator {op}"),
            }
        }
    }
}

fn value(src: &str, e: &Env) -> f64 {
    interpret(&parse(src), e)
}

#[track_caller]
fn assert_close(got: f64, want: f64, tol: f64, what: &str) {
    let scale = 1.0_f64.max(want.abs());
    assert!((got - want).abs() <= tol * scale, "{what}: got {got:e}, want {want:e} (diff {:e})", (got - want).abs());
}

// ---------------------------------------------------------------------------
// 1. Simplification rules of the smart constructors
// ---------------------------------------------------------------------------

/// `lhs` built with the smart constructors has the structure `rhs`, and still
/// evaluates to the value of `lhs` read literally.
#[track_caller]
fn check_shape(lhs: &str, rhs: &str) {
    let mut cx = Ctx::new();
    let id = cx.build(lhs);
    assert_eq!(cx.show(id), shape(rhs), "{lhs} should simplify to {rhs}");
    for e in [env(), env2()] {
        assert_close(cx.eval(id, &e), value(lhs, &e), 1e-14, lhs);
    }
}

/// `lhs` and `rhs` built with the smart constructors are the same node.
#[track_caller]
fn check_same(lhs: &str, rhs: &str) {
    let mut cx = Ctx::new();
    let l = cx.build(lhs);
    let r = cx.build(rhs);
    assert_eq!(l, r, "{lhs} = {} but {rhs} = {}", cx.show(l), cx.show(r));
}

macro_rules! simplifies {
    ($($name:ident: $lhs:expr => $rhs:expr;)*) => {$(
        #[test]
        fn $name() {
            check_shape($lhs, &$rhs);
        }
    )*};
}

macro_rules! same_node {
    ($($name:ident: $lhs:expr, $rhs:expr;)*) => {$(
        #[test]
        fn $name() {
            check_same($lhs, $rhs);
        }
    )*};
}

mod simplify {
    use super::*;

    simplifies! {
        add_zero_right:        "(+ x 0)" => "x";
        add_zero_left:         "(+ 0 x)" => "x";
        sub_zero:              "(- x 0)" => "x";
        zero_sub:              "(- 0 x)" => "(neg x)";
        mul_one_right:         "(* x 1)" => "x";
        mul_one_left:          "(* 1 x)" => "x";
        mul_zero_right:        "(* x 0)" => "0";
        mul_zero_left:         "(* 0 x)" => "0";
        mul_zero_compound:     "(* (sin (* x y)) 0)" => "0";
        mul_minus_one_right:   "(* x -1)" => "(neg x)";
        mul_minus_one_left:    "(* -1 x)" => "(neg x)";
        neg_neg:               "(neg (neg x))" => "x";
        neg_neg_compound:      "(neg (neg (* x y)))" => "(* x y)";
        fold_add:              "(+ 2 3)" => "5";
        fold_sub:              "(- 2 3)" => "-1";
        fold_mul:              "(* 2 3)" => "6";
        fold_neg:              "(neg 2)" => "-2";
        fold_sin:              "(sin 0.5)" => format!("{}", 0.5_f64.sin());
        fold_cos:              "(cos 0.5)" => format!("{}", 0.5_f64.cos());
        fold_nested:           "(+ (* 2 3) (- (sin 0) (cos 0)))" => "5";
        fold_sum:              "(sum 1 2 3)" => "6";
        sub_self:              "(- x x)" => "0";
        sub_self_compound:     "(- (* x y) (* y x))" => "0";
        add_self:              "(+ x x)" => "(* 2 x)";
        add_self_compound:     "(+ (* x y) (* y x))" => "(* 2 (* x y))";
        like_terms:            "(+ (* 3 x) (* 4 x))" => "(* 7 x)";
        like_terms_unit:       "(+ x (* 4 x))" => "(* 5 x)";
        like_terms_sub:        "(- (* 3 x) x)" => "(* 2 x)";
        like_terms_to_neg:     "(- x (* 3 x))" => "(neg (* 2 x))";
        like_terms_cancel:     "(+ (* 3 x) (* -3 x))" => "0";
        like_terms_neg:        "(+ x (neg x))" => "0";
        like_terms_neg_neg:    "(+ (neg x) (neg x))" => "(neg (* 2 x))";
        sub_neg_self:          "(- x (neg x))" => "(* 2 x)";
        add_neg_is_sub:        "(+ a (neg b))" => "(- a b)";
        neg_add_is_sub:        "(+ (neg a) b)" => "(neg (- a b))";
        add_neg_neg:           "(+ (neg a) (neg b))" => "(neg (+ a b))";
        sub_neg:               "(- a (neg b))" => "(+ a b)";
        neg_sub_pos:           "(- (neg a) b)" => "(neg (+ a b))";
        neg_sub_neg:           "(- (neg a) (neg b))" => "(neg (- a b))";
        neg_times:             "(* (neg a) b)" => "(neg (* a b))";
        times_neg:             "(* a (neg b))" => "(neg (* a b))";
        neg_times_neg:         "(* (neg a) (neg b))" => "(* a b)";
        add_canonical:         "(+ b a)" => "(+ a b)";
        mul_canonical:         "(* b a)" => "(* a b)";
        sub_ordered:           "(- a b)" => "(- a b)";
        sub_reversed:          "(- b a)" => "(neg (- a b))";
        neg_of_sub:            "(neg (- a b))" => "(neg (- a b))";
        neg_of_reversed_sub:   "(neg (- b a))" => "(- a b)";
        const_first:           "(* x 2)" => "(* 2 x)";
        const_assoc:           "(* 2 (* 3 x))" => "(* 6 x)";
        const_assoc_right:     "(* (* x 3) 2)" => "(* 6 x)";
        const_assoc_to_one:    "(* 0.5 (* 2 x))" => "x";
        const_assoc_neg:       "(* -2 (* 3 x))" => "(neg (* 6 x))";
        neg_const_factor:      "(* -2 x)" => "(neg (* 2 x))";
        const_times_neg:       "(* 2 (neg x))" => "(neg (* 2 x))";
        neg_const_times_neg:   "(* -2 (neg x))" => "(* 2 x)";
        minus_zero_literal:    "-0" => "0";
        neg_zero:              "(neg 0)" => "0";
        fold_to_minus_zero:    "(* -1 0)" => "0";
        sub_to_minus_zero:     "(- -0 0)" => "0";
        sum_empty:             "(sum)" => "0";
        sum_left_to_right:     "(sum x y z)" => "(+ z (+ x y))";
        sum_skips_zeros:       "(sum 0 x 0)" => "x";
        sin_not_folded:        "(sin x)" => "(sin x)";
        params_are_inputs:     "(+ (* p x) q)" => "(+ q (* x p))";
        div_one:               "(/ x 1)" => "x";
        div_zero_numerator:    "(/ 0 x)" => "0";
        div_fold:              "(/ 6 4)" => "1.5";
        div_kept:              "(/ x y)" => "(/ x y)";
        div_by_const_kept:     "(/ x 3)" => "(/ x 3)";
        div_neg_numerator:     "(/ (neg x) y)" => "(neg (/ x y))";
        div_neg_denominator:   "(/ x (neg y))" => "(neg (/ x y))";
        div_neg_both:          "(/ (neg x) (neg y))" => "(/ x y)";
        div_self_kept:         "(/ x x)" => "(/ x x)";
    }

    same_node! {
        add_commutes:          "(+ a b)", "(+ b a)";
        add_commutes_deep:     "(+ (* x y) (sin z))", "(+ (sin z) (* y x))";
        mul_commutes:          "(* a b)", "(* b a)";
        mul_commutes_deep:     "(* (+ x y) (cos z))", "(* (cos z) (+ y x))";
        sub_antisymmetric:     "(- b a)", "(neg (- a b))";
        sub_antisymmetric_2:   "(- a b)", "(neg (- b a))";
        neg_mul_outside:       "(* (neg a) b)", "(neg (* a b))";
        const_assoc_same:      "(* 2 (* 3 x))", "(* 6 x)";
        like_terms_same:       "(+ (* 3 x) (* 4 x))", "(* 7 x)";
        add_self_same:         "(+ x x)", "(* x 2)";
        minus_zero_same:       "-0", "0";
        neg_zero_same:         "(neg 0)", "(- 0 0)";
    }

    /// `-0.0` never reaches the arena: the bits are those of `+0.0`.
    #[test]
    fn minus_zero_stored_as_plus_zero() {
        let mut g = Graph::new();
        let m = g.constant(-0.0);
        let z = g.zero();
        assert_eq!(m, z);
        assert_eq!(g.node(m), Node::Const(0.0_f64.to_bits()));
        assert!(g.as_const(m).unwrap().is_sign_positive());
        let n = g.neg(z);
        assert_eq!(n, z);
        assert_eq!(g.len(), 1);
    }

    /// Hints name binary operations, `sin` and `cos`; inputs, constants and
    /// negations keep no hint; the first hint wins; `hint_new` only names nodes
    /// made at or after the given arena position.
    #[test]
    fn hints() {
        let mut cx = Ctx::new();
        let (x, k) = (cx.v("x"), cx.g.constant(2.5));
        let xy = cx.build("(* x y)");
        let n = cx.build("(neg (* x y))");
        let s = cx.build("(sin x)");
        for id in [x, k, n, xy, s] {
            cx.g.hint(id, "first");
        }
        cx.g.hint(xy, "second");
        assert_eq!([x, k, n].map(|i| cx.g.hint_of(i)), [None, None, None]);
        assert_eq!(cx.g.hint_of(xy), Some("first"));
        assert_eq!(cx.g.hint_of(s), Some("first"));
        let start = cx.g.len();
        let old = cx.build("(+ x y)");
        cx.g.hint_new(start, old, "old");
        assert_eq!(cx.g.hint_of(old), Some("old"), "made after start");
        let start = cx.g.len();
        let again = cx.build("(+ y x)");
        let fresh = cx.build("(- x z)");
        cx.g.hint_new(start, again, "again");
        cx.g.hint_new(start, fresh, "fresh");
        assert_eq!(cx.g.hint_of(again), Some("old"));
        assert_eq!(cx.g.hint_of(fresh), Some("fresh"));
        let pre = cx.build("(* a b)");
        let start = cx.g.len();
        cx.g.hint_new(start, pre, "late");
        assert_eq!(cx.g.hint_of(pre), None, "made before start");
    }

    /// Dependency masks: parameters and constants have none; a node has the union
    /// of its operands'.
    #[test]
    fn masks() {
        let mut cx = Ctx::new();
        let (x, y, p) = (cx.v("x"), cx.v("y"), cx.v("p"));
        let (mx, my) = (cx.g.mask(x), cx.g.mask(y));
        assert_ne!(mx, 0);
        assert_ne!(my, 0);
        assert_eq!(mx & my, 0);
        assert_eq!(cx.g.mask(p), 0);
        let e = cx.build("(sin (+ (* p x) y))");
        assert_eq!(cx.g.mask(e), mx | my);
        let k = cx.build("(* p (cos q))");
        assert_eq!(cx.g.mask(k), 0);
    }
}

// ---------------------------------------------------------------------------
// 2. Hash-consing and common subexpressions
// ---------------------------------------------------------------------------

mod hashcons {
    use super::*;

    const EXPRS: [&str; 6] = [
        "(+ (* x y) (sin z))",
        "(- (* p (cos (* x y))) (* 3 z))",
        "(neg (* (+ a b) (- c x)))",
        "(sum x y (* 2 z) (sin (cos a)))",
        "(* (- b a) (- a b))",
        "2.5",
    ];

    /// Building an expression twice returns the same id and adds no node.
    #[test]
    fn rebuilding_adds_nothing() {
        for src in EXPRS {
            let mut cx = Ctx::new();
            let first = cx.build(src);
            let len = cx.g.len();
            let second = cx.build(src);
            assert_eq!(first, second, "{src}");
            assert_eq!(cx.g.len(), len, "{src} added nodes the second time");
        }
    }

    /// A node's operands have smaller ids (the arena is in emission order).
    #[test]
    fn operands_come_first() {
        let mut cx = Ctx::new();
        for src in EXPRS {
            cx.build(src);
        }
        for i in 0..cx.g.len() {
            let id = Id(i as u32);
            let operands = match cx.g.node(id) {
                Node::Add(l, r) | Node::Sub(l, r) | Node::Mul(l, r) | Node::Div(l, r) => vec![l, r],
                Node::Neg(l) | Node::Sin(l) | Node::Cos(l) | Node::Sqrt(l) => vec![l],
                Node::Const(_) | Node::Var(_) => vec![],
            };
            assert!(operands.iter().all(|&o| o < id), "node {i} = {:?}", cx.g.node(id));
        }
    }

    /// `x*y` inside `x*y + sin(x*y)` is one node: 6 nodes in all (x, y, x*y,
    /// sin, +), nothing duplicated.
    #[test]
    fn shared_subexpression_is_one_node() {
        let mut g = Graph::new();
        let x = g.state("x");
        let y = g.state("y");
        let xy1 = g.mul(x, y);
        let s = g.sin(xy1);
        let xy2 = g.mul(y, x);
        assert_eq!(xy1, xy2);
        let f = g.add(xy2, s);
        assert_eq!(g.len(), 5);
        assert_eq!(g.node(f), Node::Add(xy1, s));
    }

    /// Constants are interned by value.
    #[test]
    fn constants_interned() {
        let mut g = Graph::new();
        let a = g.constant(2.0);
        let b = g.constant(2.0);
        let c = g.constant(1.0 + 1.0);
        assert_eq!((a, b), (c, c));
        let three = g.constant(3.0);
        assert_ne!(a, three);
        assert_eq!(g.len(), 2);
    }

    /// Two inputs with the same name are still two inputs.
    #[test]
    fn inputs_are_not_merged() {
        let mut g = Graph::new();
        let x1 = g.state("x");
        let x2 = g.state("x");
        let p1 = g.param("p");
        let p2 = g.param("p");
        assert_ne!(x1, x2);
        assert_ne!(p1, p2);
        assert_eq!(g.vars().len(), 4);
        assert_ne!(g.mask(x1), g.mask(x2));
        let d = g.sub(x1, x2);
        assert_eq!(g.node(d), Node::Sub(x1, x2));
    }

    /// Up to 64 differentiable inputs; parameters do not count.
    #[test]
    fn sixty_four_states() {
        let mut g = Graph::new();
        for i in 0..100 {
            g.param(format!("p{i}"));
        }
        let last = (0..63).map(|i| g.state(format!("s{i}"))).last().unwrap();
        assert_eq!(g.mask(last), 1 << 62);
    }

    /// Any number of differentiable inputs: masks wrap around 63 bits (a clear
    /// bit still proves independence), velocities alone set the top bit, and
    /// gradients stay exact.
    #[test]
    fn many_inputs_share_mask_bits() {
        let mut g = Graph::new();
        let xs: Vec<Id> = (0..200).map(|i| g.state(format!("s{i}"))).collect();
        let v = g.velocity("v");
        assert_eq!(g.mask(xs[0]), g.mask(xs[63]));
        assert_eq!(g.mask(xs[0]) & crate::engine::graph::VELOCITY, 0);
        assert_ne!(g.mask(v) & crate::engine::graph::VELOCITY, 0);
        // f = s0 * s63 + s199 * v: gradient with respect to s0, s63, s1 and v.
        let a = g.mul(xs[0], xs[63]);
        let b = g.mul(xs[199], v);
        let f = g.add(a, b);
        let d = grad(&mut g, f, &[xs[0], xs[63], xs[1], v]);
        assert_eq!(d, vec![xs[63], xs[0], g.zero(), xs[199]]);
    }

    /// `emit` counts a shared subexpression once: `(a*b) + (a*b)*c` is 3
    /// operations, not 4.
    #[test]
    fn shared_counted_once_in_ops() {
        let mut cx = Ctx::new();
        let f = cx.build("(+ (* a b) (* (* a b) c))");
        let out = emit(&cx.g, &[f], &f64_scalar());
        assert_eq!(out.ops, 3);
        // Two outputs sharing everything but the last step.
        let g1 = cx.build("(* (+ a b) (+ a b))");
        let g2 = cx.build("(* (+ a b) c)");
        let out = emit(&cx.g, &[g1, g2], &f64_scalar());
        assert_eq!(out.ops, 3);
    }
}

// ---------------------------------------------------------------------------
// 3. Derivatives
// ---------------------------------------------------------------------------

/// `d/dt lhs` (with `d/dt s = sd`) evaluates to the closed form `rhs` and to a
/// central difference of `lhs` along `s + t sd`, at two points.
#[track_caller]
fn check_dt_value(lhs: &str, rhs: &str) {
    let mut cx = Ctx::new();
    let f = cx.build(lhs);
    let d = cx.dt(f);
    for e in [env(), env2()] {
        let got = cx.eval(d, &e);
        assert_close(got, value(rhs, &e), 1e-13, &format!("d/dt {lhs} vs {rhs}"));
        let h = 1e-5;
        let fd = (value(lhs, &along(&e, h)) - value(lhs, &along(&e, -h))) / (2.0 * h);
        assert_close(got, fd, 1e-8, &format!("d/dt {lhs} vs central difference"));
    }
}

/// `d/dt lhs` has the structure `rhs`.
#[track_caller]
fn check_dt_shape(lhs: &str, rhs: &str) {
    let mut cx = Ctx::new();
    let f = cx.build(lhs);
    let d = cx.dt(f);
    assert_eq!(cx.show(d), shape(rhs), "d/dt {lhs}");
}

macro_rules! dt_values {
    ($($name:ident: $lhs:expr => $rhs:expr;)*) => {$(
        #[test]
        fn $name() {
            check_dt_value($lhs, $rhs);
        }
    )*};
}

macro_rules! dt_shapes {
    ($($name:ident: $lhs:expr => $rhs:expr;)*) => {$(
        #[test]
        fn $name() {
            check_dt_shape($lhs, $rhs);
        }
    )*};
}

mod time_derivative {
    use super::*;

    dt_values! {
        var:              "x" => "xd";
        rate_is_held:     "xd" => "0";
        constant:         "3.5" => "0";
        param:            "p" => "0";
        param_product:    "(* p (sin q))" => "0";
        add:              "(+ x y)" => "(+ xd yd)";
        sub:              "(- x y)" => "(- xd yd)";
        neg:              "(neg x)" => "(neg xd)";
        mul:              "(* x y)" => "(+ (* xd y) (* x yd))";
        mul_param:        "(* p x)" => "(* p xd)";
        mul_const:        "(* 3 x)" => "(* 3 xd)";
        square:           "(* x x)" => "(* 2 (* x xd))";
        cube:             "(* x (* x x))" => "(* 3 (* (* x x) xd))";
        sin:              "(sin x)" => "(* (cos x) xd)";
        cos:              "(cos x)" => "(neg (* (sin x) xd))";
        sin_chain:        "(sin (* x y))" => "(* (cos (* x y)) (+ (* xd y) (* x yd)))";
        cos_chain:        "(cos (+ (* 2 x) p))" => "(neg (* (sin (+ (* 2 x) p)) (* 2 xd)))";
        product_three:    "(* x (* y z))" => "(sum (* xd (* y z)) (* x (* yd z)) (* x (* y zd)))";
        polynomial:       "(- (* 3 (* x y)) (* z z))" => "(- (* 3 (+ (* xd y) (* x yd))) (* 2 (* z zd)))";
        mixed:            "(* (sin x) (cos y))" => "(- (* (cos x) (* xd (cos y))) (* (sin x) (* (sin y) yd)))";
        like_terms:       "(+ (* 3 x) (* 4 x))" => "(* 7 xd)";
        quotient:         "(/ x y)" => "(/ (- (* xd y) (* x yd)) (* y y))";
        quotient_const:   "(/ x 4)" => "(/ xd 4)";
        quotient_param:   "(/ p (sin x))" => "(neg (/ (* p (* (cos x) xd)) (* (sin x) (sin x))))";
    }

    dt_shapes! {
        var_shape:        "x" => "xd";
        rate_shape:       "xd" => "0";
        constant_shape:   "3.5" => "0";
        param_shape:      "p" => "0";
        param_expr_shape: "(* p (cos q))" => "0";
        add_shape:        "(+ x y)" => "(+ xd yd)";
        sub_shape:        "(- x y)" => "(- xd yd)";
        neg_shape:        "(neg x)" => "(neg xd)";
        const_mul_shape:  "(* 2 x)" => "(* 2 xd)";
        param_mul_shape:  "(* p x)" => "(* xd p)";
        mul_shape:        "(* x y)" => "(+ (* y xd) (* x yd))";
        sin_shape:        "(sin x)" => "(* xd (cos x))";
        cos_shape:        "(cos x)" => "(neg (* xd (sin x)))";
        sub_self_shape:   "(- (* x y) (* y x))" => "0";
        div_param_shape:  "(/ p q)" => "0";
        div_const_shape:  "(/ x 4)" => "(/ xd 4)";
    }

    /// The second derivative with held rates: `d²/dt² (x y) = 2 ẋ ẏ`.
    #[test]
    fn second_derivative() {
        let mut cx = Ctx::new();
        let f = cx.build("(* x y)");
        let d = cx.dt(f);
        let dd = cx.dt(d);
        for e in [env(), env2()] {
            assert_close(cx.eval(dd, &e), 2.0 * e["xd"] * e["yd"], 1e-14, "d2/dt2 xy");
        }
        let s = cx.build("(sin x)");
        let ds = cx.dt(s);
        let dds = cx.dt(ds);
        let e = env();
        assert_close(cx.eval(dds, &e), -e["x"].sin() * e["xd"] * e["xd"], 1e-14, "d2/dt2 sin x");
    }

    /// A node rule wins over the structural derivative, also inside larger
    /// expressions.
    #[test]
    fn node_rule_takes_precedence() {
        let mut cx = Ctx::new();
        let xy = cx.build("(* x y)");
        let rule = cx.build("(* 7 z)");
        cx.rules.set_node(&cx.g, xy, rule);
        assert_eq!(cx.dt(xy), rule);
        let f = cx.build("(+ (* x y) z)");
        let df = cx.dt(f);
        let want = cx.build("(+ (* 7 z) zd)");
        assert_eq!(df, want, "got {}", cx.show(df));
        // The rule is used through sin too: d/dt sin(xy) = cos(xy) · 7z.
        let s = cx.build("(sin (* x y))");
        let ds = cx.dt(s);
        let e = env();
        assert_close(cx.eval(ds, &e), (e["x"] * e["y"]).cos() * 7.0 * e["z"], 1e-14, "sin with rule");
    }

    /// The first rule for a node is kept; rules on variables and constants are
    /// ignored (variables take `set_var`).
    #[test]
    fn node_rule_first_wins_and_inputs_ignored() {
        let mut cx = Ctx::new();
        let xy = cx.build("(* x y)");
        let (r1, r2) = (cx.v("a"), cx.v("b"));
        cx.rules.set_node(&cx.g, xy, r1);
        cx.rules.set_node(&cx.g, xy, r2);
        assert_eq!(cx.dt(xy), r1);
        let (x, c) = (cx.v("x"), cx.g.constant(4.0));
        cx.rules.set_node(&cx.g, x, r2);
        cx.rules.set_node(&cx.g, c, r2);
        assert_eq!(cx.dt(x), cx.v("xd"));
        assert_eq!(cx.dt(c), cx.g.zero());
    }

    /// Overridden rules replace the node rules they name, keep the others and
    /// the variables' rules, and leave the originals as they were.
    #[test]
    fn overridden_rules_replace_node_rules() {
        let mut cx = Ctx::new();
        let (xy, yz) = (cx.build("(* x y)"), cx.build("(* y z)"));
        let (r1, r2, r3) = (cx.v("a"), cx.v("b"), cx.v("c"));
        cx.rules.set_node(&cx.g, xy, r1);
        cx.rules.set_node(&cx.g, yz, r2);
        let mut overrides = TimeRules::new();
        overrides.set_node(&cx.g, xy, r3);
        let mut both = cx.rules.overridden(&overrides);
        assert_eq!(both.dt(&mut cx.g, xy), r3);
        assert_eq!(both.dt(&mut cx.g, yz), r2);
        let x = cx.v("x");
        assert_eq!(both.dt(&mut cx.g, x), cx.v("xd"));
        assert_eq!(cx.dt(xy), r1);
    }

    /// A rule added after a derivative was taken invalidates the memo.
    #[test]
    fn rules_reset_memo() {
        let mut cx = Ctx::new();
        let f = cx.build("(* x y)");
        let structural = cx.dt(f);
        let rule = cx.v("c");
        cx.rules.set_node(&cx.g, f, rule);
        assert_eq!(cx.dt(f), rule);
        assert_ne!(structural, rule);
        // And for variables.
        let x = cx.v("x");
        assert_eq!(cx.dt(x), cx.v("xd"));
        let z = cx.v("z");
        cx.rules.set_var(&cx.g, x, z);
        assert_eq!(cx.dt(x), z);
    }

    /// `dt` is memoized: asking again returns the same node and adds nothing.
    #[test]
    fn dt_memoized() {
        let mut cx = Ctx::new();
        let f = cx.build("(sin (* (+ x y) (cos (* z x))))");
        let d1 = cx.dt(f);
        let len = cx.g.len();
        let d2 = cx.dt(f);
        assert_eq!(d1, d2);
        assert_eq!(cx.g.len(), len);
        // A fresh rule set over the same graph builds the same nodes (hash-consing).
        let mut fresh = TimeRules::new();
        for s in STATES {
            fresh.set_var(&cx.g, cx.v(s), cx.v(&format!("{s}d")));
        }
        assert_eq!(fresh.dt(&mut cx.g, f), d1);
        assert_eq!(cx.g.len(), len);
    }

    /// With no rules every variable is constant.
    #[test]
    fn no_rules_means_constant() {
        let mut cx = Ctx::new();
        let f = cx.build("(* (sin x) (+ y z))");
        let mut none = TimeRules::new();
        assert_eq!(none.dt(&mut cx.g, f), cx.g.zero());
    }
}

/// `grad lhs` with respect to `wrt` evaluates to the closed forms `rhs` and to
/// central differences, at two points.
#[track_caller]
fn check_grad(lhs: &str, wrt: &[&str], rhs: &[&str]) {
    assert_eq!(wrt.len(), rhs.len());
    let mut cx = Ctx::new();
    let f = cx.build(lhs);
    let vars: Vec<Id> = wrt.iter().map(|w| cx.v(w)).collect();
    let gr = grad(&mut cx.g, f, &vars);
    assert_eq!(gr.len(), wrt.len());
    for e in [env(), env2()] {
        for ((w, want), &gi) in wrt.iter().zip(rhs).zip(&gr) {
            let got = cx.eval(gi, &e);
            assert_close(got, value(want, &e), 1e-13, &format!("d({lhs})/d{w} vs {want}"));
            let h = 1e-5;
            let at = |v: f64| value(lhs, &with(&e, w, v));
            let fd = (at(e[*w] + h) - at(e[*w] - h)) / (2.0 * h);
            assert_close(got, fd, 1e-8, &format!("d({lhs})/d{w} vs central difference"));
        }
    }
}

macro_rules! grads {
    ($($name:ident: $lhs:expr, [$($w:expr),*] => [$($rhs:expr),*];)*) => {$(
        #[test]
        fn $name() {
            check_grad($lhs, &[$($w),*], &[$($rhs),*]);
        }
    )*};
}

mod gradient {
    use super::*;

    grads! {
        var:          "x", ["x", "y"] => ["1", "0"];
        sum:          "(+ x y)", ["x", "y"] => ["1", "1"];
        difference:   "(- x y)", ["x", "y"] => ["1", "-1"];
        negation:     "(neg (* x y))", ["x", "y"] => ["(neg y)", "(neg x)"];
        product:      "(* x y)", ["x", "y"] => ["y", "x"];
        square:       "(* x x)", ["x"] => ["(* 2 x)"];
        polynomial:   "(sum (* x (* x y)) (* 3 (* x z)) (neg (* y (* y y))) 2)", ["x", "y", "z"]
                      => ["(+ (* 2 (* x y)) (* 3 z))", "(- (* x x) (* 3 (* y y)))", "(* 3 x)"];
        shared:       "(* (+ x y) (+ x y))", ["x", "y"] => ["(* 2 (+ x y))", "(* 2 (+ x y))"];
        with_params:  "(+ (* p (* x x)) (* q y))", ["x", "y"] => ["(* 2 (* p x))", "q"];
        sin:          "(sin (* x y))", ["x", "y"] => ["(* y (cos (* x y)))", "(* x (cos (* x y)))"];
        cos:          "(* (cos x) z)", ["x", "y", "z"] => ["(neg (* z (sin x)))", "0", "(cos x)"];
        sin_minus_cos: "(- (sin x) (cos y))", ["x", "y"] => ["(cos x)", "(sin y)"];
        nested:       "(cos (sin (* x x)))", ["x"] => ["(neg (* (sin (sin (* x x))) (* (cos (* x x)) (* 2 x))))"];
        trig_product: "(* (sin x) (cos (* 2 y)))", ["x", "y"]
                      => ["(* (cos x) (cos (* 2 y)))", "(neg (* 2 (* (sin x) (sin (* 2 y)))))"];
        through_rates: "(* xd (sin x))", ["xd", "x"] => ["(sin x)", "(* xd (cos x))"];
        quotient:     "(/ x y)", ["x", "y"] => ["(/ 1 y)", "(neg (/ x (* y y)))"];
        quotient_sin: "(/ (sin x) (+ 3 (* y y)))", ["x", "y"]
                      => ["(/ (cos x) (+ 3 (* y y)))", "(neg (/ (* 2 (* y (sin x))) (* (+ 3 (* y y)) (+ 3 (* y y)))))"];
        quotient_param: "(/ p (* x z))", ["x", "z"] => ["(neg (/ p (* (* x x) z)))", "(neg (/ p (* x (* z z))))"];
    }

    /// With respect to variables the root does not depend on, the gradient is
    /// exactly the zero node, whether or not it depends on the others.
    #[test]
    fn independent_is_exact_zero() {
        let mut cx = Ctx::new();
        let zero = cx.g.zero();
        let f = cx.build("(* (sin x) (+ y p))");
        let (x, y, z, a) = (cx.v("x"), cx.v("y"), cx.v("z"), cx.v("a"));
        assert_eq!(grad(&mut cx.g, f, &[z, a]), vec![zero, zero]);
        let gr = grad(&mut cx.g, f, &[z, x, a, y]);
        assert_eq!(gr[0], zero);
        assert_eq!(gr[2], zero);
        assert_ne!(gr[1], zero);
        assert_ne!(gr[3], zero);
        // A constant root and a parameter-only root.
        let k = cx.build("(* p (cos q))");
        assert_eq!(grad(&mut cx.g, k, &[x, y]), vec![zero, zero]);
        let c = cx.g.constant(3.0);
        assert_eq!(grad(&mut cx.g, c, &[x]), vec![zero]);
    }

    /// Parameters are never differentiated: a gradient with respect to one is
    /// zero (documented on `Var::bit`).
    #[test]
    fn wrt_param_is_zero() {
        let mut cx = Ctx::new();
        let f = cx.build("(* p x)");
        let p = cx.v("p");
        let zero = cx.g.zero();
        assert_eq!(grad(&mut cx.g, f, &[p]), vec![zero]);
    }

    /// The gradient of a linear form returns its coefficients, as nodes.
    #[test]
    fn linear_form_returns_coefficients() {
        let mut cx = Ctx::new();
        let f = cx.build("(sum (* p x) (* y q) (* 3 z) (neg (* 2 a)) (- b (* (cos p) c)))");
        let wrt = ["x", "y", "z", "a", "b", "c"].map(|w| cx.v(w));
        let gr = grad(&mut cx.g, f, &wrt);
        let want = ["p", "q", "3", "-2", "1", "(neg (cos p))"];
        for (w, (&gi, want)) in ["x", "y", "z", "a", "b", "c"].iter().zip(gr.iter().zip(want)) {
            assert_eq!(cx.show(gi), shape(want), "coefficient of {w}");
        }
        assert_eq!(gr[0], cx.v("p"));
        assert_eq!(gr[1], cx.v("q"));
    }

    /// Closed forms as nodes: `∂(xy)/∂x` is `y` itself; the root's own gradient is 1.
    #[test]
    fn closed_form_nodes() {
        let mut cx = Ctx::new();
        let (x, y) = (cx.v("x"), cx.v("y"));
        let f = cx.build("(* x y)");
        assert_eq!(grad(&mut cx.g, f, &[x, y]), vec![y, x]);
        let one = cx.g.constant(1.0);
        assert_eq!(grad(&mut cx.g, x, &[x, y]), vec![one, cx.g.zero()]);
        let s = cx.build("(sin x)");
        let gs = grad(&mut cx.g, s, &[x]);
        assert_eq!(cx.show(gs[0]), "(cos x)");
        let sq = cx.build("(* x x)");
        let gq = grad(&mut cx.g, sq, &[x]);
        assert_eq!(cx.show(gq[0]), "(* 2 x)");
    }

    /// The Jacobian as the velocity gradient of a time derivative: `Φ̇ = Φ_q q̇`,
    /// so `∂Φ̇/∂q̇ = ∂Φ/∂q`, node for node.
    #[test]
    fn jacobian_from_rate() {
        let mut cx = Ctx::new();
        let f = cx.build("(+ (* x (sin y)) (* 3 z))");
        let d = cx.dt(f);
        let rates = ["xd", "yd", "zd"].map(|w| cx.v(w));
        let coords = ["x", "y", "z"].map(|w| cx.v(w));
        let j1 = grad(&mut cx.g, d, &rates);
        let j2 = grad(&mut cx.g, f, &coords);
        assert_eq!(
            j1,
            j2,
            "{:?} vs {:?}",
            j1.iter().map(|&i| cx.show(i)).collect::<Vec<_>>(),
            j2.iter().map(|&i| cx.show(i)).collect::<Vec<_>>()
        );
    }
}

// ---------------------------------------------------------------------------
// 4. Kinematics: the rotation matrix and the ω rule
// ---------------------------------------------------------------------------

/// `A(p) = (e0² − eᵀe) I + 2 e eᵀ + 2 e0 ẽ`, in plain `f64`.
fn rotation_reference(p: [f64; 4]) -> [[f64; 3]; 3] {
    let [e0, e1, e2, e3] = p;
    let e = [e1, e2, e3];
    let ete = e1 * e1 + e2 * e2 + e3 * e3;
    // ẽ: ẽ a = e × a.
    let tilde = [[0.0, -e3, e2], [e3, 0.0, -e1], [-e2, e1, 0.0]];
    let mut a = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            let id = if i == j { 1.0 } else { 0.0 };
            a[i][j] = (e0 * e0 - ete) * id + 2.0 * e[i] * e[j] + 2.0 * e0 * tilde[i][j];
        }
    }
    a
}

fn cross3(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

/// Values of variable nodes, for evaluating graphs not built by [`Ctx`].
struct EvalMap(HashMap<VarId, f64>);

fn eval_ids(g: &Graph, values: &[(Id, f64)]) -> EvalMap {
    EvalMap(values.iter().map(|&(id, v)| (g.as_var(id).expect("a variable"), v)).collect())
}

impl EvalMap {
    /// `Graph::eval` computes every node up to `id`, so inputs without a value
    /// read as NaN; a result that depends on one comes out NaN and fails.
    fn at(&self, g: &Graph, id: Id) -> f64 {
        let x = g.eval(id, &|v| self.0.get(&v).copied().unwrap_or(f64::NAN));
        assert!(!x.is_nan(), "node {id:?} depends on an input without a value");
        x
    }
}

mod kinematic {
    use super::*;

    const P_NON_UNIT: [f64; 4] = [0.9, -0.35, 0.6, 1.3];

    /// The rotation matrix built on the graph is exactly the formula of
    /// CONVENTIONS.md for a non-unit `p` (and a unit one).
    #[test]
    fn rotation_matrix_matches_formula() {
        let norm = P_NON_UNIT.iter().map(|v| v * v).sum::<f64>().sqrt();
        for p in [P_NON_UNIT, P_NON_UNIT.map(|v| v / norm), [1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 2.0]] {
            let mut g = Graph::new();
            let vars = [0, 1, 2, 3].map(|i| g.state(format!("e{i}")));
            let a = kinematics::rotation_matrix(&mut g, vars, "a");
            let values: Vec<(Id, f64)> = vars.iter().copied().zip(p).collect();
            let ev = eval_ids(&g, &values);
            let want = rotation_reference(p);
            for i in 0..3 {
                for j in 0..3 {
                    assert_close(ev.at(&g, a[i][j]), want[i][j], 1e-14, &format!("A[{i}][{j}] at {p:?}"));
                }
            }
        }
    }

    /// `A(p) A(p)ᵀ = |p|⁴ I` for any `p`: the quadratic is a scaled rotation.
    #[test]
    fn rotation_matrix_scaled_orthogonal() {
        let mut g = Graph::new();
        let vars = [0, 1, 2, 3].map(|i| g.param(format!("e{i}")));
        let a = kinematics::rotation_matrix(&mut g, vars, "a");
        let values: Vec<(Id, f64)> = vars.iter().copied().zip(P_NON_UNIT).collect();
        let ev = eval_ids(&g, &values);
        let n2: f64 = P_NON_UNIT.iter().map(|v| v * v).sum();
        for i in 0..3 {
            for j in 0..3 {
                let aat: f64 = (0..3).map(|k| ev.at(&g, a[i][k]) * ev.at(&g, a[j][k])).sum();
                let want = if i == j { n2 * n2 } else { 0.0 };
                assert_close(aat, want, 1e-13, &format!("(A Aᵀ)[{i}][{j}]"));
            }
        }
    }

    /// Under the ω rule of `omega_inertial`, `d/dt A[:, k] = ω × A[:, k]`; and
    /// that equals the structural derivative of `A(p)` along `ṗ = ½ Eᵀ ω` for a
    /// unit `p` (since `ω = 2 E ṗ`).
    #[test]
    fn omega_rule_on_columns() {
        let mut k = Kinematics::new(Formulation::OmegaInertial, Ground::None);
        // Columns: r1 (3), p1 (4), r2 (3), p2 (4); velocities: ṙ1, ω1, ṙ2, ω2.
        assert_eq!(k.coords.len(), 14);
        assert_eq!(k.velocities.len(), 12);
        let norm = P_NON_UNIT.iter().map(|v| v * v).sum::<f64>().sqrt();
        let p_unit = P_NON_UNIT.map(|v| v / norm);
        let omega = [0.7, -1.2, 0.45];
        for body in 0..2 {
            let p: [Id; 4] = std::array::from_fn(|i| k.coords[7 * body + 3 + i]);
            let w: [Id; 3] = std::array::from_fn(|i| k.velocities[6 * body + 3 + i]);
            let len = k.g.len();
            // Hash-consing: rebuilding A(p) finds the nodes the formulation made
            // (and the rules registered on them).
            let a = kinematics::rotation_matrix(&mut k.g, p, "again");
            assert_eq!(k.g.len(), len, "rebuilding A(p{}) added nodes", body + 1);
            let mut values: Vec<(Id, f64)> = p.iter().copied().zip(p_unit).collect();
            values.extend(w.iter().copied().zip(omega));
            let ev = eval_ids(&k.g, &values);
            for col in 0..3 {
                let c = [0, 1, 2].map(|row| ev.at(&k.g, a[row][col]));
                let want = cross3(omega, c);
                for row in 0..3 {
                    let d = k.rules.dt(&mut k.g, a[row][col]);
                    assert_close(ev.at(&k.g, d), want[row], 1e-14, &format!("body {body} dA[{row}][{col}]"));
                }
            }
        }

        // The same from Euler-parameter rates on a separate graph.
        let mut g = Graph::new();
        let p = [0, 1, 2, 3].map(|i| g.state(format!("e{i}")));
        let pd = [0, 1, 2, 3].map(|i| g.state(format!("ed{i}")));
        let mut rules = TimeRules::new();
        for i in 0..4 {
            rules.set_var(&g, p[i], pd[i]);
        }
        let a = kinematics::rotation_matrix(&mut g, p, "a");
        let [e0, e1, e2, e3] = p_unit;
        let e = [e1, e2, e3];
        // ṗ = ½ Eᵀ ω with E = [−e, ẽ + e0 I]: ṗ0 = −½ e·ω, ė = ½ (e0 ω − e × ω).
        let exw = cross3(e, omega);
        let pdot = [
            -0.5 * (e1 * omega[0] + e2 * omega[1] + e3 * omega[2]),
            0.5 * (e0 * omega[0] - exw[0]),
            0.5 * (e0 * omega[1] - exw[1]),
            0.5 * (e0 * omega[2] - exw[2]),
        ];
        let mut values: Vec<(Id, f64)> = p.iter().copied().zip(p_unit).collect();
        values.extend(pd.iter().copied().zip(pdot));
        let ev = eval_ids(&g, &values);
        let a_ref = rotation_reference(p_unit);
        for col in 0..3 {
            let c = [0, 1, 2].map(|row| a_ref[row][col]);
            let want = cross3(omega, c);
            for row in 0..3 {
                let d = rules.dt(&mut g, a[row][col]);
                assert_close(ev.at(&g, d), want[row], 1e-14, &format!("structural dA[{row}][{col}]"));
            }
        }
    }

    /// `euler`: the rule registered for a rotated vector `u = A(p) a'` is the
    /// exact derivative along `p + t ṗ` for a non-unit `p`, and so is its own
    /// derivative. Since `A` is quadratic, `u̇ = (A(p + ṗ) − A(p − ṗ)) a' / 2` and
    /// `ü = 2 A(ṗ) a'` exactly; the structural derivative must agree too.
    #[test]
    fn euler_rule_on_rotated_vector() {
        let mut k = Kinematics::new(Formulation::Euler, Ground::None);
        // Columns: r1 (3), p1 (4), r2 (3), p2 (4), and their rates.
        assert_eq!(k.coords.len(), 14);
        assert_eq!(k.velocities.len(), 14);
        let a = [0, 1, 2].map(|i| k.g.param(format!("ap{i}")));
        let (a_val, pd_val) = ([0.4, -1.1, 0.8], [0.3, -0.2, 0.5, 0.15]);
        for body in 0..2 {
            let u = k.rotate(body, a, "u");
            let p: [Id; 4] = std::array::from_fn(|i| k.coords[7 * body + 3 + i]);
            let pd: [Id; 4] = std::array::from_fn(|i| k.velocities[7 * body + 3 + i]);
            let mut structural = TimeRules::new();
            for i in 0..4 {
                structural.set_var(&k.g, p[i], pd[i]);
            }
            let mut values: Vec<(Id, f64)> = p.iter().copied().zip(P_NON_UNIT).collect();
            values.extend(pd.iter().copied().zip(pd_val));
            values.extend(a.iter().copied().zip(a_val));
            let plus = rotation_reference(std::array::from_fn(|i| P_NON_UNIT[i] + pd_val[i]));
            let minus = rotation_reference(std::array::from_fn(|i| P_NON_UNIT[i] - pd_val[i]));
            let a_pd = rotation_reference(pd_val);
            for j in 0..3 {
                let d_rule = k.rules.dt(&mut k.g, u[j]);
                let dd_rule = k.rules.dt(&mut k.g, d_rule);
                let d_struct = structural.dt(&mut k.g, u[j]);
                let dd_struct = structural.dt(&mut k.g, d_struct);
                let ev = eval_ids(&k.g, &values);
                let udot: f64 = (0..3).map(|c| (plus[j][c] - minus[j][c]) * a_val[c]).sum::<f64>() / 2.0;
                let uddot: f64 = (0..3).map(|c| 2.0 * a_pd[j][c] * a_val[c]).sum();
                let what = format!("body {body} component {j}");
                assert_close(ev.at(&k.g, d_rule), udot, 1e-13, &format!("{what}: rule u̇"));
                assert_close(ev.at(&k.g, d_struct), udot, 1e-13, &format!("{what}: structural u̇"));
                assert_close(ev.at(&k.g, dd_rule), uddot, 1e-13, &format!("{what}: rule ü"));
                assert_close(ev.at(&k.g, dd_struct), uddot, 1e-13, &format!("{what}: structural ü"));
            }
        }
    }
}

// ---------------------------------------------------------------------------
// 5. Emission
// ---------------------------------------------------------------------------

fn f64_scalar() -> ScalarTy {
    ScalarTy { ty: quote!(f64), krate: quote!(::joint_runtime), concrete_f64: true }
}

/// Tokens as a string with single spaces.
fn text(t: &TokenStream) -> String {
    t.to_string().split_whitespace().collect::<Vec<_>>().join(" ")
}

/// The `let` statements of a body that bind nodes (not the constant prologue,
/// whose bindings carry a type).
fn node_lets(out: &Emitted) -> Vec<String> {
    let body = text(&out.body);
    body.split(';')
        .map(str::trim)
        .filter(|s| s.starts_with("let ") && !s.contains(": f64"))
        .map(str::to_string)
        .collect()
}

/// Runs the printed code: the body and outputs are parsed back from their
/// *strings* with `syn` (so Rust's own precedence decides the grouping) and
/// evaluated in `f64`.
fn run(out: &Emitted, e: &Env) -> Vec<f64> {
    let outputs: Vec<String> = out.outputs.iter().map(|o| o.to_string()).collect();
    let src = format!("{{ {} ({},) }}", out.body, outputs.join(", "));
    let block: syn::Block =
        syn::parse_str(&src).unwrap_or_else(|err| panic!("emitted code does not parse: {err}: {src}"));
    let mut scope = e.clone();
    for stmt in &block.stmts {
        match stmt {
            syn::Stmt::Local(local) => {
                let name = match &local.pat {
                    syn::Pat::Ident(p) => p.ident.to_string(),
                    syn::Pat::Type(t) => match &*t.pat {
                        syn::Pat::Ident(p) => p.ident.to_string(),
                        other => panic!("pattern {}", quote!(#other)),
                    },
                    other => panic!("pattern {}", quote!(#other)),
                };
                let init = local.init.as_ref().expect("let without a value");
                let v = run_expr(&init.expr, &scope);
                assert!(!scope.contains_key(&name), "{name} bound twice in {src}");
                scope.insert(name, v);
            }
            syn::Stmt::Expr(syn::Expr::Tuple(t), None) => return t.elems.iter().map(|x| run_expr(x, &scope)).collect(),
            other => panic!("unexpected statement {}", quote!(#other)),
        }
    }
    panic!("no outputs in {src}")
}

fn run_expr(x: &syn::Expr, scope: &Env) -> f64 {
    match x {
        syn::Expr::Binary(b) => {
            let (l, r) = (run_expr(&b.left, scope), run_expr(&b.right, scope));
            match b.op {
                syn::BinOp::Add(_) => l + r,
                syn::BinOp::Sub(_) => l - r,
                syn::BinOp::Mul(_) => l * r,
                syn::BinOp::Div(_) => l / r,
                _ => panic!("operator {}", quote!(#x)),
            }
        }
        syn::Expr::Unary(u) if matches!(u.op, syn::UnOp::Neg(_)) => -run_expr(&u.expr, scope),
        syn::Expr::Paren(p) => run_expr(&p.expr, scope),
        syn::Expr::Group(g) => run_expr(&g.expr, scope),
        syn::Expr::Path(p) => {
            let name = p.path.get_ident().unwrap_or_else(|| panic!("path {}", quote!(#x))).to_string();
            *scope.get(&name).unwrap_or_else(|| panic!("{name} is not bound"))
        }
        syn::Expr::Lit(l) => match &l.lit {
            syn::Lit::Float(f) => f.base10_digits().parse().unwrap(),
            syn::Lit::Int(i) if i.suffix() == "f64" => i.base10_digits().parse().unwrap(),
            _ => panic!("literal {}", quote!(#x)),
        },
        syn::Expr::Call(c) => {
            let syn::Expr::Path(f) = &*c.func else { panic!("call {}", quote!(#x)) };
            assert_eq!(c.args.len(), 1);
            let arg = run_expr(&c.args[0], scope);
            match f.path.segments.last().unwrap().ident.to_string().as_str() {
                "simd_sin" => arg.sin(),
                "simd_cos" => arg.cos(),
                other => panic!("function {other}"),
            }
        }
        _ => panic!("unexpected expression {}", quote!(#x)),
    }
}

/// `src` emits with `ops` operations and `lets` node bindings, optionally prints
/// as `prints`, and the printed code gives the graph's value bit for bit.
#[track_caller]
fn check_emit(src: &str, ops: usize, lets: usize, prints: Option<&str>) {
    let mut cx = Ctx::new();
    let id = cx.build(src);
    let out = emit(&cx.g, &[id], &f64_scalar());
    let printed = text(&out.outputs[0]);
    assert_eq!(out.ops, ops, "ops of {src} (built as {}, printed {printed})", cx.show(id));
    assert_eq!(node_lets(&out).len(), lets, "lets of {src}: {:?}", node_lets(&out));
    if let Some(p) = prints {
        assert_eq!(printed, p, "{src} (built as {})", cx.show(id));
    }
    for e in [env(), env2()] {
        let got = run(&out, &e)[0];
        let want = cx.eval(id, &e);
        assert_eq!(got.to_bits(), want.to_bits(), "{src}: printed code gives {got:e}, graph {want:e}");
    }
}

macro_rules! emits {
    ($($name:ident: $src:expr => ops $ops:expr, lets $lets:expr $(, prints $p:expr)?;)*) => {$(
        #[test]
        fn $name() {
            check_emit($src, $ops, $lets, None $(.or(Some($p)))?);
        }
    )*};
}

mod emission {
    use super::*;

    emits! {
        var:              "x" => ops 0, lets 0, prints "x";
        add:              "(+ a b)" => ops 1, lets 0, prints "a + b";
        sub_nested_right: "(- a (- b c))" => ops 2, lets 0, prints "a - (b - c)";
        sub_nested_left:  "(- (- a b) c)" => ops 2, lets 0, prints "a - b - c";
        sub_of_sum:       "(- a (+ b c))" => ops 2, lets 0, prints "a - (b + c)";
        sub_of_product:   "(- a (* b c))" => ops 2, lets 0, prints "a - b * c";
        add_nested_right: "(+ a (+ b c))" => ops 2, lets 0;
        add_nested_left:  "(+ (+ a b) c)" => ops 2, lets 0;
        mul_nested_right: "(* a (* b c))" => ops 2, lets 0;
        mul_nested_left:  "(* (* a b) c)" => ops 2, lets 0;
        mul_of_sum:       "(* (+ a b) c)" => ops 2, lets 0;
        mul_of_difference: "(* (- a b) (- c x))" => ops 3, lets 0;
        sum_of_products:  "(+ (* a b) (* b c))" => ops 3, lets 0;
        neg_of_var:       "(neg a)" => ops 0, lets 0;
        neg_of_product:   "(neg (* a b))" => ops 1, lets 0;
        neg_of_sub:       "(neg (- a b))" => ops 1, lets 0;
        neg_in_sum:       "(+ c (neg (* a b)))" => ops 2, lets 0;
        constant:         "(* 2 x)" => ops 1, lets 0;
        neg_constant:     "(+ -2 x)" => ops 1, lets 0;
        sub_neg_constant: "(- x -2)" => ops 1, lets 0;
        neg_constant_sub: "(- -2 x)" => ops 1, lets 0;
        mul_neg_constant: "(* (- a b) -0.5)" => ops 2, lets 0;
        neg_of_sum_times: "(* (neg (+ a b)) (- c x))" => ops 3, lets 0;
        neg_shared:       "(+ (* c (neg (* a b))) (* x (neg (* a b))))" => ops 4, lets 1;
        sin:              "(sin (+ a b))" => ops 1, lets 0;
        polynomial:       "(sum (* x (* x y)) (* 3 (* x z)) (neg (* y (* y y))) 2)" => ops 9, lets 0;
        shared_product:   "(+ (* a b) (* (* a b) c))" => ops 3, lets 1;
        shared_sum:       "(* (+ a b) (+ a b))" => ops 2, lets 1;
        shared_scaled:    "(- (* (* 2 x) y) (* (* 2 x) z))" => ops 4, lets 1;
        shared_sin:       "(+ (* a (sin x)) (* b (sin x)))" => ops 3, lets 1;
        shared_deep:      "(* (sin (* a b)) (cos (* a b)))" => ops 2, lets 1;
        two_shared:       "(+ (* (+ a b) (+ a b)) (* (- c x) (- c x)))" => ops 5, lets 2;
        div:              "(/ a b)" => ops 1, lets 0, prints "a / b";
        div_nested_right: "(/ a (/ b c))" => ops 2, lets 0, prints "a / (b / c)";
        div_nested_left:  "(/ (/ a b) c)" => ops 2, lets 0, prints "a / b / c";
        div_of_product:   "(/ a (* b c))" => ops 2, lets 0, prints "a / (b * c)";
        div_of_sum:       "(/ (+ a b) (- c x))" => ops 3, lets 0, prints "(a + b) / (c - x)";
        mul_of_quotient:  "(* a (/ b c))" => ops 2, lets 0;
        neg_of_quotient:  "(neg (/ (+ a b) c))" => ops 2, lets 0;
        shared_quotient:  "(+ (/ a b) (* c (/ a b)))" => ops 3, lets 1;
    }

    /// The grouping that changes a rounded result is the graph's: for values
    /// where `a (b c)` and `(a b) c` differ in `f64`, the printed code gives the
    /// graph's bits (and likewise for `+`; for `−` the grouping changes the
    /// exact value, see `sub_nested_right`).
    #[test]
    fn association_preserved() {
        let mut e = env();
        e.insert("a".into(), 0.1);
        e.insert("b".into(), 0.7);
        e.insert("c".into(), 0.3);
        let (a, b, c) = (0.1_f64, 0.7_f64, 0.3_f64);
        assert_ne!((a * (b * c)).to_bits(), ((a * b) * c).to_bits(), "values do not separate the groupings");
        let (a2, b2, c2) = (0.1_f64, 0.2_f64, 0.3_f64);
        assert_ne!((a2 + (b2 + c2)).to_bits(), ((a2 + b2) + c2).to_bits(), "values do not separate the groupings");
        let cases: [(&str, f64, &Env); 4] = [
            ("(* a (* b c))", a * (b * c), &e),
            ("(* (* a b) c)", (a * b) * c, &e),
            ("(+ a (+ b c))", a2 + (b2 + c2), &with(&with(&with(&e, "a", a2), "b", b2), "c", c2)),
            ("(+ (+ a b) c)", (a2 + b2) + c2, &with(&with(&with(&e, "a", a2), "b", b2), "c", c2)),
        ];
        for (src, want, env) in cases {
            let mut cx = Ctx::new();
            let id = cx.build(src);
            let out = emit(&cx.g, &[id], &f64_scalar());
            assert_eq!(cx.eval(id, env).to_bits(), want.to_bits(), "graph of {src}");
            assert_eq!(run(&out, env)[0].to_bits(), want.to_bits(), "{src} printed as {}", text(&out.outputs[0]));
        }
    }

    /// A node used more than once gets one `let`; nodes used once are inline.
    #[test]
    fn let_only_for_shared() {
        let mut cx = Ctx::new();
        let f = cx.build("(+ (* a b) (* (* a b) c))");
        let out = emit(&cx.g, &[f], &f64_scalar());
        assert_eq!(node_lets(&out), vec!["let t1 = a * b".to_string()]);
        let printed = text(&out.outputs[0]);
        assert_eq!(printed.matches("t1").count(), 2, "{printed}");
        assert!(!printed.contains("a * b"), "{printed}");
        assert_eq!(out.ops, 3);
    }

    /// Inputs and constants are never bound to a node `let`, however often used.
    #[test]
    fn atoms_not_bound() {
        let mut cx = Ctx::new();
        let f = cx.build("(+ (* 3 (* a b)) (* 3 (* a c)))");
        let out = emit(&cx.g, &[f], &f64_scalar());
        assert!(node_lets(&out).is_empty(), "{:?}", node_lets(&out));
        assert_eq!(out.ops, 5);
        assert_eq!(run(&out, &env())[0], cx.eval(f, &env()));
    }

    /// A negation is never bound; when it is shared, its operand is.
    #[test]
    fn negation_not_bound() {
        let mut cx = Ctx::new();
        let n = cx.build("(neg (* a b))");
        let s = cx.build("(sin (neg (* a b)))");
        let out = emit(&cx.g, &[n, s], &f64_scalar());
        assert_eq!(node_lets(&out), vec!["let t1 = a * b".to_string()]);
        let e = env();
        assert_eq!(run(&out, &e), vec![cx.eval(n, &e), cx.eval(s, &e)]);
    }

    /// A hint names the binding; the first hint wins; a second node with the
    /// same name gets a suffix.
    #[test]
    fn hints_name_lets() {
        let mut cx = Ctx::new();
        let ab = cx.build("(* a b)");
        let bc = cx.build("(* b c)");
        cx.g.hint(ab, "prod");
        cx.g.hint(bc, "prod");
        cx.g.hint(ab, "ignored");
        let f = cx.build("(sum (* a b) (* c (* a b)) (* b c) (* x (* b c)))");
        let out = emit(&cx.g, &[f], &f64_scalar());
        assert_eq!(node_lets(&out), vec!["let prod = a * b".to_string(), "let prod_2 = b * c".to_string()]);
        assert_eq!(run(&out, &env())[0], cx.eval(f, &env()));
    }

    /// Constants are bound once per magnitude in the prologue, as `f64`
    /// literals for a concrete `f64` and converted otherwise.
    #[test]
    fn constants_prologue() {
        let mut cx = Ctx::new();
        let f = cx.build("(- (+ -2 x) (* 2 y))");
        let out = emit(&cx.g, &[f], &f64_scalar());
        let body = text(&out.body);
        assert_eq!(body.matches("let two : f64 = 2f64").count(), 1, "{body}");
        assert_eq!(body.matches("let").count(), 1, "{body}");
        for e in [env(), env2()] {
            assert_eq!(run(&out, &e)[0].to_bits(), cx.eval(f, &e).to_bits());
        }
        let generic = ScalarTy { ty: quote!(T), krate: quote!(::joint_runtime), concrete_f64: false };
        let out = emit(&cx.g, &[f], &generic);
        let body = text(&out.body);
        assert!(
            body.contains("let two : T = :: joint_runtime :: __private :: convert :: < f64 , T > (2f64)"),
            "{body}"
        );
    }

    /// Only reachable nodes are emitted, and only the variables they read are
    /// reported.
    #[test]
    fn reachable_and_used_vars() {
        let mut cx = Ctx::new();
        let dead = cx.build("(* (sin z) (+ a b))");
        let f = cx.build("(+ (* x y) p)");
        let live = reachable(&cx.g, &[f]);
        assert!(!live.contains(&dead));
        let xy = cx.build("(* x y)");
        let mut want = vec![cx.v("x"), cx.v("y"), cx.v("p"), xy, f];
        want.sort();
        assert_eq!(live, want);
        let out = emit(&cx.g, &[f], &f64_scalar());
        let used: Vec<VarId> = out.used_vars.iter().copied().collect();
        let mut want_vars: Vec<VarId> = ["x", "y", "p"].iter().map(|n| cx.g.as_var(cx.v(n)).unwrap()).collect();
        want_vars.sort();
        assert_eq!(used, want_vars);
        assert_eq!(out.ops, 2);
    }

    /// Several outputs: an output that is also an operand of another is bound
    /// once and counted once.
    #[test]
    fn output_shared_with_operand() {
        let mut cx = Ctx::new();
        let ab = cx.build("(* a b)");
        let f = cx.build("(+ (* a b) c)");
        let out = emit(&cx.g, &[ab, f], &f64_scalar());
        assert_eq!(node_lets(&out), vec!["let t1 = a * b".to_string()]);
        assert_eq!(text(&out.outputs[0]), "t1");
        assert_eq!(out.ops, 2);
        let e = env();
        assert_eq!(run(&out, &e), vec![cx.eval(ab, &e), cx.eval(f, &e)]);
    }

    /// A constant folded to a non-finite value (`1/0`, `0/0`) can be emitted:
    /// `Graph::div` folds constant operands without a check, and `emit` hands the
    /// value to `Literal::f64_suffixed`, which panics on infinities and NaN, so
    /// the derive would abort with "proc macro panicked" (a singularity measure of
    /// literal, parallel axes is `0/0`).
    #[test]
    fn non_finite_constant_emits() {
        let mut cx = Ctx::new();
        let k = cx.build("(/ 1 0)");
        assert_eq!(cx.g.as_const(k), Some(f64::INFINITY));
        let f = cx.build("(* (/ 1 0) x)");
        let emitted = std::panic::catch_unwind(|| text(&emit(&cx.g, &[f], &f64_scalar()).body));
        assert!(emitted.is_ok(), "emit panicked on the constant 1/0");
    }

    /// The names `emit` binds (constants `zero half one two four k_…`, and `t<n>`)
    /// are not kept apart from input names: an input called `two` or `t1` is
    /// shadowed by the prologue or by a binding, and the code computes something
    /// else. No formulation names an input this way today (inputs are `r1_x`,
    /// `p1_0`, `theta`, `length`, …), so this is latent.
    #[test]
    fn bindings_do_not_shadow_inputs() {
        let mut g = Graph::new();
        let two = g.param("two");
        let t1 = g.state("t1");
        let (a, b) = (g.state("a"), g.state("b"));
        let k = g.constant(2.0);
        let doubled = g.mul(k, two);
        let ab = g.mul(a, b);
        let s = g.add(ab, t1);
        let f = g.mul(s, ab);
        let outs = [doubled, f];
        let out = emit(&g, &outs, &f64_scalar());
        let e: Env =
            [("two", 5.0), ("t1", 0.25), ("a", 3.0), ("b", 7.0)].iter().map(|&(n, v)| (n.to_string(), v)).collect();
        let printed = std::panic::catch_unwind(|| run(&out, &e));
        let want: Vec<f64> = outs.iter().map(|&o| eval_in(&g, o, &e)).collect();
        assert_eq!(
            printed.ok(),
            Some(want),
            "{} ; {:?}",
            text(&out.body),
            out.outputs.iter().map(text).collect::<Vec<_>>()
        );
    }

    /// A value, its first and second time derivatives and a gradient emitted
    /// together (with shared subexpressions): the printed code gives the graph's
    /// bits for every output.
    #[test]
    fn derived_graph_runs() {
        let mut cx = Ctx::new();
        let f = cx.build("(- (* (sin (* 2 x)) (+ (* y z) (* p a))) (* (cos (* 2 x)) (- (* y a) (* q z))))");
        let d = cx.dt(f);
        let dd = cx.dt(d);
        let wrt = ["x", "y", "z", "a"].map(|w| cx.v(w));
        let mut outs = vec![f, d, dd];
        outs.extend(grad(&mut cx.g, d, &wrt));
        let out = emit(&cx.g, &outs, &f64_scalar());
        for e in [env(), env2()] {
            let got = run(&out, &e);
            for (k, (&o, v)) in outs.iter().zip(got).enumerate() {
                assert_eq!(v.to_bits(), cx.eval(o, &e).to_bits(), "output {k}");
            }
        }
        assert!(!node_lets(&out).is_empty());
    }
}

// ---------------------------------------------------------------------------
// 6. Random expressions: every rule at once
// ---------------------------------------------------------------------------

mod random {
    use super::*;

    /// xorshift64*: deterministic, no dependency.
    struct Rng(u64);

    impl Rng {
        fn next(&mut self) -> u64 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
        }

        fn below(&mut self, n: u64) -> u64 {
            self.next() % n
        }
    }

    const LEAVES: [&str; 14] = ["x", "y", "z", "a", "b", "p", "q", "0", "1", "-1", "2", "0.5", "-3", "x"];

    /// A random expression; divisions are by `1.5 + e²`, which stays away from 0,
    /// and subtrees are often repeated so that like terms and sharing occur.
    fn expr(rng: &mut Rng, depth: u32) -> String {
        if depth == 0 || rng.below(4) == 0 {
            return LEAVES[rng.below(LEAVES.len() as u64) as usize].to_string();
        }
        let l = expr(rng, depth - 1);
        let r = if rng.below(3) == 0 { l.clone() } else { expr(rng, depth - 1) };
        match rng.below(9) {
            0 | 1 => format!("(+ {l} {r})"),
            2 | 3 => format!("(- {l} {r})"),
            4 | 5 => format!("(* {l} {r})"),
            6 => format!("(/ {l} (+ 1.5 (* {r} {r})))"),
            7 => format!("(neg {l})"),
            _ => format!("({} {l})", if rng.below(2) == 0 { "sin" } else { "cos" }),
        }
    }

    /// Σ of the magnitudes met on the way: the size of the rounding errors a
    /// straight evaluation can make.
    fn scale(sx: &Sx, e: &Env) -> f64 {
        match sx {
            Sx::Atom(_) => interpret(sx, e).abs(),
            Sx::List(items) => {
                let args: Vec<f64> = items[1..].iter().map(|s| scale(s, e)).collect();
                let Sx::Atom(op) = &items[0] else { unreachable!() };
                match op.as_str() {
                    "+" | "-" => args[0] + args[1],
                    "*" => args[0] * args[1],
                    "/" => args[0] / 1.5 * (1.0 + args[1]),
                    "neg" => args[0],
                    _ => 1.0 + args[0],
                }
            }
        }
    }

    /// Whether `got` is the derivative at 0 of `f`, by central differences with
    /// their own truncation error estimated from two step sizes.
    fn derivative_ok(got: f64, f: impl Fn(f64) -> f64, sc: f64) -> bool {
        let central = |h: f64| (f(h) - f(-h)) / (2.0 * h);
        let (d1, d2) = (central(1e-4), central(5e-5));
        (got - d2).abs() <= 2.0 * (d1 - d2).abs() + 1e-7 * sc
    }

    #[test]
    fn random_expressions() {
        let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
        for case in 0..400 {
            let src = expr(&mut rng, 4);
            let sx = parse(&src);
            let mut cx = Ctx::new();
            let f = cx.build(&src);
            let len = cx.g.len();
            assert_eq!(cx.build(&src), f, "{src}: rebuilt differently");
            assert_eq!(cx.g.len(), len, "{src}: rebuilding added nodes");
            let d = cx.dt(f);
            let wrt = ["x", "y", "z", "a"].map(|w| cx.v(w));
            let gr = grad(&mut cx.g, f, &wrt);
            let mut outs = vec![f, d];
            outs.extend(&gr);
            let out = emit(&cx.g, &outs, &f64_scalar());
            for e in [env(), env2()] {
                let what = format!("case {case}: {src} (built as {})", cx.show(f));
                let sc = 1.0 + scale(&sx, &e);
                let v = cx.eval(f, &e);
                assert!((v - interpret(&sx, &e)).abs() <= 1e-12 * sc, "{what}: value {v} vs {}", interpret(&sx, &e));
                let dv = cx.eval(d, &e);
                assert!(derivative_ok(dv, |t| interpret(&sx, &along(&e, t)), sc), "{what}: d/dt {dv}");
                for (w, &gi) in ["x", "y", "z", "a"].iter().zip(&gr) {
                    let gv = cx.eval(gi, &e);
                    let at = |t: f64| interpret(&sx, &with(&e, w, e[*w] + t));
                    assert!(derivative_ok(gv, at, sc), "{what}: d/d{w} {gv}");
                }
                let printed = run(&out, &e);
                for (k, (&o, p)) in outs.iter().zip(printed).enumerate() {
                    assert_eq!(p, cx.eval(o, &e), "{what}: printed output {k}");
                }
            }
            // Exact zeros: derivatives of what does not move.
            if cx.g.mask(f) == 0 {
                assert_eq!(d, cx.g.zero(), "{src}: constant in time but d/dt is {}", cx.show(d));
            }
        }
    }
}
