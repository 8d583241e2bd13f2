//! Formulations: which inputs exist, how each body's frame moves, and the
//! kinematic rules for the time derivative (`CONVENTIONS.md`, "Formulations").
//!
//! Every formulation is reduced to the same picture: two frames with rotation
//! matrices `A1`, `A2` and origins `r1`, `r2` in a reference frame, plus rules that
//! say how they move. The ω formulations register `d/dt (A a') = ω × (A a')` with
//! inertial ω for every rotated vector; in `omega_body` that ω is the node
//! `A ω'` (constant when ω̇' = 0, since ω̇ = A ω̇'), so both J and γ come out in
//! vector form and J's columns are `Aᵀ (…)`. The relative formulations are the
//! same picture with B1 as the reference frame (`A1 = I`) and `d = δ`.
//!
//! In `omega_body` each rotated vector also gets the body-frame rule
//! `d/dt (A a') = A (ω' × a')` (`body_rules`, laid over the inertial ones), and
//! J is taken under it: entries `a' × (Aᵀ g)`, of the degree in `p` the exact
//! entries have, where the inertial form `Aᵀ (A a' × g)`, which multiplies `A`
//! by `A a'`, lost up to 3.4 ε·scale on the conformance vectors (the
//! body-frame form: 1.65 at worst).
//! γ comes out either way; lowering keeps the cheaper set for the fused
//! evaluation. `euler` has an exact rule for `A(p) a'` at any `p`, and the
//! dot-1 and dot-2 primitives have identities of their own (a same-body
//! product never formed; a dot-1 row in B2 components where that is cheaper).
//!
//! A scene is one `Kinematics` with a frame per body (`Kinematics::scene`,
//! each joint lowered onto its pair of frames after `connect`), so a body's
//! rotation matrix is built once for all its joints. A relative-coordinate
//! tree's frames are expressions of its joint coordinates (`Kinematics::tree`),
//! so its closures' rows are differentiated through them.

use crate::engine::{Graph, Id, TimeRules, grad};

const XYZ: [&str; 3] = ["x", "y", "z"];

/// Three nodes: a vector's components.
pub type V3 = [Id; 3];

/// The five formulations.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Formulation {
    /// `r, p; ṙ, ṗ`.
    Euler,
    /// `r, p; ṙ, ω` (inertial ω).
    OmegaInertial,
    /// `r, p; ṙ, ω'` (body ω').
    OmegaBody,
    /// `δ, p_rel; δ̇, ω_rel` (B1 components).
    RelativeB1,
    /// `δ, p_rel; δ̇, ω_rel` (B2 components).
    RelativeB2,
}

impl Formulation {
    /// All five, in the order of `CONVENTIONS.md`.
    pub const ALL: [Formulation; 5] = [
        Formulation::Euler,
        Formulation::OmegaInertial,
        Formulation::OmegaBody,
        Formulation::RelativeB1,
        Formulation::RelativeB2,
    ];

    /// The DSL name.
    pub fn name(self) -> &'static str {
        match self {
            Formulation::Euler => "euler",
            Formulation::OmegaInertial => "omega_inertial",
            Formulation::OmegaBody => "omega_body",
            Formulation::RelativeB1 => "relative_b1",
            Formulation::RelativeB2 => "relative_b2",
        }
    }

    /// The runtime enum variant.
    pub fn variant(self) -> &'static str {
        match self {
            Formulation::Euler => "Euler",
            Formulation::OmegaInertial => "OmegaInertial",
            Formulation::OmegaBody => "OmegaBody",
            Formulation::RelativeB1 => "RelativeB1",
            Formulation::RelativeB2 => "RelativeB2",
        }
    }

    /// Whether the inputs are `δ, p_rel` rather than two bodies.
    pub fn is_relative(self) -> bool {
        matches!(self, Formulation::RelativeB1 | Formulation::RelativeB2)
    }
}

/// Which body, if any, is the inertial frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Ground {
    /// Both bodies move.
    None,
    /// Body 1 is the ground.
    Body1,
    /// Body 2 is the ground.
    Body2,
}

/// A state vector the generated code destructures: `state.<path>` holds `vars`.
pub struct Input {
    /// The argument read: `state`, or `lambda` and `u` for the second-order terms.
    pub root: &'static str,
    /// Field path below the root, e.g. `["body1", "r"]`; a number is an array index.
    pub path: Vec<String>,
    /// One variable node per component.
    pub vars: Vec<Id>,
}

