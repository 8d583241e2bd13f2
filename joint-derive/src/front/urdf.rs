//! `#[scene(urdf = "robot.urdf")]`: a robot's links and joints read from its
//! URDF file at compile time and put in the scene's terms, as if written as
//! `#[body]` and `#[joint]` attributes.
//!
//! Frames: every body's frame has its origin at the body's centre of mass
//! and its axes parallel to the world's at the file's zero configuration
//! (every joint value zero). Each joint's axis is then one vector on both of
//! its bodies, its rest rotation the identity, and its coordinate the
//! file's: an angle positive about the axis (a slide along it), zero where
//! the file's is. Links joined by `fixed` joints are one body (masses,
//! centres and inertias combined: the scene models only what moves); the
//! root link and the links fixed to it are the ground. A `floating` joint
//! is left out, so its child floats (the derive gives it a free joint).
//! Visuals, collisions, transmissions and Gazebo tags are not read; a
//! `<mimic>` joint is read as an independent joint, as Pinocchio's and
//! MuJoCo's readers do by default (its coupling as a driver row is not
//! derived yet).

use std::collections::HashMap;

use super::geometry::{eigenvalues, physical};

pub use super::scene::{FileLimits, FileLink};

/// A robot in the scene's terms.
pub struct Robot {
    /// The moving bodies, in the order of their first links in the file.
    pub bodies: Vec<RobotBody>,
    /// The moving joints, in the file's order.
    pub joints: Vec<RobotJoint>,
    /// Every link's frame on its body, in the file's order.
    pub links: Vec<FileLink>,
    /// The file, absolute: the derive includes it so that cargo rebuilds
    /// when it changes.
    pub path: String,
}

/// One body: the links a chain of `fixed` joints welds together.
pub struct RobotBody {
    /// The first link's name.
    pub name: String,
    /// Mass.
    pub mass: f64,
    /// Inertia about the centre of mass, world axes at the zero
    /// configuration: `[ixx, iyy, izz, ixy, ixz, iyz]` (tensor entries).
    pub inertia: [f64; 6],
}

/// One joint between two bodies (`None`: the ground).
pub struct RobotJoint {
    /// The file's name.
    pub name: String,
    /// The catalogue's kind: `revolute` or `translational`.
    pub kind: &'static str,
    /// The parent body.
    pub parent: Option<usize>,
    /// The child body.
    pub child: usize,
    /// The unit axis, both bodies' (and the world's) components at zero.
    pub axis: [f64; 3],
    /// The joint point from the parent's centre of mass (the world's origin
    /// for the ground).
    pub rho1: [f64; 3],
    /// The joint point from the child's centre of mass.
    pub rho2: [f64; 3],
    /// Its limits and friction.
    pub limits: FileLimits,
}

type V3 = [f64; 3];
type M3 = [[f64; 3]; 3];

/// A link as the file gives it.
struct Link {
    name: String,
    /// Mass, centre and inertia in the link's frame (inertia's own frame
    /// turned into the link's axes); `None` without `<inertial>`.
    inertial: Option<(f64, V3, M3)>,
    at: roxmltree::TextPos,
}

/// A joint as the file gives it.
struct Joint {
    name: String,
    kind: String,
    parent: usize,
    child: usize,
    origin: (M3, V3),
    axis: V3,
    limits: FileLimits,
    at: roxmltree::TextPos,
}

/// Reads `path` (relative to the crate's `CARGO_MANIFEST_DIR`); every
/// error at the attribute, naming the file, line and column. With
/// `floating`, the root link (and the links fixed to it) is a body that
/// floats, not the ground.
pub fn read(path: &syn::LitStr, floating: bool) -> syn::Result<Robot> {
    let dir = std::env::var("CARGO_MANIFEST_DIR").unwrap_or_default();
    let full = std::path::Path::new(&dir).join(path.value());
    let shown = full.display().to_string();
    let text = std::fs::read_to_string(&full).map_err(|e| {
        syn::Error::new(
            path.span(),
            format!("cannot read `{shown}`: {e}; expected a URDF file's path relative to the crate's directory"),
        )
    })?;
    let robot = from_text(&text, &shown, path.span(), floating)?;
    Ok(Robot { path: shown, ..robot })
}

