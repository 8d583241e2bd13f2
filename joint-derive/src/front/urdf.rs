//! `#[scene(urdf = "robot.urdf")]`: a robot's links and joints read from its
//! URDF file at compile time and put in the scene's terms by
//! [`assemble`](super::robot::assemble) (frames at the centres, world axes
//! at the zero configuration, fixed links welded into one body). The XML is
//! read by `roxmltree`, which gives every error its line and column in the
//! file.
//!
//! `<visual>` shapes are read for pictures (`visuals`); collisions,
//! transmissions and Gazebo tags are not read; a
//! `<mimic joint multiplier offset>` is a coupling (a row in relative
//! coordinates, unless the scene says `mimic = independent`).

use super::robot::{
    Fail, FileCoupling, FileLimits, IDENTITY, Joint, Kind, Library, Link, M3, Robot, V3, assemble, mul, number,
    required, transpose, triple,
};

/// Reads `path` (relative to the crate's `CARGO_MANIFEST_DIR`); every
/// error at the attribute, naming the file, line and column. With
/// `floating`, the root link (and the links fixed to it) is a body that
/// floats, not the ground.
pub fn read(path: &syn::LitStr, floating: bool) -> syn::Result<Robot> {
    let (text, full) = super::robot::read_text(path, "a URDF")?;
    let mut robot = from_text(&text, &super::robot::shown(&full), path.span(), floating)?;
    super::visuals::find_meshes(robot.links.iter_mut().flat_map(|l| &mut l.visuals), &full);
    // URDF states no gravity; robot people's tools (Pinocchio, MuJoCo, the
    // MJCF reader here) take 9.81 down `z`, and so does a URDF scene unless
    // it says `gravity = [..]`.
    Ok(Robot { path: full, gravity: Some([0.0, 0.0, -9.81]), ..robot })
}

/// The robot of a file's `text` (`shown` names it in errors, at `span`).
fn from_text(text: &str, shown: &str, span: proc_macro2::Span, floating: bool) -> syn::Result<Robot> {
    let fail = |at: roxmltree::TextPos, message: String| {
        syn::Error::new(span, format!("{shown}:{}:{}: {message}", at.row, at.col))
    };
    let doc = super::robot::parse_xml(text, &fail)?;
    let (links, joints) = elements(&doc, &fail)?;
    if links.is_empty() {
        let at = doc.text_pos_at(doc.root_element().range().start);
        return Err(fail(at, "the robot has no `<link>`; expected its links and joints".into()));
    }
    let robot = assemble(&links, &joints, &[], (floating, Library::Pinocchio), &fail)?;
    Ok(Robot { couplings: mimics(&doc, &joints, &fail)?, ..robot })
}

/// Each `<mimic>`: its joint follows the named one, both moving joints.
fn mimics(doc: &roxmltree::Document, joints: &[Joint], fail: &Fail) -> syn::Result<Vec<FileCoupling>> {
    let mut out = Vec::new();
    for node in doc.root_element().children().filter(|n| n.has_tag_name("joint")) {
        let Some(m) = node.children().find(|n| n.has_tag_name("mimic")) else { continue };
        let at = doc.text_pos_at(m.range().start);
        let follower = node.attribute("name").unwrap_or("").to_string();
        let leader = required(m, "joint", at, fail)?;
        let moving =
            |name: &str| joints.iter().any(|j| j.name == name && matches!(j.kind, Kind::Revolute | Kind::Prismatic));
        if !moving(&leader) || !moving(&follower) {
            return Err(fail(
                at,
                format!(
                    "`<mimic joint=\"{leader}\">` of joint `{follower}`: expected both to be moving joints of the file"
                ),
            ));
        }
        let optional = |key: &str, default: f64| match m.attribute(key) {
            Some(_) => number(m, key, at, fail),
            None => Ok(default),
        };
        out.push(FileCoupling {
            follower,
            leader,
            multiplier: optional("multiplier", 1.0)?,
            offset: optional("offset", 0.0)?,
            soft: None,
        });
    }
    Ok(out)
}