struct Frame {
    /// Rotation matrix entries `a[row][col]`.
    a: [[Id; 3]; 3],
    /// Origin.
    r: V3,
    /// Inertial angular velocity, when the ω rule applies to this frame.
    omega: Option<V3>,
    /// `p`, `ṗ` and `A(ṗ)`, when the Euler-parameter rule applies.
    euler: Option<EulerRates>,
    /// The angular velocity in the frame's own components, when it is an input
    /// (`omega_body`, `relative_b2`).
    body_rate: Option<V3>,
}

#[derive(Clone, Copy)]
struct EulerRates {
    p: [Id; 4],
    pdot: [Id; 4],
    a_of_pdot: [[Id; 3]; 3],
}

/// The inputs and motion rules of one formulation, over a [`Graph`].
pub struct Kinematics {
    /// The graph every expression lives in.
    pub g: Graph,
    /// Rules for Φ̇ and γ: coordinates move, velocities are held (v̇ = 0), and a
    /// time function's rate moves with its acceleration.
    pub rules: TimeRules,
    /// Rules for Φ_t: only explicit time moves.
    pub time_rules: TimeRules,
    /// `omega_body`: each rotated vector's body-frame rule `u̇ = A (ω' × a')`
    /// (and its second derivative), overriding the inertial `u̇ = ω × u` of
    /// [`rules`](Self::rules) when J is derived (see [`Kinematics::derive_row`]).
    pub body_rules: TimeRules,
    /// Coordinates in column order (`euler`: J = ∂Φ/∂q).
    pub coords: Vec<Id>,
    /// Velocities in column order.
    pub velocities: Vec<Id>,
    /// State vectors to bind, in order.
    pub inputs: Vec<Input>,
    /// Whether [`Kinematics::dot1`] may take dot-1 rows in B2 components
    /// (`relative_b2`); the derive tries both and keeps the cheaper.
    pub dot1_in_b2: bool,
    /// Whether rotated vectors also get [`body_rules`](Self::body_rules)
    /// (`omega_body`, whose velocities are `ω'` in body components).
    body_frame_rules: bool,
    /// Frame 0 is the ground (identity); bodies follow.
    frames: Vec<Frame>,
    /// Each rotating frame of the ω formulations: its Euler parameters, its
    /// angular-velocity variables and whether they are in the frame's own
    /// components (for the direction rules of [`Kinematics::direction_rules`]).
    spins: Vec<([Id; 4], V3, bool)>,
    /// The frames of the current joint's body 1 and body 2.
    pair: [usize; 2],
    delta: Option<V3>,
}

impl Kinematics {
    /// Sets up the inputs and rules of `formulation` with `ground`.
    pub fn new(formulation: Formulation, ground: Ground) -> Self {
        let mut k = Kinematics::empty();
        k.body_frame_rules = formulation == Formulation::OmegaBody;
        if formulation.is_relative() {
            let delta = k.vector("delta", vec!["delta".into()]);
            let p = k.vector4("p", vec!["p".into()], false);
            let delta_dot = k.velocity3("delta_dot", vec!["delta_dot".into()]);
            let w = k.velocity3("w", vec!["omega".into()]);
            for j in 0..3 {
                k.rules.set_var(&k.g, delta[j], delta_dot[j]);
            }
            k.coords.extend(delta);
            k.coords.extend(p);
            k.velocities.extend(delta_dot);
            k.velocities.extend(w);
            let a = rotation_matrix(&mut k.g, p, "a");
            let body = formulation == Formulation::RelativeB2;
            let omega = k.angular_velocity(&a, w, body, "omega_rel");
            k.spins.push((p, w, body));
            let r = k.zero3();
            k.frames.push(Frame { a, r, omega: Some(omega), euler: None, body_rate: body.then_some(w) });
            k.pair = [0, 1];
            k.register_columns(1);
            k.delta = Some(delta);
            return k;
        }
        for body in 0..2 {
            let grounded = matches!((ground, body), (Ground::Body1, 0) | (Ground::Body2, 1));
            if grounded {
                continue;
            }
            let field = match (ground, body) {
                (Ground::None, 0) => "body1",
                (Ground::None, _) => "body2",
                _ => "body",
            };
            k.pair[body] = k.add_body(&format!("{}", body + 1), vec![field.to_string()], formulation);
        }
        k
    }

