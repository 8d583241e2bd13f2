//! A steering column: wheel shaft, telescoping intermediate shaft between two
//! Cardan joints, pinion shaft.
//!
//! # The model
//!
//! Three moving bodies, each with its frame's x axis along its shaft and its
//! origin at its centre of mass:
//!
//! | body | what | in the body frame |
//! |---|---|---|
//! | `input` | steering-wheel shaft, 0.6 m | column bearing at x = 0.1, upper Cardan centre at x = 0.3 |
//! | `intermediate` | upper half of the intermediate shaft | upper Cardan centre at x = −0.2, nominal lower end at x = 0.2 |
//! | `output` | pinion shaft, 0.15 m | lower Cardan centre at x = −0.075, pinion bearing at x = 0.025 |
//!
//! and five joints, 18 rows for 18 velocity columns (a fully driven mechanism):
//!
//! | joint | kind | rows | between |
//! |---|---|---|---|
//! | `column` | `revolute` about the column axis | 5 | ground, `input` |
//! | `steering` | `rotational_driver`: the driver's steering angle θ(t) | 1 | ground, `input` |
//! | `upper_cardan` | `universal`, yokes `s = z` (input), `h = z` (intermediate) | 4 | `input`, `intermediate` |
//! | `lower_cardan` | `universal_translational`, yokes `s = z` (intermediate), `h = z` (output), sliding along `d = x` of the intermediate shaft | 3 | `intermediate`, `output` |
//! | `pinion` | `revolute` about the pinion axis | 5 | ground, `output` |
//!
//! The telescoping intermediate shaft is two halves on a spline: the lower half
//! slides along the upper half's axis and cannot turn relative to it, and the
//! lower Cardan joint connects it to the pinion shaft. The lower half's motion is
//! therefore fixed by the upper half's orientation and one sliding distance, and
//! "spline + universal joint" between the upper half and the pinion shaft is
//! exactly the notes' two-angle joint with one translational degree of freedom:
//! the lower Cardan centre (a point of the pinion shaft) stays on the line
//! through the intermediate shaft's axis (`dot-2(b)`, `dot-2(c)` with `b, c ⟂ d`,
//! `d` the intermediate axis), and the two yokes stay perpendicular
//! (`dot-1(s, h)`). The lower half is not a body of this model (its mass would
//! belong to the dynamics, not to the kinematics checked here); the module's
//! [`SplitSteeringColumn`] keeps it as a fourth body, with a `translational`
//! spline and a `universal` joint, as an independent check of that equivalence.
//! Using the UT joint between the two halves instead would be wrong: it leaves
//! them two relative rotations, which a spline does not.
//!
//! Both yokes of the intermediate shaft are its body z axis: they are in phase,
//! as on a real shaft. The two bend planes are not the same plane, so the
//! velocity fluctuations of the two joints do not cancel: the pinion runs
//! between 0.79 and 1.27 times the wheel's speed.
//!
//! The joint centres are fixed points of the bearing-held input and pinion
//! shafts, so the intermediate shaft keeps its length while the wheel turns;
//! the telescoping takes up the column's reach adjustment
//! ([`SteeringColumn::new`]'s `reach`, which moves the column bearing and the
//! upper joint along the column axis). The axes and bearing points are fields
//! read at run time; the body-frame joint points are constants in the
//! attributes, repeated as the `*_X` constants below for the closed form (the
//! tests would catch the two disagreeing).
//!
//! # The closed form
//!
//! A Cardan joint whose driving shaft (axis `a`) carries the yoke `s` and whose
//! driven shaft (axis `b`, bend `β`, `cos β = a·b`) carries the yoke `h`: with
//! `n = a × b / |a × b|`, the driving yoke at angle `φ` about `a` from `n`
//! (`s = cos φ n + sin φ a × n`) turns the driven yoke to the angle `ψ` about
//! `b` from `e = b × n` with `tan ψ = cos β tan φ` ([`cardan`]). The column's
//! output angle is two such relations composed: the input angle less the
//! angle of `n₁` gives `φ₁`; `ψ₁ = C(φ₁, β₁)`; the in-phase second yoke of the
//! intermediate shaft sits at `φ₂ = ψ₁ + δ` about the intermediate axis from
//! the second bend plane's normal `n₂` (`δ` the angle from `n₂` to `e₁`);
//! `ψ₂ = C(φ₂, β₂)`, and the output angle adds the angle of `e₂` from the pinion
//! frame's reference. The rates and accelerations follow from the derivatives
//! of `C` ([`cardan_ratio`], [`cardan_ratio_derivative`]); the intermediate
//! shaft's length is the distance between the two joint centres, which are
//! fixed points of the input and pinion axes.
//!
//! A yoke axis is a line: the constraint `s ⟂ h` does not tell `h` from `−h`, so
//! the closed form fixes the output shaft only up to half a turn. The assembled
//! mechanism takes one branch and keeps it; [`Sweep::branch`] says which.
//!
//! ```text
//! cargo run --release -p joint-examples --example steering
//! ```

