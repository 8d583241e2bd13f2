//! A scene's robot file (`#[scene(urdf = "..")]`, `#[scene(mjcf = "..")]`):
//! the options that go with one checked, the file read by its format's
//! reader (each behind its feature), and its bodies and joints handed to the
//! scene parser as attributes would give them, with the data the derive
//! writes beside the dynamics (`LINKS`, `LIMITS`) and the couplings.
//!
//! The bodies and joints carry the path's span, so every check and every
//! step after this one is the same as for attributes written by hand. The
//! options checked here: `floating_base` and `file_damping` (URDF only) and
//! `mimic = independent` (followers as free joints rather than rows). An MJCF
//! file's armature, damping and springs (a URDF's damping with
//! `file_damping`) enter the dynamics in relative coordinates only.

use proc_macro2::Span;

use super::context::Errors;
use super::scene::{Body, JointAttr};
#[cfg(any(feature = "urdf", feature = "mjcf"))]
use {
    super::attr::{Arg, Number, Value},
    super::scene::{BodyRef, Quantity},
};

/// What a scene's robot file gives it (empty without one, or after an error).
#[derive(Default)]
pub(super) struct FromFile {
    /// Its bodies, as `#[body]` attributes would.
    pub bodies: Vec<Body>,
    /// Its moving joints, then the joints that close its loops, as
    /// `#[joint]` attributes would.
    pub(super) joints: Vec<JointAttr>,
    /// The file, absolute, for the output to include.
    pub files: Vec<String>,
    /// Its gravity, if the format states one.
    pub gravity: Option<[f64; 3]>,
    /// Its links and limits (`None` without a file).
    pub data: Option<FileData>,
    /// Its couplings (none with `mimic = independent`).
    pub couplings: Vec<Coupling>,
    /// Its closing joints that MuJoCo softens.
    pub soft: Vec<SoftJoint>,
}

/// MuJoCo's softening of an equality: `solref` (its time constant already
/// at least twice the file's timestep) and `solimp`, as MuJoCo clamps them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Soft {
    pub solref: [f64; 2],
    pub solimp: [f64; 5],
    /// A weld's `torquescale` (its orientation rows' factor); 1 elsewhere.
    pub torquescale: f64,
}

/// A soft `connect`'s two ends: each a body with a point in its frame, or
/// `None` for the world.
pub type SoftEnds = [Option<(usize, [f64; 3])>; 2];

/// A closing joint of a file that MuJoCo softens (a `connect`): the
/// joint's name in the scene, its softening and its ends' bodies with the
/// points MuJoCo weighs them at.
#[derive(Clone, Debug)]
pub struct SoftJoint {
    pub joint: String,
    pub soft: Soft,
    pub ends: SoftEnds,
    /// A weld's points on its first and second body (each from its centre,
    /// the body's axes); `None` for a `connect`.
    pub weld: Option<[[f64; 3]; 2]>,
}

/// What a scene asks of its file's reading, each where the option is written.
#[derive(Clone, Copy, Default)]
pub(super) struct Reading {
    /// `floating_base`: a URDF's root link floats.
    pub floating_base: Option<Span>,
    /// `mimic = independent`: the file's couplings read as independent joints.
    pub independent: Option<Span>,
    /// `file_damping`: a URDF's `<dynamics damping>` in the dynamics.
    pub file_damping: Option<Span>,
    /// `equality = hard`: an MJCF file's equalities as ideal constraints.
    pub hard: Option<Span>,
}

