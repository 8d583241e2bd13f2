//! `#[derive(Scene)]`'s declaration: bodies, joints and options read from the
//! attributes, each joint's parameters through the same resolver as
//! `#[derive(Joint)]`.
//!
//! ```text
//! #[scene(gravity = [0, 0, -9.81])]                               (optional; default zero)
//! #[body(NAME, mass = 1.0 | FIELD, inertia = [ixx, iyy, izz] | [ixx, iyy, izz, ixy, ixz, iyz] | FIELD)]
//! #[joint(NAME = KIND(BODY | ground, BODY | ground), PARAM = [x, y, z] | number | FIELD, ...)]
//! struct S<F> { FIELD: Vector3<f64> | f64 | AxisFrame<f64> | F (a time function), ... }
//! ```
//! A value that is a single lower-case identifier names a field; one that
//! starts with a capital (`RA`) or is a path (`consts::D`) names a constant.

use proc_macro2::Span;
use syn::parse::{Parse, ParseStream};
use syn::punctuated::Punctuated;
use syn::spanned::Spanned;
use syn::{Token, parenthesized};

use super::attr::{self, Arg, Number, Slot, Value};
use super::context::Errors;
use super::names::did_you_mean;
use super::resolve::{self, Dialect, Given, GivenValue, Origin, Parameter};
use crate::joints::{self, JointKind};
use crate::kinematics::Formulation;

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
            args = attr::args(input)?;
        }
        Ok(JointAttr { name, kind, bodies, args })
    }
}

/// Numbers, or a field read at run time.
pub enum Quantity {
    /// Numbers written in the attribute.
    Const(Vec<Number>),
    /// A field.
    Field(syn::Ident),
}

/// A body: its name and its inertia.
pub struct Body {
    /// The name, as in the joints' `KIND(BODY, BODY)`.
    pub name: syn::Ident,
    /// Its mass.
    pub mass: Quantity,
    /// Its inertia about the centre of mass, in body components.
    pub inertia: Quantity,
}

/// A joint of the scene.
pub struct JointDecl {
    /// Its name (the row block's).
    pub name: syn::Ident,
    /// The catalogue joint.
    pub kind: &'static JointKind,
    /// Where the kind was written.
    pub kind_span: Span,
    /// The bodies it connects (`None`: the ground).
    pub bodies: [Option<usize>; 2],
    /// Its parameters in the joint's order.
    pub params: Vec<Parameter>,
}

/// A checked scene declaration.
pub struct SceneDecl {
    /// The bodies, in state order.
    pub bodies: Vec<Body>,
    /// The joints, in row order.
    pub joints: Vec<JointDecl>,
    /// Gravity in inertial components.
    pub gravity: Quantity,
    /// Types of time-function fields (each needs a `TimeFunction` bound).
    pub time_types: Vec<syn::Type>,
}

/// The inherent constants a scene gets beside its bodies' indices.
pub const SIZE_CONSTANTS: [&str; 4] = ["NB", "NV", "ROWS", "BLOCKS"];

/// The inherent constant naming a body's index: its name in upper case
/// (`input` → `Shaft::INPUT`).
pub fn body_constant(name: &syn::Ident) -> syn::Ident {
    let text = name.to_string();
    syn::Ident::new(text.strip_prefix("r#").unwrap_or(&text).to_uppercase().as_str(), name.span())
}

/// What a stub `Scene` needs: each body's name and its index constant, and
/// the number of rows.
pub struct SceneShape {
    /// `(name, constant)` per body, in state order.
    pub bodies: Vec<(String, syn::Ident)>,
    /// Rows of all joints.
    pub rows: usize,
}

