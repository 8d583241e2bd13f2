//! The derive's input language: `#[joint(...)]` on the struct and its fields,
//! parsed into a [`Declaration`] that keeps the span of every token it came from.
//!
//! ```text
//! #[joint(KIND, formulation = NAME [, ground = body1|body2] [, PARAM = [x, y, z]]* [, length = x])]
//! struct S<T> { PARAM: Vector3<T>, #[joint(PARAM)] other_name: Vector3<T>, #[joint(skip)] extra: X }
//! ```

use proc_macro2::Span;
use quote::ToTokens;
use syn::parse::{Parse, ParseStream};
use syn::punctuated::Punctuated;
use syn::spanned::Spanned;
use syn::{Token, bracketed};

use crate::joints::{self, JointKind, Role};
use crate::kinematics::{Formulation, Ground};
use crate::params::norm3;

/// A value written in `#[joint(name = value)]`.
pub enum Value {
    /// An identifier (`omega_body`, `body1`).
    Ident(syn::Ident),
    /// A number.
    Number(f64, Span),
    /// `[x, y, z]`.
    List(Vec<f64>, Span),
    /// `rows(e1, e2, ...)`: user-written rows.
    Rows(Vec<syn::Expr>, Span),
    /// `body1(s = [..], ...)`: constants tagged with a body.
    Group(Vec<Arg>, Span),
}

/// One item of `#[joint(...)]`.
pub struct Arg {
    /// The key (or the bare word).
    pub key: syn::Ident,
    /// The value after `=`, if any.
    pub value: Option<Value>,
}

/// A number: a literal, or arithmetic on literals folded here (`0.007 - 0.00092`,
/// `-1.0 / 3.0`, `2.0 * (0.5 + 0.25)`), so that the geometry checks still see it.
fn number(input: ParseStream) -> syn::Result<(f64, Span)> {
    let expr: syn::Expr = input.parse().map_err(|e| syn::Error::new(e.span(), EXPECTED_NUMBER))?;
    Ok((fold(&expr)?, expr.span()))
}

const EXPECTED_NUMBER: &str =
    "expected a number or arithmetic on numbers, as in `0.5`, `[0, 0, 1]` or `0.007 - 0.00092`";

/// The value of arithmetic on number literals, in f64 as Rust would compute it
/// (each operation rounded once, left to right as written).
fn fold(expr: &syn::Expr) -> syn::Result<f64> {
    use syn::{BinOp, Expr, Lit, UnOp};
    let value = match expr {
        Expr::Lit(syn::ExprLit { lit: Lit::Int(i), .. }) => i.base10_parse::<f64>()?,
        Expr::Lit(syn::ExprLit { lit: Lit::Float(f), .. }) => f.base10_parse::<f64>()?,
        Expr::Paren(e) => fold(&e.expr)?,
        Expr::Group(e) => fold(&e.expr)?,
        Expr::Unary(e) if matches!(e.op, UnOp::Neg(_)) => -fold(&e.expr)?,
        Expr::Binary(e) => {
            let (a, b) = (fold(&e.left)?, fold(&e.right)?);
            match e.op {
                BinOp::Add(_) => a + b,
                BinOp::Sub(_) => a - b,
                BinOp::Mul(_) => a * b,
                BinOp::Div(_) => a / b,
                _ => return Err(syn::Error::new(e.op.span(), "expected `+`, `-`, `*` or `/` between numbers")),
            }
        }
        Expr::Path(p) => {
            return Err(syn::Error::new(
                p.span(),
                "a named constant is not accepted here; write the number or arithmetic on numbers, as in `0.007 - 0.00092`",
            ));
        }
        _ => return Err(syn::Error::new(expr.span(), EXPECTED_NUMBER)),
    };
    // A non-finite result (`1.0 / 0.0`) is the parameter checks' to report, as
    // for a non-finite literal.
    Ok(value)
}

impl Parse for Arg {
    fn parse(input: ParseStream) -> syn::Result<Self> {
        let key: syn::Ident = input.parse()?;
        if input.peek(syn::token::Paren) {
            let content;
            let paren = syn::parenthesized!(content in input);
            let value = if key == "rows" {
                let rows = Punctuated::<syn::Expr, Token![,]>::parse_terminated(&content)?;
                Value::Rows(rows.into_iter().collect(), paren.span.join())
            } else {
                let args = Punctuated::<Arg, Token![,]>::parse_terminated(&content)?;
                Value::Group(args.into_iter().collect(), paren.span.join())
            };
            return Ok(Arg { key, value: Some(value) });
        }
        if input.parse::<Option<Token![=]>>()?.is_none() {
            return Ok(Arg { key, value: None });
        }
        let value = if input.peek(syn::token::Bracket) {
            let content;
            let bracket = bracketed!(content in input);
            let mut values = Vec::new();
            while !content.is_empty() {
                values.push(number(&content)?.0);
                if content.is_empty() {
                    break;
                }
                content.parse::<Token![,]>()?;
            }
            Value::List(values, bracket.span.join())
        } else if input.peek(syn::Ident) {
            Value::Ident(input.parse()?)
        } else {
            let (v, span) = number(input)?;
            Value::Number(v, span)
        };
        Ok(Arg { key, value: Some(value) })
    }
}

