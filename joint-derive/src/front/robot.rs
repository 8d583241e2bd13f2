//! What the robot readers share (`urdf.rs`, `mjcf.rs`): a file's links and
//! joints as read, and [`assemble`], which puts them in the scene's terms,
//! as if written as `#[body]` and `#[joint]` attributes.
//!
//! Frames: every body's frame has its origin at the body's centre of mass
//! and its axes parallel to the world's at the file's zero configuration
//! (every joint value zero). Each joint's axis is then one vector on both of
//! its bodies, its rest rotation the identity, and its coordinate the
//! file's: an angle positive about the axis (a slide along it), zero where
//! the file's is. Links joined by fixed joints (a URDF `fixed` joint, an
//! MJCF body without joints, a site) are one body (masses, centres and
//! inertias combined: the scene models only what moves); the root link and
//! the links fixed to it are the ground. A floating joint is left out, so
//! its child floats (the derive gives it a free joint); with `floating_base`
//! the root link floats too. Closures (MJCF's `<equality>`) become ball or
//! fixed joints. The moving joints are also listed in their library's order
//! (MuJoCo's: the file's; Pinocchio's: depth first, siblings by name), which
//! the derive writes as the scene's `MUJOCO` or `PINOCCHIO` layout.

use std::collections::HashMap;

use super::geometry::{eigenvalues, physical};

#[cfg(feature = "mjcf")]
pub use super::files::FileSpring;
pub use super::files::{FileLimits, FileLink, FileOptions, FileVisual, Library, LibraryJoint};

/// A robot in the scene's terms.
pub struct Robot {
    /// The moving bodies, in the order of their first links in the file.
    pub bodies: Vec<RobotBody>,
    /// The moving joints, in the file's order.
    pub joints: Vec<RobotJoint>,
    /// The joints that close loops (MJCF's `<equality>`), in the file's order.
    pub closures: Vec<RobotJoint>,
    /// Every link's frame on its body, in the file's order.
    pub links: Vec<FileLink>,
    /// The file, absolute: the derive includes it so that cargo rebuilds
    /// when it changes.
    pub path: String,
    /// The file's gravity, if the format has one (MJCF's `<option gravity>`).
    pub gravity: Option<V3>,
    /// MJCF's `<option timestep integrator>`: data for the caller's step.
    pub options: FileOptions,
    /// Joints that follow others (URDF `<mimic>`, MJCF `<equality joint>`).
    pub couplings: Vec<FileCoupling>,
    /// The moving joints (a floating base's included) in the library's
    /// order: MuJoCo's for an MJCF file, Pinocchio's for a URDF.
    pub library: (Library, Vec<LibraryJoint>),
}

/// `follower = multiplier · leader + offset`, by the joints' names.
#[derive(Clone, Debug, PartialEq)]
pub struct FileCoupling {
    pub follower: String,
    pub leader: String,
    pub multiplier: f64,
    pub offset: f64,
    /// MuJoCo's softening (an MJCF `<equality joint>` read soft); `None`
    /// for an ideal row.
    pub soft: Option<Soft>,
}

/// One body: the links a chain of fixed joints welds together.
pub struct RobotBody {
    /// The first link's name.
    pub name: String,
    /// Mass.
    pub mass: f64,
    /// Inertia about the centre of mass, world axes at the zero
    /// configuration: `[ixx, iyy, izz, ixy, ixz, iyz]` (tensor entries).
    pub inertia: [f64; 6],
    /// The fraction of its weight held up at its centre (MJCF `gravcomp`).
    pub gravcomp: f64,
}

/// One joint between two bodies (`None`: the ground).
pub struct RobotJoint {
    /// The file's name.
    pub name: String,
    /// The catalogue's kind: `revolute`, `translational`, `spherical` or `fixed`.
    pub kind: &'static str,
    /// The parent body.
    pub parent: Option<usize>,
    /// The child body.
    pub child: usize,
    /// The unit axis, both bodies' (and the world's) components at zero.
    pub axis: V3,
    /// The joint point from the parent's centre of mass (the world's origin
    /// for the ground).
    pub rho1: V3,
    /// The joint point from the child's centre of mass.
    pub rho2: V3,
    /// Its limits and friction.
    pub limits: FileLimits,
    /// A closing joint MuJoCo softens: its `solref`, `solimp` and each
    /// end's body with that MuJoCo body's centre of mass from the body's
    /// (what MuJoCo's inverse weights are taken at); `None` for an ideal one.
    pub soft: Option<(Soft, SoftEnds)>,
}

