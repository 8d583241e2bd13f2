//! Hard cases: where the numbers are hard, where the geometry is singular, and
//! where the inputs are not numbers at all.
//!
//! * The regimes of `conformance/hard.json` one by one — bodies 1e6 m from
//!   the origin, spin up to 3e3 rad/s, rotations near a half turn (`e0 ≈ 0`, both
//!   signs), Euler parameters off the unit sphere (`euler`), offsets of 1e-6 m and
//!   axes of length 1e-3 — against the 60-digit references under the
//!   conformance test's `256 ε · scale` rule, every joint and formulation; each
//!   test first checks that its inputs really are in the regime.
//! * A Cardan shaft bent towards 90°: the scene's conditioning measure (the
//!   smallest singular value of `J` over the largest) vanishes like `cos β`; the
//!   velocity analysis either matches the closed form `ω₂/ω₁ = 1/cos β` within
//!   the accuracy the measure predicts, or reports the singularity naming the
//!   motor — never a wrong velocity. The joint-level measure of a universal
//!   joint tends to zero as its yoke axes become parallel (closed form `sin²`).
//! * NaN and infinities: every generated function of every joint and formulation
//!   turns each output entry that depends on a poisoned input into NaN (or a
//!   non-finite value) without panicking; the analyses name the body and field,
//!   the joint row, or the quantity, and leave the state untouched.
//!
//! Elsewhere: the Bricard mechanism's redundant rows and the four-bar's dead
//! position (`examples/tests/bricard.rs`, `four_bar.rs`), the 10⁶-step Cardan run
//! (`examples/tests/long_run.rs`), property tests of J against num-dual and of γ
//! against differences of `J v` for every joint and formulation
//! (`derivatives.rs`, `catalogue/`).

use joint_runtime::analysis::{AnalysisError, AssemblyOptions, accelerations, assemble, velocities};
use joint_runtime::conditioning::conditioning;
use joint_runtime::dynamics::{NoLoads, Simulation, SimulationOptions};
use joint_runtime::nalgebra::{SMatrix, UnitQuaternion, Vector3};
use joint_runtime::{AxisFrame, OmegaBody, Ramp, Scene, Singularity, SystemState, TwoBodies};
use joint_tests::conformance::{self, TOLERANCE, VectorFile};
use joint_tests::joints::UniversalOmegaBody;

// ---------------------------------------------------------------------------
// hard.json, one regime at a time.

/// The cases of `hard.json` whose id names `regime` (`joint/formulation/regime/NNN`).
fn regime(name: &str) -> VectorFile {
    let mut doc = conformance::vectors("hard.json");
    doc.cases.retain(|c| c.id.split('/').nth(2) == Some(name));
    doc
}

/// What the regime checks look at in a body, or in a relative state (which has
/// no position).
struct Pose {
    r: Option<[f64; 3]>,
    p: [f64; 4],
    omega: Option<[f64; 3]>,
}

/// Every input state's bodies (or the relative state) of a document.
fn bodies(doc: &VectorFile) -> Vec<Pose> {
    doc.cases
        .iter()
        .flat_map(|c| match &c.state.relative {
            Some(rel) => vec![Pose { r: None, p: rel.p, omega: Some(rel.omega) }],
            None => {
                let bodies = [&c.state.body1, &c.state.body2].into_iter().flatten();
                bodies.map(|b| Pose { r: Some(b.r), p: b.p, omega: b.omega }).collect()
            }
        })
        .collect()
}

fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// Runs a regime through the conformance test; returns the worst error (ε·scale).
fn check_regime(name: &str, doc: &VectorFile, min_cases: usize, formulations: usize) -> f64 {
    let summary = conformance::run(doc, None, false).expect("well-formed cases");
    let mut worst = 0.0f64;
    for ((joint, form), (w, n)) in &summary.worst {
        println!("{name}: {joint}/{form}: worst {w:.3} eps*scale over {n} cases");
        worst = worst.max(*w);
    }
    println!("{name}: worst {worst:.3} eps*scale over {} cases", summary.outputs.len());
    assert!(summary.missing.is_empty(), "{name}: no generated code for {:?}", summary.missing);
    assert!(summary.failures.is_empty(), "{name}: failures:\n{}", summary.failures.join("\n"));
    assert!(worst <= TOLERANCE, "{name}: worst error {worst}");
    assert!(summary.outputs.len() >= min_cases, "{name}: only {} cases", summary.outputs.len());
    let forms: std::collections::BTreeSet<_> = summary.worst.keys().map(|(_, f)| f.clone()).collect();
    assert_eq!(forms.len(), formulations, "{name}: formulations {forms:?}");
    worst
}