/// The `<link>` and `<joint>` elements, checked one by one.
fn elements(doc: &roxmltree::Document, fail: &Fail) -> syn::Result<(Vec<Link>, Vec<Joint>)> {
    let robot = doc.root_element();
    let pos = |n: roxmltree::Node| doc.text_pos_at(n.range().start);
    if robot.tag_name().name() != "robot" {
        return Err(fail(pos(robot), format!("expected a `<robot>` element, found `<{}>`", robot.tag_name().name())));
    }
    let mut materials = Vec::new();
    for m in robot.children().filter(|n| n.has_tag_name("material")) {
        if let (Some(name), Some(rgba)) = (m.attribute("name"), super::visuals::urdf_colour(m, &pos, fail)?) {
            materials.push((name.to_string(), rgba));
        }
    }
    let mut links: Vec<Link> = Vec::new();
    for node in robot.children().filter(|n| n.has_tag_name("link")) {
        let name = required(node, "name", pos(node), fail)?;
        if links.iter().any(|l| l.name == name) {
            return Err(fail(pos(node), format!("link `{name}` is declared twice; expected unique link names")));
        }
        let (inertial, inertial_at) = match node.children().find(|n| n.has_tag_name("inertial")) {
            Some(i) => {
                let at = |tag| i.children().find(|n| n.has_tag_name(tag)).map_or(pos(i), pos);
                (Some(inertial(i, &name, &pos, fail)?), [at("mass"), at("inertia")])
            }
            None => (None, [pos(node); 2]),
        };
        let visuals = link_visuals(node, &materials, &pos, fail)?;
        links.push(Link { name, inertial, unknown: false, gravcomp: 0.0, visuals, at: pos(node), inertial_at });
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
        let written = required(node, "type", at, fail)?;
        let kind = match written.as_str() {
            "revolute" | "continuous" => Kind::Revolute,
            "prismatic" => Kind::Prismatic,
            "fixed" => Kind::Fixed,
            "floating" => Kind::Floating,
            kind => {
                // What Pinocchio's reader makes of it, so the user knows what is missing.
                let theirs = match kind {
                    "planar" => {
                        ": Pinocchio reads it as a planar joint (moves in x, y and turns about z), which is \
                                 not read here"
                    }
                    _ => ", which neither Pinocchio nor this reader knows",
                };
                let at = super::robot::attribute_at(node, "type").unwrap_or(at);
                return Err(fail(
                    at,
                    format!(
                        "joint `{name}` has type `{kind}`{theirs}; expected `revolute`, `continuous`, `prismatic`, \
                         `fixed` or `floating`"
                    ),
                ));
            }
        };
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
        let (axis, axis_at) = match node.children().find(|n| n.has_tag_name("axis")) {
            Some(a) => (triple(a, "xyz", pos(a), fail)?.unwrap_or([1.0, 0.0, 0.0]), pos(a)),
            None => ([1.0, 0.0, 0.0], at),
        };
        let limits = limits(node, &pos, fail)?;
        let continuous = written == "continuous";
        let point = [0.0; 3];
        joints.push(Joint { name, kind, parent, child, origin, point, axis, limits, continuous, at, axis_at });
    }
    Ok((links, joints))
}

