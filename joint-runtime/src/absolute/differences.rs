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

use nalgebra::SVector;

use super::buf::{Boxed, at_rest, boxed_with, zero_state, zeros};
use super::loads::neighbours;
use super::second_order::{JointBodies, RowTerm, SecondOrderLayout};
use crate::analysis::{apply_increment, set_velocities, velocity_vector_into};
use crate::scene::{Scene, SparseJacobian, SystemState};

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
    /// A zeroed work (its states at rest), boxed (with `alloc`) and written
    /// in the heap (`buf`).
    pub(super) fn boxed() -> Boxed<Self> {
        let mut w = boxed_with(|| {
            const {
                DifferenceWork {
                    delta: zeros(),
                    v: zeros(),
                    moved_v: zeros(),
                    states: [zero_state(); 2],
                    j: [[0.0; NNZ]; 2],
                    gamma: [zeros(); 2],
                    phi_t: [zeros(); 2],
                }
            }
        });
        w.states.iter_mut().for_each(at_rest);
        w
    }
}

/// A scene's sparse second-order terms by central differences, in the
/// layout of [`SecondOrderLayout`]; the colouring of its `NB` bodies is found
/// once, in [`DifferenceTerms::new`], and kept in an array (no allocator).
///
/// ```
/// use joint_runtime::nalgebra::{SVector, UnitQuaternion, Vector3};
/// use joint_runtime::absolute::{DifferenceTerms, SecondOrderLayout};
/// use joint_runtime::{OmegaBody, Scene, SparseJacobian, SystemState};
///
/// #[derive(Scene)]
/// #[scene(coordinates = absolute, gravity = [0, 0, -9.81], second_order)]
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
/// let terms = DifferenceTerms::<2>::new(Pendulum::BLOCK_BODIES);
/// assert_eq!(terms.colours(), 2);
/// assert!(terms.values(&Pendulum, &state, &lambda, &u, &mut differences));
/// for (x, y) in exact.iter().zip(&differences) {
///     assert!((x - y).abs() < 1e-8 * (1.0 + x.abs()));
/// }
/// ```
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DifferenceTerms<const NB: usize> {
    /// Each body's colour (no joint connects two bodies of one colour).
    colour_of: [usize; NB],
    colours: usize,
}

impl<const NB: usize> DifferenceTerms<NB> {
    /// The colouring of a scene's `NB` bodies, which its joints connect as
    /// `joint_bodies` says ([`SparseJacobian::BLOCK_BODIES`]): greedily in
    /// body order, each body the least colour no body it shares a joint
    /// with has.
    pub fn new(joint_bodies: &[[Option<usize>; 2]]) -> Self {
        let (colour_of, colours) = greedy_colours(|b| neighbours(joint_bodies, &[], b));
        DifferenceTerms { colour_of, colours }
    }

    /// The number of colours (each costs 24 evaluations of the scene).
    pub fn colours(&self) -> usize {
        self.colours
    }