#[test]
fn far_from_the_origin() {
    let doc = regime("far");
    let far = bodies(&doc).iter().filter_map(|b| b.r).map(|r| norm(&r)).fold(0.0, f64::max);
    assert!(far >= 1e5, "the regime's bodies are only {far} m out");
    check_regime("far", &doc, 150, 5);
}

#[test]
fn fast_rotation() {
    let doc = regime("fast");
    let spin = bodies(&doc).iter().filter_map(|b| b.omega).map(|w| norm(&w)).fold(0.0, f64::max);
    assert!(spin >= 1e3, "the regime spins at only {spin} rad/s");
    check_regime("fast", &doc, 150, 5);
}

#[test]
fn near_a_half_turn_both_signs() {
    let doc = regime("half_turn");
    let e0: Vec<f64> = bodies(&doc).iter().map(|b| b.p[0]).filter(|e| e.abs() < 1e-2).collect();
    assert!(e0.iter().any(|&e| e > 0.0 || (e == 0.0 && e.is_sign_positive())), "no e0 ≈ +0");
    assert!(e0.iter().any(|&e| e < 0.0 || (e == 0.0 && e.is_sign_negative())), "no e0 ≈ −0");
    check_regime("half_turn", &doc, 150, 5);
}

#[test]
fn euler_parameters_off_the_unit_sphere() {
    let doc = regime("nonunit");
    let off = bodies(&doc).iter().map(|b| (norm(&b.p) - 1.0).abs()).fold(0.0, f64::max);
    assert!(off >= 0.1, "|p| − 1 is at most {off}");
    check_regime("nonunit", &doc, 30, 1);
}

#[test]
fn tiny_offsets_and_short_axes() {
    let doc = regime("tiny");
    let (mut offset, mut axis) = (f64::INFINITY, f64::INFINITY);
    for c in &doc.cases {
        for (k, v) in c.params.vectors() {
            let n = norm(&v);
            if k.starts_with("rho") { offset = offset.min(n) } else { axis = axis.min(n) }
        }
    }
    assert!(offset <= 1e-5 && axis <= 1e-2, "offsets down to {offset}, axes down to {axis}");
    check_regime("tiny", &doc, 150, 5);
}

// ---------------------------------------------------------------------------
// A universal joint bent towards 90°.

/// A Cardan shaft like `examples/src/cardan.rs`'s, but accepting any bend.
#[derive(Scene, Clone, Copy, Debug)]
#[scene(coordinates = absolute, gravity = [0, 0, -9.81])]
#[body(input, mass = 2.0, inertia = [0.001, 0.17, 0.17])]
#[body(output, mass = 2.0, inertia = [0.001, 0.17, 0.17])]
#[joint(input_bearing = revolute(ground, input), axis1 = [1, 0, 0], axis2 = [1, 0, 0], rho1 = [-0.5, 0, 0], rho2 = [0, 0, 0])]
#[joint(output_bearing = revolute(ground, output), axis1 = output_axis, axis2 = [1, 0, 0], rho1 = output_centre, rho2 = [0, 0, 0])]
#[joint(cross = universal(input, output), s = [0, 1, 0], h = [0, 0, 1], rho1 = [0.5, 0, 0], rho2 = [-0.5, 0, 0])]
#[joint(motor = rotational_driver(ground, input), axis1 = [1, 0, 0], axis2 = [1, 0, 0], theta = drive)]
struct Bent {
    output_axis: AxisFrame<f64>,
    output_centre: Vector3<f64>,
    drive: Ramp,
}

/// The shaft bent by `degrees`, and its assembled state at `φ₁ = 0` (the phase
/// where the output turns fastest, `1/cos β` times the input), at `t = 0`.
fn bent(degrees: f64) -> (Bent, SystemState<2>) {
    let b = degrees.to_radians();
    let u = Vector3::new(b.cos(), b.sin(), 0.0);
    let scene = Bent {
        output_axis: AxisFrame::new(u).expect("a unit axis"),
        output_centre: u * 0.5,
        drive: Ramp { start: 0.0, rate: 1.0 },
    };
    let z = Vector3::zeros();
    let output = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), b);
    let state = SystemState {
        bodies: [
            OmegaBody::from_rotation(Vector3::new(-0.5, 0.0, 0.0), &UnitQuaternion::identity(), z, z),
            OmegaBody::from_rotation(u * 0.5, &output, z, z),
        ],
        t: 0.0,
    };
    (scene, state)
}