/// Where a parameter's value comes from.
pub enum Source {
    /// A constant written in the attribute, folded into the generated code.
    Const(Vec<f64>, Span),
    /// A struct field read at run time.
    Field {
        /// The field.
        member: syn::Ident,
        /// What the field holds.
        shape: FieldShape,
        /// The field's span.
        span: Span,
    },
}

/// The type of a parameter field.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum FieldShape {
    /// `Vector3<T>`.
    Vector,
    /// `T`.
    Scalar,
    /// `AxisFrame<T>` (or its alias `SlidingFrame<T>`): an axis given instead of
    /// the vectors derived from it (`axis1`, `axis2`, `d`).
    Frame,
    /// One part of an `AxisFrame` field, standing for a derived parameter.
    FramePart(joints::Part),
    /// Any type implementing `joint_runtime::TimeFunction` (a driver's time function).
    Time,
}

/// The scalar the impl is for.
pub enum ScalarKind {
    /// `struct S<T>`: every `T: SimdRealField + Copy`.
    Generic(syn::Ident),
    /// Fields of one concrete float type.
    Concrete(syn::Ident),
    /// No field names a scalar: every `T: SimdRealField + Copy`, on a non-generic struct.
    Any,
}

/// A parsed declaration.
pub struct Declaration {
    /// The struct.
    pub ident: syn::Ident,
    /// Its generics.
    pub generics: syn::Generics,
    /// The joint kind.
    pub kind: &'static JointKind,
    /// The formulation.
    pub formulation: Formulation,
    /// The grounded body.
    pub ground: Ground,
    /// Parameters by name, in the joint's order.
    pub params: Vec<(&'static str, Source)>,
    /// The scalar.
    pub scalar: ScalarKind,
    /// Fields that are parameters the formulation does not read.
    pub unused_fields: Vec<syn::Ident>,
    /// Types of the time-function fields (each gets a `TimeFunction` bound).
    pub time_fields: Vec<syn::Type>,
    /// The span of each row of a user-written joint (empty for catalogue joints).
    pub row_spans: Vec<Span>,
    /// The span of the joint kind (or of `rows`).
    pub kind_span: Span,
}

/// Collects errors so that one run reports every mistake (after serde's `Ctxt`).
#[derive(Default)]
pub struct Errors(Vec<syn::Error>);

impl Errors {
    /// Records an error at `span`.
    pub fn at(&mut self, span: Span, message: impl std::fmt::Display) {
        self.0.push(syn::Error::new(span, message));
    }

    /// Records an error spanning every token of `tokens` (a whole type, say).
    pub fn spanned(&mut self, tokens: impl quote::ToTokens, message: impl std::fmt::Display) {
        self.0.push(syn::Error::new_spanned(tokens, message));
    }

    /// Records a parse error.
    pub fn push(&mut self, e: syn::Error) {
        self.0.push(e);
    }

