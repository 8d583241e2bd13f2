//! Lowering: a checked declaration's rows onto the symbolic graph, and the
//! derivatives of every row (Φ_t, J, γ), checked. Printing comes after, in
//! the code generator; the front end never sees the graph.
//!
//! A parameter given as a number becomes a constant node (folded wherever it
//! meets another); one read from a field becomes a variable bound once to
//! `self.field`, shared by every joint of a scene that reads it; a number that
//! names constants (`-RA`) becomes a variable bound to
//! `{ let value: f64 = -RA; value }`, which the compiler folds. The checks
//! are the ones only the graph can make, each an error at the row's span: a
//! row that folds to a constant, a row that repeats another (or its negation),
//! and a row whose J depends on the velocities. A scene's joints are lowered
//! one after another onto one graph (`derive_scene`), then derived together.

use proc_macro2::Span;

use crate::engine::Id;
use crate::engine::emit;
use crate::engine::graph::Node;
use crate::front::attr::Number;
use crate::front::context::Errors;
use crate::front::joint::Declaration;
use crate::front::resolve::{FieldShape, Parameter, Source};
use crate::joints::{Expr, JointKind, Role, Row, VExpr};
use crate::kinematics::{self, Formulation, Ground, Kinematics, V3};

/// Everything derived for one declaration, before printing.
pub struct Derived {
    /// The kinematics and graph.
    pub kinematics: Kinematics,
    /// Φ rows.
    pub phi: Vec<Id>,
    /// Φ_t rows.
    pub phi_t: Vec<Id>,
    /// J, row-major.
    pub jacobian: Vec<Vec<Id>>,
    /// γ rows.
    pub gamma: Vec<Id>,
    /// Parameter nodes and what they are read from.
    pub bindings: Vec<Binding>,
    /// The singularity measure, for joints that have one.
    pub singularity: Option<Id>,
}

/// What a parameter node is read from at run time.
#[derive(Clone, PartialEq)]
pub enum Read {
    /// `self.member` (or `self.member.part` of an `AxisFrame`).
    Field {
        /// The field.
        member: syn::Ident,
        /// What it holds.
        shape: FieldShape,
        /// The `AxisFrame` part read (`axis`, `b`, `c`), or empty.
        part: &'static str,
    },
    /// A number naming constants (`-RA`), an `f64` the compiler folds.
    Constant(syn::Expr),
}

/// Parameter nodes bound to what they are read from.
pub struct Binding {
    /// The source.
    pub read: Read,
    /// One node per scalar read (three for a vector; value, rate and
    /// acceleration for a time function).
    pub nodes: Vec<Id>,
}

/// How parameter variables are named in generated code.
#[derive(Clone, Copy, PartialEq, Eq)]
pub enum Naming<'a> {
    /// By the joint's parameter name (`s_x`): one joint.
    ByParam,
    /// By the field read (`offset_x`): a scene, where joints share fields;
    /// constants by joint and parameter (`cardan_rho2_x`).
    ByField {
        /// The joint's name.
        joint: &'a str,
    },
}

/// Puts a joint's parameters on the graph: known numbers as constants, fields
/// and named constants as parameter variables (recorded in `bindings`; a field
/// bound before is reused). Returns each parameter's nodes by name.
pub fn param_nodes(
    k: &mut Kinematics,
    kind: &JointKind,
    params: &[Parameter],
    naming: Naming,
    bindings: &mut Vec<Binding>,
) -> Vec<(String, Vec<Id>)> {
    let mut values = Vec::new();
    for Parameter { name, source } in params {
        let role = kind.param(name).map(|p| p.role);
        let nodes = match source {
            Source::Const(numbers, _) => constant_nodes(k, name, numbers, naming, bindings),
            Source::Field { member, shape, .. } => field_nodes(k, name, role, member, *shape, naming, bindings),
        };
        values.push((name.clone(), nodes));
    }
    values
}

/// Known numbers as constants; each named one as a variable bound to its expression.
fn constant_nodes(
    k: &mut Kinematics,
    name: &str,
    numbers: &[Number],
    naming: Naming,
    bindings: &mut Vec<Binding>,
) -> Vec<Id> {
    let base = match naming {
        Naming::ByParam => name.to_string(),
        Naming::ByField { joint } => format!("{joint}_{name}"),
    };
    let components = ["x", "y", "z"];
    numbers
        .iter()
        .enumerate()
        .map(|(i, n)| match n {
            Number::Known(x) => k.g.constant(*x),
            Number::Named(expr) => {
                let var = if numbers.len() == 1 { base.clone() } else { format!("{base}_{}", components[i % 3]) };
                let node = k.g.param(var);
                bindings.push(Binding { read: Read::Constant(expr.clone()), nodes: vec![node] });
                node
            }
        })
        .collect()
}

