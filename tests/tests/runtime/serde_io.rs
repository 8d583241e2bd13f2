//! The `serde` feature: every type that deserializes comes back bitwise equal
//! through JSON (serde_json with `float_roundtrip`), the reports serialize with
//! their joints named, and malformed input is rejected with a message.

#![allow(missing_docs)]

use std::fmt::Debug;

use joint_runtime::analysis::{AssemblyOptions, assemble};
use joint_runtime::dynamics::{
    Attachment, Integrator, Loads, NoLoads, Reaction, Simulation, SimulationOptions, SpringDamper, Stabilisation,
    StepReport,
};
use joint_runtime::nalgebra::{Matrix3, UnitQuaternion, Vector3, Vector4};
use joint_runtime::record::{SvgOptions, View};
use joint_runtime::{
    AxisFrame, BodyInertia, Constant, Drive, EulerBody, Formulation, Joint, OmegaBody, OneBody, Polynomial, Profile,
    Ramp, RelativeState, Scene, Sinusoid, SmoothStep, SystemState, TwoBodies,
};
use joint_tests::scenes::hanging_rods;
use serde::Serialize;
use serde::de::DeserializeOwned;

fn round_trip<T: Serialize + DeserializeOwned + PartialEq + Debug>(value: &T) -> String {
    let json = serde_json::to_string(value).expect("serializes");
    let back: T = serde_json::from_str(&json).unwrap_or_else(|e| panic!("{json} does not read back: {e}"));
    assert_eq!(&back, value, "{json}");
    json
}

fn body() -> OmegaBody<f64> {
    let q = UnitQuaternion::from_axis_angle(
        &joint_runtime::nalgebra::Unit::new_normalize(Vector3::new(1.0, 2.0, -0.5)),
        0.7,
    );
    OmegaBody::from_rotation(
        Vector3::new(0.1, -2.0, 1e-300),
        &q,
        Vector3::new(3.0, 0.0, -1.0),
        Vector3::new(0.3, 1e5, -7.0),
    )
}

