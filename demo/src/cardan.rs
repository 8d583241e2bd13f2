//! The Cardan shaft: two shafts in bearings, bent by β, coupled by a universal
//! (Cardan, Hooke) joint, the input driven at constant speed.
//!
//! # The mechanism
//!
//! The joint centre is the origin. The *input* shaft (length 1, centre of mass at
//! `(−0.5, 0, 0)`) turns in a bearing about the inertial x axis; the *output*
//! shaft (length 1) turns in its own bearing about `u = (cos β, sin β, 0)`, its
//! centre of mass at `0.5 u`. Each body's frame has its x axis along its shaft. The
//! cross of the joint carries the input yoke `s' = y'` (in the input) and the
//! output yoke `h' = z'` (in the output); the motor is a `rotational_driver`
//! between the ground and the input about x with `θ(t) = ω₁ t` (a [`Ramp`]).
//!
//! # Closed form
//!
//! Let `φ₁` be the input's rotation about x and `φ₂` the output's about `u`,
//! both zero in the reference configuration (frames `I` and `R_z(β)`), so
//! `A₁ = R_x(φ₁)` and `A₂ = R_z(β) R_x(φ₂)`. At `φ₁ = 0` the input yoke lies
//! *in* the plane of the two shafts (along y) and the output yoke is
//! perpendicular to it (along z). The cross keeps the yokes perpendicular:
//!
//! ```text
//! A₁ s' = (0, cos φ₁, sin φ₁),   A₂ h' = (sin β sin φ₂, −cos β sin φ₂, cos φ₂)
//! (A₁ s')·(A₂ h') = sin φ₁ cos φ₂ − cos β cos φ₁ sin φ₂ = 0
//! ⇒ tan φ₂ = tan φ₁ / cos β
//! ```
//!
//! with `φ₂` in the quadrant of `φ₁` (cos β > 0). Continuous over any number of
//! turns, `φ₂ = φ₁ + atan2(sin φ₁ cos φ₁ (1 − cos β), cos β cos² φ₁ + sin² φ₁)`
//! (the tangent of the difference; the denominator is positive), and its
//! derivative is the speed ratio
//!
//! ```text
//! ω₂ / ω₁ = dφ₂/dφ₁ = cos β / (1 − sin² β cos² φ₁)
//! ```
//!
//! largest, `1 / cos β`, at `φ₁ = 0, π` (input yoke in the plane of the shafts) and
//! smallest, `cos β`, at `φ₁ = ±π/2`.
//!
//! # Redundant rows
//!
//! Two bodies have 12 velocity columns; the bearings (5 + 5 rows), the cross (4)
//! and the motor (1) give 15 rows, and the mechanism has no freedom left: the
//! Jacobian has rank 12, so **3 rows are redundant**. The reason: both bearing
//! axes pass through the joint centre, so the bearings alone keep each shaft's
//! end point at the centre whatever the shafts' angles — the cross's three
//! spherical rows repeat what the bearings already impose (its perpendicularity
//! row is the one that couples the shafts). Which three rows the rank-revealing
//! factorisation drops is its choice among the nine dependent translational rows:
//! here it keeps the cross's and drops three of the bearings' spherical rows,
//! which three changing with the configuration; [`sweep`] returns them. They are
//! consistent, so assembly and velocity analysis succeed. (A real
//! shaft has the same redundancy; it is why one bearing is made a floating one.)

// `AnalysisError` is returned by value, as in `joint_runtime` (it carries the worst rows).

use joint_runtime::analysis::{AnalysisError, Assembly, AssemblyOptions, RowInfo, assemble, velocities};
use joint_runtime::nalgebra::{UnitQuaternion, Vector3};
use joint_runtime::record::Trajectory;
use joint_runtime::{AxisFrame, OmegaBody, Ramp, Scene, SparseJacobian, SystemState};

