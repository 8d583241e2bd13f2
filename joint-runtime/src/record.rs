//! Seeing a run: a [`Trajectory`] of [`SystemState`]s, from a
//! [`Simulation`](crate::dynamics::Simulation) or the kinematic analyses, written
//! as CSV (one row per sample), in 3D ([`Trajectory::write_3d`]: a glTF 2.0
//! file with each body's shapes, and a page that plays it offline), or as an
//! animated SVG that plays in a browser by itself (SMIL animation, no script).
//! Feature `record`.
//!
//! The rest of this page is the SVG's drawing; the 3D run's is at
//! [`Trajectory::write_3d`].
//!
//! Each body is drawn from its joint points ([`Scene::joint_points`]) as a
//! polyline through them in declaration order (from its centre of mass when it
//! has one joint point, a dot there when it has none), so a bar between two
//! joints is drawn as that bar; [`Trajectory::add_segment`] adds body-fixed
//! marks, such as a shaft's yoke, whose spin points on the axis cannot show.
//! Points on the ground are small squares. The view is a projection on a plane
//! ([`View`]).
//!
//! ```
//! use joint_runtime::dynamics::{NoLoads, Simulation, SimulationOptions};
//! use joint_runtime::nalgebra::{UnitQuaternion, Vector3};
//! use joint_runtime::record::{Column, SvgOptions, Trajectory, View};
//! use joint_runtime::{OmegaBody, Scene, SystemState};
//!
//! #[derive(Scene)]
//! #[scene(coordinates = absolute, gravity = [0, 0, -9.81])]
//! #[body(link, mass = 1.0, inertia = [0.0833, 0.0833, 0.001])]
//! #[joint(hinge = revolute(ground, link), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0, 0, 0], rho2 = [0, 0, 0.5])]
//! struct Pendulum;
//!
//! let tilt = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), 1.0);
//! let mut state = SystemState { bodies: [OmegaBody::from_rotation(tilt * Vector3::new(0.0, 0.0, -0.5), &tilt, Vector3::zeros(), Vector3::zeros())], t: 0.0 };
//! let mut sim = Simulation::new(&Pendulum, NoLoads, &[], SimulationOptions::default()).expect("valid options");
//! let mut run = Trajectory::new(&Pendulum);
//! for step in 0..=500 {
//!     if step % 10 == 0 { run.record(&state); }
//!     sim.step(&mut state, 2e-3).expect("steps");
//! }
//! let mut csv = Vec::new();
//! let height = |s: &SystemState<1>| s.bodies[0].r.z;
//! run.write_csv(&mut csv, &[Column::new("height", &height)]).expect("written");
//! assert!(String::from_utf8(csv).unwrap().starts_with("t,link.x,link.y,link.z,link.e0,"));
//! let svg = run.svg(&SvgOptions::default().with_view(View::xz()));
//! assert!(svg.contains("<animate attributeName=\"d\""));
//! ```

use std::fmt::Write as _;
use std::io;

use nalgebra::Vector3;

use crate::robot::Visual;
use crate::rotation_matrix;
use crate::scene::{JointPoint, Scene, SystemState};

mod gltf;
mod shapes;
mod viewer;

pub use gltf::Glb;
pub use viewer::{GltfOptions, Written, viewer_page};

/// The states of a run, with what is needed to draw them: the scene's body
/// names and joint points, read once by [`Trajectory::new`].
#[derive(Clone, Debug, PartialEq)]
pub struct Trajectory<const NB: usize> {
    bodies: [&'static str; NB],
    masses: [f64; NB],
    /// Against gravity (`z` without gravity): up in pictures.
    up: Vector3<f64>,
    visuals: &'static [Visual],
    points: Vec<JointPoint>,
    segments: Vec<Segment>,
    samples: Vec<SystemState<NB>>,
}

/// A body-fixed mark: body index, both ends in body components.
type Segment = (usize, Vector3<f64>, Vector3<f64>);

/// A column the user adds to the CSV: a name and a value computed from each
/// sample.
pub struct Column<'a, const NB: usize> {
    /// The header.
    pub name: &'a str,
    /// The value at one sample.
    pub value: &'a dyn Fn(&SystemState<NB>) -> f64,
}

