//! The arena of scalar nodes.
//!
//! Nodes are created only through the smart constructors below, which fold
//! constants, apply the 0/1 rules, keep signs outside (`(−a)·b → −(a·b)`,
//! `a + (−b) → a − b`), combine like terms (`c1·x + c2·x`), put commutative
//! operands in id order and hash-cons the result. A node's children always
//! have smaller ids than the node, so the arena is already in emission order,
//! and equal subexpressions are one node: common-subexpression sharing comes
//! for free, across Φ, J and γ alike, and `x − y` and `y − x` share one node
//! (one of them negated, which costs no operation).

use std::collections::HashMap;

/// Index of a node in the [`Graph`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Id(pub u32);

impl Id {
    /// The position in the arena.
    pub fn index(self) -> usize {
        self.0 as usize
    }
}

/// Index of an input variable.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct VarId(pub u32);

/// One scalar operation. Constants are stored by their bits so that nodes hash.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Node {
    /// A numeric constant (`f64::to_bits`, never `-0.0`).
    Const(u64),
    /// An input.
    Var(VarId),
    /// `a + b`, with `a < b`.
    Add(Id, Id),
    /// `a - b`, with `a < b` (the other order is a negated `Sub`).
    Sub(Id, Id),
    /// `a * b`, with `a <= b`; a constant factor comes first.
    Mul(Id, Id),
    /// `a / b`.
    Div(Id, Id),
    /// `-a`: free in the operation count.
    Neg(Id),
    /// `sin a`.
    Sin(Id),
    /// `cos a`.
    Cos(Id),
    /// `√a` (a soft weld's quaternion error: `w = ½ √(1 + tr E)`).
    Sqrt(Id),
}

/// What kind of input a variable is; the derivative rules and emission read it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Var {
    /// The name used in generated code.
    pub name: String,
    /// Its bits in the dependency mask (0 for parameters, which are constant in
    /// time and never differentiated).
    pub mask: u64,
}

/// The mask bit every velocity sets, exactly: J must not depend on it.
pub const VELOCITY: u64 = 1 << 63;

/// The arena.
#[derive(Default)]
pub struct Graph {
    nodes: Vec<Node>,
    /// Bitmask of the differentiable variables each node depends on.
    masks: Vec<u64>,
    lookup: HashMap<Node, Id>,
    vars: Vec<Var>,
    next_bit: u32,
    /// Readable names for intermediates (first hint wins).
    hints: HashMap<Id, String>,
}

impl Graph {
    /// An empty graph.
    pub fn new() -> Self {
        Self::default()
    }

    /// The node behind an id.
    pub fn node(&self, id: Id) -> Node {
        self.nodes[id.index()]
    }

    /// Number of nodes.
    pub fn len(&self) -> usize {
        self.nodes.len()
    }

    /// Gives a node a readable name for emission; the first name given wins, and
    /// variables and constants keep their own.
    pub fn hint(&mut self, id: Id, name: impl Into<String>) {
        if matches!(
            self.node(id),
            Node::Mul(..) | Node::Div(..) | Node::Add(..) | Node::Sub(..) | Node::Sin(_) | Node::Cos(_) | Node::Sqrt(_)
        ) {
            self.hints.entry(id).or_insert_with(|| name.into());
        }
    }

    /// Names `id` only if it was created at or after arena position `start`, so
    /// that code naming its results never renames a node some other code built
    /// (a doubled Euler parameter is not an axis's `w`).
    pub fn hint_new(&mut self, start: usize, id: Id, name: impl Into<String>) {
        if id.index() >= start {
            self.hint(id, name);
        }
    }

    /// The readable name of a node, if it has one.
    pub fn hint_of(&self, id: Id) -> Option<&str> {
        self.hints.get(&id).map(String::as_str)
    }

    /// The variables, by `VarId`.
    pub fn vars(&self) -> &[Var] {
        &self.vars
    }

    /// Dependency mask of a node: the union of its inputs' masks. Each
    /// differentiable input has one of 63 bits (its index modulo 63), so a clear
    /// bit proves independence while a set bit may be shared — enough to skip
    /// work in the gradient, with any number of inputs. Bit 63 ([`VELOCITY`]) is
    /// exact: set only by velocities.
    pub fn mask(&self, id: Id) -> u64 {
        self.masks[id.index()]
    }