/// The Cardan shaft (see the module documentation): bodies `input`, `output`;
/// joints `input_bearing`, `output_bearing` (revolute to the ground), `cross`
/// (universal) and `motor` (rotational driver of the input).
#[derive(Scene, Clone, Copy, Debug)]
#[scene(gravity = [0, 0, -9.81], coordinates = both)]
#[body(input, mass = 2.0, inertia = [0.001, 0.17, 0.17])]
#[body(output, mass = 2.0, inertia = [0.001, 0.17, 0.17])]
#[joint(input_bearing = revolute(ground, input), axis1 = [1, 0, 0], axis2 = [1, 0, 0], rho1 = [-0.5, 0, 0], rho2 = [0, 0, 0])]
#[joint(output_bearing = revolute(ground, output), axis1 = output_axis, axis2 = [1, 0, 0], rho1 = output_centre, rho2 = [0, 0, 0])]
#[joint(cross = universal(input, output), s = [0, 1, 0], h = [0, 0, 1], rho1 = [0.5, 0, 0], rho2 = [-0.5, 0, 0])]
#[joint(motor = rotational_driver(ground, input), axis1 = [1, 0, 0], axis2 = [1, 0, 0], theta = drive)]
pub struct CardanShaft {
    /// The output bearing's axis `u = (cos β, sin β, 0)` (ground).
    output_axis: AxisFrame<f64>,
    /// The output bearing's centre `0.5 u` (ground), the output's centre of mass.
    output_centre: Vector3<f64>,
    /// The motor: `θ(t) = ω₁ t`.
    drive: Ramp,
    /// β.
    bend: f64,
}

impl CardanShaft {
    /// A shaft bent by `bend` (radians, `0 ≤ β < π/2`) whose input turns at
    /// `input_speed` rad/s; `None` for a bend outside that range or non-finite inputs.
    pub fn new(bend: f64, input_speed: f64) -> Option<Self> {
        if !(bend.is_finite() && (0.0..core::f64::consts::FRAC_PI_2).contains(&bend) && input_speed.is_finite()) {
            return None;
        }
        let u = Vector3::new(bend.cos(), bend.sin(), 0.0);
        Some(CardanShaft {
            output_axis: AxisFrame::new(u)?,
            output_centre: u * 0.5,
            drive: Ramp { start: 0.0, rate: input_speed },
            bend,
        })
    }

    /// β, radians.
    pub fn bend(&self) -> f64 {
        self.bend
    }

    /// The input speed ω₁, rad/s.
    pub fn input_speed(&self) -> f64 {
        self.drive.rate
    }

    /// The assembled reference configuration at `t = 0` (both angles zero), at rest.
    pub fn reference_state(&self) -> CardanShaftState {
        let still = Vector3::zeros();
        let output = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), self.bend);
        SystemState {
            bodies: [
                OmegaBody::from_rotation(Vector3::new(-0.5, 0.0, 0.0), &UnitQuaternion::identity(), still, still),
                OmegaBody::from_rotation(self.output_centre, &output, still, still),
            ],
            t: 0.0,
        }
    }
}

/// The closed-form output angle `φ₂(φ₁)` of a Cardan joint bent by `bend`
/// (`tan φ₂ = tan φ₁ / cos β`), continuous in `φ₁` (no quadrant jumps).
pub fn output_angle(input_angle: f64, bend: f64) -> f64 {
    let (s, c) = input_angle.sin_cos();
    let cb = bend.cos();
    input_angle + (s * c * (1.0 - cb)).atan2(cb * c * c + s * s)
}

/// The closed-form speed ratio `ω₂/ω₁ = cos β / (1 − sin² β cos² φ₁)`, the
/// derivative of [`output_angle`].
pub fn speed_ratio(input_angle: f64, bend: f64) -> f64 {
    let c = input_angle.cos();
    let sb = bend.sin();
    bend.cos() / (1.0 - sb * sb * c * c)
}

/// `x` wrapped into `(−π, π]`.
pub fn wrap(x: f64) -> f64 {
    let two_pi = 2.0 * core::f64::consts::PI;
    let y = x - two_pi * (x / two_pi).round();
    if y <= -core::f64::consts::PI { y + two_pi } else { y }
}

/// The rotation angle of a shaft about its own x axis, measured from its
/// reference orientation `reference` (the shaft's frame at angle zero): the angle
/// of the body's y axis from the reference's y axis towards the reference's z axis.
/// In `(−π, π]`.
pub fn shaft_angle(body: &OmegaBody<f64>, reference: &UnitQuaternion<f64>) -> f64 {
    let y = body.rotation_matrix() * Vector3::y();
    let (ry, rz) = (reference * Vector3::y(), reference * Vector3::z());
    y.dot(&rz).atan2(y.dot(&ry))
}