use core::f64::consts::{PI, TAU};

use joint_runtime::analysis::{AnalysisError, AssemblyOptions, RowList, accelerations, assemble, velocities};
use joint_runtime::nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};
use joint_runtime::record::Trajectory;
use joint_runtime::{AxisFrame, Drive, OmegaBody, Ramp, SystemState, TimeFunction};

/// Column bearing point in the input body frame (x).
pub const INPUT_BEARING_X: f64 = 0.1;
/// Upper Cardan centre in the input body frame (x).
pub const INPUT_JOINT_X: f64 = 0.3;
/// Upper Cardan centre in the intermediate body frame (x).
pub const INTERMEDIATE_UPPER_X: f64 = -0.2;
/// Nominal lower end of the intermediate shaft's upper half (x): the point of
/// the UT joint's line through which the lower Cardan centre slides.
pub const INTERMEDIATE_LOWER_X: f64 = 0.2;
/// Lower Cardan centre in the output (pinion) body frame (x).
pub const OUTPUT_JOINT_X: f64 = -0.075;
/// Pinion bearing point in the output body frame (x).
pub const OUTPUT_BEARING_X: f64 = 0.025;

/// The column axis, pointing from the wheel down and forward (x forward, y
/// left, z up; metres), about 24° below the horizontal.
pub fn column_direction() -> Vector3<f64> {
    Vector3::new(1.0, 0.0, -0.45).normalize()
}

/// The pinion axis, pointing down, forward and slightly right.
pub fn pinion_direction() -> Vector3<f64> {
    Vector3::new(0.45, -0.1, -1.0).normalize()
}

/// The upper Cardan centre at zero reach adjustment (the origin).
pub fn upper_joint_nominal() -> Vector3<f64> {
    Vector3::zeros()
}

/// The lower Cardan centre (fixed by the pinion's bearing).
pub fn lower_joint_position() -> Vector3<f64> {
    Vector3::new(0.30, 0.12, -0.30)
}

/// The steering column: wheel shaft in its bearing, driven by the steering
/// angle `steer`; a telescoping intermediate shaft between two Cardan joints (the
/// lower one the two-angle joint with one translational degree of freedom); the
/// pinion shaft in its bearing. See the module documentation.
#[derive(joint_runtime::Scene)]
#[scene(coordinates = both)]
#[body(input, mass = 1.5, inertia = [0.0008, 0.045, 0.045])]
#[body(intermediate, mass = 0.9, inertia = [0.0003, 0.012, 0.012])]
#[body(output, mass = 0.4, inertia = [0.0001, 0.0008, 0.0008])]
#[joint(column = revolute(ground, input), axis1 = column_axis, axis2 = [1, 0, 0], rho1 = column_bearing, rho2 = [0.1, 0, 0])]
#[joint(steering = rotational_driver(ground, input), axis1 = column_axis, axis2 = [1, 0, 0], theta = steer)]
#[joint(upper_cardan = universal(input, intermediate), s = [0, 0, 1], h = [0, 0, 1], rho1 = [0.3, 0, 0], rho2 = [-0.2, 0, 0])]
#[joint(lower_cardan = universal_translational(intermediate, output), s = [0, 0, 1], h = [0, 0, 1], d = [1, 0, 0], rho1 = [0.2, 0, 0], rho2 = [-0.075, 0, 0])]
#[joint(pinion = revolute(ground, output), axis1 = pinion_axis, axis2 = [1, 0, 0], rho1 = pinion_bearing, rho2 = [0.025, 0, 0])]
pub struct SteeringColumn<F> {
    /// The driver's steering angle θ(t) (radians; the wheel shaft's turn about
    /// the column axis, measured from the column frame's `b` towards its `c`).
    pub steer: F,
    /// The column (wheel shaft) axis, ground components, with its perpendicular pair.
    pub column_axis: AxisFrame<f64>,
    /// The column bearing's centre on that axis, ground.
    pub column_bearing: Vector3<f64>,
    /// The pinion shaft axis, ground components.
    pub pinion_axis: AxisFrame<f64>,
    /// The pinion bearing's centre on that axis, ground.
    pub pinion_bearing: Vector3<f64>,
}