/// A link's `<visual>`s, each in the link's frame (`materials`: the file's
/// named colours).
fn link_visuals(
    link: roxmltree::Node,
    materials: &[(String, [f64; 4])],
    pos: &dyn Fn(roxmltree::Node) -> roxmltree::TextPos,
    fail: &Fail,
) -> syn::Result<Vec<super::visuals::FileVisual>> {
    let mut out = Vec::new();
    for v in link.children().filter(|n| n.has_tag_name("visual")) {
        let at = match v.children().find(|n| n.has_tag_name("origin")) {
            Some(o) => origin(o, pos(o), fail)?,
            None => (IDENTITY, [0.0; 3]),
        };
        out.extend(super::visuals::urdf(v, at, materials, pos, fail)?);
    }
    Ok(out)
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
        armature: None,
        spring: Default::default(),
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

#[cfg(test)]
mod tests {
    use super::super::geometry::eigenvalues;
    use super::super::robot::apply;
    use super::super::robot::tests::{cut_and_mutated, test_file};
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
            (&two_links(&hinge("spherical"), MASS), "4:17:", "has type `spherical`, which neither Pinocchio"),
            (&two_links(&hinge("planar"), MASS), "4:17:", "Pinocchio reads it as a planar joint"),
            (&two_links(&hinge("revolute"), ""), "3:1:", "link `arm` moves but has mass 0"),
            (
                &two_links(&hinge("revolute"), &MASS.replace(r#"izz="1""#, r#"izz="100""#)),
                "3:45:",
                "principal moments [1.0, 1.0, 100.0]; expected a real body's inertia",
            ),
            (
                &two_links(&hinge("revolute"), &MASS.replace(r#"ixy="0""#, r#"ixy="2""#)),
                "3:45:",
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
                "4:54:",
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
        let span = proc_macro2::Span::call_site();
        for robot in ["double_pendulum", "ur5", "panda", "solo12"] {
            let text = test_file(&format!("robots/{robot}.urdf"));
            assert!(from_text(&text, robot, span, false).is_ok() && from_text(&text, robot, span, true).is_ok());
            for (k, mutated) in cut_and_mutated(&text, 300).iter().enumerate() {
                let _ = from_text(mutated, robot, span, k % 2 == 0);
            }
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
        let robot = assemble(&links, &joints, &[], (false, Library::Pinocchio), &fail).unwrap();
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

    #[test]
    fn visuals_with_their_origins_and_colours() {
        use super::super::visuals::FileShape;
        let text = r#"<robot name="r">
          <material name="steel"><color rgba="0.5 0.5 0.6 1"/></material>
          <link name="base">
            <visual><origin xyz="0 0 0.1" rpy="0 0 1.5707963267948966"/><geometry><box size="0.2 0.4 0.6"/></geometry>
              <material name="steel"/></visual>
            <visual><geometry><cylinder radius="0.1" length="0.5"/></geometry>
              <material name="own"><color rgba="1 0 0 1"/></material></visual>
            <visual><geometry><sphere radius="0.3"/></geometry></visual>
            <visual><geometry><mesh filename="m.stl" scale="2 2 2"/></geometry></visual>
            <visual><geometry><plane/></geometry></visual>
          </link></robot>"#;
        let robot = from_text(text, "r.urdf", proc_macro2::Span::call_site(), false).unwrap();
        let v = &robot.links[0].visuals;
        assert_eq!(v.len(), 4, "a geometry not read is not drawn");
        assert_eq!((&v[0].shape, v[0].rgba), (&FileShape::Box([0.1, 0.2, 0.3]), Some([0.5, 0.5, 0.6, 1.0])));
        assert_eq!(v[0].pose.1, [0.0, 0.0, 0.1]);
        assert!((apply(&v[0].pose.0, &[1.0, 0.0, 0.0])[1] - 1.0).abs() < 1e-15, "the yaw turns x to y");
        assert_eq!((&v[1].shape, v[1].rgba), (&FileShape::Cylinder(0.1, 0.25), Some([1.0, 0.0, 0.0, 1.0])));
        assert_eq!((&v[2].shape, v[2].rgba), (&FileShape::Sphere(0.3), None));
        assert_eq!(v[3].shape, FileShape::Mesh { file: "m.stl".into(), scale: [2.0; 3] });
        let bad = text.replace("radius=\"0.3\"", "radius=\"big\"");
        let message = from_text(&bad, "r.urdf", proc_macro2::Span::call_site(), false).err().unwrap().to_string();
        assert!(message.contains("r.urdf:8:") && message.contains("`radius=\"big\"`: expected a number"), "{message}");
    }

    fn origin_of(rpy: &str) -> (M3, V3) {
        let text = format!("<origin rpy=\"{rpy}\"/>");
        let doc = roxmltree::Document::parse(&text).unwrap();
        let fail = |_: roxmltree::TextPos, m: String| syn::Error::new(proc_macro2::Span::call_site(), m);
        origin(doc.root_element(), roxmltree::TextPos::new(1, 1), &fail).unwrap()
    }
}