impl<'a, const NB: usize> Column<'a, NB> {
    /// A column `name` whose value at each sample is `value(state)`.
    pub fn new(name: &'a str, value: &'a dyn Fn(&SystemState<NB>) -> f64) -> Self {
        Column { name, value }
    }
}

impl<const NB: usize> core::fmt::Debug for Column<'_, NB> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Column").field("name", &self.name).finish_non_exhaustive()
    }
}

/// A projection of inertial space on the drawing: screen `x = right · p`,
/// screen `y = up · p` (up on the page).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct View {
    /// The inertial direction drawn to the right.
    pub right: Vector3<f64>,
    /// The inertial direction drawn upwards.
    pub up: Vector3<f64>,
}

impl View {
    /// The plane of two inertial directions (used as given: unit and
    /// perpendicular for an undistorted picture).
    pub fn new(right: Vector3<f64>, up: Vector3<f64>) -> Self {
        View { right, up }
    }
    /// Looking down the z axis: x right, y up.
    pub fn xy() -> Self {
        View::new(Vector3::x(), Vector3::y())
    }
    /// Looking along y: x right, z up.
    pub fn xz() -> Self {
        View::new(Vector3::x(), Vector3::z())
    }
    /// Looking along x: y right, z up.
    pub fn yz() -> Self {
        View::new(Vector3::y(), Vector3::z())
    }
    /// The isometric view from `(1, 1, 1)` with z up.
    pub fn isometric() -> Self {
        let (s2, s6) = (core::f64::consts::SQRT_2, 6f64.sqrt());
        View::new(Vector3::new(-1.0, 1.0, 0.0) / s2, Vector3::new(-1.0, -1.0, 2.0) / s6)
    }
    fn project(&self, p: &Vector3<f64>) -> [f64; 2] {
        [self.right.dot(p), self.up.dot(p)]
    }
}

/// How [`Trajectory::svg`] draws.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize), serde(default))]
#[non_exhaustive]
pub struct SvgOptions {
    /// The projection.
    pub view: View,
    /// Picture size in pixels.
    pub width: u32,
    /// Picture size in pixels.
    pub height: u32,
    /// Playback speed: 1 is real time, 0.5 half speed.
    pub speed: f64,
    /// At most this many frames (evenly chosen among the samples, first and
    /// last kept), which bounds the file's size.
    pub max_frames: usize,
    /// A title drawn at the top.
    pub title: String,
}

impl Default for SvgOptions {
    fn default() -> Self {
        SvgOptions {
            view: View::isometric(),
            width: 640,
            height: 480,
            speed: 1.0,
            max_frames: 300,
            title: String::new(),
        }
    }
}

impl SvgOptions {
    /// Sets [`view`](Self::view).
    pub fn with_view(mut self, view: View) -> Self {
        self.view = view;
        self
    }
    /// Sets [`width`](Self::width) and [`height`](Self::height).
    pub fn with_size(mut self, width: u32, height: u32) -> Self {
        (self.width, self.height) = (width, height);
        self
    }
    /// Sets [`speed`](Self::speed).
    pub fn with_speed(mut self, speed: f64) -> Self {
        self.speed = speed;
        self
    }
    /// Sets [`max_frames`](Self::max_frames).
    pub fn with_max_frames(mut self, max_frames: usize) -> Self {
        self.max_frames = max_frames;
        self
    }
    /// Sets [`title`](Self::title).
    pub fn with_title(mut self, title: &str) -> Self {
        self.title = title.into();
        self
    }
}

/// Body colours, one per body in turn (Tableau 10).
const PALETTE: [&str; 10] =
    ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf"];

/// The colour [`Trajectory::svg`] draws body `index` in.
pub fn body_colour(index: usize) -> &'static str {
    PALETTE[index % PALETTE.len()]
}

