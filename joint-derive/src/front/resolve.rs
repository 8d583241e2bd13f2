//! The one parameter resolver of both derives: what was given (constants and
//! fields, by name) against what the joint takes, with the person-friendly axes
//! expanded (`axis1 → f, g`, ...), constant geometry checked (shapes, zero
//! axes, non-finite numbers, axes that must be perpendicular), and unknown,
//! repeated and missing parameters reported in one wording, an unknown one
//! with the name it most likely stands for. Both derives call it, so a mistake
//! they share is worded once (`front/tests.rs` holds them to it).

use proc_macro2::Span;

use super::attr::{Number, known};
use super::context::Errors;
use super::geometry::{cosine, list, perpendicular_pair};
use super::names::{did_you_mean, quoted, similar};
use crate::joints::{Derivation, JointKind, Part, Role};
use crate::kinematics::Formulation;

/// Where a parameter's value comes from.
#[derive(Clone)]
pub enum Source {
    /// Numbers written in the attribute: folded into the generated code, or,
    /// naming constants, emitted as written.
    Const(Vec<Number>, Span),
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

impl Source {
    /// Where the value was written.
    pub fn span(&self) -> Span {
        match self {
            Source::Const(_, span) | Source::Field { span, .. } => *span,
        }
    }

    /// The values, when the derive knows them all.
    pub fn known(&self) -> Option<Vec<f64>> {
        match self {
            Source::Const(v, _) => known(v),
            Source::Field { .. } => None,
        }
    }
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
    FramePart(Part),
    /// Any type implementing `joint_runtime::TimeFunction` (a driver's time function).
    Time,
}

/// A resolved parameter of a joint.
#[derive(Clone)]
pub struct Parameter {
    /// Its name in the joint (`s`, `rho1`, `length`).
    pub name: String,
    /// Its value.
    pub source: Source,
}

/// A parameter as written, before it is checked against the joint.
pub struct Given {
    /// The name it was given under.
    pub name: String,
    /// The span of that name.
    pub span: Span,
    /// Where it was written.
    pub origin: Origin,
    /// What was written.
    pub value: GivenValue,
}

/// Where a parameter was given, for "given twice, here and ...".
pub enum Origin {
    /// `name = ..` in the attribute.
    Attribute,
    /// A struct field, possibly renamed by `#[joint(name)]`.
    Field(syn::Ident),
}

/// What was written for a parameter.
pub enum GivenValue {
    /// Numbers; `list` when written in brackets.
    Numbers {
        /// The numbers.
        values: Vec<Number>,
        /// Where.
        span: Span,
        /// `[..]` rather than a lone number.
        list: bool,
    },
    /// A field and its type.
    Field {
        /// The field.
        member: syn::Ident,
        /// Its type as written (boxed: it is large).
        ty: Box<syn::Type>,
    },
    /// Something else, already reported: counted as given, so that one mistake
    /// gives one message.
    Rejected,
}

/// How the derive's user writes a parameter, for the hints of messages.
pub struct Dialect<'a> {
    /// The scalar as written (`T` of `struct S<T>`, `f64` in a scene).
    pub scalar: &'a str,
    /// Parameters are fields named after them (`#[derive(Joint)]`), rather than
    /// `name = FIELD` in the attribute (`#[derive(Scene)]`).
    pub fields_by_name: bool,
}

impl Dialect<'_> {
    /// "a field `h: Vector3<T>`", or "`h = FIELD` with a field `FIELD: Vector3<f64>`".
    fn field(&self, name: &str, ty: &str) -> String {
        if self.fields_by_name {
            format!("a field `{name}: {ty}`")
        } else {
            format!("`{name} = FIELD` with a field `FIELD: {ty}`")
        }
    }

    /// The type a field of `shape` has.
    fn field_type(&self, shape: FieldShape) -> String {
        let t = self.scalar;
        match shape {
            FieldShape::Vector => format!("Vector3<{t}>"),
            FieldShape::Scalar => t.to_string(),
            FieldShape::Frame | FieldShape::FramePart(_) => format!("AxisFrame<{t}>"),
            FieldShape::Time => "F".to_string(),
        }
    }
}

