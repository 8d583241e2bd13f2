//! Triangle meshes for a 3D run: the primitives a robot file names (box,
//! sphere, cylinder, capsule, ellipsoid, plane) tessellated, mesh files
//! (STL, OBJ, Collada) read by `mesh-loader` (feature `meshes`), and the stand-in a body gets
//! when its file draws nothing: a capsule along its joint points whose
//! radius gives it its mass at the density of water.

use std::collections::BTreeMap;
use std::f64::consts::PI;
use std::sync::{Arc, Mutex};

use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};

use crate::robot::Shape;

/// One glTF primitive: triangles (with normals) or lines, in its node's
/// frame, and its colour.
#[derive(Clone, Debug, Default)]
pub(super) struct Mesh {
    pub positions: Vec<[f32; 3]>,
    /// One per position; empty for lines and mesh files (shaded flat).
    pub normals: Vec<[f32; 3]>,
    pub indices: Vec<u32>,
    pub lines: bool,
    pub rgba: [f32; 4],
}

/// Segments around a circle: smooth at a viewer's distance, small in a file.
const AROUND: usize = 24;
/// Rings from pole to pole.
const RINGS: usize = 12;
/// The stand-in's density (kg/m³): water's, MuJoCo's default.
pub(super) const DENSITY: f64 = 1000.0;

impl Mesh {
    fn vertex(&mut self, p: [f64; 3], n: [f64; 3]) -> u32 {
        let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt().max(1e-300);
        self.positions.push(p.map(|x| x as f32));
        self.normals.push(n.map(|x| (x / l) as f32));
        u32::try_from(self.positions.len() - 1).unwrap_or(u32::MAX)
    }
    fn quad(&mut self, [a, b, c, d]: [u32; 4]) {
        self.indices.extend([a, b, c, a, c, d]);
    }
}

/// A primitive `shape` as triangles (`None` for a mesh file: [`load`]).
pub(super) fn primitive(shape: &Shape, rgba: [f32; 4]) -> Option<Mesh> {
    let mut m = Mesh { rgba, ..Mesh::default() };
    match *shape {
        Shape::Box(h) => cuboid(&mut m, h),
        Shape::Sphere(r) => ellipsoid(&mut m, [r; 3], 0.0),
        Shape::Ellipsoid(a) => ellipsoid(&mut m, a, 0.0),
        Shape::Capsule(r, h) => ellipsoid(&mut m, [r; 3], h),
        Shape::Cylinder(r, h) => cylinder(&mut m, r, h),
        Shape::Plane([x, y]) => {
            // MJCF's zero size is an infinite plane: a finite one here.
            let [x, y] = [x, y].map(|s| if s > 0.0 { s } else { 2.0 });
            cuboid(&mut m, [x, y, 1e-4]);
        }
        Shape::Mesh { .. } => return None,
    }
    Some(m)
}

/// A box of half sizes `h`, flat faces.
fn cuboid(m: &mut Mesh, h: [f64; 3]) {
    for axis in 0..3 {
        for sign in [1.0, -1.0] {
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            let mut n = [0.0; 3];
            n[axis] = sign;
            let corner = |a: f64, b: f64| {
                let mut p = [0.0; 3];
                p[axis] = sign * h[axis];
                p[u] = a * h[u];
                p[v] = b * h[v] * sign;
                p
            };
            let q = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)].map(|(a, b)| m.vertex(corner(a, b), n));
            m.quad(q);
        }
    }
}

/// An ellipsoid of semi-axes `a`, its halves moved `±h` along `z`: a
/// sphere, an ellipsoid, or (with `h > 0`) a capsule, whose cylinder is the
/// band between the two equators.
fn ellipsoid(m: &mut Mesh, a: [f64; 3], h: f64) {
    let start = m.positions.len();
    let mut rings = 0;
    // The upper half from its pole to its equator, moved up `h`; the lower
    // from its equator (again only for a capsule: the cylinder's band) down.
    let step = PI / RINGS as f64;
    let lower = usize::from(h <= 0.0);
    let upper = (0..=RINGS / 2).map(|i| (PI / 2.0 - i as f64 * step, h));
    let lower = (lower..=RINGS / 2).map(|i| (-(i as f64) * step, -h));
    for (lat, shift) in upper.chain(lower) {
        let (sz, cz) = lat.sin_cos();
        for j in 0..=AROUND {
            let (sy, cy) = (2.0 * PI * j as f64 / AROUND as f64).sin_cos();
            let unit = [cz * cy, cz * sy, sz];
            let p = [a[0] * unit[0], a[1] * unit[1], a[2] * unit[2] + shift];
            m.vertex(p, [unit[0] / a[0], unit[1] / a[1], unit[2] / a[2]]);
        }
        rings += 1;
    }
    let row = AROUND + 1;
    let at = |r: usize, j: usize| u32::try_from(start + r * row + j).unwrap_or(u32::MAX);
    for r in 0..rings - 1 {
        for j in 0..AROUND {
            m.quad([at(r, j), at(r + 1, j), at(r + 1, j + 1), at(r, j + 1)]);
        }
    }
}