    /// The mask of a variable (0 for a parameter).
    pub fn var_mask(&self, v: VarId) -> u64 {
        self.vars[v.0 as usize].mask
    }

    /// A parameter: an input that is constant in time (a joint's axes and points).
    pub fn param(&mut self, name: impl Into<String>) -> Id {
        self.new_var(name.into(), 0)
    }

    /// A differentiable input: a coordinate or a time-function value.
    pub fn state(&mut self, name: impl Into<String>) -> Id {
        let bit = 1u64 << (self.next_bit % 63);
        self.next_bit += 1;
        self.new_var(name.into(), bit)
    }

    /// A velocity: differentiable, and marked so that J can be checked free of it.
    pub fn velocity(&mut self, name: impl Into<String>) -> Id {
        let bit = 1u64 << (self.next_bit % 63);
        self.next_bit += 1;
        self.new_var(name.into(), bit | VELOCITY)
    }

    fn new_var(&mut self, name: String, mask: u64) -> Id {
        let v = VarId(self.vars.len() as u32);
        self.vars.push(Var { name, mask });
        self.intern(Node::Var(v))
    }

    /// The variable behind a `Var` node.
    pub fn as_var(&self, id: Id) -> Option<VarId> {
        match self.node(id) {
            Node::Var(v) => Some(v),
            _ => None,
        }
    }

    /// The value of a constant node.
    pub fn as_const(&self, id: Id) -> Option<f64> {
        match self.node(id) {
            Node::Const(bits) => Some(f64::from_bits(bits)),
            _ => None,
        }
    }

    fn is_const(&self, id: Id, value: f64) -> bool {
        self.as_const(id) == Some(value)
    }

    fn intern(&mut self, node: Node) -> Id {
        if let Some(&id) = self.lookup.get(&node) {
            return id;
        }
        let mask = match node {
            Node::Const(_) => 0,
            Node::Var(v) => self.var_mask(v),
            Node::Add(a, b) | Node::Sub(a, b) | Node::Mul(a, b) | Node::Div(a, b) => self.mask(a) | self.mask(b),
            Node::Neg(a) | Node::Sin(a) | Node::Cos(a) | Node::Sqrt(a) => self.mask(a),
        };
        let id = Id(self.nodes.len() as u32);
        self.nodes.push(node);
        self.masks.push(mask);
        self.lookup.insert(node, id);
        id
    }

    /// A constant (`-0.0` is stored as `0.0`).
    pub fn constant(&mut self, value: f64) -> Id {
        let value = if value == 0.0 { 0.0 } else { value };
        self.intern(Node::Const(value.to_bits()))
    }

    /// `0`.
    pub fn zero(&mut self) -> Id {
        self.constant(0.0)
    }

    /// `-a`.
    pub fn neg(&mut self, a: Id) -> Id {
        match self.node(a) {
            Node::Const(_) => {
                let v = self.as_const(a).unwrap_or_default();
                self.constant(-v)
            }
            Node::Neg(x) => x,
            // -(x - y) = y - x: canonical order makes this a negated Sub again,
            // so the sign stays outside where it is free.
            _ => self.intern(Node::Neg(a)),
        }
    }

    /// Splits a node into a sign and a magnitude: `-x` gives `(true, x)`.
    fn unsign(&self, a: Id) -> (bool, Id) {
        match self.node(a) {
            Node::Neg(x) => (true, x),
            _ => (false, a),
        }
    }

    /// Splits `c * x` into `(c, x)`, anything else into `(1, x)`.
    fn coefficient(&self, a: Id) -> (f64, Id) {
        match self.node(a) {
            Node::Mul(c, x) => match self.as_const(c) {
                Some(c) => (c, x),
                None => (1.0, a),
            },
            Node::Neg(x) => {
                let (c, y) = self.coefficient(x);
                (-c, y)
            }
            _ => (1.0, a),
        }
    }