/// Numbers written for a parameter, with the span of its key.
struct Written {
    values: Vec<Number>,
    span: Span,
    list: bool,
    key: Span,
}

/// What the resolver found.
pub struct Resolved {
    /// Every parameter the formulation reads, in the joint's order.
    pub params: Vec<Parameter>,
    /// The scalar each numeric field names, with the field type's span.
    pub scalars: Vec<(String, Span)>,
    /// The types of time-function fields (each needs a `TimeFunction` bound).
    pub time_types: Vec<syn::Type>,
    /// Fields holding parameters the formulation does not read.
    pub unused_fields: Vec<syn::Ident>,
}

/// The role of a name a joint accepts: its parameters, and its axes.
pub fn role_of(kind: &JointKind, name: &str) -> Option<Role> {
    kind.param(name).map(|p| p.role).or_else(|| kind.derivation(name).map(|d| Role::Axis(d.body)))
}

/// The field shape a parameter called `name` needs.
pub fn shape_of(kind: &JointKind, name: &str) -> FieldShape {
    match role_of(kind, name) {
        _ if kind.derivation(name).is_some() => FieldShape::Frame,
        Some(Role::Scalar) => FieldShape::Scalar,
        Some(Role::Time) => FieldShape::Time,
        _ => FieldShape::Vector,
    }
}

/// Every name `kind` accepts: its parameters, then its axes.
fn accepted(kind: &JointKind) -> Vec<&str> {
    kind.params.iter().map(|p| p.name.as_ref()).chain(kind.derivations.iter().map(|d| d.source)).collect()
}

/// The resolver's working set.
struct Resolver<'a> {
    kind: &'a JointKind,
    formulation: Formulation,
    dialect: &'a Dialect<'a>,
    /// Accepted so far, by name.
    params: Vec<Parameter>,
    /// Each name given, with where (for "given twice").
    origins: Vec<(String, String)>,
    /// Given but rejected: present for "missing", absent from the result.
    rejected: Vec<String>,
    /// Not a parameter of the joint: (name, span, from a field).
    unknown: Vec<(String, Span, bool)>,
    out: Resolved,
}

/// Checks `given` against `kind` (read in `formulation`) and returns every
/// parameter in the joint's order; every mistake goes to `errors`.
pub fn resolve(
    kind: &JointKind,
    formulation: Formulation,
    given: Vec<Given>,
    dialect: &Dialect,
    kind_span: Span,
    errors: &mut Errors,
) -> Resolved {
    let empty = Resolved { params: Vec::new(), scalars: Vec::new(), time_types: Vec::new(), unused_fields: Vec::new() };
    let mut r = Resolver {
        kind,
        formulation,
        dialect,
        params: Vec::new(),
        origins: Vec::new(),
        rejected: Vec::new(),
        unknown: Vec::new(),
        out: empty,
    };
    for g in given {
        r.accept(g, errors);
    }
    let mut excused = Vec::new();
    for der in &kind.derivations {
        r.expand_axis(der, kind_span, &mut excused, errors);
    }
    r.check_perpendicular(errors);
    let missing = r.order(&excused);
    r.report_unknown_and_missing(missing, kind_span, errors);
    r.out
}

