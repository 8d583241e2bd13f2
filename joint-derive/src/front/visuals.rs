//! What a robot's file says its links look like: URDF `<visual>` and MJCF
//! `<geom>`, read into [`FileVisual`]s in the link's frame, and their mesh
//! files looked up on disk at compile time. Data for pictures only (the
//! runtime's `robot::Visual`): the dynamics never read it, so a shape this
//! reader does not know (a URDF `<geometry>` it has no word for, an MJCF
//! `hfield` or `sdf`) is drawn as nothing rather than refused; numbers that
//! do not parse are still errors at their line and column, as everywhere in
//! the file.

#[cfg(feature = "mjcf")]
use std::collections::HashMap;
use std::path::{Path, PathBuf};

pub use super::files::{FileShape, FileVisual};
use super::robot::{Fail, numbers, triple};
#[cfg(feature = "mjcf")]
use super::robot::{M3, V3};
#[cfg(feature = "urdf")]
use super::robot::{Pose, number};
#[cfg(test)]
use super::robot::{apply, mul};

/// A URDF `<visual>`: `origin` is its `<origin>` read; `materials` the
/// file's named `<material>` colours. `None` for a geometry without a shape
/// read here.
#[cfg(feature = "urdf")]
pub fn urdf(
    node: roxmltree::Node,
    origin: Pose,
    materials: &[(String, [f64; 4])],
    pos: &dyn Fn(roxmltree::Node) -> roxmltree::TextPos,
    fail: &Fail,
) -> syn::Result<Option<FileVisual>> {
    let Some(geometry) = node.children().find(|n| n.has_tag_name("geometry")) else { return Ok(None) };
    let Some(g) = geometry.children().find(|n| n.is_element()) else { return Ok(None) };
    let at = pos(g);
    let shape = match g.tag_name().name() {
        "box" => FileShape::Box(triple(g, "size", at, fail)?.unwrap_or([0.0; 3]).map(|x| 0.5 * x)),
        "sphere" => FileShape::Sphere(number(g, "radius", at, fail)?),
        "cylinder" => FileShape::Cylinder(number(g, "radius", at, fail)?, 0.5 * number(g, "length", at, fail)?),
        "capsule" => FileShape::Capsule(number(g, "radius", at, fail)?, 0.5 * number(g, "length", at, fail)?),
        "mesh" => FileShape::Mesh {
            file: super::robot::required(g, "filename", at, fail)?,
            scale: triple(g, "scale", at, fail)?.unwrap_or([1.0; 3]),
        },
        _ => return Ok(None),
    };
    let rgba = match node.children().find(|n| n.has_tag_name("material")) {
        Some(m) => match urdf_colour(m, pos, fail)? {
            Some(c) => Some(c),
            None => m.attribute("name").and_then(|name| materials.iter().find(|(n, _)| n == name)).map(|(_, c)| *c),
        },
        None => None,
    };
    Ok(Some(FileVisual { pose: origin, shape, rgba }))
}

/// A URDF `<material>`'s own `<color rgba>`, if it has one.
#[cfg(feature = "urdf")]
pub fn urdf_colour(
    material: roxmltree::Node,
    pos: &dyn Fn(roxmltree::Node) -> roxmltree::TextPos,
    fail: &Fail,
) -> syn::Result<Option<[f64; 4]>> {
    match material.children().find(|n| n.has_tag_name("color")) {
        Some(c) => numbers::<4>(c, "rgba", pos(c), fail),
        None => Ok(None),
    }
}

/// An MJCF `<geom>`'s shape from its `type` and `size` (`fromto`'s length
/// where given: `length`); `mesh` is its mesh asset's file and scale.
#[cfg(feature = "mjcf")]
pub fn mjcf_shape(
    kind: &str,
    size: &[f64],
    length: Option<f64>,
    mesh: Option<(String, V3)>,
) -> Result<Option<FileShape>, String> {
    let at = |i: usize| size.get(i).copied().unwrap_or(0.0);
    let half = |i: usize| length.map_or(at(i), |l| 0.5 * l);
    Ok(Some(match kind {
        "sphere" => FileShape::Sphere(at(0)),
        "capsule" => FileShape::Capsule(at(0), half(1)),
        "cylinder" => FileShape::Cylinder(at(0), half(1)),
        "ellipsoid" => FileShape::Ellipsoid([at(0), at(1), at(2)]),
        "box" => FileShape::Box([at(0), at(1), half(2)]),
        "plane" => FileShape::Plane([at(0), at(1)]),
        "mesh" => match mesh {
            Some((file, scale)) => FileShape::Mesh { file, scale },
            None => return Err("a `mesh` geom without `mesh=\"..\"`; expected the name of an `<asset><mesh>`".into()),
        },
        "hfield" | "sdf" => return Ok(None),
        other => {
            return Err(format!(
                "geom type `{other}`; expected `plane`, `sphere`, `capsule`, `ellipsoid`, `cylinder`, `box` or `mesh`"
            ));
        }
    }))
}

