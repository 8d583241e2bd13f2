//! `#[scene(mjcf = "robot.xml")]`: a robot's bodies and joints read from
//! MuJoCo's MJCF file at compile time and put in the scene's terms by
//! [`assemble`] (frames at the centres, world axes at the zero
//! configuration, bodies without joints welded to their parents).
//!
//! Read: `<compiler angle eulerseq inertiafromgeom>`, `<option gravity>`,
//! `<default>` classes for joints, nested `<body>` and `<frame>` with any of
//! MuJoCo's orientations (`quat`, `axisangle`, `euler`, `xyaxes`, `zaxis`),
//! `<inertial>` (`diaginertia` turned by its orientation, or
//! `fullinertia`), one joint per body (`hinge`, `slide`, `ball`, or `free`
//! and `<freejoint>` on a body of the world), `<site>` as frames, and
//! `<equality>`'s `connect` (a ball joint) and `weld` (a fixed joint) as
//! joints that close loops, at the file's reference configuration. A
//! joint's range, damping, `frictionloss`, `armature` and
//! `actuatorfrcrange` are data ([`FileLimits`]); a hinge's or slide's
//! `stiffness`, `springref` and `ref` are its spring and the coordinate's
//! offset (the tree's zero at the file's pose, MuJoCo's `ref`);
//! `<compiler settotalmass>` scales every body's mass and inertia; a body's
//! `gravcomp` holds that fraction of its weight up;
//! `<flag gravity="disable">` switches gravity off. Refused, each by name at
//! the attribute: what would change the dynamics without being modelled
//! ([`UNMODELLED`]: compensation through actuators, spring-dampers, fluid forces, the
//! compiler's mass bounds, switched-off passive forces or constraints; an
//! equality's softness; a ball or free joint's spring, inertia computed
//! from geoms, several joints in one body, a damped free joint,
//! `<include>`, composites, mocap bodies).
//! Geoms (their classes' `<default><geom>` too) and `<asset>` meshes and
//! materials are read for pictures only ([`super::visuals`]): geoms of
//! `group` 3 and above, which MuJoCo's viewer hides, are left out.
//! Actuators, sensors and contacts are not read.

use std::collections::HashMap;

use super::robot::{
    Class, Closure, Fail, FileCoupling, FileLimits, FileOptions, FileSpring, IDENTITY, Joint, Kind, Library, Link, M3,
    Robot, Soft, V3, add, apply, assemble, attribute_at, mul, norm, number, numbers, parse_numbers, read_text,
    required, transpose, triple,
};
use super::visuals::{FileVisual, Looks, mjcf_shape, z_turn};

/// Reads `path` (relative to the crate's `CARGO_MANIFEST_DIR`); every
/// error at the attribute, naming the file, line and column.
///
/// `equalities`: the scene's `equality = hard` and `mimic = independent`
/// (see [`Reader::equalities`]).
pub fn read(path: &syn::LitStr, equalities: (bool, bool)) -> syn::Result<Robot> {
    let (text, full) = read_text(path, "an MJCF")?;
    let mut robot = from_text(&text, &super::robot::shown(&full), path.span(), equalities)?;
    super::visuals::find_meshes(robot.links.iter_mut().flat_map(|l| &mut l.visuals), &full);
    Ok(Robot { path: full, ..robot })
}

/// The robot of a file's `text` (`shown` names it in errors, at `span`).
fn from_text(text: &str, shown: &str, span: proc_macro2::Span, equalities: (bool, bool)) -> syn::Result<Robot> {
    let fail = |at: roxmltree::TextPos, message: String| {
        syn::Error::new(span, format!("{shown}:{}:{}: {message}", at.row, at.col))
    };
    let doc = super::robot::parse_xml(text, &fail)?;
    let mut reader = Reader::new(&doc, &fail)?;
    let root = doc.root_element();
    let world = root.children().find(|n| n.has_tag_name("worldbody"));
    let world = world.ok_or_else(|| {
        fail(reader.pos(root), "the file has no `<worldbody>`; expected the robot's bodies in it".into())
    })?;
    reader.links.push(Link {
        name: "world".into(),
        inertial: None,
        unknown: false,
        gravcomp: 0.0,
        visuals: Vec::new(),
        at: reader.pos(world),
        inertial_at: [reader.pos(world); 2],
    });
    reader.children(world, 0, "main", (IDENTITY, [0.0; 3]))?;
    if reader.links.len() == 1 {
        return Err(fail(reader.pos(world), "the `<worldbody>` has no `<body>`; expected the robot's bodies".into()));
    }
    total_mass(root, &mut reader.links, &fail)?;
    let option = root.children().find(|n| n.has_tag_name("option"));
    let gravity = match option {
        Some(o) => triple(o, "gravity", reader.pos(o), &fail)?,
        None => None,
    };
    // `<flag gravity="disable"/>`: MuJoCo's model without gravity.
    let flags = option.into_iter().flat_map(|o| o.children()).filter(|n| n.has_tag_name("flag"));
    let off = flags.clone().any(|f| f.attribute("gravity") == Some("disable"));
    let gravity = if off { [0.0; 3] } else { gravity.unwrap_or([0.0, 0.0, -9.81]) };
    let mut options = match option {
        Some(o) => step_options(o, reader.pos(o), &fail)?,
        None => FileOptions::default(),
    };
    // What MuJoCo steps with where the file says nothing.
    let timestep = *options.timestep.get_or_insert(0.002);
    options.integrator.get_or_insert_with(|| "Euler".to_string());
    // MuJoCo raises a soft row's time constant to twice the step unless
    // `<flag refsafe="disable">`.
    let refsafe = !flags.clone().any(|f| f.attribute("refsafe") == Some("disable"));
    let (closures, couplings) = reader.equalities(root, equalities, refsafe.then_some(timestep))?;
    let robot = assemble(&reader.links, &reader.joints, &closures, (false, Library::MuJoCo), &fail)?;
    Ok(Robot { gravity: Some(gravity), couplings, options, ..robot })
}

/// What `<compiler>` says that changes numbers.
struct Compiler {
    /// `angle="degree"` (MuJoCo's default): angles in the file are degrees.
    degrees: bool,
    /// `eulerseq`: the axes of `euler`, lower case about the turned axes.
    eulerseq: [u8; 3],
}

/// The file walked, bodies and sites as links, their joints as joints.
struct Reader<'a, 'i> {
    doc: &'a roxmltree::Document<'i>,
    fail: &'a Fail<'a>,
    compiler: Compiler,
    /// Each `<default>` class's joint attributes, its parents' included.
    defaults: HashMap<String, Class>,
    /// The same for equalities (`solref`, `solimp`).
    equality_defaults: HashMap<String, Class>,
    /// The same for geoms, and the `<asset>`s they name: pictures only.
    looks: Looks,
    links: Vec<Link>,
    joints: Vec<Joint>,
}

impl<'a, 'i> Reader<'a, 'i> {
    fn new(doc: &'a roxmltree::Document<'i>, fail: &'a Fail<'a>) -> syn::Result<Self> {
        let root = doc.root_element();
        let pos = |n: roxmltree::Node| doc.text_pos_at(n.range().start);
        if root.tag_name().name() != "mujoco" {
            return Err(fail(
                pos(root),
                format!("expected a `<mujoco>` element, found `<{}>`", root.tag_name().name()),
            ));
        }
        let mut compiler = Compiler { degrees: true, eulerseq: *b"xyz" };
        for c in root.children().filter(|n| n.has_tag_name("compiler")) {
            match c.attribute("angle") {
                None => {}
                Some("degree") => compiler.degrees = true,
                Some("radian") => compiler.degrees = false,
                Some(other) => return Err(fail(pos(c), format!("`angle=\"{other}\"`: expected `degree` or `radian`"))),
            }
            if let Some(seq) = c.attribute("eulerseq") {
                let ok = seq.len() == 3 && seq.bytes().all(|b| b"xyzXYZ".contains(&b));
                if !ok {
                    return Err(fail(pos(c), format!("`eulerseq=\"{seq}\"`: expected three of `xyzXYZ`, as in `xyz`")));
                }
                compiler.eulerseq.copy_from_slice(seq.as_bytes());
            }
            if c.attribute("inertiafromgeom") == Some("true") {
                return Err(fail(
                    pos(c),
                    "`inertiafromgeom=\"true\"`: inertia from geoms is not computed; expected `<inertial>` in every \
                     body that has mass"
                        .into(),
                ));
            }
        }
        for n in root.descendants().filter(|n| n.is_element()) {
            let what = match n.tag_name().name() {
                "include" => "`<include>` is not read; expected one file",
                "composite" | "flexcomp" | "replicate" | "attach" => {
                    "this element is not read; expected plain `<body>`s"
                }
                _ => continue,
            };
            return Err(fail(pos(n), format!("`<{}>`: {what}", n.tag_name().name())));
        }
        unmodelled(doc, fail)?;
        let (mut defaults, mut geoms, mut equality_defaults) = (HashMap::new(), HashMap::new(), HashMap::new());
        for d in root.children().filter(|n| n.has_tag_name("default")) {
            default_class(d, ("main", "joint"), &HashMap::new(), &mut defaults, &pos, fail)?;
            default_class(d, ("main", "geom"), &HashMap::new(), &mut geoms, &pos, fail)?;
            default_class(d, ("main", "equality"), &HashMap::new(), &mut equality_defaults, &pos, fail)?;
        }
        defaults.entry("main".to_string()).or_default();
        equality_defaults.entry("main".to_string()).or_default();
        let looks = Looks::read(root, geoms, &pos, fail)?;
        let (links, joints) = (Vec::new(), Vec::new());
        Ok(Reader { doc, fail, compiler, defaults, equality_defaults, looks, links, joints })
    }