/// The bodies' names and the number of rows, read from the attributes alone
/// when every body and joint attribute parses and names a known joint: enough
/// for a stub impl beside a compile error.
pub fn shape(input: &syn::DeriveInput) -> Option<SceneShape> {
    let (mut bodies, mut rows) = (Vec::new(), 0);
    for attr in &input.attrs {
        if attr.path().is_ident("body") {
            let name = attr.parse_args_with(attr::args).ok()?.into_iter().next()?.key;
            bodies.push((name.to_string(), body_constant(&name)));
        } else if attr.path().is_ident("joint") {
            let joint = attr.parse_args::<JointAttr>().ok()?;
            rows += joints::lookup(&joint.kind.to_string())?.row_count();
        }
    }
    (!bodies.is_empty()).then_some(SceneShape { bodies, rows })
}

/// The struct's fields and their types.
type Fields = Vec<(syn::Ident, syn::Type)>;

/// A value naming a field or a constant (see the module docs).
enum Named<'a> {
    Field(&'a syn::Type),
    Constant,
    Unknown,
}

fn named<'a>(ident: &syn::Ident, fields: &'a Fields) -> Named<'a> {
    match fields.iter().find(|(n, _)| n == ident) {
        Some((_, ty)) => Named::Field(ty),
        None if ident.to_string().starts_with(|c: char| c.is_lowercase() || c == '_') => Named::Unknown,
        None => Named::Constant,
    }
}

fn no_field(f: &syn::Ident, what: &str, fields: &Fields) -> String {
    let hint = did_you_mean(
        &f.to_string(),
        fields.iter().map(|(n, _)| n.to_string()).collect::<Vec<_>>().iter().map(String::as_str),
    );
    format!("no field `{f}` in this struct{hint}; expected a number, a named constant or a field for `{what}`")
}

fn quantity(v: Option<Value>, key: &syn::Ident, fields: &Fields, errors: &mut Errors) -> Option<Quantity> {
    let what = key.to_string();
    match v {
        Some(Value::Ident(f)) => match named(&f, fields) {
            Named::Field(_) => return Some(Quantity::Field(f)),
            Named::Unknown => {
                errors.at(f.span(), no_field(&f, &what, fields));
                return None;
            }
            Named::Constant => return Value::Ident(f).numbers().map(|(v, _)| Quantity::Const(v)),
        },
        Some(v @ (Value::Number(..) | Value::List(..))) => return v.numbers().map(|(v, _)| Quantity::Const(v)),
        _ => {}
    }
    errors.at(key.span(), format!("expected `{what} = NUMBER` or `{what} = FIELD`"));
    None
}

/// Parses and checks a `#[derive(Scene)]` input.
pub fn parse(input: &syn::DeriveInput) -> syn::Result<SceneDecl> {
    let mut errors = Errors::new();
    let syn::Data::Struct(data) = &input.data else {
        let message = "`Scene` can only be derived for a struct, as in `struct Shaft { bend: f64 }`";
        errors.at(input.ident.span(), message);
        return Err(errors.finish().err().unwrap_or_else(|| syn::Error::new(input.ident.span(), message)));
    };
    let fields: Fields = data.fields.iter().filter_map(|f| f.ident.clone().map(|i| (i, f.ty.clone()))).collect();
    // Attributes written, parsed or not: a scene whose only joint attribute has a
    // mistake gets that mistake reported, not a second "needs joints" as well.
    let written = |name: &str| input.attrs.iter().any(|a| a.path().is_ident(name));
    let gravity = scene_options(input, &fields, &mut errors);
    let bodies = bodies(input, &fields, &mut errors);
    if bodies.is_empty() && !written("body") {
        let message = "a scene needs bodies; add `#[body(NAME, mass = 1.0, inertia = [ixx, iyy, izz])]`";
        errors.at(input.ident.span(), message);
    }
    if !bodies.is_empty() && !written("joint") {
        errors.at(input.ident.span(), "a scene needs joints; add `#[joint(NAME = KIND(BODY, BODY), ..)]`");
    }
    let mut scene = SceneDecl { bodies, joints: Vec::new(), gravity, time_types: Vec::new() };
    // With no bodies every joint would be ground to ground: say the one thing that is wrong.
    if !scene.bodies.is_empty() {
        for attr in input.attrs.iter().filter(|a| a.path().is_ident("joint")) {
            match attr.parse_args::<JointAttr>() {
                Ok(j) => scene.joint(j, &fields, &mut errors),
                Err(e) => errors.push(e),
            }
        }
    }
    errors.finish()?;
    Ok(scene)
}

