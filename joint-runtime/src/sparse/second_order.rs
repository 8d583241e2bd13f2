//! The sparse layout of a scene's second-order terms
//! ([`Scene::second_order_values`](crate::Scene::second_order_values)).

use alloc::vec::Vec;

use crate::scene::RowBlock;

/// Where each entry of a scene's sparse second-order terms lives.
///
/// A joint's rows touch only the bodies it connects, so every second-order
/// term is zero outside their columns. For joint `k` (in
/// [`Scene::BLOCKS`](crate::Scene::BLOCKS) order) connecting the bodies `b_0`
/// (and `b_1`; the ground has no columns), its columns are `6 b_0 .. 6 b_0 + 6`
/// then `6 b_1 .. 6 b_1 + 6`: `w_k = 6` or `12` of them. The values are
///
/// 1. for each joint, its stiffness block `∂(J_kᵀ λ_k)/∂q` over its columns,
///    `w_k × w_k` row-major (row: the force's column, column: the increment's);
/// 2. for each row `i` of each joint in turn, `∂(J_i u)/∂q` over its joint's
///    `w_k` columns; then the same rows again for `∂γ_i/∂q`, for `∂γ_i/∂v` and
///    for `∂Φ_t,i/∂q`.
///
/// The scene's `K = ∂(Jᵀλ)/∂q` is the sum of the joints' blocks.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SecondOrderLayout {
    /// Per joint: its bodies and the offset of its stiffness block.
    joints: Vec<JointTerms>,
    /// Each row's joint and the offset of its entries within a row section.
    rows: Vec<(usize, usize)>,
    /// Where the stiffness blocks end (the first row section starts).
    stiffness_len: usize,
    /// The length of one row section.
    section_len: usize,
}

#[derive(Clone, Debug, PartialEq, Eq)]
struct JointTerms {
    bodies: Vec<usize>,
    stiffness: usize,
}

/// The four row sections, in layout order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RowTerm {
    /// `∂(J u)/∂q`.
    JacobianQ,
    /// `∂γ/∂q`.
    GammaQ,
    /// `∂γ/∂v`.
    GammaV,
    /// `∂Φ_t/∂q`.
    PhiTQ,
}

impl SecondOrderLayout {
    /// The layout of a scene with joint blocks `blocks` connecting `bodies`
    /// ([`Scene::BLOCKS`](crate::Scene::BLOCKS),
    /// [`SparseJacobian::BLOCK_BODIES`](crate::SparseJacobian::BLOCK_BODIES)).
    pub fn new(blocks: &[RowBlock], bodies: &[[Option<usize>; 2]]) -> Self {
        let (mut joints, mut rows) = (Vec::new(), Vec::new());
        let (mut stiffness, mut section) = (0, 0);
        for (block, pair) in blocks.iter().zip(bodies) {
            let mut list: Vec<usize> = pair.iter().flatten().copied().collect();
            list.dedup();
            let w = 6 * list.len();
            for _ in 0..block.rows {
                rows.push((joints.len(), section));
                section += w;
            }
            joints.push(JointTerms { bodies: list, stiffness });
            stiffness += w * w;
        }
        SecondOrderLayout { joints, rows, stiffness_len: stiffness, section_len: section }
    }

    /// The number of values (the length `second_order_values` writes).
    pub fn len(&self) -> usize {
        self.stiffness_len + 4 * self.section_len
    }

    /// Whether there are no values (a scene without rows).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The joints, each as `(its bodies, its stiffness block)`, the block
    /// `6n × 6n` row-major over the bodies' columns.
    pub fn stiffness<'v>(&'v self, values: &'v [f64]) -> impl Iterator<Item = (&'v [usize], &'v [f64])> + 'v {
        self.joints.iter().map(move |j| {
            let w = 6 * j.bodies.len();
            (&j.bodies[..], values.get(j.stiffness..j.stiffness + w * w).unwrap_or(&[]))
        })
    }

    /// Row `row`'s entries of `term` with its joint's bodies (`6n` values over
    /// their columns); `None` for a row out of range.
    pub fn row<'v>(&'v self, values: &'v [f64], term: RowTerm, row: usize) -> Option<(&'v [usize], &'v [f64])> {
        let (bodies, at) = self.row_at(term, row)?;
        Some((bodies, values.get(at..at + 6 * bodies.len())?))
    }

    /// Row `row`'s joint's bodies and where its entries of `term` start.
    pub(crate) fn row_at(&self, term: RowTerm, row: usize) -> Option<(&[usize], usize)> {
        let &(joint, offset) = self.rows.get(row)?;
        let joint = self.joints.get(joint)?;
        Some((&joint.bodies[..], self.stiffness_len + term as usize * self.section_len + offset))
    }

    /// Joint `joint`'s bodies and where its stiffness block starts.
    pub(crate) fn stiffness_at(&self, joint: usize) -> Option<(&[usize], usize)> {
        let joint = self.joints.get(joint)?;
        Some((&joint.bodies[..], joint.stiffness))
    }
}
