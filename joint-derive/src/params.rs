//! Resolving a joint's parameters: what was given (constants and fields) against
//! what the joint takes, with the person-friendly axes (`axis1 → f, g`, ...)
//! expanded and constant geometry checked. Used by `#[derive(Scene)]`.

use proc_macro2::Span;

use crate::dsl::{self, Errors, FieldShape, Source, perpendicular_pair};
use crate::joints::{JointKind, Part, Role};
use crate::kinematics::Formulation;

/// `[x, y, z]` as written, for messages.
pub fn list(v: &[f64]) -> String {
    format!("[{}]", v.iter().map(|x| format!("{x}")).collect::<Vec<_>>().join(", "))
}

/// `a · b`.
pub fn dot3(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// `|a|`.
pub fn norm3(a: &[f64]) -> f64 {
    dot3(a, a).sqrt()
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

/// Expands the axes a person gave instead of the vectors derived from them
/// (`axis1 → f, g`, `d → b, c`, ...): a constant axis is resolved now, by the
/// rule of `joint_runtime::perpendicular_pair`; a field is read through its parts.
/// With every derived vector given as well, the axis is only a check. `invalid`
/// names were given but rejected. Returns the derived names whose absence an
/// error already explains.
pub fn expand_axes(
    kind: &JointKind,
    params: &mut Vec<(String, Source)>,
    invalid: &[String],
    kind_span: Span,
    errors: &mut Errors,
) -> Vec<&'static str> {
    let has =
        |params: &Vec<(String, Source)>, n: &str| params.iter().any(|(x, _)| x == n) || invalid.iter().any(|x| x == n);
    // Derived parameters whose absence is explained by an error already reported.
    let mut excused: Vec<&'static str> = Vec::new();
    for der in &kind.derivations {
        if !has(params, der.source) {
            continue;
        }
        let source_span =
            params.iter().find(|(n, _)| n == der.source).map(|(_, s)| source_span(s)).unwrap_or(kind_span);
        let given: Vec<&'static str> = der.outputs.iter().map(|(o, _)| *o).filter(|o| has(params, o)).collect();
        let all: Vec<&'static str> = der.outputs.iter().map(|(o, _)| *o).collect();
        if !given.is_empty() && given.len() < all.len() {
            excused.extend(all.iter().copied());
            let list = |v: &[&str]| v.iter().map(|n| format!("`{n}`")).collect::<Vec<_>>().join(", ");
            errors.at(
                source_span,
                format!(
                    "`{}` with {} but not {}; expected the axis `{}` alone, or all of {}",
                    der.source,
                    list(&given),
                    list(&all.iter().copied().filter(|o| !given.contains(o)).collect::<Vec<_>>()),
                    der.source,
                    list(&all)
                ),
            );
            continue;
        }
        let source_const = params.iter().find_map(|(n, s)| match s {
            Source::Const(v, span) if n == der.source => Some((v.clone(), *span)),
            _ => None,
        });
        let source_field = params.iter().find_map(|(n, s)| match s {
            Source::Field { member, span, shape: FieldShape::Frame } if n == der.source => {
                Some((member.clone(), *span))
            }
            _ => None,
        });
        if !given.is_empty() {
            // Every derived vector given as well: the axis is then only a check,
            // constant perpendicular parts must be perpendicular to a constant axis.
            if let Some((a, _)) = &source_const {
                for (out, part) in &der.outputs {
                    if *part == Part::Axis {
                        continue;
                    }
                    if let Some((_, Source::Const(v, span))) = params.iter().find(|(n, _)| n == out) {
                        let cos = dot3(v, a) / (norm3(v) * norm3(a));
                        if cos.abs() > 1e-12 {
                            errors.at(
                                *span,
                                format!(
                                    "`{out} = {}` is not perpendicular to `{} = {}` (cosine {cos:.3e}); \
                                     expected `{out}` ⟂ `{}`, or `{}` alone",
                                    list(v),
                                    der.source,
                                    list(a),
                                    der.source,
                                    der.source
                                ),
                            );
                        }
                    }
                }
            }
        } else if let Some((a, span)) = source_const {
            let (b, c) = perpendicular_pair(&a);
            for (out, part) in &der.outputs {
                let v = match part {
                    Part::Axis => a.clone(),
                    Part::First => b.to_vec(),
                    Part::Second => c.to_vec(),
                };
                params.push(((*out).into(), Source::Const(v, span)));
            }
        } else if let Some((member, span)) = source_field {
            for (out, part) in &der.outputs {
                params.push((
                    (*out).into(),
                    Source::Field { member: member.clone(), shape: FieldShape::FramePart(*part), span },
                ));
            }
        } else {
            // Given but rejected (wrong type): already reported.
            excused.extend(all.iter().copied());
        }
        params.retain(|(n, _)| n != der.source);
    }

    excused
}

/// Constant vectors of one body that must be perpendicular, checked.
pub fn check_perpendicular(kind: &JointKind, params: &[(String, Source)], errors: &mut Errors) {
    for (a, b) in &kind.perpendicular {
        let constant = |n: &str| {
            params.iter().find_map(|(x, s)| match s {
                Source::Const(v, span) if x == n => Some((v.clone(), *span)),
                _ => None,
            })
        };
        if let (Some((va, _)), Some((vb, span))) = (constant(a), constant(b)) {
            let cos = dot3(&va, &vb) / (norm3(&va) * norm3(&vb));
            if cos.abs() > 1e-12 {
                errors.at(
                    span,
                    format!(
                        "`{b} = {}` must be perpendicular to `{a} = {}` (cosine {cos:.3e}); expected `{a}` ⟂ `{b}`",
                        list(&vb),
                        list(&va)
                    ),
                );
            }
        }
    }
}

/// Every parameter of `kind` in its order, from what was `given` (names as
/// written, with spans; `invalid` names were given but rejected already). Reports unknown, repeated, missing and geometrically
/// wrong parameters into `errors`.
pub fn resolve(
    kind: &'static JointKind,
    formulation: Formulation,
    given: Vec<(String, Span, Source)>,
    invalid: &[String],
    kind_span: Span,
    errors: &mut Errors,
) -> Vec<(&'static str, Source)> {
    let mut params: Vec<(String, Source)> = Vec::new();
    for (name, span, source) in given {
        let Some(role) = role_of(kind, &name) else {
            let names: Vec<&str> =
                kind.params.iter().map(|p| p.name).chain(kind.derivations.iter().map(|d| d.source)).collect();
            let expected = names.iter().map(|n| format!("`{n}`")).collect::<Vec<_>>().join(", ");
            errors.at(
                span,
                format!(
                    "unknown parameter `{name}` for `{}`{}; expected one of {expected}",
                    kind.name,
                    dsl::did_you_mean(&name, names.iter().copied())
                ),
            );
            continue;
        };
        if params.iter().any(|(n, _)| *n == name) {
            errors.at(span, format!("parameter `{name}` is given twice; expected it once"));
            continue;
        }
        if let Source::Const(v, s) = &source {
            let vector = matches!(role, Role::Axis(_) | Role::Point(_));
            if vector && v.len() != 3 {
                errors.at(*s, format!("`{name}` takes 3 components, found {}; expected `{name} = [x, y, z]`", v.len()));
                continue;
            }
            if matches!(role, Role::Axis(_)) && v.iter().all(|&x| x == 0.0) {
                errors.at(
                    *s,
                    format!(
                        "`{name}` is an axis and must not be zero; expected a direction, as in `{name} = [0, 0, 1]`"
                    ),
                );
                continue;
            }
            if role == Role::Time {
                errors.at(
                    *s,
                    format!("`{name}` is a time function; expected a field `{name}: F` with `F: TimeFunction`"),
                );
                continue;
            }
        }
        params.push((name, source));
    }
    let excused = expand_axes(kind, &mut params, invalid, kind_span, errors);
    check_perpendicular(kind, &params, errors);
    let mut ordered = Vec::new();
    for p in &kind.params {
        match params.iter().position(|(n, _)| n == p.name) {
            Some(i) => ordered.push((p.name, params.remove(i).1)),
            None if formulation.is_relative() && matches!(p.role, Role::Point(_)) => {}
            None if excused.contains(&p.name) || invalid.iter().any(|n| n == p.name) => {}
            None => {
                let also =
                    kind.derived_from(p.name).map(|d| format!(" (or its axis `{}`)", d.source)).unwrap_or_default();
                errors.at(kind_span, format!("missing parameter `{}` of `{}`{also}", p.name, kind.name));
            }
        }
    }
    ordered
}

fn source_span(s: &Source) -> Span {
    match s {
        Source::Const(_, span) | Source::Field { span, .. } => *span,
    }
}