#[cfg(feature = "mjcf")]
/// An MJCF file's geom classes and the meshes and materials of its
/// `<asset>`s, by name.
pub struct Looks {
    /// Each `<default>` class's geom attributes, its parents' included.
    pub defaults: HashMap<String, super::robot::Class>,
    /// Each `<mesh>`'s file (`<compiler meshdir>` in front) and scale.
    pub meshes: HashMap<String, (String, V3)>,
    /// Each `<material>`'s `rgba`.
    pub materials: HashMap<String, [f64; 4]>,
}

#[cfg(feature = "mjcf")]
impl Looks {
    /// The assets under the `<mujoco>` element `root`, with `defaults`.
    pub fn read(
        root: roxmltree::Node,
        defaults: HashMap<String, super::robot::Class>,
        pos: &dyn Fn(roxmltree::Node) -> roxmltree::TextPos,
        fail: &Fail,
    ) -> syn::Result<Self> {
        let compiler = root.children().filter(|n| n.has_tag_name("compiler"));
        let dir = compiler.filter_map(|c| c.attribute("meshdir").or(c.attribute("assetdir"))).next_back().unwrap_or("");
        let (mut meshes, mut materials) = (HashMap::new(), HashMap::new());
        for asset in root.children().filter(|n| n.has_tag_name("asset")) {
            for m in asset.children().filter(|n| n.has_tag_name("mesh")) {
                let Some(file) = m.attribute("file") else { continue };
                let stem = Path::new(file).file_stem().map(|s| s.to_string_lossy().into_owned());
                let name = m.attribute("name").map(str::to_string).or(stem).unwrap_or_default();
                let scale = triple(m, "scale", pos(m), fail)?.unwrap_or([1.0; 3]);
                let file =
                    if dir.is_empty() { file.to_string() } else { format!("{}/{file}", dir.trim_end_matches('/')) };
                meshes.insert(name, (file, scale));
            }
            for m in asset.children().filter(|n| n.has_tag_name("material")) {
                if let (Some(name), Some(rgba)) = (m.attribute("name"), numbers::<4>(m, "rgba", pos(m), fail)?) {
                    materials.insert(name.to_string(), rgba);
                }
            }
        }
        Ok(Looks { defaults, meshes, materials })
    }
}

/// The turn taking `z` to the direction of `d`, the shortest (MuJoCo's for
/// `zaxis` and `fromto`), by rows; `None` for a zero `d`.
#[cfg(feature = "mjcf")]
pub fn z_turn(d: V3) -> Option<M3> {
    let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    if l.is_nan() || l <= 0.0 || !l.is_finite() {
        return None;
    }
    let z = d.map(|x| x / l);
    let axis = [-z[1], z[0], 0.0];
    let s = (axis[0] * axis[0] + axis[1] * axis[1]).sqrt();
    if s < 1e-14 {
        return Some(if z[2] > 0.0 {
            super::robot::IDENTITY
        } else {
            [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]]
        });
    }
    let (u, angle) = ([axis[0] / s, axis[1] / s, 0.0], s.atan2(z[2]));
    // Rodrigues: I cos θ + sin θ [u]× + (1 − cos θ) u uᵀ.
    let (sn, c) = angle.sin_cos();
    let k = [[0.0, -u[2], u[1]], [u[2], 0.0, -u[0]], [-u[1], u[0], 0.0]];
    Some(std::array::from_fn(|i| {
        std::array::from_fn(|j| f64::from(u8::from(i == j)) * c + sn * k[i][j] + (1.0 - c) * u[i] * u[j])
    }))
}