/// The same column with the intermediate shaft's lower half as a body of its
/// own: a `translational` spline between the two halves and a plain `universal`
/// lower Cardan joint. Four bodies, 24 rows. An independent check that the
/// two-angle joint with one translational degree of freedom of
/// [`SteeringColumn`] is the spline and the Cardan joint together.
#[derive(joint_runtime::Scene)]
#[scene(coordinates = both)]
#[body(input, mass = 1.5, inertia = [0.0008, 0.045, 0.045])]
#[body(upper_half, mass = 0.5, inertia = [0.0002, 0.006, 0.006])]
#[body(lower_half, mass = 0.4, inertia = [0.0001, 0.005, 0.005])]
#[body(output, mass = 0.4, inertia = [0.0001, 0.0008, 0.0008])]
#[joint(column = revolute(ground, input), axis1 = column_axis, axis2 = [1, 0, 0], rho1 = column_bearing, rho2 = [0.1, 0, 0])]
#[joint(steering = rotational_driver(ground, input), axis1 = column_axis, axis2 = [1, 0, 0], theta = steer)]
#[joint(upper_cardan = universal(input, upper_half), s = [0, 0, 1], h = [0, 0, 1], rho1 = [0.3, 0, 0], rho2 = [-0.2, 0, 0])]
#[joint(spline = translational(upper_half, lower_half), axis1 = [1, 0, 0], axis2 = [1, 0, 0], rho1 = [0.2, 0, 0], rho2 = [0, 0, 0])]
#[joint(lower_cardan = universal(lower_half, output), s = [0, 0, 1], h = [0, 0, 1], rho1 = [0, 0, 0], rho2 = [-0.075, 0, 0])]
#[joint(pinion = revolute(ground, output), axis1 = pinion_axis, axis2 = [1, 0, 0], rho1 = pinion_bearing, rho2 = [0.025, 0, 0])]
pub struct SplitSteeringColumn<F> {
    /// As [`SteeringColumn::steer`].
    pub steer: F,
    /// As [`SteeringColumn::column_axis`].
    pub column_axis: AxisFrame<f64>,
    /// As [`SteeringColumn::column_bearing`].
    pub column_bearing: Vector3<f64>,
    /// As [`SteeringColumn::pinion_axis`].
    pub pinion_axis: AxisFrame<f64>,
    /// As [`SteeringColumn::pinion_bearing`].
    pub pinion_bearing: Vector3<f64>,
}

/// The driven angle of a Cardan joint: `ψ` with `tan ψ = cos β tan φ`, on the
/// branch continuous with `φ` (`|ψ − φ| < π/2` for `cos β > 0`).
pub fn cardan(phi: f64, cos_bend: f64) -> f64 {
    let (s, c) = phi.sin_cos();
    phi + f64::atan2((cos_bend - 1.0) * s * c, c * c + cos_bend * s * s)
}

/// `dψ/dφ = cos β / (cos²φ + cos²β sin²φ)`.
pub fn cardan_ratio(phi: f64, cos_bend: f64) -> f64 {
    let (s, c) = phi.sin_cos();
    cos_bend / (c * c + cos_bend * cos_bend * s * s)
}

/// `d²ψ/dφ² = cos β (1 − cos²β) sin 2φ / (cos²φ + cos²β sin²φ)²`.
pub fn cardan_ratio_derivative(phi: f64, cos_bend: f64) -> f64 {
    let (s, c) = phi.sin_cos();
    let den = c * c + cos_bend * cos_bend * s * s;
    cos_bend * (1.0 - cos_bend * cos_bend) * 2.0 * s * c / (den * den)
}

/// The signed angle about the unit axis `axis` from `from` to `to` (both ⟂ `axis`).
fn angle_about(axis: &Vector3<f64>, from: &Vector3<f64>, to: &Vector3<f64>) -> f64 {
    f64::atan2(from.cross(to).dot(axis), from.dot(to))
}