    /// All errors combined, or `Ok` if none.
    pub fn finish(self) -> syn::Result<()> {
        let mut iter = self.0.into_iter();
        match iter.next() {
            None => Ok(()),
            Some(mut first) => {
                for e in iter {
                    first.combine(e);
                }
                Err(first)
            }
        }
    }
}

fn joint_args(attrs: &[syn::Attribute], errors: &mut Errors) -> Vec<Arg> {
    let mut out = Vec::new();
    for attr in attrs.iter().filter(|a| a.path().is_ident("joint")) {
        match attr.parse_args_with(Punctuated::<Arg, Token![,]>::parse_terminated) {
            Ok(args) => out.extend(args),
            Err(e) => errors.push(e),
        }
    }
    out
}

const FORMULATIONS: &str = "`euler`, `omega_inertial`, `omega_body`, `relative_b1`, `relative_b2`";

/// A parameter name the struct gave that the joint does not take, reported once
/// the missing parameters are known (it is most likely a misspelling of one).
struct Unknown {
    name: String,
    span: Span,
    field: bool,
}

/// A declaration that does not check: the errors, and as much of the
/// declaration as was understood (enough for a stub impl when the joint kind
/// and the formulation were).
pub struct Failure {
    /// Every error found.
    pub error: syn::Error,
    /// The declaration as far as it goes (boxed: it is large, and only the
    /// error path carries it).
    pub partial: Option<Box<Declaration>>,
}

impl From<syn::Error> for Failure {
    fn from(error: syn::Error) -> Self {
        Failure { error, partial: None }
    }
}

/// Parses and checks a derive input.
pub fn parse(input: &syn::DeriveInput) -> Result<Declaration, Failure> {
    let mut errors = Errors::default();
    const SHAPE: &str = "expected a struct with named fields, as in `struct Cardan<T> { h: Vector3<T>, .. }`";
    let fields = match &input.data {
        syn::Data::Struct(syn::DataStruct { fields: syn::Fields::Named(named), .. }) => Some(&named.named),
        syn::Data::Struct(syn::DataStruct { fields: syn::Fields::Unit, .. }) => None,
        syn::Data::Struct(syn::DataStruct { fields: syn::Fields::Unnamed(unnamed), .. }) => {
            let message = format!("`Joint` cannot be derived for a tuple struct; {SHAPE}");
            return Err(syn::Error::new(unnamed.paren_token.span.join(), message).into());
        }
        syn::Data::Enum(e) => {
            let message = format!("`Joint` cannot be derived for an enum; {SHAPE}");
            return Err(syn::Error::new(e.enum_token.span, message).into());
        }
        syn::Data::Union(u) => {
            let message = format!("`Joint` cannot be derived for a union; {SHAPE}");
            return Err(syn::Error::new(u.union_token.span, message).into());
        }
    };
    // The scalar as the user wrote it, for messages: `T` in `struct S<T>`.
    let scalar_name = match input.generics.type_params().collect::<Vec<_>>().as_slice() {
        [t] => t.ident.to_string(),
        _ => "f64".to_string(),
    };

    // Struct attribute: kind, formulation, ground, constants.
    let mut kind: Option<(&'static JointKind, Span)> = None;
    let mut formulation: Option<Formulation> = None;
    // A formulation was written (perhaps misspelled): do not also call it missing.
    let mut formulation_given = false;
    let mut ground = (Ground::None, Span::call_site(), String::new());
    let mut consts: Vec<(syn::Ident, Value)> = Vec::new();
    let mut rows: Option<(Vec<syn::Expr>, Span)> = None;
    let mut tagged: Vec<(String, Role)> = Vec::new();
    let mut row_spans: Vec<Span> = Vec::new();
    let args = joint_args(&input.attrs, &mut errors);
    if args.is_empty() && errors.0.is_empty() {
        errors.at(
            input.ident.span(),
            "missing `#[joint(...)]`: name the joint and formulation, as in `#[joint(universal, formulation = omega_body)]`",
        );
    }
    let mut kind_given = false;
    for arg in args {
        let name = arg.key.to_string();
        match (name.as_str(), arg.value) {
            (_, None) => {
                kind_given = true;
                match joints::lookup(&name) {
                    Some(k) if kind.is_none() => kind = Some((k, arg.key.span())),
                    Some(_) => errors.at(arg.key.span(), "the joint kind is given twice; expected one joint name"),
                    None => {
                        let all = joints::catalogue().iter().map(|k| k.name);
                        errors.at(
                            arg.key.span(),
                            format!(
                                "unknown joint `{name}`{}; expected one of {}",
                                did_you_mean(&name, all),
                                joints::names()
                            ),
                        )
                    }
                }
            }
            ("formulation", Some(Value::Ident(f))) => {
                formulation_given = true;
                let f_name = f.to_string();
                match Formulation::ALL.into_iter().find(|x| f_name == x.name()) {
                    Some(x) if formulation.is_none() => formulation = Some(x),
                    Some(_) => errors.at(f.span(), "`formulation` is given twice; expected it once"),
                    None => {
                        let all = Formulation::ALL.into_iter().map(|x| x.name());
                        errors.at(
                            f.span(),
                            format!(
                                "unknown formulation `{f}`{}; expected one of {FORMULATIONS}",
                                did_you_mean(&f_name, all)
                            ),
                        )
                    }
                }
            }
            ("ground", Some(Value::Ident(b))) => match b.to_string().as_str() {
                "body1" => ground = (Ground::Body1, b.span(), "body1".into()),
                "body2" => ground = (Ground::Body2, b.span(), "body2".into()),
                other => errors.at(
                    b.span(),
                    format!(
                        "unknown body `{b}`{}; expected `ground = body1` or `ground = body2`",
                        did_you_mean(other, ["body1", "body2"])
                    ),
                ),
            },
            ("formulation" | "ground", Some(v)) => {
                if name == "formulation" {
                    formulation_given = true;
                }
                let example = if name == "ground" { "body1" } else { "omega_body" };
                errors.at(value_span(&v), format!("expected a name, as in `{name} = {example}`"))
            }
            ("rows", Some(Value::Rows(exprs, _))) => {
                kind_given = true;
                if rows.is_some() {
                    errors.at(arg.key.span(), "`rows(...)` is given twice; expected one list of rows");
                }
                rows = Some((exprs, arg.key.span()));
            }
            (tag @ ("body1" | "body2" | "point1" | "point2"), Some(Value::Group(items, _))) => {
                let role = tag_role(tag);
                for item in items {
                    match item.value {
                        Some(v @ Value::List(..)) => {
                            tagged.push((item.key.to_string(), role));
                            consts.push((item.key, v));
                        }
                        _ => errors
                            .at(item.key.span(), format!("expected a vector, as in `{tag}({} = [0, 0, 1])`", item.key)),
                    }
                }
            }
            (_, Some(Value::Rows(..) | Value::Group(..))) => errors.at(
                arg.key.span(),
                format!(
                    "unknown group `{name}(...)`{}; expected `rows(...)`, `body1(...)`, `body2(...)`, `point1(...)` or \
                     `point2(...)`",
                    did_you_mean(&name, ["rows", "body1", "body2", "point1", "point2"])
                ),
            ),
            (_, Some(v)) => consts.push((arg.key, v)),
        }
    }
    // User-written rows: the joint is described by the declaration itself.
    if let Some((exprs, span)) = rows {
        match kind {
            Some((k, _)) => errors.at(
                span,
                format!("a joint is either a catalogue joint or `rows(...)`; remove `rows(...)` or `{}`", k.name),
            ),
            None => {
                let (custom, spans) = custom_kind(&exprs, span, &tagged, &consts, fields, &mut errors);
                kind = Some((custom, span));
                row_spans = spans;
            }
        }
    }
    let Some((kind, kind_span)) = kind else {
        if !kind_given && errors.0.is_empty() {
            errors.at(
                input.ident.span(),
                format!("missing joint kind in `#[joint(...)]`; expected one of {}", joints::names()),
            );
        }
        errors.finish()?;
        unreachable!("finish fails when there are errors")
    };
    let formulation_known = formulation.is_some();
    let formulation = match formulation {
        Some(f) => f,
        None => {
            if !formulation_given {
                errors.at(
                    kind_span,
                    format!("missing formulation; add `formulation = NAME` with NAME one of {FORMULATIONS}"),
                );
            }
            Formulation::OmegaBody
        }
    };
    if formulation.is_relative() && ground.0 != Ground::None {
        errors.at(
            ground.1,
            format!(
                "`ground` needs an absolute formulation (`euler`, `omega_inertial` or `omega_body`); remove `ground = {}` \
                 with `formulation = {}`",
                ground.2,
                formulation.name()
            ),
        );
    }

    // Which parameters this joint takes; an axis (`axis1`, `axis2`, `d`) stands
    // in for the vectors derived from it.
    let accepts = |name: &str| kind.param(name).is_some() || kind.derivation(name).is_some();
    let role_of = |name: &str| {
        kind.param(name)
            .map(|p| p.role)
            .or_else(|| kind.derivation(name).map(|d| Role::Axis(d.body)))
            .unwrap_or(Role::Axis(0))
    };
    let param_names = || {
        let mut names: Vec<&'static str> = kind.params.iter().map(|p| p.name).collect();
        names.extend(kind.derivations.iter().map(|d| d.source));
        names
    };
    let expected = || param_names().iter().map(|n| format!("`{n}`")).collect::<Vec<_>>().join(", ");
    let mut params: Vec<(String, Source)> = Vec::new();
    // Where each parameter was given, for "given twice".
    let mut origins: Vec<(String, String)> = Vec::new();
    // Parameters given but rejected: present for "missing", absent from the result.
    let mut invalid: Vec<String> = Vec::new();
    let mut unknown: Vec<Unknown> = Vec::new();
    let mut add = |errors: &mut Errors, name: String, span: Span, origin: String, source: Option<Source>| {
        if let Some((_, first)) = origins.iter().find(|(n, _)| *n == name) {
            errors.at(span, format!("parameter `{name}` is given twice, here and {first}; expected it once"));
            return;
        }
        origins.push((name.clone(), origin));
        match source {
            Some(source) => params.push((name, source)),
            None => invalid.push(name),
        }
    };
    for (key, value) in consts {
        let name = key.to_string();
        if !accepts(&name) {
            unknown.push(Unknown { name, span: key.span(), field: false });
            continue;
        }
        let role = role_of(&name);
        let origin = format!("by `{name} = ..` in `#[joint(...)]`");
        let checked = if matches!(role, Role::Axis(_) | Role::Point(_)) {
            match value {
                Value::List(v, s) if v.len() == 3 => Ok((v, s)),
                Value::List(v, s) => {
                    Err((s, format!("`{name}` takes 3 components, found {}; expected `{name} = [x, y, z]`", v.len())))
                }
                v => Err((value_span(&v), format!("`{name}` is a vector; expected `{name} = [x, y, z]`"))),
            }
        } else if matches!(role, Role::Scalar) {
            match value {
                Value::Number(v, s) => Ok((vec![v], s)),
                v => Err((value_span(&v), format!("`{name}` is a number; expected `{name} = 1.5`"))),
            }
        } else {
            let message = format!(
                "`{name}` is a time function and cannot be a constant; expected a field `{name}: F` with \
                 `F: joint_runtime::TimeFunction`"
            );
            Err((key.span(), message))
        };
        let (values, span) = match checked {
            Ok(ok) => ok,
            Err((span, message)) => {
                errors.at(span, message);
                add(&mut errors, name, span, origin, None);
                continue;
            }
        };
        if matches!(role, Role::Axis(_)) && values.iter().all(|&x| x == 0.0) {
            errors.at(
                span,
                format!("`{name}` is an axis and must not be zero; expected a direction, as in `{name} = [0, 0, 1]`"),
            );
            add(&mut errors, name, span, origin, None);
            continue;
        }
        if values.iter().any(|x| !x.is_finite()) {
            errors.at(span, format!("`{name}` must be finite; expected `{name} = [x, y, z]` with finite numbers"));
            add(&mut errors, name, span, origin, None);
            continue;
        }
        add(&mut errors, name, key.span(), origin, Some(Source::Const(values, span)));
    }

    // Fields.
    let mut scalar_names: Vec<(String, Span)> = Vec::new();
    let mut unused_fields = Vec::new();
    let mut time_fields: Vec<syn::Type> = Vec::new();
    for field in fields.into_iter().flatten() {
        let Some(ident) = field.ident.clone() else { continue };
        let mut name = ident.to_string();
        let mut span = ident.span();
        let mut skip = false;
        for arg in joint_args(&field.attrs, &mut errors) {
            match arg.value {
                None if arg.key == "skip" => skip = true,
                // A role tag of a user-written joint, read by `custom_kind`.
                None if kind.name == CUSTOM && TAGS.iter().any(|t| arg.key == t) => {}
                None => {
                    name = arg.key.to_string();
                    span = arg.key.span();
                }
                Some(v) => errors.at(
                    value_span(&v),
                    format!(
                        "a field's `#[joint(...)]` takes a parameter name or `skip`; expected `#[joint({})]`",
                        arg.key
                    ),
                ),
            }
        }
        if skip {
            continue;
        }
        if !accepts(&name) {
            unknown.push(Unknown { name, span, field: true });
            continue;
        }
        let origin = if ident == name {
            format!("by field `{ident}`")
        } else {
            format!("by field `{ident}` (`#[joint({name})]`)")
        };
        let role = role_of(&name);
        let want = if kind.derivation(&name).is_some() {
            FieldShape::Frame
        } else if matches!(role, Role::Scalar) {
            FieldShape::Scalar
        } else if matches!(role, Role::Axis(_) | Role::Point(_)) {
            FieldShape::Vector
        } else {
            FieldShape::Time
        };
        if want != FieldShape::Time {
            match field_scalar(&field.ty, want) {
                Some(s) => scalar_names.push((s, field.ty.span())),
                None => {
                    let t = &scalar_name;
                    let shape = match want {
                        FieldShape::Vector => format!("Vector3<{t}>"),
                        FieldShape::Scalar => t.clone(),
                        _ => format!("AxisFrame<{t}>"),
                    };
                    errors.spanned(&field.ty, format!("parameter `{name}` has the wrong type; expected `{shape}`"));
                    // Counted as given, so that one mistake gives one message.
                    add(&mut errors, name, span, origin, None);
                    continue;
                }
            }
        }
        if want == FieldShape::Time {
            time_fields.push(field.ty.clone());
        }
        if formulation.is_relative() && matches!(role, Role::Point(_)) {
            unused_fields.push(ident.clone());
        }
        add(&mut errors, name, span, origin, Some(Source::Field { member: ident, shape: want, span: field.ty.span() }));
    }

    // The scalar: the type parameter the vector fields name (`struct S<T>`), a
    // concrete float, or, with no such field, a fresh parameter of the impl. Other
    // type parameters (a time function's type) pass through.
    let type_params: Vec<&syn::TypeParam> = input.generics.type_params().collect();
    let is_time_type =
        |t: &syn::TypeParam| time_fields.iter().any(|ty| matches!(ty, syn::Type::Path(p) if p.path.is_ident(&t.ident)));
    let named = type_params.iter().find(|t| scalar_names.iter().any(|(s, _)| t.ident == s));
    let scalar = match (named, scalar_names.first()) {
        (Some(t), _) => {
            for (s, span) in &scalar_names {
                if t.ident != s {
                    errors.at(*span, format!("expected the struct's scalar `{}` here, found `{s}`", t.ident));
                }
            }
            ScalarKind::Generic(t.ident.clone())
        }
        (None, None) => match type_params.as_slice() {
            [t] if !is_time_type(t) => ScalarKind::Generic(t.ident.clone()),
            _ => ScalarKind::Any,
        },
        (None, Some((s, span))) => {
            if s != "f64" && s != "f32" {
                errors.at(
                    *span,
                    format!("unknown scalar `{s}`; make the struct generic (`struct S<T>`) or use `f64` or `f32`"),
                );
            }
            for (other, span) in &scalar_names[1..] {
                if other != s {
                    errors.at(*span, format!("all fields must use one scalar; expected `{s}`, found `{other}`"));
                }
            }
            ScalarKind::Concrete(syn::Ident::new(s, *span))
        }
    };

    let excused = crate::params::expand_axes(kind, &mut params, &invalid, kind_span, &mut errors);
    crate::params::check_perpendicular(kind, &params, &mut errors);

    // Every parameter present, in the joint's order.
    let mut ordered = Vec::new();
    let mut missing: Vec<&'static joints::Param> = Vec::new();
    for p in kind.params.iter() {
        let p_name = p.name;
        match params.iter().position(|(n, _)| n == p_name) {
            Some(i) => ordered.push((p_name, params.remove(i).1)),
            None if formulation.is_relative() && matches!(p.role, Role::Point(_)) => {}
            // Given but rejected, or explained by an error about its axis: already reported.
            None if invalid.iter().any(|n| n == p_name) || excused.contains(&p_name) => {}
            None => missing.push(p),
        }
    }

    // Each unknown name stands for the missing parameter it most resembles (or
    // the first one still missing), which is then not reported a second time.
    for u in &unknown {
        let candidates = || missing.iter().map(|p| p.name);
        let close_missing = similar(&u.name, candidates());
        let hint = match close_missing.or_else(|| candidates().next()) {
            Some(m) => {
                missing.retain(|p| p.name != m);
                if close_missing.is_some() { format!(" (did you mean `{m}`?)") } else { format!(" (`{m}` is missing)") }
            }
            None => did_you_mean(&u.name, param_names()),
        };
        let skip = if u.field { "; mark fields that are not parameters `#[joint(skip)]`" } else { "" };
        errors.at(
            u.span,
            format!("unknown parameter `{}` for `{}`{hint}; expected one of {}{skip}", u.name, kind.name, expected()),
        );
    }
    for p in missing {
        let t = &scalar_name;
        let hint = if matches!(p.role, Role::Scalar) {
            format!("`{} = 1.0` in `#[joint(...)]` or a field `{}: {t}`", p.name, p.name)
        } else if matches!(p.role, Role::Axis(_) | Role::Point(_)) {
            format!("`{} = [x, y, z]` in `#[joint(...)]` or a field `{}: Vector3<{t}>`", p.name, p.name)
        } else {
            format!("a field `{}: F` with `F: joint_runtime::TimeFunction`", p.name)
        };
        let also = match kind.derived_from(p.name) {
            Some(der) => format!(" (or give the axis `{}`)", der.source),
            None => String::new(),
        };
        errors.at(kind_span, format!("missing parameter `{}` of `{}`; add {hint}{also}", p.name, kind.name));
    }
    let decl = Declaration {
        ident: input.ident.clone(),
        generics: input.generics.clone(),
        kind,
        formulation,
        ground: ground.0,
        params: ordered,
        scalar,
        unused_fields,
        time_fields,
        row_spans,
        kind_span,
    };
    match errors.finish() {
        Ok(()) => Ok(decl),
        Err(error) => {
            // A stub needs the formulation and a scalar that exists.
            let scalar_known = match &decl.scalar {
                ScalarKind::Concrete(t) => t == "f64" || t == "f32",
                _ => true,
            };
            Err(Failure { error, partial: (formulation_known && scalar_known).then(|| Box::new(decl)) })
        }
    }
}

/// The edit (Levenshtein) distance of `a` and `b`.
fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut diag = row[0];
        row[0] = i + 1;
        for (j, &cb) in b.iter().enumerate() {
            let next = (diag + usize::from(ca != cb)).min(row[j] + 1).min(row[j + 1] + 1);
            diag = row[j + 1];
            row[j + 1] = next;
        }
    }
    row[b.len()]
}