    /// The inputs and rules of a mechanism of `bodies` (names used in generated
    /// code); the state's bodies are `state.bodies[i]`. Joints are then lowered
    /// one after the other with [`Kinematics::connect`].
    pub fn scene(formulation: Formulation, bodies: &[String]) -> Self {
        let mut k = Kinematics::empty();
        k.body_frame_rules = formulation == Formulation::OmegaBody;
        for (i, name) in bodies.iter().enumerate() {
            k.add_body(&format!("_{name}"), vec!["bodies".into(), i.to_string()], formulation);
        }
        k
    }

    /// The inputs of a relative-coordinate tree: `state.q` and `state.v` of
    /// its `TreeState`, in tree order. The caller states how each coordinate
    /// moves ([`Kinematics::rate`], [`Kinematics::spin`]) and adds every
    /// body's frame as the tree's kinematics makes it ([`Kinematics::frame`]),
    /// in body order; time derivatives then go through the frames' expressions.
    pub fn tree(nq: usize, nv: usize) -> Self {
        let mut k = Kinematics::empty();
        let q: Vec<Id> = (0..nq).map(|i| k.g.state(format!("q_{i}"))).collect();
        let v: Vec<Id> = (0..nv).map(|i| k.g.velocity(format!("v_{i}"))).collect();
        k.inputs.push(Input { root: "state", path: vec!["q".into()], vars: q.clone() });
        k.inputs.push(Input { root: "state", path: vec!["v".into()], vars: v.clone() });
        k.coords = q;
        k.velocities = v;
        k
    }

    /// `θ̇ = v` for a coordinate whose rate is a velocity (a revolute angle).
    pub fn rate(&mut self, coordinate: Id, velocity: Id) {
        self.rules.set_var(&self.g, coordinate, velocity);
    }

    /// `ṗ = ½ p ⊗ (0, ω')` for Euler parameters turned by `ω'` in the moving
    /// frame's own components (a spherical joint's relative rotation).
    pub fn spin(&mut self, p: [Id; 4], w: V3) {
        let zero = self.g.zero();
        let product = quat_mul(&mut self.g, p, [zero, w[0], w[1], w[2]]);
        let half = self.g.constant(0.5);
        for (e, x) in p.iter().zip(product) {
            let rate = self.g.mul(half, x);
            self.rules.set_var(&self.g, *e, rate);
        }
    }

    /// Adds a body's frame (rotation matrix and origin as expressions of the
    /// inputs): the next body of [`Kinematics::connect`].
    pub fn frame(&mut self, a: [[Id; 3]; 3], r: V3) {
        self.frames.push(Frame { a, r, omega: None, euler: None, body_rate: None });
    }

    /// Body `body`'s frame (the scene's bodies in order; the ground is not
    /// one): its rotation's entries and its centre.
    pub fn pose(&self, body: usize) -> ([[Id; 3]; 3], V3) {
        let f = &self.frames[body + 1];
        (f.a, f.r)
    }

    /// The ground frame alone: no inputs, no rules.
    fn empty() -> Self {
        let mut g = Graph::new();
        let identity = identity_frame(&mut g);
        Kinematics {
            g,
            rules: TimeRules::new(),
            time_rules: TimeRules::new(),
            body_rules: TimeRules::new(),
            coords: Vec::new(),
            velocities: Vec::new(),
            inputs: Vec::new(),
            frames: vec![identity],
            spins: Vec::new(),
            pair: [0, 0],
            delta: None,
            dot1_in_b2: true,
            body_frame_rules: false,
        }
    }

    /// Makes the next joint connect `body1` and `body2` (`None`: the ground).
    pub fn connect(&mut self, body1: Option<usize>, body2: Option<usize>) {
        self.pair = [body1.map_or(0, |b| b + 1), body2.map_or(0, |b| b + 1)];
    }

