//! A joint the declaration writes itself, `#[joint(rows(...))]`: its parameters
//! (roles from the tags, `rho1`/`rho2` as the joint points, untagged scalar
//! fields and numbers as scalars) and its rows, checked. The kind is owned by
//! the declaration, like any value, and lowered like a catalogue joint.

use proc_macro2::Span;

use super::attr::{self, Fields, Value};
use super::context::Errors;
use super::rows::{self, Names};
use crate::joints::{JointKind, Param, Role};

/// The kind name of a joint declared by `rows(...)`.
pub const CUSTOM: &str = "custom";

/// Field tags of a user-written joint.
pub const TAGS: [&str; 5] = ["body1", "body2", "point1", "point2", "time"];

/// The role a tag gives a vector or field.
pub fn tag_role(tag: &str) -> Role {
    match tag {
        "body1" => Role::Axis(0),
        "body2" => Role::Axis(1),
        "point1" => Role::Point(0),
        "point2" => Role::Point(1),
        _ => Role::Time,
    }
}

/// The parameters of a user-written joint as they are found.
#[derive(Default)]
struct Params {
    list: Vec<Param>,
    /// Vectors whose body is not given: reported once, then taken as known (so
    /// that neither the rows reading them nor the parameter list report them again).
    untagged: Vec<String>,
}

impl Params {
    fn add(&mut self, name: &str, role: Role) {
        if !self.list.iter().any(|p| p.name == name) {
            self.list.push(Param { name: name.to_string().into(), role });
        }
    }

    fn untagged(&mut self, name: String, span: Span, expected: &str, errors: &mut Errors) {
        let message = format!("the body of the vector `{name}` is not given; expected {expected}");
        errors.at(span, message);
        self.add(&name, Role::Axis(0));
        self.untagged.push(name);
    }

    fn role(&self, name: &str) -> Option<Role> {
        self.list.iter().find(|p| p.name == name).map(|p| p.role)
    }
}

/// `rho1` and `rho2` are the joint points wherever they appear.
fn point(name: &str) -> Option<Role> {
    match name {
        "rho1" => Some(Role::Point(0)),
        "rho2" => Some(Role::Point(1)),
        _ => None,
    }
}

/// The joint `rows(...)` describes, and each row's span.
pub fn kind(
    exprs: &[syn::Expr],
    rows_span: Span,
    tagged: &[(String, Role)],
    consts: &[(syn::Ident, Value)],
    fields: &Fields,
    errors: &mut Errors,
) -> (JointKind, Vec<Span>) {
    let mut params = Params::default();
    for (name, role) in tagged {
        params.add(name, *role);
    }
    from_consts(&mut params, tagged, consts, errors);
    from_fields(&mut params, fields, errors);
    let (rows, spans) = check_rows(exprs, &params, errors);
    // `d` (or `spherical`, `dot2`) needs the joint points; they are then required
    // parameters, reported missing like any other.
    if rows.iter().any(rows::uses_separation) {
        for p in ["rho1", "rho2"] {
            if params.role(p).is_none() {
                params.add(p, point(p).unwrap_or(Role::Point(0)));
            }
        }
    }
    if exprs.is_empty() {
        errors.at(rows_span, "`rows()` is empty; expected at least one row, as in `rows(spherical, dot1(s, h))`");
    }
    let kind = JointKind {
        name: CUSTOM,
        params: params.list,
        rows,
        derivations: Vec::new(),
        perpendicular: Vec::new(),
        singularity: None,
    };
    (kind, spans)
}

/// Parameters written in the attribute: joint points, numbers (scalars), and
/// vectors, which need a body.
fn from_consts(params: &mut Params, tagged: &[(String, Role)], consts: &[(syn::Ident, Value)], errors: &mut Errors) {
    for (key, value) in consts {
        let name = key.to_string();
        if tagged.iter().any(|(n, _)| *n == name) {
            continue;
        }
        match (point(&name), value) {
            (Some(role), _) => params.add(&name, role),
            (None, Value::Number(..) | Value::Ident(_)) => params.add(&name, Role::Scalar),
            (None, Value::List(..)) => {
                let expected = format!(
                    "`body1({name} = [..])`, `body2({name} = [..])`, `point1({name} = [..])` or `point2({name} = [..])`"
                );
                params.untagged(name, key.span(), &expected, errors);
            }
            _ => {}
        }
    }
}

/// Parameters read from fields: a tag gives the role, a `Vector3` needs one.
fn from_fields(params: &mut Params, fields: &Fields, errors: &mut Errors) {
    for field in fields.iter().flatten() {
        let Some(ident) = &field.ident else { continue };
        let (mut name, mut role, mut skip) = (ident.to_string(), None, false);
        // Mistakes in these attributes are reported when the fields are read as parameters.
        let mut ignored = Errors::new();
        for arg in attr::items(&field.attrs, "joint", &mut ignored) {
            let key = arg.key.to_string();
            if key == "skip" {
                skip = true;
            } else if TAGS.contains(&key.as_str()) {
                role = Some(tag_role(&key));
            } else if arg.value.is_none() {
                name = key;
            }
        }
        let _reported_elsewhere = ignored.finish();
        if skip {
            continue;
        }
        let is_vector =
            matches!(&field.ty, syn::Type::Path(p) if p.path.segments.last().is_some_and(|s| s.ident == "Vector3"));
        match role.or_else(|| point(&name)) {
            Some(r) => params.add(&name, r),
            None if is_vector => {
                let expected = "a tag `#[joint(body1)]`, `#[joint(body2)]`, `#[joint(point1)]` or `#[joint(point2)]` \
                                on the field";
                params.untagged(name, ident.span(), expected, errors);
            }
            None => params.add(&name, Role::Scalar),
        }
    }
}

/// The rows, checked over the parameters found; a row reading an untagged
/// vector cannot be checked (its tag is reported).
fn check_rows(exprs: &[syn::Expr], params: &Params, errors: &mut Errors) -> (Vec<crate::joints::Row>, Vec<Span>) {
    let role = |n: &str| params.role(n);
    let all: Vec<&str> = params.list.iter().map(|p| p.name.as_ref()).collect();
    let names = Names { role: &role, all: &all };
    let (mut rows, mut spans) = (Vec::new(), Vec::new());
    for e in exprs.iter().filter(|e| !attr::mentions(e, &params.untagged)) {
        match rows::row(e, &names) {
            Ok(r) => {
                rows.push(r);
                spans.push(syn::spanned::Spanned::span(e));
            }
            Err(err) => errors.push(err),
        }
    }
    (rows, spans)
}
