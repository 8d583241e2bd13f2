//! The double Cardan shaft: input, intermediate and output shafts, two universal
//! joints, in the Z and W arrangements, with the intermediate shaft's yokes in
//! phase or a quarter turn out of phase.
//!
//! # The mechanism
//!
//! As in [`crate::cardan`]: the input (length 1) turns in a bearing about x, its
//! end at the first joint centre `A = 0`; the intermediate shaft (length 1, no
//! bearing, carried by the two joints) has its axis along `(cos β, sin β, 0)`, so
//! the second joint centre is `B = (cos β, sin β, 0)`; the output (length 1) turns
//! in a bearing about `u_o = (cos β_o, sin β_o, 0)` through `B`:
//!
//! - **Z arrangement**: `β_o = 0`. Input and output are parallel and offset by
//!   `sin β`; the two joints bend by `+β` and `−β`.
//! - **W arrangement**: `β_o = 2β`. Input and output meet at the angle `2β`; the
//!   intermediate shaft makes the same angle β with both.
//!
//! Each body's frame has x along its shaft; the reference orientations are
//! `I`, `R_z(β)`, `R_z(β_o)` and each shaft's angle φ is its rotation about its
//! own axis from there (`A = R_z(·) R_x(φ)`). The first joint's yokes are `y'`
//! (input) and `z'` (intermediate), as in [`crate::cardan`], so
//! `tan φ_m = tan φ₁ / cos β`.
//!
//! # Closed forms
//!
//! With `γ = β_o − β = ∓β` the bend of the second joint, the output direction seen
//! from the intermediate frame is `R_x(−φ_m) R_z(γ) R_x(φ_o)`.
//!
//! - **In phase** (the intermediate shaft's two yokes parallel: `s₂' = z'` in the
//!   intermediate, `h₂' = y'` in the output):
//!   `(0, −sin φ_m, cos φ_m)·(−sin γ cos φ_o, cos γ cos φ_o, sin φ_o) = 0`, i.e.
//!   `tan φ_o = cos β tan φ_m = tan φ₁`: **φ_o = φ₁ and ω_o = ω₁** at every
//!   angle, in both arrangements (γ enters only through cos γ = cos β).
//! - **A quarter turn out of phase** (`s₂' = y'`, `h₂' = z'`): the second joint
//!   is the first one again, `tan φ_o = tan φ_m / cos β = tan φ₁ / cos² β`, and the
//!   speed ratio is the product of the two single-joint ratios, each at its own
//!   input angle:
//!
//!   ```text
//!   ω_o/ω₁ = (dφ_o/dφ_m)(dφ_m/dφ₁) = cos β/(1 − sin²β cos²φ_m) · cos β/(1 − sin²β cos²φ₁)
//!          = cos²β / (1 − (1 − cos⁴β) cos² φ₁)
//!   ```
//!
//!   (the second form is the single-joint formula with `cos β → cos² β`), between
//!   `cos² β` and `1 / cos² β`.
//!
//! # Redundant rows
//!
//! Three bodies have 18 columns; the two bearings (5 + 5), the two crosses
//! (4 + 4) and the motor (1) give 19 rows and no freedom is left, so **one row is
//! redundant**: the bearings fix both joint centres `A` and `B` in space, and the
//! crosses' six spherical rows pin the intermediate shaft's two ends to them, so
//! its length `|AB|` is imposed twice (a real double Cardan shaft has a sliding
//! spline in its intermediate shaft for exactly this reason). The bearings plus
//! the first cross's spherical rows are *not* redundant here as they are in the
//! single shaft: the intermediate shaft has no bearing of its own.

// `AnalysisError` is returned by value, as in `joint_runtime` (it carries the worst rows).

use joint_runtime::analysis::{AnalysisError, RowInfo, velocities};
use joint_runtime::nalgebra::{UnitQuaternion, Vector3};
use joint_runtime::record::Trajectory;
use joint_runtime::{AxisFrame, OmegaBody, Ramp, Scene, SystemState};

