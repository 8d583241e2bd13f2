//! A run as glTF 2.0 binary (`.glb`): one node per body, animated by
//! translation and rotation channels at a display rate, its shapes as
//! child nodes; the ground's shapes, a grid and the world's axes static.
//! The JSON is written here (a few dozen kinds of object; no JSON crate
//! needed), the binary chunk holds every accessor's data, 4-byte aligned.
//!
//! The world's `z` is up (the project's gravity is `−z` by habit); glTF's
//! is `y`, so a root node turns the one into the other, as Blender and the
//! robot viewers do on import.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use nalgebra::{UnitQuaternion, Vector3};

use super::shapes::{self, GREY, Mesh, Placement};
use super::{GltfOptions, Trajectory};
use crate::robot::Shape;

/// A `.glb` written: its bytes and what went into it.
#[derive(Clone, Debug, PartialEq)]
pub struct Glb {
    /// The file's bytes.
    pub bytes: Vec<u8>,
    /// Frames in the animation (after decimation to the display rate).
    pub frames: usize,
    /// Mesh files named by the robot's file that could not be read, with
    /// the reason: their bodies are drawn as stand-ins instead.
    pub missing: Vec<String>,
}

/// The JSON's arrays and the binary chunk, filled as the scene is walked.
#[derive(Default)]
struct Builder {
    bin: Vec<u8>,
    views: Vec<String>,
    accessors: Vec<String>,
    meshes: Vec<String>,
    materials: Vec<String>,
    material_of: BTreeMap<([u32; 4], bool), usize>,
    nodes: Vec<String>,
}

/// `x` for JSON: finite, shortest.
fn num(x: f64) -> String {
    let x = if x.is_finite() { x as f32 } else { 0.0 };
    format!("{x}")
}

impl Builder {
    /// Appends `data` as a buffer view (`target`: 34962 vertices, 34963
    /// indices, 0 none) and returns its index.
    fn view(&mut self, data: &[u8], target: u32) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let target = if target == 0 { String::new() } else { format!(",\"target\":{target}") };
        self.views.push(format!(
            "{{\"buffer\":0,\"byteOffset\":{},\"byteLength\":{}{target}}}",
            self.bin.len(),
            data.len()
        ));
        self.bin.extend_from_slice(data);
        self.views.len() - 1
    }

    /// A float accessor of `kind` (`VEC3`, …) over `data`, with its bounds.
    fn floats<const N: usize>(&mut self, data: &[[f32; N]], kind: &str, target: u32, bounds: bool) -> usize {
        let bytes: Vec<u8> = data.iter().flatten().flat_map(|x| x.to_le_bytes()).collect();
        let view = self.view(&bytes, target);
        let mut text =
            format!("{{\"bufferView\":{view},\"componentType\":5126,\"count\":{},\"type\":\"{kind}\"", data.len());
        if bounds {
            let lo: [f32; N] = std::array::from_fn(|k| data.iter().map(|v| v[k]).fold(f32::INFINITY, f32::min));
            let hi: [f32; N] = std::array::from_fn(|k| data.iter().map(|v| v[k]).fold(f32::NEG_INFINITY, f32::max));
            let list = |v: [f32; N]| v.iter().map(|x| num(f64::from(*x))).collect::<Vec<_>>().join(",");
            let _ = write!(text, ",\"min\":[{}],\"max\":[{}]", list(lo), list(hi));
        }
        text.push('}');
        self.accessors.push(text);
        self.accessors.len() - 1
    }

    fn material(&mut self, rgba: [f32; 4], unlit: bool) -> usize {
        let key = (rgba.map(f32::to_bits), unlit);
        if let Some(&m) = self.material_of.get(&key) {
            return m;
        }
        let [r, g, b, a] = rgba.map(|c| num(f64::from(c.clamp(0.0, 1.0))));
        let blend = if rgba[3] < 1.0 { ",\"alphaMode\":\"BLEND\"" } else { "" };
        let unlit = if unlit { ",\"extensions\":{\"KHR_materials_unlit\":{}}" } else { "" };
        self.materials.push(format!(
            "{{\"pbrMetallicRoughness\":{{\"baseColorFactor\":[{r},{g},{b},{a}],\"metallicFactor\":0.1,\"roughnessFactor\":0.7}}{blend}{unlit}}}"
        ));
        self.materials.len() - 1
    }

    /// A glTF mesh of one primitive per part; its index.
    fn mesh(&mut self, parts: &[Mesh], name: &str) -> usize {
        let mut primitives = Vec::new();
        for m in parts {
            let position = self.floats(&m.positions, "VEC3", 34962, true);
            let mut attributes = format!("\"POSITION\":{position}");
            if !m.normals.is_empty() {
                let normal = self.floats(&m.normals, "VEC3", 34962, false);
                let _ = write!(attributes, ",\"NORMAL\":{normal}");
            }
            // 16-bit indices where they reach every vertex: half the bytes.
            let (bytes, kind): (Vec<u8>, u32) = if m.positions.len() <= usize::from(u16::MAX) {
                (m.indices.iter().flat_map(|&i| u16::try_from(i).unwrap_or(u16::MAX).to_le_bytes()).collect(), 5123)
            } else {
                (m.indices.iter().flat_map(|i| i.to_le_bytes()).collect(), 5125)
            };
            let view = self.view(&bytes, 34963);
            self.accessors.push(format!(
                "{{\"bufferView\":{view},\"componentType\":{kind},\"count\":{},\"type\":\"SCALAR\"}}",
                m.indices.len()
            ));
            let indices = self.accessors.len() - 1;
            let material = self.material(m.rgba, m.lines);
            let mode = if m.lines { 1 } else { 4 };
            primitives.push(format!(
                "{{\"attributes\":{{{attributes}}},\"indices\":{indices},\"material\":{material},\"mode\":{mode}}}"
            ));
        }
        self.meshes.push(format!("{{\"name\":{},\"primitives\":[{}]}}", json_string(name), primitives.join(",")));
        self.meshes.len() - 1
    }

    /// A node; its index.
    fn node(&mut self, name: &str, at: Option<&Placement>, mesh: Option<usize>, children: &[usize]) -> usize {
        let mut text = format!("{{\"name\":{}", json_string(name));
        if let Some(p) = at {
            let t = p.translation;
            let q = p.rotation.quaternion().coords;
            let _ = write!(
                text,
                ",\"translation\":[{},{},{}],\"rotation\":[{},{},{},{}]",
                num(t.x),
                num(t.y),
                num(t.z),
                num(q.x),
                num(q.y),
                num(q.z),
                num(q.w)
            );
        }
        if let Some(m) = mesh {
            let _ = write!(text, ",\"mesh\":{m}");
        }
        if !children.is_empty() {
            let list: Vec<String> = children.iter().map(usize::to_string).collect();
            let _ = write!(text, ",\"children\":[{}]", list.join(","));
        }
        text.push('}');
        self.nodes.push(text);
        self.nodes.len() - 1
    }
}