/// Moves every body along its velocity for `dt` (first order: `r += ṙ dt`,
/// `p ← p ⊗ q(ω' dt)`): the predictor before assembling the next configuration.
pub fn predict<const NB: usize>(state: &mut SystemState<NB>, dt: f64) {
    for b in state.bodies.iter_mut() {
        b.r += b.rdot * dt;
        b.turn(&(b.omega * dt));
    }
}

/// Step `k` of a sweep at constant input speed: the state moved on by `dt`
/// ([`predict`], after the first step), set to `t = k dt`, assembled and given
/// the velocities of the driven motion. Records the redundant rows of the first
/// velocity analysis in `first` and every distinct list of redundant rows of
/// either analysis in `variants`.
///
/// # Errors
/// Those of [`assemble`] and [`velocities`].
pub fn sweep_step<S, const NB: usize, const NV: usize, const M: usize, const NNZ: usize>(
    scene: &S,
    state: &mut SystemState<NB>,
    (k, dt): (usize, f64),
    first: &mut Vec<RowInfo>,
    variants: &mut Vec<Vec<RowInfo>>,
) -> Result<Assembly<M>, AnalysisError>
where
    S: Scene<NB, NV, M> + SparseJacobian<NB, NNZ>,
{
    if k > 0 {
        predict(state, dt);
    }
    state.t = k as f64 * dt;
    let a = assemble(scene, state, &AssemblyOptions::default())?;
    let v = velocities(scene, state)?;
    if k == 0 {
        *first = v.redundant.as_slice().to_vec();
    }
    for rows in [a.redundant.as_slice(), v.redundant.as_slice()] {
        if !variants.iter().any(|x| x.as_slice() == rows) {
            variants.push(rows.to_vec());
        }
    }
    Ok(a)
}

/// One configuration of the sweep.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// Time, s.
    pub t: f64,
    /// The motor's angle θ(t) = φ₁, rad.
    pub input_angle: f64,
    /// φ₁ measured on the assembled input shaft, unwrapped, rad.
    pub measured_input_angle: f64,
    /// The input's spin ω₁' (x component of its body angular velocity), rad/s.
    pub input_speed: f64,
    /// φ₂ measured on the assembled output shaft, unwrapped, rad.
    pub output_angle: f64,
    /// The output's spin ω₂' (x), rad/s.
    pub output_speed: f64,
    /// [`output_angle`] at φ₁.
    pub closed_angle: f64,
    /// ω₁ × [`speed_ratio`] at φ₁.
    pub closed_speed: f64,
    /// Newton iterations of the assembly from the predicted configuration.
    pub iterations: usize,
}

/// The kinematic analysis of one bent shaft over one turn of the input.
#[derive(Clone, Debug, PartialEq)]
pub struct Sweep {
    /// β, radians.
    pub bend: f64,
    /// ω₁, rad/s.
    pub input_speed: f64,
    /// One sample per input angle `2π k / steps`, `k = 0..steps`.
    pub samples: Vec<Sample>,
    /// The redundant rows found by the velocity analysis at the first sample.
    pub redundant: Vec<RowInfo>,
    /// Every distinct list of redundant rows the assemblies and velocity analyses
    /// of the sweep reported, in order of first appearance (the factorisation's
    /// pivoting picks which of the dependent rows to drop, and the pick may change
    /// with the configuration; the number does not).
    pub redundant_variants: Vec<Vec<RowInfo>>,
    /// max |φ₂ − φ₂,closed|, rad.
    pub max_angle_error: f64,
    /// max |ω₂ − ω₂,closed|, rad/s.
    pub max_speed_error: f64,
    /// max |φ₁,measured − θ(t)|, rad (the driver's accuracy).
    pub max_input_error: f64,
    /// min ω₂/ω₁ over the samples.
    pub min_ratio: f64,
    /// max ω₂/ω₁ over the samples.
    pub max_ratio: f64,
    /// Largest ‖Φ‖ after assembly.
    pub max_residual: f64,
    /// The assembled states, to write as CSV or an animated SVG.
    pub trajectory: Trajectory<2>,
}

