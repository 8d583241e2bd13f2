//! `#[derive(Scene)]`: a mechanism's bodies and joints, one system of rows.
//!
//! ```text
//! #[derive(Scene)]
//! #[scene(gravity = [0, 0, -9.81])]                               (optional; default zero)
//! #[body(NAME, mass = 1.0 | FIELD, inertia = [ixx, iyy, izz] | [ixx, iyy, izz, ixy, ixz, iyz] | FIELD)]
//! #[joint(NAME = KIND(BODY | ground, BODY | ground), PARAM = [x, y, z] | number | FIELD, ...)]
//! struct S<F> { FIELD: Vector3<f64> | f64 | AxisFrame<f64> | F (a time function), ... }
//! ```
//! Every joint of the catalogue is available. All rows are lowered onto one
//! graph over the bodies' frames (the `omega_body` formulation: `r, p; ṙ, ω'`
//! per body), so a body's rotation is computed once for all its joints, and the
//! system Jacobian's zero pattern is known here, at compile time.

use proc_macro2::{Literal, Span, TokenStream};
use quote::quote;
use syn::parse::{Parse, ParseStream};
use syn::punctuated::Punctuated;
use syn::spanned::Spanned;
use syn::{Token, parenthesized};

use crate::dsl::{Arg, Errors, FieldShape, Source, Value};
use crate::engine::emit::ScalarTy;
use crate::expand::{self, Derived, Naming};
use crate::joints::{self, JointKind};
use crate::kinematics::{Formulation, Kinematics};

/// `NAME = KIND(BODY, BODY), PARAM = VALUE, ...`
struct JointAttr {
    name: syn::Ident,
    kind: syn::Ident,
    bodies: Vec<syn::Ident>,
    args: Vec<Arg>,
}

impl Parse for JointAttr {
    fn parse(input: ParseStream) -> syn::Result<Self> {
        let name: syn::Ident = input.parse()?;
        input.parse::<Token![=]>().map_err(|e| {
            syn::Error::new(e.span(), "expected `NAME = KIND(BODY, BODY)`, as in `cardan = universal(input, output)`")
        })?;
        let kind: syn::Ident = input.parse()?;
        let content;
        parenthesized!(content in input);
        let bodies = Punctuated::<syn::Ident, Token![,]>::parse_terminated(&content)?.into_iter().collect();
        let mut args = Vec::new();
        if input.parse::<Option<Token![,]>>()?.is_some() {
            args = Punctuated::<Arg, Token![,]>::parse_terminated(input)?.into_iter().collect();
        }
        Ok(JointAttr { name, kind, bodies, args })
    }
}

/// A number, a vector, or a field read at run time.
enum Quantity {
    Const(Vec<f64>),
    Field(syn::Ident),
}

struct Body {
    name: syn::Ident,
    mass: Quantity,
    inertia: Quantity,
}