/// `#[scene(gravity = .., formulation = omega_body)]`: the gravity.
fn scene_options(input: &syn::DeriveInput, fields: &Fields, errors: &mut Errors) -> Quantity {
    let mut gravity = Slot::new("`gravity`", "it once");
    for a in attr::items(&input.attrs, "scene", errors) {
        match a.key.to_string().as_str() {
            "gravity" => {
                if let Some(q) = quantity(a.value, &a.key, fields, errors) {
                    gravity.set(a.key.span(), q, errors);
                }
            }
            "formulation" => match &a.value {
                Some(Value::Ident(f)) if f == "omega_body" => {}
                _ => errors.at(
                    a.key.span(),
                    "scenes use the `omega_body` formulation (`r, p; ṙ, ω'` per body); expected `formulation = \
                     omega_body` or nothing",
                ),
            },
            other => errors.at(a.key.span(), format!("unknown scene option `{other}`; expected `gravity`")),
        }
    }
    gravity.take().map_or(Quantity::Const(vec![Number::Known(0.0); 3]), |(q, _)| q)
}

/// The `#[body(..)]` attributes, checked: names unique and distinct from the
/// scene's constants, inertias of 3 or 6 entries.
fn bodies(input: &syn::DeriveInput, fields: &Fields, errors: &mut Errors) -> Vec<Body> {
    let mut bodies: Vec<Body> = Vec::new();
    for attr in input.attrs.iter().filter(|a| a.path().is_ident("body")) {
        let args = match attr.parse_args_with(attr::args) {
            Ok(args) => args,
            Err(e) => {
                errors.push(e);
                continue;
            }
        };
        let mut args = args.into_iter();
        let Some(first) = args.next().filter(|a| a.value.is_none()) else {
            errors.at(attr.span(), "expected `#[body(NAME, mass = .., inertia = ..)]`");
            continue;
        };
        let (mut mass, mut inertia) = (Slot::new("`mass`", "it once"), Slot::new("`inertia`", "it once"));
        for a in args {
            let slot = match a.key.to_string().as_str() {
                "mass" => &mut mass,
                "inertia" => &mut inertia,
                other => {
                    errors.at(a.key.span(), format!("unknown body option `{other}`; expected `mass` or `inertia`"));
                    continue;
                }
            };
            if let Some(q) = quantity(a.value, &a.key, fields, errors) {
                slot.set(a.key.span(), q, errors);
            }
        }
        if bodies.iter().any(|b| b.name == first.key) || first.key == "ground" {
            errors.at(first.key.span(), format!("body `{}` is declared twice (or is `ground`)", first.key));
        }
        let ones = |n| Quantity::Const(vec![Number::Known(1.0); n]);
        let body = Body {
            name: first.key,
            mass: mass.take().map_or(ones(1), |(q, _)| q),
            inertia: inertia.take().map_or(ones(3), |(q, _)| q),
        };
        if let Quantity::Const(v) = &body.inertia
            && v.len() != 3
            && v.len() != 6
        {
            errors.at(
                body.name.span(),
                "`inertia` takes 3 principal moments or 6 entries `[ixx, iyy, izz, ixy, ixz, iyz]`",
            );
        }
        bodies.push(body);
    }
    check_constant_names(&bodies, errors);
    bodies
}

