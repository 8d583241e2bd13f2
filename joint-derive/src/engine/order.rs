//! A fill-reducing elimination order of a symmetric sparsity pattern, fixed at
//! compile time: minimum degree with the fill written out (exact, `O(n · d²)`
//! for `n` nodes of degree `d`; a scene has hundreds of joints, not millions).
//! Ties go to the node written first, so the order is deterministic.
//!
//! On a tree (a chain, a branched mechanism) it eliminates leaves first and
//! creates no fill; where loops close it keeps the fill of each loop local.
//! A scene's derive orders two patterns with it: the joint blocks of
//! `J M⁻¹ Jᵀ` (the runtime's block factor), and the implicit integrators'
//! saddle-point matrix over bodies and joints, each joint after its bodies
//! (the runtime's `absolute/kkt/`, which finds the same order at run time only
//! for springs between bodies no joint joins).

use std::collections::BTreeSet;

/// The elimination order of the nodes of `adjacency` (symmetric; a node's own
/// index, if listed, is ignored), and the pattern of the factor: for each node
/// in that order, its neighbours eliminated after it (the original pattern
/// plus fill), as positions in the order.
pub struct Elimination {
    /// Nodes in elimination order.
    pub order: Vec<usize>,
    /// For the k-th eliminated node, the positions (> k) of its neighbours at
    /// its elimination, ascending: the nonzero blocks of column k of the factor.
    pub below: Vec<Vec<usize>>,
}

/// Minimum-degree elimination of `adjacency`.
pub fn minimum_degree(adjacency: &[Vec<usize>]) -> Elimination {
    minimum_degree_after(adjacency, &vec![Vec::new(); adjacency.len()])
}

/// Minimum-degree elimination of `adjacency` in which node `i` is eligible
/// only once every node of `after[i]` is eliminated (a saddle-point matrix's
/// joint after its bodies, so that no pivot block is a zero block). The
/// runtime's `absolute/kkt/pattern.rs` runs the same rule and tie-break.
pub fn minimum_degree_after(adjacency: &[Vec<usize>], after: &[Vec<usize>]) -> Elimination {
    let n = adjacency.len();
    let mut graph: Vec<BTreeSet<usize>> =
        adjacency.iter().enumerate().map(|(i, a)| a.iter().copied().filter(|&j| j != i && j < n).collect()).collect();
    // Symmetric whatever the caller gave.
    for i in 0..n {
        for j in graph[i].clone() {
            graph[j].insert(i);
        }
    }
    let mut done = vec![false; n];
    let mut order = Vec::with_capacity(n);
    let mut neighbours = Vec::with_capacity(n);
    for _ in 0..n {
        let eligible =
            |i: usize| !done[i] && after.get(i).is_none_or(|a| a.iter().all(|&j| done.get(j) != Some(&false)));
        let Some(v) = (0..n).filter(|&i| eligible(i)).min_by_key(|&i| (graph[i].len(), i)) else { break };
        let around: Vec<usize> = graph[v].iter().copied().collect();
        for &a in &around {
            graph[a].remove(&v);
            graph[a].extend(around.iter().copied().filter(|&b| b != a));
        }
        graph[v].clear();
        done[v] = true;
        order.push(v);
        neighbours.push(around);
    }
    let mut position = vec![0; n];
    for (k, &v) in order.iter().enumerate() {
        position[v] = k;
    }
    let below = neighbours
        .into_iter()
        .map(|around| {
            let mut p: Vec<usize> = around.into_iter().map(|a| position[a]).collect();
            p.sort_unstable();
            p
        })
        .collect();
    Elimination { order, below }
}

#[cfg(test)]
mod tests {
    use super::minimum_degree;

    /// Fill entries: below-pattern entries that are not edges of the graph.
    fn fill(adjacency: &[Vec<usize>]) -> usize {
        let e = minimum_degree(adjacency);
        let mut count = 0;
        for (k, below) in e.below.iter().enumerate() {
            for &p in below {
                if !adjacency[e.order[k]].contains(&e.order[p]) {
                    count += 1;
                }
            }
        }
        count
    }

    #[test]
    fn a_chain_is_eliminated_from_an_end_without_fill() {
        let chain: Vec<Vec<usize>> =
            (0..6usize).map(|i| [i.wrapping_sub(1), i + 1].into_iter().filter(|&j| j < 6).collect()).collect();
        let e = minimum_degree(&chain);
        assert_eq!(e.order, [0, 1, 2, 3, 4, 5]);
        assert_eq!(fill(&chain), 0);
        assert!(e.below.iter().all(|b| b.len() <= 1));
    }

    #[test]
    fn a_star_is_eliminated_leaves_first_without_fill() {
        // Node 0 is the hub.
        let star: Vec<Vec<usize>> = (0..5).map(|i| if i == 0 { vec![1, 2, 3, 4] } else { vec![0] }).collect();
        let e = minimum_degree(&star);
        // The hub goes when one leaf is left (then both have degree 1).
        assert!(e.order[..3].iter().all(|&v| v != 0), "{:?}", e.order);
        assert_eq!(fill(&star), 0);
    }

    #[test]
    fn a_node_waits_for_the_nodes_it_comes_after() {
        // Nodes 0, 1 (bodies); 2 couples 0 and 1, 3 hangs on 0. By degree
        // alone 3 (one neighbour) would go first.
        let adjacency = vec![vec![2, 3], vec![2], vec![0, 1], vec![0]];
        let after = vec![vec![], vec![], vec![0, 1], vec![0]];
        let e = super::minimum_degree_after(&adjacency, &after);
        let at = |x: usize| e.order.iter().position(|&y| y == x).expect("every node");
        assert!(at(3) > at(0) && at(2) > at(0) && at(2) > at(1), "{:?}", e.order);
    }

    #[test]
    fn a_ring_closes_with_fill_of_one_path() {
        let n = 8;
        let ring: Vec<Vec<usize>> = (0..n).map(|i| vec![(i + n - 1) % n, (i + 1) % n]).collect();
        let e = minimum_degree(&ring);
        assert_eq!(e.order.len(), n);
        // Eliminating a ring node joins its two neighbours: n - 3 fill edges in all.
        assert_eq!(fill(&ring), n - 3);
    }

    #[test]
    fn a_ladder_keeps_its_fill_bounded_per_rung() {
        // Two rails of n nodes and a rung at each position: 3n - 2 edges.
        let n = 20;
        let mut adj = vec![Vec::new(); 2 * n];
        let mut edge = |a: usize, b: usize| {
            adj[a].push(b);
            adj[b].push(a);
        };
        for i in 0..n {
            edge(i, n + i);
            if i + 1 < n {
                edge(i, i + 1);
                edge(n + i, n + i + 1);
            }
        }
        let e = minimum_degree(&adj);
        assert!(e.below.iter().all(|b| b.len() <= 3), "{:?}", e.below);
        assert!(fill(&adj) <= 2 * n, "fill {}", fill(&adj));
    }
}