    fn pos(&self, n: roxmltree::Node) -> roxmltree::TextPos {
        self.doc.text_pos_at(n.range().start)
    }

    /// The bodies, frames and sites in `node` (link `parent`, childclass
    /// `class`), each placed by `offset` in the parent's frame.
    fn children(&mut self, node: roxmltree::Node, parent: usize, class: &str, offset: (M3, V3)) -> syn::Result<()> {
        for c in node.children().filter(|n| n.is_element()) {
            let at = self.pos(c);
            match c.tag_name().name() {
                "body" => self.body(c, parent, class, offset)?,
                "frame" => {
                    let frame = self.frame(c)?;
                    let inner = self.class(c, "childclass", class)?;
                    self.children(c, parent, &inner, compose(&offset, &frame))?;
                }
                "site" => {
                    let name = self.name(c, "site")?;
                    let origin = compose(&offset, &self.frame(c)?);
                    let visuals = Vec::new();
                    self.links.push(Link {
                        name: name.clone(),
                        inertial: None,
                        unknown: false,
                        gravcomp: 0.0,
                        visuals,
                        at,
                        inertial_at: [at; 2],
                    });
                    let child = self.links.len() - 1;
                    let (point, axis, limits) = ([0.0; 3], [0.0, 0.0, 1.0], FileLimits::default());
                    let continuous = false;
                    self.joints.push(Joint {
                        name,
                        kind: Kind::Fixed,
                        parent,
                        child,
                        origin,
                        point,
                        axis,
                        limits,
                        continuous,
                        at,
                        axis_at: at,
                    });
                }
                "geom" => {
                    let class = self.class(c, "class", class)?;
                    let visual = self.geom(c, &class, &offset)?;
                    self.links[parent].visuals.extend(visual);
                }
                "joint" | "freejoint" if parent == 0 => {
                    return Err((self.fail)(at, "a joint of the world; expected joints inside a `<body>`".into()));
                }
                _ => {}
            }
        }
        Ok(())
    }

    /// A `<body>`: its link, its joint from `parent` (fixed without one),
    /// then its children.
    fn body(&mut self, b: roxmltree::Node, parent: usize, class: &str, offset: (M3, V3)) -> syn::Result<()> {
        let at = self.pos(b);
        let name = self.name(b, "body")?;
        if b.attribute("mocap") == Some("true") {
            return Err((self.fail)(
                attribute_at(b, "mocap").unwrap_or(at),
                format!("body `{name}` is a mocap body; expected a body that moves by its joints"),
            ));
        }
        let class = self.class(b, "childclass", class)?;
        let origin = compose(&offset, &self.frame(b)?);
        let (inertial, inertial_at) = match b.children().find(|n| n.has_tag_name("inertial")) {
            Some(i) => {
                let written = |key| super::robot::attribute_at(i, key).unwrap_or(self.pos(i));
                let inertia = if i.attribute("fullinertia").is_some() { "fullinertia" } else { "diaginertia" };
                (Some(self.inertial(i, &name)?), [written("mass"), written(inertia)])
            }
            None => (None, [at; 2]),
        };
        // Geoms without `<inertial>` would give MuJoCo's body a mass from
        // them: an error if the body moves (`assemble` knows), not if the
        // ground holds it.
        let unknown = inertial.is_none() && b.children().any(|n| n.has_tag_name("geom"));
        let gravcomp = match b.attribute("gravcomp") {
            None => 0.0,
            Some(text) => match text.trim().parse::<f64>() {
                Ok(c) if c.is_finite() => c,
                _ => {
                    let at = attribute_at(b, "gravcomp").unwrap_or(at);
                    return Err((self.fail)(at, format!("`gravcomp=\"{text}\"`: expected a number")));
                }
            },
        };
        self.links.push(Link { name: name.clone(), inertial, unknown, gravcomp, visuals: Vec::new(), at, inertial_at });
        let child = self.links.len() - 1;
        let declared: Vec<roxmltree::Node> =
            b.children().filter(|n| n.has_tag_name("joint") || n.has_tag_name("freejoint")).collect();
        let joint = match declared.as_slice() {
            [] => Joint {
                name,
                kind: Kind::Fixed,
                parent,
                child,
                origin,
                point: [0.0; 3],
                axis: [0.0, 0.0, 1.0],
                limits: FileLimits::default(),
                continuous: false,
                at,
                axis_at: at,
            },
            [j] => self.joint(*j, parent, child, origin, &class)?,
            [_, second, ..] => {
                return Err((self.fail)(
                    self.pos(*second),
                    format!(
                        "body `{name}` has a second joint; expected one (`hinge`, `slide`, `ball` or `free`): \
                         several joints in one body are not read yet"
                    ),
                ));
            }
        };
        self.joints.push(joint);
        self.children(b, child, &class, (IDENTITY, [0.0; 3]))
    }

    /// A body's joint, with its class's defaults; each mistake at the
    /// attribute that makes it (the class's line where the class sets it).
    fn joint(
        &self,
        j: roxmltree::Node,
        parent: usize,
        child: usize,
        origin: (M3, V3),
        class: &str,
    ) -> syn::Result<Joint> {
        let (at, fail) = (self.pos(j), self.fail);
        let name = self.name(j, "joint")?;
        let label = match name.as_str() {
            "" => format!("the joint of body `{}`", self.links[child].name),
            _ => format!("joint `{name}`"),
        };
        let free = j.has_tag_name("freejoint");
        // `<freejoint/>` takes no class defaults (MuJoCo 4.0: its compiled
        // `dof_damping` and `dof_armature` stay 0 under a `childclass` that
        // sets them); `<joint type="free">` takes them like any joint.
        let class = if free { String::new() } else { self.class(j, "class", class)? };
        let get = Lookup { node: j, class: self.defaults.get(&class), at };
        let value = |key: &str| get.number(key, fail);
        let kind = match if free { "free" } else { get.text("type").unwrap_or("hinge") } {
            "hinge" => Kind::Revolute,
            "slide" => Kind::Prismatic,
            "ball" => Kind::Spherical,
            "free" if parent == 0 => Kind::Floating,
            "free" => {
                let message =
                    format!("{label} is free on a body of a body; expected a free joint only on a body of the world");
                return Err(fail(get.at("type"), message));
            }
            other => {
                let message = format!("{label} has type `{other}`; expected `hinge`, `slide`, `ball` or `free`");
                return Err(fail(get.at("type"), message));
            }
        };
        let (point, axis) = (get.triple("pos", [0.0; 3], fail)?, get.triple("axis", [0.0, 0.0, 1.0], fail)?);
        let angular = matches!(kind, Kind::Revolute | Kind::Spherical);
        let scale = if angular && self.compiler.degrees { std::f64::consts::PI / 180.0 } else { 1.0 };
        let range = range(get.text("range"), get.text("limited"), scale, &|m| fail(get.at("range"), m))?;
        let effort = get.text("actuatorfrcrange").and_then(|text| {
            text.split_whitespace().filter_map(|t| t.parse::<f64>().ok()).map(f64::abs).reduce(f64::max)
        });
        let (damping, armature) = (value("damping")?, value("armature")?);
        let spring = spring(&value, (kind, scale), &label, &|key, m| fail(get.at(key), m))?;
        // MuJoCo's coordinate is `ref` at the file's pose, the tree's zero:
        // its range in the tree's coordinate.
        let range = range.map(|(a, b)| (a - spring.reference, b - spring.reference));
        for (key, x) in [("damping", damping), ("armature", armature)] {
            let Some(x) = x else { continue };
            if kind == Kind::Floating && x != 0.0 {
                let message = format!(
                    "{label} is `type=\"free\"` and has `{key}` (its own or its class's): MuJoCo applies it to the six \
                     freedoms of the floating body, which is not modelled; expected none (`<freejoint/>` takes no class)"
                );
                return Err(fail(get.at(key), message));
            }
            if x < 0.0 {
                return Err(fail(
                    get.at(key),
                    format!("{label} has a negative `{key}`; expected a number at least zero"),
                ));
            }
        }
        let friction = value("frictionloss")?;
        let limits = FileLimits { range, effort, velocity: None, damping, friction, armature, spring };
        let axis_at = get.at("axis");
        Ok(Joint { name, kind, parent, child, origin, point, axis, limits, continuous: false, at, axis_at })
    }