const BENDS: [f64; 10] = [60.0, 85.0, 89.0, 89.9, 89.99, 89.999, 89.9999, 89.99999, 89.999999, 90.0];

#[test]
fn cardan_conditioning_vanishes_like_cos_beta() {
    let mut ratios = Vec::new();
    for degrees in BENDS {
        let (scene, mut state) = bent(degrees);
        let a = assemble(&scene, &mut state, &AssemblyOptions::default()).expect("assembled");
        assert!(a.residual < 1e-15, "{degrees}°: |Φ| = {:e}", a.residual);
        let c = conditioning(&scene, &state, 0, 1e-10).expect("finite");
        // The singular values against nalgebra's SVD (Golub–Kahan), sorted.
        let j: SMatrix<f64, 15, 12> = scene.jacobian(&state);
        let mut reference: Vec<f64> = j.svd(false, false).singular_values.iter().copied().collect();
        reference.sort_by(|x, y| y.total_cmp(x));
        for (got, want) in c.singular_values.iter().zip(&reference) {
            assert!((got - want).abs() <= 1e-14 * reference[0], "{degrees}°: σ {got} vs {want}");
        }
        let cos = degrees.to_radians().cos();
        println!(
            "β = {degrees}°: measure {:.6e}, measure / cos β = {:.6}, rank {}",
            c.measure,
            c.measure / cos,
            c.rank
        );
        if degrees < 90.0 {
            assert_eq!(c.rank, 12, "{degrees}°: rank");
            assert!(!c.is_singular(0));
            if degrees >= 85.0 {
                ratios.push(c.measure / cos);
            }
        } else {
            assert_eq!(c.rank, 11, "at 90° the Jacobian loses a rank");
            assert!(c.is_singular(0) && c.measure < 1e-15, "measure at 90°: {:e}", c.measure);
        }
    }
    // Linear in cos β: the ratio settles to a constant (0.2994…) as β → 90°.
    let last = ratios[ratios.len() - 1];
    for r in &ratios[1..] {
        assert!((r / last - 1.0).abs() < 1e-3, "measure / cos β drifts: {ratios:?}");
    }
    assert!((ratios[0] / last - 1.0).abs() < 0.01, "{ratios:?}");
}

#[test]
fn cardan_velocity_near_90_degrees_is_right_or_reported() {
    let (mut solved, mut reported) = (0, 0);
    for degrees in BENDS {
        let (scene, mut state) = bent(degrees);
        assemble(&scene, &mut state, &AssemblyOptions::default()).expect("assembled");
        let measure = conditioning(&scene, &state, 0, 1e-10).expect("finite").measure;
        let before = state;
        match velocities(&scene, &mut state) {
            Ok(v) => {
                // The output's spin, relative to the closed form 1/cos β (input at 1 rad/s).
                let ratio = state.bodies[1].omega.x;
                let error = (ratio * degrees.to_radians().cos() - 1.0).abs();
                println!("β = {degrees}°: ω₂/ω₁ relative error {error:.2e} (measure {measure:.2e})");
                // The minimum-norm solve goes through J Jᵀ: it loses the square of
                // the condition number, which the measure predicts.
                assert!(error <= 1.0 * f64::EPSILON / (measure * measure) + 1e-14, "{degrees}°: error {error:e}");
                assert!(error <= 1e-5, "{degrees}°: an inaccurate velocity was returned as a solution: {error:e}");
                assert_eq!(v.redundant.len(), 3, "{degrees}°: the bearings' and cross's three repeated rows");
                solved += 1;
            }
            Err(AnalysisError::Inconsistent { worst, .. }) => {
                println!("β = {degrees}°: reported singular: {worst}");
                assert!(measure < 1e-5, "{degrees}°: reported singular at measure {measure:e}");
                // The driver can no longer be followed: its row, or the rows it forces.
                let rows: Vec<_> = worst.0.iter().flatten().map(|r| r.row.joint).collect();
                assert!(!rows.is_empty(), "{degrees}°: no row named");
                assert!(
                    rows.iter().all(|j| ["motor", "input_bearing", "output_bearing", "cross"].contains(j)),
                    "{rows:?}"
                );
                assert_eq!(state.bodies[1].omega, before.bodies[1].omega, "{degrees}°: the state changed");
                reported += 1;
            }
            Err(e) => panic!("{degrees}°: unexpected error {e}"),
        }
    }
    // Down to 89.999° (ratio 57 296) solved; from 89.9999° on, and at 90°, reported.
    assert_eq!((solved, reported), (6, 4));
}