impl<const NB: usize> Trajectory<NB> {
    /// An empty trajectory of `scene`'s bodies.
    pub fn new<S: Scene<NB, NV, M>, const NV: usize, const M: usize>(scene: &S) -> Self {
        let mut points = Vec::new();
        scene.joint_points(&mut |p| points.push(p));
        let masses = scene.inertias().map(|i| i.mass);
        let up = (-scene.gravity()).try_normalize(0.0).unwrap_or_else(Vector3::z);
        let (visuals, segments, samples) = (S::VISUALS, Vec::new(), Vec::new());
        Trajectory { bodies: S::BODIES, masses, up, visuals, points, segments, samples }
    }

    /// Adds a segment fixed in body `body` from `a` to `b` (body components,
    /// from its centre of mass) to its drawing: a yoke across a shaft shows the
    /// shaft's spin, which its points on the axis do not. An out-of-range `body`
    /// is ignored.
    pub fn add_segment(&mut self, body: usize, a: Vector3<f64>, b: Vector3<f64>) {
        if body < NB {
            self.segments.push((body, a, b));
        }
    }

    /// Appends a sample. Record in time order: the animation's key times follow
    /// the samples' times.
    pub fn record(&mut self, state: &SystemState<NB>) {
        self.samples.push(*state);
    }

    /// The samples, in the order recorded.
    pub fn samples(&self) -> &[SystemState<NB>] {
        &self.samples
    }

    /// The scene's joint points, as drawn.
    pub fn joint_points(&self) -> &[JointPoint] {
        &self.points
    }