/// `x` wrapped into `(−π, π]`.
pub fn wrap(x: f64) -> f64 {
    let y = x - TAU * (x / TAU).round();
    if y <= -PI { y + TAU } else { y }
}

/// A shaft's orientation: its frame's x along `frame.axis`, turned by `angle`
/// about it from the reference where its z axis is `frame.b` (so that the
/// rotational driver's angle, measured from `b` towards `c`, is `angle`).
pub fn shaft_rotation(frame: &AxisFrame<f64>, angle: f64) -> UnitQuaternion<f64> {
    let a = frame.axis.normalize();
    let reference = Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[a, -frame.c, frame.b]));
    UnitQuaternion::from_axis_angle(&joint_runtime::nalgebra::Unit::new_unchecked(a), angle)
        * UnitQuaternion::from_rotation_matrix(&reference)
}

/// The closed-form motion of the column at one steering angle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClosedForm {
    /// Pinion angle (radians, from the pinion frame's `b` towards `c`), on the
    /// closed form's branch (see the module documentation).
    pub output_angle: f64,
    /// Pinion rate.
    pub output_rate: f64,
    /// Pinion angular acceleration.
    pub output_accel: f64,
    /// Distance between the Cardan centres: the intermediate shaft's length.
    pub length: f64,
    /// Bend of the upper joint (radians).
    pub bend_upper: f64,
    /// Bend of the lower joint (radians).
    pub bend_lower: f64,
}

impl<F> SteeringColumn<F> {
    /// The documented geometry, with the column (bearing and upper joint) moved
    /// by `reach` metres along its own axis (a reach adjustment, taken up by the
    /// telescoping intermediate shaft), driven by `steer`.
    pub fn new(steer: F, reach: f64) -> Self {
        let (a, c) = (column_direction(), pinion_direction());
        let upper = upper_joint_nominal() + a * reach;
        let lower = lower_joint_position();
        SteeringColumn {
            steer,
            column_axis: AxisFrame::new(a).expect("nonzero axis"),
            column_bearing: upper - a * (INPUT_JOINT_X - INPUT_BEARING_X),
            pinion_axis: AxisFrame::new(c).expect("nonzero axis"),
            pinion_bearing: lower + c * (OUTPUT_BEARING_X - OUTPUT_JOINT_X),
        }
    }

    /// The same geometry and drive as a [`SplitSteeringColumn`].
    pub fn split(&self) -> SplitSteeringColumn<F>
    where
        F: Clone,
    {
        SplitSteeringColumn {
            steer: self.steer.clone(),
            column_axis: self.column_axis,
            column_bearing: self.column_bearing,
            pinion_axis: self.pinion_axis,
            pinion_bearing: self.pinion_bearing,
        }
    }

    /// The upper Cardan centre: a fixed point of the column axis.
    pub fn upper_joint(&self) -> Vector3<f64> {
        self.column_bearing + self.column_axis.axis.normalize() * (INPUT_JOINT_X - INPUT_BEARING_X)
    }

    /// The lower Cardan centre: a fixed point of the pinion axis.
    pub fn lower_joint(&self) -> Vector3<f64> {
        self.pinion_bearing + self.pinion_axis.axis.normalize() * (OUTPUT_JOINT_X - OUTPUT_BEARING_X)
    }