/// Kinematic analysis of the Cardan shaft bent by `bend` over one turn of the
/// input at `input_speed` rad/s, in `steps` equal steps: at each step set the
/// time, predict from the previous velocities, [`assemble`], then [`velocities`];
/// read φ₂ and ω₂ off the output and compare with the closed form.
///
/// # Errors
/// [`AnalysisError::BadOption`] (`"bend"`, `"input_speed"`, `"steps"`) for a bend
/// outside `[0, π/2)`, a zero or non-finite speed or no steps; any error of the analyses.
pub fn sweep(bend: f64, input_speed: f64, steps: usize) -> Result<Sweep, AnalysisError> {
    if steps == 0 {
        return Err(AnalysisError::BadOption { name: "steps" });
    }
    if !(input_speed.is_finite() && input_speed != 0.0) {
        return Err(AnalysisError::BadOption { name: "input_speed" });
    }
    let scene = CardanShaft::new(bend, input_speed).ok_or(AnalysisError::BadOption { name: "bend" })?;
    let input_ref = UnitQuaternion::identity();
    let output_ref = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), bend);
    let period = 2.0 * core::f64::consts::PI / input_speed.abs();
    let dt = period / steps as f64;
    let mut state = scene.reference_state();
    let mut out = Sweep {
        bend,
        input_speed,
        samples: Vec::with_capacity(steps),
        redundant: Vec::new(),
        redundant_variants: Vec::new(),
        max_angle_error: 0.0,
        max_speed_error: 0.0,
        max_input_error: 0.0,
        min_ratio: f64::INFINITY,
        max_ratio: f64::NEG_INFINITY,
        max_residual: 0.0,
        trajectory: Trajectory::new(&scene),
    };
    let (mut last_in, mut last_out) = (0.0, 0.0);
    for k in 0..steps {
        let a = sweep_step(&scene, &mut state, (k, dt), &mut out.redundant, &mut out.redundant_variants)?;
        let t = state.t;
        out.max_residual = out.max_residual.max(a.residual);
        // Unwrap: each step moves an angle by less than π.
        let phi1 = last_in + wrap(shaft_angle(&state.bodies[0], &input_ref) - last_in);
        let phi2 = last_out + wrap(shaft_angle(&state.bodies[1], &output_ref) - last_out);
        (last_in, last_out) = (phi1, phi2);
        let theta = input_speed * t;
        let sample = Sample {
            t,
            input_angle: theta,
            measured_input_angle: phi1,
            input_speed: state.bodies[0].omega.x,
            output_angle: phi2,
            output_speed: state.bodies[1].omega.x,
            closed_angle: output_angle(theta, bend),
            closed_speed: input_speed * speed_ratio(theta, bend),
            iterations: a.iterations,
        };
        out.max_angle_error = out.max_angle_error.max((sample.output_angle - sample.closed_angle).abs());
        out.max_speed_error = out.max_speed_error.max((sample.output_speed - sample.closed_speed).abs());
        out.max_input_error = out.max_input_error.max((sample.measured_input_angle - theta).abs());
        let ratio = sample.output_speed / sample.input_speed;
        out.min_ratio = out.min_ratio.min(ratio);
        out.max_ratio = out.max_ratio.max(ratio);
        out.samples.push(sample);
        out.trajectory.record(&state);
    }
    Ok(out)
}

/// The scene's joint blocks, for reports: `name rows start..end`.
pub fn blocks() -> &'static [joint_runtime::RowBlock] {
    CardanShaft::BLOCKS
}

/// One curve of a speed plot: a label and `(input angle in degrees, ω_out/ω_in)` points.
#[derive(Clone, Debug, PartialEq)]
pub struct Curve {
    /// Legend text.
    pub label: String,
    /// The points.
    pub points: Vec<(f64, f64)>,
    /// Drawn as sparse markers instead of a line (for a curve that coincides with another).
    pub markers: bool,
}