    /// `<inertial>`: mass, centre and inertia in the body's frame.
    fn inertial(&self, i: roxmltree::Node, body: &str) -> syn::Result<(f64, V3, M3)> {
        let (at, fail) = (self.pos(i), self.fail);
        let (turn, centre) = self.frame(i)?;
        let mass = number(i, "mass", at, fail)?;
        let turned = ORIENTATIONS.iter().any(|k| i.attribute(*k).is_some());
        let tensor = match (numbers::<3>(i, "diaginertia", at, fail)?, numbers::<6>(i, "fullinertia", at, fail)?) {
            (Some([a, b, c]), None) => {
                mul(&mul(&turn, &[[a, 0.0, 0.0], [0.0, b, 0.0], [0.0, 0.0, c]]), &transpose(&turn))
            }
            (None, Some([xx, yy, zz, xy, xz, yz])) if !turned => [[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]],
            (None, Some(_)) => {
                return Err(fail(
                    attribute_at(i, "fullinertia").unwrap_or(at),
                    format!("body `{body}`'s `<inertial>` has `fullinertia` and an orientation; expected one of them"),
                ));
            }
            _ => {
                return Err(fail(
                    at,
                    format!(
                        "body `{body}`'s `<inertial>` needs one of `diaginertia=\"ixx iyy izz\"` or `fullinertia=\"ixx iyy izz ixy ixz iyz\"`"
                    ),
                ));
            }
        };
        Ok((mass, centre, tensor))
    }

    /// An element's `pos` and orientation (at most one of MuJoCo's five).
    fn frame(&self, n: roxmltree::Node) -> syn::Result<(M3, V3)> {
        let (at, fail) = (self.pos(n), self.fail);
        let p = triple(n, "pos", at, fail)?.unwrap_or([0.0; 3]);
        let given: Vec<&str> = ["quat", "axisangle", "euler", "xyaxes", "zaxis"]
            .into_iter()
            .filter(|k| n.attribute(*k).is_some())
            .collect();
        let turn = match given.as_slice() {
            [] => IDENTITY,
            [_, _, ..] => {
                return Err(fail(
                    attribute_at(n, given[1]).unwrap_or(at),
                    format!("`{}` and `{}` both give the orientation; expected one", given[0], given[1]),
                ));
            }
            ["quat"] => quaternion(numbers::<4>(n, "quat", at, fail)?.unwrap_or([1.0, 0.0, 0.0, 0.0])),
            ["axisangle"] => {
                let [x, y, z, a] = numbers::<4>(n, "axisangle", at, fail)?.unwrap_or([0.0, 0.0, 1.0, 0.0]);
                let angle = if self.compiler.degrees { a.to_radians() } else { a };
                let l = norm(&[x, y, z]);
                let (s, c) = (0.5 * angle).sin_cos();
                quaternion([c, s * x / l, s * y / l, s * z / l])
            }
            ["euler"] => {
                let angles = triple(n, "euler", at, fail)?.unwrap_or([0.0; 3]);
                let mut turn = IDENTITY;
                for (axis, angle) in self.compiler.eulerseq.iter().zip(angles) {
                    let angle = if self.compiler.degrees { angle.to_radians() } else { angle };
                    let (s, c) = (0.5 * angle).sin_cos();
                    let k = usize::from(axis.to_ascii_lowercase() - b'x');
                    let mut q = [c, 0.0, 0.0, 0.0];
                    q[1 + k] = s;
                    // Lower case: about the turned axes (after); upper case: about the fixed ones (before).
                    turn =
                        if axis.is_ascii_lowercase() { mul(&turn, &quaternion(q)) } else { mul(&quaternion(q), &turn) };
                }
                turn
            }
            ["xyaxes"] => {
                let [a, b, c, d, e, f] = numbers::<6>(n, "xyaxes", at, fail)?.unwrap_or([1.0, 0.0, 0.0, 0.0, 1.0, 0.0]);
                let x = unit([a, b, c]);
                let y = [d, e, f];
                let along = x[0] * y[0] + x[1] * y[1] + x[2] * y[2];
                let y = unit(add(&y, &x.map(|v| -along * v)));
                let z = cross(&x, &y);
                transpose(&[x, y, z])
            }
            _ => {
                let z = unit(triple(n, "zaxis", at, fail)?.unwrap_or([0.0, 0.0, 1.0]));
                // The shortest turn taking the frame's z to `z` (MuJoCo's).
                let axis = cross(&[0.0, 0.0, 1.0], &z);
                let s = norm(&axis);
                if s < 1e-14 {
                    if z[2] > 0.0 { IDENTITY } else { quaternion([0.0, 1.0, 0.0, 0.0]) }
                } else {
                    let angle = s.atan2(z[2]);
                    let (hs, hc) = (0.5 * angle).sin_cos();
                    quaternion([hc, hs * axis[0] / s, hs * axis[1] / s, hs * axis[2] / s])
                }
            }
        };
        if !turn.iter().flatten().all(|x| x.is_finite()) {
            return Err(fail(
                attribute_at(n, given[0]).unwrap_or(at),
                format!("the orientation `{}` is degenerate (a zero vector); expected a turn", given[0]),
            ));
        }
        Ok((turn, p))
    }

    /// A `<geom>` of class `class` placed by `offset` in its link's frame;
    /// `None` for one MuJoCo's viewer hides (`group` 3 and above, or
    /// transparent) or of a type not drawn.
    fn geom(&self, g: roxmltree::Node, class: &str, offset: &(M3, V3)) -> syn::Result<Option<FileVisual>> {
        let (at, fail) = (self.pos(g), self.fail);
        let get = |key: &str| g.attribute(key).or_else(|| Some(self.looks.defaults.get(class)?.get(key)?.0.as_str()));
        let list = |key: &str| -> syn::Result<Vec<f64>> {
            let Some(text) = get(key) else { return Ok(Vec::new()) };
            let parsed: Option<Vec<f64>> =
                text.split_whitespace().map(|t| t.parse::<f64>().ok().filter(|x| x.is_finite())).collect();
            parsed.ok_or_else(|| fail(at, format!("`{key}=\"{text}\"`: expected numbers")))
        };
        let group = list("group")?.first().copied().unwrap_or(0.0);
        let rgba = match list("rgba")?.as_slice() {
            [] => get("material").and_then(|m| self.looks.materials.get(m)).copied(),
            &[r, g, b, a] => Some([r, g, b, a]),
            _ => return Err(fail(at, "`rgba`: expected four numbers, as in `rgba=\"0.5 0.5 0.5 1\"`".into())),
        };
        if group >= 3.0 || rgba.is_some_and(|c| c[3] <= 0.0) {
            return Ok(None);
        }
        let fromto = list("fromto")?;
        let (pose, length) = match fromto.as_slice() {
            [] => (compose(offset, &self.frame(g)?), None),
            &[a, b, c, d, e, f] => {
                let turn = z_turn([d - a, e - b, f - c])
                    .ok_or_else(|| fail(at, "`fromto`: both ends are the same point; expected a segment".into()))?;
                let centre = [0.5 * (a + d), 0.5 * (b + e), 0.5 * (c + f)];
                (compose(offset, &(turn, centre)), Some(norm(&[d - a, e - b, f - c])))
            }
            _ => return Err(fail(at, "`fromto`: expected six numbers, as in `fromto=\"0 0 0 0 0 1\"`".into())),
        };
        let mesh = get("mesh").map(|name| {
            self.looks.meshes.get(name).cloned().ok_or_else(|| {
                fail(
                    at,
                    format!(
                        "`mesh=\"{name}\"` names no `<asset><mesh name=\"{name}\">`; expected one of the file's meshes"
                    ),
                )
            })
        });
        let mesh = mesh.transpose()?;
        let shape =
            mjcf_shape(get("type").unwrap_or("sphere"), &list("size")?, length, mesh).map_err(|m| fail(at, m))?;
        Ok(shape.map(|shape| FileVisual { pose, shape, rgba }))
    }

