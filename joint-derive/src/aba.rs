//! The articulated-body algorithm written out for a relative-coordinate
//! scene's fixed tree (`TreeScene::forward_dynamics_into`), on the engine's
//! graph: the same three passes as the runtime's recursion
//! (`joint_runtime::tree`), but every axis, joint point, motion subspace and
//! rest rotation is a number here, so the structural zeros of the spatial
//! algebra fold away (a revolute joint about `z` moves three of six
//! components; a diagonal inertia has three of nine entries) and equal
//! subexpressions are one node. Masses, inertias and gravity may be fields
//! (read into `let`s); the joints' points and axes must be numbers, or the
//! method is not written and the runtime's recursion runs. Not written above
//! [`LIMIT`] operations either (build time).

use proc_macro2::TokenStream;
use quote::{format_ident, quote};

use crate::engine::emit::{ScalarTy, emit};
use crate::engine::graph::{Graph, Id};
use crate::front::attr::Number;
use crate::front::resolve::Source;
use crate::front::scene::{JointDecl, Quantity, SceneDecl};
use crate::front::tree::{TreeEdge, TreeKind};
use crate::generate::{krate, named_f64};

/// Operations above which the method is not written: one straight-line
/// function of 17 000 operations (a 40-bar chain) took rustc 7.5 s, its
/// crate 1.65 times the absolute scene's build; at most 10 000 (a 20-bar
/// chain, 8 432) keeps a 40-body tree's build near the absolute one's.
pub const LIMIT: usize = 10_000;

type V3 = [Id; 3];
type M3 = [[Id; 3]; 3];
type V6 = [Id; 6];
type M6 = [[Id; 6]; 6];

/// The graph and the inputs bound from the scene's fields.
struct Builder {
    g: Graph,
    /// `(name, expression)` of every parameter input.
    bindings: Vec<(String, TokenStream)>,
}

impl Builder {
    fn c(&mut self, x: f64) -> Id {
        self.g.constant(x)
    }

    /// `x · id` for a number `x`.
    fn scale(&mut self, x: f64, id: Id) -> Id {
        let k = self.c(x);
        self.g.mul(k, id)
    }

    /// A number of the declaration: folded, or an input bound to the named constant.
    fn number(&mut self, n: &Number) -> Id {
        match n {
            Number::Known(x) => self.c(*x),
            Number::Named(e) => self.input(named_f64(e)),
        }
    }

    fn input(&mut self, expr: TokenStream) -> Id {
        let name = format!("p_{}", self.bindings.len());
        self.bindings.push((name.clone(), expr));
        self.g.param(name)
    }

    fn add3(&mut self, a: V3, b: V3) -> V3 {
        [0, 1, 2].map(|i| self.g.add(a[i], b[i]))
    }

    fn sub3(&mut self, a: V3, b: V3) -> V3 {
        [0, 1, 2].map(|i| self.g.sub(a[i], b[i]))
    }

    fn cross(&mut self, a: V3, b: V3) -> V3 {
        let mut out = [a[0]; 3];
        for (i, o) in out.iter_mut().enumerate() {
            let (j, k) = ((i + 1) % 3, (i + 2) % 3);
            let (x, y) = (self.g.mul(a[j], b[k]), self.g.mul(a[k], b[j]));
            *o = self.g.sub(x, y);
        }
        out
    }

    fn dot(&mut self, a: &[Id], b: &[Id]) -> Id {
        let terms: Vec<Id> = a.iter().zip(b).map(|(x, y)| self.g.mul(*x, *y)).collect();
        self.g.sum(&terms)
    }

    /// `M v`.
    fn mv(&mut self, m: &M3, v: V3) -> V3 {
        [0, 1, 2].map(|i| self.dot(&m[i], &v))
    }

    /// `Mᵀ v`.
    fn mtv(&mut self, m: &M3, v: V3) -> V3 {
        [0, 1, 2].map(|i| {
            let col = [m[0][i], m[1][i], m[2][i]];
            self.dot(&col, &v)
        })
    }

    /// `Aᵀ B C` for 3 × 3 blocks (`Eᵀ X E`).
    fn rotate(&mut self, e: &M3, x: &M3) -> M3 {
        let xe: M3 = [0, 1, 2].map(|i| [0, 1, 2].map(|j| self.dot(&x[i], &[e[0][j], e[1][j], e[2][j]])));
        [0, 1, 2].map(|i| [0, 1, 2].map(|j| self.dot(&[e[0][i], e[1][i], e[2][i]], &[xe[0][j], xe[1][j], xe[2][j]])))
    }