/// Reads the scene's `file` (none: nothing) as `reading` asks, knowing
/// whether the absolute impls are wanted; every mistake into `errors`.
pub(super) fn read(
    file: Option<&(RobotFormat, syn::LitStr)>,
    reading: &Reading,
    absolute: bool,
    errors: &mut Errors,
) -> FromFile {
    let Reading { floating_base, independent, file_damping, hard } = *reading;
    if let (Some(at), None) = (independent, file) {
        errors.at(at, "`mimic` is for a robot's file (`urdf = \"..\"` or `mjcf = \"..\"`)");
    }
    match (hard, file) {
        (Some(_), Some((RobotFormat::Mjcf, _))) | (None, _) => {}
        (Some(at), _) => errors.at(
            at,
            "`equality` is for an MJCF file (`mjcf = \"..\"`), whose `<equality>`s MuJoCo makes soft; a URDF's \
             `<mimic>` is an ideal row already",
        ),
    }
    match (floating_base, file) {
        (Some(_), Some((RobotFormat::Urdf, _))) | (None, _) => {}
        (Some(at), _) => errors.at(
            at,
            "`floating_base` is for a URDF file (`urdf = \"..\"`): in MJCF a `<freejoint/>` floats a body, and a \
             body without joints floats already",
        ),
    }
    match (file_damping, file) {
        (Some(_), Some((RobotFormat::Urdf, _))) | (None, _) => {}
        (Some(at), _) => errors.at(
            at,
            "`file_damping` is for a URDF file (`urdf = \"..\"`): an MJCF joint's `damping` is in the dynamics already",
        ),
    }
    if let (Some(at), true) = (file_damping, absolute) {
        errors.at(at, "`file_damping` is modelled in relative coordinates only; expected `coordinates = relative`");
    }
    let Some((format, lit)) = file else { return FromFile::default() };
    // MJCF's armature and damping enter the dynamics (MuJoCo's do) where the
    // scene is relative only; URDF's `<dynamics damping>` is data (Pinocchio's
    // algorithms leave it out too) unless the scene asks (`file_damping`).
    let dynamics = (*format == RobotFormat::Mjcf || file_damping.is_some()) && !absolute;
    let Some(mut read) = robot(*format, lit, (reading, dynamics), errors) else {
        return FromFile::default();
    };
    if let (Some(_), true) = (
        read.soft.first().map(|j| &j.joint).or(read.couplings.iter().find(|c| c.soft.is_some()).map(|c| &c.name)),
        absolute,
    ) {
        errors.at(
            lit.span(),
            "the file's equalities are soft as MuJoCo makes them, which is modelled in relative coordinates only; \
             expected `coordinates = relative` (the default), or `equality = hard` to read them as ideal \
             constraints",
        );
    }
    if independent.is_some() {
        read.couplings.clear();
    } else if let (Some(c), true) = (read.couplings.first(), absolute) {
        errors.at(
            lit.span(),
            format!(
                "the file couples joint `{}` to another; couplings are rows in relative coordinates only: expected \
                 `coordinates = relative` (the default), or `mimic = independent` to read them as independent \
                 joints",
                c.name
            ),
        );
    }
    read
}

/// The formats of robot files.
#[derive(Clone, Copy, PartialEq, Eq)]
pub enum RobotFormat {
    /// `urdf = ".."`.
    Urdf,
    /// `mjcf = ".."`.
    Mjcf,
}

impl RobotFormat {
    fn key(self) -> &'static str {
        match self {
            RobotFormat::Urdf => "urdf",
            RobotFormat::Mjcf => "mjcf",
        }
    }
}

/// A robot file read; `None` after an error.
#[cfg(any(feature = "urdf", feature = "mjcf"))]
fn robot(
    format: RobotFormat,
    lit: &syn::LitStr,
    (reading, dynamics): (&Reading, bool),
    errors: &mut Errors,
) -> Option<FromFile> {
    let read = match format {
        #[cfg(feature = "urdf")]
        RobotFormat::Urdf => super::urdf::read(lit, reading.floating_base.is_some()),
        #[cfg(feature = "mjcf")]
        RobotFormat::Mjcf => super::mjcf::read(lit, (reading.hard.is_some(), reading.independent.is_some())),
        #[allow(unreachable_patterns)] // with both features on
        _ => return missing_feature(format, lit, errors),
    };
    from_file(read.map_err(|e| errors.push(e)).ok()?, lit.span(), dynamics, errors)
}

