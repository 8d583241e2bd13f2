//! `#[scene(coordinates = relative)]`: the joints as a spanning tree from the
//! ground, checked: every joint a tree joint (`revolute`, `spherical` for
//! now), no joint closing a loop, every body reached.

use super::context::Errors;
use super::scene::{Body, JointDecl};

/// A tree joint's freedoms.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum TreeKind {
    /// One angle.
    Revolute,
    /// A unit quaternion.
    Spherical,
}

impl TreeKind {
    /// Of a catalogue joint, if it is a tree joint.
    pub fn of(name: &str) -> Option<Self> {
        match name {
            "revolute" => Some(TreeKind::Revolute),
            "spherical" => Some(TreeKind::Spherical),
            _ => None,
        }
    }

    /// Coordinates and velocities.
    pub fn sizes(self) -> (usize, usize) {
        match self {
            TreeKind::Revolute => (1, 1),
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

/// The joints in tree order, parents first: the first declared joint that
/// reaches a new body from the reached ones, again and again (a
/// breadth-first spanning tree that keeps the declaration's order among
/// equals).
pub fn spanning_tree(bodies: &[Body], joints: &[JointDecl], errors: &mut Errors) -> Vec<TreeEdge> {
    let mut kinds_ok = true;
    for j in joints {
        if TreeKind::of(j.kind.name).is_none() {
            kinds_ok = false;
            errors.at(
                j.kind_span,
                format!(
                    "`{}` has no tree parametrisation yet; relative coordinates take `revolute` and `spherical` \
                     joints; expected `coordinates = absolute` for this scene",
                    j.kind.name
                ),
            );
        }
    }
    if !kinds_ok {
        return Vec::new();
    }
    let mut reached = vec![false; bodies.len()];
    let is_reached = |b: Option<usize>, reached: &[bool]| b.is_none_or(|i| reached[i]);
    let mut edges = Vec::new();
    let mut used = vec![false; joints.len()];
    loop {
        let next = joints.iter().enumerate().find_map(|(i, j)| {
            let [a, b] = j.bodies;
            let (ra, rb) = (is_reached(a, &reached), is_reached(b, &reached));
            (!used[i] && ra != rb).then_some((i, rb))
        });
        let Some((i, reversed)) = next else { break };
        used[i] = true;
        let child = joints[i].bodies[usize::from(!reversed)];
        if let Some(c) = child {
            reached[c] = true;
        }
        let kind = TreeKind::of(joints[i].kind.name).unwrap_or(TreeKind::Revolute);
        edges.push(TreeEdge { joint: i, kind, reversed });
    }
    for j in joints.iter().zip(&used).filter(|(_, u)| !**u).map(|(j, _)| j) {
        let closes = j.bodies.iter().all(|b| is_reached(*b, &reached));
        if closes {
            errors.at(
                j.name.span(),
                format!(
                    "joint `{}` closes a loop; relative coordinates take trees for now; expected `coordinates = \
                     absolute` for this scene",
                    j.label()
                ),
            );
        }
    }
    // One message for all of them: they are one mistake (a missing joint, or
    // a floating base), at the first.
    let unreached: Vec<&Body> = bodies.iter().zip(&reached).filter(|(_, r)| !**r).map(|(b, _)| b).collect();
    if let Some(first) = unreached.first() {
        let names: Vec<String> = unreached.iter().map(|b| format!("`{}`", b.label())).collect();
        let (names, verb) = if names.len() == 1 { (names[0].clone(), "has") } else { (names.join(", "), "have") };
        errors.at(
            first.name.span(),
            format!(
                "{names} {verb} no path of joints to the ground; relative coordinates need one for every body \
                 (floating bases are not supported yet); expected a joint to the ground or `coordinates = absolute`"
            ),
        );
    }
    edges
}