/// A field's nodes: bound once, reused by every joint that reads it.
fn field_nodes(
    k: &mut Kinematics,
    name: &str,
    role: Option<Role>,
    member: &syn::Ident,
    shape: FieldShape,
    naming: Naming,
    bindings: &mut Vec<Binding>,
) -> Vec<Id> {
    let part = match shape {
        FieldShape::FramePart(part) => part.field(),
        _ => "",
    };
    let read = Read::Field { member: member.clone(), shape, part };
    if let Some(b) = bindings.iter().find(|b| b.read == read) {
        return b.nodes.clone();
    }
    let base = match naming {
        Naming::ByParam => name.to_string(),
        Naming::ByField { .. } if part.is_empty() => member.to_string(),
        Naming::ByField { .. } => format!("{member}_{part}"),
    };
    let nodes = match role {
        Some(Role::Time) => k.time_function(&base).to_vec(),
        Some(Role::Scalar) => vec![k.g.param(base)],
        _ => ["x", "y", "z"].iter().map(|c| k.g.param(format!("{base}_{c}"))).collect(),
    };
    bindings.push(Binding { read, nodes: nodes.clone() });
    nodes
}

/// A joint's rows on the graph.
pub struct LoweredRows {
    /// Φ, one node per scalar row.
    pub phi: Vec<Id>,
    /// Each row's span, for errors.
    pub spans: Vec<Span>,
    /// The singularity measure, for joints that have one.
    pub singularity: Option<Id>,
}

/// Lowers a joint's rows (and its singularity measure) onto the current pair
/// of frames of `k`.
pub fn lower_rows(
    k: &mut Kinematics,
    kind: &JointKind,
    values: &[(String, Vec<Id>)],
    row_spans: &[Span],
    kind_span: Span,
) -> LoweredRows {
    let mut phi = Vec::new();
    let mut spans: Vec<Span> = Vec::new();
    let mut lower = Lowering { k, values, kind };
    for (i, row) in kind.rows.iter().enumerate() {
        let span = row_spans.get(i).copied().unwrap_or(kind_span);
        let before = phi.len();
        match row {
            Row::Spherical => {
                let d = lower.separation();
                phi.extend(d);
            }
            Row::Scalar(e) => phi.push(lower.expr(e)),
            Row::Vector(v) => {
                let x = lower.vexpr(v);
                phi.extend(x);
            }
        }
        spans.extend(std::iter::repeat_n(span, phi.len() - before));
    }
    let singularity = kind.singularity.as_ref().map(|s| lower.expr(&s.measure));
    LoweredRows { phi, spans, singularity }
}

/// J (row-major), γ and Φ_t of a system's rows.
pub struct SystemDerivatives {
    /// J, row-major.
    pub jacobian: Vec<Vec<Id>>,
    /// γ rows.
    pub gamma: Vec<Id>,
    /// Φ_t rows.
    pub phi_t: Vec<Id>,
}

/// J, γ and Φ_t of every row, after the compile-time checks of the rows.
pub fn derive_all(k: &mut Kinematics, phi: &[Id], spans: &[Span]) -> syn::Result<SystemDerivatives> {
    check_rows(k, phi, spans)?;
    let mut out = SystemDerivatives { jacobian: Vec::new(), gamma: Vec::new(), phi_t: Vec::new() };
    let mut alternatives = Vec::new();
    let mut body = k.body_view();
    for (&row, &span) in phi.iter().zip(spans) {
        let d = k.derive_row(row, body.as_mut()).map_err(|m| syn::Error::new(span, m))?;
        out.jacobian.push(d.jacobian);
        out.gamma.push(d.gamma);
        alternatives.push(d.gamma_body);
        out.phi_t.push(d.phi_t);
    }
    choose_gammas(k, phi, &mut out, &alternatives);
    Ok(out)
}

/// Where rows' γ can be written two ways, keeps the set that costs the fused
/// evaluation (Φ, J and γ) fewest operations among: every row's body-frame
/// form, a row-by-row greedy choice, every row's inertial form; on a tie the
/// earlier, whose rounding follows the exact entries' degree in `p`.
fn choose_gammas(k: &Kinematics, phi: &[Id], out: &mut SystemDerivatives, alternatives: &[Option<Id>]) {
    let mut base = emit::OpCount::new(&k.g);
    base.add(phi);
    for row in &out.jacobian {
        base.add(row);
    }
    let cost = |gammas: &[Id]| base.clone().add(gammas);
    let inertial = out.gamma.clone();
    let body: Vec<Id> = inertial.iter().zip(alternatives).map(|(&g, a)| a.unwrap_or(g)).collect();
    let mut greedy = Vec::new();
    let mut so_far = base.clone();
    for (&g, alternative) in inertial.iter().zip(alternatives) {
        let pick = match *alternative {
            Some(b) if so_far.extra(&[b]) <= so_far.extra(&[g]) => b,
            _ => g,
        };
        so_far.add(&[pick]);
        greedy.push(pick);
    }
    let best = [body, greedy, inertial].into_iter().min_by_key(|gammas| cost(gammas));
    if let Some(best) = best {
        out.gamma = best;
    }
}

