//! `#[scene(coordinates = relative)]`: the joints as a spanning tree from the
//! ground through its tree joints (`revolute`, `spherical`, `translational`,
//! `universal`, `fixed`), every body reached; the other joints close loops.

use super::context::Errors;
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
    /// Two angles (`universal`): about the parent's axis, then the child's.
    Universal,
    /// Welded (`fixed`): no freedom.
    Fixed,
}

impl TreeKind {
    /// Of a catalogue joint, if it is a tree joint.
    pub fn of(name: &str) -> Option<Self> {
        match name {
            "revolute" => Some(TreeKind::Revolute),
            "spherical" => Some(TreeKind::Spherical),
            "translational" => Some(TreeKind::Prismatic),
            "universal" => Some(TreeKind::Universal),
            "fixed" => Some(TreeKind::Fixed),
            _ => None,
        }
    }

    /// Coordinates and velocities.
    pub fn sizes(self) -> (usize, usize) {
        match self {
            TreeKind::Revolute | TreeKind::Prismatic => (1, 1),
            TreeKind::Universal => (2, 2),
            TreeKind::Fixed => (0, 0),
            TreeKind::Spherical => (4, 3),
        }
    }
}

/// A joint of the tree: which declared joint, which of its bodies is the
/// parent (the one nearer the ground).
#[derive(Clone, Copy, Debug)]
pub struct TreeEdge {
    /// The joint's index in the declaration.
    pub joint: usize,
    /// Its freedoms.
    pub kind: TreeKind,
    /// `true` when the joint's second body is the parent (`revolute(bar, ground)`).
    pub reversed: bool,
}

/// The joints in tree order, parents first: the first declared tree joint
/// (`revolute`, `spherical`, `translational`, `universal`, `fixed`) that
/// reaches a new body from the reached ones, again and again (a
/// breadth-first spanning tree that keeps the declaration's order among
/// equals). Every other joint (one that closes a
/// loop, or of a kind without a tree parametrisation) is a closure: its rows
/// stay constraints, composed with the tree's kinematics ([`closures`]).
pub fn spanning_tree(bodies: &[Body], joints: &[JointDecl], errors: &mut Errors) -> Vec<TreeEdge> {
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
        let Some((i, kind, reversed)) = next else { break };
        used[i] = true;
        if let Some(c) = joints[i].bodies[usize::from(!reversed)] {
            reached[c] = true;
        }
        edges.push(TreeEdge { joint: i, kind, reversed });
    }
    unreached(bodies, joints, &reached, errors);
    edges
}

/// One message for the bodies no tree joint reaches: they are one mistake (a
/// missing joint, a joint without a tree parametrisation, or a floating
/// base), at the first such joint's kind or else at the first body.
fn unreached(bodies: &[Body], joints: &[JointDecl], reached: &[bool], errors: &mut Errors) {
    let unreached: Vec<&Body> = bodies.iter().zip(reached).filter(|(_, r)| !**r).map(|(b, _)| b).collect();
    let Some(first) = unreached.first() else { return };
    let names: Vec<String> = unreached.iter().map(|b| format!("`{}`", b.label())).collect();
    let (names, verb) = if names.len() == 1 { (names[0].clone(), "has") } else { (names.join(", "), "have") };
    let touches = |j: &&JointDecl| j.bodies.iter().any(|b| b.is_some_and(|i| !reached[i]));
    match joints.iter().filter(touches).find(|j| TreeKind::of(j.kind.name).is_none()) {
        Some(j) => errors.at(
            j.kind_span,
            format!(
                "`{}` has no tree parametrisation yet, so {names} {verb} no path of tree joints (`revolute`, \
                 `spherical`, `translational`, `universal`, `fixed`) to the ground; expected `coordinates = absolute` for this scene",
                j.kind.name
            ),
        ),
        None => errors.at(
            first.name.span(),
            format!(
                "{names} {verb} no path of joints to the ground; relative coordinates need one for every body \
                 (floating bases are not supported yet); expected a joint to the ground or `coordinates = absolute`"
            ),
        ),
    }
}

/// The joints that are not in the tree, in declaration order: each closes a
/// loop (or joins two bodies the tree moves already), and its rows are
/// constraints on the tree's coordinates.
pub fn closures(joints: &[JointDecl], edges: &[TreeEdge]) -> Vec<usize> {
    (0..joints.len()).filter(|i| edges.iter().all(|e| e.joint != *i)).collect()
}
