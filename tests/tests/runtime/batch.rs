//! Batches (`joint_runtime::batch`): scalar, SIMD lanes and rayon against
//! per-state `evaluate`, bitwise, at random but deterministic states.
//!
//! * `evaluate_batch` is `evaluate` state by state.
//! * `evaluate_batch_simd` with `WideF64x4` (4 lanes) and `WideF32x8` (8 lanes)
//!   equals the scalar batch lane by lane, bitwise, for a universal joint in
//!   `omega_body`, `euler` and `relative_b2`, a grounded joint, a revolute joint
//!   in `relative_b1` and a translational driver; a rotational driver within a few
//!   ulps (`wide`'s `sin`/`cos` is its own polynomial).
//! * Tails: 0, 1, 3, 5, 9 and 1000 states; the report counts packs and padding.
//! * Mixed times in a pack: `Lanes::pack` refuses, the batch splits the pack and
//!   stays exact.
//! * rayon (`_par`) equals the scalar batch; a length mismatch is an error and
//!   writes nothing.

use joint_runtime::batch::{
    BatchError, LaneScalar, Lanes, MixedTimes, WideF32x8, WideF64x4, evaluate_batch, evaluate_batch_par,
    evaluate_batch_simd, evaluate_batch_simd_par, splat,
};
use joint_runtime::nalgebra::{RealField, SMatrix, SVector, Vector3};
use joint_runtime::{
    AxisFrame, EulerBody, Evaluation, Joint, OmegaBody, OneBody, Ramp, RelativeState, Sinusoid, TimeFunction, TwoBodies,
};
use joint_tests::joints::{RevoluteRelativeB1, UniversalEuler, UniversalOmegaBody, UniversalRelativeB2};
use joint_tests::random::Rng;

// ---------------------------------------------------------------------------
// Joints.
// ---------------------------------------------------------------------------

/// Cylindrical joint with body 1 grounded, `omega_inertial`: a `OneBody` state.
#[derive(Joint, Clone, Copy, Debug)]
#[joint(cylindrical, formulation = omega_inertial, ground = body1)]
struct SleeveGrounded<T> {
    f: Vector3<T>,
    g: Vector3<T>,
    h: Vector3<T>,
    rho1: Vector3<T>,
    rho2: Vector3<T>,
}

/// A linear actuator in `euler`, driven by a ramp: reads `state.t`.
#[derive(Joint, Clone, Copy, Debug)]
#[joint(translational_driver, formulation = euler)]
struct Actuator<T> {
    h: Vector3<T>,
    rho1: Vector3<T>,
    rho2: Vector3<T>,
    x: Ramp,
}

/// A motor in `omega_body`, θ(t) a sinusoid: `sin`/`cos` on the lane type.
#[derive(Joint, Clone, Copy, Debug)]
#[joint(rotational_driver, formulation = omega_body)]
struct Motor<T> {
    f: Vector3<T>,
    g: Vector3<T>,
    k: Vector3<T>,
    theta: Sinusoid,
}

// ---------------------------------------------------------------------------
// Deterministic random states.
// ---------------------------------------------------------------------------

fn cardan_params(rng: &mut Rng) -> [Vector3<f64>; 4] {
    [rng.v3(1.0).normalize(), rng.v3(1.0).normalize(), rng.v3(0.5), rng.v3(0.5)]
}

fn cardan_omega_b(rng: &mut Rng) -> UniversalOmegaBody<f64> {
    let [s, h, rho1, rho2] = cardan_params(rng);
    UniversalOmegaBody { s, h, rho1, rho2 }
}

fn wide_omega_b<E: LaneScalar<N>, const N: usize>(j: &UniversalOmegaBody<E>) -> UniversalOmegaBody<E::Wide> {
    UniversalOmegaBody { s: splat(&j.s), h: splat(&j.h), rho1: splat(&j.rho1), rho2: splat(&j.rho2) }
}

fn f32_omega_b(j: &UniversalOmegaBody<f64>) -> UniversalOmegaBody<f32> {
    UniversalOmegaBody { s: j.s.cast(), h: j.h.cast(), rho1: j.rho1.cast(), rho2: j.rho2.cast() }
}

fn f32_body(b: &OmegaBody<f64>) -> OmegaBody<f32> {
    OmegaBody { r: b.r.cast(), p: b.p.cast(), rdot: b.rdot.cast(), omega: b.omega.cast() }
}

fn two_omega(rng: &mut Rng, t: f64) -> TwoBodies<OmegaBody<f64>> {
    TwoBodies { body1: rng.omega_body(), body2: rng.omega_body(), t }
}