    /// Adds a moving body with its coordinates, velocities and rules; returns its frame.
    fn add_body(&mut self, n: &str, path: Vec<String>, formulation: Formulation) -> usize {
        let k = self;
        let at = |leaf: &str| {
            let mut p = path.clone();
            p.push(leaf.to_string());
            p
        };
        let r = k.vector(&format!("r{n}"), at("r"));
        let p = k.vector4(&format!("p{n}"), at("p"), false);
        let rdot = k.velocity3(&format!("rdot{n}"), at("rdot"));
        for j in 0..3 {
            k.rules.set_var(&k.g, r[j], rdot[j]);
        }
        k.coords.extend(r);
        k.coords.extend(p);
        k.velocities.extend(rdot);
        let a = rotation_matrix(&mut k.g, p, &format!("a{n}"));
        let mut w_body = k.zero3();
        let (omega, euler) = if formulation == Formulation::Euler {
            let pdot = k.vector4(&format!("pdot{n}"), at("pdot"), true);
            for j in 0..4 {
                k.rules.set_var(&k.g, p[j], pdot[j]);
            }
            k.velocities.extend(pdot);
            let a_of_pdot = rotation_matrix(&mut k.g, pdot, &format!("a{n}_pdot"));
            (None, Some(EulerRates { p, pdot, a_of_pdot }))
        } else {
            let w = k.velocity3(&format!("w{n}"), at("omega"));
            k.velocities.extend(w);
            w_body = w;
            k.spins.push((p, w, formulation == Formulation::OmegaBody));
            (Some(k.angular_velocity(&a, w, formulation == Formulation::OmegaBody, &format!("omega{n}"))), None)
        };
        let body_rate = (formulation == Formulation::OmegaBody).then_some(w_body);
        k.frames.push(Frame { a, r, omega, euler, body_rate });
        let index = k.frames.len() - 1;
        k.register_columns(index);
        index
    }

    fn zero3(&mut self) -> V3 {
        let z = self.g.zero();
        [z; 3]
    }

    /// Declares a 3-vector input read from `state.<path>` (rules are set by the caller).
    fn vector(&mut self, name: &str, path: Vec<String>) -> V3 {
        let vars = ["x", "y", "z"].map(|c| self.g.state(format!("{name}_{c}")));
        self.inputs.push(Input { root: "state", path, vars: vars.to_vec() });
        vars
    }

    /// Declares a 3-vector velocity input read from `state.<path>`.
    fn velocity3(&mut self, name: &str, path: Vec<String>) -> V3 {
        let vars = ["x", "y", "z"].map(|c| self.g.velocity(format!("{name}_{c}")));
        self.inputs.push(Input { root: "state", path, vars: vars.to_vec() });
        vars
    }

    fn vector4(&mut self, name: &str, path: Vec<String>, velocity: bool) -> [Id; 4] {
        let vars = [0, 1, 2, 3].map(|c| {
            let n = format!("{name}_{c}");
            if velocity { self.g.velocity(n) } else { self.g.state(n) }
        });
        self.inputs.push(Input { root: "state", path, vars: vars.to_vec() });
        vars
    }

    /// Inertial ω of a frame: the variables themselves, or `A ω'` held constant
    /// (ω̇ = A ω̇' = 0 when ω̇' = 0).
    fn angular_velocity(&mut self, a: &[[Id; 3]; 3], w: V3, body_components: bool, name: &str) -> V3 {
        if !body_components {
            return w;
        }
        let start = self.g.len();
        let omega = mat_vec(&mut self.g, a, w);
        let zero = self.g.zero();
        for (j, &o) in omega.iter().enumerate() {
            self.g.hint_new(start, o, format!("{name}_{}", XYZ[j]));
            self.rules.set_node(&self.g, o, zero);
        }
        omega
    }

    /// `d/dt A[:, k] = ω × A[:, k]` for every column of a moving frame.
    fn register_columns(&mut self, body: usize) {
        let Some(omega) = self.frames[body].omega else { return };
        for col in 0..3 {
            let c = [0, 1, 2].map(|row| self.frames[body].a[row][col]);
            let dc = cross(&mut self.g, omega, c);
            for j in 0..3 {
                self.rules.set_node(&self.g, c[j], dc[j]);
            }
        }
    }

    /// `A_body a'`: a vector fixed in `body` (0 or 1) in reference components.
    pub fn rotate(&mut self, body: usize, a: V3, hint: &str) -> V3 {
        let frame = self.pair[body];
        let m = self.frames[frame].a;
        let start = self.g.len();
        let u = mat_vec(&mut self.g, &m, a);
        for (j, &c) in u.iter().enumerate() {
            self.g.hint_new(start, c, format!("{hint}_{}", XYZ[j]));
        }
        if let Some(omega) = self.frames[frame].omega {
            let du = cross(&mut self.g, omega, u);
            for j in 0..3 {
                self.rules.set_node(&self.g, u[j], du[j]);
            }
        }
        if let Some(rates) = self.frames[frame].euler {
            self.euler_rule(rates, a, u, hint);
        }
        if self.body_frame_rules {
            self.body_rule(frame, a, u, 2);
        }
        u
    }

