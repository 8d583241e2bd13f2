//! Scenes that scale: µs per step against the number of bodies for a chain, a
//! ladder of closed loops and a branched tree, on the sparse path
//! ([`joint_runtime::absolute`]) and, where it still fits, the dense one; the
//! program `cargo run --release -p joint-scaling` writes
//! `report/scaling.md` and `report/scaling.svg`.
//!
//! Every scene is declared with rows of bodies and joints (`#[body(bar[40], ..)]`,
//! `#[joint(ball[i in 1..40] = spherical(bar[i - 1], bar[i]), ..)]`), so a
//! size is one number.
//!
//! - **Chain**: the chain the peers were timed on (Exudyn, MuJoCo): bars of 1 m and 1 kg
//!   (solid cylinders of radius 0.05 m along body x), spherical joints, the first
//!   hanging from the origin, gravity −z, straight along `(sin 1, 0, −cos 1)` at rest.
//! - **Ladder**: the N-four-bar (IFToMM A02, as [`crate::four_bar`]): `N + 1`
//!   cranks pinned to the ground 1 m apart, `N` couplers, spatial revolute joints,
//!   so every loop has redundant rows; `N` closed loops, `2N + 1` bodies.
//! - **Tree**: a spine of `K` bars hanging like the chain, with a rib of the
//!   same bar hanging from the lower end of each: `2K` bodies, branched at every
//!   spine joint.

use std::time::Instant;

use joint_runtime::analysis::AnalysisError;
use joint_runtime::dynamics::{AbsoluteSimulation, Integrator, NoLoads, SimulationOptions};
use joint_runtime::nalgebra::{Rotation3, UnitQuaternion, Vector3};
use joint_runtime::{OmegaBody, Scene, SparseJacobian, SystemState};

/// Declares the chain of `$n` bars (scene options after the size:
/// `second_order` for the terms generalised-α needs; absolute coordinates
/// unless `coordinates = ..` comes first among them).
#[macro_export]
macro_rules! chain_scene {
    ($name:ident, $n:tt, coordinates = $c:ident $(, $($option:tt)+)?) => {
        $crate::chain_scene!(@ $name, $n, coordinates = $c $(, $($option)+)?);
    };
    ($name:ident, $n:tt $(, $($option:tt)+)?) => {
        $crate::chain_scene!(@ $name, $n, coordinates = absolute $(, $($option)+)?);
    };
    (@ $name:ident, $n:tt, $($option:tt)+) => {
        /// A chain of bars on spherical joints (see the module docs).
        #[derive(joint_runtime::Scene, Clone, Copy, Debug, Default)]
        #[scene(gravity = [0, 0, -9.81], $($option)+)]
        #[body(bar[$n], mass = 1.0, inertia = [0.00125, 0.08395833333333333, 0.08395833333333333])]
        #[joint(pivot = spherical(ground, bar[0]), rho1 = [0, 0, 0], rho2 = [-0.5, 0, 0])]
        #[joint(ball[i in 1..$n] = spherical(bar[i - 1], bar[i]), rho1 = [0.5, 0, 0], rho2 = [-0.5, 0, 0])]
        pub struct $name;
    };
}

/// Declares the ladder of `$n` four-bar loops (`$cranks = $n + 1`).
#[macro_export]
macro_rules! ladder_scene {
    ($name:ident, $n:tt, $cranks:tt $(, $option:ident)?) => {
        /// The N-four-bar: cranks pinned to the ground, couplers between them.
        #[derive(joint_runtime::Scene, Clone, Copy, Debug, Default)]
        #[scene(gravity = [0, -9.81, 0], coordinates = absolute $(, $option)?)]
        #[body(crank[$cranks], mass = 1.0, inertia = [0.08333333333333333, 0.08333333333333333, 0.08333333333333333])]
        #[body(coupler[$n], mass = 1.0, inertia = [0.08333333333333333, 0.08333333333333333, 0.08333333333333333])]
        #[joint(pin[i in 0..$cranks] = revolute(ground, crank[i]), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [i, 0, 0], rho2 = [0, -0.5, 0])]
        #[joint(left[i in 0..$n] = revolute(crank[i], coupler[i]), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0, 0.5, 0], rho2 = [-0.5, 0, 0])]
        #[joint(right[i in 0..$n] = revolute(crank[i + 1], coupler[i]), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0, 0.5, 0], rho2 = [0.5, 0, 0])]
        pub struct $name;
    };
}

/// Declares the tree of a `$k`-bar spine with a rib on each.
#[macro_export]
macro_rules! tree_scene {
    ($name:ident, $k:tt $(, $option:ident)?) => {
        /// A spine of bars with a rib hanging from each.
        #[derive(joint_runtime::Scene, Clone, Copy, Debug, Default)]
        #[scene(gravity = [0, 0, -9.81], coordinates = absolute $(, $option)?)]
        #[body(spine[$k], mass = 1.0, inertia = [0.00125, 0.08395833333333333, 0.08395833333333333])]
        #[body(rib[$k], mass = 1.0, inertia = [0.00125, 0.08395833333333333, 0.08395833333333333])]
        #[joint(pivot = spherical(ground, spine[0]), rho1 = [0, 0, 0], rho2 = [-0.5, 0, 0])]
        #[joint(ball[i in 1..$k] = spherical(spine[i - 1], spine[i]), rho1 = [0.5, 0, 0], rho2 = [-0.5, 0, 0])]
        #[joint(branch[i in 0..$k] = spherical(spine[i], rib[i]), rho1 = [0.5, 0, 0], rho2 = [-0.5, 0, 0])]
        pub struct $name;
    };
}

