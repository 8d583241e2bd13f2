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

use alloc::vec;
use alloc::vec::Vec;

use nalgebra::{SVector, Vector3};

use super::alpha::missing;
use super::differences::greedy_colours;
use super::kkt::{Kkt, KktStorage};
use crate::analysis::{AnalysisError, velocity_vector};
use crate::dynamics::{AppliedLoads, Direction, LOAD_STEP, Loads, load_differences_along};
use crate::scene::SystemState;

/// The bodies coloured at distance two on the Newton matrix's pattern.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(super) struct LoadColouring {
    colours: Vec<Vec<usize>>,
    /// Each body's neighbours on the pattern, itself included, ascending.
    neighbours: Vec<Vec<usize>>,
}

impl LoadColouring {
    /// The colouring of `bodies` bodies whose body-body blocks are `pairs`
    /// (both orders and the diagonal, as the pattern stores them).
    pub(super) fn new(bodies: usize, pairs: &[(usize, usize)]) -> Self {
        let mut neighbours = vec![Vec::new(); bodies];
        for &(a, b) in pairs {
            if let Some(n) = neighbours.get_mut(a) {
                n.push(b);
            }
        }
        for (b, n) in neighbours.iter_mut().enumerate() {
            n.push(b);
            n.sort_unstable();
            n.dedup();
        }
        // Within two couplings: the neighbours' neighbours.
        let near = |b: usize| neighbours[b].iter().flat_map(|&n| neighbours[n].iter().copied()).collect();
        let (colours, _) = greedy_colours(bodies, near);
        LoadColouring { colours, neighbours }
    }

    /// Adds `scale ×` the user loads' `∂Q/∂q` (`velocity` false) or `∂Q/∂v`
    /// at `state` to the body-body blocks of `kkt`.
    pub(super) fn add_blocks<L: AppliedLoads<NB>, const NB: usize, const NV: usize>(
        &self,
        kkt: &mut Kkt<f64, impl KktStorage<f64>>,
        user: &mut L,
        state: &SystemState<NB>,
        velocity: bool,
        scale: f64,
    ) -> Result<(), AnalysisError> {
        for colour in &self.colours {
            for k in 0..6 {
                let loads = derivative::<L, NB, NV>(user, state, colour, k, velocity);
                for (a, (f, t)) in loads.force.iter().zip(&loads.torque).enumerate() {
                    if *f == Vector3::zeros() && *t == Vector3::zeros() {
                        continue;
                    }
                    let near = self.neighbours.get(a).map_or(&[][..], |n| &n[..]);
                    let Some(&b) = colour.iter().find(|b| near.binary_search(b).is_ok()) else { continue };
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
}

/// The user loads' derivative along column `k` of every body of `colour` at
/// once: the user's own, or central differences of the loads.
fn derivative<L: AppliedLoads<NB>, const NB: usize, const NV: usize>(
    user: &mut L,
    state: &SystemState<NB>,
    colour: &[usize],
    k: usize,
    velocity: bool,
) -> Loads<NB> {
    let mut direction: Direction<NB> = [[Vector3::zeros(); 4]; NB];
    let mut delta = SVector::<f64, NV>::zeros();
    for &b in colour {
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
    let fastest = colour.iter().filter_map(|&b| v.get(6 * b + k)).fold(0.0, |m: f64, x| m.max(x.abs()));
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
        let n = 7;
        let mut pairs: Vec<(usize, usize)> = (0..n).map(|b| (b, b)).collect();
        for b in 1..n {
            pairs.extend([(b - 1, b), (b, b - 1)]);
        }
        let c = LoadColouring::new(n, &pairs);
        assert_eq!(c.colours.len(), 3);
        for colour in &c.colours {
            for (i, &a) in colour.iter().enumerate() {
                for &b in &colour[i + 1..] {
                    assert!(a.abs_diff(b) > 2, "{a} and {b} in one colour: {:?}", c.colours);
                }
            }
        }
    }
}