pub use super::files::{Soft, SoftEnds};

/// An MJCF `<default>` class's attributes of one element (joint, geom):
/// each value and where it is written, its parents' included.
#[cfg(feature = "mjcf")]
pub type Class = HashMap<String, (String, roxmltree::TextPos)>;

pub type V3 = [f64; 3];
pub type M3 = [[f64; 3]; 3];
/// A rotation (by rows) and an offset: a frame in another.
pub type Pose = (M3, V3);

/// A joint's kind as the files give it.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Kind {
    /// URDF `revolute` and `continuous`, MJCF `hinge`.
    Revolute,
    /// URDF `prismatic`, MJCF `slide`.
    Prismatic,
    /// MJCF `ball`.
    Spherical,
    /// URDF `fixed`; an MJCF body without joints, a site.
    Fixed,
    /// URDF `floating`, MJCF `free`: left out, so the child floats.
    Floating,
}

/// A link as the file gives it.
pub struct Link {
    pub name: String,
    /// Mass, centre and inertia in the link's frame (inertia's own frame
    /// turned into the link's axes); `None` without one.
    pub inertial: Option<(f64, V3, M3)>,
    /// Its mass is the file's but not stated (an MJCF body with geoms and
    /// no `<inertial>`): an error on a moving body.
    pub unknown: bool,
    /// MJCF's `gravcomp`: the fraction of its weight held up (zero elsewhere).
    pub gravcomp: f64,
    /// What it looks like (URDF `<visual>`, MJCF `<geom>`), in its frame.
    pub visuals: Vec<FileVisual>,
    pub at: roxmltree::TextPos,
    /// Where its mass and its inertia are written (`at` without them).
    pub inertial_at: [roxmltree::TextPos; 2],
}

/// A joint as the file gives it: the child link's frame is `origin` in the
/// parent's, the joint's point `point` in the child's.
pub struct Joint {
    pub name: String,
    pub kind: Kind,
    pub parent: usize,
    pub child: usize,
    pub origin: (M3, V3),
    pub point: V3,
    /// In the child link's frame.
    pub axis: V3,
    pub limits: FileLimits,
    /// A URDF `continuous` joint (Pinocchio writes it `cos θ, sin θ`).
    pub continuous: bool,
    pub at: roxmltree::TextPos,
    /// Where its axis is written (`at` without one).
    pub axis_at: roxmltree::TextPos,
}

/// A joint that closes a loop between two links: a ball (`weld: false`)
/// or a weld, at `anchor` in the frame of link `anchor_on`.
pub struct Closure {
    pub name: String,
    pub weld: bool,
    pub links: [usize; 2],
    pub anchor_on: usize,
    pub anchor: V3,
    pub at: roxmltree::TextPos,
    /// MuJoCo's softening; `None` for an ideal joint.
    pub soft: Option<Soft>,
}

/// Reads `path`: relative to the crate's `CARGO_MANIFEST_DIR`, or, where
/// the crate's directory has no such file, to the folder of the source file
/// that holds the derive (as `include_str!` reads). The second place is what
/// lets a file beside its module, or a test harness's generated crate (whose
/// directory is inside the target folder), name its robot the same way
/// wherever the target folder is. Returns the text and its absolute name
/// (what the build tracks; errors name it by [`shown`]).
pub fn read_text(path: &syn::LitStr, what: &str) -> syn::Result<(String, String)> {
    let wanted = std::path::PathBuf::from(path.value());
    let dir = std::env::var("CARGO_MANIFEST_DIR").unwrap_or_default();
    let in_crate = std::path::Path::new(&dir).join(&wanted);
    // The compiler's span (`local_file` is the compiler's, stable since 1.88);
    // outside a macro (the front end's unit tests) there is no source file.
    let source = proc_macro::is_available().then(|| path.span().unwrap().local_file()).flatten();
    let beside = source.and_then(|f| f.parent().map(|d| d.join(&wanted)));
    let full = match beside {
        Some(b) if !in_crate.exists() && b.exists() => b,
        _ => in_crate,
    };
    // `..` resolved, so that errors name the file as cargo names paths.
    let full = std::fs::canonicalize(&full).unwrap_or(full);
    let shown = full.display().to_string();
    let text = std::fs::read_to_string(&full).map_err(|e| {
        syn::Error::new(
            path.span(),
            format!(
                "cannot read `{shown}`: {e}; expected {what} file's path relative to the crate's directory \
                 (or to the folder of this source file)"
            ),
        )
    })?;
    Ok((text, shown))
}