/// Bars hanging straight along `(sin 1, 0, −cos 1)` at rest: body `i` of the
/// chain (`parent(i)` is the body whose lower end it hangs from, `None` for the
/// origin).
pub fn hanging<const NB: usize>(parent: impl Fn(usize) -> Option<usize>) -> SystemState<NB> {
    let dir = Vector3::new(1f64.sin(), 0.0, -1f64.cos());
    let rotation = Rotation3::rotation_between(&Vector3::x(), &dir).unwrap_or_else(Rotation3::identity);
    let q = UnitQuaternion::from_rotation_matrix(&rotation);
    let mut tops = [Vector3::zeros(); NB];
    let bodies = core::array::from_fn(|i| {
        let top = parent(i).map_or(Vector3::zeros(), |p: usize| tops[p] + dir);
        tops[i] = top;
        OmegaBody::from_rotation(top + dir * 0.5, &q, Vector3::zeros(), Vector3::zeros())
    });
    SystemState { bodies, t: 0.0 }
}

/// The chain's start: each bar hangs from the previous one.
pub fn chain_start<const NB: usize>() -> SystemState<NB> {
    hanging(|i| i.checked_sub(1))
}

/// The tree's start (spine `0..K`, ribs `K..2K`): a rib hangs from its spine
/// bar's lower end, along the same line (the bars overlap, which the joints allow).
pub fn tree_start<const NB: usize>() -> SystemState<NB> {
    let k = NB / 2;
    hanging(move |i| if i < k { i.checked_sub(1) } else { Some(i - k) })
}

/// The ladder's start: cranks upright, the first loop moving at 1 m/s.
pub fn ladder_start<const NB: usize>() -> SystemState<NB> {
    let cranks = NB / 2 + 1;
    let rate = -1.0;
    let tip = Vector3::new(-rate, 0.0, 0.0);
    let bodies = core::array::from_fn(|b| {
        if b < cranks {
            let r = Vector3::new(b as f64, 0.5, 0.0);
            OmegaBody::from_rotation(r, &UnitQuaternion::identity(), tip * 0.5, Vector3::new(0.0, 0.0, rate))
        } else {
            let r = Vector3::new((b - cranks) as f64 + 0.5, 1.0, 0.0);
            OmegaBody::from_rotation(r, &UnitQuaternion::identity(), tip, Vector3::zeros())
        }
    });
    SystemState { bodies, t: 0.0 }
}

/// Median of `rounds` timings of `steps` steps of `step`, in µs per step,
/// after `steps / 10` steps of warm-up; each round restarts from `start`.
pub fn median_us<const NB: usize>(
    start: &SystemState<NB>,
    steps: usize,
    rounds: usize,
    mut step: impl FnMut(&mut SystemState<NB>) -> Result<(), AnalysisError>,
) -> Result<f64, AnalysisError> {
    let mut warm = *start;
    for _ in 0..steps / 10 {
        step(&mut warm)?;
    }
    let mut times = Vec::with_capacity(rounds);
    for _ in 0..rounds {
        let mut state = *start;
        let t = Instant::now();
        for _ in 0..steps {
            step(&mut state)?;
        }
        times.push(t.elapsed().as_secs_f64() * 1e6 / steps as f64);
    }
    times.sort_by(f64::total_cmp);
    Ok(times[times.len() / 2])
}

/// The options of a measured run: the defaults (projection on) with `integrator`.
pub fn options(integrator: Integrator) -> SimulationOptions {
    let mut options = SimulationOptions::default();
    options.integrator = integrator;
    options
}

/// µs per step with projection (h = 1 ms) of `integrator` on the sparse path,
/// and the 6 × 6 blocks of generalised-α's iteration matrix (its memory).
///
/// # Errors
/// The simulation's.
pub fn sparse_step_us<S, const NB: usize, const NV: usize, const M: usize, const NNZ: usize>(
    scene: &S,
    start: &SystemState<NB>,
    steps: usize,
    integrator: Integrator,
) -> Result<(f64, Option<usize>), AnalysisError>
where
    S: Scene<NB, NV, M> + SparseJacobian<NB, NNZ>,
{
    let mut sim = AbsoluteSimulation::new(scene, NoLoads, &[], options(integrator))?;
    let us = median_us(start, steps, 3, |s| sim.step(s, 1e-3).map(|_| ()))?;
    Ok((us, sim.iteration_blocks()))
}

/// The least-squares slope of `ln y` on `ln x`.
pub fn exponent(points: &[(f64, f64)]) -> f64 {
    let n = points.len() as f64;
    let (lx, ly): (Vec<f64>, Vec<f64>) = points.iter().map(|&(x, y)| (x.ln(), y.ln())).unzip();
    let (mx, my) = (lx.iter().sum::<f64>() / n, ly.iter().sum::<f64>() / n);
    let sxy: f64 = lx.iter().zip(&ly).map(|(x, y)| (x - mx) * (y - my)).sum();
    let sxx: f64 = lx.iter().map(|x| (x - mx) * (x - mx)).sum();
    sxy / sxx
}
