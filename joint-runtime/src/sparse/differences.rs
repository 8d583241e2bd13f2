//! A scene's sparse second-order terms by central differences of its
//! generated `J`, `γ` and `Φ_t`: what the sparse implicit integrators build
//! their Newton matrices from for a scene derived without `second_order`, or
//! when the options ask for differences
//! ([`NewtonMatrix::FiniteDifferences`](crate::dynamics::NewtonMatrix)).
//!
//! Every term of a joint is a derivative along its own bodies' columns only,
//! so bodies that no joint connects can be moved at once, each joint seeing
//! one of them move. The bodies are coloured greedily so that the two bodies
//! of a joint differ; a chain needs two colours however long it is, a tree as
//! many as one more than its largest branching. One colour's six position
//! directions and six velocity directions, both ways, cost 24 evaluations of
//! `J`, `γ` and `Φ_t` (velocities: of `γ` alone): `O(N)` for the whole scene,
//! where a column at a time would cost `O(N²)`.
//!
//! Central differences with steps `10⁻⁶ (1 + |r|)` for a translation, `10⁻⁶`
//! for a turn and `10⁻⁶ (1 + |v|)` for a velocity agree with the generated
//! terms to about `10⁻⁹` relative (`γ` is quadratic in the velocities, so its
//! velocity derivative is exact but for round-off): a Newton matrix that good
//! keeps Newton's convergence.

use alloc::boxed::Box;
use alloc::vec;
use alloc::vec::Vec;

use nalgebra::SVector;

use super::second_order::{RowTerm, SecondOrderLayout};
use crate::OmegaBody;
use crate::analysis::{apply_increment, set_velocities, velocity_vector_into};
use crate::scene::{RowBlock, Scene, SparseJacobian, SystemState};

/// The relative step of the differences.
const STEP: f64 = 1e-6;

/// What one direction of the differences moves and evaluates: the step, the
/// two moved states and the scene's `J`, `γ`, `Φ_t` at them, the velocities.
/// Boxed and kept by the implicit integrators, so that a step's frames hold
/// none of the scene's size.
#[derive(Clone, Debug)]
pub(super) struct DifferenceWork<const NB: usize, const NV: usize, const M: usize, const NNZ: usize> {
    delta: SVector<f64, NV>,
    v: SVector<f64, NV>,
    moved_v: SVector<f64, NV>,
    states: [SystemState<NB>; 2],
    j: [[f64; NNZ]; 2],
    gamma: [SVector<f64, M>; 2],
    phi_t: [SVector<f64, M>; 2],
}

impl<const NB: usize, const NV: usize, const M: usize, const NNZ: usize> DifferenceWork<NB, NV, M, NNZ> {
    /// A zeroed work, boxed.
    pub(super) fn boxed() -> Box<Self> {
        let state = SystemState { bodies: [OmegaBody::default(); NB], t: 0.0 };
        let (v, m) = (SVector::zeros(), SVector::zeros());
        Box::new(DifferenceWork {
            delta: v,
            v,
            moved_v: v,
            states: [state; 2],
            j: [[0.0; NNZ]; 2],
            gamma: [m; 2],
            phi_t: [m; 2],
        })
    }
}

