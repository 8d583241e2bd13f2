//! The sparse layout of a scene's second-order terms
//! ([`Scene::second_order_values`](crate::Scene::second_order_values)).

use core::ops::Range;

use super::buf::{Buf, filled};
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
/// The scene's `K = ∂(Jᵀλ)/∂q` is the sum of the joints' blocks. The layout
/// borrows the scene's constants and stores nothing else (no allocator):
/// offsets are running sums, so walking the joints in order
/// ([`stiffness`](Self::stiffness)) is free, and looking one row up
/// ([`row`](Self::row)) walks the joints before it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SecondOrderLayout<'s> {
    blocks: &'s [RowBlock],
    bodies: &'s [[Option<usize>; 2]],
    /// Where the stiffness blocks end (the first row section starts).
    stiffness_len: usize,
    /// The length of one row section.
    section_len: usize,
}

/// The bodies a joint connects (one or two; none for a joint of the ground
/// alone), as its second-order terms order their columns.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct JointBodies {
    bodies: [usize; 2],
    len: usize,
}

impl JointBodies {
    /// A joint's bodies from its pair (the ground, `None`, has no columns; a
    /// body given twice counts once).
    fn of(pair: [Option<usize>; 2]) -> Self {
        match pair {
            [Some(a), Some(b)] if a != b => JointBodies { bodies: [a, b], len: 2 },
            [Some(a), _] | [None, Some(a)] => JointBodies { bodies: [a, a], len: 1 },
            [None, None] => JointBodies { bodies: [0, 0], len: 0 },
        }
    }

    /// The bodies, in column order.
    pub fn as_slice(&self) -> &[usize] {
        self.bodies.get(..self.len).unwrap_or(&[])
    }

    /// The joint's columns: six per body.
    pub fn width(&self) -> usize {
        6 * self.len
    }
}

/// One joint's place in the layout.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct JointTerms {
    /// Its node among the joints (`Scene::BLOCKS` order).
    pub(crate) index: usize,
    pub(crate) bodies: JointBodies,
    /// Where its stiffness block starts.
    pub(crate) stiffness: usize,
    /// Its rows of the scene.
    pub(crate) rows: Range<usize>,
    /// Where its first row's entries start within a row section (each row
    /// after it `bodies.width()` further).
    pub(crate) section: usize,
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

impl<'s> SecondOrderLayout<'s> {
    /// The layout of a scene with joint blocks `blocks` connecting `bodies`
    /// ([`Scene::BLOCKS`](crate::Scene::BLOCKS),
    /// [`SparseJacobian::BLOCK_BODIES`](crate::SparseJacobian::BLOCK_BODIES)).
    pub fn new(blocks: &'s [RowBlock], bodies: &'s [[Option<usize>; 2]]) -> Self {
        let mut layout = SecondOrderLayout { blocks, bodies, stiffness_len: 0, section_len: 0 };
        if let Some(last) = layout.joints().last() {
            let w = last.bodies.width();
            layout.stiffness_len = last.stiffness + w * w;
            layout.section_len = last.section + w * last.rows.len();
        }
        layout
    }

    /// The number of values (the length `second_order_values` writes).
    pub fn len(&self) -> usize {
        self.stiffness_len + 4 * self.section_len
    }

    /// Whether there are no values (a scene without rows).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Where section `term`'s entries start.
    pub(crate) fn section_start(&self, term: RowTerm) -> usize {
        self.stiffness_len + term as usize * self.section_len
    }

    /// The joints in order, each with its offsets (running sums).
    pub(crate) fn joints(&self) -> impl Iterator<Item = JointTerms> + 's {
        let (mut stiffness, mut section) = (0, 0);
        self.blocks.iter().zip(self.bodies).enumerate().map(move |(index, (block, &pair))| {
            let bodies = JointBodies::of(pair);
            let w = bodies.width();
            let terms = JointTerms { index, bodies, stiffness, rows: block.start..block.start + block.rows, section };
            stiffness += w * w;
            section += w * block.rows;
            terms
        })
    }

    /// The joints, each as `(its bodies, its stiffness block)`, the block
    /// `6n × 6n` row-major over the bodies' columns.
    pub fn stiffness<'v>(&self, values: &'v [f64]) -> impl Iterator<Item = (JointBodies, &'v [f64])> + 'v
    where
        's: 'v,
    {
        self.joints().map(move |j| {
            let w = j.bodies.width();
            (j.bodies, values.get(j.stiffness..j.stiffness + w * w).unwrap_or(&[]))
        })
    }

    /// Row `row`'s entries of `term` with its joint's bodies (`6n` values over
    /// their columns); `None` for a row out of range. Walks the joints up to
    /// the row's.
    pub fn row<'v>(&self, values: &'v [f64], term: RowTerm, row: usize) -> Option<(JointBodies, &'v [f64])> {
        let joint = self.joints().find(|j| j.rows.contains(&row))?;
        let w = joint.bodies.width();
        let at = self.section_start(term) + joint.section + (row - joint.rows.start) * w;
        Some((joint.bodies, values.get(at..at + w)?))
    }
}

/// Where a scene's second-order terms live between their evaluation and
/// the Newton matrix they build: implemented by [`TermArray`], whose length
/// the derive writes into each scene's
/// [`SparseJacobian::Terms`](crate::SparseJacobian::Terms).
pub trait TermStorage: Clone + core::fmt::Debug + Send + Sync + sealed::Sealed {
    /// Zeros.
    #[doc(hidden)]
    fn zeroed() -> Self;
    /// The values.
    #[doc(hidden)]
    fn values(&self) -> &[f64];
    /// The values, to write.
    #[doc(hidden)]
    fn values_mut(&mut self) -> &mut [f64];
}

mod sealed {
    pub trait Sealed {}
}

/// The `L` values of a scene's [`SecondOrderLayout`] (boxed with `alloc`,
/// inline without).
#[derive(Clone, Debug)]
pub struct TermArray<const L: usize>(Buf<f64, L>);

impl<const L: usize> sealed::Sealed for TermArray<L> {}

impl<const L: usize> TermStorage for TermArray<L> {
    fn zeroed() -> Self {
        TermArray(filled(0.0))
    }

    fn values(&self) -> &[f64] {
        &self.0[..]
    }

    fn values_mut(&mut self) -> &mut [f64] {
        &mut self.0[..]
    }
}