/// How an error names the file at `full` (absolute): as cargo prints
/// paths, relative to the directory the compiler runs in (the workspace's
/// root, where the terminal usually is), or absolute where the file is
/// outside it; so that a terminal's or an editor's link opens it.
pub fn shown(full: &str) -> String {
    let path = std::path::Path::new(full);
    let cwd = std::env::current_dir().ok();
    match cwd.as_deref().and_then(|d| path.strip_prefix(d).ok()) {
        Some(relative) if !relative.as_os_str().is_empty() => relative.display().to_string(),
        _ => full.to_string(),
    }
}

/// A file's name as a Rust identifier: other characters as `_`, a leading
/// `_` where the name is not one (a digit first, a keyword, `ground`), and
/// `_{index}` for a name with nothing left.
pub fn rust_name(name: &str, index: usize) -> String {
    let mut text: String = name.chars().map(|c| if c.is_ascii_alphanumeric() { c } else { '_' }).collect();
    if text == "ground" || syn::parse_str::<syn::Ident>(&text).is_err() {
        text.insert(0, '_');
    }
    if syn::parse_str::<syn::Ident>(&text).is_err() {
        text = format!("_{index}");
    }
    text
}

pub type Fail<'f> = dyn Fn(roxmltree::TextPos, String) -> syn::Error + 'f;

/// `text` parsed, or the error at its place: a file cut short at its last
/// line and column (where the reader ran out), not at `1:1`.
pub fn parse_xml<'i>(text: &'i str, fail: &Fail) -> syn::Result<roxmltree::Document<'i>> {
    roxmltree::Document::parse(text).map_err(|e| {
        let cut = matches!(e, roxmltree::Error::UnexpectedEndOfStream | roxmltree::Error::UnclosedRootNode);
        if !cut {
            return fail(e.pos(), format!("malformed XML: {e}"));
        }
        let row = text.lines().count().max(1);
        let col = text.lines().last().map_or(0, |l| l.chars().count()) + 1;
        let end =
            roxmltree::TextPos::new(u32::try_from(row).unwrap_or(u32::MAX), u32::try_from(col).unwrap_or(u32::MAX));
        fail(end, format!("malformed XML: {e} (the file ends here, cut short)"))
    })
}