/// A scene's sparse second-order terms by central differences, in the
/// layout of [`SecondOrderLayout`]; the colouring of its bodies is found once,
/// in [`DifferenceTerms::new`].
///
/// ```
/// use joint_runtime::nalgebra::{SVector, UnitQuaternion, Vector3};
/// use joint_runtime::sparse::{DifferenceTerms, SecondOrderLayout};
/// use joint_runtime::{OmegaBody, Scene, SparseJacobian, SystemState};
///
/// #[derive(Scene)]
/// #[scene(gravity = [0, 0, -9.81], second_order)]
/// #[body(upper, mass = 1.0, inertia = [0.08, 0.08, 0.001])]
/// #[body(lower, mass = 1.0, inertia = [0.08, 0.08, 0.001])]
/// #[joint(shoulder = spherical(ground, upper), rho1 = [0, 0, 0], rho2 = [0, 0, 0.5])]
/// #[joint(elbow = spherical(upper, lower), rho1 = [0, 0, -0.5], rho2 = [0, 0, 0.5])]
/// struct Pendulum;
///
/// let tilt = UnitQuaternion::from_scaled_axis(Vector3::new(0.3, -0.2, 0.1));
/// let body = |r: Vector3<f64>| OmegaBody::from_rotation(r, &tilt, Vector3::new(0.2, 0.1, 0.0), Vector3::new(1.0, -0.5, 2.0));
/// let state = SystemState { bodies: [body(Vector3::new(0.1, 0.0, -0.5)), body(Vector3::new(0.2, 0.1, -1.4))], t: 0.0 };
/// let (lambda, u) = (SVector::<f64, 6>::from_fn(|i, _| i as f64 - 2.5), SVector::<f64, 12>::repeat(0.7));
///
/// let layout = SecondOrderLayout::new(Pendulum::BLOCKS, Pendulum::BLOCK_BODIES);
/// let (mut exact, mut differences) = (vec![0.0; layout.len()], vec![0.0; layout.len()]);
/// assert!(Pendulum.second_order_values(&state, &lambda, &u, &mut exact));
/// let terms = DifferenceTerms::new(Pendulum::BLOCKS, Pendulum::BLOCK_BODIES, 2);
/// assert_eq!(terms.colours(), 2);
/// assert!(terms.values(&Pendulum, &state, &lambda, &u, &mut differences));
/// for (x, y) in exact.iter().zip(&differences) {
///     assert!((x - y).abs() < 1e-8 * (1.0 + x.abs()));
/// }
/// ```
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DifferenceTerms {
    layout: SecondOrderLayout,
    /// The bodies of each colour (no joint connects two of them).
    colours: Vec<Vec<usize>>,
    /// Each body's colour.
    colour_of: Vec<usize>,
}

impl DifferenceTerms {
    /// The colouring of a scene of `bodies` bodies whose joint blocks
    /// `blocks` connect `joint_bodies` ([`Scene::BLOCKS`],
    /// [`SparseJacobian::BLOCK_BODIES`]).
    pub fn new(blocks: &[RowBlock], joint_bodies: &[[Option<usize>; 2]], bodies: usize) -> Self {
        let mut neighbours = vec![Vec::new(); bodies];
        for pair in joint_bodies {
            if let [Some(a), Some(b)] = *pair
                && a != b
                && a < bodies
                && b < bodies
            {
                neighbours[a].push(b);
                neighbours[b].push(a);
            }
        }
        let (colours, colour_of) = greedy_colours(bodies, |b| neighbours[b].clone());
        DifferenceTerms { layout: SecondOrderLayout::new(blocks, joint_bodies), colours, colour_of }
    }

    /// The number of colours (each costs 24 evaluations of the scene).
    pub fn colours(&self) -> usize {
        self.colours.len()
    }

    /// The terms of [`Scene::second_order_values`] at `state` for the
    /// multipliers `lambda` and the velocity `u` of `∂(J u)/∂q`, by central
    /// differences, written into `out`; `false` (and nothing written) when
    /// `out` is not exactly the layout's length. Allocates its scratch (the
    /// moved states and the scene's values at them) for the call.
    pub fn values<S, const NB: usize, const NV: usize, const M: usize, const NNZ: usize>(
        &self,
        scene: &S,
        state: &SystemState<NB>,
        lambda: &SVector<f64, M>,
        u: &SVector<f64, NV>,
        out: &mut [f64],
    ) -> bool
    where
        S: Scene<NB, NV, M> + SparseJacobian<NB, NNZ>,
    {
        self.values_in::<S, NB, NV, M, NNZ>(scene, state, (lambda, u), out, &mut DifferenceWork::boxed())
    }

    /// [`values`](Self::values) (for `(λ, u)`) with the scratch `work`.
    pub(super) fn values_in<S, const NB: usize, const NV: usize, const M: usize, const NNZ: usize>(
        &self,
        scene: &S,
        state: &SystemState<NB>,
        (lambda, u): (&SVector<f64, M>, &SVector<f64, NV>),
        out: &mut [f64],
        work: &mut DifferenceWork<NB, NV, M, NNZ>,
    ) -> bool
    where
        S: Scene<NB, NV, M> + SparseJacobian<NB, NNZ>,
    {
        if out.len() != self.layout.len() {
            return false;
        }
        out.fill(0.0);
        for (colour, bodies) in self.colours.iter().enumerate() {
            for k in 0..6 {
                self.position_direction::<S, NB, NV, M, NNZ>(scene, state, (colour, bodies, k), (lambda, u), out, work);
                self.velocity_direction::<S, NB, NV, M, NNZ>(scene, state, (colour, bodies, k), out, work);
            }
        }
        true
    }

