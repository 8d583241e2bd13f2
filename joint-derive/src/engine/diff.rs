//! Differentiation on the graph: a time derivative with kinematic rules, and
//! reverse-mode gradients.
//!
//! The time derivative is structural (sum, product, chain rules) except where a
//! node has a *rule*: the derivative of an input variable (`ṙ` for `r`, zero for
//! a velocity when γ is wanted), or a kinematic identity registered by the
//! formulation for a rotated vector (`d/dt (A a') = ω × (A a')`). Rules are what
//! make the ω formulations come out in compact vector form rather than through
//! Euler-parameter rates. γ is `−dΦ̇/dt` under rules that hold the velocities
//! (`v̇ = 0`) and move the time functions; Φ_t is the time derivative under
//! rules in which only time moves (`CONVENTIONS.md`). The same rules taken
//! along another direction (`TimeRules::along`) give the directional
//! derivatives of the second-order terms.
//!
//! The gradient is reverse mode over the arena (children have smaller ids, so a
//! descending sweep is a reverse topological order). Taking the Jacobian row as
//! the gradient of Φ̇ with respect to the velocities pushes adjoints through the
//! rotation matrices, which yields `Aᵀ g` and `a × b` directly, rather than
//! expanded sums. A row whose Jacobian depends on a velocity is not linear in
//! the velocities, and lowering rejects it.

use std::collections::HashMap;

use super::graph::{Graph, Id, Node, VELOCITY, VarId};

/// The rules of one time derivative.
#[derive(Default, Clone)]
pub struct TimeRules {
    vars: HashMap<VarId, Id>,
    nodes: HashMap<Id, Id>,
    memo: HashMap<Id, Id>,
}

impl TimeRules {
    /// Rules in which every variable is constant.
    pub fn new() -> Self {
        Self::default()
    }

    /// `d/dt var = derivative`.
    pub fn set_var(&mut self, graph: &Graph, var: Id, derivative: Id) {
        let v = graph.as_var(var).expect("set_var takes a variable node");
        self.vars.insert(v, derivative);
        self.memo.clear();
    }

    /// `d/dt node = derivative`, for a node that is not a constant (a rotated
    /// vector's component, say). A rule already present is kept: two rules for
    /// one node are the same identity.
    pub fn set_node(&mut self, graph: &Graph, node: Id, derivative: Id) {
        if graph.as_const(node).is_some() || graph.as_var(node).is_some() {
            return;
        }
        self.nodes.entry(node).or_insert(derivative);
        self.memo.clear();
    }

    /// These rules with `overrides`' node rules in place of their own (the same
    /// motion written another way, e.g. a rotated vector's body-frame rule).
    pub fn overridden(&self, overrides: &TimeRules) -> TimeRules {
        let mut rules = self.clone();
        for (&node, &derivative) in &overrides.nodes {
            rules.nodes.insert(node, derivative);
        }
        rules.memo.clear();
        rules
    }

    /// The same motion along another direction: the rules of the coordinates
    /// `coords` and of every node free of velocities, with each velocity
    /// variable replaced by its node in `direction`. Rules stated on nodes that
    /// hold a velocity (an ω held constant, a second derivative) hold only along
    /// the velocity itself and are left out, as are the time functions': the
    /// derivative then goes through their parts. The velocities are held.
    pub fn along(&self, g: &mut Graph, coords: &[Id], direction: &HashMap<VarId, Id>) -> TimeRules {
        let mut memo = HashMap::new();
        let mut out = TimeRules::new();
        let mut vars: Vec<(VarId, Id)> =
            coords.iter().filter_map(|&c| g.as_var(c)).filter_map(|v| self.vars.get(&v).map(|&d| (v, d))).collect();
        vars.sort_by_key(|&(v, _)| v.0);
        for (v, d) in vars {
            let d = g.substitute(d, direction, &mut memo);
            out.vars.insert(v, d);
        }
        let mut nodes: Vec<(Id, Id)> =
            self.nodes.iter().filter(|&(&n, _)| g.mask(n) & VELOCITY == 0).map(|(&n, &d)| (n, d)).collect();
        nodes.sort_by_key(|&(n, _)| n);
        for (n, d) in nodes {
            let d = g.substitute(d, direction, &mut memo);
            out.nodes.insert(n, d);
        }
        out
    }