    /// An element's `name` (empty if none), unique among the links.
    fn name(&self, n: roxmltree::Node, what: &str) -> syn::Result<String> {
        let name = n.attribute("name").unwrap_or("").to_string();
        let named = |l: &Link| !name.is_empty() && l.name == name;
        let taken = if what == "joint" {
            self.joints.iter().any(|j| !name.is_empty() && j.name == name)
        } else {
            self.links.iter().any(named)
        };
        if taken {
            let plural = if what == "joint" { "joint" } else { "body or site" };
            return Err((self.fail)(
                self.pos(n),
                format!("{what} `{name}` is declared twice; expected unique {plural} names"),
            ));
        }
        Ok(name)
    }

    /// The class of `n`: its own (`key`) or the one it inherits.
    fn class(&self, n: roxmltree::Node, key: &str, inherited: &str) -> syn::Result<String> {
        let class = n.attribute(key).unwrap_or(inherited).to_string();
        if self.defaults.contains_key(&class) {
            return Ok(class);
        }
        let at = attribute_at(n, key).unwrap_or(self.pos(n));
        Err((self.fail)(at, format!("`{key}=\"{class}\"` names no `<default class=\"{class}\">`")))
    }

    /// `<equality>`'s `connect` and `weld` as closing joints, `joint` as
    /// couplings (`joint1 = a0 + a1 joint2`): none where `<flag equality>` or
    /// `<flag constraint>` is `disable` (MuJoCo leaves them out). Each soft
    /// as MuJoCo makes it (`solref`, `solimp`; `refsafe`: the file's step
    /// where MuJoCo raises time constants to twice it), or ideal where the
    /// scene asks (`hard`; `independent` for `<equality joint>`s, which the
    /// scene then leaves out).
    fn equalities(
        &self,
        root: roxmltree::Node,
        (hard, independent): (bool, bool),
        refsafe: Option<f64>,
    ) -> syn::Result<(Vec<Closure>, Vec<FileCoupling>)> {
        let fail = self.fail;
        let flags = root.children().filter(|n| n.has_tag_name("option")).flat_map(|o| o.children());
        let off = |f: roxmltree::Node| ["equality", "constraint"].iter().any(|k| f.attribute(*k) == Some("disable"));
        if flags.filter(|n| n.has_tag_name("flag")).any(off) {
            return Ok((Vec::new(), Vec::new()));
        }
        let link = |n: roxmltree::Node, key: &str| -> syn::Result<usize> {
            let name = n.attribute(key).unwrap_or("world");
            self.links.iter().position(|l| l.name == name).ok_or_else(|| {
                let at = attribute_at(n, key).unwrap_or(self.pos(n));
                fail(at, format!("`{key}=\"{name}\"` is not a body of the file; expected one of its bodies"))
            })
        };
        let (mut out, mut couplings) = (Vec::new(), Vec::new());
        for (k, e) in root
            .children()
            .filter(|n| n.has_tag_name("equality"))
            .flat_map(|q| q.children())
            .filter(|n| n.is_element())
            .enumerate()
        {
            let (at, tag) = (self.pos(e), e.tag_name().name());
            if e.attribute("active") == Some("false") {
                continue;
            }
            if independent && tag == "joint" {
                continue;
            }
            let soft = if hard { None } else { Some(self.softness(e, refsafe)?) };
            let weld = match tag {
                "connect" => false,
                "weld" => true,
                "joint" => {
                    couplings.push(FileCoupling { soft, ..self.coupling(e)? });
                    continue;
                }
                _ => {
                    return Err(fail(
                        at,
                        format!("`<{tag}>` equalities are not read yet; expected `connect`, `weld` or `joint`"),
                    ));
                }
            };
            if e.attribute("site1").is_some() {
                return Err(fail(at, format!("`<{tag}>` between sites is not read yet; expected `body1` and `body2`")));
            }
            let _ = required(e, "body1", at, fail)?;
            let links = [link(e, "body1")?, link(e, "body2")?];
            let anchor = triple(e, "anchor", at, fail)?;
            if !weld && anchor.is_none() {
                return Err(fail(
                    at,
                    "`<connect>` has no `anchor`; expected `anchor=\"x y z\"` in `body1`'s frame".into(),
                ));
            }
            // A zero quaternion is MuJoCo's "the reference pose".
            let relpose = numbers::<7>(e, "relpose", at, fail)?;
            if relpose.is_some_and(|[_, _, _, a, b, c, d]| [a, b, c, d] != [0.0; 4]) {
                let message =
                    "`relpose` is not read yet; expected the weld at the file's reference pose (no `relpose`)";
                return Err(fail(attribute_at(e, "relpose").unwrap_or(at), message.into()));
            }
            let name = e.attribute("name").map_or_else(|| format!("{tag}{k}"), str::to_string);
            // `connect`'s anchor is in body1's frame, `weld`'s in body2's.
            let anchor_on = if weld { links[1] } else { links[0] };
            out.push(Closure { name, weld, links, anchor_on, anchor: anchor.unwrap_or([0.0; 3]), at, soft });
        }
        Ok((out, couplings))
    }

    /// `<joint joint1 joint2 polycoef>`: `joint1 = a0 + a1 joint2`, both
    /// moving joints of the file (higher powers are not read).
    fn coupling(&self, e: roxmltree::Node) -> syn::Result<FileCoupling> {
        let (at, fail) = (self.pos(e), self.fail);
        let follower = required(e, "joint1", at, fail)?;
        let leader = e.attribute("joint2").ok_or_else(|| {
            fail(
                at,
                "`<joint>` equality without `joint2` (a locked joint) is not read; expected `joint2=\"..\"`".into(),
            )
        })?;
        let [a0, a1, a2, a3, a4] = numbers::<5>(e, "polycoef", at, fail)?.unwrap_or([0.0, 1.0, 0.0, 0.0, 0.0]);
        if [a2, a3, a4] != [0.0; 3] {
            return Err(fail(
                at,
                "`polycoef` beyond the linear term is not read; expected `polycoef=\"a0 a1 0 0 0\"`".into(),
            ));
        }
        let moving = |name: &str| {
            self.joints.iter().any(|j| j.name == name && matches!(j.kind, Kind::Revolute | Kind::Prismatic))
        };
        if !moving(&follower) || !moving(leader) {
            return Err(fail(
                at,
                format!(
                    "`<joint>` equality of `{follower}` and `{leader}`: expected two hinge or slide joints of the file"
                ),
            ));
        }
        Ok(FileCoupling { follower, leader: leader.to_string(), multiplier: a1, offset: a0, soft: None })
    }

    /// An equality's `solref` and `solimp` (its own, else its class's, else
    /// MuJoCo's `0.02 1` and `0.9 0.95 0.001 0.5 2`; fewer numbers than
    /// five fill the first ones, as MuJoCo reads them), clamped and with
    /// the time constant raised to twice `refsafe`'s step, as MuJoCo's
    /// `getsolparam` does.
    fn softness(&self, e: roxmltree::Node, refsafe: Option<f64>) -> syn::Result<Soft> {
        let (at, fail) = (self.pos(e), self.fail);
        let class = self.class(e, "class", "main")?;
        let class = self.equality_defaults.get(&class);
        let get = Lookup { node: e, class, at };
        let mut solref = [0.02, 1.0];
        let mut solimp = [0.9, 0.95, 0.001, 0.5, 2.0];
        for (key, out) in [("solref", &mut solref[..]), ("solimp", &mut solimp[..])] {
            // The class's numbers over MuJoCo's, the element's over those.
            let own = e.attribute(key).map(|t| (t, attribute_at(e, key).unwrap_or(at)));
            let inherited = class.and_then(|c| c.get(key)).map(|(t, at)| (t.as_str(), *at));
            for (text, at) in inherited.into_iter().chain(own) {
                let parsed: Vec<Option<f64>> = text.split_whitespace().map(|t| t.parse().ok()).collect();
                let n = out.len();
                if parsed.is_empty() || parsed.len() > n || parsed.iter().any(|x| !x.is_some_and(f64::is_finite)) {
                    return Err(fail(at, format!("`{key}=\"{text}\"`: expected one to {n} numbers")));
                }
                for (o, x) in out.iter_mut().zip(parsed.into_iter().flatten()) {
                    *o = x;
                }
            }
        }
        if (solref[0] > 0.0) != (solref[1] > 0.0) {
            let at = get.at("solref");
            let message = "`solref` mixes MuJoCo's two forms, which MuJoCo replaces by its default with a warning; \
                           expected a time constant and a damping ratio (both positive) or a stiffness and a damping \
                           (both negative)";
            return Err(fail(at, message.into()));
        }
        if let (Some(step), true) = (refsafe, solref[0] > 0.0) {
            solref[0] = solref[0].max(2.0 * step);
        }
        // MuJoCo's mjMINIMP and mjMAXIMP.
        let (low, high) = (0.0001, 0.9999);
        for k in [0, 1, 3] {
            solimp[k] = solimp[k].clamp(low, high);
        }
        solimp[2] = solimp[2].max(0.0);
        solimp[4] = solimp[4].max(1.0);
        let torquescale = get.number("torquescale", fail)?.unwrap_or(1.0);
        Ok(Soft { solref, solimp, torquescale })
    }
}