/// Builds Φ from the joint's primitives and derives the rest.
pub fn derive_rows(decl: &Declaration) -> syn::Result<Derived> {
    let first = derive_with(decl, true)?;
    if decl.formulation != Formulation::RelativeB2 {
        return Ok(first);
    }
    // Two ways to take dot-1 rows in `relative_b2` (B1 or B2 components): keep
    // the one whose fused evaluation needs fewer operations.
    let second = derive_with(decl, false)?;
    let cost = |d: &Derived| {
        let all: Vec<Id> = d.phi.iter().chain(d.jacobian.iter().flatten()).chain(&d.gamma).copied().collect();
        emit::count_ops(&d.kinematics.g, &all)
    };
    Ok(if cost(&second) < cost(&first) { second } else { first })
}

fn derive_with(decl: &Declaration, dot1_in_b2: bool) -> syn::Result<Derived> {
    let mut k = Kinematics::new(decl.formulation, decl.ground);
    k.dot1_in_b2 = dot1_in_b2;
    let mut bindings = Vec::new();
    let values = param_nodes(&mut k, &decl.kind, &decl.params, Naming::ByParam, &mut bindings);
    let LoweredRows { phi, spans, singularity } =
        lower_rows(&mut k, &decl.kind, &values, &decl.row_spans, decl.kind_span);
    let SystemDerivatives { jacobian, gamma, phi_t } = derive_all(&mut k, &phi, &spans)?;
    Ok(Derived { kinematics: k, phi, phi_t, jacobian, gamma, bindings, singularity })
}

/// Rows the engine can tell are wrong at compile time: a constant row, and a
/// row that repeats another (or its negation), which would make J lose rank.
fn check_rows(k: &Kinematics, phi: &[Id], spans: &[Span]) -> syn::Result<()> {
    let mut errors = Errors::new();
    for (j, &row) in phi.iter().enumerate() {
        if let Some(c) = k.g.as_const(row) {
            errors.at(
                spans[j],
                format!(
                    "this row is the constant {c}: it constrains nothing; expected a row that depends on the bodies"
                ),
            );
            continue;
        }
        let twin = (0..j).find(|&i| {
            let a = phi[i];
            a == row || k.g.node(row) == Node::Neg(a) || k.g.node(a) == Node::Neg(row)
        });
        if let Some(i) = twin {
            errors.at(
                spans[j],
                format!(
                    "row {} repeats row {} (the same constraint twice makes the Jacobian lose rank); remove one",
                    j + 1,
                    i + 1
                ),
            );
            errors.at(spans[i], format!("row {} is here", i + 1));
        }
    }
    errors.finish()
}

/// The number of rows and columns of a declaration, from its rows and
/// formulation alone (no derivation): for a stub after an error.
pub fn shape(decl: &Declaration) -> (usize, usize) {
    let rows = decl.kind.row_count();
    let per_body = if decl.formulation == Formulation::Euler { 7 } else { 6 };
    let cols = match (decl.formulation.is_relative(), decl.ground) {
        (true, _) => 6,
        (false, Ground::None) => 2 * per_body,
        (false, _) => per_body,
    };
    (rows, cols)
}

/// Lowers row expressions onto the graph.
struct Lowering<'a> {
    k: &'a mut Kinematics,
    values: &'a [(String, Vec<Id>)],
    kind: &'a JointKind,
}