use crate::cardan::{output_angle, shaft_angle, speed_ratio, sweep_step, wrap};

/// How the output shaft sits relative to the input.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Arrangement {
    /// Input and output parallel, offset (`β_o = 0`).
    Z,
    /// Input and output meeting at `2β` (`β_o = 2β`).
    W,
}

/// The intermediate shaft's yokes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Phasing {
    /// Both yokes of the intermediate shaft in one plane: constant velocity.
    InPhase,
    /// The yokes a quarter turn (90°) apart: the two joints' fluctuations multiply.
    Quarter,
}

/// The geometry shared by [`DoubleCardan`] and [`FreeDoubleCardan`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Geometry {
    /// β, radians.
    pub bend: f64,
    /// The arrangement.
    pub arrangement: Arrangement,
    /// The phasing.
    pub phasing: Phasing,
    /// The output's direction angle β_o (0 or 2β).
    pub output_direction: f64,
    /// The output bearing's axis `u_o` (ground).
    pub output_axis: AxisFrame<f64>,
    /// The output bearing's centre, `B + 0.5 u_o` (ground), the output's centre of mass.
    pub output_centre: Vector3<f64>,
    /// The second joint's yoke in the intermediate shaft.
    pub middle_yoke: Vector3<f64>,
    /// The second joint's yoke in the output shaft.
    pub output_yoke: Vector3<f64>,
}

impl Geometry {
    /// The geometry for `bend` (radians, `0 ≤ β < π/2`), or `None` outside that range.
    pub fn new(bend: f64, arrangement: Arrangement, phasing: Phasing) -> Option<Self> {
        if !(bend.is_finite() && (0.0..core::f64::consts::FRAC_PI_2).contains(&bend)) {
            return None;
        }
        let output_direction = match arrangement {
            Arrangement::Z => 0.0,
            Arrangement::W => 2.0 * bend,
        };
        let b = Vector3::new(bend.cos(), bend.sin(), 0.0);
        let u = Vector3::new(output_direction.cos(), output_direction.sin(), 0.0);
        let (middle_yoke, output_yoke) = match phasing {
            Phasing::InPhase => (Vector3::z(), Vector3::y()),
            Phasing::Quarter => (Vector3::y(), Vector3::z()),
        };
        Some(Geometry {
            bend,
            arrangement,
            phasing,
            output_direction,
            output_axis: AxisFrame::new(u)?,
            output_centre: b + u * 0.5,
            middle_yoke,
            output_yoke,
        })
    }

    /// The reference orientations of the input, intermediate and output shafts.
    pub fn references(&self) -> [UnitQuaternion<f64>; 3] {
        [
            UnitQuaternion::identity(),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), self.bend),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), self.output_direction),
        ]
    }

    /// The assembled reference configuration (all angles zero) at `t = 0`, at rest.
    pub fn reference_state(&self) -> DoubleCardanState {
        let still = Vector3::zeros();
        let [qi, qm, qo] = self.references();
        let middle = Vector3::new(self.bend.cos(), self.bend.sin(), 0.0) * 0.5;
        SystemState {
            bodies: [
                OmegaBody::from_rotation(Vector3::new(-0.5, 0.0, 0.0), &qi, still, still),
                OmegaBody::from_rotation(middle, &qm, still, still),
                OmegaBody::from_rotation(self.output_centre, &qo, still, still),
            ],
            t: 0.0,
        }
    }
}