/// Writes an SVG plot of speed ratio against input angle (0–360°), on a
/// logarithmic ratio axis, one curve per entry; creates the file's directory.
/// Written by hand (a few lines of SVG), so that the main example builds on
/// the runtime alone.
///
/// # Errors
/// Any I/O error, or nothing positive to plot, as text.
pub fn plot_speed_ratios(path: &std::path::Path, caption: &str, curves: &[Curve]) -> Result<(), String> {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for c in curves {
        for &(_, y) in &c.points {
            lo = lo.min(y);
            hi = hi.max(y);
        }
    }
    if !(lo.is_finite() && hi.is_finite() && lo > 0.0) {
        return Err("nothing positive to plot".into());
    }
    let (lo, hi) = ((lo / 1.15).ln(), (hi * 1.15).ln());
    let (left, top, width, height) = (90.0, 60.0, 840.0, 520.0);
    let x = |deg: f64| left + width * deg / 360.0;
    let y = |ratio: f64| top + height * (hi - ratio.ln()) / (hi - lo);
    let mut svg = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"960\" height=\"660\" font-family=\"sans-serif\">\n\
         <rect width=\"960\" height=\"660\" fill=\"white\"/>\n\
         <text x=\"480\" y=\"32\" font-size=\"24\" text-anchor=\"middle\">{caption}</text>\n\
         <rect x=\"{left}\" y=\"{top}\" width=\"{width}\" height=\"{height}\" fill=\"none\" stroke=\"black\"/>\n"
    );
    for deg in (0..=360).step_by(30) {
        let px = x(f64::from(deg));
        svg += &format!(
            "<line x1=\"{px}\" y1=\"{top}\" x2=\"{px}\" y2=\"{}\" stroke=\"#ddd\"/>\
             <text x=\"{px}\" y=\"{}\" font-size=\"14\" text-anchor=\"middle\">{deg}</text>\n",
            top + height,
            top + height + 20.0
        );
    }
    // Sixteen ratio ticks, evenly spaced on the logarithmic axis.
    for i in 0..=15 {
        let ratio = (lo + (hi - lo) * f64::from(i) / 15.0).exp();
        let py = y(ratio);
        svg += &format!(
            "<line x1=\"{left}\" y1=\"{py:.1}\" x2=\"{}\" y2=\"{py:.1}\" stroke=\"#ddd\"/>\
             <text x=\"{}\" y=\"{:.1}\" font-size=\"14\" text-anchor=\"end\">{ratio:.3}</text>\n",
            left + width,
            left - 8.0,
            py + 5.0
        );
    }
    svg += &format!(
        "<text x=\"480\" y=\"{}\" font-size=\"16\" text-anchor=\"middle\">input angle φ₁ (degrees)</text>\n\
         <text x=\"22\" y=\"{}\" font-size=\"16\" text-anchor=\"middle\" transform=\"rotate(-90 22 {})\">\
         output speed / input speed</text>\n",
        top + height + 48.0,
        top + height / 2.0,
        top + height / 2.0
    );
    const COLOURS: [&str; 6] = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#17becf"];
    for (i, c) in curves.iter().enumerate() {
        let colour = COLOURS[i % COLOURS.len()];
        if c.markers {
            let step = (c.points.len() / 36).max(1);
            for &(a, r) in c.points.iter().step_by(step) {
                svg += &format!(
                    "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"3\" fill=\"none\" stroke=\"{colour}\"/>\n",
                    x(a),
                    y(r)
                );
            }
        } else {
            let points: Vec<String> = c.points.iter().map(|&(a, r)| format!("{:.1},{:.1}", x(a), y(r))).collect();
            svg += &format!(
                "<polyline points=\"{}\" fill=\"none\" stroke=\"{colour}\" stroke-width=\"2\"/>\n",
                points.join(" ")
            );
        }
        let ly = top + 20.0 + 22.0 * i as f64;
        svg += &format!(
            "<line x1=\"{}\" y1=\"{ly}\" x2=\"{}\" y2=\"{ly}\" stroke=\"{colour}\" stroke-width=\"2\"/>\
             <text x=\"{}\" y=\"{}\" font-size=\"15\">{}</text>\n",
            left + width - 250.0,
            left + width - 225.0,
            left + width - 218.0,
            ly + 5.0,
            c.label
        );
    }
    svg += "</svg>\n";
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).map_err(|e| format!("creating {}: {e}", dir.display()))?;
    }
    std::fs::write(path, svg).map_err(|e| format!("writing {}: {e}", path.display()))
}

/// Draws the yokes of a shaft drawing: on body `input` across its fork at
/// `(0.5, 0, 0)` along y, on each of `outputs` across the fork at `(−0.5, 0, 0)`
/// along z (the yoke axes `s`, `h` of the crosses), so that the shafts' spin
/// shows, which their points on the axes alone do not.
pub fn mark_yokes<const NB: usize>(run: &mut Trajectory<NB>, input: usize, outputs: &[usize]) {
    let yoke = |centre: Vector3<f64>, across: Vector3<f64>| (centre - 0.15 * across, centre + 0.15 * across);
    let (a, b) = yoke(Vector3::new(0.5, 0.0, 0.0), Vector3::y());
    run.add_segment(input, a, b);
    for &body in outputs {
        let (a, b) = yoke(Vector3::new(-0.5, 0.0, 0.0), Vector3::z());
        run.add_segment(body, a, b);
    }
}