    /// Writes one CSV row per sample: `t`, then for each body `NAME.x, NAME.y,
    /// NAME.z` (position of its centre of mass, inertial) and `NAME.e0 … NAME.e3`
    /// (Euler parameters), then the user's `columns`. Numbers are written in
    /// their shortest form that reads back exactly.
    ///
    /// # Errors
    /// What writing to `out` returns.
    pub fn write_csv<W: io::Write>(&self, out: W, columns: &[Column<'_, NB>]) -> io::Result<()> {
        let mut csv = csv::Writer::from_writer(out);
        let mut header = vec![String::from("t")];
        for b in self.bodies {
            header.extend(["x", "y", "z", "e0", "e1", "e2", "e3"].map(|c| format!("{b}.{c}")));
        }
        header.extend(columns.iter().map(|c| String::from(c.name)));
        csv.write_record(&header)?;
        let mut row = Vec::with_capacity(header.len());
        for s in &self.samples {
            row.clear();
            row.push(s.t);
            for b in &s.bodies {
                row.extend(b.r.iter().chain(b.p.iter()));
            }
            row.extend(columns.iter().map(|c| (c.value)(s)));
            csv.write_record(row.iter().map(|x| format!("{x:?}")))?;
        }
        csv.flush()
    }

    /// The run as an animated SVG, looping: bodies move, the time is shown. A
    /// viewer that does not animate (or a trajectory of one sample) shows the
    /// first frame, exactly as [`svg_frame`](Self::svg_frame)`(0)` draws it.
    pub fn svg(&self, options: &SvgOptions) -> String {
        let frames = self.frames(options.max_frames);
        let canvas = Canvas::fit(self, &frames, options);
        let (t0, t1) = match (frames.first(), frames.last()) {
            (Some(a), Some(b)) => (a.t, b.t),
            _ => (0.0, 0.0),
        };
        let span = t1 - t0;
        let animated = frames.len() > 1 && span > 0.0 && options.speed > 0.0;
        let duration = if animated { span / options.speed } else { 0.0 };
        let key_times = || frames.iter().map(|s| format!("{:.5}", (s.t - t0) / span)).collect::<Vec<_>>().join(";");
        let mut out = canvas.open(self, options);
        for body in 0..NB {
            let paths: Vec<String> = frames.iter().map(|s| canvas.body_path(self, s, body)).collect();
            let first = paths.first().cloned().unwrap_or_default();
            let _ = write!(out, r#"<path d="{first}" stroke="{}" class="body">"#, body_colour(body));
            if animated {
                let _ = write!(
                    out,
                    r#"<animate attributeName="d" dur="{duration:.4}s" repeatCount="indefinite" keyTimes="{}" values="{}"/>"#,
                    key_times(),
                    paths.join(";")
                );
            }
            out.push_str("</path>\n");
        }
        for (k, s) in frames.iter().enumerate() {
            let visible = if k == 0 { "visible" } else { "hidden" };
            let _ = write!(out, r#"<text x="10" y="{}" visibility="{visible}">t = {:.3} s"#, canvas.height - 10, s.t);
            if animated {
                // Shown from this frame's time to the next one's, hidden otherwise.
                let at = |i: usize| frames.get(i).map(|f| (f.t - t0) / span);
                let (on, off) = (at(k).unwrap_or(0.0), at(k + 1));
                let (values, times) = match (k, off) {
                    (0, Some(off)) => ("visible;hidden".to_string(), format!("0;{off:.5}")),
                    (_, Some(off)) => ("hidden;visible;hidden".to_string(), format!("0;{on:.5};{off:.5}")),
                    (_, None) => ("hidden;visible".to_string(), format!("0;{on:.5}")),
                };
                let _ = write!(
                    out,
                    r#"<animate attributeName="visibility" calcMode="discrete" dur="{duration:.4}s" repeatCount="indefinite" keyTimes="{times}" values="{values}"/>"#
                );
            }
            out.push_str("</text>\n");
        }
        out.push_str("</svg>\n");
        out
    }

    /// One frame as a still SVG (`index` among the frames [`svg`](Self::svg)
    /// animates, with the same layout), or `None` past the last frame.
    pub fn svg_frame(&self, index: usize, options: &SvgOptions) -> Option<String> {
        let frames = self.frames(options.max_frames);
        let state = frames.get(index)?;
        let canvas = Canvas::fit(self, &frames, options);
        let mut out = canvas.open(self, options);
        for body in 0..NB {
            let path = canvas.body_path(self, state, body);
            let _ = writeln!(out, r#"<path d="{path}" stroke="{}" class="body"></path>"#, body_colour(body));
        }
        let _ = writeln!(out, r#"<text x="10" y="{}">t = {:.3} s</text>"#, canvas.height - 10, state.t);
        out.push_str("</svg>\n");
        Some(out)
    }

    /// The samples drawn: all of them, or `max_frames` evenly chosen with the
    /// first and the last.
    fn frames(&self, max_frames: usize) -> Vec<SystemState<NB>> {
        let n = self.samples.len();
        if n <= max_frames.max(2) {
            return self.samples.clone();
        }
        let m = max_frames.max(2);
        (0..m).filter_map(|k| self.samples.get(k * (n - 1) / (m - 1)).copied()).collect()
    }

    /// Body `body` at `state`, inertial: the polylines that draw it (its joint
    /// points, then each added segment).
    fn body_lines(&self, state: &SystemState<NB>, body: usize) -> Vec<Vec<Vector3<f64>>> {
        let Some(b) = state.bodies.get(body) else { return Vec::new() };
        let a = rotation_matrix(&b.p);
        let at = |p: &Vector3<f64>| b.r + a * p;
        let mut points: Vec<_> = self.points.iter().filter(|p| p.body == Some(body)).map(|p| at(&p.point)).collect();
        if points.len() < 2 {
            points.insert(0, b.r);
        }
        let mut lines = vec![points];
        lines.extend(self.segments.iter().filter(|s| s.0 == body).map(|s| vec![at(&s.1), at(&s.2)]));
        lines
    }
}

/// The drawing's frame: a uniform scale from projected inertial coordinates to
/// pixels, chosen so that every frame fits.
struct Canvas {
    view: View,
    scale: f64,
    origin: [f64; 2],
    height: u32,
    width: u32,
}

/// Room around the drawing and above it (for the title and legend), pixels.
const MARGIN: f64 = 20.0;
const HEADER: f64 = 40.0;

impl Canvas {
    fn fit<const NB: usize>(run: &Trajectory<NB>, frames: &[SystemState<NB>], options: &SvgOptions) -> Canvas {
        let view = options.view;
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        let mut include = |p: &Vector3<f64>| {
            let q = view.project(p);
            for i in 0..2 {
                lo[i] = lo[i].min(q[i]);
                hi[i] = hi[i].max(q[i]);
            }
        };
        for s in frames {
            for (i, b) in s.bodies.iter().enumerate() {
                include(&b.r);
                run.body_lines(s, i).iter().flatten().for_each(&mut include);
            }
        }
        run.points.iter().filter(|p| p.body.is_none()).for_each(|p| include(&p.point));
        if !(lo[0].is_finite() && lo[1].is_finite() && hi[0].is_finite() && hi[1].is_finite()) {
            (lo, hi) = ([-1.0; 2], [1.0; 2]);
        }
        let (w, h) = (f64::from(options.width), f64::from(options.height));
        let room = [w - 2.0 * MARGIN, h - 2.0 * MARGIN - HEADER];
        let extent = [(hi[0] - lo[0]).max(1e-9), (hi[1] - lo[1]).max(1e-9)];
        let scale = (room[0] / extent[0]).min(room[1] / extent[1]).max(0.0);
        // Centred in the room left under the header.
        let origin = [
            MARGIN + 0.5 * (room[0] - scale * extent[0]) - scale * lo[0],
            MARGIN + HEADER + 0.5 * (room[1] + scale * extent[1]) + scale * lo[1],
        ];
        Canvas { view, scale, origin, height: options.height, width: options.width }
    }

    fn pixel(&self, p: &Vector3<f64>) -> [f64; 2] {
        let [x, y] = self.view.project(p);
        [self.origin[0] + self.scale * x, self.origin[1] - self.scale * y]
    }

    /// The body's polylines as one path; the same commands in every frame, so
    /// that a browser interpolates between frames. A lone point is a dot.
    fn body_path<const NB: usize>(&self, run: &Trajectory<NB>, state: &SystemState<NB>, body: usize) -> String {
        let mut d = String::new();
        for line in run.body_lines(state, body) {
            for (k, p) in line.iter().enumerate() {
                let [x, y] = self.pixel(p);
                let _ = write!(d, "{}{x:.2} {y:.2}", if k == 0 { 'M' } else { 'L' });
            }
            if let [p] = line.as_slice() {
                let [x, y] = self.pixel(p);
                let _ = write!(d, "L{x:.2} {y:.2}");
            }
        }
        d
    }

    /// The document's head: style, title, legend and the ground's points.
    fn open<const NB: usize>(&self, run: &Trajectory<NB>, options: &SvgOptions) -> String {
        let (w, h) = (self.width, self.height);
        let mut out = format!(
            "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" viewBox=\"0 0 {w} {h}\">\n\
             <style>.body{{fill:none;stroke-width:4;stroke-linecap:round;stroke-linejoin:round}}\
             text{{font-family:sans-serif;font-size:14px}}</style>\n\
             <rect width=\"{w}\" height=\"{h}\" fill=\"white\"/>\n"
        );
        if !options.title.is_empty() {
            let _ = writeln!(out, r#"<text x="10" y="18">{}</text>"#, escape(&options.title));
        }
        let mut x = 10.0;
        for (i, name) in run.bodies.iter().enumerate() {
            let _ = writeln!(out, r#"<text x="{x:.0}" y="36" fill="{}">{}</text>"#, body_colour(i), escape(name));
            x += 12.0 + 8.0 * name.chars().count() as f64;
        }
        for p in run.points.iter().filter(|p| p.body.is_none()) {
            let [px, py] = self.pixel(&p.point);
            let _ =
                writeln!(out, r##"<rect x="{:.2}" y="{:.2}" width="8" height="8" fill="#444"/>"##, px - 4.0, py - 4.0);
        }
        out
    }
}

/// Text for XML character data.
fn escape(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;")
}