/// The robot of a file's `text` (`shown` names it in errors, at `span`).
fn from_text(text: &str, shown: &str, span: proc_macro2::Span, floating: bool) -> syn::Result<Robot> {
    let fail = |at: roxmltree::TextPos, message: String| {
        syn::Error::new(span, format!("{shown}:{}:{}: {message}", at.row, at.col))
    };
    let doc = roxmltree::Document::parse(text).map_err(|e| fail(e.pos(), format!("malformed XML: {e}")))?;
    let (links, joints) = elements(&doc, &fail)?;
    if links.is_empty() {
        let at = doc.text_pos_at(doc.root_element().range().start);
        return Err(fail(at, "the robot has no `<link>`; expected its links and joints".into()));
    }
    assemble(&links, &joints, floating, &fail)
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

type Fail<'f> = dyn Fn(roxmltree::TextPos, String) -> syn::Error + 'f;

/// The `<link>` and `<joint>` elements, checked one by one.
fn elements(doc: &roxmltree::Document, fail: &Fail) -> syn::Result<(Vec<Link>, Vec<Joint>)> {
    let robot = doc.root_element();
    let pos = |n: roxmltree::Node| doc.text_pos_at(n.range().start);
    if robot.tag_name().name() != "robot" {
        return Err(fail(pos(robot), format!("expected a `<robot>` element, found `<{}>`", robot.tag_name().name())));
    }
    let mut links: Vec<Link> = Vec::new();
    for node in robot.children().filter(|n| n.has_tag_name("link")) {
        let name = required(node, "name", pos(node), fail)?;
        if links.iter().any(|l| l.name == name) {
            return Err(fail(pos(node), format!("link `{name}` is declared twice; expected unique link names")));
        }
        let inertial = match node.children().find(|n| n.has_tag_name("inertial")) {
            Some(i) => Some(inertial(i, &name, &pos, fail)?),
            None => None,
        };
        links.push(Link { name, inertial, at: pos(node) });
    }
    let index = |name: &str, at, what: &str| {
        links.iter().position(|l| l.name == name).ok_or_else(|| {
            fail(at, format!("joint's {what} link `{name}` is not a `<link>` of the file; expected one of its links"))
        })
    };
    let mut joints: Vec<Joint> = Vec::new();
    for node in robot.children().filter(|n| n.has_tag_name("joint")) {
        let at = pos(node);
        let name = required(node, "name", at, fail)?;
        if joints.iter().any(|j| j.name == name) {
            return Err(fail(at, format!("joint `{name}` is declared twice; expected unique joint names")));
        }
        let kind = required(node, "type", at, fail)?;
        if !matches!(kind.as_str(), "revolute" | "continuous" | "prismatic" | "fixed" | "floating") {
            return Err(fail(
                at,
                format!(
                    "joint `{name}` has type `{kind}`; expected `revolute`, `continuous`, `prismatic`, `fixed` or \
                     `floating` (`planar` is not read yet)"
                ),
            ));
        }
        let link_of = |tag: &str| -> syn::Result<usize> {
            let n = node.children().find(|n| n.has_tag_name(tag));
            let n = n.ok_or_else(|| fail(at, format!("joint `{name}` has no `<{tag} link=\"..\"/>`")))?;
            index(&required(n, "link", pos(n), fail)?, pos(n), tag)
        };
        let (parent, child) = (link_of("parent")?, link_of("child")?);
        let origin = match node.children().find(|n| n.has_tag_name("origin")) {
            Some(o) => origin(o, pos(o), fail)?,
            None => (IDENTITY, [0.0; 3]),
        };
        let axis = match node.children().find(|n| n.has_tag_name("axis")) {
            Some(a) => triple(a, "xyz", pos(a), fail)?.unwrap_or([1.0, 0.0, 0.0]),
            None => [1.0, 0.0, 0.0],
        };
        let limits = limits(node, &pos, fail)?;
        joints.push(Joint { name, kind, parent, child, origin, axis, limits, at });
    }
    Ok((links, joints))
}

/// `<limit>` and `<dynamics>`: each number where given.
fn limits(
    node: roxmltree::Node,
    pos: &dyn Fn(roxmltree::Node) -> roxmltree::TextPos,
    fail: &Fail,
) -> syn::Result<FileLimits> {
    let optional = |tag: &str, key: &str| -> syn::Result<Option<f64>> {
        match node.children().find(|n| n.has_tag_name(tag)) {
            Some(n) if n.attribute(key).is_some() => number(n, key, pos(n), fail).map(Some),
            _ => Ok(None),
        }
    };
    let range = match (optional("limit", "lower")?, optional("limit", "upper")?) {
        (Some(lower), Some(upper)) => Some((lower, upper)),
        _ => None,
    };
    Ok(FileLimits {
        range,
        effort: optional("limit", "effort")?,
        velocity: optional("limit", "velocity")?,
        damping: optional("dynamics", "damping")?,
        friction: optional("dynamics", "friction")?,
    })
}

/// `<inertial>`: mass, centre and inertia in the link's frame.
fn inertial(
    node: roxmltree::Node,
    link: &str,
    pos: &dyn Fn(roxmltree::Node) -> roxmltree::TextPos,
    fail: &Fail,
) -> syn::Result<(f64, V3, M3)> {
    let (turn, centre) = match node.children().find(|n| n.has_tag_name("origin")) {
        Some(o) => origin(o, pos(o), fail)?,
        None => (IDENTITY, [0.0; 3]),
    };
    let mass_node = node.children().find(|n| n.has_tag_name("mass"));
    let mass_node =
        mass_node.ok_or_else(|| fail(pos(node), format!("link `{link}`'s `<inertial>` has no `<mass>`")))?;
    let mass = number(mass_node, "value", pos(mass_node), fail)?;
    let i = node.children().find(|n| n.has_tag_name("inertia"));
    let i = i.ok_or_else(|| fail(pos(node), format!("link `{link}`'s `<inertial>` has no `<inertia>`")))?;
    let e = |k: &str| number(i, k, pos(i), fail);
    let (xx, xy, xz, yy, yz, zz) = (e("ixx")?, e("ixy")?, e("ixz")?, e("iyy")?, e("iyz")?, e("izz")?);
    let tensor = [[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]];
    Ok((mass, centre, mul(&mul(&turn, &tensor), &transpose(&turn))))
}

/// The bodies (links welded by fixed joints) and the moving joints.
fn assemble(links: &[Link], joints: &[Joint], floating: bool, fail: &Fail) -> syn::Result<Robot> {
    // Each link's joint from its parent: one at most (a URDF is a tree).
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
    let root = match roots.as_slice() {
        [root] => *root,
        [] => return Err(fail(joints.first().map_or(links[0].at, |j| j.at), "the joints form a cycle".into())),
        [_, second, ..] => {
            let (a, b) = (&links[roots[0]].name, &links[*second].name);
            return Err(fail(
                links[*second].at,
                format!("links `{a}` and `{b}` both have no parent joint; expected one root link"),
            ));
        }
    };
    // Poses at zero, root first: the child's frame is the joint's.
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
    if let Some(l) = (0..links.len()).find(|&l| pose[l].is_none()) {
        return Err(fail(links[l].at, format!("link `{}` is on a cycle of joints", links[l].name)));
    }
    // Bodies: each moving joint's child starts one; a fixed joint's child
    // joins its parent's (the root's: the ground, or a floating base).
    let mut body_of: Vec<Option<usize>> = vec![None; links.len()];
    let mut heads: Vec<usize> = Vec::new();
    if floating {
        heads.push(root);
        body_of[root] = Some(0);
    }
    for &l in &order[1..] {
        let j = &joints[inbound[l].unwrap_or(0)];
        body_of[l] = if j.kind == "fixed" {
            body_of[j.parent]
        } else {
            heads.push(l);
            Some(heads.len() - 1)
        };
    }
    // The file's link order for the bodies.
    let mut by_file: Vec<usize> = (0..heads.len()).collect();
    by_file.sort_by_key(|&b| heads[b]);
    let renumber: HashMap<usize, usize> = by_file.iter().enumerate().map(|(new, &old)| (old, new)).collect();
    let body_of: Vec<Option<usize>> = body_of.iter().map(|b| b.map(|b| renumber[&b])).collect();
    let heads: Vec<usize> = by_file.iter().map(|&b| heads[b]).collect();
    let mut centres = Vec::new();
    let mut bodies = Vec::new();
    for (b, &head) in heads.iter().enumerate() {
        let members: Vec<usize> = (0..links.len()).filter(|&l| body_of[l] == Some(b)).collect();
        let (mass, centre, inertia) = combine(&members, links, &pose);
        check_inertia(&links[head], mass, &inertia, fail)?;
        centres.push(centre);
        bodies.push(RobotBody {
            name: links[head].name.clone(),
            mass,
            inertia: [inertia[0][0], inertia[1][1], inertia[2][2], inertia[0][1], inertia[0][2], inertia[1][2]],
        });
    }
    let mut out = Vec::new();
    for j in joints.iter().filter(|j| j.kind != "fixed" && j.kind != "floating") {
        let (r, o) = pose[j.child].unwrap_or((IDENTITY, [0.0; 3]));
        let length = norm(&j.axis);
        if length.is_nan() || length <= 1e-12 {
            return Err(fail(j.at, format!("joint `{}` has a zero axis; expected `<axis xyz=\"0 0 1\"/>`", j.name)));
        }
        let axis = apply(&r, &j.axis.map(|x| x / length));
        let (parent, child) = (body_of[j.parent], body_of[j.child].unwrap_or(0));
        let from = |b: Option<usize>| b.map_or([0.0; 3], |b| centres[b]);
        let (rho1, rho2) = (sub(&o, &from(parent)), sub(&o, &centres[child]));
        if !rho1.iter().chain(&rho2).all(|x| x.is_finite()) {
            return Err(fail(j.at, format!("joint `{}` is at a point out of range", j.name)));
        }
        out.push(RobotJoint {
            name: j.name.clone(),
            kind: if j.kind == "prismatic" { "translational" } else { "revolute" },
            parent,
            child,
            axis,
            rho1,
            rho2,
            limits: j.limits,
        });
    }
    // Every link's frame: the body's axes are the world's at zero.
    let frames = (0..links.len())
        .map(|l| {
            let (r, p) = pose[l].unwrap_or((IDENTITY, [0.0; 3]));
            let body = body_of[l];
            let origin = body.map_or(p, |b| sub(&p, &centres[b]));
            FileLink { name: links[l].name.clone(), body, rotation: r, origin }
        })
        .collect();
    Ok(Robot { bodies, joints: out, links: frames, path: String::new() })
}

/// Mass, centre and inertia about it (world axes at zero) of welded links.
fn combine(members: &[usize], links: &[Link], pose: &[Option<(M3, V3)>]) -> (f64, V3, M3) {
    let parts: Vec<(f64, V3, M3)> = members
        .iter()
        .filter_map(|&l| {
            let (m, c, i) = links[l].inertial?;
            let (r, p) = pose[l]?;
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

/// A moving body needs a positive mass and the inertia of a real body:
/// positive definite, each principal moment at most the sum of the others.
fn check_inertia(head: &Link, mass: f64, i: &M3, fail: &Fail) -> syn::Result<()> {
    let name = &head.name;
    if mass.is_nan() || mass <= 0.0 || mass.is_infinite() {
        return Err(fail(head.at, format!("link `{name}` moves but has mass {mass}; expected a positive `<mass>`")));
    }
    let moments = eigenvalues(i);
    if !physical(&moments) {
        return Err(fail(
            head.at,
            format!(
                "link `{name}` moves with principal moments {moments:?}; expected a real body's inertia: positive, \
                 each at most the sum of the other two"
            ),
        ));
    }
    Ok(())
}

/// `<origin xyz=".." rpy=".."/>`: the rotation `Rz(y) Ry(p) Rx(r)` and the offset.
fn origin(node: roxmltree::Node, at: roxmltree::TextPos, fail: &Fail) -> syn::Result<(M3, V3)> {
    let xyz = triple(node, "xyz", at, fail)?.unwrap_or([0.0; 3]);
    let [r, p, y] = triple(node, "rpy", at, fail)?.unwrap_or([0.0; 3]);
    let (sr, cr, sp, cp, sy, cy) = (r.sin(), r.cos(), p.sin(), p.cos(), y.sin(), y.cos());
    let turn = [
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ];
    Ok((turn, xyz))
}

/// An attribute of three numbers, if present.
fn triple(node: roxmltree::Node, key: &str, at: roxmltree::TextPos, fail: &Fail) -> syn::Result<Option<V3>> {
    let Some(text) = node.attribute(key) else { return Ok(None) };
    let numbers: Vec<f64> = text.split_whitespace().filter_map(|t| t.parse().ok()).collect();
    match numbers.as_slice() {
        [x, y, z] if text.split_whitespace().count() == 3 && [x, y, z].iter().all(|v| v.is_finite()) => {
            Ok(Some([*x, *y, *z]))
        }
        _ => Err(fail(at, format!("`{key}=\"{text}\"`: expected three numbers, as in `{key}=\"0 0 1\"`"))),
    }
}

/// An attribute holding one number.
fn number(node: roxmltree::Node, key: &str, at: roxmltree::TextPos, fail: &Fail) -> syn::Result<f64> {
    let text = node.attribute(key).ok_or_else(|| {
        fail(at, format!("`<{}>` has no `{key}`; expected `{key}=\"NUMBER\"`", node.tag_name().name()))
    })?;
    match text.trim().parse::<f64>() {
        Ok(x) if x.is_finite() => Ok(x),
        _ => Err(fail(at, format!("`{key}=\"{text}\"`: expected a number"))),
    }
}

/// A required text attribute.
fn required(node: roxmltree::Node, key: &str, at: roxmltree::TextPos, fail: &Fail) -> syn::Result<String> {
    node.attribute(key)
        .map(str::to_string)
        .ok_or_else(|| fail(at, format!("`<{}>` has no `{key}`; expected `{key}=\"..\"`", node.tag_name().name())))
}

const IDENTITY: M3 = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

fn mul(a: &M3, b: &M3) -> M3 {
    std::array::from_fn(|r| std::array::from_fn(|c| (0..3).map(|k| a[r][k] * b[k][c]).sum()))
}

fn transpose(a: &M3) -> M3 {
    std::array::from_fn(|r| std::array::from_fn(|c| a[c][r]))
}

fn apply(a: &M3, v: &V3) -> V3 {
    std::array::from_fn(|r| (0..3).map(|k| a[r][k] * v[k]).sum())
}

fn add(a: &V3, b: &V3) -> V3 {
    std::array::from_fn(|i| a[i] + b[i])
}

fn sub(a: &V3, b: &V3) -> V3 {
    std::array::from_fn(|i| a[i] - b[i])
}

fn norm(v: &V3) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eigenvalues_of_a_turned_box() {
        let (turn, _) = origin_of("0.3 -0.7 1.1");
        let d = [[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 2.5]];
        let e = eigenvalues(&mul(&mul(&turn, &d), &transpose(&turn)));
        for (x, y) in e.iter().zip([1.0, 2.0, 2.5]) {
            assert!((x - y).abs() < 1e-14, "{e:?}");
        }
    }

    #[test]
    fn rpy_is_z_then_y_then_x() {
        // A quarter turn in yaw takes x to y; a quarter turn in roll takes y to z.
        let (yaw, _) = origin_of("0 0 1.5707963267948966");
        let x = apply(&yaw, &[1.0, 0.0, 0.0]);
        assert!((x[1] - 1.0).abs() < 1e-15 && x[0].abs() < 1e-15);
        let (roll, _) = origin_of("1.5707963267948966 0 0");
        let y = apply(&roll, &[0.0, 1.0, 0.0]);
        assert!((y[2] - 1.0).abs() < 1e-15);
    }

    /// The error of reading `text` as a file, its position and message.
    fn error(text: &str) -> String {
        use std::sync::atomic::{AtomicUsize, Ordering};
        static N: AtomicUsize = AtomicUsize::new(0);
        let n = N.fetch_add(1, Ordering::Relaxed);
        let path = std::env::temp_dir().join(format!("joint-derive-urdf-{}-{n}.urdf", std::process::id()));
        std::fs::write(&path, text).unwrap();
        let lit = syn::LitStr::new(&path.display().to_string(), proc_macro2::Span::call_site());
        let message = read(&lit, false).err().map(|e| e.to_string()).unwrap_or_default();
        std::fs::remove_file(&path).ok();
        message.split_once(".urdf:").map_or(message.clone(), |(_, rest)| rest.to_string())
    }

    const MASS: &str =
        r#"<inertial><mass value="1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial>"#;

    fn two_links(joint: &str, second: &str) -> String {
        format!("<robot name=\"r\">\n<link name=\"base\"/>\n<link name=\"arm\">{second}</link>\n{joint}\n</robot>")
    }

    fn hinge(kind: &str) -> String {
        format!(r#"<joint name="j" type="{kind}"><parent link="base"/><child link="arm"/></joint>"#)
    }

    #[test]
    fn bad_files_one_message_each_at_line_and_column() {
        let cases = [
            ("<robot><link name=\"a\"></robot>", "1:", "malformed XML"),
            ("<robbot/>", "1:1:", "expected a `<robot>` element"),
            (&two_links(&hinge("spherical"), MASS), "4:1:", "has type `spherical`; expected `revolute`"),
            (&two_links(&hinge("revolute"), ""), "3:1:", "link `arm` moves but has mass 0"),
            (
                &two_links(&hinge("revolute"), &MASS.replace(r#"izz="1""#, r#"izz="100""#)),
                "3:1:",
                "principal moments [1.0, 1.0, 100.0]; expected a real body's inertia",
            ),
            (
                &two_links(&hinge("revolute"), &MASS.replace(r#"ixy="0""#, r#"ixy="2""#)),
                "3:1:",
                "expected a real body's inertia",
            ),
            (&two_links(&hinge("revolute").replace("arm", "hand"), MASS), "4:", "child link `hand` is not a `<link>`"),
            (&two_links(&format!("{}\n{}", hinge("revolute"), hinge("fixed")), MASS), "5:1:", "declared twice"),
            (
                &two_links(&format!("{}\n{}", hinge("revolute"), hinge("fixed").replace(r#""j""#, r#""k""#)), MASS),
                "5:1:",
                "link `arm` is the child of joints `j` and `k`",
            ),
            ("<robot><link name=\"a\"/><link name=\"a\"/></robot>", "1:", "link `a` is declared twice"),
            (
                &two_links(&hinge("revolute").replace("<child", "<axis xyz=\"0 0 0\"/><child"), MASS),
                "4:1:",
                "zero axis",
            ),
            (
                &two_links(&hinge("revolute").replace("<child", "<axis xyz=\"0 1\"/><child"), MASS),
                "4:",
                "expected three numbers",
            ),
        ];
        for (text, at, expected) in cases {
            let message = error(text);
            assert!(message.starts_with(at) && message.contains(expected), "{text}\n{message}");
        }
        let missing = read(&syn::LitStr::new("/no/such/robot.urdf", proc_macro2::Span::call_site()), false);
        assert!(missing.err().is_some_and(|e| e.to_string().starts_with("cannot read `/no/such/robot.urdf`")));
    }

    /// The robots of the tests, cut short and with bytes changed: an error
    /// or a robot, never a panic.
    #[test]
    fn cut_and_mutated_files_never_panic() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/data/robots");
        let mut seed = 2026_u64;
        let mut next = |n: usize| {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((seed >> 33) as usize) % n.max(1)
        };
        let span = proc_macro2::Span::call_site();
        for robot in ["double_pendulum", "ur5", "panda", "solo12"] {
            let text = std::fs::read_to_string(dir.join(format!("{robot}.urdf"))).unwrap();
            assert!(from_text(&text, robot, span, false).is_ok() && from_text(&text, robot, span, true).is_ok());
            let bytes = text.as_bytes();
            for _ in 0..300 {
                let mut mutated = bytes[..next(bytes.len())].to_vec();
                mutated.extend_from_slice(&bytes[next(bytes.len())..]);
                for _ in 0..next(4) {
                    let at = next(mutated.len());
                    if let Some(b) = mutated.get_mut(at) {
                        *b = b"<>/\"= 0-.e9xyz"[next(14)];
                    }
                }
                let _ = from_text(&String::from_utf8_lossy(&mutated), robot, span, next(2) == 0);
            }
        }
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

    #[test]
    fn welded_links_are_one_body() {
        // A 2 kg link with a 1 kg tool welded 0.3 m along its x: one body of
        // 3 kg whose centre is 0.1 m along x, inertia shifted by Steiner.
        let text = format!(
            r#"<robot name="r"><link name="base"/><link name="arm">{MASS}</link>
            <link name="tool"><inertial><origin xyz="0 0 0"/><mass value="1"/>
            <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>
            <joint name="j" type="revolute"><parent link="base"/><child link="arm"/><axis xyz="0 0 1"/></joint>
            <joint name="w" type="fixed"><origin xyz="0.3 0 0"/><parent link="arm"/><child link="tool"/></joint>
            </robot>"#
        )
        .replace(r#"<mass value="1"/><inertia ixx="1""#, r#"<mass value="2"/><inertia ixx="1""#);
        let doc = roxmltree::Document::parse(&text).unwrap();
        let fail = |_: roxmltree::TextPos, m: String| syn::Error::new(proc_macro2::Span::call_site(), m);
        let (links, joints) = elements(&doc, &fail).unwrap();
        let robot = assemble(&links, &joints, false, &fail).unwrap();
        assert_eq!(robot.bodies.len(), 1);
        let b = &robot.bodies[0];
        assert!((b.mass - 3.0).abs() < 1e-15);
        // About the centre: 1 + 2·0.1² and the tool's 1·0.2², about y and z.
        let (yy, zz) = (1.0 + 2.0 * 0.01 + 0.04, 1.0 + 2.0 * 0.01 + 0.04);
        assert!(
            (b.inertia[0] - 1.0).abs() < 1e-15
                && (b.inertia[1] - yy).abs() < 1e-14
                && (b.inertia[2] - zz).abs() < 1e-14
        );
        let j = &robot.joints[0];
        assert_eq!((j.kind, j.parent, j.child, j.axis), ("revolute", None, 0, [0.0, 0.0, 1.0]));
        assert!((j.rho2[0] + 0.1).abs() < 1e-15 && j.rho1 == [0.0; 3]);
    }

    fn origin_of(rpy: &str) -> (M3, V3) {
        let text = format!("<origin rpy=\"{rpy}\"/>");
        let doc = roxmltree::Document::parse(&text).unwrap();
        let fail = |_: roxmltree::TextPos, m: String| syn::Error::new(proc_macro2::Span::call_site(), m);
        origin(doc.root_element(), roxmltree::TextPos::new(1, 1), &fail).unwrap()
    }
}