    /// The closed form at the steering angle, rate and acceleration `drive`:
    /// two Cardan relations composed (module documentation).
    pub fn closed_form(&self, drive: Drive) -> ClosedForm {
        let (fa, fc) = (self.column_axis.b, self.pinion_axis.b);
        let a = self.column_axis.axis.normalize();
        let c = self.pinion_axis.axis.normalize();
        let (upper, lower) = (self.upper_joint(), self.lower_joint());
        let b = (lower - upper).normalize();
        let (cos1, cos2) = (a.dot(&b), b.dot(&c));
        // First joint: the input yoke (the input's z, at θ from `fa`) from the bend plane's normal.
        let n1 = a.cross(&b).normalize();
        let phi1 = drive.value - angle_about(&a, &fa, &n1);
        let psi1 = cardan(phi1, cos1);
        // The intermediate's second yoke is in phase with its first: at ψ₁ about b from e₁ = b × n₁.
        let e1 = b.cross(&n1);
        let n2 = b.cross(&c).normalize();
        let phi2 = psi1 + angle_about(&b, &n2, &e1);
        let psi2 = cardan(phi2, cos2);
        // The pinion's yoke (its z) at ψ₂ about c from e₂ = c × n₂.
        let e2 = c.cross(&n2);
        let output_angle = psi2 + angle_about(&c, &fc, &e2);
        let (r1, r2) = (cardan_ratio(phi1, cos1), cardan_ratio(phi2, cos2));
        let (d1, d2) = (cardan_ratio_derivative(phi1, cos1), cardan_ratio_derivative(phi2, cos2));
        let rate1 = r1 * drive.rate;
        let accel1 = d1 * drive.rate * drive.rate + r1 * drive.accel;
        ClosedForm {
            output_angle,
            output_rate: r2 * rate1,
            output_accel: d2 * rate1 * rate1 + r2 * accel1,
            length: (lower - upper).norm(),
            bend_upper: cos1.clamp(-1.0, 1.0).acos(),
            bend_lower: cos2.clamp(-1.0, 1.0).acos(),
        }
    }

    /// A rough starting configuration for assembly at steering angle `theta`:
    /// every shaft on its nominal axis at its reference turn (the intermediate
    /// shaft not yet turned to meet its yokes, nor slid to its length).
    pub fn rough_state(&self, theta: f64) -> SteeringColumnState {
        let (upper, lower) = (self.upper_joint(), self.lower_joint());
        let a = self.column_axis.axis.normalize();
        let c = self.pinion_axis.axis.normalize();
        let mid = AxisFrame::new((lower - upper).normalize()).expect("joint centres apart");
        let zero = Vector3::zeros();
        SystemState {
            bodies: [
                OmegaBody::from_rotation(
                    upper - a * INPUT_JOINT_X,
                    &shaft_rotation(&self.column_axis, theta),
                    zero,
                    zero,
                ),
                OmegaBody::from_rotation(
                    upper - mid.axis * INTERMEDIATE_UPPER_X,
                    &shaft_rotation(&mid, theta + 0.3),
                    zero,
                    zero,
                ),
                OmegaBody::from_rotation(
                    lower - c * OUTPUT_JOINT_X,
                    &shaft_rotation(&self.pinion_axis, theta),
                    zero,
                    zero,
                ),
            ],
            t: 0.0,
        }
    }

    /// The pinion's angle in `state` (from its frame's `b` towards `c`), in `(−π, π]`.
    pub fn output_angle(&self, state: &SteeringColumnState) -> f64 {
        let z = state.bodies[2].rotation_matrix() * Vector3::z();
        f64::atan2(z.dot(&self.pinion_axis.c), z.dot(&self.pinion_axis.b))
    }

    /// The wheel shaft's angle in `state`, in `(−π, π]`.
    pub fn input_angle(&self, state: &SteeringColumnState) -> f64 {
        let z = state.bodies[0].rotation_matrix() * Vector3::z();
        f64::atan2(z.dot(&self.column_axis.c), z.dot(&self.column_axis.b))
    }
}

impl<F> SplitSteeringColumn<F> {
    /// A rough starting configuration at steering angle `theta`: that of
    /// [`SteeringColumn::rough_state`], with the lower half at the lower Cardan
    /// centre, turned as the upper half.
    pub fn rough_state(&self, theta: f64) -> SplitSteeringColumnState {
        let column = SteeringColumn {
            steer: (),
            column_axis: self.column_axis,
            column_bearing: self.column_bearing,
            pinion_axis: self.pinion_axis,
            pinion_bearing: self.pinion_bearing,
        };
        let [input, upper, output] = column.rough_state(theta).bodies;
        let lower = OmegaBody { r: column.lower_joint(), ..upper };
        SystemState { bodies: [input, upper, lower, output], t: 0.0 }
    }

    /// The pinion's angle in `state`, as [`SteeringColumn::output_angle`].
    pub fn output_angle(&self, state: &SplitSteeringColumnState) -> f64 {
        let z = state.bodies[3].rotation_matrix() * Vector3::z();
        f64::atan2(z.dot(&self.pinion_axis.c), z.dot(&self.pinion_axis.b))
    }
}