    /// The bodies of `colour`, ascending.
    fn bodies(&self, colour: usize) -> impl Iterator<Item = usize> + '_ {
        (0..NB).filter(move |&b| self.colour_of.get(b) == Some(&colour))
    }

    /// The terms of [`Scene::second_order_values`] at `state` for the
    /// multipliers `lambda` and the velocity `u` of `∂(J u)/∂q`, by central
    /// differences, written into `out`; `false` (and nothing written) when
    /// `out` is not exactly the layout's length. Allocates its scratch (the
    /// moved states and the scene's values at them) for the call.
    pub fn values<S, const NV: usize, const M: usize, const NNZ: usize>(
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
        self.values_in::<S, NV, M, NNZ>(scene, state, (lambda, u), out, &mut DifferenceWork::boxed())
    }

    /// [`values`](Self::values) (for `(λ, u)`) with the scratch `work`.
    pub(super) fn values_in<S, const NV: usize, const M: usize, const NNZ: usize>(
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
        if out.len() != SecondOrderLayout::new(S::BLOCKS, S::BLOCK_BODIES).len() {
            return false;
        }
        out.fill(0.0);
        for colour in 0..self.colours {
            for k in 0..6 {
                self.position_direction::<S, NV, M, NNZ>(scene, state, (colour, k), (lambda, u), out, work);
                self.velocity_direction::<S, NV, M, NNZ>(scene, state, (colour, k), out, work);
            }
        }
        true
    }

    /// One colour's bodies moved along coordinate `k` of their position
    /// increments, both ways: the position derivatives' differences. In a
    /// frame of its own, apart from the velocity direction's.
    #[inline(never)]
    fn position_direction<S, const NV: usize, const M: usize, const NNZ: usize>(
        &self,
        scene: &S,
        state: &SystemState<NB>,
        (colour, k): (usize, usize),
        (lambda, u): (&SVector<f64, M>, &SVector<f64, NV>),
        out: &mut [f64],
        work: &mut DifferenceWork<NB, NV, M, NNZ>,
    ) where
        S: Scene<NB, NV, M> + SparseJacobian<NB, NNZ>,
    {
        let DifferenceWork { delta, states, j, gamma, phi_t, .. } = work;
        delta.fill(0.0);
        for b in self.bodies(colour) {
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
        self.positions::<S, NV, M, NNZ>(&moved, lambda, u, out);
    }

    /// One colour's bodies' velocity coordinate `k` moved both ways: `∂γ/∂v`.
    #[inline(never)]
    fn velocity_direction<S, const NV: usize, const M: usize, const NNZ: usize>(
        &self,
        scene: &S,
        state: &SystemState<NB>,
        (colour, k): (usize, usize),
        out: &mut [f64],
        work: &mut DifferenceWork<NB, NV, M, NNZ>,
    ) where
        S: Scene<NB, NV, M> + SparseJacobian<NB, NNZ>,
    {
        let DifferenceWork { delta: dv, v, moved_v, states, gamma, .. } = work;
        velocity_vector_into(state, v);
        dv.fill(0.0);
        for b in self.bodies(colour) {
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
        let layout = SecondOrderLayout::new(S::BLOCKS, S::BLOCK_BODIES);
        let start = layout.section_start(RowTerm::GammaV);
        self.each_row(&layout, colour, k, dv, |r, h, lc, row| {
            let d = (gp.get(r).copied().unwrap_or(0.0) - gm.get(r).copied().unwrap_or(0.0)) / (2.0 * h);
            if let Some(o) = out.get_mut(start + row.section + lc) {
                *o = d;
            }
        });
    }

    /// Scatters one colour's position direction: `∂(J u)/∂q`, `∂γ/∂q`,
    /// `∂Φ_t/∂q` of each row and the stiffness `∂(Jᵀλ)/∂q` of each joint.
    fn positions<S, const NV: usize, const M: usize, const NNZ: usize>(
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
        let layout = SecondOrderLayout::new(S::BLOCKS, S::BLOCK_BODIES);
        self.each_row(&layout, moved.colour, moved.k, moved.delta, |r, h, lc, row| {
            let (Some(&a), Some(&e)) = (S::ROW_STARTS.get(r), S::ROW_STARTS.get(r + 1)) else { return };
            let (bodies, stiffness) = (row.bodies.as_slice(), row.stiffness);
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
                if let Some(o) = out.get_mut(layout.section_start(term) + row.section + lc) {
                    *o = value;
                }
            }
        });
    }

    /// Calls `f(row, step, local column, row's place)` for each row of each
    /// joint that has a body of `colour`, moved along its column `k` by
    /// `delta`'s entry.
    fn each_row<const NV: usize>(
        &self,
        layout: &SecondOrderLayout<'_>,
        colour: usize,
        k: usize,
        delta: &SVector<f64, NV>,
        mut f: impl FnMut(usize, f64, usize, RowPlace),
    ) {
        for joint in layout.joints() {
            let bodies = joint.bodies.as_slice();
            let Some(i) = bodies.iter().position(|&b| self.colour_of.get(b) == Some(&colour)) else { continue };
            let Some(&h) = bodies.get(i).and_then(|&b| delta.get(6 * b + k)) else { continue };
            if h == 0.0 {
                continue;
            }
            let w = joint.bodies.width();
            for (local, r) in joint.rows.clone().enumerate() {
                let place =
                    RowPlace { bodies: joint.bodies, stiffness: joint.stiffness, section: joint.section + local * w };
                f(r, h, 6 * i + k, place);
            }
        }
    }
}

/// Where a row's terms go: its joint's bodies, where the joint's stiffness
/// block starts, where the row's entries start within a row section.
#[derive(Clone, Copy, Debug)]
struct RowPlace {
    bodies: JointBodies,
    stiffness: usize,
    section: usize,
}

/// Colours the `NB` bodies greedily in body order, each the least colour
/// none of the bodies `near(b)` has yet: each body's colour, and how many
/// colours there are.
pub(super) fn greedy_colours<const NB: usize, I: Iterator<Item = usize>>(
    near: impl Fn(usize) -> I,
) -> ([usize; NB], usize) {
    let mut colour_of = [usize::MAX; NB];
    let mut colours = 0;
    for b in 0..NB {
        let taken = |c: usize| near(b).any(|n| colour_of.get(n) == Some(&c));
        let c = (0..=NB).find(|&c| !taken(c)).unwrap_or(NB);
        if let Some(x) = colour_of.get_mut(b) {
            *x = c;
        }
        colours = colours.max(c + 1);
    }
    (colour_of, colours)
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
