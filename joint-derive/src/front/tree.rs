//! `#[scene(coordinates = relative)]`: the joints as a spanning tree from the
//! ground through its tree joints (`revolute`, `spherical`, `translational`,
//! `cylindrical`, `planar`, `universal`, `fixed`); a body no path of them
//! reaches floats (a free joint from the ground, as a body without joints is
//! free in absolute coordinates); the other joints close loops. The tree is
//! found breadth first from the ground, in declaration order among equals, so
//! the same declaration always gives the same tree, coordinates and closures.

use super::scene::{Body, JointDecl};

/// A tree joint's freedoms.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum TreeKind {
    /// One angle.
    Revolute,
    /// A unit quaternion.
    Spherical,
    /// A slide along the axis (`translational`), rotation locked.
    Prismatic,
    /// An angle and a slide along one axis (`cylindrical`).
    Cylindrical,
    /// Two slides in a plane and the turn about its normal (`planar`).
    Planar,
    /// Two angles (`universal`): about the parent's axis, then the child's.
    Universal,
    /// Welded (`fixed`): no freedom.
    Fixed,
    /// A floating body: its centre from the ground's origin, then a unit
    /// quaternion (no declared joint).
    Free,
}

impl TreeKind {
    /// Of a catalogue joint, if it is a tree joint.
    pub fn of(name: &str) -> Option<Self> {
        match name {
            "revolute" => Some(TreeKind::Revolute),
            "spherical" => Some(TreeKind::Spherical),
            "translational" => Some(TreeKind::Prismatic),
            "universal" => Some(TreeKind::Universal),
            "cylindrical" => Some(TreeKind::Cylindrical),
            "planar" => Some(TreeKind::Planar),
            "fixed" => Some(TreeKind::Fixed),
            _ => None,
        }
    }

    /// Coordinates and velocities.
    pub fn sizes(self) -> (usize, usize) {
        match self {
            TreeKind::Revolute | TreeKind::Prismatic => (1, 1),
            TreeKind::Universal | TreeKind::Cylindrical => (2, 2),
            TreeKind::Fixed => (0, 0),
            TreeKind::Spherical => (4, 3),
            TreeKind::Planar => (3, 3),
            TreeKind::Free => (7, 6),
        }
    }
}

/// A joint of the tree: which declared joint, which of its bodies is the
/// parent (the one nearer the ground).
#[derive(Clone, Copy, Debug)]
pub struct TreeEdge {
    /// The joint's index in the declaration; `None` for a floating body's
    /// free joint.
    pub joint: Option<usize>,
    /// Its freedoms.
    pub kind: TreeKind,
    /// `true` when the joint's second body is the parent (`revolute(bar, ground)`).
    pub reversed: bool,
    /// The parent body (`None`: the ground) and the child.
    pub ends: (Option<usize>, usize),
}

/// The joints in tree order, parents first: the first declared tree joint
/// (`revolute`, `spherical`, `translational`, `cylindrical`, `planar`,
/// `universal`, `fixed`) that
/// reaches a new body from the reached ones, again and again (a
/// breadth-first spanning tree that keeps the declaration's order among
/// equals). Every other joint (one that closes a
/// loop, or of a kind without a tree parametrisation) is a closure: its rows
/// stay constraints, composed with the tree's kinematics ([`closures`]).
/// When no tree joint reaches a new body, the first body not reached
/// (declaration order) floats: a free joint from the ground, and the search
/// goes on from it (a drone and the arm it carries).
pub fn spanning_tree(bodies: &[Body], joints: &[JointDecl]) -> Vec<TreeEdge> {
    let mut reached = vec![false; bodies.len()];
    let is_reached = |b: Option<usize>, reached: &[bool]| b.is_none_or(|i| reached[i]);
    let mut edges = Vec::new();
    let mut used = vec![false; joints.len()];
    loop {
        let next = joints.iter().enumerate().find_map(|(i, j)| {
            let kind = TreeKind::of(j.kind.name)?;
            let [a, b] = j.bodies;
            let (ra, rb) = (is_reached(a, &reached), is_reached(b, &reached));
            (!used[i] && ra != rb).then_some((i, kind, rb))
        });
        let edge = match next {
            Some((i, kind, reversed)) => {
                used[i] = true;
                let [a, b] = joints[i].bodies;
                let (parent, child) = if reversed { (b, a) } else { (a, b) };
                let Some(child) = child else { break };
                TreeEdge { joint: Some(i), kind, reversed, ends: (parent, child) }
            }
            None => match reached.iter().position(|r| !r) {
                Some(body) => TreeEdge { joint: None, kind: TreeKind::Free, reversed: false, ends: (None, body) },
                None => break,
            },
        };
        reached[edge.ends.1] = true;
        edges.push(edge);
    }
    edges
}

/// The joints that are not in the tree, in declaration order: each closes a
/// loop (or joins two bodies the tree moves already), and its rows are
/// constraints on the tree's coordinates.
pub fn closures(joints: &[JointDecl], edges: &[TreeEdge]) -> Vec<usize> {
    (0..joints.len()).filter(|i| edges.iter().all(|e| e.joint != Some(*i))).collect()
}