/// Without the format's feature, a file cannot be read.
#[cfg(not(any(feature = "urdf", feature = "mjcf")))]
fn robot(format: RobotFormat, lit: &syn::LitStr, _: (&Reading, bool), errors: &mut Errors) -> Option<FromFile> {
    missing_feature(format, lit, errors)
}

/// The error for a file whose format's feature is off.
fn missing_feature(format: RobotFormat, lit: &syn::LitStr, errors: &mut Errors) -> Option<FromFile> {
    let key = format.key();
    errors.at(
        lit.span(),
        format!(
            "reading a robot's `{key}` file needs the `{key}` feature: `joint-runtime = {{ version = \"..\", features \
             = [\"{key}\"] }}`"
        ),
    );
    None
}

/// A robot read, as attributes would give it (with each joint's armature
/// and damping when `dynamics`).
#[cfg(any(feature = "urdf", feature = "mjcf"))]
fn from_file(robot: super::robot::Robot, span: Span, dynamics: bool, errors: &mut Errors) -> Option<FromFile> {
    if let Some(b) = robot.bodies.iter().find(|b| b.gravcomp != 0.0 && !dynamics) {
        let message = format!(
            "body `{}` has gravity compensation (`gravcomp`), modelled in relative coordinates only; expected \
             `coordinates = relative`",
            b.name
        );
        errors.at(span, message);
    }
    // Links and joints are named apart, as in the file.
    let (mut body_names, mut joint_names) = (Vec::new(), Vec::new());
    let ident = |name: &str, taken: &mut Vec<String>, errors: &mut Errors| -> syn::Ident {
        let text = super::robot::rust_name(name, taken.len());
        if taken.contains(&text) {
            errors.at(span, format!("`{name}` and another name of the file are both `{text}` as Rust names"));
        }
        taken.push(text.clone());
        syn::Ident::new(&text, span)
    };
    let known = |v: &[f64]| v.iter().map(|&x| Number::Known(x)).collect::<Vec<_>>();
    let bodies: Vec<Body> = robot
        .bodies
        .iter()
        .map(|b| Body {
            name: ident(&b.name, &mut body_names, errors),
            element: None,
            mass: Quantity::Const(known(&[b.mass])),
            inertia: Quantity::Const(known(&b.inertia)),
        })
        .collect();
    let body_ref = |b: Option<usize>| BodyRef {
        name: b.map_or_else(|| syn::Ident::new("ground", span), |b| bodies[b].name.clone()),
        index: None,
    };
    let list = |v: &[f64; 3]| Some(Value::List(known(v), span));
    let arg = |key: &str, v: &[f64; 3]| Arg { key: syn::Ident::new(key, span), value: list(v) };
    let mut soft = Vec::new();
    let joints = robot
        .joints
        .iter()
        .chain(&robot.closures)
        .map(|j| {
            // A weld's axis is `z` on both bodies: its rest rotation the identity.
            let mut args = match j.kind {
                "spherical" => vec![arg("rho1", &j.rho1), arg("rho2", &j.rho2)],
                _ => vec![arg("axis1", &j.axis), arg("axis2", &j.axis), arg("rho1", &j.rho1), arg("rho2", &j.rho2)],
            };
            args.extend(dynamics_args(j, dynamics, span, errors));
            let name = ident(&j.name, &mut joint_names, errors);
            if let Some((s, ends)) = j.soft {
                let weld = (j.kind == "fixed").then_some([j.rho1, j.rho2]);
                soft.push(SoftJoint { joint: name.to_string(), soft: s, ends, weld });
            }
            JointAttr {
                name,
                repeat: None,
                kind: syn::Ident::new(j.kind, span),
                bodies: vec![body_ref(j.parent), body_ref(Some(j.child))],
                args,
            }
        })
        .collect();
    let limits = robot.joints.iter().map(|j| (j.name.clone(), j.limits)).collect();
    // The file's moving joints are the scene's first joints, in its order.
    let index = |name: &str| robot.joints.iter().position(|j| j.name == name);
    let couplings = robot
        .couplings
        .iter()
        .filter_map(|c| {
            let (follower, leader) = (index(&c.follower)?, index(&c.leader)?);
            let (multiplier, offset, soft) = (c.multiplier, c.offset, c.soft);
            Some(Coupling { name: c.follower.clone(), follower, leader, multiplier, offset, soft })
        })
        .collect();
    Some(FromFile {
        bodies,
        joints,
        files: vec![robot.path],
        gravity: robot.gravity,
        data: Some(FileData {
            links: robot.links,
            limits,
            library: robot.library,
            options: robot.options,
            compensation: robot.bodies.iter().map(|b| b.gravcomp).collect(),
        }),
        couplings,
        soft,
    })
}