    /// `a + b`.
    pub fn add(&mut self, a: Id, b: Id) -> Id {
        if let (Some(x), Some(y)) = (self.as_const(a), self.as_const(b)) {
            return self.constant(x + y);
        }
        if self.is_const(a, 0.0) {
            return b;
        }
        if self.is_const(b, 0.0) {
            return a;
        }
        let (sa, ma) = self.unsign(a);
        let (sb, mb) = self.unsign(b);
        // Like terms: c1·x + c2·x = (c1 + c2)·x (and x + x = 2x).
        let (ca, xa) = self.coefficient(a);
        let (cb, xb) = self.coefficient(b);
        if xa == xb && self.as_const(xa).is_none() {
            let c = self.constant(ca + cb);
            return self.mul(c, xa);
        }
        match (sa, sb) {
            (false, false) => {
                let (lo, hi) = if ma <= mb { (ma, mb) } else { (mb, ma) };
                self.intern(Node::Add(lo, hi))
            }
            (false, true) => self.sub(ma, mb),
            (true, false) => self.sub(mb, ma),
            (true, true) => {
                let s = self.add(ma, mb);
                self.neg(s)
            }
        }
    }

    /// `a - b`.
    pub fn sub(&mut self, a: Id, b: Id) -> Id {
        if let (Some(x), Some(y)) = (self.as_const(a), self.as_const(b)) {
            return self.constant(x - y);
        }
        if self.is_const(b, 0.0) {
            return a;
        }
        if self.is_const(a, 0.0) {
            return self.neg(b);
        }
        if a == b {
            return self.zero();
        }
        let (sa, ma) = self.unsign(a);
        let (sb, mb) = self.unsign(b);
        let (ca, xa) = self.coefficient(a);
        let (cb, xb) = self.coefficient(b);
        if xa == xb && self.as_const(xa).is_none() {
            let c = self.constant(ca - cb);
            return self.mul(c, xa);
        }
        match (sa, sb) {
            (false, true) => self.add(ma, mb),
            (true, false) => {
                let s = self.add(ma, mb);
                self.neg(s)
            }
            (true, true) => self.sub(mb, ma),
            (false, false) => {
                if ma < mb {
                    self.intern(Node::Sub(ma, mb))
                } else {
                    let s = self.intern(Node::Sub(mb, ma));
                    self.neg(s)
                }
            }
        }
    }

    /// `a * b`.
    pub fn mul(&mut self, a: Id, b: Id) -> Id {
        if let (Some(x), Some(y)) = (self.as_const(a), self.as_const(b)) {
            return self.constant(x * y);
        }
        // Constant first, then the rules for 0, 1 and -1. The zero rule is what
        // makes an entry whose scale is 0 an exact zero for every input.
        let (a, b) = if self.as_const(b).is_some() { (b, a) } else { (a, b) };
        if let Some(c) = self.as_const(a) {
            if c == 0.0 {
                return self.zero();
            }
            if c == 1.0 {
                return b;
            }
            if c == -1.0 {
                return self.neg(b);
            }
            let (sb, mb) = self.unsign(b);
            if sb {
                return self.mul_signed(-c, mb);
            }
            // c1·(c2·x) = (c1c2)·x
            if let Node::Mul(c2, x) = self.node(b)
                && let Some(c2) = self.as_const(c2)
            {
                let k = self.constant(c * c2);
                return self.mul(k, x);
            }
            if c < 0.0 {
                let k = self.constant(-c);
                let m = self.intern(Node::Mul(k, b));
                return self.neg(m);
            }
            return self.intern(Node::Mul(a, b));
        }
        // Constant factors stay where they are: (2x)·y is one multiplication when
        // 2x is shared, which is how the rotation matrix is built.
        let (sa, ma) = self.unsign(a);
        let (sb, mb) = self.unsign(b);
        let (lo, hi) = if ma <= mb { (ma, mb) } else { (mb, ma) };
        let m = self.intern(Node::Mul(lo, hi));
        if sa != sb { self.neg(m) } else { m }
    }

    fn mul_signed(&mut self, c: f64, x: Id) -> Id {
        let k = self.constant(c);
        self.mul(k, x)
    }

