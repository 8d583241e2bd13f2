//! `#[contact(..)]`: a point or a frame of a body held to the world or to
//! another body, as rows on a relative scene's tree (a foot on the ground, a
//! tool welded to a fixture, a loop closed at a point).
//!
//! ```text
//! #[contact(NAME = point(END) | point(END, END) | frame(END), at = [x, y, z], at2 = [x, y, z], axes = world | local)]
//! END = a body of the scene, `ground`, or a link of the scene's robot file (a URDF link, an MJCF body)
//! ```
//!
//! `at` is the point on the first end, in that end's frame: a body's (from
//! its centre of mass, its own axes, as a joint's `rho1`) or a file link's
//! (from the link's origin, its axes); `at2` the same on the second end
//! (`point` between two bodies). A contact's rows are written at the
//! velocity level, as Pinocchio's rigid constraints are: `J v` is the
//! point's velocity (`point`, 3 rows) or the frame's twist (`frame`, 6 rows,
//! linear then angular), relative to the second end, and `γ` the rest of its
//! acceleration. `axes = world` (the default) gives them in the world's axes
//! (Pinocchio's `LOCAL_WORLD_ALIGNED`: a foot's force is then the ground's
//! reaction in the world's axes, where a terrain's normal and a friction cone
//! are known); `axes = local` in the first end's frame (`LOCAL`). Which
//! contacts hold is chosen per call at run time.

use syn::parse::{Parse, ParseStream};
use syn::{Token, parenthesized};

use super::attr::{self, Arg, Value};
use super::context::Errors;
use super::scene::Body;

/// `NAME = KIND(END[, END]), ARG, ...`.
struct ContactAttr {
    name: syn::Ident,
    kind: syn::Ident,
    ends: Vec<syn::Ident>,
    args: Vec<Arg>,
}

const FORM: &str = "expected `NAME = point(BODY)`, `NAME = point(BODY, BODY)` or `NAME = frame(BODY)`, as in \
                    `left_foot = point(shank), at = [0, 0, -0.2]`";

impl Parse for ContactAttr {
    fn parse(input: ParseStream) -> syn::Result<Self> {
        let name: syn::Ident = input.parse()?;
        input.parse::<Token![=]>().map_err(|e| syn::Error::new(e.span(), FORM))?;
        let kind: syn::Ident = input.parse().map_err(|e| syn::Error::new(e.span(), FORM))?;
        let content;
        parenthesized!(content in input);
        let ends = syn::punctuated::Punctuated::<syn::Ident, Token![,]>::parse_terminated(&content)
            .map_err(|e| syn::Error::new(e.span(), FORM))?;
        let mut args = Vec::new();
        if input.parse::<Option<Token![,]>>()?.is_some() {
            args = attr::args_until_semicolon(input)?;
        }
        Ok(ContactAttr { name, kind, ends: ends.into_iter().collect(), args })
    }
}

/// What a contact holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ContactKind {
    /// A point (3 rows).
    Point,
    /// A frame: its point and its axes (6 rows).
    Frame,
}

/// In whose axes a contact's rows and force are given.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Axes {
    /// The world's (`LOCAL_WORLD_ALIGNED`).
    World,
    /// The first end's frame (`LOCAL`).
    Local,
}

/// One end of a contact: a body (`None`: the ground) and the contact's frame
/// on it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ContactEnd {
    /// The body, `None` for the ground.
    pub body: Option<usize>,
    /// The contact frame's axes in the body's frame, by rows.
    pub rotation: [[f64; 3]; 3],
    /// The contact point in the body's frame, from its centre of mass (from
    /// the world's origin on the ground).
    pub point: [f64; 3],
}

/// A checked contact.
pub struct ContactDecl {
    /// Its name (its row block's).
    pub name: syn::Ident,
    /// Point or frame.
    pub kind: ContactKind,
    /// The end that is held, then the one that holds it.
    pub ends: [ContactEnd; 2],
    /// The rows' axes.
    pub axes: Axes,
}

impl ContactDecl {
    /// Its number of rows.
    pub fn rows(&self) -> usize {
        match self.kind {
            ContactKind::Point => 3,
            ContactKind::Frame => 6,
        }
    }
}

/// A frame a contact may name: a scene's body, or a robot file's link.
pub struct Named<'a> {
    /// The scene's bodies.
    pub bodies: &'a [Body],
    /// A file's links by their file name, each as a frame on its body (its
    /// axes, by rows, and its origin).
    pub links: Vec<(String, ContactEnd)>,
}

const IDENTITY: [[f64; 3]; 3] = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

/// Every `#[contact(..)]` of `input`, checked.
pub fn parse(input: &syn::DeriveInput, named: &Named, errors: &mut Errors) -> Vec<ContactDecl> {
    let mut out: Vec<ContactDecl> = Vec::new();
    for a in input.attrs.iter().filter(|a| a.path().is_ident("contact")) {
        let entries = match attr::entries::<ContactAttr>(a) {
            Ok(entries) => entries,
            Err(e) => {
                errors.push(e);
                continue;
            }
        };
        for c in entries {
            if out.iter().any(|x| x.name == c.name) {
                errors.at(c.name.span(), format!("contact `{}` is declared twice", c.name));
            }
            if let Some(decl) = check(c, named, errors) {
                out.push(decl);
            }
        }
    }
    out
}

