//! Evaluations per second of `Joint::evaluate` (Φ, J and γ) over batches of
//! independent states: scalar `f64` and `f32`, SIMD lanes (`WideF64x4`,
//! `WideF32x8`) from scalar states (packed and unpacked on the fly, array of
//! structures) and from states kept packed (structure of arrays), on one core; and
//! a large batch over all cores with rayon. Universal joint in `omega_body` (the
//! target), `euler` and `relative_b2`, random unit quaternions and velocities.
//!
//! One-core rows: a batch of `SMALL` states (cache-resident) evaluated `ROUNDS`
//! times per repetition, `REPS` repetitions, the median. Large rows: `LARGE`
//! states, `REPS_LARGE` repetitions, the median.
//!
//! ```text
//! cargo run --release -p joint-examples --features bench --example batch_bench
//! RUSTFLAGS="-C target-cpu=native" cargo run --release -p joint-examples --features bench --example batch_bench
//! ```
//!
//! `wide` uses the vector instructions the build enables: the default x86-64
//! target has SSE2 only, so a `f64x4` is two 128-bit halves; with AVX (e.g.
//! `-C target-cpu=native`) it is one 256-bit register.

use std::hint::black_box;
use std::time::Instant;

use joint_runtime::Joint;
use joint_runtime::batch::{
    LaneScalar, Lanes, WideF32x8, WideF64x4, evaluate_batch, evaluate_batch_par, evaluate_batch_simd,
    evaluate_batch_simd_par, splat,
};
use joint_runtime::nalgebra::{SMatrix, SVector, SimdRealField, Vector3};
use joint_runtime::{EulerBody, Evaluation, OmegaBody, RelativeState, TwoBodies};
use joint_tests::joints::{UniversalEuler, UniversalOmegaBody, UniversalRelativeB2};
use joint_tests::random::Rng;

const SMALL: usize = 1024;
const ROUNDS: usize = 20;
const REPS: usize = 15;
const LARGE: usize = 1_000_000;
const REPS_LARGE: usize = 7;

/// The joint's parameters: `s ⟂ h`, offsets of half a metre.
fn params() -> [Vector3<f64>; 4] {
    [Vector3::y(), Vector3::z(), Vector3::new(0.5, 0.02, -0.01), Vector3::new(-0.5, 0.01, 0.03)]
}

fn zeros<E: SimdRealField + Copy, const R: usize, const C: usize>(n: usize) -> Vec<Evaluation<E, R, C>> {
    vec![Evaluation { phi: SVector::zeros(), jacobian: SMatrix::zeros(), gamma: SVector::zeros() }; n]
}

/// Median evaluations per second of `run`, which evaluates `per_run` states.
fn rate(per_run: usize, reps: usize, mut run: impl FnMut()) -> f64 {
    run(); // warm-up: caches, page faults, rayon's threads
    let mut rates: Vec<f64> = (0..reps)
        .map(|_| {
            let clock = Instant::now();
            run();
            per_run as f64 / clock.elapsed().as_secs_f64()
        })
        .collect();
    rates.sort_by(f64::total_cmp);
    rates[rates.len() / 2]
}

/// States already in lanes: `N` consecutive states per packed state.
fn packed<S: Lanes<N>, const N: usize>(states: &[S]) -> Vec<S::Packed> {
    states.chunks_exact(N).filter_map(|c| c.try_into().ok()).filter_map(|lanes: [S; N]| S::pack(&lanes).ok()).collect()
}