/// Each body's index constant must not clash with another's or a size constant.
fn check_constant_names(bodies: &[Body], errors: &mut Errors) {
    for (i, b) in bodies.iter().enumerate() {
        let constant = body_constant(&b.name).to_string();
        // A body declared twice is reported as such, not again here.
        let clash = bodies[..i].iter().find(|e| e.name != b.name && body_constant(&e.name) == constant);
        if SIZE_CONSTANTS.contains(&constant.as_str()) {
            let message = format!("body `{}` would be named `{constant}`, a constant of the scene's size", b.name);
            errors.at(b.name.span(), format!("{message}; rename the body"));
        } else if let Some(earlier) = clash {
            let message = format!("bodies `{}` and `{}` would both be named `{constant}`", earlier.name, b.name);
            errors.at(b.name.span(), format!("{message}; rename one"));
        }
    }
}

impl SceneDecl {
    /// Checks one `#[joint(..)]` and adds it.
    fn joint(&mut self, j: JointAttr, fields: &Fields, errors: &mut Errors) {
        if self.joints.iter().any(|x| x.name == j.name) {
            errors.at(j.name.span(), format!("joint `{}` is declared twice", j.name));
        }
        let Some(kind) = joints::lookup(&j.kind.to_string()) else {
            let hint = did_you_mean(&j.kind.to_string(), joints::catalogue().iter().map(|k| k.name));
            errors.at(j.kind.span(), format!("unknown joint `{}`{hint}; expected one of {}", j.kind, joints::names()));
            return;
        };
        let [a, b] = j.bodies.as_slice() else {
            let message = format!("`{}` connects two bodies; expected `{}(BODY1, BODY2)`", kind.name, kind.name);
            errors.at(j.kind.span(), message);
            return;
        };
        let pair = [self.body_index(a, errors), self.body_index(b, errors)];
        if a == "ground" && b == "ground" {
            errors.at(j.kind.span(), "a joint between the ground and itself constrains nothing");
        }
        let given: Vec<Given> = j.args.into_iter().map(|a| given(a, fields, errors)).collect();
        let dialect = Dialect { scalar: "f64", fields_by_name: false };
        let resolved = resolve::resolve(kind, Formulation::OmegaBody, given, &dialect, j.kind.span(), errors);
        for (s, span) in resolved.scalars.iter().filter(|(s, _)| s != "f64") {
            errors.at(*span, format!("a scene's fields are `f64`; expected `f64` here, found `{s}`"));
        }
        self.time_types.extend(resolved.time_types);
        let decl = JointDecl { name: j.name, kind, kind_span: j.kind.span(), bodies: pair, params: resolved.params };
        self.joints.push(decl);
    }

    fn body_index(&self, b: &syn::Ident, errors: &mut Errors) -> Option<usize> {
        if b == "ground" {
            return None;
        }
        let i = self.bodies.iter().position(|x| x.name == *b);
        if i.is_none() {
            let message = format!("unknown body `{b}`; expected `ground` or a body declared with `#[body({b}, ..)]`");
            errors.at(b.span(), message);
        }
        i
    }
}

/// A joint parameter as written in a scene: numbers, a field, or a constant.
fn given(a: Arg, fields: &Fields, errors: &mut Errors) -> Given {
    let (name, span) = (a.key.to_string(), a.key.span());
    let value = match a.value {
        Some(Value::Ident(f)) => match named(&f, fields) {
            Named::Field(ty) => GivenValue::Field { member: f.clone(), ty: Box::new(ty.clone()) },
            Named::Unknown => {
                errors.at(f.span(), no_field(&f, &name, fields));
                GivenValue::Rejected
            }
            Named::Constant => {
                let span = f.span();
                let values = vec![Number::Named(syn::parse_quote_spanned!(span=> #f))];
                GivenValue::Numbers { values, span, list: false }
            }
        },
        Some(v @ (Value::Number(..) | Value::List(..))) => {
            let list = matches!(v, Value::List(..));
            match v.numbers() {
                Some((values, span)) => GivenValue::Numbers { values, span, list },
                None => GivenValue::Rejected,
            }
        }
        _ => {
            errors.at(span, format!("expected `{name} = [x, y, z]`, a number or a field"));
            GivenValue::Rejected
        }
    };
    Given { name, span, origin: Origin::Attribute, value }
}