/// The driven double Cardan shaft: bodies `input`, `middle`, `output`; joints
/// `input_bearing`, `output_bearing` (revolute to the ground), `first`, `second`
/// (universal) and `motor` (rotational driver of the input, `θ = ω₁ t`).
#[derive(Scene, Clone, Copy, Debug)]
#[scene(gravity = [0, 0, -9.81], second_order, coordinates = both)]
#[body(input, mass = 2.0, inertia = [0.001, 0.17, 0.17])]
#[body(middle, mass = 2.0, inertia = [0.001, 0.17, 0.17])]
#[body(output, mass = 2.0, inertia = [0.001, 0.17, 0.17])]
#[joint(input_bearing = revolute(ground, input), axis1 = [1, 0, 0], axis2 = [1, 0, 0], rho1 = [-0.5, 0, 0], rho2 = [0, 0, 0])]
#[joint(output_bearing = revolute(ground, output), axis1 = output_axis, axis2 = [1, 0, 0], rho1 = output_centre, rho2 = [0, 0, 0])]
#[joint(first = universal(input, middle), s = [0, 1, 0], h = [0, 0, 1], rho1 = [0.5, 0, 0], rho2 = [-0.5, 0, 0])]
#[joint(second = universal(middle, output), s = middle_yoke, h = output_yoke, rho1 = [0.5, 0, 0], rho2 = [-0.5, 0, 0])]
#[joint(motor = rotational_driver(ground, input), axis1 = [1, 0, 0], axis2 = [1, 0, 0], theta = drive)]
pub struct DoubleCardan {
    /// The output bearing's axis.
    output_axis: AxisFrame<f64>,
    /// The output bearing's centre.
    output_centre: Vector3<f64>,
    /// The second joint's yoke in the intermediate shaft.
    middle_yoke: Vector3<f64>,
    /// The second joint's yoke in the output shaft.
    output_yoke: Vector3<f64>,
    /// The motor.
    drive: Ramp,
    /// Everything above, as built.
    geometry: Geometry,
}

impl DoubleCardan {
    /// The shaft of `geometry` with its input driven at `input_speed` rad/s.
    pub fn new(geometry: Geometry, input_speed: f64) -> Self {
        DoubleCardan {
            output_axis: geometry.output_axis,
            output_centre: geometry.output_centre,
            middle_yoke: geometry.middle_yoke,
            output_yoke: geometry.output_yoke,
            drive: Ramp { start: 0.0, rate: input_speed },
            geometry,
        }
    }

    /// The geometry.
    pub fn geometry(&self) -> &Geometry {
        &self.geometry
    }

    /// The reference configuration at `t = 0` with the velocities of the driven
    /// motion (velocity analysis): the consistent initial state of a simulation.
    ///
    /// # Errors
    /// Those of [`velocities`].
    pub fn initial_state(&self) -> Result<DoubleCardanState, AnalysisError> {
        let mut state = self.geometry.reference_state();
        velocities(self, &mut state)?;
        Ok(state)
    }
}

/// The same shaft without the motor: one degree of freedom, for dynamics (the
/// input spins freely in its bearing). Joints `input_bearing`, `output_bearing`,
/// `first`, `second`; gravity along −z.
#[derive(Scene, Clone, Copy, Debug)]
#[scene(gravity = [0, 0, -9.81], second_order, coordinates = both)]
#[body(input, mass = 2.0, inertia = [0.001, 0.17, 0.17])]
#[body(middle, mass = 2.0, inertia = [0.001, 0.17, 0.17])]
#[body(output, mass = 2.0, inertia = [0.001, 0.17, 0.17])]
#[joint(input_bearing = revolute(ground, input), axis1 = [1, 0, 0], axis2 = [1, 0, 0], rho1 = [-0.5, 0, 0], rho2 = [0, 0, 0])]
#[joint(output_bearing = revolute(ground, output), axis1 = output_axis, axis2 = [1, 0, 0], rho1 = output_centre, rho2 = [0, 0, 0])]
#[joint(first = universal(input, middle), s = [0, 1, 0], h = [0, 0, 1], rho1 = [0.5, 0, 0], rho2 = [-0.5, 0, 0])]
#[joint(second = universal(middle, output), s = middle_yoke, h = output_yoke, rho1 = [0.5, 0, 0], rho2 = [-0.5, 0, 0])]
pub struct FreeDoubleCardan {
    /// The output bearing's axis.
    output_axis: AxisFrame<f64>,
    /// The output bearing's centre.
    output_centre: Vector3<f64>,
    /// The second joint's yoke in the intermediate shaft.
    middle_yoke: Vector3<f64>,
    /// The second joint's yoke in the output shaft.
    output_yoke: Vector3<f64>,
}