/// The joint's rows of the table: one core on `SMALL` states, then (if `large`)
/// `LARGE` states on one core and across all cores.
fn bench<J64, J4, J32, J8, S64, S32, const R: usize, const C: usize>(
    name: &str,
    joints: (J64, J4, J32, J8),
    states: Vec<S64>,
    to_f32: impl Fn(&S64) -> S32,
    large: Option<Vec<S64>>,
) where
    S64: Lanes<4> + Sync,
    S32: Lanes<8>,
    J64: Joint<f64, R, C, State = S64> + Sync,
    J4: Joint<WideF64x4, R, C, State = S64::Packed> + Sync,
    J32: Joint<f32, R, C, State = S32>,
    J8: Joint<WideF32x8, R, C, State = S32::Packed>,
    S64::Packed: Sync,
{
    let (j64, j4, j32, j8) = joints;
    let n = states.len();
    let states32: Vec<S32> = states.iter().map(&to_f32).collect();
    let packed4 = packed::<S64, 4>(&states);
    let packed8 = packed::<S32, 8>(&states32);
    let mut out64 = zeros::<f64, R, C>(n);
    let mut out32 = zeros::<f32, R, C>(n);
    let mut out4 = zeros::<WideF64x4, R, C>(packed4.len());
    let mut out8 = zeros::<WideF32x8, R, C>(packed8.len());
    let per_run = n * ROUNDS;
    let one = |f: &mut dyn FnMut()| {
        rate(per_run, REPS, || {
            for _ in 0..ROUNDS {
                f();
            }
        })
    };
    let scalar64 = one(&mut || {
        evaluate_batch(&j64, black_box(&states), &mut out64).ok();
        black_box(&out64);
    });
    let simd4 = one(&mut || {
        evaluate_batch_simd(&j4, black_box(&states), &mut out64).ok();
        black_box(&out64);
    });
    let soa4 = one(&mut || {
        evaluate_batch(&j4, black_box(&packed4), &mut out4).ok();
        black_box(&out4);
    });
    let scalar32 = one(&mut || {
        evaluate_batch(&j32, black_box(&states32), &mut out32).ok();
        black_box(&out32);
    });
    let simd8 = one(&mut || {
        evaluate_batch_simd(&j8, black_box(&states32), &mut out32).ok();
        black_box(&out32);
    });
    let soa8 = one(&mut || {
        evaluate_batch(&j8, black_box(&packed8), &mut out8).ok();
        black_box(&out8);
    });
    let row = |what: &str, r: f64, base: f64| {
        println!("{name:<14} {what:<44} {:>10.2} {:>9.1} {:>7.2}×", r / 1e6, 1e9 / r, r / base);
    };
    row("f64 scalar, 1 core", scalar64, scalar64);
    row("WideF64x4, 1 core, scalar states (AoS)", simd4, scalar64);
    row("WideF64x4, 1 core, packed states (SoA)", soa4, scalar64);
    row("f32 scalar, 1 core", scalar32, scalar64);
    row("WideF32x8, 1 core, scalar states (AoS)", simd8, scalar64);
    row("WideF32x8, 1 core, packed states (SoA)", soa8, scalar64);
    println!("{:<14} {:<44} f32x8/f32: AoS {:.2}×, SoA {:.2}×", "", "", simd8 / scalar32, soa8 / scalar32);

    let Some(big) = large else { return };
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let m = big.len();
    let big4 = packed::<S64, 4>(&big);
    let mut out = zeros::<f64, R, C>(m);
    let mut out4 = zeros::<WideF64x4, R, C>(big4.len());
    let one_core = rate(m, REPS_LARGE, || {
        evaluate_batch(&j64, black_box(&big), &mut out).ok();
    });
    let one_core4 = rate(m, REPS_LARGE, || {
        evaluate_batch_simd(&j4, black_box(&big), &mut out).ok();
    });
    let par = rate(m, REPS_LARGE, || {
        evaluate_batch_par(&j64, black_box(&big), &mut out).ok();
    });
    let par4 = rate(m, REPS_LARGE, || {
        evaluate_batch_simd_par(&j4, black_box(&big), &mut out).ok();
    });
    let par_soa4 = rate(m, REPS_LARGE, || {
        evaluate_batch_par(&j4, black_box(&big4), &mut out4).ok();
    });
    println!();
    let what = |s: &str| format!("{s}, {m} states");
    row(&what("f64 scalar, 1 core"), one_core, one_core);
    row(&what("WideF64x4 AoS, 1 core"), one_core4, one_core);
    row(&what(&format!("f64 scalar, rayon {threads} threads")), par, one_core);
    row(&what(&format!("WideF64x4 AoS, rayon {threads} threads")), par4, one_core);
    row(&what(&format!("WideF64x4 SoA, rayon {threads} threads")), par_soa4, one_core);
}