/// A joint's attributes: its own, else its class's (`class`: each value
/// with where the class states it), so that a mistake is reported where it
/// is written; `at`: the element, for what neither states.
struct Lookup<'a, 'i> {
    node: roxmltree::Node<'a, 'i>,
    class: Option<&'a Class>,
    at: roxmltree::TextPos,
}

impl Lookup<'_, '_> {
    fn find(&self, key: &str) -> Option<(&str, roxmltree::TextPos)> {
        match (self.node.attribute(key), attribute_at(self.node, key)) {
            (Some(text), Some(at)) => Some((text, at)),
            _ => self.class?.get(key).map(|(v, at)| (v.as_str(), *at)),
        }
    }

    fn text(&self, key: &str) -> Option<&str> {
        self.find(key).map(|(v, _)| v)
    }

    /// Where `key` is written (the element where it is not).
    fn at(&self, key: &str) -> roxmltree::TextPos {
        self.find(key).map_or(self.at, |(_, at)| at)
    }

    /// One number, if given; MuJoCo's polynomial (several) refused by name.
    fn number(&self, key: &str, fail: &Fail) -> syn::Result<Option<f64>> {
        let Some((text, at)) = self.find(key) else { return Ok(None) };
        match text.trim().parse::<f64>() {
            Ok(x) if x.is_finite() => Ok(Some(x)),
            _ if text.split_whitespace().filter(|t| t.parse::<f64>().is_ok()).count() > 1 => Err(fail(
                at,
                format!(
                    "`{key}=\"{text}\"`: MuJoCo reads the numbers after the first as a polynomial (damping \
                     `d₀ v + d₁ v|v| + d₂ v³`, stiffness likewise in the stretch), which is not modelled; expected \
                     one number"
                ),
            )),
            _ => Err(fail(at, format!("`{key}=\"{text}\"`: expected a number"))),
        }
    }

    /// Three numbers, `default` where not given.
    fn triple(&self, key: &str, default: V3, fail: &Fail) -> syn::Result<V3> {
        let Some((text, at)) = self.find(key) else { return Ok(default) };
        parse_numbers(key, text, at, fail)
    }
}

/// The values of an attribute that leave MuJoCo's dynamics as this reader
/// models them.
#[derive(Clone, Copy)]
enum Neutral {
    /// Numbers, all zero.
    Zero,
    /// `false`.
    False,
    /// `enable`: a `<flag>` left on.
    Enable,
}

impl Neutral {
    fn holds(self, value: &str) -> bool {
        let numbers = || value.split_whitespace().map(str::parse::<f64>);
        match self {
            Neutral::Zero => numbers().all(|x| x == Ok(0.0)),
            Neutral::False => value == "false",
            Neutral::Enable => value == "enable",
        }
    }
}

/// `<option timestep integrator>`: a positive step, one of MuJoCo's four
/// integrators (its names), each checked at the element.
fn step_options(o: roxmltree::Node, at: roxmltree::TextPos, fail: &Fail) -> syn::Result<FileOptions> {
    let at = |key| attribute_at(o, key).unwrap_or(at);
    let timestep = match o.attribute("timestep") {
        None => None,
        Some(text) => match text.trim().parse::<f64>() {
            Ok(h) if h.is_finite() && h > 0.0 => Some(h),
            _ => return Err(fail(at("timestep"), format!("`timestep=\"{text}\"`: expected a positive number (s)"))),
        },
    };
    let integrator = match o.attribute("integrator") {
        None => None,
        Some(name @ ("Euler" | "RK4" | "implicit" | "implicitfast")) => Some(name.to_string()),
        Some(other) => {
            return Err(fail(
                at("integrator"),
                format!("`integrator=\"{other}\"`: expected `Euler`, `RK4`, `implicit` or `implicitfast`"),
            ));
        }
    };
    Ok(FileOptions { timestep, integrator })
}

/// `<compiler settotalmass="m">` (positive): every body's mass and inertia
/// scaled by one factor so that the masses sum to `m`, as MuJoCo's compiler
/// does. Refused where a body's mass would come from its geoms (not
/// computed here, yet part of MuJoCo's sum) or the bodies have no mass.
fn total_mass(root: roxmltree::Node, links: &mut [Link], fail: &Fail) -> syn::Result<()> {
    for c in root.children().filter(|n| n.has_tag_name("compiler")) {
        let Some(text) = c.attribute("settotalmass") else { continue };
        let at = attribute_at(c, "settotalmass").unwrap_or_else(|| c.document().text_pos_at(c.range().start));
        let total = text.trim().parse::<f64>().ok().filter(|x| x.is_finite());
        let Some(total) = total else {
            return Err(fail(at, format!("`settotalmass=\"{text}\"`: expected a number")));
        };
        if total <= 0.0 {
            continue;
        }
        if let Some(l) = links.iter().find(|l| l.unknown) {
            let message = format!(
                "`settotalmass` scales every body's mass, and body `{}`'s comes from its geoms, which is not \
                 computed; expected `<inertial>` in every body with geoms",
                l.name
            );
            return Err(fail(at, message));
        }
        let sum: f64 = links.iter().filter_map(|l| l.inertial.map(|(m, _, _)| m)).sum();
        if sum <= 0.0 {
            return Err(fail(at, "`settotalmass` with no body of positive mass to scale".into()));
        }
        let scale = total / sum;
        for (m, _, inertia) in links.iter_mut().filter_map(|l| l.inertial.as_mut()) {
            *m *= scale;
            *inertia = inertia.map(|row| row.map(|x| x * scale));
        }
    }
    Ok(())
}

/// A hinge's or slide's `stiffness`, `springref` and `ref` (angles in the
/// compiler's unit, `scale` to radians): the spring in the tree's coordinate
/// (MuJoCo's minus `ref`). A ball or free joint's spring is refused; their
/// `ref` MuJoCo does not use.
fn spring(
    value: &dyn Fn(&str) -> syn::Result<Option<f64>>,
    (kind, scale): (Kind, f64),
    label: &str,
    fail: &dyn Fn(&str, String) -> syn::Error,
) -> syn::Result<FileSpring> {
    let stiffness = value("stiffness")?.unwrap_or(0.0);
    if stiffness < 0.0 {
        return Err(fail("stiffness", format!("{label} has a negative `stiffness`; expected a number at least zero")));
    }
    if !matches!(kind, Kind::Revolute | Kind::Prismatic) {
        if stiffness != 0.0 {
            return Err(fail(
                "stiffness",
                format!(
                    "{label} is a ball or free joint with a `stiffness` (its own or its class's): MuJoCo springs its \
                     quaternion towards the reference pose, which is not modelled; expected `stiffness=\"0\"` or none"
                ),
            ));
        }
        return Ok(FileSpring::default());
    }
    let reference = value("ref")?.unwrap_or(0.0) * scale;
    let rest = value("springref")?.unwrap_or(0.0) * scale - reference;
    Ok(FileSpring { stiffness, rest, reference })
}

/// What changes MuJoCo's dynamics and is not modelled here, refused
/// wherever the file states it (a `<default>` class included), at the
/// attribute: `(element, attribute, what leaves it neutral, what MuJoCo
/// does with it)`. Modelled instead: `<option gravity>` and `<flag
/// gravity>`, a joint's `armature` and `damping`, `<flag equality
/// constraint>` (no equalities); data: `<option timestep integrator>`,
/// ranges, `frictionloss`, actuators (the guide's table). Fluid forces need
/// `density` or `viscosity` (MuJoCo computes none while both are zero, so
/// `wind` and `fluidshape` alone change nothing).
const UNMODELLED: &[(&str, &str, Neutral, &str)] = &[
    (
        "joint",
        "actuatorgravcomp",
        Neutral::False,
        "moves this joint's gravity compensation into its actuator force (`qfrc_actuator`, clamped by \
         `actuatorfrcrange`)",
    ),
    (
        "joint",
        "springdamper",
        Neutral::Zero,
        "sets the joint's stiffness and damping from this time constant and damping ratio and the joint's inertia",
    ),
    ("compiler", "boundmass", Neutral::Zero, "raises every smaller body mass to this bound"),
    ("compiler", "boundinertia", Neutral::Zero, "raises every smaller principal inertia to this bound"),
    ("compiler", "balanceinertia", Neutral::False, "changes the inertias that break the triangle inequality"),
    ("option", "density", Neutral::Zero, "applies fluid forces (from `density` and `viscosity`) to every body"),
    ("option", "viscosity", Neutral::Zero, "applies fluid forces (from `density` and `viscosity`) to every body"),
    (
        "flag",
        "passive",
        Neutral::Enable,
        "leaves out every passive force (joint springs and damping, gravity compensation)",
    ),
    ("flag", "damper", Neutral::Enable, "leaves out joint damping"),
];