/// Every mesh file of `visuals` looked up from the robot file at `robot`:
/// an absolute path where the file is found, the file's own name where not
/// (the picture then draws the body without it).
pub fn find_meshes<'v>(visuals: impl Iterator<Item = &'v mut FileVisual>, robot: &str) {
    let dir = Path::new(robot).parent().map(Path::to_path_buf).unwrap_or_default();
    for v in visuals {
        if let FileShape::Mesh { file, .. } = &mut v.shape
            && let Some(found) = find(file, &dir)
        {
            *file = found.display().to_string();
        }
    }
}

/// A mesh's `written` name (a path, `file://` or ROS's `package://NAME/REST`)
/// on disk: relative to the robot file's folder; a package's in
/// `ROS_PACKAGE_PATH`'s folders or beside the robot file or one of its
/// parent folders, as `NAME/REST` or as `REST` (a description that is its
/// own package).
fn find(written: &str, dir: &Path) -> Option<PathBuf> {
    let existing = |p: PathBuf| p.is_file().then(|| p.canonicalize().unwrap_or(p));
    if let Some(rest) = written.strip_prefix("package://") {
        let (package, inside) = rest.split_once('/')?;
        let ros = std::env::var("ROS_PACKAGE_PATH").unwrap_or_default();
        let roots = ros.split(':').filter(|p| !p.is_empty()).map(PathBuf::from);
        let roots = roots.chain(dir.ancestors().map(Path::to_path_buf));
        for root in roots {
            for candidate in [root.join(package).join(inside), root.join(inside)] {
                if let Some(found) = existing(candidate) {
                    return Some(found);
                }
            }
        }
        return None;
    }
    let path = Path::new(written.strip_prefix("file://").unwrap_or(written));
    existing(if path.is_absolute() { path.to_path_buf() } else { dir.join(path) })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn z_turn_takes_z_to_the_direction() {
        for d in [[1.0, 0.0, 0.0], [0.3, -0.4, 0.5], [0.0, 0.0, -2.0], [0.0, 0.0, 3.0], [-1e-9, 0.0, 1.0]] {
            let r = z_turn(d).unwrap();
            let z = apply(&r, &[0.0, 0.0, 1.0]);
            let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            for k in 0..3 {
                assert!((z[k] - d[k] / l).abs() < 1e-14, "{d:?} {z:?}");
            }
            let rt = super::super::robot::transpose(&r);
            let i = mul(&r, &rt);
            for (a, b) in i.iter().flatten().zip(super::super::robot::IDENTITY.iter().flatten()) {
                assert!((a - b).abs() < 1e-14);
            }
        }
        assert!(z_turn([0.0; 3]).is_none());
    }

    #[test]
    fn mjcf_sizes_as_mujoco_reads_them() {
        assert_eq!(mjcf_shape("capsule", &[0.1, 0.3], None, None), Ok(Some(FileShape::Capsule(0.1, 0.3))));
        assert_eq!(mjcf_shape("cylinder", &[0.1], Some(1.0), None), Ok(Some(FileShape::Cylinder(0.1, 0.5))));
        assert_eq!(mjcf_shape("box", &[0.1, 0.2, 0.3], None, None), Ok(Some(FileShape::Box([0.1, 0.2, 0.3]))));
        assert_eq!(mjcf_shape("hfield", &[], None, None), Ok(None));
        assert!(mjcf_shape("mesh", &[], None, None).unwrap_err().contains("`<asset><mesh>`"));
        assert!(mjcf_shape("cone", &[], None, None).unwrap_err().contains("geom type `cone`"));
    }

    #[test]
    fn packages_found_beside_the_robot_or_above_it() {
        let dir = std::env::temp_dir().join(format!("joint-visuals-{}", std::process::id()));
        let meshes = dir.join("pkg/meshes");
        std::fs::create_dir_all(&meshes).unwrap();
        std::fs::write(meshes.join("a.stl"), b"solid").unwrap();
        let robot = dir.join("pkg/robots/r.urdf");
        std::fs::create_dir_all(robot.parent().unwrap()).unwrap();
        let at = robot.parent().unwrap();
        assert!(find("package://pkg/meshes/a.stl", at).is_some_and(|p| p.ends_with("pkg/meshes/a.stl")));
        assert!(find("../meshes/a.stl", at).is_some());
        assert!(find("package://pkg/meshes/b.stl", at).is_none());
        assert!(find("package://nopackage", at).is_none());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
