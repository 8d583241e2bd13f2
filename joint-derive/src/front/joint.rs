//! `#[derive(Joint)]`'s declaration: the struct attribute and the fields, read
//! into a [`Declaration`] that keeps the span of every token it came from.
//!
//! ```text
//! #[joint(KIND, formulation = NAME [, ground = body1|body2] [, PARAM = [x, y, z]]* [, length = x])]
//! struct S<T> { PARAM: Vector3<T>, #[joint(PARAM)] other_name: Vector3<T>, #[joint(skip)] extra: X }
//! ```

use std::borrow::Cow;

use proc_macro2::Span;

use super::attr::{self, Arg, Fields, Slot, Value};
use super::context::Errors;
use super::custom::{CUSTOM, TAGS, tag_role};
use super::names::did_you_mean;
use super::resolve::{self, Dialect, Given, GivenValue, Origin, Parameter};
use crate::joints::{self, JointKind, Role};
use crate::kinematics::{Formulation, Ground};

/// The scalar the impl is for.
pub enum ScalarKind {
    /// `struct S<T>`: every `T: SimdRealField + Copy`.
    Generic(syn::Ident),
    /// Fields of one concrete float type.
    Concrete(syn::Ident),
    /// No field names a scalar: every `T: SimdRealField + Copy`, on a non-generic struct.
    Any,
}

/// A checked joint declaration.
pub struct Declaration {
    /// The struct.
    pub ident: syn::Ident,
    /// Its generics.
    pub generics: syn::Generics,
    /// The joint kind: from the catalogue, or the user's own (`rows(...)`).
    pub kind: Cow<'static, JointKind>,
    /// The formulation.
    pub formulation: Formulation,
    /// The grounded body.
    pub ground: Ground,
    /// Parameters in the joint's order.
    pub params: Vec<Parameter>,
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
    /// Whether `second_order` was asked for (the `second_order` method).
    pub second_order: bool,
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

impl Failure {
    fn new(errors: Errors, partial: Option<Declaration>) -> Self {
        let error = match errors.finish() {
            Err(e) => e,
            Ok(()) => syn::Error::new(Span::call_site(), "the declaration does not check"),
        };
        Failure { error, partial: partial.map(Box::new) }
    }
}

const FORMULATIONS: &str = "`euler`, `omega_inertial`, `omega_body`, `relative_b1`, `relative_b2`";
const SHAPE: &str = "expected a struct with named fields, as in `struct Cardan<T> { h: Vector3<T>, .. }`";

fn fields(input: &syn::DeriveInput) -> syn::Result<Fields> {
    let (span, what) = match &input.data {
        syn::Data::Struct(syn::DataStruct { fields: syn::Fields::Named(named), .. }) => {
            return Ok(Some(named.named.clone()));
        }
        syn::Data::Struct(syn::DataStruct { fields: syn::Fields::Unit, .. }) => return Ok(None),
        syn::Data::Struct(syn::DataStruct { fields: syn::Fields::Unnamed(u), .. }) => {
            (u.paren_token.span.join(), "a tuple struct")
        }
        syn::Data::Enum(e) => (e.enum_token.span, "an enum"),
        syn::Data::Union(u) => (u.union_token.span, "a union"),
    };
    Err(syn::Error::new(span, format!("`Joint` cannot be derived for {what}; {SHAPE}")))
}

/// The struct's `#[joint(...)]`, item by item.
struct StructAttr {
    kind: Slot<&'static JointKind>,
    formulation: Slot<Formulation>,
    ground: Slot<(Ground, String)>,
    rows: Slot<Vec<syn::Expr>>,
    second_order: Slot<()>,
    /// `PARAM = VALUE` items.
    consts: Vec<(syn::Ident, Value)>,
    /// Vectors given in `body1(...)` and the other groups, with their roles.
    tagged: Vec<(String, Role)>,
}

impl StructAttr {
    fn read(input: &syn::DeriveInput, errors: &mut Errors) -> Self {
        let mut out = StructAttr {
            kind: Slot::new("the joint kind", "one joint name"),
            formulation: Slot::new("`formulation`", "it once"),
            ground: Slot::new("`ground`", "it once"),
            rows: Slot::new("`rows(...)`", "one list of rows"),
            second_order: Slot::new("`second_order`", "it once"),
            consts: Vec::new(),
            tagged: Vec::new(),
        };
        let args = attr::items(&input.attrs, "joint", errors);
        if args.is_empty() && errors.is_empty() {
            errors.at(
                input.ident.span(),
                "missing `#[joint(...)]`: name the joint and formulation, as in `#[joint(universal, formulation = omega_body)]`",
            );
        }
        for arg in args {
            out.item(arg, errors);
        }
        out
    }