#[test]
fn universal_joint_measure_tends_to_zero_as_the_yokes_align() {
    let joint = |angle: f64| UniversalOmegaBody {
        s: Vector3::new(0.0, 0.0, 2.0),
        h: Vector3::new(angle.sin(), 0.0, angle.cos()) * 0.5,
        rho1: Vector3::new(0.1, 0.2, 0.3),
        rho2: Vector3::new(-0.2, 0.1, 0.0),
    };
    let z = Vector3::zeros();
    let q = UnitQuaternion::from_euler_angles(0.3, -0.2, 0.7);
    let state = TwoBodies::new(OmegaBody::from_rotation(z, &q, z, z), OmegaBody::from_rotation(z, &q, z, z));
    for angle in [std::f64::consts::FRAC_PI_2, 0.5, 1e-2, 1e-4, 1e-8, 0.0] {
        let m = joint(angle).singularity(&state);
        let want = angle.sin().powi(2);
        // The rotated axes' cross product carries an absolute error of a few ε, so
        // sin² is good to a few ε · sin: relative accuracy ε / sin near zero.
        let eps = f64::EPSILON;
        assert!((m - want).abs() <= 8.0 * eps * angle.sin() + 4.0 * eps * eps, "angle {angle}: {m} vs {want}");
    }
}

// ---------------------------------------------------------------------------
// NaN and infinities.

/// Entries of `poisoned` where `base` and `moved` differ (they depend on the
/// input) must be non-finite; with `nan`, NaN.
fn propagated(base: &[f64], moved: &[f64], poisoned: &[f64], nan: bool) -> Result<usize, String> {
    let mut dependent = 0;
    for (i, ((b, m), p)) in base.iter().zip(moved).zip(poisoned).enumerate() {
        if b != m {
            dependent += 1;
            if (nan && !p.is_nan()) || p.is_finite() {
                return Err(format!("entry {i} depends on the input but is {p}"));
            }
        }
    }
    Ok(dependent)
}

#[test]
fn generated_functions_propagate_nan_and_infinity() {
    let doc = conformance::vectors("vectors.json");
    let groups = conformance::groups(&doc.cases, None);
    let (mut checked, mut dependent) = (0usize, 0usize);
    for ((joint, form), cs) in &groups {
        let group = joint_tests::joints::group(joint, form, cs).expect("generated").expect("parsed");
        let base = group.run();
        for field in group.fields() {
            for i in 0..3 {
                let moved = group.run_poisoned(field, i, 0.37);
                for (value, nan) in [(f64::NAN, true), (f64::INFINITY, false), (f64::NEG_INFINITY, false)] {
                    let poisoned = group.run_poisoned(field, i, value);
                    for ((b, m), p) in base.iter().zip(&moved).zip(&poisoned) {
                        // The input's value before poisoning is replaced by 0.37: an
                        // entry that changes depends on it.
                        let flat = |o: &conformance::Output| {
                            o.phi.iter().chain(o.jacobian.iter().flatten()).chain(&o.gamma).copied().collect::<Vec<_>>()
                        };
                        match propagated(&flat(b), &flat(m), &flat(p), nan) {
                            Ok(n) => dependent += n,
                            Err(e) => panic!("{joint}/{form} {}: {field}[{i}] = {value}: {e}", p.id),
                        }
                        checked += 1;
                    }
                }
            }
        }
    }
    println!("{checked} poisoned evaluations, {dependent} dependent entries all non-finite");
    assert!(checked > 10_000 && dependent > 100_000, "{checked} evaluations, {dependent} entries");
}

