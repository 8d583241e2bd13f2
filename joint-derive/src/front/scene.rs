//! `#[derive(Scene)]`'s declaration: bodies, joints and options read from the
//! attributes, each joint's parameters through the same resolver as
//! `#[derive(Joint)]`.
//!
//! ```text
//! #[scene(gravity = [0, 0, -9.81])]          (optional; default zero, a robot file's own, 9.81 down z for URDF)
//! #[body(NAME, mass = 1.0 | FIELD, inertia = [ixx, iyy, izz] | [ixx, iyy, izz, ixy, ixz, iyz] | FIELD)]
//! #[joint(NAME = KIND(BODY | ground, BODY | ground), PARAM = [x, y, z] | number | FIELD, ...)]
//! struct S<F> { FIELD: Vector3<f64> | f64 | AxisFrame<f64> | F (a time function), ... }
//! ```
//! A value that is a single lower-case identifier names a field; one that
//! starts with a capital (`RA`) or is a path (`consts::D`) names a constant.
//! Rows: `#[body(bar[40], ..)]`, `#[joint(ball[i in 1..40] = spherical(bar[i - 1],
//! bar[i]), rho1 = [i, 0, 0], ..)]`. Several entries may share an attribute,
//! separated by `;`.

use proc_macro2::Span;
use syn::parse::{Parse, ParseStream};
use syn::spanned::Spanned;
use syn::{Token, parenthesized};

use super::attr::{self, Arg, Number, Slot, Value};
use super::context::Errors;
use super::files::{Coupling, FileData, FromFile, Reading, RobotFormat};
use super::names::did_you_mean;
use super::resolve::{self, Dialect, Given, GivenValue, Origin, Parameter, Source};
use crate::joints::{self, JointKind};
use crate::kinematics::Formulation;

/// `NAME = KIND(BODY, BODY), PARAM = VALUE, ...`, or a row of joints
/// `NAME[i in A..B] = KIND(BODY[i - 1], BODY[i]), ...`.
pub(super) struct JointAttr {
    pub(super) name: syn::Ident,
    pub(super) repeat: Option<Repeat>,
    pub(super) kind: syn::Ident,
    pub(super) bodies: Vec<BodyRef>,
    pub(super) args: Vec<Arg>,
}

/// `[i in A..B]` or `[i in A..=B]`: one joint per value of `i`.
pub(super) struct Repeat {
    var: syn::Ident,
    values: core::ops::Range<i64>,
}

/// A body in `KIND(BODY, BODY)`: `ground`, `NAME`, or `NAME[INDEX]` with the
/// index a number or the joint's variable plus or minus a number.
pub(super) struct BodyRef {
    pub(super) name: syn::Ident,
    pub(super) index: Option<(Index, Span)>,
}

#[derive(Clone, Copy)]
pub(super) enum Index {
    Fixed(i64),
    /// `i + offset`.
    Var(i64),
}

const REPEAT_FORM: &str = "expected `NAME[i in A..B]` with whole numbers, as in `hinge[i in 1..40]`";
const INDEX_FORM: &str = "expected an index `[3]`, `[i]`, `[i + 1]` or `[i - 1]`";

fn int(e: &syn::Expr, form: &str) -> syn::Result<i64> {
    match e {
        syn::Expr::Lit(syn::ExprLit { lit: syn::Lit::Int(i), .. }) => i.base10_parse(),
        _ => Err(syn::Error::new(e.span(), form)),
    }
}

impl Parse for Repeat {
    fn parse(input: ParseStream) -> syn::Result<Self> {
        let var: syn::Ident = input.parse()?;
        input.parse::<Token![in]>().map_err(|e| syn::Error::new(e.span(), REPEAT_FORM))?;
        let range: syn::ExprRange = input.parse().map_err(|e| syn::Error::new(e.span(), REPEAT_FORM))?;
        let (Some(a), Some(b)) = (&range.start, &range.end) else {
            return Err(syn::Error::new(range.span(), REPEAT_FORM));
        };
        let (a, mut b) = (int(a, REPEAT_FORM)?, int(b, REPEAT_FORM)?);
        if matches!(range.limits, syn::RangeLimits::Closed(_)) {
            b += 1;
        }
        if b <= a {
            return Err(syn::Error::new(range.span(), format!("the range is empty; {REPEAT_FORM}")));
        }
        Ok(Repeat { var, values: a..b })
    }
}