/// A cylinder of radius `r` along `z`, half length `h`, with its caps.
fn cylinder(m: &mut Mesh, r: f64, h: f64) {
    let ring = |j: usize| (2.0 * PI * j as f64 / AROUND as f64).sin_cos();
    for j in 0..AROUND {
        let ((s0, c0), (s1, c1)) = (ring(j), ring(j + 1));
        let q = [(c0, s0, -h), (c1, s1, -h), (c1, s1, h), (c0, s0, h)]
            .map(|(c, s, z)| m.vertex([r * c, r * s, z], [c, s, 0.0]));
        m.quad(q);
    }
    for z in [h, -h] {
        let centre = m.vertex([0.0, 0.0, z], [0.0, 0.0, z]);
        let rim: Vec<u32> = (0..=AROUND).map(ring).map(|(s, c)| m.vertex([r * c, r * s, z], [0.0, 0.0, z])).collect();
        for w in rim.windows(2) {
            let (a, b) = if z > 0.0 { (w[0], w[1]) } else { (w[1], w[0]) };
            m.indices.extend([centre, a, b]);
        }
    }
}

/// The radius of a capsule of cylinder length `length` that has `mass` at
/// [`DENSITY`]: the root of `ρ (π r² L + 4/3 π r³) = m` (a sphere's when
/// `L = 0`), by Newton from above (the function is convex and increasing).
pub(super) fn equivalent_radius(mass: f64, length: f64) -> f64 {
    let volume = (mass / DENSITY).max(0.0);
    let sphere = (3.0 * volume / (4.0 * PI)).cbrt();
    let f = |r: f64| PI * r * r * length + 4.0 / 3.0 * PI * r * r * r - volume;
    let df = |r: f64| 2.0 * PI * r * length + 4.0 * PI * r * r;
    // The sphere's radius is never below the root.
    let mut r = sphere;
    for _ in 0..60 {
        let d = df(r);
        if d.is_nan() || d <= 0.0 {
            break;
        }
        let next = r - f(r) / d;
        // Newton from above stops where it no longer comes down.
        if next.is_nan() || next >= r {
            break;
        }
        r = next;
    }
    r
}

/// The stand-in for a body that its file does not draw: a capsule from each
/// of its `points` (body frame) to the next (to its centre of mass from a
/// lone point, a sphere at the centre without any), their radius from the
/// body's `mass` (but not below `thinnest`), and a thinner one along each
/// of its `marks`. Each part with its pose in the body's frame.
pub(super) fn stand_in(
    points: &[Vector3<f64>],
    marks: &[(Vector3<f64>, Vector3<f64>)],
    (mass, thinnest): (f64, f64),
    rgba: [f32; 4],
) -> Vec<(Placement, Mesh)> {
    let mut path: Vec<Vector3<f64>> = Vec::new();
    for p in points {
        if path.last().is_none_or(|q: &Vector3<f64>| (q - p).norm() > 1e-9) {
            path.push(*p);
        }
    }
    if path.len() == 1 {
        path.insert(0, Vector3::zeros());
        if path[1].norm() <= 1e-9 {
            path.pop();
        }
    }
    let length: f64 = path.windows(2).map(|w| (w[1] - w[0]).norm()).sum();
    let r = equivalent_radius(mass, length).max(thinnest).max(1e-4);
    let capsule = |a: &Vector3<f64>, b: &Vector3<f64>, r: f64| {
        let d = b - a;
        let mut m = Mesh { rgba, ..Mesh::default() };
        ellipsoid(&mut m, [r; 3], 0.5 * d.norm());
        let turn = UnitQuaternion::rotation_between(&Vector3::z(), &d)
            .unwrap_or_else(|| UnitQuaternion::from_axis_angle(&Vector3::x_axis(), PI));
        (Placement { translation: 0.5 * (a + b), rotation: turn }, m)
    };
    let mut parts: Vec<(Placement, Mesh)> = path.windows(2).map(|w| capsule(&w[0], &w[1], r)).collect();
    if path.len() < 2 {
        let mut m = Mesh { rgba, ..Mesh::default() };
        ellipsoid(&mut m, [r; 3], 0.0);
        parts.push((Placement::at(path.first().copied().unwrap_or_else(Vector3::zeros)), m));
    }
    parts.extend(marks.iter().map(|(a, b)| capsule(a, b, 0.6 * r)));
    parts
}