/// The Cardan shaft at 30°, assembled and moving.
fn moving_shaft() -> (Bent, SystemState<2>) {
    let (scene, mut state) = bent(30.0);
    assemble(&scene, &mut state, &AssemblyOptions::default()).expect("assembled");
    velocities(&scene, &mut state).expect("velocities");
    (scene, state)
}

#[test]
fn analyses_name_the_non_finite_input_and_leave_the_state_alone() {
    let (scene, good) = moving_shaft();
    let mut sim = Simulation::new(&scene, NoLoads, &[], SimulationOptions::default()).expect("options");
    let fields = ["r", "p", "rdot", "omega"];
    for (b, name) in ["input", "output"].into_iter().enumerate() {
        for field in fields {
            for value in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
                let mut bad = good;
                let body = &mut bad.bodies[b];
                match field {
                    "r" => body.r.y = value,
                    "p" => body.p[2] = value,
                    "rdot" => body.rdot.z = value,
                    _ => body.omega.x = value,
                }
                let want = AnalysisError::NonFinite { body: Some(name), field };
                let position = matches!(field, "r" | "p");
                let mut s = bad;
                let step = sim.step(&mut s, 1e-3);
                assert_eq!(step, Err(want), "step, {name}.{field} = {value}");
                assert!(same(&s, &bad), "step changed the state");
                let mut s = bad;
                assert_eq!(accelerations(&scene, &s).err(), Some(want), "accelerations, {name}.{field}");
                if position {
                    assert_eq!(assemble(&scene, &mut s, &AssemblyOptions::default()).err(), Some(want));
                    assert!(same(&s, &bad), "assemble changed the state");
                    assert_eq!(velocities(&scene, &mut s).err(), Some(want));
                    assert!(same(&s, &bad), "velocities changed the state");
                    assert_eq!(conditioning(&scene, &s, 0, 1e-10).err(), Some(want));
                }
            }
        }
    }
    let mut bad = good;
    bad.t = f64::NAN;
    let want = AnalysisError::NonFinite { body: None, field: "t" };
    assert_eq!(velocities(&scene, &mut bad.clone()).err(), Some(want));
    assert_eq!(sim.step(&mut bad, 1e-3).err(), Some(want));
    assert_eq!(want.to_string(), "non-finite input: `t` is NaN or infinite");
    let named = AnalysisError::NonFinite { body: Some("output"), field: "omega" };
    assert_eq!(named.to_string(), "non-finite input: field `omega` of body `output` is NaN or infinite");
}

/// Bitwise equality, NaN included.
fn same(a: &SystemState<2>, b: &SystemState<2>) -> bool {
    let bits = |s: &SystemState<2>| {
        let mut v = vec![s.t.to_bits()];
        for body in &s.bodies {
            for x in body.r.iter().chain(body.p.iter()).chain(body.rdot.iter()).chain(body.omega.iter()) {
                v.push(x.to_bits());
            }
        }
        v
    };
    bits(a) == bits(b)
}

#[test]
fn a_nan_parameter_is_named_by_joint_and_row() {
    let (mut scene, state) = moving_shaft();
    scene.output_centre.z = f64::NAN;
    let err = assemble(&scene, &mut state.clone(), &AssemblyOptions::default()).expect_err("NaN parameter");
    match err {
        AnalysisError::NonFiniteOutput { quantity: "Φ", row: Some(r) } => {
            assert_eq!((r.joint, r.joint_row), ("output_bearing", 2), "{err}");
            assert_eq!(err.to_string(), "the scene's Φ is not finite at row 7 (joint `output_bearing`, row 2)");
        }
        other => panic!("unexpected {other}"),
    }
    // Not clamped away by a step either.
    let mut sim = Simulation::new(&scene, NoLoads, &[], SimulationOptions::default()).expect("options");
    let mut s = state;
    assert!(matches!(sim.step(&mut s, 1e-3), Err(AnalysisError::NonFiniteOutput { .. })));
    assert!(same(&s, &state));
}

#[test]
fn zero_euler_parameters_are_an_error_not_a_rotation() {
    let (scene, state) = moving_shaft();
    let mut bad = state;
    bad.bodies[1].p = joint_runtime::nalgebra::Vector4::zeros();
    let err = assemble(&scene, &mut bad, &AssemblyOptions::default()).expect_err("zero p");
    assert_eq!(err, AnalysisError::ZeroQuaternion { body: "output" });
    assert_eq!(err.to_string(), "body `output` has zero Euler parameters");
}