/// The bodies (links welded by fixed joints), the moving joints and the
/// closures. With `floating`, the root link (and the links fixed to it) is
/// a body that floats, not the ground.
pub fn assemble(
    links: &[Link],
    joints: &[Joint],
    closures: &[Closure],
    (floating, library): (bool, Library),
    fail: &Fail,
) -> syn::Result<Robot> {
    let (inbound, root) = tree(links, joints, fail)?;
    let (pose, order) = poses(links, joints, root, fail)?;
    let (body_of, heads) = welded_bodies(joints, &inbound, (root, &order), floating);
    let mut centres = Vec::new();
    let mut bodies = Vec::new();
    for (b, &head) in heads.iter().enumerate() {
        let members: Vec<usize> = (0..links.len()).filter(|&l| body_of[l] == Some(b)).collect();
        if let Some(&l) = members.iter().find(|&&l| links[l].unknown) {
            let name = &links[l].name;
            return Err(fail(
                links[l].at,
                format!(
                    "body `{name}` moves and has geoms but no `<inertial>`: inertia from geoms is not computed; \
                     expected `<inertial pos=\"..\" mass=\"..\" diaginertia=\"..\"/>`"
                ),
            ));
        }
        let (mass, centre, inertia) = combine(&members, links, &pose);
        check_inertia(&links[head], mass, &inertia, fail)?;
        let gravcomp = compensation(&members, links, fail)?;
        centres.push(centre);
        let inertia =
            round_off([inertia[0][0], inertia[1][1], inertia[2][2], inertia[0][1], inertia[0][2], inertia[1][2]]);
        bodies.push(RobotBody { name: links[head].name.clone(), mass, inertia, gravcomp });
    }
    let from = |b: Option<usize>| b.map_or([0.0; 3], |b| centres[b]);
    let link_centres: Vec<V3> = links.iter().map(|l| l.inertial.map_or([0.0; 3], |(_, c, _)| c)).collect();
    let placed = Placed { pose: &pose, centres: &link_centres, body_of: &body_of, from: &from };
    let out = moving_joints(links, joints, &placed, fail)?;
    let loops = closure_joints(closures, &placed, fail)?;
    // Every link's frame: the body's axes are the world's at zero.
    let frames = (0..links.len())
        .map(|l| {
            let (r, p) = pose[l];
            let body = body_of[l];
            let visuals = links[l].visuals.clone();
            FileLink { name: links[l].name.clone(), body, rotation: r, origin: sub(&p, &from(body)), visuals }
        })
        .collect();
    let library_joints = library_joints(joints, (library, root, floating), &body_of);
    Ok(Robot {
        bodies,
        joints: out,
        closures: loops,
        links: frames,
        path: String::new(),
        gravity: None,
        options: FileOptions::default(),
        couplings: Vec::new(),
        library: (library, library_joints),
    })
}

/// Where the links are: each link's pose, its body, and a body's centre
/// (the ground's: the origin).
struct Placed<'a> {
    pose: &'a [Pose],
    /// Each link's centre of mass in its frame (its origin without mass).
    centres: &'a [V3],
    body_of: &'a [Option<usize>],
    from: &'a dyn Fn(Option<usize>) -> V3,
}

/// Each link's body and each body's head link: a moving joint's child
/// starts a body, a fixed joint's child joins its parent's (the root's: the
/// ground, or a floating base); bodies in the file's link order.
fn welded_bodies(
    joints: &[Joint],
    inbound: &[Option<usize>],
    (root, order): (usize, &[usize]),
    floating: bool,
) -> (Vec<Option<usize>>, Vec<usize>) {
    let mut body_of: Vec<Option<usize>> = vec![None; inbound.len()];
    let mut heads: Vec<usize> = Vec::new();
    if floating {
        heads.push(root);
        body_of[root] = Some(0);
    }
    for &l in &order[1..] {
        let j = &joints[inbound[l].unwrap_or(0)];
        body_of[l] = if j.kind == Kind::Fixed {
            body_of[j.parent]
        } else {
            heads.push(l);
            Some(heads.len() - 1)
        };
    }
    let mut by_file: Vec<usize> = (0..heads.len()).collect();
    by_file.sort_by_key(|&b| heads[b]);
    let renumber: HashMap<usize, usize> = by_file.iter().enumerate().map(|(new, &old)| (old, new)).collect();
    let body_of = body_of.iter().map(|b| b.map(|b| renumber[&b])).collect();
    (body_of, by_file.iter().map(|&b| heads[b]).collect())
}

/// The moving joints between bodies: kind, unit axis and joint points.
fn moving_joints(links: &[Link], joints: &[Joint], at: &Placed, fail: &Fail) -> syn::Result<Vec<RobotJoint>> {
    let mut out = Vec::new();
    for j in joints.iter().filter(|j| !matches!(j.kind, Kind::Fixed | Kind::Floating)) {
        let (r, o) = at.pose[j.child];
        let length = norm(&j.axis);
        if j.kind != Kind::Spherical && (length.is_nan() || length <= 1e-12) {
            let label = match j.name.as_str() {
                "" => format!("the joint of body `{}`", links[j.child].name),
                name => format!("joint `{name}`"),
            };
            return Err(fail(j.axis_at, format!("{label} has a zero axis; expected an axis such as `0 0 1`")));
        }
        let (parent, child) = (at.body_of[j.parent], at.body_of[j.child].unwrap_or(0));
        let point = add(&o, &apply(&r, &j.point));
        let (rho1, rho2) = points(&point, at.from, (parent, child)).ok_or_else(|| out_of_range(&j.name, j.at, fail))?;
        let kind = match j.kind {
            Kind::Prismatic => "translational",
            Kind::Spherical => "spherical",
            _ => "revolute",
        };
        let axis = match j.kind {
            Kind::Spherical => [0.0, 0.0, 1.0],
            _ => {
                let axis = round_off(apply(&r, &j.axis.map(|x| x / length)));
                axis.map(|x| x / norm(&axis))
            }
        };
        let name = j.name.clone();
        out.push(RobotJoint { name, kind, parent, child, axis, rho1, rho2, limits: j.limits, soft: None });
    }
    Ok(out)
}