impl BodyRef {
    fn parse_with(input: ParseStream, var: Option<&syn::Ident>) -> syn::Result<Self> {
        let name: syn::Ident = input.parse()?;
        if !input.peek(syn::token::Bracket) {
            return Ok(BodyRef { name, index: None });
        }
        let content;
        syn::bracketed!(content in input);
        let e: syn::Expr = content.parse()?;
        let is_var = |p: &syn::Expr| matches!(p, syn::Expr::Path(p) if var.is_some_and(|v| p.path.is_ident(v)));
        let index = match &e {
            syn::Expr::Lit(_) => Index::Fixed(int(&e, INDEX_FORM)?),
            p if is_var(p) => Index::Var(0),
            syn::Expr::Binary(b) if is_var(&b.left) => match b.op {
                syn::BinOp::Add(_) => Index::Var(int(&b.right, INDEX_FORM)?),
                syn::BinOp::Sub(_) => Index::Var(-int(&b.right, INDEX_FORM)?),
                _ => return Err(syn::Error::new(b.op.span(), INDEX_FORM)),
            },
            _ => return Err(syn::Error::new(e.span(), INDEX_FORM)),
        };
        Ok(BodyRef { name, index: Some((index, e.span())) })
    }
}

impl Parse for JointAttr {
    fn parse(input: ParseStream) -> syn::Result<Self> {
        let name: syn::Ident = input.parse()?;
        let repeat = if input.peek(syn::token::Bracket) {
            let content;
            syn::bracketed!(content in input);
            Some(content.parse::<Repeat>()?)
        } else {
            None
        };
        input.parse::<Token![=]>().map_err(|e| {
            syn::Error::new(e.span(), "expected `NAME = KIND(BODY, BODY)`, as in `cardan = universal(input, output)`")
        })?;
        let kind: syn::Ident = input.parse()?;
        let content;
        parenthesized!(content in input);
        let var = repeat.as_ref().map(|r| &r.var);
        let mut bodies = Vec::new();
        while !content.is_empty() {
            bodies.push(BodyRef::parse_with(&content, var)?);
            if content.is_empty() {
                break;
            }
            content.parse::<Token![,]>()?;
        }
        let mut args = Vec::new();
        if input.parse::<Option<Token![,]>>()?.is_some() {
            args = attr::args_until_semicolon(input)?;
        }
        Ok(JointAttr { name, repeat, kind, bodies, args })
    }
}

/// `NAME` or `NAME[COUNT]`, then the body's options.
struct BodyAttr {
    name: syn::Ident,
    count: Option<usize>,
    args: Vec<Arg>,
}

impl Parse for BodyAttr {
    fn parse(input: ParseStream) -> syn::Result<Self> {
        let name: syn::Ident = input.parse()?;
        let count = if input.peek(syn::token::Bracket) {
            let content;
            syn::bracketed!(content in input);
            let n: syn::LitInt =
                content.parse().map_err(|e| syn::Error::new(e.span(), "expected `NAME[COUNT]`, as in `link[40]`"))?;
            match n.base10_parse::<usize>()? {
                0 => {
                    return Err(syn::Error::new(
                        n.span(),
                        "a row of bodies needs at least one; expected `NAME[COUNT]` with COUNT ≥ 1",
                    ));
                }
                c => Some(c),
            }
        } else {
            None
        };
        let mut args = Vec::new();
        if input.parse::<Option<Token![,]>>()?.is_some() {
            args = attr::args_until_semicolon(input)?;
        }
        Ok(BodyAttr { name, count, args })
    }
}

/// Numbers, or a field read at run time.
#[derive(Clone)]
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
    /// Its place in a row of bodies (`link[3]`), if declared as one.
    pub element: Option<usize>,
    /// Its mass.
    pub mass: Quantity,
    /// Its inertia about the centre of mass, in body components.
    pub inertia: Quantity,
}

impl Body {
    /// `link` or `link[3]`.
    pub fn label(&self) -> String {
        label(&self.name, self.element)
    }
}

fn label(name: &syn::Ident, element: Option<usize>) -> String {
    match element {
        Some(i) => format!("{name}[{i}]"),
        None => name.to_string(),
    }
}

/// A joint of the scene.
pub struct JointDecl {
    /// Its name (the row block's).
    pub name: syn::Ident,
    /// Its value of the row's variable, for a row of joints.
    pub element: Option<usize>,
    /// The catalogue joint.
    pub kind: &'static JointKind,
    /// Where the kind was written.
    pub kind_span: Span,
    /// The bodies it connects (`None`: the ground).
    pub bodies: [Option<usize>; 2],
    /// Its parameters in the joint's order.
    pub params: Vec<Parameter>,
    /// `armature = ..`, `damping = ..`, `stiffness = ..`, `spring_rest = ..`
    /// (zero unless given).
    pub dynamics: JointDynamics,
}