    fn item(&mut self, arg: Arg, errors: &mut Errors) {
        let name = arg.key.to_string();
        match (name.as_str(), arg.value) {
            ("second_order", None) => self.second_order.set(arg.key.span(), (), errors),
            ("second_order", Some(v)) => {
                errors.at(v.span(), "`second_order` takes no value; expected `second_order` alone")
            }
            (_, None) => self.kind_name(&arg.key, errors),
            ("formulation", Some(Value::Ident(f))) => match Formulation::ALL.into_iter().find(|x| f == x.name()) {
                Some(x) => self.formulation.set(f.span(), x, errors),
                None => {
                    self.formulation.written = true;
                    let all = Formulation::ALL.into_iter().map(|x| x.name());
                    let hint = did_you_mean(&f.to_string(), all);
                    errors.at(f.span(), format!("unknown formulation `{f}`{hint}; expected one of {FORMULATIONS}"));
                }
            },
            ("ground", Some(Value::Ident(b))) => match b.to_string().as_str() {
                "body1" => self.ground.set(b.span(), (Ground::Body1, "body1".into()), errors),
                "body2" => self.ground.set(b.span(), (Ground::Body2, "body2".into()), errors),
                other => errors.at(
                    b.span(),
                    format!(
                        "unknown body `{b}`{}; expected `ground = body1` or `ground = body2`",
                        did_you_mean(other, ["body1", "body2"])
                    ),
                ),
            },
            ("formulation" | "ground", Some(v)) => {
                self.formulation.written |= name == "formulation";
                let example = if name == "ground" { "body1" } else { "omega_body" };
                errors.at(v.span(), format!("expected a name, as in `{name} = {example}`"))
            }
            ("rows", Some(Value::Rows(exprs, _))) => self.rows.set(arg.key.span(), exprs, errors),
            (tag @ ("body1" | "body2" | "point1" | "point2"), Some(Value::Group(items, _))) => {
                self.group(tag, items, errors)
            }
            (_, Some(Value::Rows(..) | Value::Group(..))) => errors.at(
                arg.key.span(),
                format!(
                    "unknown group `{name}(...)`{}; expected `rows(...)`, `body1(...)`, `body2(...)`, `point1(...)` or \
                     `point2(...)`",
                    did_you_mean(&name, ["rows", "body1", "body2", "point1", "point2"])
                ),
            ),
            (_, Some(v)) => self.consts.push((arg.key, v)),
        }
    }

    /// A bare word: the joint kind.
    fn kind_name(&mut self, key: &syn::Ident, errors: &mut Errors) {
        let name = key.to_string();
        match joints::lookup(&name) {
            Some(k) => self.kind.set(key.span(), k, errors),
            None => {
                self.kind.written = true;
                let hint = did_you_mean(&name, joints::catalogue().iter().map(|k| k.name));
                errors.at(key.span(), format!("unknown joint `{name}`{hint}; expected one of {}", joints::names()));
            }
        }
    }

