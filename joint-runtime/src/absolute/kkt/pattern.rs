//! A saddle-point pattern found at run time (with `alloc`): for couplings
//! the derive's pattern does not have (springs between bodies no joint
//! joins). The same minimum degree as the derive's (`joint-derive`'s
//! `engine/order.rs`, the joints' rule included), so a scene's own couplings
//! give the derive's pattern exactly (a test checks it).

use alloc::collections::BTreeSet;
use alloc::vec;
use alloc::vec::Vec;

use super::BAD_STRUCTURE;
use crate::linalg::LinalgError;

/// The elimination order (nodes: bodies `0..bodies`, joint `j` at
/// `bodies + j`) and each position's later neighbours (positions,
/// ascending; fill included) of the graph of `joint_bodies` and
/// `couplings`.
///
/// # Errors
/// [`LinalgError::NonFinite`] for a joint of more than 6 rows or a body
/// index out of range.
pub(super) fn eliminate(
    bodies: usize,
    joint_rows: &[usize],
    joint_bodies: &[[Option<usize>; 2]],
    couplings: &[(usize, usize)],
) -> Result<(Vec<usize>, Vec<Vec<usize>>), LinalgError> {
    let n = bodies + joint_rows.len();
    let mut graph: Vec<BTreeSet<usize>> = vec![BTreeSet::new(); n];
    let mut link = |a: usize, b: usize| -> Result<(), LinalgError> {
        if a >= n || b >= n {
            return Err(BAD_STRUCTURE);
        }
        if a != b {
            graph[a].insert(b);
            graph[b].insert(a);
        }
        Ok(())
    };
    for (j, (&rows, pair)) in joint_rows.iter().zip(joint_bodies).enumerate() {
        if rows > 6 {
            return Err(BAD_STRUCTURE);
        }
        for &b in pair.iter().flatten() {
            if b >= bodies {
                return Err(BAD_STRUCTURE);
            }
            link(bodies + j, b)?;
        }
    }
    for &(a, b) in couplings {
        if a >= bodies || b >= bodies {
            return Err(BAD_STRUCTURE);
        }
        link(a, b)?;
    }
    let (order, later) = elimination_order(graph, bodies, joint_bodies);
    let mut position = vec![0; n];
    for (k, &node) in order.iter().enumerate() {
        position[node] = k;
    }
    let below = later
        .into_iter()
        .map(|nodes| {
            let mut ps: Vec<usize> = nodes.iter().map(|&x| position[x]).collect();
            ps.sort_unstable();
            ps
        })
        .collect();
    Ok((order, below))
}

/// Minimum degree on `graph` (bodies are nodes `0..bodies`, joint `j` node
/// `bodies + j`), a joint eligible only once its bodies are eliminated; ties
/// go to the lower node, so the order is deterministic. Returns the order and,
/// for each step, the nodes still in the graph that the eliminated one reached
/// (fill included): the factor's pattern.
fn elimination_order(
    mut graph: Vec<BTreeSet<usize>>,
    bodies: usize,
    joint_bodies: &[[Option<usize>; 2]],
) -> (Vec<usize>, Vec<Vec<usize>>) {
    let n = graph.len();
    let mut done = vec![false; n];
    let (mut order, mut later) = (Vec::with_capacity(n), Vec::with_capacity(n));
    while order.len() < n {
        let eligible = |x: usize| {
            !done[x]
                && (x < bodies || joint_bodies.get(x - bodies).is_none_or(|p| p.iter().flatten().all(|&b| done[b])))
        };
        let Some(next) = (0..n).filter(|&x| eligible(x)).min_by_key(|&x| (graph[x].len(), x)) else { break };
        let neighbours: Vec<usize> = graph[next].iter().copied().collect();
        for &a in &neighbours {
            graph[a].remove(&next);
            for &b in &neighbours {
                if a != b {
                    graph[a].insert(b);
                }
            }
        }
        done[next] = true;
        order.push(next);
        later.push(neighbours);
    }
    (order, later)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn joints_wait_for_their_bodies() {
        // Bodies 0, 1; joint 2 grounds body 0, joint 3 joins 0 and 1. By degree
        // alone joint 2 (one neighbour) would go first, onto a zero pivot.
        let mut graph = vec![BTreeSet::new(); 4];
        for (a, b) in [(2, 0), (3, 0), (3, 1)] {
            graph[a].insert(b);
            graph[b].insert(a);
        }
        let (order, _) = elimination_order(graph, 2, &[[None, Some(0)], [Some(0), Some(1)]]);
        let at = |x: usize| order.iter().position(|&y| y == x).expect("every node");
        assert!(at(2) > at(0) && at(3) > at(0) && at(3) > at(1), "{order:?}");
    }
}