fn two_euler(rng: &mut Rng, t: f64) -> TwoBodies<EulerBody<f64>> {
    TwoBodies { body1: rng.euler_body(), body2: rng.euler_body(), t }
}

// ---------------------------------------------------------------------------
// Comparisons.
// ---------------------------------------------------------------------------

trait Bits: Copy {
    fn bits(self) -> u64;
    fn value(self) -> f64;
}

impl Bits for f64 {
    fn bits(self) -> u64 {
        self.to_bits()
    }
    fn value(self) -> f64 {
        self
    }
}

impl Bits for f32 {
    fn bits(self) -> u64 {
        u64::from(self.to_bits())
    }
    fn value(self) -> f64 {
        f64::from(self)
    }
}

fn entries<E: Bits, const R: usize, const C: usize>(e: &Evaluation<E, R, C>) -> Vec<E> {
    e.phi.iter().chain(e.jacobian.iter()).chain(e.gamma.iter()).copied().collect()
}

/// Every entry of every evaluation bitwise equal (so `-0.0` ≠ `0.0`, NaN = NaN of the same bits).
#[track_caller]
fn assert_bitwise<E: Bits, const R: usize, const C: usize>(
    what: &str,
    got: &[Evaluation<E, R, C>],
    want: &[Evaluation<E, R, C>],
) {
    assert_eq!(got.len(), want.len(), "{what}: lengths");
    for (i, (g, w)) in got.iter().zip(want).enumerate() {
        let (g, w) = (entries(g), entries(w));
        for (k, (a, b)) in g.iter().zip(&w).enumerate() {
            assert!(a.bits() == b.bits(), "{what}: state {i} entry {k}: {} against {}", a.value(), b.value());
        }
    }
}

fn zeros<E: RealField + Copy, const R: usize, const C: usize>(n: usize) -> Vec<Evaluation<E, R, C>> {
    vec![Evaluation { phi: SVector::zeros(), jacobian: SMatrix::zeros(), gamma: SVector::zeros() }; n]
}

/// Per-state `evaluate`: the reference.
fn reference<J, E, const R: usize, const C: usize>(joint: &J, states: &[J::State]) -> Vec<Evaluation<E, R, C>>
where
    J: Joint<E, R, C>,
{
    states.iter().map(|s| joint.evaluate(s)).collect()
}

const TAILS: [usize; 6] = [0, 1, 3, 5, 9, 1000];

/// The SIMD batch against per-state scalar `evaluate`, bitwise, with its report,
/// and the same through rayon.
#[track_caller]
fn check_simd<J, W, E, S, const N: usize, const R: usize, const C: usize>(what: &str, joint: &J, wide: &W, states: &[S])
where
    E: LaneScalar<N> + Bits + RealField + Send,
    S: Lanes<N> + Sync,
    J: Joint<E, R, C, State = S>,
    W: Joint<E::Wide, R, C, State = S::Packed> + Sync,
{
    let want = reference(joint, states);
    let mut got = zeros::<E, R, C>(states.len());
    let report = evaluate_batch_simd(wide, states, &mut got).expect("lengths agree");
    assert_bitwise(&format!("{what} simd, {} states", states.len()), &got, &want);
    let padding = states.len().next_multiple_of(N) - states.len();
    assert_eq!((report.packed, report.split, report.padding), (states.len().div_ceil(N), 0, padding), "{what}");
    let mut par = zeros::<E, R, C>(states.len());
    let report_par = evaluate_batch_simd_par(wide, states, &mut par).expect("lengths agree");
    assert_bitwise(&format!("{what} simd_par, {} states", states.len()), &par, &want);
    assert_eq!(report_par, report, "{what}: the parallel report");
}

// ---------------------------------------------------------------------------
// Tests.
// ---------------------------------------------------------------------------

#[test]
fn scalar_batch_is_evaluate_per_state() {
    let mut rng = Rng(1);
    let joint = cardan_omega_b(&mut rng);
    for n in TAILS {
        let states = rng.states(n, |r| two_omega(r, 0.0));
        let mut out = zeros(n);
        evaluate_batch(&joint, &states, &mut out).expect("lengths agree");
        assert_bitwise("scalar batch", &out, &reference(&joint, &states));
        let mut par = zeros(n);
        evaluate_batch_par(&joint, &states, &mut par).expect("lengths agree");
        assert_bitwise("rayon batch", &par, &out);
    }
}

