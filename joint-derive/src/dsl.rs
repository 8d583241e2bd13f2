//! The derive's input language: `#[joint(...)]` on the struct and its fields,
//! parsed into a [`Declaration`] that keeps the span of every token it came from.
//!
//! ```text
//! #[joint(KIND, formulation = NAME [, ground = body1|body2] [, PARAM = [x, y, z]]* [, length = x])]
//! struct S<T> { PARAM: Vector3<T>, #[joint(PARAM)] other_name: Vector3<T>, #[joint(skip)] extra: X }
//! ```

use proc_macro2::Span;
use syn::parse::{Parse, ParseStream};
use syn::punctuated::Punctuated;
use syn::spanned::Spanned;
use syn::{Token, bracketed};

use crate::joints::{self, JointKind, Role};
use crate::kinematics::{Formulation, Ground};

/// A value written in `#[joint(name = value)]`.
pub enum Value {
    /// An identifier (`omega_body`, `body1`).
    Ident(syn::Ident),
    /// A number.
    Number(f64, Span),
    /// `[x, y, z]`.
    List(Vec<f64>, Span),
}

/// One item of `#[joint(...)]`.
pub struct Arg {
    /// The key (or the bare word).
    pub key: syn::Ident,
    /// The value after `=`, if any.
    pub value: Option<Value>,
}

fn number(input: ParseStream) -> syn::Result<(f64, Span)> {
    let neg = input.parse::<Option<Token![-]>>()?.is_some();
    let lit: syn::Lit = input.parse()?;
    let v = match &lit {
        syn::Lit::Int(i) => i.base10_parse::<f64>()?,
        syn::Lit::Float(f) => f.base10_parse::<f64>()?,
        _ => return Err(syn::Error::new(lit.span(), "expected a number, as in `[0, 0, 1]` or `0.5`")),
    };
    Ok((if neg { -v } else { v }, lit.span()))
}