    /// The time derivative of `id`.
    pub fn dt(&mut self, g: &mut Graph, id: Id) -> Id {
        if let Some(&d) = self.memo.get(&id) {
            return d;
        }
        let d = if let Some(&d) = self.nodes.get(&id) {
            d
        } else {
            match g.node(id) {
                Node::Const(_) => g.zero(),
                Node::Var(v) => match self.vars.get(&v) {
                    Some(&d) => d,
                    None => g.zero(),
                },
                Node::Add(a, b) => {
                    let (da, db) = (self.dt(g, a), self.dt(g, b));
                    g.add(da, db)
                }
                Node::Sub(a, b) => {
                    let (da, db) = (self.dt(g, a), self.dt(g, b));
                    g.sub(da, db)
                }
                Node::Mul(a, b) => {
                    let (da, db) = (self.dt(g, a), self.dt(g, b));
                    let l = g.mul(da, b);
                    let r = g.mul(a, db);
                    g.add(l, r)
                }
                Node::Div(a, b) => {
                    // (a/b)' = (a' − (a/b) b') / b
                    let (da, db) = (self.dt(g, a), self.dt(g, b));
                    let q = g.div(a, b);
                    let m = g.mul(q, db);
                    let n = g.sub(da, m);
                    g.div(n, b)
                }
                Node::Neg(a) => {
                    let da = self.dt(g, a);
                    g.neg(da)
                }
                Node::Sin(a) => {
                    let da = self.dt(g, a);
                    let c = g.cos(a);
                    g.mul(c, da)
                }
                Node::Cos(a) => {
                    let da = self.dt(g, a);
                    let s = g.sin(a);
                    let m = g.mul(s, da);
                    g.neg(m)
                }
                Node::Sqrt(a) => {
                    // (√a)' = a' / (2 √a)
                    let da = self.dt(g, a);
                    let two = g.constant(2.0);
                    let root = g.mul(two, id);
                    g.div(da, root)
                }
            }
        };
        self.memo.insert(id, d);
        d
    }
}

/// Reverse-mode gradient of `root` with respect to `wrt` (variable nodes).
///
/// Adjoints are propagated only into subgraphs that depend on some of `wrt`
/// (by the dependency masks), so parameters and constants cost nothing.
pub fn grad(g: &mut Graph, root: Id, wrt: &[Id]) -> Vec<Id> {
    let wanted: u64 = wrt
        .iter()
        .map(|&w| g.var_mask(g.as_var(w).expect("grad is taken with respect to variables")))
        .fold(0, |a, b| a | b);
    let zero = g.zero();
    let mut adjoint: HashMap<Id, Id> = HashMap::new();
    if g.mask(root) & wanted == 0 {
        return vec![zero; wrt.len()];
    }
    adjoint.insert(root, g.constant(1.0));
    // Descending ids are a reverse topological order of the arena: a node is
    // taken once every node above it that reaches it has given its share. Only
    // the nodes the root reaches are visited (a scene's row touches two bodies
    // of hundreds), so a row costs its own subgraph, not the arena.
    let mut pending = std::collections::BinaryHeap::from([root]);
    while let Some(id) = pending.pop() {
        let Some(&bar) = adjoint.get(&id) else { continue };
        let mut push = |g: &mut Graph, child: Id, contribution: Id| {
            if g.mask(child) & wanted == 0 {
                return;
            }
            let next = match adjoint.get(&child) {
                Some(&acc) => g.add(acc, contribution),
                None => {
                    pending.push(child);
                    contribution
                }
            };
            adjoint.insert(child, next);
        };
        match g.node(id) {
            Node::Const(_) | Node::Var(_) => {}
            Node::Add(a, b) => {
                push(g, a, bar);
                push(g, b, bar);
            }
            Node::Sub(a, b) => {
                push(g, a, bar);
                let nb = g.neg(bar);
                push(g, b, nb);
            }
            Node::Mul(a, b) => {
                if g.mask(a) & wanted != 0 {
                    let c = g.mul(bar, b);
                    push(g, a, c);
                }
                if g.mask(b) & wanted != 0 {
                    let c = g.mul(bar, a);
                    push(g, b, c);
                }
            }
            Node::Div(a, b) => {
                let over = g.div(bar, b);
                if g.mask(a) & wanted != 0 {
                    push(g, a, over);
                }
                if g.mask(b) & wanted != 0 {
                    let q = g.div(a, b);
                    let m = g.mul(over, q);
                    let c = g.neg(m);
                    push(g, b, c);
                }
            }
            Node::Neg(a) => {
                let c = g.neg(bar);
                push(g, a, c);
            }
            Node::Sin(a) => {
                let cos = g.cos(a);
                let c = g.mul(bar, cos);
                push(g, a, c);
            }
            Node::Cos(a) => {
                let sin = g.sin(a);
                let m = g.mul(bar, sin);
                let c = g.neg(m);
                push(g, a, c);
            }
            Node::Sqrt(a) => {
                let two = g.constant(2.0);
                let root = g.mul(two, id);
                let c = g.div(bar, root);
                push(g, a, c);
            }
        }
    }
    wrt.iter().map(|w| adjoint.get(w).copied().unwrap_or(zero)).collect()
}