impl Resolver<'_> {
    /// Records one given parameter, checked against its role.
    fn accept(&mut self, g: Given, errors: &mut Errors) {
        let Given { name, span, origin, value } = g;
        let Some(role) = role_of(self.kind, &name) else {
            self.unknown.push((name, span, matches!(origin, Origin::Field(_))));
            return;
        };
        let origin = match origin {
            Origin::Attribute => format!("by `{name} = ..` in `#[joint(...)]`"),
            Origin::Field(ident) if ident == name => format!("by field `{ident}`"),
            Origin::Field(ident) => format!("by field `{ident}` (`#[joint({name})]`)"),
        };
        if let Some((_, first)) = self.origins.iter().find(|(n, _)| *n == name) {
            errors.at(span, format!("parameter `{name}` is given twice, here and {first}; expected it once"));
            return;
        }
        self.origins.push((name.clone(), origin));
        let source = match value {
            GivenValue::Numbers { values, span: at, list } => {
                self.constant(&name, role, Written { values, span: at, list, key: span }, errors)
            }
            GivenValue::Field { member, ty } => self.field(&name, role, member, &ty, errors),
            GivenValue::Rejected => None,
        };
        match source {
            Some(source) => self.params.push(Parameter { name, source }),
            None => self.rejected.push(name),
        }
    }

    /// A constant for `name`, checked: its shape, a zero axis, non-finite numbers.
    fn constant(&self, name: &str, role: Role, written: Written, errors: &mut Errors) -> Option<Source> {
        let Written { values, span, list, key } = written;
        let vector = matches!(role, Role::Axis(_) | Role::Point(_));
        let problem = match role {
            _ if vector && !list => Some(format!("`{name}` is a vector; expected `{name} = [x, y, z]`")),
            _ if vector && values.len() != 3 => {
                Some(format!("`{name}` takes 3 components, found {}; expected `{name} = [x, y, z]`", values.len()))
            }
            Role::Scalar if list => Some(format!("`{name}` is a number; expected `{name} = 1.5`")),
            Role::Time => Some(format!(
                "`{name}` is a time function and cannot be a constant; expected {} with \
                 `F: joint_runtime::TimeFunction`",
                self.dialect.field(name, "F")
            )),
            _ => None,
        };
        let known = known(&values);
        let problem = problem.or_else(|| match &known {
            Some(v) if matches!(role, Role::Axis(_)) && v.iter().all(|&x| x == 0.0) => Some(format!(
                "`{name}` is an axis and must not be zero; expected a direction, as in `{name} = [0, 0, 1]`"
            )),
            _ if values.iter().any(|x| x.known().is_some_and(|x| !x.is_finite())) => {
                let form = if vector { "[x, y, z]" } else { "1.5" };
                Some(format!("`{name}` must be finite; expected `{name} = {form}` with finite numbers"))
            }
            _ => None,
        });
        match problem {
            Some(message) => {
                errors.at(if role == Role::Time { key } else { span }, message);
                None
            }
            None => Some(Source::Const(values, span)),
        }
    }

    /// A field for `name`, its type checked against the shape the role needs.
    fn field(
        &mut self,
        name: &str,
        role: Role,
        member: syn::Ident,
        ty: &syn::Type,
        errors: &mut Errors,
    ) -> Option<Source> {
        let shape = shape_of(self.kind, name);
        if shape == FieldShape::Time {
            self.out.time_types.push(ty.clone());
        } else {
            match field_scalar(ty, shape) {
                Some(s) => self.out.scalars.push((s, syn::spanned::Spanned::span(ty))),
                None => {
                    let want = self.dialect.field_type(shape);
                    errors.spanned(ty, format!("parameter `{name}` has the wrong type; expected `{want}`"));
                    return None;
                }
            }
        }
        if self.formulation.is_relative() && matches!(role, Role::Point(_)) {
            self.out.unused_fields.push(member.clone());
        }
        Some(Source::Field { member, shape, span: syn::spanned::Spanned::span(ty) })
    }

    fn has(&self, name: &str) -> bool {
        self.params.iter().any(|p| p.name == name) || self.rejected.iter().any(|x| x == name)
    }

    fn source(&self, name: &str) -> Option<&Source> {
        self.params.iter().find(|p| p.name == name).map(|p| &p.source)
    }

    /// Expands an axis given instead of the vectors derived from it: a
    /// constant now, by the rule of `joint_runtime::perpendicular_pair`; a
    /// field through its parts. With every derived vector given as well, the
    /// axis is only a check. Names whose absence an error explains go to `excused`.
    fn expand_axis(&mut self, der: &Derivation, kind_span: Span, excused: &mut Vec<String>, errors: &mut Errors) {
        if !self.has(der.source) {
            return;
        }
        let all: Vec<&str> = der.outputs.iter().map(|(o, _)| *o).collect();
        let given: Vec<&str> = all.iter().copied().filter(|o| self.has(o)).collect();
        let source = self.source(der.source).cloned();
        let span = source.as_ref().map_or(kind_span, Source::span);
        if !given.is_empty() && given.len() < all.len() {
            excused.extend(all.iter().map(|s| s.to_string()));
            let rest: Vec<&str> = all.iter().copied().filter(|o| !given.contains(o)).collect();
            errors.at(
                span,
                format!(
                    "`{}` with {} but not {}; expected the axis `{}` alone, or all of {}",
                    der.source,
                    quoted(given.iter().copied()),
                    quoted(rest),
                    der.source,
                    quoted(all.iter().copied())
                ),
            );
        } else if !given.is_empty() {
            self.check_axis_parts(der, errors);
        } else {
            match source {
                Some(Source::Const(values, span)) => match known(&values) {
                    Some(a) => self.split_constant(der, &a, span),
                    None => {
                        excused.extend(all.iter().map(|s| s.to_string()));
                        errors.at(
                            span,
                            format!(
                                "`{}` is split into perpendicular vectors at compile time, so its components must be \
                                 numbers; expected numbers, or {} given as well (named constants are accepted there)",
                                der.source,
                                quoted(all.iter().copied())
                            ),
                        );
                    }
                },
                Some(Source::Field { member, span, .. }) => {
                    for (out, part) in &der.outputs {
                        let shape = FieldShape::FramePart(*part);
                        let source = Source::Field { member: member.clone(), shape, span };
                        self.params.push(Parameter { name: out.to_string(), source });
                    }
                }
                // Given but rejected: already reported.
                None => excused.extend(all.iter().map(|s| s.to_string())),
            }
        }
        self.params.retain(|p| p.name != der.source);
    }

    /// A constant axis's derived vectors, now.
    fn split_constant(&mut self, der: &Derivation, a: &[f64], span: Span) {
        let (b, c) = perpendicular_pair(a);
        for (out, part) in &der.outputs {
            let v = match part {
                Part::Axis => a.to_vec(),
                Part::First => b.to_vec(),
                Part::Second => c.to_vec(),
            };
            let source = Source::Const(v.into_iter().map(Number::Known).collect(), span);
            self.params.push(Parameter { name: out.to_string(), source });
        }
    }

    /// With an axis and all its derived vectors given: constant perpendicular
    /// parts must be perpendicular to a constant axis.
    fn check_axis_parts(&self, der: &Derivation, errors: &mut Errors) {
        let Some(a) = self.source(der.source).and_then(Source::known) else { return };
        for (out, part) in &der.outputs {
            let Some(source) = self.source(out).filter(|_| *part != Part::Axis) else { continue };
            let Some(v) = source.known() else { continue };
            let cos = cosine(&v, &a);
            if cos.abs() > 1e-12 {
                let s = der.source;
                errors.at(
                    source.span(),
                    format!(
                        "`{out} = {}` is not perpendicular to `{s} = {}` (cosine {cos:.3e}); expected `{out}` ⟂ `{s}`, \
                         or `{s}` alone",
                        list(&v),
                        list(&a)
                    ),
                );
            }
        }
    }

    /// Constant vectors of one body that must be perpendicular, checked.
    fn check_perpendicular(&self, errors: &mut Errors) {
        for (a, b) in &self.kind.perpendicular {
            let (Some(va), Some(sb)) = (self.source(a).and_then(Source::known), self.source(b)) else { continue };
            let Some(vb) = sb.known() else { continue };
            let cos = cosine(&va, &vb);
            if cos.abs() > 1e-12 {
                errors.at(
                    sb.span(),
                    format!(
                        "`{b} = {}` must be perpendicular to `{a} = {}` (cosine {cos:.3e}); expected `{a}` ⟂ `{b}`",
                        list(&vb),
                        list(&va)
                    ),
                );
            }
        }
    }

    /// The parameters in the joint's order; returns the names still missing.
    fn order(&mut self, excused: &[String]) -> Vec<String> {
        let mut missing = Vec::new();
        for p in &self.kind.params {
            let name = p.name.as_ref();
            match self.params.iter().position(|x| x.name == name) {
                Some(i) => self.out.params.push(self.params.remove(i)),
                None if self.formulation.is_relative() && matches!(p.role, Role::Point(_)) => {}
                // Given but rejected, or explained by an error about its axis: already reported.
                None if self.rejected.iter().any(|n| n == name) || excused.iter().any(|n| n == name) => {}
                None => missing.push(name.to_string()),
            }
        }
        missing
    }

    /// Each unknown name stands for the missing parameter it most resembles (or
    /// the first one still missing), which is then not reported a second time.
    fn report_unknown_and_missing(&self, mut missing: Vec<String>, kind_span: Span, errors: &mut Errors) {
        let names = accepted(self.kind);
        for (name, span, from_field) in &self.unknown {
            let close = similar(name, missing.iter().map(String::as_str)).map(str::to_string);
            let hint = match close.clone().or_else(|| missing.first().cloned()) {
                Some(m) => {
                    missing.retain(|x| *x != m);
                    if close.is_some() { format!(" (did you mean `{m}`?)") } else { format!(" (`{m}` is missing)") }
                }
                None => did_you_mean(name, names.iter().copied()),
            };
            let skip = if *from_field { "; mark fields that are not parameters `#[joint(skip)]`" } else { "" };
            errors.at(
                *span,
                format!(
                    "unknown parameter `{name}` for `{}`{hint}; expected one of {}{skip}",
                    self.kind.name,
                    quoted(names.iter().copied())
                ),
            );
        }
        for name in missing {
            errors.at(
                kind_span,
                format!("missing parameter `{name}` of `{}`; add {}", self.kind.name, self.how_to_give(&name)),
            );
        }
    }

    /// "`h = [x, y, z]` in `#[joint(...)]` or a field `h: Vector3<T>` (or give the axis `axis2`)".
    fn how_to_give(&self, name: &str) -> String {
        let role = role_of(self.kind, name);
        let shape = shape_of(self.kind, name);
        let field = self.dialect.field(name, &self.dialect.field_type(shape));
        let hint = match role {
            Some(Role::Scalar) => format!("`{name} = 1.0` in `#[joint(...)]` or {field}"),
            Some(Role::Time) => format!("{field} with `F: joint_runtime::TimeFunction`"),
            _ => format!("`{name} = [x, y, z]` in `#[joint(...)]` or {field}"),
        };
        match self.kind.derived_from(name) {
            Some(der) => format!("{hint} (or give the axis `{}`)", der.source),
            None => hint,
        }
    }
}

/// The scalar named by a field type of the wanted shape: `Vector3<T>` → `T`,
/// `SlidingFrame<T>` → `T`, `T` → `T`.
fn field_scalar(ty: &syn::Type, want: FieldShape) -> Option<String> {
    let syn::Type::Path(tp) = ty else { return None };
    let last = tp.path.segments.last()?;
    let expect: &[&str] = match want {
        FieldShape::Scalar => {
            return (tp.path.segments.len() == 1 && last.arguments.is_none()).then(|| last.ident.to_string());
        }
        FieldShape::Time | FieldShape::FramePart(_) => return None,
        FieldShape::Vector => &["Vector3"],
        FieldShape::Frame => &["AxisFrame", "SlidingFrame"],
    };
    if !expect.iter().any(|e| last.ident == e) {
        return None;
    }
    let syn::PathArguments::AngleBracketed(args) = &last.arguments else { return None };
    match args.args.iter().collect::<Vec<_>>().as_slice() {
        [syn::GenericArgument::Type(syn::Type::Path(inner))] => inner.path.get_ident().map(|i| i.to_string()),
        _ => None,
    }
}