impl Parse for Arg {
    fn parse(input: ParseStream) -> syn::Result<Self> {
        let key: syn::Ident = input.parse()?;
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
    /// `SlidingFrame<T>` (only for `d`).
    SlidingFrame,
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
}

/// Collects errors so that one run reports every mistake (after serde's `Ctxt`).
#[derive(Default)]
pub struct Errors(Vec<syn::Error>);

impl Errors {
    /// Records an error at `span`.
    pub fn at(&mut self, span: Span, message: impl std::fmt::Display) {
        self.0.push(syn::Error::new(span, message));
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

/// Parses and checks a derive input.
pub fn parse(input: &syn::DeriveInput) -> syn::Result<Declaration> {
    let mut errors = Errors::default();
    let fields = match &input.data {
        syn::Data::Struct(syn::DataStruct { fields: syn::Fields::Named(named), .. }) => Some(&named.named),
        syn::Data::Struct(syn::DataStruct { fields: syn::Fields::Unit, .. }) => None,
        _ => {
            return Err(syn::Error::new(
                input.ident.span(),
                "`Joint` can only be derived for a struct with named fields, as in `struct Cardan<T> { h: Vector3<T> }`",
            ));
        }
    };

    // Struct attribute: kind, formulation, ground, constants.
    let mut kind: Option<(&'static JointKind, Span)> = None;
    let mut formulation: Option<Formulation> = None;
    let mut ground = (Ground::None, Span::call_site());
    let mut consts: Vec<(syn::Ident, Value)> = Vec::new();
    let args = joint_args(&input.attrs, &mut errors);
    if args.is_empty() && errors.0.is_empty() {
        errors.at(
            input.ident.span(),
            "missing `#[joint(...)]`: name the joint and formulation, as in `#[joint(universal, formulation = omega_body)]`",
        );
    }
    for arg in args {
        let name = arg.key.to_string();
        match (name.as_str(), arg.value) {
            (_, None) => match joints::lookup(&name) {
                Some(k) if kind.is_none() => kind = Some((k, arg.key.span())),
                Some(_) => errors.at(arg.key.span(), "the joint kind is given twice"),
                None => errors.at(
                    arg.key.span(),
                    format!("unknown joint `{name}`; expected one of {}", joints::names()),
                ),
            },
            ("formulation", Some(Value::Ident(f))) => {
                match Formulation::ALL.into_iter().find(|x| f == x.name()) {
                    Some(x) if formulation.is_none() => formulation = Some(x),
                    Some(_) => errors.at(f.span(), "`formulation` is given twice"),
                    None => errors.at(
                        f.span(),
                        format!(
                            "unknown formulation `{f}`; expected one of `euler`, `omega_inertial`, `omega_body`, `relative_b1`, `relative_b2`"
                        ),
                    ),
                }
            }
            ("ground", Some(Value::Ident(b))) => {
                ground = match b.to_string().as_str() {
                    "body1" => (Ground::Body1, b.span()),
                    "body2" => (Ground::Body2, b.span()),
                    _ => {
                        errors.at(b.span(), format!("unknown body `{b}`; expected `ground = body1` or `ground = body2`"));
                        ground
                    }
                }
            }
            ("formulation" | "ground", Some(v)) => {
                errors.at(value_span(&v), format!("expected a name, as in `{name} = {}`", if name == "ground" { "body1" } else { "omega_body" }))
            }
            (_, Some(v)) => consts.push((arg.key, v)),
        }
    }
    let Some((kind, kind_span)) = kind else {
        if errors.0.is_empty() {
            errors.at(
                input.ident.span(),
                format!("missing joint kind in `#[joint(...)]`; expected one of {}", joints::names()),
            );
        }
        errors.finish()?;
        unreachable!("finish fails when there are errors")
    };
    let formulation = match formulation {
        Some(f) => f,
        None => {
            errors.at(kind_span, "missing formulation; add `formulation = euler | omega_inertial | omega_body | relative_b1 | relative_b2`");
            Formulation::OmegaBody
        }
    };
    if formulation.is_relative() && ground.0 != Ground::None {
        errors.at(ground.1, "`ground` applies to the absolute formulations only: in a relative formulation B1 already is the reference frame");
    }

    // Which parameters this joint takes; `d` stands in for `b, c` where allowed.
    let accepts = |name: &str| kind.param(name).is_some() || (name == "d" && kind.param("b").is_some());
    let role_of = |name: &str| kind.param(name).map(|p| p.role).unwrap_or(Role::Axis(0));
    let expected = || {
        let mut names: Vec<String> = kind.params.iter().map(|p| format!("`{}`", p.name)).collect();
        if kind.param("b").is_some() {
            names.push("`d`".into());
        }
        names.join(", ")
    };
    let mut params: Vec<(String, Source)> = Vec::new();
    let mut add = |errors: &mut Errors, name: String, span: Span, source: Source| {
        if params.iter().any(|(n, _)| *n == name) {
            errors.at(span, format!("parameter `{name}` is given twice"));
        } else {
            params.push((name, source));
        }
    };
    for (key, value) in consts {
        let name = key.to_string();
        if !accepts(&name) {
            errors.at(
                key.span(),
                format!("unknown parameter `{name}` for `{}`; expected one of {}", kind.name, expected()),
            );
            continue;
        }
        let role = role_of(&name);
        let (values, span) = match (value, role) {
            (Value::List(v, s), Role::Axis(_) | Role::Point(_)) if v.len() == 3 => (v, s),
            (Value::List(v, s), Role::Axis(_) | Role::Point(_)) => {
                errors.at(s, format!("`{name}` takes 3 components, found {}; expected `{name} = [x, y, z]`", v.len()));
                continue;
            }
            (Value::Number(v, s), Role::Scalar) => (vec![v], s),
            (v, Role::Scalar) => {
                errors.at(value_span(&v), format!("`{name}` is a number; expected `{name} = 1.5`"));
                continue;
            }
            (v, _) => {
                errors.at(value_span(&v), format!("`{name}` is a vector; expected `{name} = [x, y, z]`"));
                continue;
            }
        };
        if matches!(role, Role::Axis(_)) && values.iter().all(|&x| x == 0.0) {
            errors.at(span, format!("`{name}` is an axis and must not be zero"));
            continue;
        }
        if values.iter().any(|x| !x.is_finite()) {
            errors.at(span, format!("`{name}` must be finite"));
            continue;
        }
        add(&mut errors, name, span, Source::Const(values, span));
    }

    // Fields.
    let mut scalar_names: Vec<(String, Span)> = Vec::new();
    let mut unused_fields = Vec::new();
    for field in fields.into_iter().flatten() {
        let Some(ident) = field.ident.clone() else { continue };
        let mut name = ident.to_string();
        let mut span = ident.span();
        let mut skip = false;
        for arg in joint_args(&field.attrs, &mut errors) {
            match arg.value {
                None if arg.key == "skip" => skip = true,
                None => {
                    name = arg.key.to_string();
                    span = arg.key.span();
                }
                Some(v) => {
                    errors.at(value_span(&v), format!("expected a parameter name, as in `#[joint({})]`", arg.key))
                }
            }
        }
        if skip {
            continue;
        }
        if !accepts(&name) {
            errors.at(
                span,
                format!(
                    "unknown parameter `{name}` for `{}`; expected one of {} (mark other fields `#[joint(skip)]`)",
                    kind.name,
                    expected()
                ),
            );
            continue;
        }
        let want = if name == "d" {
            FieldShape::SlidingFrame
        } else if role_of(&name) == Role::Scalar {
            FieldShape::Scalar
        } else {
            FieldShape::Vector
        };
        match field_scalar(&field.ty, want) {
            Some(s) => scalar_names.push((s, field.ty.span())),
            None => {
                let shape = match want {
                    FieldShape::Vector => "Vector3<T>",
                    FieldShape::Scalar => "T",
                    FieldShape::SlidingFrame => "SlidingFrame<T>",
                };
                errors.at(field.ty.span(), format!("parameter `{name}` has the wrong type; expected `{shape}`"));
                // Counted as given, so that one mistake gives one message.
                add(&mut errors, name, span, Source::Const(vec![0.0; 3], span));
                continue;
            }
        }
        if formulation.is_relative() && matches!(role_of(&name), Role::Point(_)) {
            unused_fields.push(ident.clone());
        }
        add(&mut errors, name, span, Source::Field { member: ident, shape: want, span: field.ty.span() });
    }

    // The scalar type.
    let type_params: Vec<&syn::TypeParam> = input.generics.type_params().collect();
    let scalar = match type_params.as_slice() {
        [t] => {
            for (s, span) in &scalar_names {
                if t.ident != s {
                    errors.at(*span, format!("expected the struct's scalar `{}` here, found `{s}`", t.ident));
                }
            }
            ScalarKind::Generic(t.ident.clone())
        }
        [] => match scalar_names.first() {
            None => ScalarKind::Any,
            Some((s, span)) => {
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
        },
        [_, second, ..] => {
            errors.at(second.ident.span(), "expected one type parameter, the scalar, as in `struct Cardan<T>`");
            ScalarKind::Any
        }
    };

    // The sliding direction `d` of `universal_translational`.
    let has = |params: &Vec<(String, Source)>, n: &str| params.iter().any(|(x, _)| x == n);
    if has(&params, "d") {
        let (b, c) = (has(&params, "b"), has(&params, "c"));
        let d_const = params.iter().find_map(|(n, s)| match s {
            Source::Const(v, span) if n == "d" => Some((v.clone(), *span)),
            _ => None,
        });
        if b != c {
            let span = params.iter().find(|(n, _)| n == "d").map(|(_, s)| source_span(s)).unwrap_or(kind_span);
            errors.at(span, "give either the sliding direction `d` alone or `b` and `c` both");
        } else if b && c {
            // `d` is then only a check: constant b, c must be perpendicular to constant d.
            if let Some((d, _)) = &d_const {
                for axis in ["b", "c"] {
                    if let Some((_, Source::Const(v, span))) = params.iter().find(|(n, _)| n == axis) {
                        let cos = dot3(v, d) / (norm3(v) * norm3(d));
                        if cos.abs() > 1e-12 {
                            errors.at(
                                *span,
                                format!(
                                    "`{axis}` must be perpendicular to the sliding direction `d` (cosine {cos:.3e})"
                                ),
                            );
                        }
                    }
                }
            }
            params.retain(|(n, _)| n != "d");
        } else if let Some((d, span)) = d_const {
            // Constant `d`: choose b, c now, by the rule of `joint_runtime::perpendicular_pair`.
            params.retain(|(n, _)| n != "d");
            let (b, c) = perpendicular_pair(&d);
            params.push(("b".into(), Source::Const(b.to_vec(), span)));
            params.push(("c".into(), Source::Const(c.to_vec(), span)));
        }
    }

    // Every parameter present, in the joint's order.
    let mut ordered = Vec::new();
    for p in kind.params {
        let pos = params.iter().position(|(n, _)| n == p.name);
        let from_frame = params.iter().find_map(|(n, s)| match s {
            Source::Field { member, span, shape: FieldShape::SlidingFrame } if n == "d" => {
                Some((member.clone(), *span))
            }
            _ => None,
        });
        match (pos, from_frame) {
            (Some(i), _) => ordered.push((p.name, params.remove(i).1)),
            (None, Some((member, span))) if p.name == "b" || p.name == "c" => {
                ordered.push((p.name, Source::Field { member, shape: FieldShape::SlidingFrame, span }));
            }
            (None, _) if formulation.is_relative() && matches!(p.role, Role::Point(_)) => {}
            (None, _) => {
                let hint = match p.role {
                    Role::Scalar => format!("`{} = 1.0` in `#[joint(...)]` or a field `{}: T`", p.name, p.name),
                    _ => format!("`{} = [x, y, z]` in `#[joint(...)]` or a field `{}: Vector3<T>`", p.name, p.name),
                };
                let also = if p.name == "b" || p.name == "c" { " (or give the sliding direction `d`)" } else { "" };
                errors.at(kind_span, format!("missing parameter `{}` of `{}`: add {hint}{also}", p.name, kind.name));
            }
        }
    }
    errors.finish()?;
    Ok(Declaration {
        ident: input.ident.clone(),
        generics: input.generics.clone(),
        kind,
        formulation,
        ground: ground.0,
        params: ordered,
        scalar,
        unused_fields,
    })
}

fn value_span(v: &Value) -> Span {
    match v {
        Value::Ident(i) => i.span(),
        Value::Number(_, s) | Value::List(_, s) => *s,
    }
}

fn source_span(s: &Source) -> Span {
    match s {
        Source::Const(_, span) | Source::Field { span, .. } => *span,
    }
}

/// The scalar named by a field type of the wanted shape: `Vector3<T>` → `T`,
/// `SlidingFrame<T>` → `T`, `T` → `T`.
fn field_scalar(ty: &syn::Type, want: FieldShape) -> Option<String> {
    let syn::Type::Path(tp) = ty else { return None };
    let last = tp.path.segments.last()?;
    match want {
        FieldShape::Scalar => (tp.path.segments.len() == 1 && last.arguments.is_none()).then(|| last.ident.to_string()),
        FieldShape::Vector | FieldShape::SlidingFrame => {
            let expect = if want == FieldShape::Vector { "Vector3" } else { "SlidingFrame" };
            if last.ident != expect {
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

fn dot3(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

fn norm3(a: &[f64]) -> f64 {
    dot3(a, a).sqrt()
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