/// A tree joint's own inertia, damping and spring, per freedom (relative
/// coordinates only).
#[derive(Clone, Copy, Default, Debug)]
pub struct JointDynamics {
    /// Inertia added to each freedom.
    pub armature: f64,
    /// Viscous damping of each freedom.
    pub damping: f64,
    /// A revolute or translational joint's spring: its force `−k (q − q₀)`.
    pub stiffness: f64,
    /// `q₀`, where the spring's force is zero (any number).
    pub spring_rest: f64,
    /// Where the first was written (`None`: none).
    pub span: Option<Span>,
    /// Where `stiffness` or `spring_rest` was written.
    pub spring: Option<Span>,
}

/// The keys [`joint_dynamics`] takes out of a joint's arguments.
const DYNAMICS_KEYS: [&str; 4] = ["armature", "damping", "stiffness", "spring_rest"];

impl JointDecl {
    /// `hinge` or `hinge[3]`.
    pub fn label(&self) -> String {
        label(&self.name, self.element)
    }

    /// `hinge` or `hinge_3`: a prefix for generated names.
    pub fn prefix(&self) -> String {
        match self.element {
            Some(i) => format!("{}_{i}", self.name),
            None => self.name.to_string(),
        }
    }
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
    /// `#[scene(second_order)]`: where it was asked for.
    pub second_order: Option<Span>,
    /// Relative coordinates (`coordinates = relative`, the default, or
    /// `both`): the joints as a tree, parents first.
    pub tree: Option<Vec<super::tree::TreeEdge>>,
    /// Whether the absolute impls are wanted (`coordinates = absolute` or `both`).
    pub absolute: bool,
    /// Files read (`urdf = ".."`), absolute: the output includes them so that
    /// cargo rebuilds when they change.
    pub files: Vec<String>,
    /// A robot file's links and limits (`None` without a file).
    pub file: Option<FileData>,
    /// Joints that follow others (a file's `<mimic>` or `<equality
    /// joint>`), as rows of the tree's coordinates.
    pub couplings: Vec<Coupling>,
    /// `#[contact(..)]`: points and frames held, rows on the tree.
    pub contacts: Vec<super::contact::ContactDecl>,
    /// A file's closing joints that MuJoCo softens.
    pub soft: Vec<super::files::SoftJoint>,
}

/// The inherent constants a scene gets beside its bodies' indices.
pub const SIZE_CONSTANTS: [&str; 4] = ["NB", "NV", "ROWS", "BLOCKS"];

/// The inherent constant naming a body's index: its name in upper case
/// (`input` → `Shaft::INPUT`).
pub fn body_constant(name: &syn::Ident) -> syn::Ident {
    let text = name.to_string();
    syn::Ident::new(text.strip_prefix("r#").unwrap_or(&text).to_uppercase().as_str(), name.span())
}

/// A body's name in generated code.
pub struct BodyName {
    /// `link` or `link[3]`.
    pub label: String,
    /// The inherent constant: `LINK`, an index or (rows of bodies) an array.
    pub constant: syn::Ident,
    /// Part of a row of bodies.
    pub element: bool,
}

/// What a stub `Scene` needs: each body's name and constant, and the number
/// of rows.
pub struct SceneShape {
    /// Per body, in state order.
    pub bodies: Vec<BodyName>,
    /// Rows of all joints.
    pub rows: usize,
    /// In relative coordinates (the default): the tree's coordinates and velocities
    /// (the joints that are not tree joints count none; read from the
    /// attributes alone, a joint of a tree kind that closes a loop counts
    /// too: the derive puts the spanning tree's sizes here when it has them).
    pub tree: Option<(usize, usize)>,
    /// Whether the absolute impls are derived (`coordinates = absolute` or
    /// `both`): with `absolute` the one `Simulation` runs the absolute engine.
    pub absolute: bool,
    /// The robot file's format key (`urdf`, `mjcf`), if the scene names one:
    /// the stub then has the file's constants too, empty.
    pub file: Option<&'static str>,
}

