//! The pipeline: declaration → rows over the graph → Φ, Φ_t, J, γ → Rust.

use proc_macro2::{Ident, Literal, Span, TokenStream};
use quote::{format_ident, quote};

use crate::dsl::{self, Declaration, FieldShape, ScalarKind, Source};
use crate::engine::Id;
use crate::engine::emit::{self, ScalarTy};
use crate::engine::graph::Node;
use crate::joints::{Expr, JointKind, Role, Row, VExpr};
use crate::kinematics::{self, Formulation, Ground, Kinematics, V3};

/// The derive's entry point: tokens in, tokens out; errors become
/// `compile_error!` beside a stub impl.
pub fn derive(input: &syn::DeriveInput) -> TokenStream {
    match dsl::parse(input) {
        Ok(decl) => match expand(&decl) {
            Ok(tokens) => tokens,
            Err(e) => crate::fallback::expand(input, e, Some(&decl)),
        },
        Err(failure) => crate::fallback::expand(input, failure.error, failure.partial.as_deref()),
    }
}

/// Everything derived for one declaration, before printing.
pub struct Derived {
    /// The kinematics and graph.
    pub k: Kinematics,
    /// Φ rows.
    pub phi: Vec<Id>,
    /// Φ_t rows.
    pub phi_t: Vec<Id>,
    /// J, row-major.
    pub jacobian: Vec<Vec<Id>>,
    /// γ rows.
    pub gamma: Vec<Id>,
    /// Parameter nodes bound from fields: (member, shape, sub-field, nodes).
    pub bindings: Vec<Binding>,
    /// The singularity measure, for joints that have one.
    pub singularity: Option<Id>,
}

