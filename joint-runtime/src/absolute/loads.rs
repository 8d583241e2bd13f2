//! The user loads' derivatives `∂Q/∂q`, `∂Q/∂v` in the sparse Newton
//! matrices (midpoint, generalised-α, Radau IIA), on the blocks their pattern
//! has: each body's own block and the blocks of the bodies a joint or a spring
//! couples to it.
//!
//! A user load is a closure over the whole state, so its derivative could
//! couple any two bodies; a column at a time would cost `O(N)` evaluations of
//! an `O(N)` closure. The bodies are coloured instead so that no two bodies of
//! a colour are within two couplings of each other: moving a colour's bodies
//! at once, the response of a body comes from the one moved body among itself
//! and its neighbours, and lands on that block. Six directions of positions
//! and six of velocities per colour (a chain needs three colours, whatever
//! its length) by the user's [`AppliedLoads::derivative`] along the combined
//! direction, or central differences of [`AppliedLoads::apply`]. What a load
//! couples beyond the pattern is left out: simplified Newton then converges
//! more slowly, to the same solution.

use nalgebra::{SVector, Vector3};

use super::alpha::missing;
use super::differences::greedy_colours;
use super::kkt::{Kkt, KktStorage};
use crate::analysis::{AnalysisError, velocity_vector};
use crate::dynamics::{AppliedLoads, Attachment, Direction, LOAD_STEP, Loads, SpringDamper, load_differences_along};
use crate::scene::SystemState;

/// The pairs of distinct bodies a joint (of `joint_bodies`) or a spring
/// couples, each once per joint or spring.
pub(super) fn body_pairs<'a>(
    joint_bodies: &'a [[Option<usize>; 2]],
    springs: &'a [SpringDamper],
) -> impl Iterator<Item = (usize, usize)> + 'a {
    let end = |e: Attachment| match e {
        Attachment::Body { body, .. } => Some(body),
        Attachment::Ground(_) => None,
    };
    let joints = joint_bodies.iter().copied();
    let springs = springs.iter().map(move |s| [end(s.a), end(s.b)]);
    joints.chain(springs).filter_map(|pair| match pair {
        [Some(a), Some(b)] if a != b => Some((a, b)),
        _ => None,
    })
}

/// The bodies coloured at distance two on the Newton matrix's pattern: no
/// two bodies of a colour within two couplings of each other. Arrays of the
/// scene's size; the couplings are read from the scene's constants and the
/// springs, not stored.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(super) struct LoadColouring<const NB: usize> {
    joint_bodies: &'static [[Option<usize>; 2]],
    colour_of: [usize; NB],
    colours: usize,
    /// Per body, the one body of the colour being moved among itself and its
    /// neighbours (`usize::MAX`: none): where its response lands.
    moved_near: [usize; NB],
}

impl<const NB: usize> LoadColouring<NB> {
    /// The colouring of the bodies `joint_bodies` (the scene's
    /// `BLOCK_BODIES`) and `springs` couple: greedily in body order, each
    /// body the least colour no body within two couplings has.
    pub(super) fn new(joint_bodies: &'static [[Option<usize>; 2]], springs: &[SpringDamper]) -> Self {
        // Within two couplings: the neighbours' neighbours (`b` itself, not
        // yet coloured, takes no colour).
        let near = |x: usize| core::iter::once(x).chain(neighbours(joint_bodies, springs, x));
        let (colour_of, colours) = greedy_colours(|b| near(b).flat_map(near));
        LoadColouring { joint_bodies, colour_of, colours, moved_near: [usize::MAX; NB] }
    }