/// The bodies' names and the number of rows, read from the attributes alone
/// when every body and joint attribute parses and names a known joint: enough
/// for a stub impl beside a compile error.
pub fn shape(input: &syn::DeriveInput) -> Option<SceneShape> {
    let (mut bodies, mut rows, mut tree, mut tree_joints) = (Vec::new(), 0, (0, 0), 0);
    for attr in &input.attrs {
        if attr.path().is_ident("body") {
            let b = attr.parse_args::<BodyAttr>().ok()?;
            let constant = body_constant(&b.name);
            match b.count {
                Some(n) => bodies.extend((0..n).map(|i| BodyName {
                    label: label(&b.name, Some(i)),
                    constant: constant.clone(),
                    element: true,
                })),
                None => bodies.push(BodyName { label: b.name.to_string(), constant, element: false }),
            }
        } else if attr.path().is_ident("joint") {
            for joint in attr::entries::<JointAttr>(attr).ok()? {
                let copies = joint.repeat.map_or(1, |r| r.values.count());
                rows += copies * joints::lookup(&joint.kind.to_string())?.row_count();
                if let Some(kind) = super::tree::TreeKind::of(&joint.kind.to_string()) {
                    let (q, v) = kind.sizes();
                    tree = (tree.0 + copies * q, tree.1 + copies * v);
                    tree_joints += copies;
                }
            }
        }
    }
    // Bodies beyond the tree joints float (exact unless a tree joint closes a loop).
    let floating = bodies.len().saturating_sub(tree_joints);
    let coordinates = scene_word(input, "coordinates");
    // A robot's file runs in relative coordinates unless the scene says
    // otherwise; one that failed to read gives a stub of no bodies, so that
    // the scene's uses type-check and the file's error stands alone.
    let format = match (scene_word(input, "urdf"), scene_word(input, "mjcf")) {
        (Some(_), _) => Some("urdf"),
        (None, Some(_)) => Some("mjcf"),
        (None, None) => None,
    };
    let relative = coordinates.as_deref().is_none_or(|word| matches!(word, "relative" | "both"));
    let tree = relative.then_some((tree.0 + 7 * floating, tree.1 + 6 * floating));
    let absolute = coordinates.as_deref().is_some_and(|word| word != "relative");
    (!bodies.is_empty() || format.is_some()).then_some(SceneShape { bodies, rows, tree, absolute, file: format })
}

/// The value of `#[scene(.., KEY = VALUE, ..)]` as a word (an identifier's
/// or a string's), if written (read leniently, for the stub).
fn scene_word(input: &syn::DeriveInput, key: &str) -> Option<String> {
    let parser = syn::punctuated::Punctuated::<syn::Meta, syn::Token![,]>::parse_terminated;
    let metas =
        input.attrs.iter().filter(|a| a.path().is_ident("scene")).filter_map(|a| a.parse_args_with(parser).ok());
    metas.flatten().find_map(|m| match m {
        syn::Meta::NameValue(nv) if nv.path.is_ident(key) => match &nv.value {
            syn::Expr::Path(p) => p.path.get_ident().map(ToString::to_string),
            syn::Expr::Lit(syn::ExprLit { lit: syn::Lit::Str(s), .. }) => Some(s.value()),
            _ => None,
        },
        _ => None,
    })
}