/// The candidate `name` is most likely a misspelling of, if any: at most a third
/// of the letters differ, and not all of them.
fn similar<'a>(name: &str, candidates: impl IntoIterator<Item = &'a str>) -> Option<&'a str> {
    candidates
        .into_iter()
        .map(|c| (edit_distance(name, c), c))
        .filter(|&(d, c)| d < c.chars().count() && d <= (name.chars().count().max(c.chars().count()) / 3).max(1))
        .min_by_key(|&(d, _)| d)
        .map(|(_, c)| c)
}

/// " (did you mean `x`?)" or nothing.
pub fn did_you_mean<'a>(name: &str, candidates: impl IntoIterator<Item = &'a str>) -> String {
    similar(name, candidates).map(|c| format!(" (did you mean `{c}`?)")).unwrap_or_default()
}

fn value_span(v: &Value) -> Span {
    match v {
        Value::Ident(i) => i.span(),
        Value::Number(_, s) | Value::List(_, s) | Value::Rows(_, s) | Value::Group(_, s) => *s,
    }
}

/// The kind name of a joint declared by `rows(...)`.
pub const CUSTOM: &str = "custom";

/// Field tags of a user-written joint.
const TAGS: [&str; 5] = ["body1", "body2", "point1", "point2", "time"];

fn tag_role(tag: &str) -> Role {
    match tag {
        "body1" => Role::Axis(0),
        "body2" => Role::Axis(1),
        "point1" => Role::Point(0),
        "point2" => Role::Point(1),
        _ => Role::Time,
    }
}