#[test]
fn rayon_batch_of_many_chunks_is_scalar() {
    let mut rng = Rng(2);
    let [s, h, rho1, rho2] = cardan_params(&mut rng);
    let joint = UniversalEuler { s, h, rho1, rho2 };
    let states = rng.states(10_007, |r| two_euler(r, 0.0));
    let mut out = zeros(states.len());
    evaluate_batch_par(&joint, &states, &mut out).expect("lengths agree");
    assert_bitwise("rayon batch, euler", &out, &reference(&joint, &states));
}

#[test]
fn wide_f64x4_universal_omega_body() {
    let mut rng = Rng(3);
    let joint = cardan_omega_b(&mut rng);
    let wide = wide_omega_b(&joint);
    for n in TAILS {
        let states = rng.states(n, |r| two_omega(r, 0.25));
        check_simd("universal omega_body f64x4", &joint, &wide, &states);
    }
}

#[test]
fn wide_f64x4_universal_euler_and_relative() {
    let mut rng = Rng(4);
    let [s, h, rho1, rho2] = cardan_params(&mut rng);
    let euler = UniversalEuler { s, h, rho1, rho2 };
    let euler_w = UniversalEuler { s: splat(&s), h: splat(&h), rho1: splat(&rho1), rho2: splat(&rho2) };
    let rel = UniversalRelativeB2 { s, h, rho1, rho2 };
    let rel_w = UniversalRelativeB2 { s: splat(&s), h: splat(&h), rho1: splat(&rho1), rho2: splat(&rho2) };
    for n in TAILS {
        let states = rng.states(n, |r| two_euler(r, 0.0));
        check_simd("universal euler f64x4", &euler, &euler_w, &states);
        let states = rng.states(n, |r| r.relative(1.5));
        check_simd("universal relative_b2 f64x4", &rel, &rel_w, &states);
    }
}

#[test]
fn wide_f64x4_revolute_relative_b1_and_grounded() {
    let mut rng = Rng(5);
    let frame = AxisFrame::new(rng.v3(1.0)).expect("a non-zero axis");
    let (h, rho1, rho2) = (rng.v3(1.0).normalize(), rng.v3(0.5), rng.v3(0.5));
    let hinge = RevoluteRelativeB1 { f: frame.b, g: frame.c, h, rho1, rho2 };
    // The parameters through `Lanes::splat` of a whole `AxisFrame`.
    let wide_frame: AxisFrame<WideF64x4> = Lanes::splat(&frame);
    let hinge_w =
        RevoluteRelativeB1 { f: wide_frame.b, g: wide_frame.c, h: splat(&h), rho1: splat(&rho1), rho2: splat(&rho2) };
    let sleeve = SleeveGrounded { f: frame.b, g: frame.c, h, rho1, rho2 };
    let sleeve_w =
        SleeveGrounded { f: wide_frame.b, g: wide_frame.c, h: splat(&h), rho1: splat(&rho1), rho2: splat(&rho2) };
    for n in TAILS {
        let states = rng.states(n, |r| r.relative(0.0));
        check_simd("revolute relative_b1 f64x4", &hinge, &hinge_w, &states);
        let states = rng.states(n, |r| OneBody { body: r.omega_body(), t: 0.0 });
        check_simd("grounded cylindrical omega_inertial f64x4", &sleeve, &sleeve_w, &states);
    }
}

#[test]
fn wide_f64x4_translational_driver_is_bitwise() {
    let mut rng = Rng(6);
    let x = Ramp { start: 0.3, rate: -0.7 };
    let joint = Actuator { h: rng.v3(1.0).normalize(), rho1: rng.v3(0.5), rho2: rng.v3(0.5), x };
    let wide = Actuator { h: splat(&joint.h), rho1: splat(&joint.rho1), rho2: splat(&joint.rho2), x };
    for n in TAILS {
        let states = rng.states(n, |r| two_euler(r, 2.5));
        check_simd("translational_driver euler f64x4", &joint, &wide, &states);
    }
}