/// The point at `x` on a shaft's axis (body x), in ground.
pub fn body_point(b: &OmegaBody<f64>, x: f64) -> Vector3<f64> {
    b.point(&Vector3::new(x, 0.0, 0.0))
}

/// The intermediate shaft's length in `state`: from the upper Cardan centre (a
/// point of the intermediate shaft) to the lower one (a point of the pinion shaft).
pub fn intermediate_length(state: &SteeringColumnState) -> f64 {
    (body_point(&state.bodies[2], OUTPUT_JOINT_X) - body_point(&state.bodies[1], INTERMEDIATE_UPPER_X)).norm()
}

/// How far the lower half has slid out of its nominal position (the lower
/// Cardan centre along the intermediate axis, from the nominal lower end).
pub fn slide(state: &SteeringColumnState) -> f64 {
    let mid = &state.bodies[1];
    (mid.rotation_matrix().transpose() * (body_point(&state.bodies[2], OUTPUT_JOINT_X) - mid.r)).x
        - INTERMEDIATE_LOWER_X
}

/// One step of a [`Sweep`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// Steering (input) angle, continuous, radians.
    pub input: f64,
    /// Pinion angle from the assembled mechanism, continuous, radians.
    pub output: f64,
    /// The closed form's pinion angle, on the mechanism's branch.
    pub closed: f64,
    /// `output − closed`.
    pub error: f64,
    /// Pinion rate from velocity analysis (rad/s).
    pub rate: f64,
    /// Error of the pinion rate.
    pub rate_error: f64,
    /// Pinion angular acceleration from acceleration analysis.
    pub accel: f64,
    /// Error of the pinion angular acceleration.
    pub accel_error: f64,
    /// Intermediate shaft length from the assembled mechanism.
    pub length: f64,
    /// Its error against the distance between the joint centres.
    pub length_error: f64,
    /// The lower half's slide.
    pub slide: f64,
    /// ‖Φ‖ after assembly.
    pub residual: f64,
    /// Newton iterations.
    pub iterations: usize,
}

/// A full steering turn.
#[derive(Clone, Debug, PartialEq)]
pub struct Sweep {
    /// The samples, `steps + 1` of them from 0 to one full turn.
    pub samples: Vec<Sample>,
    /// 0 if the mechanism's pinion is on the closed form's branch, 1 if it is
    /// half a turn from it (the yoke sign; module documentation).
    pub branch: i64,
    /// The closed form at θ = 0 (bends, length).
    pub geometry: ClosedForm,
    /// Redundant rows reported by assembly, velocity or acceleration analysis:
    /// the last nonempty list over the turn, or empty if none ever was.
    pub redundant: RowList<18>,
    /// The assembled bodies at each step, for the 3D run.
    pub trajectory: Trajectory<3>,
}

impl Sweep {
    /// Largest |angle error| (radians).
    pub fn max_error(&self) -> f64 {
        self.samples.iter().map(|s| s.error.abs()).fold(0.0, f64::max)
    }
    /// Largest |rate error| (rad/s).
    pub fn max_rate_error(&self) -> f64 {
        self.samples.iter().map(|s| s.rate_error.abs()).fold(0.0, f64::max)
    }
    /// Largest |acceleration error| (rad/s²).
    pub fn max_accel_error(&self) -> f64 {
        self.samples.iter().map(|s| s.accel_error.abs()).fold(0.0, f64::max)
    }
    /// Largest |length error| (m).
    pub fn max_length_error(&self) -> f64 {
        self.samples.iter().map(|s| s.length_error.abs()).fold(0.0, f64::max)
    }
}