/// A joint's armature, damping and spring as the derive's attributes, in
/// relative coordinates (`dynamics`); a spring is refused otherwise.
#[cfg(any(feature = "urdf", feature = "mjcf"))]
fn dynamics_args(j: &super::robot::RobotJoint, dynamics: bool, span: Span, errors: &mut Errors) -> Vec<Arg> {
    let mut args = Vec::new();
    let spring = j.limits.spring;
    if spring.stiffness != 0.0 && !dynamics {
        let message = format!(
            "joint `{}` has a spring (`stiffness`), modelled in relative coordinates only; expected \
             `coordinates = relative`",
            j.name
        );
        errors.at(span, message);
    }
    let sprung = (spring.stiffness != 0.0).then_some(spring);
    let springs = [("stiffness", sprung.map(|s| s.stiffness)), ("spring_rest", sprung.map(|s| s.rest))];
    for (key, value) in [("armature", j.limits.armature), ("damping", j.limits.damping)].into_iter().chain(springs) {
        if let Some(x) = value.filter(|&x| dynamics && x != 0.0) {
            args.push(Arg { key: syn::Ident::new(key, span), value: Some(Value::Number(Number::Known(x), span)) });
        }
    }
    args
}

/// `follower = multiplier · leader + offset`: joints by their index.
#[derive(Clone, Debug)]
pub struct Coupling {
    /// The follower's name in the file (the row block's).
    pub name: String,
    pub follower: usize,
    pub leader: usize,
    pub multiplier: f64,
    pub offset: f64,
    /// MuJoCo's softening (an MJCF `<equality joint>`); `None`: an ideal row.
    pub soft: Option<Soft>,
}

/// A link's frame on its body (`None`: the ground), from a robot's file:
/// the rotation from the link's frame to the body's (rows) and the link's
/// origin from the body's centre, the body's components.
pub struct FileLink {
    /// The file's name.
    pub name: String,
    /// Its body.
    pub body: Option<usize>,
    /// The rotation from the link's frame to the body's, by rows.
    pub rotation: [[f64; 3]; 3],
    /// The link's origin from the body's centre (the world's origin for the ground).
    pub origin: [f64; 3],
    /// What it looks like, in its own frame.
    pub visuals: Vec<FileVisual>,
}

/// One shape on a link, its pose in the link's frame.
#[derive(Clone, Debug, PartialEq)]
pub struct FileVisual {
    /// The shape's axes (by rows) and origin in the link's frame.
    pub pose: ([[f64; 3]; 3], [f64; 3]),
    pub shape: FileShape,
    /// Red, green, blue, opacity, where the file gives them.
    pub rgba: Option<[f64; 4]>,
}

/// The runtime's `robot::Shape`, with the mesh's file as read.
// MJCF's shapes without `mjcf` (URDF draws neither ellipsoids nor planes).
#[cfg_attr(not(feature = "mjcf"), allow(dead_code))]
#[derive(Clone, Debug, PartialEq)]
pub enum FileShape {
    Box([f64; 3]),
    Sphere(f64),
    /// Radius, half length, along `z`.
    Cylinder(f64, f64),
    /// Radius, half length of the cylinder, along `z`.
    Capsule(f64, f64),
    Ellipsoid([f64; 3]),
    Plane([f64; 2]),
    Mesh {
        file: String,
        scale: [f64; 3],
    },
}