    /// `body1(s = [..], ..)`: vectors of a user-written joint with their body.
    fn group(&mut self, tag: &str, items: Vec<Arg>, errors: &mut Errors) {
        for item in items {
            match item.value {
                Some(v @ Value::List(..)) => {
                    self.tagged.push((item.key.to_string(), tag_role(tag)));
                    self.consts.push((item.key, v));
                }
                _ => errors.at(item.key.span(), format!("expected a vector, as in `{tag}({} = [0, 0, 1])`", item.key)),
            }
        }
    }
}

/// The joint kind: the catalogue's, or one the declaration writes itself.
fn joint_kind(
    attr: &mut StructAttr,
    input: &syn::DeriveInput,
    fields: &Fields,
    errors: &mut Errors,
) -> Option<(Cow<'static, JointKind>, Vec<Span>, Span)> {
    let kind_written = attr.kind.written || attr.rows.written;
    match (attr.kind.take(), attr.rows.take()) {
        (Some((k, span)), None) => Some((Cow::Borrowed(k), Vec::new(), span)),
        (Some((k, _)), Some((_, span))) => {
            let message =
                format!("a joint is either a catalogue joint or `rows(...)`; remove `rows(...)` or `{}`", k.name);
            errors.at(span, message);
            None
        }
        (None, Some((exprs, span))) => {
            let (kind, spans) = super::custom::kind(&exprs, span, &attr.tagged, &attr.consts, fields, errors);
            Some((Cow::Owned(kind), spans, span))
        }
        (None, None) => {
            if !kind_written && errors.is_empty() {
                let message = format!("missing joint kind in `#[joint(...)]`; expected one of {}", joints::names());
                errors.at(input.ident.span(), message);
            }
            None
        }
    }
}

/// The parameters written in the attribute and the fields, by name.
fn given(consts: Vec<(syn::Ident, Value)>, fields: &Fields, custom: bool, errors: &mut Errors) -> Vec<Given> {
    let mut out = Vec::new();
    for (key, value) in consts {
        let list = matches!(value, Value::List(..));
        let value = match value.numbers() {
            Some((values, span)) => GivenValue::Numbers { values, span, list },
            None => GivenValue::Rejected,
        };
        out.push(Given { name: key.to_string(), span: key.span(), origin: Origin::Attribute, value });
    }
    for field in fields.iter().flatten() {
        let Some(ident) = field.ident.clone() else { continue };
        let (mut name, mut span, mut skip) = (ident.to_string(), ident.span(), false);
        for arg in attr::items(&field.attrs, "joint", errors) {
            match arg.value {
                None if arg.key == "skip" => skip = true,
                // A role tag of a user-written joint, read by `custom::kind`.
                None if custom && TAGS.iter().any(|t| arg.key == t) => {}
                None => (name, span) = (arg.key.to_string(), arg.key.span()),
                Some(v) => errors.at(
                    v.span(),
                    format!(
                        "a field's `#[joint(...)]` takes a parameter name or `skip`; expected `#[joint({})]`",
                        arg.key
                    ),
                ),
            }
        }
        if !skip {
            let value = GivenValue::Field { member: ident.clone(), ty: Box::new(field.ty.clone()) };
            out.push(Given { name, span, origin: Origin::Field(ident), value });
        }
    }
    out
}

/// The scalar: the type parameter the numeric fields name (`struct S<T>`), a
/// concrete float, or, with no such field, a fresh parameter of the impl.
/// Other type parameters (a time function's type) pass through.
fn scalar(
    generics: &syn::Generics,
    scalars: &[(String, Span)],
    time_types: &[syn::Type],
    errors: &mut Errors,
) -> ScalarKind {
    let type_params: Vec<&syn::TypeParam> = generics.type_params().collect();
    let is_time_type =
        |t: &syn::TypeParam| time_types.iter().any(|ty| matches!(ty, syn::Type::Path(p) if p.path.is_ident(&t.ident)));
    let named = type_params.iter().find(|t| scalars.iter().any(|(s, _)| t.ident == s));
    match (named, scalars.first()) {
        (Some(t), _) => {
            for (s, span) in scalars.iter().filter(|(s, _)| t.ident != s) {
                errors.at(*span, format!("expected the struct's scalar `{}` here, found `{s}`", t.ident));
            }
            ScalarKind::Generic(t.ident.clone())
        }
        (None, None) => match type_params.as_slice() {
            [t] if !is_time_type(t) => ScalarKind::Generic(t.ident.clone()),
            _ => ScalarKind::Any,
        },
        (None, Some((s, span))) => {
            if s != "f64" && s != "f32" {
                let message =
                    format!("unknown scalar `{s}`; make the struct generic (`struct S<T>`) or use `f64` or `f32`");
                errors.at(*span, message);
            }
            for (other, span) in scalars[1..].iter().filter(|(o, _)| o != s) {
                errors.at(*span, format!("all fields must use one scalar; expected `{s}`, found `{other}`"));
            }
            ScalarKind::Concrete(syn::Ident::new(s, *span))
        }
    }
}

/// The formulation, reported missing when none was written (then `omega_body`,
/// so that the other checks still run).
fn formulation(attr: &mut StructAttr, kind_span: Span, errors: &mut Errors) -> (Formulation, bool) {
    let written = attr.formulation.written;
    match attr.formulation.take() {
        Some((f, _)) => (f, true),
        None => {
            if !written {
                let message = format!("missing formulation; add `formulation = NAME` with NAME one of {FORMULATIONS}");
                errors.at(kind_span, message);
            }
            (Formulation::OmegaBody, false)
        }
    }
}

/// Parses and checks a derive input.
pub fn parse(input: &syn::DeriveInput) -> Result<Declaration, Failure> {
    let mut errors = Errors::new();
    let fields = match fields(input) {
        Ok(f) => f,
        Err(e) => {
            errors.push(e);
            return Err(Failure::new(errors, None));
        }
    };
    let mut attr = StructAttr::read(input, &mut errors);
    let Some((kind, row_spans, kind_span)) = joint_kind(&mut attr, input, &fields, &mut errors) else {
        return Err(Failure::new(errors, None));
    };
    let (formulation, formulation_known) = formulation(&mut attr, kind_span, &mut errors);
    let ground = attr.ground.take();
    if let Some(((_, written), span)) = &ground
        && formulation.is_relative()
    {
        let message = format!(
            "`ground` needs an absolute formulation (`euler`, `omega_inertial` or `omega_body`); remove `ground = \
             {written}` with `formulation = {}`",
            formulation.name()
        );
        errors.at(*span, message);
    }
    let scalar_name = match input.generics.type_params().collect::<Vec<_>>().as_slice() {
        [t] => t.ident.to_string(),
        _ => "f64".to_string(),
    };
    let given = given(std::mem::take(&mut attr.consts), &fields, kind.name == CUSTOM, &mut errors);
    let dialect = Dialect { scalar: &scalar_name, fields_by_name: true };
    let resolved = resolve::resolve(&kind, formulation, given, &dialect, kind_span, &mut errors);
    let scalar = scalar(&input.generics, &resolved.scalars, &resolved.time_types, &mut errors);
    let decl = Declaration {
        ident: input.ident.clone(),
        generics: input.generics.clone(),
        kind,
        formulation,
        ground: ground.map_or(Ground::None, |((g, _), _)| g),
        params: resolved.params,
        scalar,
        unused_fields: resolved.unused_fields,
        time_fields: resolved.time_types,
        row_spans,
        kind_span,
        second_order: attr.second_order.take().is_some(),
    };
    if errors.is_empty() {
        errors.finish().map_err(|e| Failure { error: e, partial: None })?;
        return Ok(decl);
    }
    // A stub needs the formulation and a scalar that exists.
    let scalar_known = !matches!(&decl.scalar, ScalarKind::Concrete(t) if t != "f64" && t != "f32");
    Err(Failure::new(errors, (formulation_known && scalar_known).then_some(decl)))
}