#[test]
fn states_round_trip() {
    let json = round_trip(&body());
    assert!(json.starts_with(r#"{"r":[0.1,-2.0,1e-300],"p":["#), "{json}");
    let euler = EulerBody {
        r: Vector3::new(1.0, 2.0, 3.0),
        p: Vector4::new(0.9, 0.1, -0.2, 0.3),
        rdot: Vector3::x(),
        pdot: Vector4::y(),
    };
    round_trip(&euler);
    round_trip(&TwoBodies { body1: body(), body2: OmegaBody::default(), t: 0.25 });
    round_trip(&OneBody { body: euler, t: -1.0 });
    round_trip(&RelativeState::<f64> {
        delta: Vector3::x(),
        p: Vector4::x(),
        delta_dot: Vector3::y(),
        omega: Vector3::z(),
        t: 2.0,
    });
    let state = hanging_rods([0.3, -0.2, 1.1]);
    let json = round_trip(&state);
    assert!(json.contains(r#""t":0.0"#), "{json}");
    // More bodies than serde's own array impls cover (32).
    let long = SystemState { bodies: [body(); 40], t: 1.5 };
    round_trip(&long);
}

#[test]
fn options_time_functions_and_springs_round_trip() {
    let options = SimulationOptions::default()
        .with_integrator(Integrator::ImplicitMidpoint)
        .with_stabilisation(Stabilisation::Baumgarte { alpha: 5.0, beta: 7.0 })
        .with_projection(None);
    let json = round_trip(&options);
    assert!(json.contains(r#""integrator":"implicit_midpoint""#) && json.contains(r#""baumgarte""#), "{json}");
    round_trip(&SimulationOptions::default());
    round_trip(&AssemblyOptions::default().with_tolerance(1e-9));
    // Options read from a partial document keep their defaults (and will when
    // fields are added).
    let partial: SimulationOptions = serde_json::from_str(r#"{"integrator": "implicit_midpoint"}"#).expect("partial");
    assert_eq!(partial, SimulationOptions::default().with_integrator(Integrator::ImplicitMidpoint));
    assert_eq!(serde_json::from_str::<AssemblyOptions>("{}").expect("empty"), AssemblyOptions::default());
    let svg: SvgOptions = serde_json::from_str(r#"{"width": 800, "title": "run"}"#).expect("partial");
    assert_eq!(svg, SvgOptions::default().with_size(800, 480).with_title("run"));
    round_trip(&Drive { value: 1.0, rate: -2.0, accel: 3.0 });
    round_trip(&Constant(0.5));
    round_trip(&Ramp { start: 0.1, rate: 10.0 });
    round_trip(&Polynomial([1.0, 0.0, -0.5, 1.0 / 3.0]));
    round_trip(&Sinusoid { offset: 0.1, amplitude: 0.2, frequency: 3.0, phase: -1.0 });
    let step = SmoothStep { from: 0.0, to: 1.0, t0: 0.5, t1: 1.5, profile: Profile::Quintic };
    assert!(round_trip(&step).contains(r#""profile":"quintic""#));
    let spring = SpringDamper {
        a: Attachment::Ground(Vector3::new(0.0, 0.0, 1.0)),
        b: Attachment::Body { body: 2, point: Vector3::new(0.0, 0.5, 0.0) },
        stiffness: 1e4,
        damping: 3.0,
        rest_length: 0.8,
    };
    round_trip(&spring);
    let mut loads = Loads::<2>::default();
    loads.add_force_at(&hanging_rods([0.1, 0.2]), 1, &Vector3::new(1.0, 2.0, 3.0), &Vector3::new(0.0, 0.0, 0.5));
    round_trip(&loads);
}

#[test]
fn values_and_results_round_trip() {
    round_trip(&BodyInertia { mass: 2.0, inertia: Matrix3::new(1.0, 0.1, 0.0, 0.1, 2.0, 0.0, 0.0, 0.0, 3.0) });
    round_trip(&AxisFrame::new(Vector3::new(1.0, 2.0, 3.0)).expect("an axis"));
    for f in Formulation::ALL {
        assert_eq!(round_trip(&f), format!("\"{f}\""));
    }
    round_trip(&View::isometric());
    round_trip(&StepReport::default());
    let mut sim = Simulation::new(&Redundant, NoLoads, &[], SimulationOptions::default()).expect("valid");
    round_trip(&sim.energy(&hanging()));
    let report = sim.step(&mut hanging(), 1e-3).expect("steps");
    assert!(round_trip(&report).contains("constraint_residual"));
    round_trip(&Reaction { force: Vector3::x(), torque: Vector3::z() });
    let joint = joint_tests::joints::UniversalOmegaBody {
        s: Vector3::y(),
        h: Vector3::z(),
        rho1: Vector3::new(0.5, 0.0, 0.0),
        rho2: Vector3::new(-0.5, 0.0, 0.0),
    };
    let evaluation = joint.evaluate(&TwoBodies::new(body(), OmegaBody::default()));
    round_trip(&evaluation);
    round_trip(&<joint_tests::joints::UniversalOmegaBody<f64> as Joint<f64, 4, 12>>::OPS);
}

/// A pendulum on a revolute joint and a ball joint further along the hinge's
/// axis (two bearings of one shaft): three rows are redundant.
#[derive(Scene)]
#[scene(coordinates = absolute)]
#[body(link, mass = 1.0, inertia = [0.1, 0.1, 0.01])]
#[joint(hinge = revolute(ground, link), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0, 0, 0], rho2 = [0, 0, 0.5])]
#[joint(ball = spherical(ground, link), rho1 = [0, 0.2, 0], rho2 = [0, 0.2, 0.5])]
struct Redundant;

/// The link swung by 0.4 rad about the hinge, at rest: assembled.
fn hanging() -> SystemState<1> {
    let q = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), 0.4);
    let link = OmegaBody::from_rotation(q * Vector3::new(0.0, 0.0, -0.5), &q, Vector3::zeros(), Vector3::zeros());
    SystemState { bodies: [link], t: 0.0 }
}

#[test]
fn reports_serialize_with_joint_names() {
    let mut state = hanging();
    let assembly = assemble(&Redundant, &mut state, &AssemblyOptions::default()).expect("assembles");
    let json = serde_json::to_value(assembly).expect("serializes");
    let rows = json["redundant"].as_array().expect("a list of rows");
    assert_eq!(rows.len(), 3, "{json}");
    assert!(rows.iter().all(|r| r["joint"] == "hinge" || r["joint"] == "ball"), "{json}");
    assert_eq!(json["iterations"], assembly.iterations);
    assert_eq!(Redundant.phi(&state).len(), 8);
}

#[test]
fn an_analysis_error_names_its_source() {
    use std::error::Error;
    let e = joint_runtime::analysis::AnalysisError::from(joint_runtime::linalg::LinalgError::Singular { step: 4 });
    let source = e.source().expect("a factorisation error wraps its cause");
    assert_eq!(source.to_string(), "matrix is singular (zero pivot at step 4)");
    assert!(!e.to_string().contains("step 4"), "the cause is shown once, by source(): {e}");
    assert!(joint_runtime::analysis::AnalysisError::BadOption { name: "h" }.source().is_none());
}

#[test]
fn malformed_input_is_an_error() {
    let state = serde_json::to_string(&hanging_rods([0.1, 0.2])).expect("serializes");
    let e = serde_json::from_str::<SystemState<3>>(&state).expect_err("two bodies are not three");
    assert!(e.to_string().contains("an array of 3 elements"), "{e}");
    let e = serde_json::from_str::<SystemState<1>>(&state).expect_err("two bodies are not one");
    assert!(e.to_string().contains("an array of 1 elements"), "{e}");
    assert!(serde_json::from_str::<Formulation>("\"omega\"").is_err());
    assert!(
        serde_json::from_str::<OmegaBody<f64>>(r#"{"r":[1,2],"p":[1,0,0,0],"rdot":[0,0,0],"omega":[0,0,0]}"#).is_err()
    );
}