    /// One colour's bodies moved along coordinate `k` of their position
    /// increments, both ways: the position derivatives' differences. In a
    /// frame of its own, apart from the velocity direction's.
    #[inline(never)]
    fn position_direction<S, const NB: usize, const NV: usize, const M: usize, const NNZ: usize>(
        &self,
        scene: &S,
        state: &SystemState<NB>,
        (colour, bodies, k): (usize, &[usize], usize),
        (lambda, u): (&SVector<f64, M>, &SVector<f64, NV>),
        out: &mut [f64],
        work: &mut DifferenceWork<NB, NV, M, NNZ>,
    ) where
        S: Scene<NB, NV, M> + SparseJacobian<NB, NNZ>,
    {
        let DifferenceWork { delta, states, j, gamma, phi_t, .. } = work;
        delta.fill(0.0);
        for &b in bodies {
            let (Some(d), Some(body)) = (delta.get_mut(6 * b + k), state.bodies.get(b)) else { continue };
            *d = STEP * if k < 3 { 1.0 + body.r.amax() } else { 1.0 };
        }
        for (((moved, sign), j), (gamma, phi_t)) in
            states.iter_mut().zip([1.0, -1.0]).zip(j.iter_mut()).zip(gamma.iter_mut().zip(phi_t.iter_mut()))
        {
            moved.clone_from(state);
            apply_increment(moved, delta, sign);
            scene.jacobian_values_into(moved, j);
            *gamma = scene.gamma(moved);
            *phi_t = scene.phi_t(moved);
        }
        let moved = Moved { colour, k, delta, j, gamma, phi_t };
        self.positions::<S, NB, NV, M, NNZ>(&moved, lambda, u, out);
    }

    /// One colour's bodies' velocity coordinate `k` moved both ways: `∂γ/∂v`.
    #[inline(never)]
    fn velocity_direction<S, const NB: usize, const NV: usize, const M: usize, const NNZ: usize>(
        &self,
        scene: &S,
        state: &SystemState<NB>,
        (colour, bodies, k): (usize, &[usize], usize),
        out: &mut [f64],
        work: &mut DifferenceWork<NB, NV, M, NNZ>,
    ) where
        S: Scene<NB, NV, M> + SparseJacobian<NB, NNZ>,
    {
        let DifferenceWork { delta: dv, v, moved_v, states, gamma, .. } = work;
        velocity_vector_into(state, v);
        dv.fill(0.0);
        for &b in bodies {
            let speed = state.bodies.get(b).map_or(0.0, |x| x.rdot.amax().max(x.omega.amax()));
            if let Some(d) = dv.get_mut(6 * b + k) {
                *d = STEP * (1.0 + speed);
            }
        }
        for ((moved, sign), g) in states.iter_mut().zip([1.0, -1.0]).zip(gamma.iter_mut()) {
            for ((m, v), d) in moved_v.as_mut_slice().iter_mut().zip(v.as_slice().iter()).zip(dv.as_slice().iter()) {
                *m = if sign > 0.0 { v + d } else { v - d };
            }
            moved.clone_from(state);
            set_velocities(moved, moved_v);
            *g = scene.gamma(moved);
        }
        let [gp, gm] = &*gamma;
        self.each_row::<S, NB, NV, M, NNZ>(colour, k, dv, |r, h, lc, _| {
            let d = (gp.get(r).copied().unwrap_or(0.0) - gm.get(r).copied().unwrap_or(0.0)) / (2.0 * h);
            if let Some((_, at)) = self.layout.row_at(RowTerm::GammaV, r)
                && let Some(o) = out.get_mut(at + lc)
            {
                *o = d;
            }
        });
    }