impl SceneDecl {
    /// Every body's name in generated code.
    pub fn body_names(&self) -> Vec<BodyName> {
        let name =
            |b: &Body| BodyName { label: b.label(), constant: body_constant(&b.name), element: b.element.is_some() };
        self.bodies.iter().map(name).collect()
    }
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
    let Options { gravity, second_order, relative, absolute, file, reading } =
        scene_options(input, &fields, &mut errors);
    let read = super::files::read(file.as_ref(), &reading, absolute, &mut errors);
    let FromFile { mut bodies, joints: file_joints, files, gravity: file_gravity, data: file_data, couplings, soft } =
        read;
    let known = |g: [f64; 3]| Quantity::Const(g.iter().map(|&x| Number::Known(x)).collect());
    let gravity = gravity.unwrap_or_else(|| known(file_gravity.unwrap_or([0.0; 3])));
    bodies.extend(self::bodies(input, &fields, &mut errors));
    let from_file = file.is_some();
    if bodies.is_empty() && !written("body") && !from_file {
        let message = "a scene needs bodies; add `#[body(NAME, mass = 1.0, inertia = [ixx, iyy, izz])]`";
        errors.at(input.ident.span(), message);
    }
    if !bodies.is_empty() && !written("joint") && !from_file {
        errors.at(input.ident.span(), "a scene needs joints; add `#[joint(NAME = KIND(BODY, BODY), ..)]`");
    }
    let mut scene = SceneDecl {
        bodies,
        joints: Vec::new(),
        gravity,
        time_types: Vec::new(),
        second_order,
        tree: None,
        absolute,
        files,
        file: file_data,
        couplings,
        contacts: Vec::new(),
        soft,
    };
    for j in file_joints {
        scene.joint(j, &fields, &mut errors);
    }
    // With no bodies every joint would be ground to ground: say the one thing that is wrong.
    if !scene.bodies.is_empty() {
        for attr in input.attrs.iter().filter(|a| a.path().is_ident("joint")) {
            match attr::entries::<JointAttr>(attr) {
                Ok(entries) => entries.into_iter().for_each(|j| scene.joint(j, &fields, &mut errors)),
                Err(e) => errors.push(e),
            }
        }
    }
    // The tree only of joints that parsed: a mistaken joint is one message,
    // not also an unreached body.
    let links =
        scene.file.iter().flat_map(|f| &f.links).map(|l| {
            (l.name.clone(), super::contact::ContactEnd { body: l.body, rotation: l.rotation, point: l.origin })
        });
    let named = super::contact::Named { bodies: &scene.bodies, links: links.collect() };
    scene.contacts = super::contact::parse(input, &named, &mut errors);
    if let (Some(c), None) = (scene.contacts.first(), relative) {
        let message = "contacts are rows on a tree; expected `coordinates = relative` (the default) or `both`";
        errors.at(c.name.span(), message);
    }
    if relative.is_some() && errors.is_empty() {
        scene.tree = Some(super::tree::spanning_tree(&scene.bodies, &scene.joints));
    }
    check_dynamics(&scene, &mut errors);
    errors.finish()?;
    Ok(scene)
}

/// What `#[scene(..)]` says.
struct Options {
    /// `None`: the file's, or zero.
    gravity: Option<Quantity>,
    second_order: Option<Span>,
    /// Where `relative` or `both` was asked for.
    relative: Option<Span>,
    absolute: bool,
    /// `urdf = "path"` or `mjcf = "path"`: a robot's file.
    file: Option<(RobotFormat, syn::LitStr)>,
    /// How the file is read (`floating_base`, `mimic`, `file_damping`, `equality`).
    reading: Reading,
}

/// `armature`, `damping` and springs only on a tree's moving joints, in
/// relative coordinates alone (the absolute engine does not model them);
/// springs on revolute and translational joints.
fn check_dynamics(scene: &SceneDecl, errors: &mut Errors) {
    use super::tree::TreeKind;
    for (i, j) in scene.joints.iter().enumerate() {
        let Some(span) = j.dynamics.span else { continue };
        let edge = scene.tree.as_ref().and_then(|edges| edges.iter().find(|e| e.joint == Some(i)));
        let message = match edge {
            _ if scene.absolute => "`armature`, `damping` and joint springs are modelled in relative coordinates \
                                    only; expected `coordinates = relative`"
                .to_string(),
            None if scene.tree.is_some() => {
                format!(
                    "joint `{}` closes a loop; `armature`, `damping` and springs are for the tree's joints",
                    j.label()
                )
            }
            Some(e) if e.kind == TreeKind::Fixed => "a fixed joint has no freedom to damp or spring".to_string(),
            Some(e) if j.dynamics.spring.is_some() && !matches!(e.kind, TreeKind::Revolute | TreeKind::Prismatic) => {
                errors.at(
                    j.dynamics.spring.unwrap_or(span),
                    "a joint spring is for `revolute` and `translational` joints (one freedom)",
                );
                continue;
            }
            _ => continue,
        };
        errors.at(span, message);
    }
}

/// `armature = A`, `damping = D` taken out of a joint's arguments: numbers,
/// at least zero.
fn joint_dynamics(args: Vec<Arg>, errors: &mut Errors) -> (JointDynamics, Vec<Arg>) {
    let mut out = JointDynamics::default();
    let mut rest = Vec::new();
    for a in args {
        let key = a.key.to_string();
        if !DYNAMICS_KEYS.contains(&key.as_str()) {
            rest.push(a);
            continue;
        }
        // Every one a number at least zero but the spring's rest, any number.
        let signed = key == "spring_rest";
        let value = match &a.value {
            Some(Value::Number(Number::Known(x), _)) if x.is_finite() && (signed || *x >= 0.0) => *x,
            _ if signed => {
                errors.at(a.key.span(), format!("expected `{key} = NUMBER`"));
                continue;
            }
            _ => {
                errors.at(a.key.span(), format!("expected `{key} = NUMBER`, a number at least zero"));
                continue;
            }
        };
        match key.as_str() {
            "armature" => out.armature = value,
            "damping" => out.damping = value,
            "stiffness" => out.stiffness = value,
            _ => out.spring_rest = value,
        }
        if matches!(key.as_str(), "stiffness" | "spring_rest") {
            out.spring.get_or_insert(a.key.span());
        }
        out.span.get_or_insert(a.key.span());
    }
    (out, rest)
}