/// The joints that close loops: a ball or a weld at its anchor.
fn closure_joints(closures: &[Closure], at: &Placed, fail: &Fail) -> syn::Result<Vec<RobotJoint>> {
    let mut loops = Vec::new();
    for c in closures {
        let (r, o) = at.pose[c.anchor_on];
        let point = add(&o, &apply(&r, &c.anchor));
        let [a, b] = c.links.map(|l| at.body_of[l]);
        let (parent, child) = match (a, b) {
            (_, Some(b)) if a != Some(b) => (a, b),
            (Some(a), None) => (None, a),
            _ => {
                let message = format!("`{}` joins a body to itself (links on one body or both the world)", c.name);
                return Err(fail(c.at, message));
            }
        };
        let (rho1, rho2) = points(&point, at.from, (parent, child)).ok_or_else(|| out_of_range(&c.name, c.at, fail))?;
        let (name, kind, axis) = (c.name.clone(), if c.weld { "fixed" } else { "spherical" }, [0.0, 0.0, 1.0]);
        let limits = FileLimits::default();
        // MuJoCo weighs a soft connect at each MuJoCo body's centre of mass.
        let centre = |l: usize| {
            let (r, o) = at.pose[l];
            let c = at.centres[l];
            let b = at.body_of[l]?;
            Some((b, round_off(sub(&add(&o, &apply(&r, &c)), &(at.from)(Some(b))))))
        };
        let soft = c.soft.map(|s| (s, c.links.map(centre)));
        loops.push(RobotJoint { name, kind, parent, child, axis, rho1, rho2, limits, soft });
    }
    Ok(loops)
}

/// The joints in the library's order (MuJoCo: the file's; Pinocchio: depth
/// first, siblings by name), a floating base first as `root_joint`.
fn library_joints(
    joints: &[Joint],
    (library, root, floating): (Library, usize, bool),
    body_of: &[Option<usize>],
) -> Vec<LibraryJoint> {
    let order = match library {
        Library::MuJoCo => (0..joints.len()).collect(),
        Library::Pinocchio => by_name_depth_first(joints, root),
    };
    let mut library_joints = Vec::new();
    if floating {
        let (name, body) = ("root_joint".to_string(), body_of[root].unwrap_or(0));
        library_joints.push(LibraryJoint { name, kind: "free", link: root, body, joint: None, offset: 0.0 });
    }
    let moving = |k: usize| !matches!(joints[k].kind, Kind::Fixed | Kind::Floating);
    for k in order.into_iter().filter(|&k| joints[k].kind != Kind::Fixed) {
        let j = &joints[k];
        let kind = match j.kind {
            Kind::Floating => "free",
            Kind::Spherical => "ball",
            Kind::Prismatic => "slide",
            _ if j.continuous && library == Library::Pinocchio => "continuous",
            _ => "hinge",
        };
        let joint = moving(k).then(|| (0..k).filter(|&i| moving(i)).count());
        let (name, body, offset) = (j.name.clone(), body_of[j.child].unwrap_or(0), j.limits.spring.reference);
        library_joints.push(LibraryJoint { name, kind, link: j.child, body, joint, offset });
    }
    library_joints
}

/// The joints depth first from `link`, each link's child joints by name
/// (Pinocchio's order for a URDF).
fn by_name_depth_first(joints: &[Joint], link: usize) -> Vec<usize> {
    let mut children: Vec<usize> = (0..joints.len()).filter(|&k| joints[k].parent == link).collect();
    children.sort_by(|&a, &b| joints[a].name.cmp(&joints[b].name));
    children.into_iter().flat_map(|k| std::iter::once(k).chain(by_name_depth_first(joints, joints[k].child))).collect()
}