/// A node's pose in its parent's frame.
#[derive(Clone, Copy, Debug)]
pub(super) struct Placement {
    pub translation: Vector3<f64>,
    pub rotation: UnitQuaternion<f64>,
}

impl Placement {
    pub fn at(translation: Vector3<f64>) -> Self {
        Placement { translation, rotation: UnitQuaternion::identity() }
    }
    /// From axes by columns and an origin, as `robot::Visual` holds them.
    pub fn of(columns: &[[f64; 3]; 3], origin: &[f64; 3]) -> Self {
        let [x, y, z] = columns.map(Vector3::from);
        let rotation = Rotation3::from_matrix(&Matrix3::from_columns(&[x, y, z]));
        Placement { translation: Vector3::from(*origin), rotation: UnitQuaternion::from_rotation_matrix(&rotation) }
    }
}

/// A mesh file's key in [`READ`]: path, scale and colour (their bits).
type Key = (String, [u64; 3], Option<[u32; 4]>);

/// Mesh files read in this process, each with its length and modification
/// time when read: a run written again (a controller's developer writing
/// each attempt) reads its meshes once, the Panda's 10.5 MB of Collada in
/// about 80 ms. A file that changed on disk is read again.
static READ: Mutex<BTreeMap<Key, Read>> = Mutex::new(BTreeMap::new());

/// A file as read: its stamp then, its meshes.
type Read = (Stamp, Arc<Vec<Mesh>>);

/// A file's length and modification time.
type Stamp = (u64, Option<std::time::SystemTime>);

/// [`load`], read once per process while the file stays the same.
pub(super) fn read(file: &str, scale: [f64; 3], rgba: Option<[f32; 4]>) -> Result<Arc<Vec<Mesh>>, String> {
    let meta = std::fs::metadata(file).map_err(|e| format!("{file}: {e}"))?;
    let stamp = (meta.len(), meta.modified().ok());
    let key = (file.to_string(), scale.map(f64::to_bits), rgba.map(|c| c.map(f32::to_bits)));
    // A panic elsewhere while holding the lock leaves the map as it was: still usable.
    let cached = READ.lock().unwrap_or_else(std::sync::PoisonError::into_inner).get(&key).cloned();
    if let Some((at, meshes)) = cached
        && at == stamp
    {
        return Ok(meshes);
    }
    let meshes = Arc::new(load(file, scale, rgba)?);
    READ.lock().unwrap_or_else(std::sync::PoisonError::into_inner).insert(key, (stamp, Arc::clone(&meshes)));
    Ok(meshes)
}

/// Without the `meshes` feature no mesh file is read: the body gets its
/// stand-in, and the run names the file among those it could not draw.
#[cfg(not(feature = "meshes"))]
fn load(file: &str, _: [f64; 3], _: Option<[f32; 4]>) -> Result<Vec<Mesh>, String> {
    Err(format!("{file}: mesh files are read with joint-runtime's `meshes` feature"))
}

/// A mesh file's triangles scaled by `scale`, one [`Mesh`] per material
/// (the file's colour, or `rgba` where the robot file gives one); the
/// reader's message where it cannot be read.
#[cfg(feature = "meshes")]
fn load(file: &str, scale: [f64; 3], rgba: Option<[f32; 4]>) -> Result<Vec<Mesh>, String> {
    let scene = mesh_loader::Loader::default().load(file).map_err(|e| format!("{file}: {e}"))?;
    let mut out = Vec::new();
    for (i, mesh) in scene.meshes.into_iter().enumerate() {
        let diffuse = scene.materials.get(i).and_then(|m| m.color.diffuse);
        let colour = rgba.or(diffuse).unwrap_or(GREY);
        let s = scale.map(|x| x as f32);
        let positions: Vec<[f32; 3]> = mesh.vertices.iter().map(|p| [p[0] * s[0], p[1] * s[1], p[2] * s[2]]).collect();
        let indices: Vec<u32> = mesh.faces.iter().flatten().copied().collect();
        if positions.is_empty() || indices.iter().any(|&i| i as usize >= positions.len()) {
            continue;
        }
        out.push(weld(Mesh { positions, normals: Vec::new(), indices, lines: false, rgba: colour }));
    }
    if out.is_empty() {
        return Err(format!("{file}: no triangles"));
    }
    Ok(out)
}