    /// With ω' in the frame's own components: `u = A a'` moves as `u̇ = A (ω' × a')`
    /// (and, ω̇' held at zero, `ü = A (ω' × (ω' × a'))`, for `depth` 2). The
    /// Jacobian then comes out as `a' × (Aᵀ g)`: products of `A`'s entries with
    /// the body-fixed vector, of the degree in `p` the exact entries have, where
    /// `ω × u` with `ω = A ω'` multiplies `A` by `A a'` and loses digits.
    fn body_rule(&mut self, frame: usize, a: V3, u: V3, depth: usize) {
        let (Some(w), m) = (self.frames[frame].body_rate, self.frames[frame].a) else { return };
        let b = cross(&mut self.g, w, a);
        let du = mat_vec(&mut self.g, &m, b);
        for j in 0..3 {
            self.body_rules.set_node(&self.g, u[j], du[j]);
        }
        if depth > 1 {
            self.body_rule(frame, b, du, depth - 1);
        }
    }

    /// The Euler-parameter rule for `u = A(p) a'`, exact for any `p` (unit or not):
    /// `∂u/∂p = [w, s I − w̃]` with `w = 2 (e0 a' + e × a')` and `s = 2 e·a'`, so
    /// `u̇ = w ė0 + s ė + ė × w`; and along `p + t ṗ`, `ü = 2 A(ṗ) a'` (A is quadratic).
    /// The structural derivative of the quadratic `A(p)` gives the same numbers with
    /// about half again as many operations.
    fn euler_rule(&mut self, rates: EulerRates, a: V3, u: V3, hint: &str) {
        let g = &mut self.g;
        let start = g.len();
        let two = g.constant(2.0);
        let a2 = a.map(|x| g.mul(two, x));
        let [e0, e1, e2, e3] = rates.p;
        let e = [e1, e2, e3];
        let c = cross(g, e, a2);
        let w = [0, 1, 2].map(|j| {
            let m = g.mul(e0, a2[j]);
            g.add(m, c[j])
        });
        let s = dot(g, e, a2);
        for (j, &x) in w.iter().enumerate() {
            g.hint_new(start, x, format!("{hint}_w{}", XYZ[j]));
        }
        g.hint_new(start, s, format!("{hint}_s"));
        let [d0, d1, d2, d3] = rates.pdot;
        let ed = [d1, d2, d3];
        let ew = cross(g, ed, w);
        let udot = [0, 1, 2].map(|j| {
            let l = g.mul(w[j], d0);
            let m = g.mul(s, ed[j]);
            let lm = g.add(l, m);
            g.add(lm, ew[j])
        });
        let second = mat_vec(g, &rates.a_of_pdot, a2);
        for j in 0..3 {
            self.rules.set_node(&self.g, u[j], udot[j]);
            self.rules.set_node(&self.g, udot[j], second[j]);
        }
    }

    /// A time function's value node; its rate and acceleration follow it in the
    /// returned triple. Φ̇ and γ see `θ̇ = rate`, `θ̈ = accel`; so does Φ_t.
    pub fn time_function(&mut self, name: &str) -> [Id; 3] {
        let value = self.g.state(name.to_string());
        let rate = self.g.state(format!("{name}_rate"));
        let accel = self.g.state(format!("{name}_accel"));
        for rules in [&mut self.rules, &mut self.time_rules] {
            rules.set_var(&self.g, value, rate);
            rules.set_var(&self.g, rate, accel);
        }
        [value, rate, accel]
    }

    /// The position of a point `q'` fixed in `body`: `r + A q'` (absolute), or,
    /// in a relative formulation, measured from the joint point `ρ1'` of B1 in B1
    /// components: `q' − ρ1'` on B1 and `δ + A_rel (q' − ρ2')` on B2.
    pub fn point(&mut self, body: usize, q: V3, rho: [V3; 2], hint: &str) -> V3 {
        if let Some(delta) = self.delta {
            let local = [0, 1, 2].map(|j| self.g.sub(q[j], rho[body][j]));
            if body == 0 {
                return local;
            }
            let u = self.rotate(1, local, hint);
            return [0, 1, 2].map(|j| self.g.add(delta[j], u[j]));
        }
        let u = self.rotate(body, q, hint);
        let r = self.frames[self.pair[body]].r;
        [0, 1, 2].map(|j| self.g.add(r[j], u[j]))
    }