/// `text` as a JSON string.
fn json_string(text: &str) -> String {
    let mut out = String::from("\"");
    for c in text.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            c if (c as u32) < 0x20 => {
                let _ = write!(out, "\\u{:04x}", c as u32);
            }
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

impl<const NB: usize> Trajectory<NB> {
    /// The run as a glTF 2.0 binary ([`Glb`]): see [`write_3d`](Self::write_3d).
    pub fn glb(&self, options: &GltfOptions) -> Glb {
        let mut b = Builder::default();
        let mut missing = Vec::new();
        let mut world = Vec::new();
        let frames = self.display_frames(options.fps);
        // The bodies, each with its shapes as children.
        let (mut animated, mut corners) = (Vec::new(), Vec::new());
        for body in 0..NB {
            let mut parts = self.visual_parts(Some(body), &mut missing);
            if parts.is_empty() {
                parts = self.stand_in_parts(body);
            }
            corners.extend(parts.iter().flat_map(Part::corners).map(|c| (body, c)));
            let children = place(&mut b, parts);
            let first = frames.first().map(|&i| self.pose(i, body));
            let node = b.node(self.bodies[body], first.as_ref(), None, &children);
            animated.push(node);
            world.push(node);
        }
        let on_ground = self.visual_parts(None, &mut missing);
        world.extend(place(&mut b, on_ground));
        world.extend(self.ground_points(&mut b));
        if options.ground {
            world.extend(ground(&mut b, &self.extent(&corners), &self.up));
        }
        // glTF's up is `y`: the world turned so that its up is.
        let turn = UnitQuaternion::rotation_between(&self.up, &Vector3::y())
            .unwrap_or_else(|| UnitQuaternion::from_axis_angle(&Vector3::x_axis(), core::f64::consts::PI));
        let turn = Placement { translation: Vector3::zeros(), rotation: turn };
        let root = b.node("world", Some(&turn), None, &world);
        let animation = self.animation(&mut b, &frames, &animated);
        missing.sort();
        missing.dedup();
        Glb { bytes: assemble(b, root, animation, &options.title), frames: frames.len(), missing }
    }

    /// Body `body`'s pose at sample `i`.
    fn pose(&self, i: usize, body: usize) -> Placement {
        let s = &self.samples[i].bodies[body];
        Placement { translation: s.r, rotation: s.rotation() }
    }

    /// The samples shown at `fps` frames a second (every sample where they
    /// are sparser), the first and last kept, times strictly increasing.
    fn display_frames(&self, fps: f64) -> Vec<usize> {
        let period = if fps > 0.0 { 1.0 / fps } else { 0.0 };
        let mut out: Vec<usize> = Vec::new();
        let mut next = f64::NEG_INFINITY;
        for (i, s) in self.samples.iter().enumerate() {
            let later = out.last().is_none_or(|&j| s.t > self.samples[j].t);
            if later && s.t >= next - 1e-9 * period {
                out.push(i);
                next = s.t + period;
            }
        }
        if let (Some(&last), Some(end)) = (out.last(), self.samples.len().checked_sub(1))
            && last != end
            && self.samples[end].t > self.samples[last].t
        {
            out.push(end);
        }
        out
    }

    /// The file's shapes on `body` (the ground's for `None`); an
    /// unreadable mesh into `missing`, and nothing drawn for it.
    fn visual_parts(&self, body: Option<usize>, missing: &mut Vec<String>) -> Vec<Part> {
        let mut out = Vec::new();
        for (k, v) in self.visuals.iter().enumerate().filter(|(_, v)| v.body == body) {
            let rgba = v.rgba.map(|c| c.map(|x| x as f32));
            let parts = match v.shape {
                Shape::Mesh { file, scale } => match shapes::read(file, scale, rgba) {
                    Ok(parts) => parts.as_ref().clone(),
                    Err(e) => {
                        missing.push(e);
                        continue;
                    }
                },
                ref shape => shapes::primitive(shape, rgba.unwrap_or(GREY)).into_iter().collect(),
            };
            let name = match body {
                Some(i) => format!("{} shape {k}", self.bodies[i]),
                None => format!("ground shape {k}"),
            };
            out.push(Part { name, at: Placement::of(&v.rotation, &v.origin), meshes: parts });
        }
        out
    }

    /// A body the file does not draw: capsules along its joint points.
    fn stand_in_parts(&self, body: usize) -> Vec<Part> {
        let points: Vec<Vector3<f64>> = self.points.iter().filter(|p| p.body == Some(body)).map(|p| p.point).collect();
        let colour = super::body_colour(body);
        let rgba = hex(colour);
        let marks: Vec<_> = self.segments.iter().filter(|s| s.0 == body).map(|s| (s.1, s.2)).collect();
        let parts = shapes::stand_in(&points, &marks, (self.masses[body], self.thinnest()), rgba);
        let name = |k| format!("{} stand-in {k}", self.bodies[body]);
        parts.into_iter().enumerate().map(|(k, (at, mesh))| Part { name: name(k), at, meshes: vec![mesh] }).collect()
    }

    /// Small dark spheres at the joints' points on the ground.
    fn ground_points(&self, b: &mut Builder) -> Vec<usize> {
        let r = 1.5 * self.thinnest();
        let mut sphere = shapes::primitive(&Shape::Sphere(r), [0.2, 0.2, 0.22, 1.0]).into_iter().collect::<Vec<_>>();
        if sphere.is_empty() || !self.points.iter().any(|p| p.body.is_none()) {
            return Vec::new();
        }
        let mesh = b.mesh(&std::mem::take(&mut sphere), "ground point");
        let on_ground = self.points.iter().filter(|p| p.body.is_none());
        on_ground.map(|p| b.node(p.joint, Some(&Placement::at(p.point)), Some(mesh), &[])).collect()
    }

    /// Where the bodies go: the centre of the box around them (their
    /// centres, the points on the ground, the ground's shapes), its half
    /// width across `up`, and its lowest height along `up` (of the bodies'
    /// `corners`, where given: body, corner in its frame).
    fn extent(&self, corners: &[(usize, Vector3<f64>)]) -> Extent {
        let mut lo = Vector3::repeat(f64::INFINITY);
        let mut hi = Vector3::repeat(f64::NEG_INFINITY);
        let (mut low, mut n) = (f64::INFINITY, 0);
        let ground = self.points.iter().filter(|p| p.body.is_none()).map(|p| p.point);
        for s in &self.samples {
            for (k, c) in corners {
                if let Some(b) = s.bodies.get(*k) {
                    low = low.min((b.r + b.rotation() * c).dot(&self.up));
                }
            }
        }
        let bodies = self.samples.iter().flat_map(|s| s.bodies.iter().map(|b| b.r));
        let shapes = self.visuals.iter().filter(|v| v.body.is_none()).map(|v| Vector3::from(v.origin));
        for p in ground.chain(bodies).chain(shapes) {
            lo = lo.inf(&p);
            hi = hi.sup(&p);
            low = low.min(p.dot(&self.up));
            n += 1;
        }
        if n == 0 {
            return Extent { centre: Vector3::zeros(), half: 1.0, low: 0.0 };
        }
        let d = hi - lo;
        let across = d - self.up * d.dot(&self.up);
        Extent { centre: 0.5 * (lo + hi), half: (0.5 * across.norm()).max(0.25), low }
    }

    /// The stand-ins' radius at least this: a light bar in a large
    /// mechanism stays visible.
    fn thinnest(&self) -> f64 {
        0.012 * self.extent(&[]).half
    }

    /// The animation's JSON: one time accessor, each body's translation and
    /// rotation (signs kept continuous, so that a linear blend takes the
    /// short way).
    fn animation(&self, b: &mut Builder, frames: &[usize], nodes: &[usize]) -> Option<String> {
        if frames.len() < 2 {
            return None;
        }
        let t0 = self.samples[frames[0]].t;
        let times: Vec<[f32; 1]> = frames.iter().map(|&i| [(self.samples[i].t - t0) as f32]).collect();
        let input = b.floats(&times, "SCALAR", 0, true);
        let (mut samplers, mut channels) = (Vec::new(), Vec::new());
        for (body, &node) in nodes.iter().enumerate() {
            let translation: Vec<[f32; 3]> =
                frames.iter().map(|&i| self.samples[i].bodies[body].r.map(|x| x as f32).into()).collect();
            let mut last = UnitQuaternion::identity();
            let rotation: Vec<[f32; 4]> = frames
                .iter()
                .map(|&i| {
                    let mut q = self.samples[i].bodies[body].rotation();
                    if q.coords.dot(&last.coords) < 0.0 {
                        q = UnitQuaternion::new_unchecked(-q.into_inner());
                    }
                    last = q;
                    let c = q.coords;
                    [c.x, c.y, c.z, c.w].map(|x| x as f32)
                })
                .collect();
            for (path, output) in [
                ("translation", b.floats(&translation, "VEC3", 0, false)),
                ("rotation", b.floats(&rotation, "VEC4", 0, false)),
            ] {
                samplers.push(format!("{{\"input\":{input},\"output\":{output},\"interpolation\":\"LINEAR\"}}"));
                channels.push(format!(
                    "{{\"sampler\":{},\"target\":{{\"node\":{node},\"path\":\"{path}\"}}}}",
                    samplers.len() - 1
                ));
            }
        }
        Some(format!(
            "{{\"name\":\"run\",\"samplers\":[{}],\"channels\":[{}]}}",
            samplers.join(","),
            channels.join(",")
        ))
    }
}

/// A shape to draw: its node's name, pose and primitives.
struct Part {
    name: String,
    at: Placement,
    meshes: Vec<Mesh>,
}

impl Part {
    /// The corners of its box in its parent's frame.
    fn corners(&self) -> Vec<Vector3<f64>> {
        let mut lo = Vector3::repeat(f64::INFINITY);
        let mut hi = Vector3::repeat(f64::NEG_INFINITY);
        for p in self.meshes.iter().flat_map(|m| &m.positions) {
            let p = Vector3::from(p.map(f64::from));
            (lo, hi) = (lo.inf(&p), hi.sup(&p));
        }
        if !lo.x.is_finite() {
            return Vec::new();
        }
        let pick = |k: usize| Vector3::new([lo.x, hi.x][k & 1], [lo.y, hi.y][(k >> 1) & 1], [lo.z, hi.z][k >> 2]);
        (0..8).map(|k| self.at.rotation * pick(k) + self.at.translation).collect()
    }
}

/// Each part as a node with its mesh; the nodes.
fn place(b: &mut Builder, parts: Vec<Part>) -> Vec<usize> {
    parts
        .into_iter()
        .map(|p| {
            let mesh = b.mesh(&p.meshes, &p.name);
            b.node(&p.name, Some(&p.at), Some(mesh), &[])
        })
        .collect()
}

/// Where the bodies go ([`Trajectory::extent`]).
struct Extent {
    centre: Vector3<f64>,
    half: f64,
    low: f64,
}

/// A grid across `up` under the bodies (at the world's origin, or lower
/// where they go lower) and the world's axes at its origin.
fn ground(b: &mut Builder, e: &Extent, up: &Vector3<f64>) -> Vec<usize> {
    // A round cell size: 1, 2 or 5 times a power of ten, about ten cells a side.
    let raw = 2.0 * e.half / 10.0;
    let decade = 10f64.powf(raw.log10().floor());
    let cell = [1.0, 2.0, 5.0, 10.0].into_iter().map(|m| m * decade).find(|c| *c >= raw).unwrap_or(decade * 10.0);
    let n = ((e.half * 1.5) / cell).ceil().max(2.0) as i64;
    // The grid's axes: the world's x and y where up is z, two across up otherwise.
    let u = (Vector3::x() - up * up.x).try_normalize(1e-6).unwrap_or_else(|| (Vector3::y() - up * up.y).normalize());
    let v = up.cross(&u);
    let level = e.low.min(0.0) - 0.05 * cell;
    let snap = |x: f64| (x / cell).round() * cell;
    let centre = u * snap(e.centre.dot(&u)) + v * snap(e.centre.dot(&v)) + up * level;
    let mut grid = Mesh { lines: true, rgba: [0.62, 0.64, 0.68, 1.0], ..Mesh::default() };
    let extent = n as f64 * cell;
    let point = |a: f64, c: f64| -> [f32; 3] { (centre + u * a + v * c).map(|x| x as f32).into() };
    for k in -n..=n {
        let s = k as f64 * cell;
        let i = u32::try_from(grid.positions.len()).unwrap_or(u32::MAX);
        grid.positions.extend([point(s, -extent), point(s, extent), point(-extent, s), point(extent, s)]);
        grid.indices.extend([i, i + 1, i + 2, i + 3]);
    }
    let mesh = b.mesh(&[grid], "ground grid");
    let mut nodes = vec![b.node("ground grid", None, Some(mesh), &[])];
    let length = (2.0 * cell).max(0.1) as f32;
    for (k, (name, rgba)) in [("x", [0.85, 0.1, 0.1, 1.0]), ("y", [0.1, 0.65, 0.1, 1.0]), ("z", [0.1, 0.2, 0.9, 1.0])]
        .into_iter()
        .enumerate()
    {
        let mut end = [0.0; 3];
        end[k] = length;
        let axis = Mesh { positions: vec![[0.0; 3], end], normals: Vec::new(), indices: vec![0, 1], lines: true, rgba };
        let mesh = b.mesh(&[axis], &format!("world {name} axis"));
        nodes.push(b.node(&format!("world {name} axis"), None, Some(mesh), &[]));
    }
    nodes
}

/// `#rrggbb` as linear-enough RGBA.
fn hex(colour: &str) -> [f32; 4] {
    let c = |k: usize| u8::from_str_radix(colour.get(1 + 2 * k..3 + 2 * k).unwrap_or("80"), 16).unwrap_or(128);
    [f32::from(c(0)) / 255.0, f32::from(c(1)) / 255.0, f32::from(c(2)) / 255.0, 1.0]
}

/// The GLB container: header, JSON chunk (space-padded), binary chunk.
fn assemble(b: Builder, root: usize, animation: Option<String>, title: &str) -> Vec<u8> {
    let unlit = b.materials.iter().any(|m| m.contains("KHR_materials_unlit"));
    let mut json =
        format!("{{\"asset\":{{\"version\":\"2.0\",\"generator\":\"joint-runtime {}\"", env!("CARGO_PKG_VERSION"));
    if !title.is_empty() {
        let _ = write!(json, ",\"extras\":{{\"title\":{}}}", json_string(title));
    }
    let _ = write!(json, "}},\"scene\":0,\"scenes\":[{{\"nodes\":[{root}]}}]");
    if unlit {
        json.push_str(",\"extensionsUsed\":[\"KHR_materials_unlit\"]");
    }
    for (key, list) in [
        ("nodes", &b.nodes),
        ("meshes", &b.meshes),
        ("materials", &b.materials),
        ("accessors", &b.accessors),
        ("bufferViews", &b.views),
    ] {
        let _ = write!(json, ",\"{key}\":[{}]", list.join(","));
    }
    if let Some(a) = animation {
        let _ = write!(json, ",\"animations\":[{a}]");
    }
    let mut bin = b.bin;
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let _ = write!(json, ",\"buffers\":[{{\"byteLength\":{}}}]}}", bin.len());
    let mut json = json.into_bytes();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut out = Vec::with_capacity(total);
    let word = |x: usize| u32::try_from(x).unwrap_or(u32::MAX).to_le_bytes();
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&word(total));
    out.extend_from_slice(&word(json.len()));
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    out.extend_from_slice(&word(bin.len()));
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin);
    out
}