fn check(c: ContactAttr, named: &Named, errors: &mut Errors) -> Option<ContactDecl> {
    let kind = match c.kind.to_string().as_str() {
        "point" => ContactKind::Point,
        "frame" => ContactKind::Frame,
        other => {
            let message = format!("unknown contact `{other}`; expected `point` (3 rows) or `frame` (6 rows)");
            errors.at(c.kind.span(), message);
            return None;
        }
    };
    let (first, second) = match (kind, c.ends.as_slice()) {
        (ContactKind::Point, [a]) | (ContactKind::Frame, [a]) => (a, None),
        (ContactKind::Point, [a, b]) => (a, Some(b)),
        (ContactKind::Frame, [_, b]) => {
            let message = "a frame contact holds a frame to the world; expected `frame(BODY)` (a frame between two \
                           bodies is a `fixed` joint)";
            errors.at(b.span(), message);
            return None;
        }
        _ => {
            errors.at(c.kind.span(), FORM);
            return None;
        }
    };
    let (mut at, mut at2, mut axes) = (None, None, Axes::World);
    for a in c.args {
        match (a.key.to_string().as_str(), a.value) {
            ("at", Some(v)) => at = point(v, "at", errors),
            ("at2", Some(v)) if second.is_some() => at2 = point(v, "at2", errors),
            ("axes", Some(Value::Ident(i))) if i == "world" => axes = Axes::World,
            ("axes", Some(Value::Ident(i))) if i == "local" => axes = Axes::Local,
            ("axes", v) => {
                let span = v.map_or(a.key.span(), |v| v.span());
                errors.at(span, "expected `axes = world` (the default) or `axes = local` (the first end's frame)");
            }
            (key, _) => {
                let keys = if second.is_some() { "`at`, `at2` or `axes`" } else { "`at` or `axes`" };
                errors.at(a.key.span(), format!("unknown contact option `{key}`; expected {keys}"));
            }
        }
    }
    let first_end = end(first, at.unwrap_or([0.0; 3]), named, errors)?;
    let ground = ContactEnd { body: None, rotation: IDENTITY, point: [0.0; 3] };
    let second_end = match second {
        Some(b) => end(b, at2.unwrap_or([0.0; 3]), named, errors)?,
        None => ground,
    };
    if first_end.body.is_none() {
        errors
            .at(first.span(), "the first end of a contact is the one held; expected a body that moves, not the ground");
        return None;
    }
    if first_end.body == second_end.body {
        errors.at(c.kind.span(), "a contact between a body and itself holds nothing; expected two bodies");
        return None;
    }
    Some(ContactDecl { name: c.name, kind, ends: [first_end, second_end], axes })
}

/// `[x, y, z]` of known numbers.
fn point(v: Value, key: &str, errors: &mut Errors) -> Option<[f64; 3]> {
    let span = v.span();
    let known = v.numbers().and_then(|(n, _)| attr::known(&n));
    match known.as_deref() {
        Some(&[x, y, z]) if [x, y, z].iter().all(|v| v.is_finite()) => Some([x, y, z]),
        _ => {
            errors.at(span, format!("expected `{key} = [x, y, z]` of finite numbers"));
            None
        }
    }
}

/// The end named `name`, with the point `at` in its frame.
fn end(name: &syn::Ident, at: [f64; 3], named: &Named, errors: &mut Errors) -> Option<ContactEnd> {
    let text = name.to_string();
    if text == "ground" {
        return Some(ContactEnd { body: None, rotation: IDENTITY, point: at });
    }
    if let Some(b) = named.bodies.iter().position(|b| b.name == text && b.element.is_none()) {
        return Some(ContactEnd { body: Some(b), rotation: IDENTITY, point: at });
    }
    let by_name = |l: &&(String, ContactEnd)| {
        l.0 == text || l.0.chars().map(|c| if c.is_ascii_alphanumeric() { c } else { '_' }).eq(text.chars())
    };
    if let Some(&(_, ContactEnd { body, rotation, point: origin })) = named.links.iter().find(by_name) {
        // The point in the body's frame: the link's origin plus `at` turned.
        let turned = [0, 1, 2].map(|r| (0..3).map(|c| rotation[r][c] * at[c]).sum::<f64>());
        let point = [0, 1, 2].map(|i| origin[i] + turned[i]);
        return Some(ContactEnd { body, rotation, point });
    }
    let bodies: Vec<String> = named.bodies.iter().map(|b| b.name.to_string()).collect();
    let candidates = bodies.iter().map(String::as_str).chain(named.links.iter().map(|l| l.0.as_str()));
    let hint = super::names::did_you_mean(&text, candidates);
    let message =
        format!("unknown body or link `{text}`{hint}; expected `ground`, a body of the scene or a link of its file");
    errors.at(name.span(), message);
    None
}