fn out_of_range(name: &str, at: roxmltree::TextPos, fail: &Fail) -> syn::Error {
    fail(at, format!("joint `{name}` is at a point out of range"))
}

/// `v` with the entries below 1e-14 of its largest set to zero: what a
/// file's quarter turns leave (`rpy="1.5707963267948966"`: cos = 6e-17),
/// which would otherwise be numbers in every product the derive writes
/// (a joint axis along a frame's axis folds its rotations to a sine and a
/// cosine; at 1e-17 off it does not). Points in metres: below 1e-14 m
/// (`at least 1 m` as the scale). The model moves by 1e-14 of itself at most.
fn round_off<const N: usize>(v: [f64; N]) -> [f64; N] {
    let scale = v.iter().fold(0.0_f64, |a, x| a.max(x.abs())).max(if N == 3 { 1.0 } else { 0.0 });
    v.map(|x| if x.abs() <= 1e-14 * scale { 0.0 } else { x })
}

/// The joint point `at` (world, at zero) from the parent's centre (the
/// world's origin for the ground) and from the child's: `rho1`, `rho2`.
fn points(at: &V3, from: impl Fn(Option<usize>) -> V3, (parent, child): (Option<usize>, usize)) -> Option<(V3, V3)> {
    let (rho1, rho2) = (round_off(sub(at, &from(parent))), round_off(sub(at, &from(Some(child)))));
    rho1.iter().chain(&rho2).all(|x| x.is_finite()).then_some((rho1, rho2))
}

/// Each link's joint from its parent (one at most: the file is a tree) and
/// the root link.
fn tree(links: &[Link], joints: &[Joint], fail: &Fail) -> syn::Result<(Vec<Option<usize>>, usize)> {
    let mut inbound: Vec<Option<usize>> = vec![None; links.len()];
    for (k, j) in joints.iter().enumerate() {
        if let Some(other) = inbound[j.child] {
            let (a, c) = (&joints[other].name, &links[j.child].name);
            return Err(fail(
                j.at,
                format!(
                    "link `{c}` is the child of joints `{a}` and `{}`; a URDF is a tree (close a loop with a \
                     `#[joint]` attribute)",
                    j.name
                ),
            ));
        }
        inbound[j.child] = Some(k);
    }
    let roots: Vec<usize> = (0..links.len()).filter(|&l| inbound[l].is_none()).collect();
    match roots.as_slice() {
        [root] => Ok((inbound, *root)),
        [] => Err(fail(joints.first().map_or(links[0].at, |j| j.at), "the joints form a cycle".into())),
        [_, second, ..] => {
            let (a, b) = (&links[roots[0]].name, &links[*second].name);
            Err(fail(
                links[*second].at,
                format!("links `{a}` and `{b}` both have no parent joint; expected one root link"),
            ))
        }
    }
}

/// Every link's pose at zero, and the links from the root outwards.
fn poses(links: &[Link], joints: &[Joint], root: usize, fail: &Fail) -> syn::Result<(Vec<Pose>, Vec<usize>)> {
    let mut pose: Vec<Option<(M3, V3)>> = vec![None; links.len()];
    pose[root] = Some((IDENTITY, [0.0; 3]));
    let mut order = vec![root];
    let mut i = 0;
    while let Some(&l) = order.get(i) {
        i += 1;
        for j in joints.iter().filter(|j| j.parent == l) {
            let (r, p) = pose[l].unwrap_or((IDENTITY, [0.0; 3]));
            let (ro, po) = j.origin;
            pose[j.child] = Some((mul(&r, &ro), add(&p, &apply(&r, &po))));
            order.push(j.child);
        }
    }
    let mut out = Vec::with_capacity(links.len());
    for (l, p) in pose.into_iter().enumerate() {
        out.push(p.ok_or_else(|| fail(links[l].at, format!("link `{}` is on a cycle of joints", links[l].name)))?);
    }
    Ok((out, order))
}