/// A rotational driver takes `sin`/`cos` on the lane type, where `wide` uses its own
/// polynomials (within 1 ε of the scalar's on [−3, 3]): Φ and J within 4 ulps of
/// their largest entry; γ, whose terms are products of two velocities that cancel,
/// within 4 ε·(1 + (|ω1| + |ω2| + |θ̇|)²); most entries bitwise.
#[test]
fn wide_f64x4_rotational_driver_within_ulps() {
    let mut rng = Rng(7);
    let theta = Sinusoid { amplitude: 0.8, frequency: 0.5, phase: 0.2, offset: 0.1 };
    let frame = AxisFrame::new(rng.v3(1.0)).expect("a non-zero axis");
    let joint = Motor { f: frame.b, g: frame.c, k: rng.v3(1.0).normalize(), theta };
    let wide = Motor { f: splat(&joint.f), g: splat(&joint.g), k: splat(&joint.k), theta };
    let (mut worst, mut worst_gamma) = (0.0f64, 0.0f64);
    let (mut same, mut total) = (0usize, 0usize);
    for t in [0.0, 0.37, 1.9, 12.5] {
        let rate = joint.theta.eval(t).rate;
        let states = rng.states(1001, |r| two_omega(r, t));
        let want: Vec<Evaluation<f64, 1, 12>> = reference(&joint, &states);
        let mut got = zeros(states.len());
        let report = evaluate_batch_simd(&wide, &states, &mut got).expect("lengths agree");
        assert_eq!((report.packed, report.split), (251, 0));
        for ((g, w), s) in got.iter().zip(&want).zip(&states) {
            let g: &Evaluation<f64, 1, 12> = g;
            let scale = w.phi.amax().max(w.jacobian.amax()).max(1.0);
            for (a, b) in g.phi.iter().chain(g.jacobian.iter()).zip(w.phi.iter().chain(w.jacobian.iter())) {
                worst = worst.max((a - b).abs() / (scale * f64::EPSILON));
            }
            let speed = s.body1.omega.norm() + s.body2.omega.norm() + rate.abs();
            let gamma_scale = 1.0 + speed * speed;
            worst_gamma = worst_gamma.max((g.gamma - w.gamma).amax() / (gamma_scale * f64::EPSILON));
            for (a, b) in entries(g).iter().zip(entries(w)) {
                same += usize::from(a.to_bits() == b.to_bits());
                total += 1;
            }
        }
    }
    assert!(worst <= 4.0, "rotational driver Φ, J: {worst} ulps of scale");
    assert!(worst_gamma <= 4.0, "rotational driver γ: {worst_gamma} ε·(1 + speed²)");
    assert!(same * 2 > total, "{same} of {total} entries bitwise");
    println!(
        "rotational driver: Φ, J within {worst:.2} ulps, γ {worst_gamma:.3} ε·(1 + speed²), {same} of {total} bitwise"
    );
}

#[test]
fn wide_f32x8_universal_omega_body() {
    let mut rng = Rng(8);
    let joint = f32_omega_b(&cardan_omega_b(&mut rng));
    let wide: UniversalOmegaBody<WideF32x8> = wide_omega_b(&joint);
    for n in TAILS {
        let states = rng.states(n, |r| {
            let s = two_omega(r, 0.0);
            TwoBodies { body1: f32_body(&s.body1), body2: f32_body(&s.body2), t: s.t }
        });
        check_simd("universal omega_body f32x8", &joint, &wide, &states);
    }
}

/// Already packed states (structure of arrays) through the plain batch with the
/// lane joint: each lane equals the scalar evaluation.
#[test]
fn packed_states_through_the_plain_batch() {
    let mut rng = Rng(9);
    let joint = cardan_omega_b(&mut rng);
    let wide = wide_omega_b(&joint);
    let states = rng.states(64, |r| two_omega(r, 0.0));
    let packed: Vec<_> = states
        .chunks_exact(4)
        .map(|c| {
            let lanes: [_; 4] = c.try_into().expect("chunks of 4");
            Lanes::pack(&lanes).expect("one time")
        })
        .collect();
    let mut out = vec![wide.evaluate(&packed[0]); packed.len()];
    evaluate_batch(&wide, &packed, &mut out).expect("lengths agree");
    let unpacked: Vec<Evaluation<f64, 4, 12>> = out.iter().flat_map(Lanes::unpack).collect();
    assert_bitwise("packed states", &unpacked, &reference(&joint, &states));
}