    /// The dot-1 primitive `a'ᵀ A1ᵀ A2 b'` of a vector of body 1 and one of body 2.
    ///
    /// When body 1 is the reference frame (relative formulations) and body 2's
    /// angular velocity is given in its own components (`relative_b2`), the
    /// product is taken in B2 components, `(A_relᵀ a')·b'`, with
    /// `d/dt (A_relᵀ a') = −ω' × (A_relᵀ a')`: no conversion of ω' into B1 and
    /// none of J's columns back. Cheaper for a lone dot-1 row (universal: 78
    /// operations instead of 108), dearer when one B2 axis meets several B1
    /// axes, so the derive tries both (see [`Kinematics::dot1_in_b2`]).
    pub fn dot1(&mut self, a: V3, b: V3, hints: [&str; 2]) -> Id {
        let (f1, f2) = (self.pair[0], self.pair[1]);
        let reference = self.frames[f1].omega.is_none() && self.frames[f1].euler.is_none();
        if let (true, Some(w)) = (reference && self.delta.is_some() && self.dot1_in_b2, self.frames[f2].body_rate) {
            let m = self.frames[f2].a;
            let transposed = [0, 1, 2].map(|i| [0, 1, 2].map(|j| m[j][i]));
            let start = self.g.len();
            let u = mat_vec(&mut self.g, &transposed, a);
            for (j, &c) in u.iter().enumerate() {
                self.g.hint_new(start, c, format!("{}_b2_{}", hints[0], XYZ[j]));
            }
            let du = cross(&mut self.g, u, w);
            for j in 0..3 {
                self.rules.set_node(&self.g, u[j], du[j]);
            }
            return dot(&mut self.g, u, b);
        }
        let u = self.rotate(0, a, hints[0]);
        let v = self.rotate(1, b, hints[1]);
        dot(&mut self.g, u, v)
    }

    /// The dot-2 primitive `a'ᵀ A1ᵀ d` of a vector `a'` fixed in body 1.
    ///
    /// In the absolute formulations `d` holds `−A1 ρ1'`, and `(A1 a')·(A1 ρ1')` is
    /// a product within one body: `a'·ρ1'` for a rotation (ω formulations, the
    /// ground), exactly `|p|⁴ a'·ρ1'` for the homogeneous `A(p)` of `euler`. So
    /// the row is `(A1 a')·(r2 − r1 + A2 ρ2') − (that)`: `A1 ρ1'` is never formed
    /// and the row's Jacobian and γ lose its terms.
    pub fn dot2(&mut self, a: V3, rho1: V3, rho2: V3, hint: &str) -> Id {
        let u = self.rotate(0, a, hint);
        if self.delta.is_some() {
            let d = self.separation(rho1, rho2);
            return dot(&mut self.g, u, d);
        }
        let local = dot(&mut self.g, a, rho1);
        let same_body = match self.frames[self.pair[0]].euler {
            Some(rates) => {
                let sq = rates.p.map(|e| self.g.mul(e, e));
                let norm2 = self.g.sum(&sq);
                let norm4 = self.g.mul(norm2, norm2);
                self.g.mul(norm4, local)
            }
            None => local,
        };
        let w2 = self.rotate(1, rho2, "rho2_n");
        let (r1, r2) = (self.frames[self.pair[0]].r, self.frames[self.pair[1]].r);
        let rest = [0, 1, 2].map(|j| {
            let dr = self.g.sub(r2[j], r1[j]);
            self.g.add(dr, w2[j])
        });
        let along = dot(&mut self.g, u, rest);
        self.g.sub(along, same_body)
    }

    /// `d = r2 + A2 ρ2' − r1 − A1 ρ1'` (absolute) or `δ` (relative).
    pub fn separation(&mut self, rho1: V3, rho2: V3) -> V3 {
        if let Some(delta) = self.delta {
            return delta;
        }
        let w1 = self.rotate(0, rho1, "rho1_n");
        let w2 = self.rotate(1, rho2, "rho2_n");
        let (r1, r2) = (self.frames[self.pair[0]].r, self.frames[self.pair[1]].r);
        // (r2 − r1) + (w2 − w1): the large positions cancel first.
        let start = self.g.len();
        let d = [0, 1, 2].map(|j| {
            let dr = self.g.sub(r2[j], r1[j]);
            let dw = self.g.sub(w2[j], w1[j]);
            self.g.add(dr, dw)
        });
        for (j, &c) in d.iter().enumerate() {
            self.g.hint_new(start, c, format!("d_{}", XYZ[j]));
        }
        d
    }