/// `m` with each position that repeats kept once, and without normals:
/// mesh files such as Collada give every triangle its own three corners,
/// each with its own normal, which would triple the run's file. glTF's
/// viewers shade a mesh without normals flat, by its faces (the standard
/// asks them to), which keeps every edge the file modelled.
#[cfg(feature = "meshes")]
fn weld(m: Mesh) -> Mesh {
    let mut first: std::collections::HashMap<[u32; 3], u32> = std::collections::HashMap::new();
    let mut positions = Vec::new();
    let remap: Vec<u32> = m
        .positions
        .iter()
        .map(|p| {
            *first.entry(p.map(f32::to_bits)).or_insert_with(|| {
                positions.push(*p);
                u32::try_from(positions.len() - 1).unwrap_or(u32::MAX)
            })
        })
        .collect();
    // Corners that were one point make a triangle of no area: dropped.
    let mut indices = Vec::with_capacity(m.indices.len());
    for t in m.indices.chunks_exact(3) {
        let [a, b, c] = [t[0], t[1], t[2]].map(|i| remap[i as usize]);
        if a != b && b != c && c != a {
            indices.extend([a, b, c]);
        }
    }
    Mesh { positions, normals: Vec::new(), indices, ..m }
}

/// A shape's colour where neither file gives one.
pub(super) const GREY: [f32; 4] = [0.72, 0.72, 0.75, 1.0];

#[cfg(test)]
mod tests {
    use super::*;

    /// The enclosed volume by the divergence theorem: `Σ (a · (b × c)) / 6`.
    fn volume(m: &Mesh) -> f64 {
        m.indices
            .chunks_exact(3)
            .map(|t| {
                let [a, b, c] = [t[0], t[1], t[2]].map(|i| m.positions[i as usize].map(f64::from)).map(Vector3::from);
                a.dot(&b.cross(&c)) / 6.0
            })
            .sum()
    }

    #[test]
    fn closed_shapes_enclose_their_volumes() {
        let cases = [
            (Shape::Box([0.1, 0.2, 0.3]), 8.0 * 0.1 * 0.2 * 0.3, 1e-6),
            (Shape::Sphere(0.5), 4.0 / 3.0 * PI * 0.125, 0.03),
            (Shape::Ellipsoid([0.1, 0.2, 0.3]), 4.0 / 3.0 * PI * 0.006, 0.03),
            (Shape::Cylinder(0.1, 0.4), PI * 0.01 * 0.8, 0.02),
            (Shape::Capsule(0.1, 0.4), PI * 0.01 * 0.8 + 4.0 / 3.0 * PI * 1e-3, 0.03),
        ];
        for (shape, exact, within) in cases {
            let m = primitive(&shape, GREY).unwrap();
            let v = volume(&m);
            // Outward faces (positive volume), short of the exact by the chords' cut only.
            assert!(v > 0.0 && (v - exact).abs() < within * exact, "{shape:?}: {v} against {exact}");
            assert_eq!(m.normals.len(), m.positions.len());
        }
    }

    #[test]
    fn equivalent_radius_solves_the_capsule_volume() {
        for (mass, length) in [(1.0, 0.5), (4.0, 0.3), (0.01, 2.0), (2.0, 0.0)] {
            let r = equivalent_radius(mass, length);
            let v = PI * r * r * length + 4.0 / 3.0 * PI * r.powi(3);
            assert!((DENSITY * v - mass).abs() < 1e-12 * mass.max(1.0), "{mass} {length}: {r}");
        }
        // A sphere of 1 kg of water: r = (3/(4π·1000))^(1/3).
        assert!((equivalent_radius(1.0, 0.0) - (3.0 / (4000.0 * PI)).cbrt()).abs() < 1e-15);
    }

    #[test]
    fn stand_ins_follow_the_joint_points() {
        let points = [Vector3::new(0.0, 0.0, -0.5), Vector3::new(0.0, 0.0, 0.5)];
        let parts = stand_in(&points, &[], (1.0, 0.0), GREY);
        assert_eq!(parts.len(), 1);
        let (at, mesh) = &parts[0];
        assert!(at.translation.norm() < 1e-15);
        // Along z already: no turn; the capsule reaches both points plus its radius.
        let top = mesh.positions.iter().map(|p| p[2]).fold(f32::MIN, f32::max);
        let r = equivalent_radius(1.0, 1.0);
        assert!((f64::from(top) - (0.5 + r)).abs() < 1e-6);
        assert_eq!(stand_in(&[], &[], (1.0, 0.0), GREY).len(), 1);
        let mark = (Vector3::new(-0.1, 0.0, 0.0), Vector3::new(0.1, 0.0, 0.0));
        assert_eq!(stand_in(&points, &[mark], (1.0, 0.0), GREY).len(), 2);
    }
}