/// The joint a `rows(...)` declaration describes: its parameters (with roles from
/// the tags, `rho1`/`rho2` as the joint points, untagged scalar fields and
/// numbers as scalars) and its rows, checked. Leaked to `'static`: a few bytes
/// per derive, and it keeps a user joint the same type as a catalogue one.
fn custom_kind(
    exprs: &[syn::Expr],
    rows_span: Span,
    tagged: &[(String, Role)],
    consts: &[(syn::Ident, Value)],
    fields: Option<&Punctuated<syn::Field, Token![,]>>,
    errors: &mut Errors,
) -> (&'static JointKind, Vec<Span>) {
    let mut params: Vec<joints::Param> = Vec::new();
    let mut add = |name: &str, role: Role| {
        if !params.iter().any(|p| p.name == name) {
            params.push(joints::Param { name: Box::leak(name.to_string().into_boxed_str()), role });
        }
    };
    let point = |name: &str| match name {
        "rho1" => Some(Role::Point(0)),
        "rho2" => Some(Role::Point(1)),
        _ => None,
    };
    for (name, role) in tagged {
        add(name, *role);
    }
    // Vectors whose body is not tagged: reported once, then taken as known (so
    // that neither the rows reading them nor the parameter list report them again).
    let mut untagged: Vec<String> = Vec::new();
    for (key, value) in consts {
        let name = key.to_string();
        if tagged.iter().any(|(n, _)| *n == name) {
            continue;
        }
        match (point(&name), value) {
            (Some(role), _) => add(&name, role),
            (None, Value::Number(..)) => add(&name, Role::Scalar),
            (None, Value::List(..)) => {
                errors.at(
                    key.span(),
                    format!(
                        "the body of the vector `{name}` is not given; expected `body1({name} = [..])`, \
                         `body2({name} = [..])`, `point1({name} = [..])` or `point2({name} = [..])`"
                    ),
                );
                add(&name, Role::Axis(0));
                untagged.push(name);
            }
            _ => {}
        }
    }
    for field in fields.into_iter().flatten() {
        let Some(ident) = &field.ident else { continue };
        let mut name = ident.to_string();
        let mut role = None;
        let mut skip = false;
        for attr in field.attrs.iter().filter(|a| a.path().is_ident("joint")) {
            let Ok(args) = attr.parse_args_with(Punctuated::<Arg, Token![,]>::parse_terminated) else { continue };
            for arg in args {
                let key = arg.key.to_string();
                if key == "skip" {
                    skip = true;
                } else if TAGS.contains(&key.as_str()) {
                    role = Some(tag_role(&key));
                } else if arg.value.is_none() {
                    name = key;
                }
            }
        }
        if skip {
            continue;
        }
        let is_vector =
            matches!(&field.ty, syn::Type::Path(p) if p.path.segments.last().is_some_and(|s| s.ident == "Vector3"));
        match role.or_else(|| point(&name)) {
            Some(r) => add(&name, r),
            None if is_vector => {
                errors.at(
                    ident.span(),
                    format!(
                        "the body of the vector `{name}` is not given; expected a tag `#[joint(body1)]`, \
                         `#[joint(body2)]`, `#[joint(point1)]` or `#[joint(point2)]` on the field"
                    ),
                );
                add(&name, Role::Axis(0));
                untagged.push(name);
            }
            None => add(&name, Role::Scalar),
        }
    }
    let mut rows = Vec::new();
    let mut spans = Vec::new();
    let missing_points: Vec<&'static str> = {
        let role = |n: &str| params.iter().find(|p| p.name == n).map(|p| p.role);
        let all: Vec<&str> = params.iter().map(|p| p.name).collect();
        let names = crate::rows::Names { role: &role, all: &all };
        for e in exprs {
            // A row reading an untagged vector cannot be checked; its tag is reported.
            if mentions(&e.to_token_stream(), &untagged) {
                continue;
            }
            match crate::rows::row(e, &names) {
                Ok(r) => {
                    rows.push(r);
                    spans.push(e.span());
                }
                Err(err) => errors.push(err),
            }
        }
        let uses_d = rows.iter().any(crate::rows::uses_separation);
        ["rho1", "rho2"].into_iter().filter(|p| uses_d && role(p).is_none()).collect()
    };
    // `d` (or `spherical`, `dot2`) needs the joint points; they are then required
    // parameters, reported missing like any other.
    for p in missing_points {
        params.push(joints::Param { name: p, role: point(p).unwrap_or(Role::Point(0)) });
    }
    if exprs.is_empty() {
        errors.at(rows_span, "`rows()` is empty; expected at least one row, as in `rows(spherical, dot1(s, h))`");
    }
    let kind =
        JointKind { name: CUSTOM, params, rows, derivations: Vec::new(), perpendicular: Vec::new(), singularity: None };
    (Box::leak(Box::new(kind)), spans)
}