/// A field bound as a parameter: (member, shape, sub-field, nodes).
pub type Binding = (syn::Ident, FieldShape, &'static str, Vec<Id>);

/// How parameter variables are named in generated code.
#[derive(Clone, Copy, PartialEq, Eq)]
pub enum Naming {
    /// By the joint's parameter name (`s_x`): one joint.
    ByParam,
    /// By the field read (`offset_x`): a scene, where joints share fields.
    ByField,
}

/// Puts a joint's parameters on the graph: constants as constants, fields as
/// parameter variables (recorded in `bindings`; a field bound before is reused).
pub fn param_nodes(
    k: &mut Kinematics,
    kind: &JointKind,
    params: &[(&'static str, Source)],
    naming: Naming,
    bindings: &mut Vec<Binding>,
) -> Vec<(&'static str, Vec<Id>)> {
    let mut values = Vec::new();
    for (name, source) in params {
        let nodes: Vec<Id> = match source {
            Source::Const(v, _) => v.iter().map(|&x| k.g.constant(x)).collect(),
            Source::Field { member, shape, .. } => {
                let sub = match shape {
                    FieldShape::FramePart(part) => part.field(),
                    _ => "",
                };
                if let Some((.., nodes)) =
                    bindings.iter().find(|(m, sh, sb, _)| m == member && sh == shape && *sb == sub)
                {
                    values.push((*name, nodes.clone()));
                    continue;
                }
                let base = match naming {
                    Naming::ByParam => name.to_string(),
                    Naming::ByField if sub.is_empty() => member.to_string(),
                    Naming::ByField => format!("{member}_{sub}"),
                };
                let n = match kind.param(name).map(|p| p.role) {
                    Some(Role::Time) => k.time_function(&base).to_vec(),
                    Some(Role::Scalar) => vec![k.g.param(base)],
                    _ => ["x", "y", "z"].iter().map(|c| k.g.param(format!("{base}_{c}"))).collect(),
                };
                bindings.push((member.clone(), *shape, sub, n.clone()));
                n
            }
        };
        values.push((name, nodes));
    }
    values
}

/// Lowers a joint's rows (and its singularity measure) onto the current pair
/// of frames of `k`; returns the rows and each row's span.
pub fn lower_rows(
    k: &mut Kinematics,
    kind: &JointKind,
    values: &[(&'static str, Vec<Id>)],
    row_spans: &[Span],
    kind_span: Span,
) -> (Vec<Id>, Vec<Span>, Option<Id>) {
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
    (phi, spans, singularity)
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
    let base: Vec<Id> = phi.iter().chain(out.jacobian.iter().flatten()).copied().collect();
    let cost = |gammas: &[Id]| emit::count_ops(&k.g, &[&base[..], gammas].concat());
    let inertial = out.gamma.clone();
    let body: Vec<Id> = inertial.iter().zip(alternatives).map(|(&g, a)| a.unwrap_or(g)).collect();
    let mut greedy = Vec::new();
    for (&g, alternative) in inertial.iter().zip(alternatives) {
        let pick = match *alternative {
            Some(b) if cost(&[&greedy[..], &[b]].concat()) <= cost(&[&greedy[..], &[g]].concat()) => b,
            _ => g,
        };
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
        emit::count_ops(&d.k.g, &all)
    };
    Ok(if cost(&second) < cost(&first) { second } else { first })
}

fn derive_with(decl: &Declaration, dot1_in_b2: bool) -> syn::Result<Derived> {
    let mut k = Kinematics::new(decl.formulation, decl.ground);
    k.dot1_in_b2 = dot1_in_b2;
    let mut bindings = Vec::new();
    let values = param_nodes(&mut k, decl.kind, &decl.params, Naming::ByParam, &mut bindings);
    let (phi, spans, singularity) = lower_rows(&mut k, decl.kind, &values, &decl.row_spans, decl.kind_span);
    let SystemDerivatives { jacobian, gamma, phi_t } = derive_all(&mut k, &phi, &spans)?;
    Ok(Derived { k, phi, phi_t, jacobian, gamma, bindings, singularity })
}

/// Rows the engine can tell are wrong at compile time: a constant row, and a
/// row that repeats another (or its negation), which would make J lose rank.
fn check_rows(k: &Kinematics, phi: &[Id], spans: &[Span]) -> syn::Result<()> {
    let mut errors = dsl::Errors::default();
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

fn expand(decl: &Declaration) -> syn::Result<TokenStream> {
    let derived = derive_rows(decl)?;
    Ok(print(decl, &derived))
}

/// The impl for a derived joint.
pub fn print(decl: &Declaration, d: &Derived) -> TokenStream {
    let krate = quote!(::joint_runtime);
    let (rows, cols) = (d.phi.len(), d.k.velocities.len());
    let (rows_lit, cols_lit) = (Literal::usize_unsuffixed(rows), Literal::usize_unsuffixed(cols));
    let (scalar, concrete) = match &decl.scalar {
        ScalarKind::Generic(t) => (quote!(#t), None),
        ScalarKind::Concrete(t) => (quote!(#t), Some(t.to_string())),
        ScalarKind::Any => (quote!(__JointScalar), None),
    };
    debug_assert_eq!(shape(decl), (rows, cols), "rows and columns from the declaration alone");
    let sty = ScalarTy { ty: scalar.clone(), krate: krate.clone(), concrete_f64: concrete.as_deref() == Some("f64") };

    let f = print_functions(d, &sty);
    let [phi_ops, phi_t_ops, jac_ops, gamma_ops, eval_ops] = f.ops;
    let [phi_ops_lit, phi_t_ops_lit, jac_ops_lit, gamma_ops_lit, eval_ops_lit] = f.ops.map(Literal::usize_unsuffixed);
    let (phi_body, phi_expr) = f.phi.clone();
    let (phi_t_body, phi_t_expr) = f.phi_t.clone();
    let (jac_body, jac_expr) = f.jacobian.clone();
    let (gamma_body, gamma_expr) = f.gamma.clone();
    let (eval_body, eval_expr) = f.evaluate.clone();
    let function = |outputs: &[Id]| f.emit(outputs);

    let kind = decl.kind.name;
    let variant = format_ident!("{}", decl.formulation.variant());
    let ident = &decl.ident;
    let (_, ty_generics, _) = decl.generics.split_for_impl();
    let touch_unused = decl.unused_fields.iter().map(|f| quote!(let _ = &self.#f;));
    let touch = quote!(#(#touch_unused)*);
    let head = impl_header(decl, rows, cols);
    let (impl_generics, _, where_clause) = head.generics.split_for_impl();
    let (impl_head, state_ty) = (&head.impl_head, &head.state_ty);
    let singularity_impl = match (d.singularity, &decl.kind.singularity) {
        (Some(node), Some(s)) => {
            let (body, out, ops) = function(&[node]);
            let out = &out[0];
            let zero_when = format!("Zero when {}.", s.zero_when);
            let doc = format!(" {ops} operations. {zero_when}");
            quote! {
                #[doc = #doc]
                #[allow(clippy::all, clippy::pedantic, unused_variables, non_snake_case)]
                #[deny(clippy::panic, clippy::unwrap_used, clippy::indexing_slicing)]
                impl #impl_generics #krate::Singularity<#scalar, #rows_lit, #cols_lit> for #ident #ty_generics #where_clause {
                    const ZERO_WHEN: &'static str = #zero_when;
                    #[inline]
                    fn singularity(&self, state: &Self::State) -> #scalar {
                        #touch #body #out
                    }
                }
            }
        }
        _ => TokenStream::new(),
    };
    let doc_ops = format!(
        " Operation counts (binary + − ×): phi {phi_ops}, phi_t {phi_t_ops}, jacobian {jac_ops}, gamma {gamma_ops}, evaluate {eval_ops}."
    );
    quote! {
        #[doc = #doc_ops]
        #[allow(clippy::all, clippy::pedantic, unused_variables, non_snake_case)]
        #[deny(clippy::panic, clippy::unwrap_used, clippy::indexing_slicing)]
        #impl_head {
            type State = #state_ty;
            const KIND: &'static str = #kind;
            const FORMULATION: #krate::Formulation = #krate::Formulation::#variant;
            const OPS: #krate::Ops = #krate::Ops {
                phi: #phi_ops_lit, phi_t: #phi_t_ops_lit, jacobian: #jac_ops_lit, gamma: #gamma_ops_lit, evaluate: #eval_ops_lit,
            };
            #[inline]
            fn phi(&self, state: &Self::State) -> #krate::__private::SVector<#scalar, #rows_lit> {
                #touch #phi_body #phi_expr
            }
            #[inline]
            fn phi_t(&self, state: &Self::State) -> #krate::__private::SVector<#scalar, #rows_lit> {
                #touch #phi_t_body #phi_t_expr
            }
            #[inline]
            fn jacobian(&self, state: &Self::State) -> #krate::__private::SMatrix<#scalar, #rows_lit, #cols_lit> {
                #touch #jac_body #jac_expr
            }
            #[inline]
            fn gamma(&self, state: &Self::State) -> #krate::__private::SVector<#scalar, #rows_lit> {
                #touch #gamma_body #gamma_expr
            }
            #[inline]
            fn evaluate(&self, state: &Self::State) -> #krate::Evaluation<#scalar, #rows_lit, #cols_lit> {
                #touch #eval_body
                #eval_expr
            }
        }
        #singularity_impl
    }
}

/// What every impl of `Joint` for a declaration starts with, real or stub.
pub struct Header {
    /// `impl<..> Joint<S, R, C> for Name<..> where ..`.
    pub impl_head: TokenStream,
    /// The state type.
    pub state_ty: TokenStream,
    /// The scalar as written in the impl.
    pub scalar: TokenStream,
    /// The impl's generics (the struct's, a fresh scalar if needed, and bounds).
    pub generics: syn::Generics,
}

/// The header of the `Joint` impl of `decl` with `rows` rows and `cols` columns.
pub fn impl_header(decl: &Declaration, rows: usize, cols: usize) -> Header {
    let krate = quote!(::joint_runtime);
    let (rows_lit, cols_lit) = (Literal::usize_unsuffixed(rows), Literal::usize_unsuffixed(cols));
    let scalar = match &decl.scalar {
        ScalarKind::Generic(t) | ScalarKind::Concrete(t) => quote!(#t),
        ScalarKind::Any => quote!(__JointScalar),
    };
    let body_ty = match decl.formulation {
        Formulation::Euler => quote!(#krate::EulerBody<#scalar>),
        _ => quote!(#krate::OmegaBody<#scalar>),
    };
    let state_ty = match (decl.formulation.is_relative(), decl.ground) {
        (true, _) => quote!(#krate::RelativeState<#scalar>),
        (false, Ground::None) => quote!(#krate::TwoBodies<#body_ty>),
        (false, _) => quote!(#krate::OneBody<#body_ty>),
    };
    // The impl's generics: the struct's own, a fresh scalar parameter if the
    // struct names none, the scalar bound, and a `TimeFunction` bound per driver field.
    let mut generics = decl.generics.clone();
    if let ScalarKind::Any = decl.scalar {
        generics.params.push(syn::parse_quote!(__JointScalar));
    }
    {
        let wc = generics.make_where_clause();
        if !matches!(decl.scalar, ScalarKind::Concrete(_)) {
            wc.predicates.push(syn::parse_quote!(#scalar: #krate::__private::SimdRealField + ::core::marker::Copy));
        }
        for ty in &decl.time_fields {
            wc.predicates.push(syn::parse_quote!(#ty: #krate::TimeFunction));
        }
    }
    let ident = &decl.ident;
    let (_, ty_generics, _) = decl.generics.split_for_impl();
    let (impl_generics, _, where_clause) = generics.split_for_impl();
    let impl_head =
        quote!(impl #impl_generics #krate::Joint<#scalar, #rows_lit, #cols_lit> for #ident #ty_generics #where_clause);
    Header { impl_head, state_ty, scalar, generics }
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

/// The printed functions of a derivation: each one's statements and result
/// expression, and the operation counts `[phi, phi_t, jacobian, gamma, evaluate]`.
pub struct Functions<'a> {
    d: &'a Derived,
    sty: ScalarTy,
    /// `phi`.
    pub phi: (TokenStream, TokenStream),
    /// `phi_t`.
    pub phi_t: (TokenStream, TokenStream),
    /// `jacobian`.
    pub jacobian: (TokenStream, TokenStream),
    /// `gamma`.
    pub gamma: (TokenStream, TokenStream),
    /// `evaluate` (an `Evaluation { .. }`).
    pub evaluate: (TokenStream, TokenStream),
    /// Operation counts.
    pub ops: [usize; 5],
}

impl Functions<'_> {
    /// Statements, output expressions and operation count for `outputs`.
    pub fn emit(&self, outputs: &[Id]) -> (TokenStream, Vec<TokenStream>, usize) {
        let e = emit::emit(&self.d.k.g, outputs, &self.sty);
        let bind = bindings(self.d, &e.used_vars, &self.sty);
        let body = e.body;
        (quote!(#bind #body), e.outputs, e.ops)
    }
}

/// `SVector` from its entries.
pub fn vector_tokens(krate: &TokenStream, outs: &[TokenStream]) -> TokenStream {
    quote!(#krate::__private::SMatrix::from_data(#krate::__private::ArrayStorage([[#(#outs),*]])))
}

/// `SMatrix` from its entries in column-major order.
pub fn matrix_tokens(krate: &TokenStream, outs: &[TokenStream], rows: usize) -> TokenStream {
    let columns = outs.chunks(rows.max(1)).map(|c| quote!([#(#c),*]));
    quote!(#krate::__private::SMatrix::from_data(#krate::__private::ArrayStorage([#(#columns),*])))
}

/// Prints Φ, Φ_t, J, γ and the fused evaluation of a derivation.
pub fn print_functions<'a>(d: &'a Derived, sty: &ScalarTy) -> Functions<'a> {
    let krate = &sty.krate;
    let (rows, cols) = (d.phi.len(), d.k.velocities.len());
    let jac_flat: Vec<Id> = (0..cols).flat_map(|c| d.jacobian.iter().map(move |row| row[c])).collect();
    let mut f = Functions {
        d,
        sty: sty.clone(),
        phi: Default::default(),
        phi_t: Default::default(),
        jacobian: Default::default(),
        gamma: Default::default(),
        evaluate: Default::default(),
        ops: [0; 5],
    };
    let (b, o, n0) = f.emit(&d.phi);
    f.phi = (b, vector_tokens(krate, &o));
    let (b, o, n1) = f.emit(&d.phi_t);
    f.phi_t = (b, vector_tokens(krate, &o));
    let (b, o, n2) = f.emit(&jac_flat);
    f.jacobian = (b, matrix_tokens(krate, &o, rows));
    let (b, o, n3) = f.emit(&d.gamma);
    f.gamma = (b, vector_tokens(krate, &o));
    let all: Vec<Id> = d.phi.iter().chain(&jac_flat).chain(&d.gamma).copied().collect();
    let (b, o, n4) = f.emit(&all);
    let (ep, rest) = o.split_at(rows);
    let (ej, eg) = rest.split_at(rows * cols);
    let (ep, ej, eg) = (vector_tokens(krate, ep), matrix_tokens(krate, ej, rows), vector_tokens(krate, eg));
    f.evaluate = (b, quote!(#krate::Evaluation { phi: #ep, jacobian: #ej, gamma: #eg }));
    f.ops = [n0, n1, n2, n3, n4];
    f
}

/// `let` statements that destructure exactly the inputs a function reads.
fn bindings(
    d: &Derived,
    used: &std::collections::BTreeSet<crate::engine::graph::VarId>,
    sty: &ScalarTy,
) -> TokenStream {
    let g = &d.k.g;
    let pattern = |nodes: &[Id]| -> Option<TokenStream> {
        let mut any = false;
        let names: Vec<TokenStream> = nodes
            .iter()
            .map(|&n| match g.as_var(n) {
                Some(v) if used.contains(&v) => {
                    any = true;
                    let id = format_ident!("{}", g.vars()[v.0 as usize].name);
                    quote!(#id)
                }
                _ => quote!(_),
            })
            .collect();
        any.then(|| quote!([[#(#names),*]]))
    };
    let mut out = TokenStream::new();
    for (member, shape, sub, nodes) in &d.bindings {
        if *shape == FieldShape::Time {
            // One call of the time function per evaluation, at the state's time.
            let names: Vec<Option<Ident>> = nodes
                .iter()
                .map(|&n| {
                    g.as_var(n).filter(|v| used.contains(v)).map(|v| format_ident!("{}", g.vars()[v.0 as usize].name))
                })
                .collect();
            if names.iter().all(Option::is_none) {
                continue;
            }
            let drive = format_ident!("{}_drive", member);
            let (ty, krate) = (&sty.ty, &sty.krate);
            out.extend(quote!(let #drive = #krate::TimeFunction::eval(&self.#member, state.t);));
            for (name, field) in names.iter().zip(["value", "rate", "accel"]) {
                if let Some(name) = name {
                    let field = format_ident!("{}", field);
                    out.extend(quote!(let #name: #ty = #krate::__private::convert::<f64, #ty>(#drive.#field);));
                }
            }
            continue;
        }
        if nodes.len() == 1 {
            if let Some(v) = g.as_var(nodes[0]).filter(|v| used.contains(v)) {
                let id = format_ident!("{}", g.vars()[v.0 as usize].name);
                out.extend(quote!(let #id = self.#member;));
            }
            continue;
        }
        if let Some(p) = pattern(nodes) {
            let source = if matches!(shape, FieldShape::FramePart(_)) {
                let s = format_ident!("{}", sub);
                quote!(self.#member.#s)
            } else {
                quote!(self.#member)
            };
            out.extend(quote!(let #p = #source.data.0;));
        }
    }
    for input in &d.k.inputs {
        if let Some(p) = pattern(&input.vars) {
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
            out.extend(quote!(let #p = state #(#path)*.data.0;));
        }
    }
    out
}

/// Lowers row expressions onto the graph.
struct Lowering<'a> {
    k: &'a mut Kinematics,
    values: &'a [(&'static str, Vec<Id>)],
    kind: &'a JointKind,
}

impl Lowering<'_> {
    fn nodes(&self, name: &str) -> Vec<Id> {
        self.values.iter().find(|(n, _)| *n == name).map(|(_, v)| v.clone()).unwrap_or_default()
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