/// Mass, centre and inertia about it (world axes at zero) of welded links.
fn combine(members: &[usize], links: &[Link], pose: &[(M3, V3)]) -> (f64, V3, M3) {
    let parts: Vec<(f64, V3, M3)> = members
        .iter()
        .filter_map(|&l| {
            let (m, c, i) = links[l].inertial?;
            let (r, p) = pose[l];
            Some((m, add(&p, &apply(&r, &c)), mul(&mul(&r, &i), &transpose(&r))))
        })
        .collect();
    // `+ 0.0`: an empty sum is −0.
    let mass: f64 = parts.iter().map(|p| p.0).sum::<f64>() + 0.0;
    let mut centre = [0.0; 3];
    if mass > 0.0 {
        for (m, c, _) in &parts {
            centre = add(&centre, &c.map(|x| x * m / mass));
        }
    }
    let mut inertia = [[0.0; 3]; 3];
    for (m, c, i) in &parts {
        let d = sub(c, &centre);
        let dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
        for r in 0..3 {
            for k in 0..3 {
                let steiner = if r == k { dd } else { 0.0 } - d[r] * d[k];
                inertia[r][k] += i[r][k] + m * steiner;
            }
        }
    }
    (mass, centre, inertia)
}

/// The gravity compensation of welded links: one fraction for all with
/// mass (the body's force then acts at its centre), else an error at the
/// second link.
fn compensation(members: &[usize], links: &[Link], fail: &Fail) -> syn::Result<f64> {
    let massive = || members.iter().filter(|&&l| links[l].inertial.is_some_and(|(m, _, _)| m > 0.0));
    let Some(&first) = massive().next() else { return Ok(0.0) };
    match massive().find(|&&l| links[l].gravcomp != links[first].gravcomp) {
        None => Ok(links[first].gravcomp),
        Some(&other) => Err(fail(
            links[other].at,
            format!(
                "links `{}` and `{}` are welded into one body with different `gravcomp`s; expected one value for \
                 the links a body without joints joins",
                links[first].name, links[other].name
            ),
        )),
    }
}

/// A moving body needs a positive mass and the inertia of a real body:
/// positive definite, each principal moment at most the sum of the others.
fn check_inertia(head: &Link, mass: f64, i: &M3, fail: &Fail) -> syn::Result<()> {
    let name = &head.name;
    if mass.is_nan() || mass <= 0.0 || mass.is_infinite() {
        return Err(fail(
            head.inertial_at[0],
            format!("link `{name}` moves but has mass {mass}; expected a positive mass"),
        ));
    }
    let moments = eigenvalues(i);
    if !physical(&moments) {
        return Err(fail(
            head.inertial_at[1],
            format!(
                "link `{name}` moves with principal moments {moments:?}; expected a real body's inertia: positive, \
                 each at most the sum of the other two"
            ),
        ));
    }
    Ok(())
}

/// Where attribute `key` of `node` is written, if it is.
pub fn attribute_at(node: roxmltree::Node, key: &str) -> Option<roxmltree::TextPos> {
    node.attribute_node(key).map(|a| node.document().text_pos_at(a.range().start))
}

/// An attribute of `N` numbers, if present (a bad value reported at the
/// attribute; `at`, the element's place, is for what is missing).
pub fn numbers<const N: usize>(
    node: roxmltree::Node,
    key: &str,
    at: roxmltree::TextPos,
    fail: &Fail,
) -> syn::Result<Option<[f64; N]>> {
    let Some(text) = node.attribute(key) else { return Ok(None) };
    parse_numbers(key, text, attribute_at(node, key).unwrap_or(at), fail).map(Some)
}

/// `text`, the value of attribute `key` written at `at`, as `N` finite
/// numbers; the error says how many and gives an example.
pub fn parse_numbers<const N: usize>(
    key: &str,
    text: &str,
    at: roxmltree::TextPos,
    fail: &Fail,
) -> syn::Result<[f64; N]> {
    let parsed: Vec<f64> = text.split_whitespace().map_while(|t| t.parse().ok()).collect();
    match <[f64; N]>::try_from(parsed.as_slice()) {
        Ok(v) if text.split_whitespace().count() == N && v.iter().all(|x| x.is_finite()) => Ok(v),
        _ => {
            let example = ["0", "0", "1", "0", "0", "0", "1"][..N.min(7)].join(" ");
            let what = match N {
                1 => "a number".to_string(),
                n => format!("{} numbers", ["two", "three", "four", "five", "six", "seven"].get(n - 2).unwrap_or(&"")),
            };
            Err(fail(at, format!("`{key}=\"{text}\"`: expected {what}, as in `{key}=\"{example}\"`")))
        }
    }
}