struct JointDecl {
    name: syn::Ident,
    kind: &'static JointKind,
    kind_span: Span,
    bodies: [Option<usize>; 2],
    params: Vec<(&'static str, Source)>,
}

/// The derive's entry point.
pub fn derive(input: &syn::DeriveInput) -> TokenStream {
    match parse(input).and_then(|s| expand(input, &s)) {
        Ok(t) => t,
        Err(e) => crate::fallback::scene(input, e, shape(input)),
    }
}

/// The bodies' names and the number of rows, read from the attributes alone
/// when every body and joint attribute parses and names a known joint: enough
/// for a stub impl beside a compile error (see [`crate::fallback::scene`]).
fn shape(input: &syn::DeriveInput) -> Option<crate::fallback::SceneShape> {
    let (mut bodies, mut rows) = (Vec::new(), 0);
    for attr in &input.attrs {
        if attr.path().is_ident("body") {
            let args = attr.parse_args_with(Punctuated::<Arg, Token![,]>::parse_terminated).ok()?;
            let name = args.into_iter().next()?.key;
            bodies.push((name.to_string(), body_constant(&name)));
        } else if attr.path().is_ident("joint") {
            let joint = attr.parse_args::<JointAttr>().ok()?;
            rows += joints::lookup(&joint.kind.to_string())?.row_count();
        }
    }
    (!bodies.is_empty()).then_some(crate::fallback::SceneShape { bodies, rows })
}

struct SceneDecl {
    bodies: Vec<Body>,
    joints: Vec<JointDecl>,
    gravity: Quantity,
    time_types: Vec<syn::Type>,
}

fn quantity(
    v: Option<Value>,
    what: &str,
    fields: &[(syn::Ident, syn::Type)],
    errors: &mut Errors,
    at: Span,
) -> Quantity {
    match v {
        Some(Value::Number(x, _)) => Quantity::Const(vec![x]),
        Some(Value::List(v, _)) => Quantity::Const(v),
        Some(Value::Ident(f)) => {
            if !fields.iter().any(|(n, _)| *n == f) {
                errors
                    .at(f.span(), format!("no field `{f}` in this struct; expected a number or a field for `{what}`"));
            }
            Quantity::Field(f)
        }
        _ => {
            errors.at(at, format!("expected `{what} = NUMBER` or `{what} = FIELD`"));
            Quantity::Const(vec![0.0])
        }
    }
}

fn parse(input: &syn::DeriveInput) -> syn::Result<SceneDecl> {
    let mut errors = Errors::default();
    let fields: Vec<(syn::Ident, syn::Type)> = match &input.data {
        syn::Data::Struct(s) => s.fields.iter().filter_map(|f| f.ident.clone().map(|i| (i, f.ty.clone()))).collect(),
        _ => {
            return Err(syn::Error::new(
                input.ident.span(),
                "`Scene` can only be derived for a struct, as in `struct Shaft { bend: f64 }`",
            ));
        }
    };
    let mut bodies: Vec<Body> = Vec::new();
    let mut joint_attrs: Vec<JointAttr> = Vec::new();
    let mut gravity = Quantity::Const(vec![0.0; 3]);
    // Attributes written, parsed or not: a scene whose only joint attribute has a
    // mistake gets that mistake reported, not a second "needs joints" as well.
    let written = |name: &str| input.attrs.iter().any(|a| a.path().is_ident(name));
    for attr in &input.attrs {
        if attr.path().is_ident("scene") {
            match attr.parse_args_with(Punctuated::<Arg, Token![,]>::parse_terminated) {
                Ok(args) => {
                    for a in args {
                        match a.key.to_string().as_str() {
                            "gravity" => gravity = quantity(a.value, "gravity", &fields, &mut errors, a.key.span()),
                            "formulation" => match &a.value {
                                Some(Value::Ident(f)) if f == "omega_body" => {}
                                _ => errors.at(
                                    a.key.span(),
                                    "scenes use the `omega_body` formulation (`r, p; ṙ, ω'` per body); expected `formulation = omega_body` or nothing",
                                ),
                            },
                            other => errors.at(a.key.span(), format!("unknown scene option `{other}`; expected `gravity`")),
                        }
                    }
                }
                Err(e) => errors.push(e),
            }
        } else if attr.path().is_ident("body") {
            match attr.parse_args_with(Punctuated::<Arg, Token![,]>::parse_terminated) {
                Ok(args) => {
                    let mut args = args.into_iter();
                    let Some(first) = args.next().filter(|a| a.value.is_none()) else {
                        errors.at(attr.span(), "expected `#[body(NAME, mass = .., inertia = ..)]`");
                        continue;
                    };
                    let (mut mass, mut inertia) = (None, None);
                    for a in args {
                        match a.key.to_string().as_str() {
                            "mass" => mass = Some(quantity(a.value, "mass", &fields, &mut errors, a.key.span())),
                            "inertia" => {
                                inertia = Some(quantity(a.value, "inertia", &fields, &mut errors, a.key.span()))
                            }
                            other => errors.at(
                                a.key.span(),
                                format!("unknown body option `{other}`; expected `mass` or `inertia`"),
                            ),
                        }
                    }
                    if bodies.iter().any(|b| b.name == first.key) || first.key == "ground" {
                        errors.at(first.key.span(), format!("body `{}` is declared twice (or is `ground`)", first.key));
                    }
                    bodies.push(Body {
                        name: first.key,
                        mass: mass.unwrap_or(Quantity::Const(vec![1.0])),
                        inertia: inertia.unwrap_or(Quantity::Const(vec![1.0, 1.0, 1.0])),
                    });
                }
                Err(e) => errors.push(e),
            }
        } else if attr.path().is_ident("joint") {
            match attr.parse_args::<JointAttr>() {
                Ok(j) => joint_attrs.push(j),
                Err(e) => errors.push(e),
            }
        }
    }
    if bodies.is_empty() {
        // Every joint would be ground to ground: say the one thing that is wrong.
        if !written("body") {
            errors.at(
                input.ident.span(),
                "a scene needs bodies; add `#[body(NAME, mass = 1.0, inertia = [ixx, iyy, izz])]`",
            );
        }
        return match errors.finish() {
            Err(e) => Err(e),
            Ok(()) => unreachable!("an error was recorded"),
        };
    }
    for (i, b) in bodies.iter().enumerate() {
        let constant = body_constant(&b.name).to_string();
        // A body declared twice is reported as such, not again here.
        let clash = bodies[..i].iter().find(|e| e.name != b.name && body_constant(&e.name) == constant);
        if crate::fallback::SIZE_CONSTANTS.contains(&constant.as_str()) {
            let message = format!("body `{}` would be named `{constant}`, a constant of the scene's size", b.name);
            errors.at(b.name.span(), format!("{message}; rename the body"));
        } else if let Some(earlier) = clash {
            let message = format!("bodies `{}` and `{}` would both be named `{constant}`", earlier.name, b.name);
            errors.at(b.name.span(), format!("{message}; rename one"));
        }
    }
    if !written("joint") {
        errors.at(input.ident.span(), "a scene needs joints; add `#[joint(NAME = KIND(BODY, BODY), ..)]`");
    }
    for b in &bodies {
        if let Quantity::Const(v) = &b.inertia
            && v.len() != 3
            && v.len() != 6
        {
            errors
                .at(b.name.span(), "`inertia` takes 3 principal moments or 6 entries `[ixx, iyy, izz, ixy, ixz, iyz]`");
        }
    }

    let mut joints = Vec::new();
    let mut time_types = Vec::new();
    for j in joint_attrs {
        if joints.iter().any(|x: &JointDecl| x.name == j.name) {
            errors.at(j.name.span(), format!("joint `{}` is declared twice", j.name));
        }
        let Some(kind) = joints::lookup(&j.kind.to_string()) else {
            errors.at(
                j.kind.span(),
                format!(
                    "unknown joint `{}`{}; expected one of {}",
                    j.kind,
                    crate::dsl::did_you_mean(&j.kind.to_string(), joints::catalogue().iter().map(|k| k.name)),
                    joints::names()
                ),
            );
            continue;
        };
        let body_index = |b: &syn::Ident, errors: &mut Errors| -> Option<usize> {
            if b == "ground" {
                return None;
            }
            let i = bodies.iter().position(|x| x.name == *b);
            if i.is_none() {
                errors.at(
                    b.span(),
                    format!("unknown body `{b}`; expected `ground` or a body declared with `#[body({b}, ..)]`"),
                );
            }
            i
        };
        if j.bodies.len() != 2 {
            errors.at(
                j.kind.span(),
                format!("`{}` connects two bodies; expected `{}(BODY1, BODY2)`", kind.name, kind.name),
            );
            continue;
        }
        let pair = [body_index(&j.bodies[0], &mut errors), body_index(&j.bodies[1], &mut errors)];
        if pair == [None, None] && j.bodies.iter().all(|b| b == "ground") {
            errors.at(j.kind.span(), "a joint between the ground and itself constrains nothing");
        }
        let mut given = Vec::new();
        let mut invalid = Vec::new();
        for a in j.args {
            let name = a.key.to_string();
            let shape = crate::params::shape_of(kind, &name);
            let source = match a.value {
                Some(Value::List(v, s)) => Source::Const(v, s),
                Some(Value::Number(x, s)) => Source::Const(vec![x], s),
                Some(Value::Ident(f)) => match fields.iter().find(|(n, _)| *n == f) {
                    Some((_, ty)) => {
                        if shape == FieldShape::Time {
                            time_types.push(ty.clone());
                        }
                        Source::Field { member: f.clone(), shape, span: f.span() }
                    }
                    None => {
                        errors.at(f.span(), format!("no field `{f}` in this struct; expected a constant or a field"));
                        invalid.push(name);
                        continue;
                    }
                },
                _ => {
                    errors.at(a.key.span(), format!("expected `{name} = [x, y, z]`, a number or a field"));
                    invalid.push(name);
                    continue;
                }
            };
            given.push((name, a.key.span(), source));
        }
        let params = crate::params::resolve(kind, Formulation::OmegaBody, given, &invalid, j.kind.span(), &mut errors);
        joints.push(JointDecl { name: j.name, kind, kind_span: j.kind.span(), bodies: pair, params });
    }
    errors.finish()?;
    Ok(SceneDecl { bodies, joints, gravity, time_types })
}

fn expand(input: &syn::DeriveInput, s: &SceneDecl) -> syn::Result<TokenStream> {
    let names: Vec<String> = s.bodies.iter().map(|b| b.name.to_string()).collect();
    let mut k = Kinematics::scene(Formulation::OmegaBody, &names);
    let mut bindings = Vec::new();
    let (mut phi, mut spans, mut blocks) = (Vec::new(), Vec::new(), Vec::new());
    for j in &s.joints {
        k.connect(j.bodies[0], j.bodies[1]);
        let values = expand::param_nodes(&mut k, j.kind, &j.params, Naming::ByField, &mut bindings);
        let (rows, row_spans, _) = expand::lower_rows(&mut k, j.kind, &values, &[], j.kind_span);
        blocks.push((j.name.to_string(), phi.len(), rows.len()));
        phi.extend(rows);
        spans.extend(row_spans);
    }
    let expand::SystemDerivatives { jacobian, gamma, phi_t } = expand::derive_all(&mut k, &phi, &spans)?;
    let d = Derived { k, phi, phi_t, jacobian, gamma, bindings, singularity: None };
    Ok(print(input, s, &d, &blocks))
}

fn print(input: &syn::DeriveInput, s: &SceneDecl, d: &Derived, blocks: &[(String, usize, usize)]) -> TokenStream {
    let krate = quote!(::joint_runtime);
    let sty = ScalarTy { ty: quote!(f64), krate: krate.clone(), concrete_f64: true };
    let (nb, m) = (s.bodies.len(), d.phi.len());
    let nv = 6 * nb;
    let [nb_l, nv_l, m_l] = [nb, nv, m].map(Literal::usize_unsuffixed);
    let f = expand::print_functions(d, &sty);
    let [o0, o1, o2, o3, o4] = f.ops.map(Literal::usize_unsuffixed);
    let ((phi_b, phi_e), (phi_t_b, phi_t_e), (jac_b, jac_e), (gamma_b, gamma_e), (eval_b, eval_e)) =
        (f.phi.clone(), f.phi_t.clone(), f.jacobian.clone(), f.gamma.clone(), f.evaluate.clone());

    // The sparse form: the entries that are not structurally zero, row by row.
    let mut row_starts = vec![0usize];
    let (mut columns, mut entries) = (Vec::new(), Vec::new());
    for row in &d.jacobian {
        for (c, &e) in row.iter().enumerate() {
            if d.k.g.as_const(e) != Some(0.0) {
                columns.push(c);
                entries.push(e);
            }
        }
        row_starts.push(columns.len());
    }
    let nnz = Literal::usize_unsuffixed(columns.len());
    let (sparse_b, sparse_o, sparse_ops) = f.emit(&entries);
    let row_starts = row_starts.iter().map(|&x| Literal::usize_unsuffixed(x));
    let columns = columns.iter().map(|&x| Literal::usize_unsuffixed(x));

    let body_names = s.bodies.iter().map(|b| b.name.to_string());
    let blocks: Vec<TokenStream> = blocks
        .iter()
        .map(|(n, start, rows)| {
            let (start, rows) = (Literal::usize_unsuffixed(*start), Literal::usize_unsuffixed(*rows));
            quote!(#krate::RowBlock { name: #n, start: #start, rows: #rows })
        })
        .collect();
    let body_indices = s.bodies.iter().enumerate().map(|(i, b)| {
        let name = body_constant(&b.name);
        let doc = format!(" The index of body `{}` in the state's `bodies`.", b.name);
        let i = Literal::usize_unsuffixed(i);
        quote!(#[doc = #doc] pub const #name: usize = #i;)
    });
    let number = |v: f64| Literal::f64_suffixed(v);
    let vec3 = |q: &Quantity| match q {
        Quantity::Const(v) => const_vector(v, &krate),
        Quantity::Field(f) => quote!(self.#f),
    };
    let inertias = s.bodies.iter().map(|b| {
        let mass = match &b.mass {
            Quantity::Const(v) => {
                let x = number(v.first().copied().unwrap_or(1.0));
                quote!(#x)
            }
            Quantity::Field(f) => quote!(self.#f),
        };
        let inertia = match &b.inertia {
            Quantity::Const(v) if v.len() == 6 => {
                let [xx, yy, zz, xy, xz, yz] = [0, 1, 2, 3, 4, 5].map(|i| number(v[i]));
                quote!(#krate::nalgebra::Matrix3::new(#xx, #xy, #xz, #xy, #yy, #yz, #xz, #yz, #zz))
            }
            q => {
                let v = vec3(q);
                quote!(#krate::nalgebra::Matrix3::from_diagonal(&#v))
            }
        };
        quote!(#krate::BodyInertia { mass: #mass, inertia: #inertia })
    });
    let gravity = vec3(&s.gravity);
    let points = joint_points(s, &krate);
    let ident = &input.ident;
    let mut generics = input.generics.clone();
    {
        let wc = generics.make_where_clause();
        for ty in &s.time_types {
            wc.predicates.push(syn::parse_quote!(#ty: #krate::TimeFunction));
        }
    }
    let (ig, tg, wc) = generics.split_for_impl();
    let doc = format!(
        " {nb} bodies, {m} rows, {nv} columns; {} structurally nonzero Jacobian entries. Operations: phi {}, phi_t {}, jacobian {}, gamma {}, evaluate {}, sparse jacobian {sparse_ops}.",
        entries.len(),
        f.ops[0],
        f.ops[1],
        f.ops[2],
        f.ops[3],
        f.ops[4]
    );
    let state = quote!(#krate::SystemState<#nb_l>);
    quote! {
        #[doc = #doc]
        #[allow(clippy::all, clippy::pedantic, unused_variables, non_snake_case)]
        #[deny(clippy::panic, clippy::unwrap_used, clippy::indexing_slicing)]
        impl #ig #krate::Scene<#nb_l, #nv_l, #m_l> for #ident #tg #wc {
            const BODIES: [&'static str; #nb_l] = [#(#body_names),*];
            const BLOCKS: &'static [#krate::RowBlock] = &[#(#blocks),*];
            const OPS: #krate::Ops = #krate::Ops { phi: #o0, phi_t: #o1, jacobian: #o2, gamma: #o3, evaluate: #o4 };
            #[inline]
            fn phi(&self, state: &#state) -> #krate::__private::SVector<f64, #m_l> { #phi_b #phi_e }
            #[inline]
            fn phi_t(&self, state: &#state) -> #krate::__private::SVector<f64, #m_l> { #phi_t_b #phi_t_e }
            #[inline]
            fn jacobian(&self, state: &#state) -> #krate::__private::SMatrix<f64, #m_l, #nv_l> { #jac_b #jac_e }
            #[inline]
            fn gamma(&self, state: &#state) -> #krate::__private::SVector<f64, #m_l> { #gamma_b #gamma_e }
            #[inline]
            fn evaluate(&self, state: &#state) -> #krate::Evaluation<f64, #m_l, #nv_l> { #eval_b #eval_e }
            fn inertias(&self) -> [#krate::BodyInertia; #nb_l] { [#(#inertias),*] }
            fn gravity(&self) -> #krate::nalgebra::Vector3<f64> { #gravity }
            fn joint_points(&self, visit: &mut dyn FnMut(#krate::JointPoint)) { #(#points)* }
        }

        /// The scene's sizes and its bodies by name, without spelling out
        /// `Scene<NB, NV, ROWS>`.
        #[automatically_derived]
        #[allow(dead_code)]
        impl #ig #ident #tg #wc {
            #(#body_indices)*
            /// Number of bodies (`NB` of `Scene<NB, NV, M>`).
            pub const NB: usize = #nb_l;
            /// Velocity columns, 6 per body (`NV`).
            pub const NV: usize = #nv_l;
            /// Constraint rows (`M`).
            pub const ROWS: usize = #m_l;
            /// Each joint's block of rows, in row order (as `Scene::BLOCKS`).
            pub const BLOCKS: &'static [#krate::RowBlock] = &[#(#blocks),*];
        }

        #[allow(clippy::all, clippy::pedantic, unused_variables, non_snake_case)]
        #[deny(clippy::panic, clippy::unwrap_used, clippy::indexing_slicing)]
        impl #ig #krate::SparseJacobian<#nb_l, #nnz> for #ident #tg #wc {
            const ROW_STARTS: &'static [usize] = &[#(#row_starts),*];
            const COLUMNS: [usize; #nnz] = [#(#columns),*];
            #[inline]
            fn jacobian_values(&self, state: &#state) -> [f64; #nnz] { #sparse_b [#(#sparse_o),*] }
        }
    }
}

/// One `visit(JointPoint { .. })` per joint point (`rho1`, `rho2`) in declaration
/// order: what a trajectory recorder draws. A point on the ground is inertial.
fn joint_points(s: &SceneDecl, krate: &TokenStream) -> Vec<TokenStream> {
    let mut calls = Vec::new();
    for j in &s.joints {
        let name = j.name.to_string();
        for (param, body) in [("rho1", j.bodies[0]), ("rho2", j.bodies[1])] {
            let Some((_, source)) = j.params.iter().find(|(p, _)| *p == param) else { continue };
            let point = match source {
                Source::Const(v, _) => const_vector(v, krate),
                Source::Field { member, .. } => quote!(self.#member),
            };
            let body = match body {
                Some(i) => {
                    let i = Literal::usize_unsuffixed(i);
                    quote!(::core::option::Option::Some(#i))
                }
                None => quote!(::core::option::Option::None),
            };
            calls.push(quote!(visit(#krate::JointPoint { joint: #name, body: #body, point: #point });));
        }
    }
    calls
}

/// A constant 3-vector (missing components zero; the parser checked the length).
fn const_vector(v: &[f64], krate: &TokenStream) -> TokenStream {
    let [x, y, z] = [0, 1, 2].map(|i| Literal::f64_suffixed(v.get(i).copied().unwrap_or(0.0)));
    quote!(#krate::nalgebra::Vector3::new(#x, #y, #z))
}

/// The inherent constant naming a body's index: its name in upper case
/// (`input` → `Shaft::INPUT`).
fn body_constant(name: &syn::Ident) -> syn::Ident {
    let text = name.to_string();
    syn::Ident::new(text.strip_prefix("r#").unwrap_or(&text).to_uppercase().as_str(), name.span())
}