/// Whether `tokens` contain one of the identifiers `names`.
fn mentions(tokens: &proc_macro2::TokenStream, names: &[String]) -> bool {
    tokens.clone().into_iter().any(|t| match t {
        proc_macro2::TokenTree::Ident(i) => names.iter().any(|n| i == n),
        proc_macro2::TokenTree::Group(g) => mentions(&g.stream(), names),
        _ => false,
    })
}

/// The scalar named by a field type of the wanted shape: `Vector3<T>` → `T`,
/// `SlidingFrame<T>` → `T`, `T` → `T`.
fn field_scalar(ty: &syn::Type, want: FieldShape) -> Option<String> {
    let syn::Type::Path(tp) = ty else { return None };
    let last = tp.path.segments.last()?;
    match want {
        FieldShape::Scalar => (tp.path.segments.len() == 1 && last.arguments.is_none()).then(|| last.ident.to_string()),
        FieldShape::Time => None,
        FieldShape::FramePart(_) => None,
        FieldShape::Vector | FieldShape::Frame => {
            let expect: &[&str] =
                if want == FieldShape::Vector { &["Vector3"] } else { &["AxisFrame", "SlidingFrame"] };
            if !expect.iter().any(|e| last.ident == e) {
                return None;
            }
            let syn::PathArguments::AngleBracketed(args) = &last.arguments else { return None };
            match args.args.iter().collect::<Vec<_>>().as_slice() {
                [syn::GenericArgument::Type(syn::Type::Path(inner))] => inner.path.get_ident().map(|i| i.to_string()),
                _ => None,
            }
        }
    }
}

/// The compile-time twin of `joint_runtime::perpendicular_pair` (same rule, f64).
pub fn perpendicular_pair(d: &[f64]) -> ([f64; 3], [f64; 3]) {
    let n = norm3(d);
    let u = [d[0] / n, d[1] / n, d[2] / n];
    let (ax, ay, az) = (u[0].abs(), u[1].abs(), u[2].abs());
    let e = if ax <= ay && ax <= az {
        [1.0, 0.0, 0.0]
    } else if ay <= az {
        [0.0, 1.0, 0.0]
    } else {
        [0.0, 0.0, 1.0]
    };
    let cross =
        |a: [f64; 3], b: [f64; 3]| [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
    let b = cross(u, e);
    let nb = norm3(&b);
    let b = [b[0] / nb, b[1] / nb, b[2] / nb];
    (b, cross(u, b))
}