#[test]
fn lanes_round_trip() {
    let mut rng = Rng(10);
    let bodies: [OmegaBody<f64>; 4] = core::array::from_fn(|_| rng.omega_body());
    let packed = <OmegaBody<f64> as Lanes<4>>::pack(&bodies).expect("no time");
    assert_eq!(packed.omega.y.into_arr(), bodies.map(|b| b.omega.y));
    assert_eq!(<OmegaBody<f64> as Lanes<4>>::unpack(&packed), bodies);
    let euler: [EulerBody<f32>; 8] = core::array::from_fn(|_| {
        let b = rng.euler_body();
        EulerBody { r: b.r.cast(), p: b.p.cast(), rdot: b.rdot.cast(), pdot: b.pdot.cast() }
    });
    let packed = <EulerBody<f32> as Lanes<8>>::pack(&euler).expect("no time");
    assert_eq!(<EulerBody<f32> as Lanes<8>>::unpack(&packed), euler);
    let relative: [RelativeState<f64>; 4] = core::array::from_fn(|_| rng.relative(0.5));
    let packed = <RelativeState<f64> as Lanes<4>>::pack(&relative).expect("one time");
    assert_eq!(<RelativeState<f64> as Lanes<4>>::unpack(&packed), relative);
    let joint = cardan_omega_b(&mut rng);
    let evaluations: [Evaluation<f64, 4, 12>; 4] = core::array::from_fn(|_| joint.evaluate(&two_omega(&mut rng, 0.0)));
    let packed = <Evaluation<f64, 4, 12> as Lanes<4>>::pack(&evaluations).expect("no time");
    assert_eq!(<Evaluation<f64, 4, 12> as Lanes<4>>::unpack(&packed), evaluations);
    let one = OneBody { body: rng.omega_body(), t: 3.0 };
    assert_eq!(<OneBody<OmegaBody<f64>> as Lanes<4>>::unpack(&Lanes::splat(&one)), [one; 4]);
}

/// States at different times: `pack` names the lane, the batch evaluates that
/// pack state by state (exactly) and says so.
#[test]
fn mixed_times_are_refused_by_pack_and_split_by_the_batch() {
    let mut rng = Rng(11);
    let mut states = rng.states(4, |r| two_euler(r, 1.0));
    states[2].t = 1.5;
    assert_eq!(
        <TwoBodies<EulerBody<f64>> as Lanes<4>>::pack(states[..4].try_into().expect("4")),
        Err(MixedTimes { lane: 2, expected: 1.0, found: 1.5 })
    );
    let mut relative = [rng.relative(0.0); 4];
    relative[3].t = -0.0; // a different bit pattern is a different time
    assert_eq!(<RelativeState<f64> as Lanes<4>>::pack(&relative).map(|_| ()).map_err(|e| e.lane), Err(3));

    let x = Ramp { start: 0.3, rate: -0.7 };
    let joint = Actuator { h: rng.v3(1.0).normalize(), rho1: rng.v3(0.5), rho2: rng.v3(0.5), x };
    let wide = Actuator { h: splat(&joint.h), rho1: splat(&joint.rho1), rho2: splat(&joint.rho2), x };
    // 11 states: packs [0..4) at one time, [4..8) mixed, [8..11) padded and mixed.
    let states: Vec<_> = (0..11).map(|i| two_euler(&mut rng, if i < 4 { 2.0 } else { 0.1 * i as f64 })).collect();
    let mut got = zeros(states.len());
    let report = evaluate_batch_simd(&wide, &states, &mut got).expect("lengths agree");
    assert_eq!((report.packed, report.split, report.padding), (1, 2, 1));
    assert_bitwise("mixed times", &got, &reference(&joint, &states));
    let mut par = zeros(states.len());
    assert_eq!(evaluate_batch_simd_par(&wide, &states, &mut par), Ok(report));
    assert_bitwise("mixed times, rayon", &par, &got);
}

#[test]
fn length_mismatch_is_an_error_and_writes_nothing() {
    let mut rng = Rng(12);
    let joint = cardan_omega_b(&mut rng);
    let wide = wide_omega_b(&joint);
    let states = rng.states(10, |r| two_omega(r, 0.0));
    let error = BatchError::LengthMismatch { states: 10, outputs: 9 };
    let mut out = zeros::<f64, 4, 12>(9);
    assert_eq!(evaluate_batch(&joint, &states, &mut out), Err(error));
    assert_eq!(evaluate_batch_par(&joint, &states, &mut out), Err(error));
    assert_eq!(evaluate_batch_simd(&wide, &states, &mut out), Err(error));
    assert_eq!(evaluate_batch_simd_par(&wide, &states, &mut out), Err(error));
    assert!(out.iter().all(|e| e.jacobian.iter().all(|x| x.to_bits() == 0)), "nothing written");
    let message = BatchError::LengthMismatch { states: 10, outputs: 9 }.to_string();
    assert!(message.contains("10 states") && message.contains("9 output"), "{message}");
    let mut longer = zeros::<f64, 4, 12>(11);
    assert_eq!(
        evaluate_batch_simd(&wide, &states, &mut longer),
        Err(BatchError::LengthMismatch { states: 10, outputs: 11 })
    );
}