/// The shape `visual` gives in the frame of a link whose frame is `link` in
/// its body's: what the runtime's `Visual` holds.
pub fn on_body(link: &([[f64; 3]; 3], [f64; 3]), visual: &FileVisual) -> ([[f64; 3]; 3], [f64; 3]) {
    let (a, (b, p)) = (&link.0, &visual.pose);
    let turn = std::array::from_fn(|i| std::array::from_fn(|j| (0..3).map(|k| a[i][k] * b[k][j]).sum()));
    (turn, std::array::from_fn(|i| link.1[i] + (0..3).map(|k| a[i][k] * p[k]).sum::<f64>()))
}

/// A joint's limits, damping and friction as its file gives them, where given.
#[derive(Clone, Copy, Default)]
pub struct FileLimits {
    /// `lower`, `upper` (both given).
    pub range: Option<(f64, f64)>,
    /// `effort`.
    pub effort: Option<f64>,
    /// `velocity`.
    pub velocity: Option<f64>,
    /// `damping`.
    pub damping: Option<f64>,
    /// `friction` (MJCF: `frictionloss`).
    pub friction: Option<f64>,
    /// MJCF's `armature`: inertia added to the joint's own freedom.
    pub armature: Option<f64>,
    /// MJCF's joint spring and `ref`.
    #[cfg_attr(not(any(feature = "urdf", feature = "mjcf")), allow(dead_code))]
    pub spring: FileSpring,
}

/// An MJCF hinge's or slide's spring and `ref` (zero where the file has none).
#[derive(Clone, Copy, Default, Debug, PartialEq)]
pub struct FileSpring {
    /// `stiffness` (N m/rad, N/m).
    pub stiffness: f64,
    /// Where its force is zero, in the tree's coordinate: `springref − ref`.
    pub rest: f64,
    /// `ref`: MuJoCo's coordinate at the file's pose, the tree's zero.
    pub reference: f64,
}

/// The robot library whose state layout a file's scene converts to.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(not(all(feature = "urdf", feature = "mjcf")), allow(dead_code))]
pub enum Library {
    /// MJCF: the file's joints as written (depth first).
    MuJoCo,
    /// URDF: depth first from the root, a link's child joints by name
    /// (urdfdom keeps them in a map), a floating base first.
    Pinocchio,
}

/// A moving joint as its library writes it.
pub struct LibraryJoint {
    /// The file's name (`root_joint`, Pinocchio's, for a URDF's floating base).
    pub name: String,
    /// `free`, `ball`, `hinge`, `continuous` (Pinocchio's `cos, sin`) or `slide`.
    pub kind: &'static str,
    /// Its child link (an index of the file's links).
    pub link: usize,
    /// Its child body.
    pub body: usize,
    /// Its index among the moving joints (the scene's first joints); `None` for a free joint.
    pub joint: Option<usize>,
    /// The library's coordinate minus the tree's (MJCF's `ref`).
    pub offset: f64,
}

/// What a robot's file says beyond its bodies and joints.
pub struct FileData {
    /// Every link's frame, in the file's order.
    pub links: Vec<FileLink>,
    /// Each moving joint's limits, by the file's name, in the file's order.
    pub limits: Vec<(String, FileLimits)>,
    /// The moving joints as the format's library (MuJoCo, Pinocchio)
    /// orders and writes them.
    pub library: (Library, Vec<LibraryJoint>),
    /// MJCF's `<option timestep integrator>`.
    pub options: FileOptions,
    /// Each file body's gravity compensation (MJCF `gravcomp`), the scene's
    /// first bodies, in its order.
    pub compensation: Vec<f64>,
}

/// MJCF's `<option timestep integrator>`, where given: the file's step,
/// data for the caller (the step is the caller's choice here).
#[derive(Clone, Default, Debug, PartialEq)]
pub struct FileOptions {
    /// `timestep` (s).
    pub timestep: Option<f64>,
    /// `integrator`: `Euler`, `RK4`, `implicit` or `implicitfast`.
    pub integrator: Option<String>,
}