    /// The rules J is derived with in `omega_body`: [`rules`](Self::rules) with
    /// the body-frame ones laid over them; `None` in the other formulations.
    /// Built once for all rows (and their memo shared), after every row is lowered.
    pub fn body_view(&self) -> Option<TimeRules> {
        self.body_frame_rules.then(|| self.rules.overridden(&self.body_rules))
    }

    /// `n` values read from the argument `root` of a generated method (an
    /// `SVector`): constants as far as every derivative is concerned.
    pub fn argument(&mut self, root: &'static str, n: usize) -> Vec<Id> {
        let vars: Vec<Id> = (0..n).map(|i| self.g.param(format!("{root}_{i}"))).collect();
        self.inputs.push(Input { root, path: Vec::new(), vars: vars.clone() });
        vars
    }

    /// Derivatives along a direction `δ` of the coordinates, laid out as the
    /// velocities (`δṙ`, `δω` or `δṗ`, ...): a new variable per velocity column,
    /// and rules under which `dt` is the directional derivative on the rotation
    /// group with the velocities and time held. In the ω formulations `δθ`
    /// rotates a frame as its angular velocity does: `p ⊕ δθ = p ⊗ q(δθ)` for
    /// body components, `q(δθ) ⊗ p` for inertial ones (`CONVENTIONS.md`,
    /// "Second-order terms"). Call after every row is lowered.
    pub fn direction_rules(&mut self) -> (Vec<Id>, TimeRules) {
        let directions: Vec<Id> = (0..self.velocities.len()).map(|c| self.g.state(format!("dir_{c}"))).collect();
        let map = self.velocities.iter().zip(&directions).filter_map(|(&v, &d)| Some((self.g.as_var(v)?, d))).collect();
        let base = self.body_view().unwrap_or_else(|| self.rules.clone());
        let mut rules = base.along(&mut self.g, &self.coords, &map);
        for (p, w, body) in self.spins.clone() {
            let d = w.map(|x| self.g.as_var(x).and_then(|v| map.get(&v).copied()).unwrap_or(x));
            let half = self.g.constant(0.5);
            let spin = [self.g.zero(), d[0], d[1], d[2]];
            let product = if body { quat_mul(&mut self.g, p, spin) } else { quat_mul(&mut self.g, spin, p) };
            for (e, x) in p.iter().zip(product) {
                let rate = self.g.mul(half, x);
                rules.set_var(&self.g, *e, rate);
            }
        }
        (directions, rules)
    }

    /// Φ̇, J and γ of one row Φ, and Φ_t, with `body` from
    /// [`body_view`](Self::body_view). Fails when J would depend on the
    /// velocities (the row is not linear in them).
    pub fn derive_row(&mut self, phi: Id, body: Option<&mut TimeRules>) -> Result<RowDerivatives, &'static str> {
        // In `omega_body`, J comes from the body-frame rules: `a' × (Aᵀ g)` keeps
        // the degree in `p` of the exact entries, where the inertial rule's
        // `Aᵀ (u × g)` multiplies `A` by `A a'` and loses up to 3 ε·scale.
        let mut body = body;
        let phi_dot = self.rules.dt(&mut self.g, phi);
        let phi_dot_body = match &mut body {
            Some(rules) => rules.dt(&mut self.g, phi),
            None => phi_dot,
        };
        // J is the coefficient of the velocities in Φ̇ (in `euler` that is ∂Φ/∂q).
        let velocities = self.velocities.clone();
        let jacobian = grad(&mut self.g, phi_dot_body, &velocities);
        if jacobian.iter().any(|&j| self.g.mask(j) & crate::engine::graph::VELOCITY != 0) {
            return Err("the derivative of this row is not linear in the velocities");
        }
        // γ both ways where there are two: the caller keeps the one that costs
        // the fused evaluation less (the body form for a point's row, the
        // inertial one where one ω serves several axes).
        let phi_ddot = self.rules.dt(&mut self.g, phi_dot);
        let gamma = self.g.neg(phi_ddot);
        let gamma_body = body.map(|rules| {
            let phi_ddot = rules.dt(&mut self.g, phi_dot_body);
            self.g.neg(phi_ddot)
        });
        let phi_t = self.time_rules.dt(&mut self.g, phi);
        Ok(RowDerivatives { jacobian, gamma, gamma_body, phi_t })
    }
}