/// Turns the wheel through one full turn at `rate` rad/s (`steps` equal steps)
/// with the column at reach `reach`: assembles the mechanism at each step from
/// the previous one, solves for the velocities and accelerations, and compares
/// with the closed form.
///
/// # Errors
/// An analysis failed (it should not: the bends stay far from 90°).
// The runtime's error type, returned as the runtime's analyses return it (it
// carries the worst rows by value).
pub fn sweep(reach: f64, rate: f64, steps: usize) -> Result<Sweep, AnalysisError> {
    let column = SteeringColumn::new(Ramp { start: 0.0, rate }, reach);
    let options = AssemblyOptions::default().with_tolerance(1e-14);
    let geometry = column.closed_form(column.steer.eval(0.0));
    let mut state = column.rough_state(0.0);
    let mut samples = Vec::with_capacity(steps + 1);
    let mut trajectory = Trajectory::new(&column);
    let mut redundant = RowList::default();
    let mut branch = None;
    let (mut previous, mut turns) = (None::<f64>, 0.0);
    for k in 0..=steps {
        state.t = TAU / rate * k as f64 / steps as f64;
        let assembly = assemble(&column, &mut state, &options)?;
        let v = velocities(&column, &mut state)?;
        let acc = accelerations(&column, &state)?;
        for list in [assembly.redundant, v.redundant, acc.redundant] {
            if !list.is_empty() {
                redundant = list;
            }
        }
        let drive = column.steer.eval(state.t);
        let closed = column.closed_form(drive);
        // The pinion angle, made continuous.
        let raw = column.output_angle(&state);
        if let Some(p) = previous {
            turns += (wrap(raw - p) - (raw - p)) / TAU;
        }
        previous = Some(raw);
        let output = raw + TAU * turns;
        let k_branch = *branch.get_or_insert_with(|| ((output - closed.output_angle) / PI).round() as i64);
        let closed_angle = closed.output_angle + PI * k_branch as f64;
        let rate_out = state.bodies[2].omega.x;
        let accel_out = acc.vdot[15];
        let length = intermediate_length(&state);
        trajectory.record(&state);
        samples.push(Sample {
            input: drive.value,
            output,
            closed: closed_angle,
            error: wrap(output - closed_angle),
            rate: rate_out,
            rate_error: rate_out - closed.output_rate,
            accel: accel_out,
            accel_error: accel_out - closed.output_accel,
            length,
            length_error: length - closed.length,
            slide: slide(&state),
            residual: assembly.residual,
            iterations: assembly.iterations,
        });
    }
    Ok(Sweep { samples, branch: branch.unwrap_or(0).rem_euclid(2), geometry, redundant, trajectory })
}

/// The largest differences between [`SteeringColumn`] (UT joint) and
/// [`SplitSteeringColumn`] (spline and Cardan joint) over a steering turn.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SplitComparison {
    /// Pinion angle (radians, wrapped).
    pub angle: f64,
    /// Pinion rate (rad/s).
    pub rate: f64,
    /// Pinion angular acceleration (rad/s²).
    pub accel: f64,
    /// Intermediate shaft length (m): the split model's lower-half origin is the
    /// lower Cardan centre.
    pub length: f64,
    /// Redundant rows of the split model (empty when there are none).
    pub redundant: RowList<24>,
}

/// Runs both models through one full steering turn (`steps` steps at `rate`
/// rad/s, column at `reach`) and compares them step by step.
///
/// # Errors
/// An analysis of either model failed.
pub fn compare_split(reach: f64, rate: f64, steps: usize) -> Result<SplitComparison, AnalysisError> {
    let column = SteeringColumn::new(Ramp { start: 0.0, rate }, reach);
    let split = column.split();
    let options = AssemblyOptions::default().with_tolerance(1e-14);
    let (mut a, mut b) = (column.rough_state(0.0), split.rough_state(0.0));
    let mut out = SplitComparison { angle: 0.0, rate: 0.0, accel: 0.0, length: 0.0, redundant: RowList::default() };
    for k in 0..=steps {
        let t = TAU / rate * k as f64 / steps as f64;
        (a.t, b.t) = (t, t);
        assemble(&column, &mut a, &options)?;
        velocities(&column, &mut a)?;
        let acc_a = accelerations(&column, &a)?;
        let assembly = assemble(&split, &mut b, &options)?;
        let vel = velocities(&split, &mut b)?;
        let acc_b = accelerations(&split, &b)?;
        for list in [assembly.redundant, vel.redundant, acc_b.redundant] {
            if !list.is_empty() {
                out.redundant = list;
            }
        }
        let length_b = (b.bodies[2].r - body_point(&b.bodies[1], INTERMEDIATE_UPPER_X)).norm();
        out.angle = out.angle.max(wrap(column.output_angle(&a) - split.output_angle(&b)).abs());
        out.rate = out.rate.max((a.bodies[2].omega.x - b.bodies[3].omega.x).abs());
        out.accel = out.accel.max((acc_a.vdot[15] - acc_b.vdot[21]).abs());
        out.length = out.length.max((intermediate_length(&a) - length_b).abs());
    }
    Ok(out)
}