/// Refuses the first of [`UNMODELLED`] the file states, at the attribute's
/// line and column, saying what MuJoCo does with it.
fn unmodelled(doc: &roxmltree::Document, fail: &Fail) -> syn::Result<()> {
    for n in doc.root_element().descendants().filter(|n| n.is_element()) {
        let tag = n.tag_name().name();
        for a in n.attributes() {
            let at = doc.text_pos_at(a.range().start);
            let (key, value) = (a.name(), a.value());
            let refused = UNMODELLED.iter().find(|(t, k, neutral, _)| *t == tag && *k == key && !neutral.holds(value));
            if let Some((_, _, neutral, does)) = refused {
                let expected = match neutral {
                    Neutral::Zero => format!("`{key}=\"0\"` or none"),
                    Neutral::False => format!("`{key}=\"false\"` or none"),
                    Neutral::Enable => format!("`{key}=\"enable\"` or none"),
                };
                return Err(fail(
                    at,
                    format!(
                        "`{key}=\"{value}\"` on `<{tag}>`: MuJoCo {does}, which is not modelled; expected {expected}"
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// MuJoCo's five ways to give an orientation.
const ORIENTATIONS: [&str; 5] = ["quat", "axisangle", "euler", "xyaxes", "zaxis"];

/// One `<default>` and the classes inside it: each class's attributes of
/// its `tag` (joint, geom) over its parent's.
fn default_class(
    d: roxmltree::Node,
    (name, tag): (&str, &str),
    parent: &Class,
    out: &mut HashMap<String, Class>,
    pos: &dyn Fn(roxmltree::Node) -> roxmltree::TextPos,
    fail: &Fail,
) -> syn::Result<()> {
    let name = d.attribute("class").unwrap_or(name).to_string();
    if out.contains_key(&name) {
        return Err(fail(pos(d), format!("default class `{name}` is declared twice; expected unique class names")));
    }
    let mut own = parent.clone();
    for j in d.children().filter(|n| n.has_tag_name(tag)) {
        let at = |a: &roxmltree::Attribute| d.document().text_pos_at(a.range().start);
        own.extend(j.attributes().map(|a| (a.name().to_string(), (a.value().to_string(), at(&a)))));
    }
    for inner in d.children().filter(|n| n.has_tag_name("default")) {
        if inner.attribute("class").is_none() {
            return Err(fail(pos(inner), "a nested `<default>` has no `class`; expected `class=\"..\"`".into()));
        }
        default_class(inner, ("", tag), &own, out, pos, fail)?;
    }
    out.insert(name, own);
    Ok(())
}

/// `b` in `a`'s frame, in the frame `a` is in.
fn compose(a: &(M3, V3), b: &(M3, V3)) -> (M3, V3) {
    (mul(&a.0, &b.0), add(&a.1, &apply(&a.0, &b.1)))
}

fn unit(v: V3) -> V3 {
    let l = norm(&v);
    v.map(|x| x / l)
}

/// The rotation of a quaternion `[w, x, y, z]` (normalised first).
fn quaternion(q: [f64; 4]) -> M3 {
    let l = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
    let [w, x, y, z] = q.map(|v| v / l);
    [
        [1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - w * z), 2.0 * (x * z + w * y)],
        [2.0 * (x * y + w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - w * x)],
        [2.0 * (x * z - w * y), 2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y)],
    ]
}

/// `u × v`.
pub fn cross(u: &V3, v: &V3) -> V3 {
    [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]
}

/// A joint's `range` (unless `limited="false"`), in radians or metres.
fn range(
    text: Option<&str>,
    limited: Option<&str>,
    scale: f64,
    fail: &dyn Fn(String) -> syn::Error,
) -> syn::Result<Option<(f64, f64)>> {
    let Some(text) = text.filter(|_| limited != Some("false")) else { return Ok(None) };
    let parsed: Vec<f64> = text.split_whitespace().map_while(|t| t.parse().ok()).collect();
    match parsed.as_slice() {
        [a, b] if text.split_whitespace().count() == 2 && a.is_finite() && b.is_finite() => {
            Ok(Some((a * scale, b * scale)))
        }
        _ => Err(fail(format!("`range=\"{text}\"`: expected two numbers, as in `range=\"-1 1\"`"))),
    }
}

#[cfg(test)]
mod tests {
    use super::super::robot::tests::{cut_and_mutated, test_file};
    use super::*;

    /// `equality = hard`: the files' equalities read as ideal rows.
    const HARD: (bool, bool) = (true, false);

    /// The error of reading `text`, from its line and column on.
    fn error(text: &str) -> String {
        let span = proc_macro2::Span::call_site();
        let message = from_text(text, "f.xml", span, HARD).err().map(|e| e.to_string()).unwrap_or_default();
        message.strip_prefix("f.xml:").unwrap_or(&message).to_string()
    }

    /// A file of one body on a hinge, `body` inside its `<body>`, `extra`
    /// after the `<worldbody>`.
    fn one_body(body: &str, extra: &str) -> String {
        format!(
            "<mujoco>\n<worldbody>\n<body name=\"arm\">\n<inertial pos=\"0 0 0\" mass=\"1\" diaginertia=\"1 1 1\"/>\n\
             {body}\n</body>\n</worldbody>\n{extra}\n</mujoco>"
        )
    }

    /// `<flag gravity="disable"/>` is MuJoCo's model without gravity; the
    /// file's `<option gravity>` otherwise, MuJoCo's `0 0 -9.81` without one.
    #[test]
    fn gravity_as_the_file_says() {
        let hinge = "<joint name=\"j\"/>";
        let gravity = |extra: &str| {
            from_text(&one_body(hinge, extra), "f.xml", proc_macro2::Span::call_site(), HARD).map(|r| r.gravity).ok()
        };
        assert_eq!(gravity(""), Some(Some([0.0, 0.0, -9.81])));
        assert_eq!(gravity("<option gravity=\"0 -1 0\"/>"), Some(Some([0.0, -1.0, 0.0])));
        assert_eq!(gravity("<option><flag gravity=\"disable\"/></option>"), Some(Some([0.0; 3])));
    }

    /// Public quadrupeds and humanoids float their base with `<freejoint/>`
    /// inside a `childclass` whose joints are damped: MuJoCo applies no class
    /// to `<freejoint/>` (its free dofs' damping and armature compile to 0),
    /// so the file reads, its hinge below still taking the class's numbers;
    /// `<joint type="free">` in that class takes them and is refused.
    #[test]
    fn freejoint_takes_no_class_defaults() {
        let file = |base: &str| {
            format!(
                "<mujoco>\n<default><default class=\"robot\"><joint damping=\"2\" armature=\"0.1\"/></default></default>\n\
                 <worldbody>\n<body name=\"base\" childclass=\"robot\">\n\
                 <inertial pos=\"0 0 0\" mass=\"1\" diaginertia=\"1 1 1\"/>\n{base}\n\
                 <body name=\"leg\"><inertial pos=\"0 0 0\" mass=\"1\" diaginertia=\"1 1 1\"/><joint name=\"hip\"/></body>\n\
                 </body>\n</worldbody>\n</mujoco>"
            )
        };
        let span = proc_macro2::Span::call_site();
        let robot = from_text(&file("<freejoint name=\"root\"/>"), "f.xml", span, HARD).unwrap();
        let hip = robot.joints.iter().find(|j| j.name == "hip").unwrap().limits;
        assert_eq!((hip.damping, hip.armature), (Some(2.0), Some(0.1)));
        assert_eq!(robot.library.1.first().map(|j| j.name.as_str()), Some("root"));
        let refused = from_text(&file("<joint name=\"root\" type=\"free\"/>"), "f.xml", span, HARD);
        let refused = refused.err().map(|e| e.to_string()).unwrap_or_default();
        // At the class's `damping`, line 2.
        assert!(
            refused.starts_with("f.xml:2:") && refused.contains("has `damping` (its own or its class's)"),
            "{refused}"
        );
    }

    #[test]
    fn bad_files_one_message_each_at_line_and_column() {
        let hinge = "<joint name=\"j\"/>";
        let second = "<body name=\"hand\"><inertial pos=\"0 0 0\" mass=\"1\" diaginertia=\"1 1 1\"/><joint/></body>";
        let cases = [
            ("<mujoco><worldbody></mujoco>", "1:", "malformed XML"),
            ("<robot/>", "1:1:", "expected a `<mujoco>` element"),
            ("<mujoco/>", "1:1:", "has no `<worldbody>`"),
            ("<mujoco><worldbody/></mujoco>", "1:9:", "has no `<body>`"),
            (&one_body("<joint type=\"cylinder\"/>", ""), "5:8:", "has type `cylinder`; expected `hinge`"),
            (&one_body("<joint/><joint name=\"k\"/>", ""), "5:9:", "has a second joint"),
            (&one_body(&format!("{hinge}<body><geom size=\"1\"/></body>"), ""), "5:18:", "inertia from geoms"),
            (&one_body("<joint type=\"ball\" stiffness=\"10\"/>", ""), "5:20:", "MuJoCo springs its quaternion"),
            (&one_body("<joint stiffness=\"-1\"/>", ""), "5:8:", "negative `stiffness`"),
            (&one_body("<joint springdamper=\"0.1 1\"/>", ""), "5:8:", "MuJoCo sets the joint's stiffness and damping"),
            (
                &one_body("<joint actuatorgravcomp=\"true\"/>", ""),
                "5:8:",
                "MuJoCo moves this joint's gravity compensation into its actuator force",
            ),
            (
                &one_body(hinge, "").replace("name=\"arm\"", "name=\"arm\" gravcomp=\"1\"").replace(
                    "</body>",
                    "<body name=\"w\" gravcomp=\"0.5\"><inertial pos=\"0 0 0\" mass=\"1\" diaginertia=\"1 1 1\"/></body></body>",
                ),
                "6:1:",
                "welded into one body with different `gravcomp`s",
            ),
            (
                &one_body(hinge, "<compiler settotalmass=\"5\"/>")
                    .replace("<worldbody>", "<worldbody><body name=\"g\"><geom size=\"1\"/></body>"),
                "8:11:",
                "body `g`'s comes from its geoms",
            ),
            (&one_body(hinge, "<compiler balanceinertia=\"true\"/>"), "8:11:", "MuJoCo changes the inertias"),
            (&one_body(hinge, "<option density=\"1.2\"/>"), "8:9:", "MuJoCo applies fluid forces (from `density` and `viscosity`)"),
            (&one_body(hinge, "<option viscosity=\"0.1\"/>"), "8:9:", "MuJoCo applies fluid forces"),
            (&one_body(hinge, "<option><flag damper=\"disable\"/></option>"), "8:15:", "MuJoCo leaves out joint damping"),
            (
                &one_body("<joint type=\"free\"/>", "<default><joint damping=\"1\"/></default>"),
                "8:17:",
                "is `type=\"free\"` and has `damping` (its own or its class's): MuJoCo applies it",
            ),
            ("<mujoco>\n<worldbody>\n<body name=\"a\">", "3:16:", "the file ends here, cut short"),
            (
                &one_body(&format!("{hinge}{}", second.replace("hand", "arm")), ""),
                "5:18:",
                "body `arm` is declared twice",
            ),
            (&one_body("<joint class=\"big\"/>", ""), "5:8:", "`class=\"big\"` names no `<default class=\"big\">`"),
            (&one_body(hinge, "<include file=\"more.xml\"/>"), "8:1:", "`<include>` is not read"),
            (
                &one_body(&format!("{hinge}{}", second.replace("<joint/>", "<freejoint/>")), ""),
                "5:88:",
                "free on a body of a body",
            ),
            (
                &one_body(hinge, "").replace("name=\"arm\"", "name=\"arm\" quat=\"1 0 0 0\" euler=\"0 0 1\""),
                "3:33:",
                "`quat` and `euler` both",
            ),
            (&one_body(hinge, "").replace("name=\"arm\"", "name=\"arm\" quat=\"0 0 0 0\""), "3:18:", "degenerate"),
            (&one_body(hinge, "").replace("mass=\"1\"", "mass=\"0\""), "4:23:", "link `arm` moves but has mass 0"),
            (&one_body(hinge, "").replace("mass=\"1\" ", ""), "4:1:", "has no `mass`"),
            (
                &one_body(hinge, "").replace("diaginertia=\"1 1 1\"", "quat=\"1 0 0 0\" fullinertia=\"1 1 1 0 0 0\""),
                "4:47:",
                "`fullinertia` and an orientation",
            ),
            (
                &one_body(hinge, "").replace("diaginertia=\"1 1 1\"", "diaginertia=\"1 1 3\""),
                "4:32:",
                "expected a real body's inertia",
            ),
            (&one_body(hinge, "").replace("name=\"arm\"", "name=\"arm\" mocap=\"true\""), "3:18:", "mocap body"),
            (&one_body("<joint range=\"1\"/>", ""), "5:8:", "`range=\"1\"`: expected two numbers"),
            (&one_body(hinge, "<option integrator=\"RK45\"/>"), "8:9:", "expected `Euler`, `RK4`, `implicit`"),
            (&one_body(hinge, "<option timestep=\"0\"/>"), "8:9:", "expected a positive number"),
            (&one_body("<joint type=\"ball\" damping=\"15 5\"/>", ""), "5:20:", "as a polynomial"),
            (&one_body("<joint axis=\"0 0 0\"/>", ""), "5:8:", "the joint of body `arm` has a zero axis"),
        ];
        for (text, at, expected) in cases {
            let message = error(text);
            assert!(message.starts_with(at) && message.contains(expected), "{text}\n{message}");
        }
    }

    #[test]
    fn bad_equalities_one_message_each_at_line_and_column() {
        let hinge = "<joint name=\"j\"/>";
        let second = "<body name=\"hand\"><inertial pos=\"0 0 0\" mass=\"1\" diaginertia=\"1 1 1\"/><joint/></body>";
        let cases = [
            (&one_body(hinge, "<equality><connect body1=\"arm\"/></equality>"), "8:11:", "has no `anchor`"),
            (
                &one_body(hinge, "<equality><connect body1=\"leg\" anchor=\"0 0 0\"/></equality>"),
                "8:20:",
                "`body1=\"leg\"` is not a body",
            ),
            (&one_body(hinge, "<equality><joint joint1=\"j\"/></equality>"), "8:11:", "without `joint2`"),
            (
                &one_body(hinge, "<equality><weld body1=\"arm\" body2=\"arm\"/></equality>"),
                "8:11:",
                "joins a body to itself",
            ),
            (
                &one_body(
                    &format!("{hinge}{second}"),
                    "<equality><weld body1=\"arm\" body2=\"hand\" relpose=\"0 0 0 1 0 0 0\"/></equality>",
                ),
                "8:42:",
                "`relpose` is not read yet",
            ),
        ];
        for (text, at, expected) in cases {
            let message = error(text);
            assert!(message.starts_with(at) && message.contains(expected), "{text}\n{message}");
        }
    }

    /// MuJoCo makes every equality soft, and so does the reader: its
    /// defaults where the file states nothing, a class's numbers under the
    /// element's (fewer than five fill the first ones), time constants
    /// raised to twice the step unless `refsafe` is off; ideal rows where
    /// the scene asks (`hard`); `mimic = independent` leaves `<equality
    /// joint>`s out; a weld's `torquescale` is read; a `<flag equality>` or
    /// `<flag constraint>` switched off leaves them all out, as in MuJoCo.
    #[test]
    fn equalities_are_soft_as_in_mujoco() {
        let second =
            "<body name=\"hand\"><inertial pos=\"0 0 0\" mass=\"1\" diaginertia=\"1 1 1\"/><joint name=\"k\"/></body>";
        let coupled = one_body(
            &format!("<joint name=\"j\"/>{second}"),
            "<equality><joint joint1=\"k\" joint2=\"j\"/></equality>",
        );
        let span = proc_macro2::Span::call_site();
        let soft = |text: &str, asked| {
            from_text(text, "f.xml", span, asked)
                .map(|r| r.couplings.first().and_then(|c| c.soft).map(|s| (s.solref, s.solimp)))
        };
        let defaults = Some(([0.02, 1.0], [0.9, 0.95, 0.001, 0.5, 2.0]));
        assert_eq!(soft(&coupled, (false, false)).ok(), Some(defaults));
        assert_eq!(soft(&coupled, (true, false)).ok(), Some(None));
        let quick = coupled.replace("/></equality>", " solref=\"0.001 1\"/></equality>");
        let stepped =
            |flags: &str| quick.replace("</mujoco>", &format!("<option timestep=\"0.004\">{flags}</option></mujoco>"));
        assert_eq!(soft(&stepped(""), (false, false)).ok().flatten().map(|s| s.0), Some([0.008, 1.0]));
        let unsafe_ = stepped("<flag refsafe=\"disable\"/>");
        assert_eq!(soft(&unsafe_, (false, false)).ok().flatten().map(|s| s.0), Some([0.001, 1.0]));
        let classed = coupled
            .replace("/></equality>", " solimp=\"0.95 0.99 0.001\"/></equality>")
            .replace("<worldbody>", "<default><equality solimp=\"0.8 0.9 0.01 0.3 3\"/></default><worldbody>");
        assert_eq!(soft(&classed, (false, false)).ok().flatten().map(|s| s.1), Some([0.95, 0.99, 0.001, 0.3, 3.0]));
        let read =
            |text: &str, asked| from_text(text, "f.xml", span, asked).map(|r| (r.closures.len(), r.couplings.len()));
        assert_eq!(read(&coupled, (false, true)).ok(), Some((0, 0)));
        let welded = one_body(
            &format!("<joint name=\"j\"/>{second}"),
            "<equality><weld body1=\"arm\" body2=\"hand\"/></equality>",
        );
        assert_eq!(read(&welded, (false, true)).ok(), Some((1, 0)));
        assert_eq!(read(&welded, (true, false)).ok(), Some((1, 0)));
        let torque = |text: &str| {
            from_text(text, "f.xml", span, (false, false))
                .map(|r| r.closures.first().and_then(|c| c.soft).map(|s| s.0.torquescale))
        };
        assert_eq!(torque(&welded).ok(), Some(Some(1.0)));
        let halved = welded.replace("/></equality>", " torquescale=\"0.5\"/></equality>");
        assert_eq!(torque(&halved).ok(), Some(Some(0.5)));
        for off in ["equality", "constraint"] {
            let flag = format!("<option><flag {off}=\"disable\"/></option>");
            assert_eq!(
                read(&welded.replace("</mujoco>", &format!("{flag}</mujoco>")), (false, false)).ok(),
                Some((0, 0))
            );
        }
    }

    /// A soft equality's numbers: each mistake at its attribute.
    #[test]
    fn bad_softness_one_message_each_at_line_and_column() {
        let second =
            "<body name=\"hand\"><inertial pos=\"0 0 0\" mass=\"1\" diaginertia=\"1 1 1\"/><joint name=\"k\"/></body>";
        let with = |attributes: &str| {
            one_body(
                &format!("<joint name=\"j\"/>{second}"),
                &format!("<equality><joint joint1=\"k\" joint2=\"j\" {attributes}/></equality>"),
            )
        };
        let span = proc_macro2::Span::call_site();
        let error = |text: &str| {
            from_text(text, "f.xml", span, (false, false)).err().map(|e| e.to_string()).unwrap_or_default()
        };
        let cases = [
            (with("solref=\"0.02 -1\""), "8:40:", "mixes MuJoCo's two forms"),
            (with("solimp=\"0.9 0.95 0.001 0.5 2 1\""), "8:40:", "expected one to 5 numbers"),
            (with("solref=\"fast\""), "8:40:", "expected one to 2 numbers"),
        ];
        for (text, at, expected) in cases {
            let message = error(&text);
            assert!(message.starts_with(&format!("f.xml:{at}")) && message.contains(expected), "{text}\n{message}");
        }
    }

    #[test]
    fn neutral_attributes_and_ground_geoms_are_no_error() {
        let hinge = "<joint name=\"j\"/>";
        // What leaves the dynamics as they are is no error.
        for neutral in [
            one_body(hinge, "").replace("name=\"arm\"", "name=\"arm\" gravcomp=\"0\""),
            one_body(hinge, "<compiler settotalmass=\"-1\"/><option density=\"0\" wind=\"0 1 0\"/>"),
            // Fluid forces need `density` or `viscosity`: MuJoCo computes none without.
            one_body(&format!("{hinge}<geom size=\"0.1\" fluidshape=\"ellipsoid\"/>"), ""),
            one_body(hinge, "<option><flag damper=\"enable\" gravity=\"enable\"/></option>"),
            one_body("<joint stiffness=\"0\" springdamper=\"0 0\"/>", ""),
        ] {
            assert!(from_text(&neutral, "f.xml", proc_macro2::Span::call_site(), HARD).is_ok(), "{neutral}");
        }
        // A body with geoms and no `<inertial>` on the ground is no error:
        // its mass would not move.
        let mount =
            one_body(hinge, "").replace("<worldbody>", "<worldbody><body name=\"mount\"><geom size=\"1\"/></body>");
        assert!(from_text(&mount, "f.xml", proc_macro2::Span::call_site(), HARD).is_ok());
        let missing = read(&syn::LitStr::new("/no/such/robot.xml", proc_macro2::Span::call_site()), HARD);
        assert!(missing.err().is_some_and(|e| e.to_string().starts_with("cannot read `/no/such/robot.xml`")));
    }

    /// A body's rotation as the reader gives it, its attributes `attr`.
    fn turn(compiler: &str, attr: &str) -> M3 {
        let text = format!(
            "<mujoco><compiler {compiler}/><worldbody><site name=\"s\" {attr}/>\
             <body><inertial pos=\"0 0 0\" mass=\"1\" diaginertia=\"1 1 1\"/><joint/></body></worldbody></mujoco>"
        );
        let robot = from_text(&text, "f.xml", proc_macro2::Span::call_site(), HARD).unwrap();
        robot.links.iter().find(|l| l.name == "s").unwrap().rotation
    }

    /// Each orientation against MuJoCo 4.0's compiled `body_quat` (as a
    /// matrix, 8 digits) for the same attribute.
    #[test]
    fn orientations_as_mujoco_compiles_them() {
        let cases: [(&str, &str, M3); 8] = [
            ("", "euler=\"90 90 0\"", [[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]),
            ("eulerseq=\"XYZ\"", "euler=\"90 90 0\"", [[0.0, 1.0, 0.0], [0.0, 0.0, -1.0], [-1.0, 0.0, 0.0]]),
            (
                "eulerseq=\"zyx\"",
                "euler=\"30 20 10\"",
                [
                    [0.81379768, -0.44096961, 0.37852231],
                    [0.46984631, 0.88256412, 0.01802831],
                    [-0.34202014, 0.16317591, 0.92541658],
                ],
            ),
            (
                "",
                "xyaxes=\"0 1 0 -1 0 0.5\"",
                [[0.0, -0.89442719, 0.4472136], [1.0, 0.0, 0.0], [0.0, 0.4472136, 0.89442719]],
            ),
            ("", "zaxis=\"1 0 0\"", [[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]]),
            ("", "zaxis=\"0 0 -1\"", [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]]),
            (
                "",
                "zaxis=\"1 1 1\"",
                [
                    [0.78867513, -0.21132487, 0.57735027],
                    [-0.21132487, 0.78867513, 0.57735027],
                    [-0.57735027, -0.57735027, 0.57735027],
                ],
            ),
            (
                "",
                "axisangle=\"1 1 0 120\"",
                [[0.25, 0.75, 0.61237244], [0.75, 0.25, -0.61237244], [-0.61237244, 0.61237244, -0.5]],
            ),
        ];
        for (compiler, attr, expected) in cases {
            let r = turn(compiler, attr);
            let worst = (0..9).map(|i| (r[i / 3][i % 3] - expected[i / 3][i % 3]).abs()).fold(0.0, f64::max);
            assert!(worst < 1e-8, "{compiler} {attr}: {r:?}");
        }
        // Radians when the compiler says so; a quaternion as given.
        let quarter = turn("angle=\"radian\"", "axisangle=\"0 0 1 1.5707963267948966\"");
        let same = turn("", "quat=\"0.7071067811865476 0 0 0.7071067811865476\"");
        assert!((0..9).all(|i| (quarter[i / 3][i % 3] - same[i / 3][i % 3]).abs() < 1e-15 && (same[1][0] - 1.0).abs() < 1e-15));
    }

    /// The robots' files and the tests' own, cut short and with bytes
    /// changed: an error or a robot, never a panic.
    #[test]
    fn cut_and_mutated_files_never_panic() {
        let span = proc_macro2::Span::call_site();
        let files = ["double_pendulum", "ur5", "panda", "solo12_floating"].map(|r| format!("robots/{r}.xml"));
        let ours = ["ball_pendulum", "four_bar", "welded_pendulum"].map(|r| format!("mjcf/{r}.xml"));
        for path in files.iter().chain(&ours) {
            let text = test_file(path);
            assert!(from_text(&text, path, span, HARD).is_ok(), "{path}");
            for mutated in cut_and_mutated(&text, 300) {
                let _ = from_text(&mutated, path, span, HARD);
            }
        }
    }
}