    /// `[r]× X` (each column crossed).
    fn cross_cols(&mut self, r: V3, x: &M3) -> M3 {
        let cols: [V3; 3] = [0, 1, 2].map(|j| self.cross(r, [x[0][j], x[1][j], x[2][j]]));
        [0, 1, 2].map(|i| [0, 1, 2].map(|j| cols[j][i]))
    }

    fn m6v(&mut self, m: &M6, v: V6) -> V6 {
        [0, 1, 2, 3, 4, 5].map(|i| self.dot(&m[i], &v))
    }
}

fn halves(m: V6) -> (V3, V3) {
    ([m[0], m[1], m[2]], [m[3], m[4], m[5]])
}

fn join(a: V3, b: V3) -> V6 {
    [a[0], a[1], a[2], b[0], b[1], b[2]]
}

/// A parent-to-child transform: `E` (parent components to child ones) and
/// `r` (the child's origin from the parent's, parent components).
struct Transform {
    e: M3,
    r: V3,
}

impl Builder {
    /// `X m`.
    fn motion(&mut self, x: &Transform, m: V6) -> V6 {
        let (w, v) = halves(m);
        let rw = self.cross(x.r, w);
        let shifted = self.sub3(v, rw);
        let (w, v) = (self.mv(&x.e, w), self.mv(&x.e, shifted));
        join(w, v)
    }

    /// `Xᵀ f`.
    fn force_back(&mut self, x: &Transform, f: V6) -> V6 {
        let (n, f) = halves(f);
        let (n, f) = (self.mtv(&x.e, n), self.mtv(&x.e, f));
        let rf = self.cross(x.r, f);
        join(self.add3(n, rf), f)
    }

    /// `Xᵀ I X` by blocks (see the runtime's `Transform::inertia_back`).
    fn inertia_back(&mut self, x: &Transform, i: &M6) -> M6 {
        let block = |r: usize, c: usize| -> M3 { [0, 1, 2].map(|a| [0, 1, 2].map(|b| i[r + a][c + b])) };
        let (a, b, c) =
            (self.rotate(&x.e, &block(0, 0)), self.rotate(&x.e, &block(0, 3)), self.rotate(&x.e, &block(3, 3)));
        // R Bᵀ − B R = N + Nᵀ with N = R Bᵀ; R C R = (R C) R = −(R (R C)ᵀ)ᵀ.
        let bt: M3 = [0, 1, 2].map(|r| [0, 1, 2].map(|s| b[s][r]));
        let n = self.cross_cols(x.r, &bt);
        let rc = self.cross_cols(x.r, &c);
        let rct: M3 = [0, 1, 2].map(|r| [0, 1, 2].map(|s| rc[s][r]));
        let r_rct = self.cross_cols(x.r, &rct);
        let mut out = [[a[0][0]; 6]; 6];
        for r in 0..3 {
            for s in r..3 {
                let sym = self.g.add(n[r][s], n[s][r]);
                let t = self.g.add(a[r][s], sym);
                // (R C R)_rs = −(R (R C)ᵀ)_sr
                let v = self.g.add(t, r_rct[s][r]);
                out[r][s] = v;
                out[s][r] = v;
                out[3 + r][3 + s] = c[r][s];
                out[3 + s][3 + r] = c[r][s];
            }
            for s in 0..3 {
                let v = self.g.add(b[r][s], rc[r][s]);
                out[r][3 + s] = v;
                out[3 + s][r] = v;
            }
        }
        out
    }

    fn cross_motion(&mut self, a: V6, b: V6) -> V6 {
        let ((w, v), (bw, bv)) = (halves(a), halves(b));
        let ang = self.cross(w, bw);
        let (x, y) = (self.cross(w, bv), self.cross(v, bw));
        join(ang, self.add3(x, y))
    }

    fn cross_force(&mut self, m: V6, f: V6) -> V6 {
        let ((w, v), (n, f)) = (halves(m), halves(f));
        let (x, y) = (self.cross(w, n), self.cross(v, f));
        join(self.add3(x, y), self.cross(w, f))
    }