/// The options `#[scene(..)]` takes (the did-you-mean candidates).
const SCENE_OPTIONS: [&str; 9] =
    ["gravity", "second_order", "coordinates", "urdf", "mjcf", "floating_base", "mimic", "file_damping", "equality"];

/// A scene option that takes no value (`second_order`, `floating_base`).
fn flag(a: attr::Arg, slot: &mut Slot<()>, errors: &mut Errors) {
    match a.value {
        None => slot.set(a.key.span(), (), errors),
        Some(v) => {
            let key = &a.key;
            errors.at(v.span(), format!("`{key}` takes no value; expected `{key}` alone"))
        }
    }
}

/// `#[scene(gravity = .., formulation = omega_body, second_order, coordinates
/// = relative)]`: the gravity, whether the second-order terms are wanted, and
/// the coordinates.
fn scene_options(input: &syn::DeriveInput, fields: &Fields, errors: &mut Errors) -> Options {
    let mut gravity = Slot::new("`gravity`", "it once");
    let mut second_order = Slot::new("`second_order`", "it once");
    let mut coordinates = Slot::new("`coordinates`", "it once");
    let mut file = Slot::new("a robot's file", "one `urdf` or `mjcf`");
    let mut floating_base = Slot::new("`floating_base`", "it once");
    let mut file_damping = Slot::new("`file_damping`", "it once");
    let mut mimic = Slot::new("`mimic`", "it once");
    let mut equality = Slot::new("`equality`", "it once");
    for a in attr::items(&input.attrs, "scene", errors) {
        match a.key.to_string().as_str() {
            "equality" => match &a.value {
                Some(Value::Ident(m)) if m == "hard" => equality.set(a.key.span(), (), errors),
                _ => errors.at(
                    a.value.as_ref().map_or(a.key.span(), Value::span),
                    "expected `equality = hard`: an MJCF file's equalities read as ideal constraints (without it \
                     they are soft, as MuJoCo makes them)",
                ),
            },
            "mimic" => match &a.value {
                Some(Value::Ident(m)) if m == "coupled" || m == "independent" => {
                    mimic.set(a.key.span(), m == "independent", errors)
                }
                _ => errors.at(
                    a.value.as_ref().map_or(a.key.span(), Value::span),
                    "expected `mimic = coupled` (a file's followers as rows, the default) or `mimic = independent`",
                ),
            },
            "floating_base" => flag(a, &mut floating_base, errors),
            "file_damping" => flag(a, &mut file_damping, errors),
            key @ ("urdf" | "mjcf") => {
                let format = if key == "urdf" { RobotFormat::Urdf } else { RobotFormat::Mjcf };
                match a.value {
                    Some(Value::Text(path)) => file.set(a.key.span(), (format, path), errors),
                    _ => errors.at(
                        a.key.span(),
                        format!("expected `{key} = \"path/to/robot.{key}\"` (relative to the crate's directory)"),
                    ),
                }
            }
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
            "second_order" => flag(a, &mut second_order, errors),
            "coordinates" => match &a.value {
                Some(Value::Ident(c)) if c == "relative" || c == "absolute" || c == "both" => {
                    coordinates.set(a.key.span(), c.to_string(), errors)
                }
                _ => errors.at(
                    a.value.as_ref().map_or(a.key.span(), Value::span),
                    "expected `coordinates = absolute` (six per body, every joint's rows as constraints), \
                     `coordinates = relative` (a tree in its joints' own freedoms) or `coordinates = both`",
                ),
            },
            other => {
                let hint = did_you_mean(other, SCENE_OPTIONS);
                errors.at(
                    a.key.span(),
                    format!(
                        "unknown scene option `{other}`{hint}; expected `gravity`, `second_order`, `coordinates`, \
                         `urdf`, `mjcf`, `floating_base`, `mimic`, `file_damping` or `equality`"
                    ),
                )
            }
        }
    }
    let gravity = gravity.take().map(|(q, _)| q);
    let file = file.take().map(|(file, _)| file);
    // A scene that does not choose runs on the tree, its file's or its
    // attributes': the engine that reaches an accuracy soonest on trees and
    // most loops (the guide's "Choosing coordinates" has the measurements).
    let (relative, absolute) = match coordinates.take() {
        Some((c, span)) if c == "relative" => (Some(span), false),
        Some((c, span)) if c == "both" => (Some(span), true),
        Some(_) => (None, true),
        None => (Some(file.as_ref().map_or(input.ident.span(), |(_, path)| path.span())), false),
    };
    let reading = Reading {
        floating_base: floating_base.take().map(|(_, span)| span),
        independent: mimic.take().and_then(|(independent, span)| independent.then_some(span)),
        file_damping: file_damping.take().map(|(_, span)| span),
        hard: equality.take().map(|(_, span)| span),
    };
    Options { gravity, second_order: second_order.take().map(|(_, span)| span), relative, absolute, file, reading }
}