impl Lowering<'_> {
    fn nodes(&self, name: &str) -> Vec<Id> {
        self.values.iter().find(|(n, _)| n == name).map(|(_, v)| v.clone()).unwrap_or_default()
    }

    fn v3(&mut self, name: &str) -> V3 {
        match self.nodes(name).as_slice() {
            [x, y, z] => [*x, *y, *z],
            // Absent points (relative formulations) are never read there.
            _ => [self.k.g.zero(); 3],
        }
    }

    fn body(&self, name: &str) -> usize {
        match self.kind.param(name).map(|p| p.role) {
            Some(Role::Axis(b) | Role::Point(b)) => b,
            _ => 0,
        }
    }

    fn separation(&mut self) -> V3 {
        let (r1, r2) = (self.v3("rho1"), self.v3("rho2"));
        self.k.separation(r1, r2)
    }

    fn axis(&mut self, name: &str) -> V3 {
        let (body, v) = (self.body(name), self.v3(name));
        self.k.rotate(body, v, &format!("{name}_n"))
    }

    fn expr(&mut self, e: &Expr) -> Id {
        match e {
            Expr::Num(x) => self.k.g.constant(*x),
            Expr::Scalar(n) | Expr::Time(n) => match self.nodes(n).first() {
                Some(&x) => x,
                None => self.k.g.zero(),
            },
            Expr::Dot1(a, b) => {
                let (va, vb) = (self.v3(a), self.v3(b));
                self.k.dot1(va, vb, [&format!("{a}_n"), &format!("{b}_n")])
            }
            Expr::Dot2(a) => {
                let (va, r1, r2) = (self.v3(a), self.v3("rho1"), self.v3("rho2"));
                self.k.dot2(va, r1, r2, &format!("{a}_n"))
            }
            Expr::Dot(a, b) => {
                let (u, w) = (self.vexpr(a), self.vexpr(b));
                kinematics::dot(&mut self.k.g, u, w)
            }
            Expr::Add(a, b) | Expr::Sub(a, b) | Expr::Mul(a, b) | Expr::Div(a, b) => {
                let (x, y) = (self.expr(a), self.expr(b));
                let g = &mut self.k.g;
                match e {
                    Expr::Add(..) => g.add(x, y),
                    Expr::Sub(..) => g.sub(x, y),
                    Expr::Mul(..) => g.mul(x, y),
                    _ => g.div(x, y),
                }
            }
            Expr::Neg(a) => {
                let x = self.expr(a);
                self.k.g.neg(x)
            }
            Expr::Sin(a) => {
                let x = self.expr(a);
                self.k.g.sin(x)
            }
            Expr::Cos(a) => {
                let x = self.expr(a);
                self.k.g.cos(x)
            }
        }
    }

    fn vexpr(&mut self, v: &VExpr) -> V3 {
        match v {
            VExpr::Axis(n) => self.axis(n),
            VExpr::Point(n) => {
                let (body, p) = (self.body(n), self.v3(n));
                let (r1, r2) = (self.v3("rho1"), self.v3("rho2"));
                self.k.point(body, p, [r1, r2], &format!("{n}_n"))
            }
            VExpr::Separation => self.separation(),
            VExpr::Local(n) => self.v3(n),
            VExpr::Add(a, b) | VExpr::Sub(a, b) | VExpr::Cross(a, b) => {
                let (x, y) = (self.vexpr(a), self.vexpr(b));
                let g = &mut self.k.g;
                match v {
                    VExpr::Add(..) => [0, 1, 2].map(|j| g.add(x[j], y[j])),
                    VExpr::Sub(..) => [0, 1, 2].map(|j| g.sub(x[j], y[j])),
                    _ => kinematics::cross(g, x, y),
                }
            }
            VExpr::Scale(s, a) => {
                let (c, x) = (self.expr(s), self.vexpr(a));
                x.map(|xj| self.k.g.mul(c, xj))
            }
            VExpr::Neg(a) => {
                let x = self.vexpr(a);
                x.map(|xj| self.k.g.neg(xj))
            }
        }
    }
}

/// A joint's block of rows in a scene.
pub struct Block {
    /// The joint's name.
    pub name: String,
    /// Its first row.
    pub start: usize,
    /// Its number of rows.
    pub rows: usize,
}

/// All joints of a scene on one graph over the bodies' frames, derived.
pub fn derive_scene(s: &crate::front::scene::SceneDecl) -> syn::Result<(Derived, Vec<Block>)> {
    // Names for generated code: `link_3` for `link[3]`.
    let names: Vec<String> = s.bodies.iter().map(|b| b.label().replace('[', "_").replace(']', "")).collect();
    let mut k = Kinematics::scene(Formulation::OmegaBody, &names);
    let mut bindings = Vec::new();
    let (mut phi, mut spans, mut blocks) = (Vec::new(), Vec::new(), Vec::new());
    for j in &s.joints {
        k.connect(j.bodies[0], j.bodies[1]);
        let prefix = j.prefix();
        let values = param_nodes(&mut k, j.kind, &j.params, Naming::ByField { joint: &prefix }, &mut bindings);
        let rows = lower_rows(&mut k, j.kind, &values, &[], j.kind_span);
        blocks.push(Block { name: j.label(), start: phi.len(), rows: rows.phi.len() });
        phi.extend(rows.phi);
        spans.extend(rows.spans);
    }
    let SystemDerivatives { jacobian, gamma, phi_t } = derive_all(&mut k, &phi, &spans)?;
    Ok((Derived { kinematics: k, phi, phi_t, jacobian, gamma, bindings, singularity: None }, blocks))
}