    fn sub6(&mut self, a: &M6, b: &M6) -> M6 {
        [0, 1, 2, 3, 4, 5].map(|r| [0, 1, 2, 3, 4, 5].map(|s| self.g.sub(a[r][s], b[r][s])))
    }

    fn add6(&mut self, a: &M6, b: &M6) -> M6 {
        [0, 1, 2, 3, 4, 5].map(|r| [0, 1, 2, 3, 4, 5].map(|s| self.g.add(a[r][s], b[r][s])))
    }
}

/// What the derive knows of one tree joint: numbers only.
struct Joint {
    kind: TreeKind,
    /// The edge index of the parent body's joint.
    parent: Option<usize>,
    child: usize,
    rho_p: [f64; 3],
    rho_c: [f64; 3],
    /// Revolute: the child axis, unit, and `R₀`.
    axis: [f64; 3],
    rest: [[f64; 3]; 3],
}

fn known(j: &JointDecl, name: &str) -> Option<[f64; 3]> {
    let p = j.params.iter().find(|p| p.name == name)?;
    match &p.source {
        Source::Const(..) => p.source.known().and_then(|v| <[f64; 3]>::try_from(v.as_slice()).ok()),
        Source::Field { .. } => None,
    }
}

fn unit(a: [f64; 3]) -> Option<[f64; 3]> {
    let n = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
    (n > 0.0 && n.is_finite()).then(|| a.map(|x| x / n))
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

/// `R₀`, the shortest rotation taking `h` onto `a` (both unit), as the runtime
/// makes it: half a turn about the first of `perpendicular_pair(h)` when opposite.
fn rest_rotation(h: [f64; 3], a: [f64; 3]) -> [[f64; 3]; 3] {
    let d: f64 = (0..3).map(|i| h[i] * a[i]).sum();
    let (axis, c, s) = if d > -1.0 + 1e-12 {
        let k = cross(h, a);
        let s = (k[0] * k[0] + k[1] * k[1] + k[2] * k[2]).sqrt();
        match unit(k) {
            Some(k) => (k, d, s),
            None => return [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        }
    } else {
        // perpendicular_pair: h × (the coordinate axis least along h), unit.
        let m = (0..3).min_by(|&i, &j| h[i].abs().total_cmp(&h[j].abs()).then(i.cmp(&j))).unwrap_or(0);
        let mut e = [0.0; 3];
        e[m] = 1.0;
        (unit(cross(h, e)).unwrap_or([1.0, 0.0, 0.0]), -1.0, 0.0)
    };
    rodrigues(axis, c, s)
}

fn rodrigues(k: [f64; 3], c: f64, s: f64) -> [[f64; 3]; 3] {
    let mut r = [[0.0; 3]; 3];
    for (i, row) in r.iter_mut().enumerate() {
        for (j, x) in row.iter_mut().enumerate() {
            let skew = match (i, j) {
                (0, 1) => -k[2],
                (0, 2) => k[1],
                (1, 0) => k[2],
                (1, 2) => -k[0],
                (2, 0) => -k[1],
                (2, 1) => k[0],
                _ => 0.0,
            };
            *x = if i == j { c } else { 0.0 } + (1.0 - c) * k[i] * k[j] + s * skew;
        }
    }
    r
}

/// The joints with their geometry as numbers, or `None` when a point or an
/// axis is a field or a named constant.
fn joints(s: &SceneDecl, edges: &[TreeEdge]) -> Option<Vec<Joint>> {
    let mut moved_by = vec![None; s.bodies.len()];
    let mut out = Vec::new();
    for (k, e) in edges.iter().enumerate() {
        let j = &s.joints[e.joint];
        let (parent, child) = if e.reversed { (j.bodies[1], j.bodies[0]) } else { (j.bodies[0], j.bodies[1]) };
        let child = child?;
        let (rho1, rho2) = (known(j, "rho1")?, known(j, "rho2")?);
        let (mut axis, mut rest) = ([0.0; 3], [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]);
        if e.kind == TreeKind::Revolute {
            let first = unit(cross(known(j, "f")?, known(j, "g")?))?;
            let second = unit(known(j, "h")?)?;
            let (a, h) = if e.reversed { (second, first) } else { (first, second) };
            axis = h;
            rest = rest_rotation(h, a);
        }
        let (rho_p, rho_c) = if e.reversed { (rho2, rho1) } else { (rho1, rho2) };
        out.push(Joint {
            kind: e.kind,
            parent: parent.map(|p| moved_by[p]).unwrap_or(None),
            child,
            rho_p,
            rho_c,
            axis,
            rest,
        });
        moved_by[child] = Some(k);
    }
    Some(out)
}

impl Builder {
    fn consts3(&mut self, v: [f64; 3]) -> V3 {
        v.map(|x| self.c(x))
    }

    /// A quantity of three numbers (gravity, principal moments): folded or read.
    fn quantity3(&mut self, q: &Quantity) -> V3 {
        match q {
            Quantity::Const(v) => [0, 1, 2].map(|i| self.number(v.get(i).unwrap_or(&Number::Known(0.0)))),
            Quantity::Field(f) => [quote!(x), quote!(y), quote!(z)].map(|c| self.input(quote!(self.#f.#c))),
        }
    }

    /// A body's `I_c` (three principal moments or six entries) and mass.
    fn body(&mut self, mass: &Quantity, inertia: &Quantity) -> (Id, M3) {
        let m = match mass {
            Quantity::Const(v) => self.number(v.first().unwrap_or(&Number::Known(1.0))),
            Quantity::Field(f) => self.input(quote!(self.#f)),
        };
        let zero = self.c(0.0);
        let i = match inertia {
            Quantity::Const(v) if v.len() == 6 => {
                let e: Vec<Id> = v.iter().map(|n| self.number(n)).collect();
                [[e[0], e[3], e[4]], [e[3], e[1], e[5]], [e[4], e[5], e[2]]]
            }
            q => {
                let d = self.quantity3(q);
                [[d[0], zero, zero], [zero, d[1], zero], [zero, zero, d[2]]]
            }
        };
        (m, i)
    }

    /// The child's rotation relative to its parent, `R₀ rot(h, θ)` or the
    /// normalised quaternion's matrix.
    fn relative(&mut self, j: &Joint, q: &[Id]) -> M3 {
        match j.kind {
            TreeKind::Revolute => {
                let (c, s) = (self.g.cos(q[0]), self.g.sin(q[0]));
                let one = self.c(1.0);
                let omc = self.g.sub(one, c);
                let h = j.axis;
                let rot: M3 = [0, 1, 2].map(|a| {
                    [0, 1, 2].map(|b| {
                        if a == b {
                            // c + (1 − c) h²: exactly 1 or c on a coordinate axis.
                            match h[a] * h[a] {
                                1.0 => one,
                                0.0 => c,
                                x => {
                                    let t = self.scale(x, omc);
                                    self.g.add(c, t)
                                }
                            }
                        } else {
                            let k = 3 - a - b;
                            let sign = if (a + 1) % 3 == b { -1.0 } else { 1.0 };
                            let t1 = self.scale(h[a] * h[b], omc);
                            let t2 = self.scale(sign * h[k], s);
                            self.g.add(t1, t2)
                        }
                    })
                });
                let rest: M3 = j.rest.map(|row| row.map(|x| self.c(x)));
                [0, 1, 2].map(|a| [0, 1, 2].map(|b| self.dot(&rest[a], &[rot[0][b], rot[1][b], rot[2][b]])))
            }
            TreeKind::Spherical => {
                let (e0, e) = (q[0], [q[1], q[2], q[3]]);
                let n2 = self.dot(q, q);
                let one = self.c(1.0);
                let inv = self.g.div(one, n2);
                let (ee, e00) = (self.dot(&e, &e), self.g.mul(e0, e0));
                let diag = self.g.sub(e00, ee);
                let two = self.c(2.0);
                let mut m = [[diag; 3]; 3];
                for (a, row) in m.iter_mut().enumerate() {
                    for (b, x) in row.iter_mut().enumerate() {
                        let outer = self.g.mul(e[a], e[b]);
                        let mut v = self.g.mul(two, outer);
                        if a == b {
                            v = self.g.add(diag, v);
                        } else {
                            let k = 3 - a - b;
                            let sign = if (a + 1) % 3 == b { -1.0 } else { 1.0 };
                            let t = self.g.mul(e0, e[k]);
                            let t = self.scale(2.0 * sign, t);
                            v = self.g.add(v, t);
                        }
                        *x = self.g.mul(v, inv);
                    }
                }
                m
            }
        }
    }
}

/// The joint's motion subspace in the child's link frame (origin at the
/// joint point): `[a; 0]` per freedom, a coordinate axis for a spherical
/// joint and for a revolute joint about `x`, `y` or `z`.
fn subspace(j: &Joint) -> Vec<[f64; 6]> {
    let axes = match j.kind {
        TreeKind::Revolute => vec![j.axis],
        TreeKind::Spherical => vec![[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
    };
    axes.into_iter().map(|a| [a[0], a[1], a[2], 0.0, 0.0, 0.0]).collect()
}

/// The entries a subspace of coordinate axes selects (`None` when a column
/// is not one): the rows and columns that `Iᴬ − U D⁻¹ Uᵀ` zeroes exactly.
fn selected(s: &[[f64; 6]]) -> Option<Vec<usize>> {
    s.iter()
        .map(|col| {
            let ones: Vec<usize> = (0..6).filter(|&i| col[i] == 1.0).collect();
            let zeros = col.iter().filter(|&&x| x == 0.0).count();
            (ones.len() == 1 && zeros == 5).then(|| ones[0])
        })
        .collect()
}

impl Builder {
    /// A body's spatial inertia about the point `−c` from its centre of mass
    /// (`c`: the centre from that point), body axes:
    /// `[I_c + m [c]× [c]×ᵀ, m [c]×; m [c]×ᵀ, m 1]`.
    fn link_inertia(&mut self, m: Id, ic: &M3, c: [f64; 3]) -> M6 {
        let zero = self.c(0.0);
        let cx = [[0.0, -c[2], c[1]], [c[2], 0.0, -c[0]], [-c[1], c[0], 0.0]];
        let mut out = [[zero; 6]; 6];
        for r in 0..3 {
            for s in 0..3 {
                // ([c]× [c]×ᵀ)_rs = Σ_k cx_rk cx_sk
                let ccx: f64 = (0..3).map(|k| cx[r][k] * cx[s][k]).sum();
                let shift = self.scale(ccx, m);
                out[r][s] = self.g.add(ic[r][s], shift);
                let mc = self.scale(cx[r][s], m);
                out[r][3 + s] = mc;
                out[3 + s][r] = mc;
            }
            out[3 + r][3 + r] = m;
        }
        out
    }
}

/// `fn forward_dynamics_into`, or nothing (points or axes not numbers, or
/// above [`LIMIT`]).
pub fn method(s: &SceneDecl, edges: &[TreeEdge], nq: usize, nv: usize) -> Option<(TokenStream, usize)> {
    let joints = joints(s, edges)?;
    let mut b = Builder { g: Graph::new(), bindings: Vec::new() };
    let q: Vec<Id> = (0..nq).map(|i| b.g.param(format!("q_{i}"))).collect();
    let v: Vec<Id> = (0..nv).map(|i| b.g.param(format!("v_{i}"))).collect();
    let tau: Vec<Id> = (0..nv).map(|i| b.g.param(format!("tau_{i}"))).collect();
    let gravity = b.quantity3(&s.gravity);
    let zero = b.c(0.0);
    let n = joints.len();
    let (mut qa, mut va) = (Vec::with_capacity(n), Vec::with_capacity(n));
    let (mut at_q, mut at_v) = (0, 0);
    for j in &joints {
        let (a, bb) = j.kind.sizes();
        qa.push(at_q);
        va.push(at_v);
        at_q += a;
        at_v += bb;
    }
    // Pass 1: transforms, velocities, velocity-product accelerations, bias forces.
    let mut xs = Vec::with_capacity(n);
    let mut subs: Vec<Vec<V6>> = Vec::with_capacity(n);
    let (mut vel, mut cc, mut ia, mut pa) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let mut sel = Vec::with_capacity(n);
    for (k, j) in joints.iter().enumerate() {
        let rel = b.relative(j, &q[qa[k]..qa[k] + j.kind.sizes().0]);
        let e: M3 = [0, 1, 2].map(|r| [0, 1, 2].map(|c| rel[c][r]));
        // Link frames: each body's axes, origin at its inbound joint point, so
        // that the joint's subspace is constant coordinate axes and the
        // offset between two joint points a constant of the parent.
        let inbound = j.parent.map_or([0.0; 3], |p| joints[p].rho_c);
        let r = [0, 1, 2].map(|i| j.rho_p[i] - inbound[i]);
        let x = Transform { e, r: b.consts3(r) };
        let cols = subspace(j);
        sel.push(selected(&cols));
        let s_k: Vec<V6> = cols.into_iter().map(|col| col.map(|x| b.c(x))).collect();
        let mut vj = [zero; 6];
        for (i, col) in s_k.iter().enumerate() {
            for r in 0..6 {
                let t = b.g.mul(col[r], v[va[k] + i]);
                vj[r] = b.g.add(vj[r], t);
            }
        }
        let vk = match j.parent {
            Some(p) => {
                let from = b.motion(&x, vel[p]);
                [0, 1, 2, 3, 4, 5].map(|r| b.g.add(from[r], vj[r]))
            }
            None => vj,
        };
        let (m, ic) = {
            let body = &s.bodies[j.child];
            b.body(&body.mass, &body.inertia)
        };
        let inertia = b.link_inertia(m, &ic, j.rho_c.map(|x| -x));
        let iv = b.m6v(&inertia, vk);
        pa.push(b.cross_force(vk, iv));
        cc.push(b.cross_motion(vk, vj));
        vel.push(vk);
        ia.push(inertia);
        xs.push(x);
        subs.push(s_k);
    }
    // Pass 2, leaves to root: U = Iᴬ S, D⁻¹, u = τ − Sᵀ pᴬ; the articulated
    // inertia and bias handed to the parent.
    let mut uu: Vec<Vec<V6>> = vec![Vec::new(); n];
    let mut dinv: Vec<Vec<Vec<Id>>> = vec![Vec::new(); n];
    let mut us: Vec<Vec<Id>> = vec![Vec::new(); n];
    for k in (0..n).rev() {
        let s_k = subs[k].clone();
        let dof = s_k.len();
        let u_cols: Vec<V6> = s_k.iter().map(|col| b.m6v(&ia[k], *col)).collect();
        let d: Vec<Vec<Id>> = (0..dof).map(|r| (0..dof).map(|c| b.dot(&s_k[r], &u_cols[c])).collect()).collect();
        let inv = b.inverse(&d);
        let u: Vec<Id> = (0..dof)
            .map(|i| {
                let sp = b.dot(&s_k[i], &pa[k]);
                b.g.sub(tau[va[k] + i], sp)
            })
            .collect();
        if let Some(p) = joints[k].parent {
            // U D⁻¹ (its columns), then Iᴬ − (U D⁻¹) Uᵀ and pᴬ + Iᵃ c + U D⁻¹ u.
            let ud: Vec<V6> = (0..dof)
                .map(|c| {
                    [0, 1, 2, 3, 4, 5].map(|r| {
                        let row: Vec<Id> = (0..dof).map(|i| u_cols[i][r]).collect();
                        let col: Vec<Id> = (0..dof).map(|i| inv[i][c]).collect();
                        b.dot(&row, &col)
                    })
                })
                .collect();
            let mut outer: M6 = [[zero; 6]; 6];
            for r in 0..6 {
                for c in r..6 {
                    let row: Vec<Id> = (0..dof).map(|i| ud[i][r]).collect();
                    let col: Vec<Id> = (0..dof).map(|i| u_cols[i][c]).collect();
                    let v = b.dot(&row, &col);
                    outer[r][c] = v;
                    outer[c][r] = v;
                }
            }
            let mut reduced = b.sub6(&ia[k], &outer);
            // Exact zeros the graph cannot see (A − A A⁻¹ A): the reduced
            // inertia moves nothing along the joint's own freedoms.
            for &i in sel[k].iter().flatten() {
                reduced[i] = [zero; 6];
                for row in reduced.iter_mut() {
                    row[i] = zero;
                }
            }
            let ic = b.m6v(&reduced, cc[k]);
            let udu = [0, 1, 2, 3, 4, 5].map(|r| {
                let row: Vec<Id> = (0..dof).map(|i| ud[i][r]).collect();
                b.dot(&row, &u)
            });
            let pa_k = [0, 1, 2, 3, 4, 5].map(|r| {
                let t = b.g.add(pa[k][r], ic[r]);
                b.g.add(t, udu[r])
            });
            let back = b.inertia_back(&xs[k], &reduced);
            ia[p] = b.add6(&ia[p], &back);
            let fb = b.force_back(&xs[k], pa_k);
            pa[p] = [0, 1, 2, 3, 4, 5].map(|r| b.g.add(pa[p][r], fb[r]));
        }
        uu[k] = u_cols;
        dinv[k] = inv;
        us[k] = u;
    }
    // Pass 3, root to leaves: accelerations.
    let neg_g = gravity.map(|x| b.g.neg(x));
    let ground = join([zero; 3], neg_g);
    let mut acc: Vec<V6> = Vec::with_capacity(n);
    let mut out = vec![zero; nv];
    for (k, j) in joints.iter().enumerate() {
        let from = match j.parent {
            Some(p) => acc[p],
            None => ground,
        };
        let moved = b.motion(&xs[k], from);
        let a = [0, 1, 2, 3, 4, 5].map(|r| b.g.add(moved[r], cc[k][r]));
        let dof = subs[k].len();
        let rhs: Vec<Id> = (0..dof)
            .map(|i| {
                let ua = b.dot(&uu[k][i], &a);
                b.g.sub(us[k][i], ua)
            })
            .collect();
        let qdd: Vec<Id> = (0..dof).map(|r| b.dot(&dinv[k][r], &rhs)).collect();
        let mut a = a;
        for (i, col) in subs[k].iter().enumerate() {
            for r in 0..6 {
                let t = b.g.mul(col[r], qdd[i]);
                a[r] = b.g.add(a[r], t);
            }
            out[va[k] + i] = qdd[i];
        }
        acc.push(a);
    }
    let k = krate();
    let sty = ScalarTy { ty: quote!(f64), krate: k.clone(), concrete_f64: true };
    let emitted = emit(&b.g, &out, &sty);
    if emitted.ops > LIMIT {
        return None;
    }
    let used: std::collections::BTreeSet<String> =
        emitted.used_vars.iter().map(|v| b.g.vars()[v.0 as usize].name.clone()).collect();
    let binds = b.bindings.iter().filter(|(name, _)| used.contains(name)).map(|(name, expr)| {
        let name = format_ident!("{name}");
        quote!(let #name: f64 = #expr;)
    });
    let names = |prefix: &str, count: usize| {
        let ids = (0..count).map(|i| {
            let name = format!("{prefix}_{i}");
            if used.contains(&name) {
                let id = format_ident!("{name}");
                quote!(#id)
            } else {
                quote!(_)
            }
        });
        quote!([#(#ids),*])
    };
    let (qp, vp, tp) = (names("q", nq), names("v", nv), names("tau", nv));
    let (body, outputs, ops) = (emitted.body, emitted.outputs, emitted.ops);
    let method = quote! {
        fn forward_dynamics_into(&self, q: &[f64; #nq], v: &[f64; #nv], tau: &[f64; #nv], out: &mut [f64; #nv]) -> bool {
            let #qp = *q;
            let #vp = *v;
            let #tp = *tau;
            #(#binds)*
            #body
            *out = [#(#outputs),*];
            true
        }
    };
    Some((method, ops))
}

impl Builder {
    /// The inverse of a 1 × 1 or symmetric 3 × 3 matrix (adjugate over the
    /// determinant: one division).
    fn inverse(&mut self, d: &[Vec<Id>]) -> Vec<Vec<Id>> {
        let one = self.c(1.0);
        if d.len() == 1 {
            return vec![vec![self.g.div(one, d[0][0])]];
        }
        let m = |r: usize, c: usize| d[r][c];
        let cof = |b: &mut Builder, r: usize, c: usize| {
            let (r1, r2) = ((r + 1) % 3, (r + 2) % 3);
            let (c1, c2) = ((c + 1) % 3, (c + 2) % 3);
            let x = b.g.mul(m(r1, c1), m(r2, c2));
            let y = b.g.mul(m(r1, c2), m(r2, c1));
            b.g.sub(x, y)
        };
        let cofactors: Vec<Vec<Id>> = (0..3).map(|r| (0..3).map(|c| cof(self, r, c)).collect()).collect();
        let det = self.dot(&[m(0, 0), m(0, 1), m(0, 2)], &[cofactors[0][0], cofactors[0][1], cofactors[0][2]]);
        let inv_det = self.g.div(one, det);
        // inverse = adj / det, adj = cofactorsᵀ (symmetric here).
        (0..3).map(|r| (0..3).map(|c| self.g.mul(cofactors[c][r], inv_det)).collect()).collect()
    }
}