    /// Scatters one colour's position direction: `∂(J u)/∂q`, `∂γ/∂q`,
    /// `∂Φ_t/∂q` of each row and the stiffness `∂(Jᵀλ)/∂q` of each joint.
    fn positions<S, const NB: usize, const NV: usize, const M: usize, const NNZ: usize>(
        &self,
        moved: &Moved<'_, NV, M, NNZ>,
        lambda: &SVector<f64, M>,
        u: &SVector<f64, NV>,
        out: &mut [f64],
    ) where
        S: Scene<NB, NV, M> + SparseJacobian<NB, NNZ>,
    {
        let [jp, jm] = moved.j;
        let difference = |pair: &[SVector<f64, M>; 2], r: usize, h: f64| {
            (pair[0].get(r).copied().unwrap_or(0.0) - pair[1].get(r).copied().unwrap_or(0.0)) / (2.0 * h)
        };
        self.each_row::<S, NB, NV, M, NNZ>(moved.colour, moved.k, moved.delta, |r, h, lc, (bodies, stiffness)| {
            let (Some(&a), Some(&e)) = (S::ROW_STARTS.get(r), S::ROW_STARTS.get(r + 1)) else { return };
            let (n, l) = (6 * bodies.len(), lambda.get(r).copied().unwrap_or(0.0));
            let mut ju = 0.0;
            for idx in a..e {
                let (Some(&p), Some(&m), Some(&col)) = (jp.get(idx), jm.get(idx), S::COLUMNS.get(idx)) else {
                    continue;
                };
                let d = (p - m) / (2.0 * h);
                ju += d * u.get(col).copied().unwrap_or(0.0);
                // Row of the stiffness block: the force's column, local to the joint.
                if let Some(i) = bodies.iter().position(|&b| b == col / 6)
                    && let Some(o) = out.get_mut(stiffness + (6 * i + col % 6) * n + lc)
                {
                    *o += l * d;
                }
            }
            let terms = [
                (RowTerm::JacobianQ, ju),
                (RowTerm::GammaQ, difference(moved.gamma, r, h)),
                (RowTerm::PhiTQ, difference(moved.phi_t, r, h)),
            ];
            for (term, value) in terms {
                if let Some((_, at)) = self.layout.row_at(term, r)
                    && let Some(o) = out.get_mut(at + lc)
                {
                    *o = value;
                }
            }
        });
    }

    /// Calls `f(row, step, local column, (bodies, stiffness offset))` for each
    /// row of each joint that has a body of `colour`, moved along its column
    /// `k` by `delta`'s entry.
    fn each_row<S, const NB: usize, const NV: usize, const M: usize, const NNZ: usize>(
        &self,
        colour: usize,
        k: usize,
        delta: &SVector<f64, NV>,
        mut f: impl FnMut(usize, f64, usize, (&[usize], usize)),
    ) where
        S: Scene<NB, NV, M> + SparseJacobian<NB, NNZ>,
    {
        for (joint, block) in S::BLOCKS.iter().enumerate() {
            let Some((bodies, stiffness)) = self.layout.stiffness_at(joint) else { continue };
            let Some(i) = bodies.iter().position(|&b| self.colour_of.get(b) == Some(&colour)) else { continue };
            let Some(&h) = bodies.get(i).and_then(|&b| delta.get(6 * b + k)) else { continue };
            if h == 0.0 {
                continue;
            }
            for r in block.start..block.start + block.rows {
                f(r, h, 6 * i + k, (bodies, stiffness));
            }
        }
    }
}

/// Colours `bodies` bodies greedily in order, each with the least colour
/// none of `conflicts(b)` has yet: the bodies of each colour, and each
/// body's colour.
pub(super) fn greedy_colours(bodies: usize, conflicts: impl Fn(usize) -> Vec<usize>) -> (Vec<Vec<usize>>, Vec<usize>) {
    let mut colour_of = vec![usize::MAX; bodies];
    let mut colours: Vec<Vec<usize>> = Vec::new();
    for b in 0..bodies {
        let taken: Vec<usize> = conflicts(b).iter().filter_map(|&n| colour_of.get(n).copied()).collect();
        let c = (0..).find(|c| !taken.contains(c)).unwrap_or(0);
        if c == colours.len() {
            colours.push(Vec::new());
        }
        if let Some(list) = colours.get_mut(c) {
            list.push(b);
        }
        if let Some(x) = colour_of.get_mut(b) {
            *x = c;
        }
    }
    (colours, colour_of)
}

/// One colour's position direction and the scene's terms both ways.
struct Moved<'d, const NV: usize, const M: usize, const NNZ: usize> {
    colour: usize,
    k: usize,
    delta: &'d SVector<f64, NV>,
    j: &'d [[f64; NNZ]; 2],
    gamma: &'d [SVector<f64, M>; 2],
    phi_t: &'d [SVector<f64, M>; 2],
}