/// Mass properties given as numbers must be a rigid body's: a positive
/// mass, principal moments positive and each at most the sum of the other
/// two (the run time checks those that are fields or constants). Six
/// entries are the tensor's, `[ixx, iyy, izz, ixy, ixz, iyz]` with
/// `ixy = −∫ x y dm`.
fn check_inertia(name: &syn::Ident, mass: &Quantity, inertia: &Quantity, errors: &mut Errors) {
    let known = |q: &Quantity| match q {
        Quantity::Const(v) => v.iter().map(|n| if let Number::Known(x) = n { Some(*x) } else { None }).collect(),
        Quantity::Field(_) => None,
    };
    if let Some(m) = known(mass).and_then(|m: Vec<f64>| m.first().copied())
        && (m.is_nan() || m <= 0.0 || m.is_infinite())
    {
        errors.at(name.span(), format!("body `{name}` has mass {m}; expected a positive mass"));
    }
    let tensor = match known(inertia).as_deref() {
        Some(&[xx, yy, zz]) => [[xx, 0.0, 0.0], [0.0, yy, 0.0], [0.0, 0.0, zz]],
        Some(&[xx, yy, zz, xy, xz, yz]) => [[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]],
        _ => return,
    };
    let moments = super::geometry::eigenvalues(&tensor);
    if !super::geometry::physical(&moments) {
        errors.at(
            name.span(),
            format!(
                "body `{name}`'s inertia has principal moments {moments:?}, which no rigid body has; expected \
                 each positive and at most the sum of the other two (`inertia = [ixx, iyy, izz]` are principal \
                 moments, `[ixx, iyy, izz, ixy, ixz, iyz]` the tensor's entries, `ixy = −∫ x y dm`)"
            ),
        );
    }
}