fn f32_omega(b: &OmegaBody<f64>) -> OmegaBody<f32> {
    OmegaBody { r: b.r.cast(), p: b.p.cast(), rdot: b.rdot.cast(), omega: b.omega.cast() }
}

fn f32_euler(b: &EulerBody<f64>) -> EulerBody<f32> {
    EulerBody { r: b.r.cast(), p: b.p.cast(), rdot: b.rdot.cast(), pdot: b.pdot.cast() }
}

macro_rules! joints {
    ($J:ident) => {{
        let [s, h, rho1, rho2] = params();
        let [s32, h32, rho132, rho232] = [s, h, rho1, rho2].map(|v| v.cast::<f32>());
        fn wide<E: LaneScalar<N>, const N: usize>(v: [Vector3<E>; 4]) -> $J<E::Wide> {
            $J { s: splat(&v[0]), h: splat(&v[1]), rho1: splat(&v[2]), rho2: splat(&v[3]) }
        }
        (
            $J { s, h, rho1, rho2 },
            wide::<f64, 4>([s, h, rho1, rho2]),
            $J { s: s32, h: h32, rho1: rho132, rho2: rho232 },
            wide::<f32, 8>([s32, h32, rho132, rho232]),
        )
    }};
}

fn main() {
    let target = if cfg!(target_feature = "avx2") {
        "AVX2"
    } else if cfg!(target_feature = "avx") {
        "AVX"
    } else {
        "SSE2 only (no AVX: build with RUSTFLAGS=\"-C target-cpu=native\" for 256-bit lanes)"
    };
    println!(
        "Φ, J and γ per state (Joint::evaluate), universal joint; {SMALL} states × {ROUNDS} rounds, median of {REPS} \
         (large: {LARGE} states, median of {REPS_LARGE}); vector instructions: {target}.\n"
    );
    println!("{:<14} {:<44} {:>10} {:>9} {:>8}", "formulation", "batch", "M eval/s", "ns/eval", "ratio");
    let mut rng = Rng(42);
    let two_omega = |rng: &mut Rng| TwoBodies::new(rng.omega_body(), rng.omega_body());
    let states: Vec<_> = (0..SMALL).map(|_| two_omega(&mut rng)).collect();
    let big: Vec<_> = (0..LARGE).map(|_| two_omega(&mut rng)).collect();
    let omega32 = |s: &TwoBodies<OmegaBody<f64>>| TwoBodies::new(f32_omega(&s.body1), f32_omega(&s.body2));
    bench("omega_body", joints!(UniversalOmegaBody), states, omega32, Some(big));
    println!();
    let states: Vec<_> = (0..SMALL).map(|_| TwoBodies::new(rng.euler_body(), rng.euler_body())).collect();
    let euler32 = |s: &TwoBodies<EulerBody<f64>>| TwoBodies::new(f32_euler(&s.body1), f32_euler(&s.body2));
    bench("euler", joints!(UniversalEuler), states, euler32, None);
    println!();
    let states: Vec<_> = (0..SMALL).map(|_| rng.relative(0.0)).collect();
    let relative32 = |s: &RelativeState<f64>| RelativeState {
        delta: s.delta.cast(),
        p: s.p.cast(),
        delta_dot: s.delta_dot.cast(),
        omega: s.omega.cast(),
        t: s.t,
    };
    bench("relative_b2", joints!(UniversalRelativeB2), states, relative32, None);
    println!(
        "\nratio: against the f64 scalar row of the same block. AoS: scalar states in and scalar Evaluations out, \
         packed/unpacked per call (evaluate_batch_simd); SoA: states and outputs kept in lanes (evaluate_batch \
         with the lane joint)."
    );
}