impl FreeDoubleCardan {
    /// The free shaft of `geometry`.
    pub fn new(geometry: &Geometry) -> Self {
        FreeDoubleCardan {
            output_axis: geometry.output_axis,
            output_centre: geometry.output_centre,
            middle_yoke: geometry.middle_yoke,
            output_yoke: geometry.output_yoke,
        }
    }
}

/// The closed-form intermediate and output angles `(φ_m, φ_o)` at input angle φ₁.
pub fn closed_angles(input_angle: f64, bend: f64, phasing: Phasing) -> (f64, f64) {
    let middle = output_angle(input_angle, bend);
    match phasing {
        Phasing::InPhase => (middle, input_angle),
        Phasing::Quarter => (middle, output_angle(middle, bend)),
    }
}

/// The closed-form output speed ratio ω_o/ω₁: 1 in phase; a quarter turn out of
/// phase, the product of the two single-joint ratios ([`speed_ratio`]) at φ₁ and
/// at φ_m.
pub fn closed_ratio(input_angle: f64, bend: f64, phasing: Phasing) -> f64 {
    match phasing {
        Phasing::InPhase => 1.0,
        Phasing::Quarter => speed_ratio(input_angle, bend) * speed_ratio(output_angle(input_angle, bend), bend),
    }
}

/// The quarter-phase ratio in one formula, `cos²β / (1 − (1 − cos⁴β) cos²φ₁)`.
pub fn quarter_ratio_direct(input_angle: f64, bend: f64) -> f64 {
    let c2 = bend.cos().powi(2);
    let cp = input_angle.cos();
    c2 / (1.0 - (1.0 - c2 * c2) * cp * cp)
}

/// One configuration of the sweep.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// Input angle θ(t) = φ₁, rad.
    pub input_angle: f64,
    /// φ_m measured, unwrapped, rad.
    pub middle_angle: f64,
    /// ω_m' (x), rad/s.
    pub middle_speed: f64,
    /// φ_o measured, unwrapped, rad.
    pub output_angle: f64,
    /// ω_o' (x), rad/s.
    pub output_speed: f64,
    /// Closed-form φ_m.
    pub closed_middle_angle: f64,
    /// Closed-form φ_o.
    pub closed_output_angle: f64,
    /// Closed-form ω_m = ω₁ · [`speed_ratio`] at φ₁.
    pub closed_middle_speed: f64,
    /// Closed-form ω_o = ω₁ · [`closed_ratio`].
    pub closed_output_speed: f64,
}

/// The kinematic analysis of one double Cardan shaft over one input turn.
#[derive(Clone, Debug, PartialEq)]
pub struct Sweep {
    /// The geometry.
    pub geometry: Geometry,
    /// ω₁, rad/s.
    pub input_speed: f64,
    /// The samples, input angles `2π k / steps`.
    pub samples: Vec<Sample>,
    /// Redundant rows of the velocity analysis at the first sample.
    pub redundant: Vec<RowInfo>,
    /// Every distinct list of redundant rows the analyses of the sweep reported,
    /// in order of first appearance (see [`crate::cardan::Sweep::redundant_variants`]).
    pub redundant_variants: Vec<Vec<RowInfo>>,
    /// max |φ_o − φ_o,closed| and |φ_m − φ_m,closed|, rad.
    pub max_angle_error: f64,
    /// max |ω_o − ω_o,closed| and |ω_m − ω_m,closed|, rad/s.
    pub max_speed_error: f64,
    /// max |ω_o − ω₁|, rad/s: the departure from constant velocity.
    pub max_output_fluctuation: f64,
    /// min ω_o/ω₁.
    pub min_ratio: f64,
    /// max ω_o/ω₁.
    pub max_ratio: f64,
    /// max |product of single-joint ratios − direct formula| (the derivation's check).
    pub max_formula_difference: f64,
    /// The assembled states, to write as CSV or an animated SVG.
    pub trajectory: Trajectory<3>,
}