/// An attribute of three numbers, if present.
pub fn triple(node: roxmltree::Node, key: &str, at: roxmltree::TextPos, fail: &Fail) -> syn::Result<Option<V3>> {
    numbers::<3>(node, key, at, fail)
}

/// An attribute holding one number.
pub fn number(node: roxmltree::Node, key: &str, at: roxmltree::TextPos, fail: &Fail) -> syn::Result<f64> {
    let text = node.attribute(key).ok_or_else(|| {
        fail(at, format!("`<{}>` has no `{key}`; expected `{key}=\"NUMBER\"`", node.tag_name().name()))
    })?;
    match text.trim().parse::<f64>() {
        Ok(x) if x.is_finite() => Ok(x),
        _ => Err(fail(attribute_at(node, key).unwrap_or(at), format!("`{key}=\"{text}\"`: expected a number"))),
    }
}

/// A required text attribute.
pub fn required(node: roxmltree::Node, key: &str, at: roxmltree::TextPos, fail: &Fail) -> syn::Result<String> {
    node.attribute(key)
        .map(str::to_string)
        .ok_or_else(|| fail(at, format!("`<{}>` has no `{key}`; expected `{key}=\"..\"`", node.tag_name().name())))
}

pub const IDENTITY: M3 = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

pub fn mul(a: &M3, b: &M3) -> M3 {
    std::array::from_fn(|r| std::array::from_fn(|c| (0..3).map(|k| a[r][k] * b[k][c]).sum()))
}

pub fn transpose(a: &M3) -> M3 {
    std::array::from_fn(|r| std::array::from_fn(|c| a[c][r]))
}

pub fn apply(a: &M3, v: &V3) -> V3 {
    std::array::from_fn(|r| (0..3).map(|k| a[r][k] * v[k]).sum())
}

pub fn add(a: &V3, b: &V3) -> V3 {
    std::array::from_fn(|i| a[i] + b[i])
}

pub fn sub(a: &V3, b: &V3) -> V3 {
    std::array::from_fn(|i| a[i] - b[i])
}

pub fn norm(v: &V3) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

#[cfg(test)]
pub mod tests {
    use super::*;

    /// A file of the workspace's `tests/data`.
    pub fn test_file(path: &str) -> String {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/data");
        std::fs::read_to_string(dir.join(path)).unwrap()
    }

    /// `n` copies of `text`, each cut (a middle part left out) and with up
    /// to three bytes changed to XML's and numbers' characters: for readers
    /// that must give an error or a robot, never a panic.
    pub fn cut_and_mutated(text: &str, n: usize) -> Vec<String> {
        let mut seed = 2026_u64;
        let mut next = |n: usize| {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((seed >> 33) as usize) % n.max(1)
        };
        let bytes = text.as_bytes();
        (0..n)
            .map(|_| {
                let mut mutated = bytes[..next(bytes.len())].to_vec();
                mutated.extend_from_slice(&bytes[next(bytes.len())..]);
                for _ in 0..next(4) {
                    let at = next(mutated.len());
                    if let Some(b) = mutated.get_mut(at) {
                        *b = b"<>/\"= 0-.e9xyz"[next(14)];
                    }
                }
                String::from_utf8_lossy(&mutated).into_owned()
            })
            .collect()
    }

    #[test]
    fn names_become_identifiers() {
        let cases = [
            ("shoulder_pan_joint", "shoulder_pan_joint"),
            ("FL-HAA", "FL_HAA"),
            ("7dof", "_7dof"),
            ("type", "_type"),
            ("ground", "_ground"),
            ("", "_3"),
            ("_", "__"),
            ("ü", "__"),
            ("a b", "a_b"),
        ];
        for (name, rust) in cases {
            assert_eq!(rust_name(name, 3), rust, "{name:?}");
            assert!(syn::parse_str::<syn::Ident>(rust).is_ok());
        }
    }
}