    /// Adds `scale ×` the user loads' `∂Q/∂q` (`velocity` false) or `∂Q/∂v`
    /// at `state` to the body-body blocks of `kkt` (the scene's couplings
    /// and `springs`, as in [`LoadColouring::new`]).
    pub(super) fn add_blocks<L: AppliedLoads<NB>, const NV: usize>(
        &mut self,
        kkt: &mut Kkt<f64, impl KktStorage<f64>>,
        user: &mut L,
        springs: &[SpringDamper],
        state: &SystemState<NB>,
        velocity: bool,
        scale: f64,
    ) -> Result<(), AnalysisError> {
        for colour in 0..self.colours {
            self.find_moved_near(springs, colour);
            for k in 0..6 {
                let loads = derivative::<L, NB, NV>(user, state, &self.colour_of, colour, k, velocity);
                for ((a, (f, t)), &b) in loads.force.iter().zip(&loads.torque).enumerate().zip(&self.moved_near) {
                    if (*f == Vector3::zeros() && *t == Vector3::zeros()) || b == usize::MAX {
                        continue;
                    }
                    let out = kkt.block_mut(a, b).ok_or_else(missing)?;
                    for i in 0..3 {
                        out[6 * i + k] += scale * f[i];
                        out[6 * (3 + i) + k] += scale * t[i];
                    }
                }
            }
        }
        Ok(())
    }

    /// `moved_near` for the bodies of `colour` (at most one per body: two
    /// would be within two couplings of each other).
    fn find_moved_near(&mut self, springs: &[SpringDamper], colour: usize) {
        for (b, (near, &c)) in self.moved_near.iter_mut().zip(&self.colour_of).enumerate() {
            *near = if c == colour { b } else { usize::MAX };
        }
        for (a, b) in body_pairs(self.joint_bodies, springs) {
            for (x, y) in [(a, b), (b, a)] {
                if self.colour_of.get(y) == Some(&colour)
                    && let Some(near) = self.moved_near.get_mut(x)
                {
                    *near = y;
                }
            }
        }
    }
}

/// The bodies coupled to `x`.
pub(super) fn neighbours<'a>(
    joint_bodies: &'a [[Option<usize>; 2]],
    springs: &'a [SpringDamper],
    x: usize,
) -> impl Iterator<Item = usize> + 'a {
    body_pairs(joint_bodies, springs).filter_map(move |(a, b)| {
        if a == x {
            Some(b)
        } else if b == x {
            Some(a)
        } else {
            None
        }
    })
}

/// The user loads' derivative along column `k` of every body of `colour` at
/// once: the user's own, or central differences of the loads.
fn derivative<L: AppliedLoads<NB>, const NB: usize, const NV: usize>(
    user: &mut L,
    state: &SystemState<NB>,
    colour_of: &[usize; NB],
    colour: usize,
    k: usize,
    velocity: bool,
) -> Loads<NB> {
    let mut direction: Direction<NB> = [[Vector3::zeros(); 4]; NB];
    let mut delta = SVector::<f64, NV>::zeros();
    let bodies = || (0..NB).filter(move |&b| colour_of.get(b) == Some(&colour));
    for b in bodies() {
        if let Some(d) = direction.get_mut(b) {
            d[usize::from(velocity) * 2 + k / 3][k % 3] = 1.0;
        }
        if let Some(d) = delta.get_mut(6 * b + k) {
            *d = 1.0;
        }
    }
    let mut loads = Loads::<NB>::default();
    if user.derivative(state, &direction, &mut loads) {
        return loads;
    }
    let v = velocity_vector::<NB, NV>(state);
    let fastest = bodies().filter_map(|b| v.get(6 * b + k)).fold(0.0, |m: f64, x| m.max(x.abs()));
    let step = LOAD_STEP * (1.0 + if velocity { fastest } else { 0.0 });
    load_differences_along(user, state, &delta, velocity, step)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// On a chain (each body coupled to the next) no two bodies of a colour
    /// are within two couplings, and three colours do.
    #[test]
    fn chains_take_three_colours_at_distance_two() {
        const JOINTS: [[Option<usize>; 2]; 7] = [
            [None, Some(0)],
            [Some(0), Some(1)],
            [Some(1), Some(2)],
            [Some(2), Some(3)],
            [Some(3), Some(4)],
            [Some(4), Some(5)],
            [Some(5), Some(6)],
        ];
        let c = LoadColouring::<7>::new(&JOINTS, &[]);
        assert_eq!(c.colours, 3);
        for a in 0..7 {
            for b in a + 1..7 {
                assert!(c.colour_of[a] != c.colour_of[b] || a.abs_diff(b) > 2, "{a} and {b}: {:?}", c.colour_of);
            }
        }
    }
}