/// Kinematic analysis over one input turn in `steps` steps: set the time,
/// predict, [`assemble`](joint_runtime::analysis::assemble), [`velocities`]; compare both shafts' angles and
/// speeds with the closed forms.
///
/// # Errors
/// [`AnalysisError::BadOption`] for a bend outside `[0, π/2)`, a zero or
/// non-finite speed or no steps; any error of the analyses.
pub fn sweep(
    bend: f64,
    arrangement: Arrangement,
    phasing: Phasing,
    input_speed: f64,
    steps: usize,
) -> Result<Sweep, AnalysisError> {
    if steps == 0 {
        return Err(AnalysisError::BadOption { name: "steps" });
    }
    if !(input_speed.is_finite() && input_speed != 0.0) {
        return Err(AnalysisError::BadOption { name: "input_speed" });
    }
    let geometry = Geometry::new(bend, arrangement, phasing).ok_or(AnalysisError::BadOption { name: "bend" })?;
    let scene = DoubleCardan::new(geometry, input_speed);
    let [_, qm, qo] = geometry.references();
    let dt = 2.0 * core::f64::consts::PI / input_speed.abs() / steps as f64;
    let mut state = geometry.reference_state();
    let mut out = Sweep {
        geometry,
        input_speed,
        samples: Vec::with_capacity(steps),
        redundant: Vec::new(),
        redundant_variants: Vec::new(),
        max_angle_error: 0.0,
        max_speed_error: 0.0,
        max_output_fluctuation: 0.0,
        min_ratio: f64::INFINITY,
        max_ratio: f64::NEG_INFINITY,
        max_formula_difference: 0.0,
        trajectory: Trajectory::new(&scene),
    };
    let (mut last_m, mut last_o) = (0.0, 0.0);
    for k in 0..steps {
        sweep_step(&scene, &mut state, (k, dt), &mut out.redundant, &mut out.redundant_variants)?;
        let t = state.t;
        let phi_m = last_m + wrap(shaft_angle(&state.bodies[1], &qm) - last_m);
        let phi_o = last_o + wrap(shaft_angle(&state.bodies[2], &qo) - last_o);
        (last_m, last_o) = (phi_m, phi_o);
        let theta = input_speed * t;
        let (cm, co) = closed_angles(theta, bend, phasing);
        let s = Sample {
            input_angle: theta,
            middle_angle: phi_m,
            middle_speed: state.bodies[1].omega.x,
            output_angle: phi_o,
            output_speed: state.bodies[2].omega.x,
            closed_middle_angle: cm,
            closed_output_angle: co,
            closed_middle_speed: input_speed * speed_ratio(theta, bend),
            closed_output_speed: input_speed * closed_ratio(theta, bend, phasing),
        };
        out.max_angle_error = out
            .max_angle_error
            .max((s.output_angle - s.closed_output_angle).abs())
            .max((s.middle_angle - s.closed_middle_angle).abs());
        out.max_speed_error = out
            .max_speed_error
            .max((s.output_speed - s.closed_output_speed).abs())
            .max((s.middle_speed - s.closed_middle_speed).abs());
        out.max_output_fluctuation = out.max_output_fluctuation.max((s.output_speed - input_speed).abs());
        let ratio = s.output_speed / input_speed;
        out.min_ratio = out.min_ratio.min(ratio);
        out.max_ratio = out.max_ratio.max(ratio);
        out.max_formula_difference = out
            .max_formula_difference
            .max((speed_ratio(theta, bend) * speed_ratio(cm, bend) - quarter_ratio_direct(theta, bend)).abs());
        out.samples.push(s);
        out.trajectory.record(&state);
    }
    Ok(out)
}