    /// `a / b` (only `b = 1` and constant operands are simplified: a division is
    /// never turned into a multiplication by a rounded reciprocal).
    pub fn div(&mut self, a: Id, b: Id) -> Id {
        if let (Some(x), Some(y)) = (self.as_const(a), self.as_const(b)) {
            return self.constant(x / y);
        }
        if self.is_const(b, 1.0) {
            return a;
        }
        if self.is_const(a, 0.0) {
            return a;
        }
        let (sa, ma) = self.unsign(a);
        let (sb, mb) = self.unsign(b);
        let q = self.intern(Node::Div(ma, mb));
        if sa != sb { self.neg(q) } else { q }
    }

    /// `sin a`.
    pub fn sin(&mut self, a: Id) -> Id {
        match self.as_const(a) {
            Some(x) => self.constant(x.sin()),
            None => self.intern(Node::Sin(a)),
        }
    }

    /// `cos a`.
    pub fn cos(&mut self, a: Id) -> Id {
        match self.as_const(a) {
            Some(x) => self.constant(x.cos()),
            None => self.intern(Node::Cos(a)),
        }
    }

    /// `√a`.
    pub fn sqrt(&mut self, a: Id) -> Id {
        match self.as_const(a) {
            Some(x) => self.constant(x.sqrt()),
            None => self.intern(Node::Sqrt(a)),
        }
    }

    /// `id` with the variables of `map` replaced by their nodes, rebuilt through
    /// the smart constructors (`memo` carries work between calls). How a rule
    /// stated along the velocities becomes the same rule along another direction.
    pub fn substitute(&mut self, id: Id, map: &HashMap<VarId, Id>, memo: &mut HashMap<Id, Id>) -> Id {
        if let Some(&done) = memo.get(&id) {
            return done;
        }
        let out = match self.node(id) {
            Node::Const(_) => id,
            Node::Var(v) => map.get(&v).copied().unwrap_or(id),
            Node::Add(a, b) | Node::Sub(a, b) | Node::Mul(a, b) | Node::Div(a, b) => {
                let (x, y) = (self.substitute(a, map, memo), self.substitute(b, map, memo));
                match self.node(id) {
                    Node::Add(..) => self.add(x, y),
                    Node::Sub(..) => self.sub(x, y),
                    Node::Mul(..) => self.mul(x, y),
                    _ => self.div(x, y),
                }
            }
            Node::Neg(a) | Node::Sin(a) | Node::Cos(a) | Node::Sqrt(a) => {
                let x = self.substitute(a, map, memo);
                match self.node(id) {
                    Node::Neg(_) => self.neg(x),
                    Node::Sin(_) => self.sin(x),
                    Node::Sqrt(_) => self.sqrt(x),
                    _ => self.cos(x),
                }
            }
        };
        memo.insert(id, out);
        out
    }

    /// `Σ terms` (0 for none), summed left to right.
    pub fn sum(&mut self, terms: &[Id]) -> Id {
        let mut acc = self.zero();
        for &t in terms {
            acc = self.add(acc, t);
        }
        acc
    }

    #[cfg(test)]
    /// Evaluates a node at given variable values (for tests and for checking
    /// constant geometry at compile time).
    pub fn eval(&self, id: Id, vars: &dyn Fn(VarId) -> f64) -> f64 {
        let mut values = vec![0.0; id.index() + 1];
        for i in 0..=id.index() {
            values[i] = match self.nodes[i] {
                Node::Const(bits) => f64::from_bits(bits),
                Node::Var(v) => vars(v),
                Node::Add(a, b) => values[a.index()] + values[b.index()],
                Node::Sub(a, b) => values[a.index()] - values[b.index()],
                Node::Mul(a, b) => values[a.index()] * values[b.index()],
                Node::Div(a, b) => values[a.index()] / values[b.index()],
                Node::Neg(a) => -values[a.index()],
                Node::Sin(a) => values[a.index()].sin(),
                Node::Cos(a) => values[a.index()].cos(),
                Node::Sqrt(a) => values[a.index()].sqrt(),
            };
        }
        values[id.index()]
    }
}