/// What [`Kinematics::derive_row`] gives for one row.
pub struct RowDerivatives {
    /// J's row, in column order.
    pub jacobian: Vec<Id>,
    /// γ.
    pub gamma: Id,
    /// γ from the body-frame rules (`omega_body`), the same number written
    /// another way.
    pub gamma_body: Option<Id>,
    /// Φ_t.
    pub phi_t: Id,
}

fn identity_frame(g: &mut Graph) -> Frame {
    let (zero, one) = (g.zero(), g.constant(1.0));
    Frame {
        a: [[one, zero, zero], [zero, one, zero], [zero, zero, one]],
        r: [zero; 3],
        omega: None,
        euler: None,
        body_rate: None,
    }
}

/// `A(p) = (e0² − eᵀe) I + 2 e eᵀ + 2 e0 ẽ`, homogeneous in `p` (no unit-norm
/// shortcut: `euler` evaluates it off the unit sphere).
pub fn rotation_matrix(g: &mut Graph, p: [Id; 4], name: &str) -> [[Id; 3]; 3] {
    let start = g.len();
    let [e0, e1, e2, e3] = p;
    let sq = p.map(|e| g.mul(e, e));
    let two = g.constant(2.0);
    let (d0, d1, d2) = (g.mul(two, e0), g.mul(two, e1), g.mul(two, e2));
    // Diagonal: (e0² − e3²) ± (e1² − e2²) and (e0² + e3²) − (e1² + e2²).
    let x = g.sub(sq[0], sq[3]);
    let y = g.sub(sq[1], sq[2]);
    let a11 = g.add(x, y);
    let a22 = g.sub(x, y);
    let s03 = g.add(sq[0], sq[3]);
    let s12 = g.add(sq[1], sq[2]);
    let a33 = g.sub(s03, s12);
    let (p12, p03) = (g.mul(d1, e2), g.mul(d0, e3));
    let (p13, p02) = (g.mul(d1, e3), g.mul(d0, e2));
    let (p23, p01) = (g.mul(d2, e3), g.mul(d0, e1));
    let a = [
        [a11, g.sub(p12, p03), g.add(p13, p02)],
        [g.add(p12, p03), a22, g.sub(p23, p01)],
        [g.sub(p13, p02), g.add(p23, p01), a33],
    ];
    for (i, row) in a.iter().enumerate() {
        for (j, &e) in row.iter().enumerate() {
            g.hint_new(start, e, format!("{name}_{}{}", i + 1, j + 1));
        }
    }
    a
}

/// The quaternion product `p ⊗ q`.
fn quat_mul(g: &mut Graph, p: [Id; 4], q: [Id; 4]) -> [Id; 4] {
    let (pv, qv) = ([p[1], p[2], p[3]], [q[1], q[2], q[3]]);
    let scalar = {
        let d = dot(g, pv, qv);
        let s = g.mul(p[0], q[0]);
        g.sub(s, d)
    };
    let c = cross(g, pv, qv);
    let v = [0, 1, 2].map(|j| {
        let a = g.mul(p[0], qv[j]);
        let b = g.mul(q[0], pv[j]);
        let ab = g.add(a, b);
        g.add(ab, c[j])
    });
    [scalar, v[0], v[1], v[2]]
}

/// `M v`.
pub fn mat_vec(g: &mut Graph, m: &[[Id; 3]; 3], v: V3) -> V3 {
    m.map(|row| dot(g, row, v))
}

/// `a · b`, summed left to right.
pub fn dot(g: &mut Graph, a: V3, b: V3) -> Id {
    let terms = [0, 1, 2].map(|j| g.mul(a[j], b[j]));
    g.sum(&terms)
}

/// `a × b`.
pub fn cross(g: &mut Graph, a: V3, b: V3) -> V3 {
    [(1, 2), (2, 0), (0, 1)].map(|(i, j)| {
        let l = g.mul(a[i], b[j]);
        let r = g.mul(a[j], b[i]);
        g.sub(l, r)
    })
}