/// The `#[body(..)]` attributes, checked: names unique and distinct from the
/// scene's constants, inertias of 3 or 6 entries.
fn bodies(input: &syn::DeriveInput, fields: &Fields, errors: &mut Errors) -> Vec<Body> {
    let mut bodies: Vec<Body> = Vec::new();
    let mut heads = Vec::new();
    for attr in input.attrs.iter().filter(|a| a.path().is_ident("body")) {
        match attr::entries::<BodyAttr>(attr) {
            Ok(entries) => heads.extend(entries),
            Err(e) => errors.push(e),
        }
    }
    for head in heads {
        let (mut mass, mut inertia) = (Slot::new("`mass`", "it once"), Slot::new("`inertia`", "it once"));
        for a in head.args {
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
        if bodies.iter().any(|b| b.name == head.name) || head.name == "ground" {
            errors.at(head.name.span(), format!("body `{}` is declared twice (or is `ground`)", head.name));
        }
        let ones = |n| Quantity::Const(vec![Number::Known(1.0); n]);
        let (mass, inertia) = (mass.take().map_or(ones(1), |(q, _)| q), inertia.take().map_or(ones(3), |(q, _)| q));
        if let Quantity::Const(v) = &inertia
            && v.len() != 3
            && v.len() != 6
        {
            errors.at(
                head.name.span(),
                "`inertia` takes 3 principal moments or 6 entries `[ixx, iyy, izz, ixy, ixz, iyz]`",
            );
        }
        check_inertia(&head.name, &mass, &inertia, errors);
        let elements: Vec<Option<usize>> = match head.count {
            Some(n) => (0..n).map(Some).collect(),
            None => vec![None],
        };
        for element in elements {
            let (mass, inertia) = (mass.clone(), inertia.clone());
            bodies.push(Body { name: head.name.clone(), element, mass, inertia });
        }
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
        if bodies[..i].iter().any(|e| e.name == b.name) {
            continue;
        }
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
    /// Checks one `#[joint(..)]` (or a row of them) and adds it.
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
        if a.name == "ground" && b.name == "ground" {
            errors.at(j.kind.span(), "a joint between the ground and itself constrains nothing");
        }
        let (dynamics, args) = joint_dynamics(j.args, errors);
        let given: Vec<Given> = args.into_iter().map(|a| given(a, fields, errors)).collect();
        let dialect = Dialect { scalar: "f64", fields_by_name: false };
        let resolved = resolve::resolve(kind, Formulation::OmegaBody, given, &dialect, j.kind.span(), errors);
        for (s, span) in resolved.scalars.iter().filter(|(s, _)| s != "f64") {
            errors.at(*span, format!("a scene's fields are `f64`; expected `f64` here, found `{s}`"));
        }
        self.time_types.extend(resolved.time_types);
        let values: Vec<Option<i64>> = match &j.repeat {
            Some(r) => r.values.clone().map(Some).collect(),
            None => vec![None],
        };
        for i in values {
            // One message per mistaken reference, not one per joint of the row.
            let at = i.zip(j.repeat.as_ref().map(|r| &r.var));
            let pair = [self.body_index(a, at, errors), self.body_index(b, at, errors)];
            if pair.iter().zip([a, b]).any(|(p, r)| p.is_none() && r.name != "ground") {
                break;
            }
            let element = i.and_then(|i| usize::try_from(i).ok());
            let params = match at {
                Some((i, var)) => with_variable(&resolved.params, var, i, errors),
                None => resolved.params.clone(),
            };
            let (name, kind_span, bodies) = (j.name.clone(), j.kind.span(), pair);
            let decl = JointDecl { name, element, kind, kind_span, bodies, params, dynamics };
            self.joints.push(decl);
        }
    }

    /// The state index of the body `r` names (with the row's variable at `i`).
    fn body_index(&self, r: &BodyRef, at: Option<(i64, &syn::Ident)>, errors: &mut Errors) -> Option<usize> {
        let i = at.map(|(i, _)| i);
        if r.name == "ground" && r.index.is_none() {
            return None;
        }
        let element = match (r.index, i) {
            (None, _) => None,
            (Some((Index::Fixed(k), _)), _) => Some(k),
            (Some((Index::Var(d), _)), Some(i)) => Some(i + d),
            (Some((Index::Var(_), span)), None) => {
                errors.at(span, format!("`{}` has no row variable; {REPEAT_FORM}", r.name));
                return None;
            }
        };
        let found = self.bodies.iter().position(|x| x.name == r.name && x.element.map(|e| e as i64) == element);
        if found.is_none() {
            let span = r.index.map_or(r.name.span(), |(_, s)| s);
            let count = self.bodies.iter().filter(|x| x.name == r.name && x.element.is_some()).count();
            let message = match (element, count) {
                (Some(e), n) if n > 0 => {
                    let at = at.map(|(i, var)| format!(" for {var} = {i}")).unwrap_or_default();
                    format!("`{}[{e}]`{at} is outside `{}[0..{n}]`", r.name, r.name)
                }
                (Some(_), _) => format!(
                    "`{}` is not a row of bodies; expected `{}` or a body declared `#[body({}[COUNT], ..)]`",
                    r.name, r.name, r.name
                ),
                (None, n) if n > 0 => format!("`{}` is a row of {n} bodies; expected `{}[INDEX]`", r.name, r.name),
                (None, _) => format!(
                    "unknown body `{}`; expected `ground` or a body declared with `#[body({}, ..)]`",
                    r.name, r.name
                ),
            };
            errors.at(span, message);
        }
        found
    }
}

/// The parameters of one joint of a row: the row's variable replaced by its
/// value in every number (`rho1 = [i, 0, 0]`), folded where nothing else is named.
fn with_variable(params: &[Parameter], var: &syn::Ident, value: i64, errors: &mut Errors) -> Vec<Parameter> {
    let mut out = params.to_vec();
    for p in &mut out {
        if let Source::Const(numbers, _) = &mut p.source {
            for n in numbers.iter_mut() {
                match attr::substitute(n, var, value) {
                    Ok(x) => *n = x,
                    Err(e) => errors.push(e),
                }
            }
        }
    }
    out
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
