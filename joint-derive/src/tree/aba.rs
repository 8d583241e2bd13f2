//! The articulated-body algorithm written out for a relative-coordinate
//! scene's fixed tree (`TreeScene::forward_dynamics_into`), on the engine's
//! graph: the same three passes as the runtime's recursion
//! (`joint_runtime::relative`), but every axis, joint point, motion subspace and
//! rest rotation given as a number is one here, so the structural zeros of the spatial
//! algebra fold away (a revolute joint about `z` moves three of six
//! components; a diagonal inertia has three of nine entries) and equal
//! subexpressions are one node. Masses, inertias and gravity may be fields
//! (read into `let`s); a joint whose points or axes are fields reads all of
//! its geometry from the runtime's `TreeGeometry` (`geometry`, made once by
//! `Tree::new`: unit axes, rest rotation), so only its own terms stay
//! unfolded (`closure::read_joint`, which the closures' rows read too). Not
//! written above [`LIMIT`] operations (build time): the runtime's recursion
//! runs there.
//!
//! From the same per-joint passes come the recursive Newton–Euler algorithm
//! (`TreeScene::inverse_dynamics_into`) and the composite-rigid-body mass
//! matrix (`mass_matrix_into`), each one straight line under the same limit;
//! `TreeSimulation` falls back to the runtime's recursions for any it lacks.
//! Everything is in link frames, as in the runtime: each body's axes with the
//! origin at its inbound joint point, so that a joint's motion subspace is
//! constant coordinate axes `[a; 0]` and the offset between two joint points a
//! constant of the parent. A spherical joint hands its parent only the
//! translational block `C − Bᵀ A⁻¹ B` of its articulated inertia (the graph
//! cannot see that `A − A A⁻¹ A` vanishes: those zeros are set); a free joint
//! hands on nothing, its body's acceleration `Iᴬ⁻¹ (S τ − pᴬ)` whatever its
//! parent's, one 6 × 6 `L D Lᵀ` solve without a square root. A universal
//! joint's subspace turns with its second angle and a planar joint's slides
//! with its angle: the passes take such a joint's columns from the first pass
//! and add its `Ṡ q̇`.
//!
//! Past the limit one function costs more build time than the whole absolute
//! scene, so the forward dynamics is written as one kernel per distinct joint
//! and pass (a chain's identical links share theirs, de-duplicated by their
//! printed text), called in tree order over per-joint arrays (a 40-bar chain's
//! crate then builds in 2.0 s, where its one straight line took rustc 7.5 s
//! alone). Kernels are free functions of numbers with constant subspaces: a
//! tree with fields, universal, planar or free joints, or a joint's armature,
//! damping or spring gets the straight line or nothing, and the runtime's
//! recursion runs it.

use proc_macro2::TokenStream;
use quote::{format_ident, quote};

use crate::engine::emit::{ScalarTy, emit};
use crate::engine::graph::{Graph, Id};
use crate::front::attr::Number;
use crate::front::geometry::{cross3, dot3, norm3, perpendicular_pair};
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
pub(crate) struct Builder {
    pub(crate) g: Graph,
    /// `(name, expression)` of every parameter input.
    pub(crate) bindings: Vec<(String, TokenStream)>,
}

impl Builder {
    pub(crate) fn new(g: Graph) -> Self {
        Builder { g, bindings: Vec::new() }
    }

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

    /// An input bound to `expr`, once per expression.
    fn input(&mut self, expr: TokenStream) -> Id {
        let text = expr.to_string();
        if let Some((name, _)) = self.bindings.iter().find(|(_, e)| e.to_string() == text) {
            let name = name.clone();
            return self.g.param(name);
        }
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

    /// A vector of the runtime's `TreeGeometry` at `path` (`["rest", "3",
    /// "0"]`: `geometry.rest[3][0]`), for a joint whose points or axes are
    /// fields.
    pub(crate) fn geometry(&mut self, path: &[&str]) -> V3 {
        let field = format_ident!("{}", path[0]);
        let index = path[1..].iter().map(|i| {
            let i = proc_macro2::Literal::usize_unsuffixed(i.parse().unwrap_or(0));
            quote!([#i])
        });
        let at = quote!(geometry.#field #(#index)*);
        [quote!(x), quote!(y), quote!(z)].map(|c| self.input(quote!(#at.#c)))
    }

    pub(crate) fn dot(&mut self, a: &[Id], b: &[Id]) -> Id {
        let terms: Vec<Id> = a.iter().zip(b).map(|(x, y)| self.g.mul(*x, *y)).collect();
        self.g.sum(&terms)
    }

    /// `M v`.
    pub(crate) fn mv(&mut self, m: &M3, v: V3) -> V3 {
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

/// A rigid body's spatial inertia about a frame's origin, compact: the
/// mass, the first moment `h = m c` and the rotational inertia `Ī` about the
/// origin (symmetric). Composite inertias stay rigid, so carrying one to
/// the parent turns `Ī` and `h` (and keeps `m` exact) instead of the three
/// 6 × 6 blocks of `Xᵀ I X` (where `Eᵀ (m 1) E` would not fold to `m 1`).
#[derive(Clone, Copy)]
struct Rigid {
    m: Id,
    h: V3,
    i: M3,
}

impl Rigid {
    /// Of a spatial inertia `[Ī, [h]×; [h]×ᵀ, m 1]` (as `link_inertia` makes them).
    fn of(i: &M6) -> Self {
        Rigid { m: i[3][3], h: [i[2][4], i[0][5], i[1][3]], i: [0, 1, 2].map(|r| [0, 1, 2].map(|c| i[r][c])) }
    }
}

impl Builder {
    /// `Xᵀ I X` of a rigid inertia: with `R = Eᵀ`, `h̃ = R h`,
    /// `h' = h̃ + m r` and `Ī' = R Ī Rᵀ + (2 r·h̃ + m r·r) 1 − h̃ rᵀ − r h̃ᵀ − m r rᵀ`
    /// (the parallel-axis theorem for the moved first moment).
    fn rigid_back(&mut self, x: &Transform, b: &Rigid) -> Rigid {
        let ht = self.mtv(&x.e, b.h);
        let mr = x.r.map(|r| self.g.mul(b.m, r));
        let h = self.add3(ht, mr);
        // R Ī Rᵀ = Eᵀ Ī E, its upper triangle.
        let ie: M3 = [0, 1, 2].map(|i| [0, 1, 2].map(|j| self.dot(&b.i[i], &[x.e[0][j], x.e[1][j], x.e[2][j]])));
        let rh = self.dot(&x.r, &ht);
        let rmr = self.dot(&x.r, &mr);
        let twice = self.g.add(rh, rh);
        let diagonal = self.g.add(twice, rmr);
        let mut i = [[b.m; 3]; 3];
        for r in 0..3 {
            for c in r..3 {
                let turned = self.dot(&[x.e[0][r], x.e[1][r], x.e[2][r]], &[ie[0][c], ie[1][c], ie[2][c]]);
                let cross = [self.g.mul(ht[r], x.r[c]), self.g.mul(x.r[r], ht[c]), self.g.mul(mr[r], x.r[c])];
                let mut v = turned;
                for t in cross {
                    v = self.g.sub(v, t);
                }
                if r == c {
                    v = self.g.add(v, diagonal);
                }
                i[r][c] = v;
                i[c][r] = v;
            }
        }
        Rigid { m: b.m, h, i }
    }

    fn rigid_add(&mut self, a: &Rigid, b: &Rigid) -> Rigid {
        let m = self.g.add(a.m, b.m);
        let h = self.add3(a.h, b.h);
        let i = [0, 1, 2].map(|r| [0, 1, 2].map(|c| self.g.add(a.i[r][c], b.i[r][c])));
        Rigid { m, h, i }
    }

    /// `I s`: `[Ī w + h × v; m v − h × w]`.
    fn rigid_mul(&mut self, a: &Rigid, s: V6) -> V6 {
        let (w, v) = halves(s);
        let iw = self.mv(&a.i, w);
        let hv = self.cross(a.h, v);
        let mv = v.map(|x| self.g.mul(a.m, x));
        let hw = self.cross(a.h, w);
        join(self.add3(iw, hv), self.sub3(mv, hw))
    }
}

/// What the derive knows of one tree joint: numbers only.
pub(crate) struct Joint {
    pub(crate) kind: TreeKind,
    /// The edge index of the parent body's joint.
    pub(crate) parent: Option<usize>,
    pub(crate) child: usize,
    pub(crate) rho_p: [f64; 3],
    pub(crate) rho_c: [f64; 3],
    /// Revolute, prismatic: the child axis, unit, and `R₀`.
    axis: [f64; 3],
    rest: [[f64; 3]; 3],
    /// Prismatic: the unit axis in the parent's frame, `R₀ h`.
    slide: [f64; 3],
    /// Planar: the parent's unit in-plane axes `f`, `g` (`f × g = a`).
    plane: [[f64; 3]; 2],
    /// `Some(k)`: its points or axes are fields, so all of its geometry is
    /// read from the runtime's `TreeGeometry` at `k` (the numbers above unused).
    pub(crate) read: Option<usize>,
    /// Inertia added to each freedom (`armature`), viscous damping of each
    /// (`damping`) and a one-freedom joint's spring: numbers, zero unless
    /// declared.
    pub(crate) armature: f64,
    pub(crate) damping: f64,
    pub(crate) stiffness: f64,
    pub(crate) spring_rest: f64,
}

fn known(j: &JointDecl, name: &str) -> Option<[f64; 3]> {
    let p = j.params.iter().find(|p| p.name == name)?;
    match &p.source {
        Source::Const(..) => p.source.known().and_then(|v| <[f64; 3]>::try_from(v.as_slice()).ok()),
        Source::Field { .. } => None,
    }
}

/// `a / |a|`, `None` for a zero or non-finite vector.
fn unit(a: [f64; 3]) -> Option<[f64; 3]> {
    let n = norm3(&a);
    (n > 0.0 && n.is_finite()).then(|| a.map(|x| x / n))
}

/// `R₀`, the shortest rotation taking `h` onto `a` (both unit), as the runtime
/// makes it: half a turn about the first of `perpendicular_pair(h)` when opposite.
fn rest_rotation(h: [f64; 3], a: [f64; 3]) -> [[f64; 3]; 3] {
    let d = dot3(&h, &a);
    let (axis, c, s) = if d > -1.0 + 1e-12 {
        let k = cross3(h, a);
        let s = norm3(&k);
        match unit(k) {
            Some(k) => (k, d, s),
            None => return [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        }
    } else {
        (perpendicular_pair(&h).0, -1.0, 0.0)
    };
    rodrigues(axis, c, s)
}

/// `h` made perpendicular to `a` (both unit), as the runtime makes a
/// universal joint's rest direction (`perpendicular_pair`'s first when `h` is
/// along `a`).
fn across(h: [f64; 3], a: [f64; 3]) -> [f64; 3] {
    let d = dot3(&h, &a);
    unit([0, 1, 2].map(|i| h[i] - a[i] * d))
        .filter(|_| (1.0 - d * d).sqrt() > 1e-9)
        .unwrap_or_else(|| perpendicular_pair(&a).0)
}

/// The rotation taking the child's axes `(h, k)` onto the parent's `(a, g)`
/// (each second axis made perpendicular to its unit first), as the runtime
/// makes it; `None` when a second axis is along its first.
fn locked_rotation(h: [f64; 3], k: [f64; 3], a: [f64; 3], g: [f64; 3]) -> Option<[[f64; 3]; 3]> {
    let frame = |x: [f64; 3], y: [f64; 3]| -> Option<[[f64; 3]; 3]> {
        let d = dot3(&x, &y);
        let y = unit([0, 1, 2].map(|i| y[i] - x[i] * d))?;
        Some([x, y, cross3(x, y)])
    };
    let (child, parent) = (frame(h, k)?, frame(a, g)?);
    // Σ_c parent[c] ⊗ child[c]: the parent frame's columns times the child's rows.
    Some([0, 1, 2].map(|r| [0, 1, 2].map(|s| (0..3).map(|c| parent[c][r] * child[c][s]).sum())))
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

impl Joint {
    /// A spherical joint (its relative rotation needs no geometry).
    pub(crate) fn spherical() -> Self {
        let identity = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        Joint {
            kind: TreeKind::Spherical,
            parent: None,
            child: 0,
            rho_p: [0.0; 3],
            rho_c: [0.0; 3],
            axis: [0.0; 3],
            rest: identity,
            slide: [0.0; 3],
            plane: [[0.0; 3]; 2],
            read: None,
            armature: 0.0,
            damping: 0.0,
            stiffness: 0.0,
            spring_rest: 0.0,
        }
    }
}

/// Each edge's parent edge (the one that moves its parent body).
pub(crate) fn parent_edges(s: &SceneDecl, edges: &[TreeEdge]) -> Vec<Option<usize>> {
    let mut moved_by = vec![None; s.bodies.len()];
    let mut out = Vec::new();
    for (k, e) in edges.iter().enumerate() {
        let (parent, child) = e.ends;
        out.push(parent.and_then(|p| moved_by[p]));
        moved_by[child] = Some(k);
    }
    out
}

/// One edge's joint with its geometry as numbers (`parent`: its parent
/// edge), or `None` when a point or an axis is not a number.
pub(crate) fn joint(s: &SceneDecl, e: &TreeEdge, parent: Option<usize>) -> Option<Joint> {
    let child = e.ends.1;
    let Some(j) = e.joint.map(|i| &s.joints[i]) else {
        // A floating body: its centre from the ground's origin.
        return Some(Joint { kind: TreeKind::Free, parent, child, ..Joint::spherical() });
    };
    let d = j.dynamics;
    let (armature, damping, stiffness, spring_rest) = (d.armature, d.damping, d.stiffness, d.spring_rest);
    let (rho1, rho2) = (known(j, "rho1")?, known(j, "rho2")?);
    let (mut axis, mut rest) = ([0.0; 3], [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]);
    let mut slide = [0.0; 3];
    if e.kind == TreeKind::Universal {
        let (first, second) = (unit(known(j, "s")?)?, unit(known(j, "h")?)?);
        let (a, h) = if e.reversed { (second, first) } else { (first, second) };
        let (rho_p, rho_c) = if e.reversed { (rho2, rho1) } else { (rho1, rho2) };
        let rest = rest_rotation(h, across(h, a));
        return Some(Joint {
            kind: e.kind,
            parent,
            child,
            rho_p,
            rho_c,
            axis: h,
            rest,
            slide: a,
            plane: [[0.0; 3]; 2],
            read: None,
            armature,
            damping,
            stiffness,
            spring_rest,
        });
    }
    let mut plane = [[0.0; 3]; 2];
    if e.kind != TreeKind::Spherical {
        let first = unit(cross3(known(j, "f")?, known(j, "g")?))?;
        let second = unit(known(j, "h")?)?;
        let (a, h) = if e.reversed { (second, first) } else { (first, second) };
        axis = h;
        rest = rest_rotation(h, a);
        if matches!(e.kind, TreeKind::Cylindrical | TreeKind::Planar) {
            slide = a;
        }
        if e.kind == TreeKind::Planar {
            // The parent's in-plane axes: its `f` (body 1), else as the runtime picks them.
            let f = if e.reversed { [0.0; 3] } else { known(j, "f")? };
            plane = in_plane(a, f);
        }
        if matches!(e.kind, TreeKind::Prismatic | TreeKind::Fixed) {
            // The second axes `g` (body 1) and `k` (body 2) lock the turn.
            let (g, k) = (known(j, "g")?, known(j, "k")?);
            let (g, k) = if e.reversed { (k, g) } else { (g, k) };
            rest = locked_rotation(h, k, a, g)?;
            slide = a;
        }
    }
    let (rho_p, rho_c) = if e.reversed { (rho2, rho1) } else { (rho1, rho2) };
    let (read, kind) = (None, e.kind);
    Some(Joint {
        kind,
        parent,
        child,
        rho_p,
        rho_c,
        axis,
        rest,
        slide,
        plane,
        read,
        armature,
        damping,
        stiffness,
        spring_rest,
    })
}

/// A planar joint's in-plane unit axes `(f, g)` of the parent, `f × g = a`,
/// as the runtime makes them: `f` made perpendicular to `a`, the first of
/// `perpendicular_pair(a)` when it is zero or along `a`.
fn in_plane(a: [f64; 3], f: [f64; 3]) -> [[f64; 3]; 2] {
    let along = dot3(&a, &f);
    let f = [0, 1, 2].map(|i| f[i] - a[i] * along);
    let f = if norm3(&f) < 1e-12 { perpendicular_pair(&a).0 } else { unit(f).unwrap_or([1.0, 0.0, 0.0]) };
    [f, cross3(a, f)]
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

    /// `r + d a`: a prismatic joint's offset moved by its slide `d` along its
    /// parent-frame axis `a`; `r` otherwise.
    pub(crate) fn slid(&mut self, j: &Joint, r: V3, q: &[Id]) -> V3 {
        if j.kind == TreeKind::Free {
            // A floating body's own offset, parent components.
            return [0, 1, 2].map(|i| self.g.add(r[i], q[i]));
        }
        let d = match j.kind {
            TreeKind::Prismatic => q[0],
            TreeKind::Cylindrical => q[1],
            TreeKind::Planar => {
                return [0, 1, 2].map(|i| {
                    let (x, y) = (self.scale(j.plane[0][i], q[0]), self.scale(j.plane[1][i], q[1]));
                    let t = self.g.add(r[i], x);
                    self.g.add(t, y)
                });
            }
            _ => return r,
        };
        [0, 1, 2].map(|i| {
            let t = self.scale(j.slide[i], d);
            self.g.add(r[i], t)
        })
    }

    /// `rot(h, θ)` about a unit axis of numbers.
    fn turn(&mut self, h: [f64; 3], theta: Id) -> M3 {
        let (c, s) = (self.g.cos(theta), self.g.sin(theta));
        let one = self.c(1.0);
        let omc = self.g.sub(one, c);
        [0, 1, 2].map(|a| {
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
        })
    }

    /// `A B` for 3 × 3 blocks.
    fn mm(&mut self, a: &M3, b: &M3) -> M3 {
        [0, 1, 2].map(|r| [0, 1, 2].map(|c| self.dot(&a[r], &[b[0][c], b[1][c], b[2][c]])))
    }

    /// The child's rotation relative to its parent: `R₀ rot(h, θ)`,
    /// `R₀`, `rot(s, θ₁) R₀ rot(h, θ₂)` or the normalised quaternion's matrix.
    pub(crate) fn relative(&mut self, j: &Joint, q: &[Id]) -> M3 {
        match j.kind {
            TreeKind::Revolute | TreeKind::Cylindrical | TreeKind::Planar => {
                let rot = self.turn(j.axis, q[if j.kind == TreeKind::Planar { 2 } else { 0 }]);
                let rest: M3 = j.rest.map(|row| row.map(|x| self.c(x)));
                self.mm(&rest, &rot)
            }
            TreeKind::Universal => {
                let (first, second) = (self.turn(j.slide, q[0]), self.turn(j.axis, q[1]));
                let rest: M3 = j.rest.map(|row| row.map(|x| self.c(x)));
                let turned = self.mm(&first, &rest);
                self.mm(&turned, &second)
            }
            TreeKind::Prismatic | TreeKind::Fixed => j.rest.map(|row| row.map(|x| self.c(x))),
            TreeKind::Spherical => self.quaternion_matrix(q),
            TreeKind::Free => self.quaternion_matrix(&q[3..]),
        }
    }

    /// The rotation matrix of the quaternion `q` normalised (`/ |q|²`: an
    /// RK4 stage's is off the unit sphere).
    pub(crate) fn quaternion_matrix(&mut self, q: &[Id]) -> M3 {
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

/// The joint's motion subspace in the child's link frame (origin at the
/// joint point): `[a; 0]` per freedom, a coordinate axis for a spherical
/// joint and for a revolute joint about `x`, `y` or `z`.
fn subspace(j: &Joint) -> Vec<[f64; 6]> {
    let turn = |a: [f64; 3]| [a[0], a[1], a[2], 0.0, 0.0, 0.0];
    match j.kind {
        TreeKind::Revolute => vec![turn(j.axis)],
        TreeKind::Spherical => vec![turn([1.0, 0.0, 0.0]), turn([0.0, 1.0, 0.0]), turn([0.0, 0.0, 1.0])],
        TreeKind::Prismatic => vec![[0.0, 0.0, 0.0, j.axis[0], j.axis[1], j.axis[2]]],
        TreeKind::Cylindrical => vec![turn(j.axis), [0.0, 0.0, 0.0, j.axis[0], j.axis[1], j.axis[2]]],
        // At θ = 0 only: `Builder::columns` turns the slides with θ.
        TreeKind::Planar => {
            let back = |x: [f64; 3]| [0, 1, 2].map(|i| (0..3).map(|r| j.rest[r][i] * x[r]).sum::<f64>());
            let [f, g] = j.plane.map(back);
            vec![[0.0, 0.0, 0.0, f[0], f[1], f[2]], [0.0, 0.0, 0.0, g[0], g[1], g[2]], turn(j.axis)]
        }
        TreeKind::Fixed => Vec::new(),
        // The point's velocity, then ω' (the runtime's order).
        TreeKind::Free => (0..6).map(|i| std::array::from_fn(|r| if r == (i + 3) % 6 { 1.0 } else { 0.0 })).collect(),
        // At θ₂ = 0 only: `Builder::columns` turns the first with θ₂.
        TreeKind::Universal => {
            let b = [0, 1, 2].map(|i| (0..3).map(|r| j.rest[r][i] * j.slide[r]).sum());
            vec![turn(b), turn(j.axis)]
        }
    }
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

/// Pass 1 of one joint: its transform, velocity, velocity-product
/// acceleration `c`, bias force `pᴬ` and link inertia.
struct Down {
    x: Transform,
    /// The joint's subspace columns (a universal's first turns with θ₂).
    s: Vec<V6>,
    vel: V6,
    c: V6,
    pa: V6,
    inertia: M6,
}

/// Pass 2's result for one joint: what it keeps, and, with a parent, the
/// articulated inertia and bias it hands on.
type UpPass = (Keep, Option<(M6, V6)>);

/// What pass 2 keeps of one joint for pass 3: `U`, `D⁻¹`, `u`; for a free
/// joint only its body's acceleration `Iᴬ⁻¹ (S τ − pᴬ)`.
struct Keep {
    u_cols: Vec<V6>,
    dinv: Vec<Vec<Id>>,
    u: Vec<Id>,
    free: Option<V6>,
}

impl Builder {
    /// The joint's subspace columns as nodes at `q` (its coordinates): a
    /// universal joint's first is `rot(h, θ₂)ᵀ R₀ᵀ s`, the rest numbers (`q`
    /// unread: empty will do).
    fn columns(&mut self, j: &Joint, q: &[Id]) -> Vec<V6> {
        if j.kind == TreeKind::Planar {
            // rot(h, θ)ᵀ R₀ᵀ f and the same of g, then the turn about h.
            let turn = self.turn(j.axis, q[2]);
            let zero = self.c(0.0);
            let mut cols: Vec<V6> = subspace(j).into_iter().map(|col| col.map(|x| self.c(x))).collect();
            for col in cols.iter_mut().take(2) {
                let slide = self.mtv(&turn, [col[3], col[4], col[5]]);
                *col = join([zero; 3], slide);
            }
            return cols;
        }
        if j.kind == TreeKind::Universal {
            let b = [0, 1, 2].map(|i| (0..3).map(|r| j.rest[r][i] * j.slide[r]).sum::<f64>());
            let turn = self.turn(j.axis, q[1]);
            let b = self.consts3(b);
            let first = self.mtv(&turn, b);
            let zero = self.c(0.0);
            let h = self.consts3(j.axis);
            return vec![join(first, [zero; 3]), join(h, [zero; 3])];
        }
        subspace(j).into_iter().map(|col| col.map(|x| self.c(x))).collect()
    }

    /// Pass 1 (root to leaves) of joint `j`: `e` is `E` when given as inputs
    /// (a kernel), else made from `q`.
    fn down(&mut self, s: &SceneDecl, j: &Joint, inbound: V3, q: &[Id], v: &[Id], parent: Option<V6>) -> Down {
        let zero = self.c(0.0);
        // Link frames: each body's axes, origin at its inbound joint point, so
        // that the joint's subspace is constant coordinate axes and the
        // offset between two joint points a constant of the parent.
        let (rel, r, rho_c, s_k, h) = match j.read {
            None => {
                // The offset between the joint points folded first (a number
                // when the parent's joint is one too), then slid.
                let r = match inbound.map(|i| self.g.as_const(i)) {
                    [Some(x), Some(y), Some(z)] => self.consts3([j.rho_p[0] - x, j.rho_p[1] - y, j.rho_p[2] - z]),
                    _ => {
                        let rho_p = self.consts3(j.rho_p);
                        self.sub3(rho_p, inbound)
                    }
                };
                let r = self.slid(j, r, q);
                let (rel, cols) = (self.relative(j, q), self.columns(j, q));
                (rel, r, self.consts3(j.rho_c), cols, self.consts3(j.axis))
            }
            Some(k) => {
                let at = k.to_string();
                let (rel, r, rho_c) = crate::tree::closure::read_joint(self, j.kind, k, q, &mut |b, p| b.geometry(p));
                let h = self.geometry(&["axis", &at]);
                let r = self.sub3(r, inbound);
                (rel, r, rho_c, self.read_columns(j.kind, &at, q), h)
            }
        };
        let e: M3 = [0, 1, 2].map(|r| [0, 1, 2].map(|c| rel[c][r]));
        let x = Transform { e, r };
        let mut vj = [zero; 6];
        for (i, col) in s_k.iter().enumerate() {
            for r in 0..6 {
                let t = self.g.mul(col[r], v[i]);
                vj[r] = self.g.add(vj[r], t);
            }
        }
        let vel = match parent {
            Some(pv) => {
                let from = self.motion(&x, pv);
                [0, 1, 2, 3, 4, 5].map(|r| self.g.add(from[r], vj[r]))
            }
            None => vj,
        };
        let (m, ic) = {
            let body = &s.bodies[j.child];
            self.body(&body.mass, &body.inertia)
        };
        let inertia = match j.read {
            None => self.link_inertia(m, &ic, j.rho_c.map(|x| -x)),
            Some(_) => {
                let c = rho_c.map(|x| self.g.neg(x));
                self.link_inertia_at(m, &ic, c)
            }
        };
        let iv = self.m6v(&inertia, vel);
        let pa = self.cross_force(vel, iv);
        let mut c = self.cross_motion(vel, vj);
        if j.kind == TreeKind::Planar {
            // Ṡ q̇ = θ̇ [0; (ẋ S₁ + ẏ S₂) × h]: the slides turn with θ.
            let slide: V3 = [3, 4, 5].map(|r| {
                let (x, y) = (self.g.mul(s_k[0][r], v[0]), self.g.mul(s_k[1][r], v[1]));
                self.g.add(x, y)
            });
            let turn = self.cross(slide, h);
            for (i, t) in turn.iter().enumerate() {
                let bias = self.g.mul(v[2], *t);
                c[3 + i] = self.g.add(c[3 + i], bias);
            }
        }
        if j.kind == TreeKind::Universal {
            // Ṡ q̇ = θ̇₁ θ̇₂ [S₁ × h; 0]: the first column turns with θ₂.
            let first = [s_k[0][0], s_k[0][1], s_k[0][2]];
            let turn = self.cross(first, h);
            let rates = self.g.mul(v[0], v[1]);
            for (i, t) in turn.iter().enumerate() {
                let bias = self.g.mul(rates, *t);
                c[i] = self.g.add(c[i], bias);
            }
        }
        Down { x, s: s_k, vel, c, pa, inertia }
    }

    /// Pass 2 (leaves to root) of joint `j`: what it keeps, and, with a
    /// parent, the articulated inertia and bias it hands on (parent frame).
    fn up(&mut self, j: &Joint, (s_k, x): (&[V6], &Transform), ia: &M6, pa: V6, c: V6, tau: &[Id]) -> UpPass {
        let zero = self.c(0.0);
        let dof = s_k.len();
        if j.kind == TreeKind::Free {
            // S is a permutation, so U D⁻¹ Uᵀ = Iᴬ: nothing of the inertia
            // moves on, only the joint force (the reaction), and the body's
            // acceleration does not depend on its parent's.
            let f = [0, 1, 2, 3, 4, 5].map(|r| {
                let col: Vec<Id> = s_k.iter().map(|c| c[r]).collect();
                self.dot(&col, tau)
            });
            let rhs = [0, 1, 2, 3, 4, 5].map(|r| self.g.sub(f[r], pa[r]));
            let acc = self.solve_spd(ia, rhs);
            let keep = Keep { u_cols: Vec::new(), dinv: Vec::new(), u: Vec::new(), free: Some(acc) };
            return (keep, j.parent.map(|_| ([[zero; 6]; 6], self.force_back(x, f))));
        }
        let u_cols: Vec<V6> = s_k.iter().map(|col| self.m6v(ia, *col)).collect();
        let mut d: Vec<Vec<Id>> = (0..dof).map(|r| (0..dof).map(|c| self.dot(&s_k[r], &u_cols[c])).collect()).collect();
        if j.armature != 0.0 {
            let a = self.c(j.armature);
            for (r, row) in d.iter_mut().enumerate() {
                row[r] = self.g.add(row[r], a);
            }
        }
        let dinv = self.inverse(&d);
        let u: Vec<Id> = (0..dof)
            .map(|i| {
                let sp = self.dot(&s_k[i], &pa);
                self.g.sub(tau[i], sp)
            })
            .collect();
        let keep = Keep { u_cols, dinv, u, free: None };
        if j.parent.is_none() {
            return (keep, None);
        }
        let Keep { u_cols, dinv, u, .. } = &keep;
        // U D⁻¹ (its columns), then Iᴬ − (U D⁻¹) Uᵀ and pᴬ + Iᵃ c + U D⁻¹ u.
        let ud: Vec<V6> = (0..dof)
            .map(|c| {
                [0, 1, 2, 3, 4, 5].map(|r| {
                    let row: Vec<Id> = (0..dof).map(|i| u_cols[i][r]).collect();
                    let col: Vec<Id> = (0..dof).map(|i| dinv[i][c]).collect();
                    self.dot(&row, &col)
                })
            })
            .collect();
        let mut outer: M6 = [[zero; 6]; 6];
        for r in 0..6 {
            for c in r..6 {
                let row: Vec<Id> = (0..dof).map(|i| ud[i][r]).collect();
                let col: Vec<Id> = (0..dof).map(|i| u_cols[i][c]).collect();
                let v = self.dot(&row, &col);
                outer[r][c] = v;
                outer[c][r] = v;
            }
        }
        let mut reduced = self.sub6(ia, &outer);
        // Exact zeros the graph cannot see (A − A A⁻¹ A): the reduced
        // inertia moves nothing along the joint's own freedoms.
        // (Known only for numbers: a read joint's subspace is not.)
        // (Not with an armature: D is then more than Sᵀ Iᴬ S.)
        let constant =
            !matches!(j.kind, TreeKind::Universal | TreeKind::Planar) && j.read.is_none() && j.armature == 0.0;
        for &i in selected(&subspace(j)).filter(|_| constant).iter().flatten() {
            reduced[i] = [zero; 6];
            for row in reduced.iter_mut() {
                row[i] = zero;
            }
        }
        let ic = self.m6v(&reduced, c);
        let udu = [0, 1, 2, 3, 4, 5].map(|r| {
            let row: Vec<Id> = (0..dof).map(|i| ud[i][r]).collect();
            self.dot(&row, u)
        });
        let pa_k = [0, 1, 2, 3, 4, 5].map(|r| {
            let t = self.g.add(pa[r], ic[r]);
            self.g.add(t, udu[r])
        });
        let back = self.inertia_back(x, &reduced);
        let fb = self.force_back(x, pa_k);
        (keep, Some((back, fb)))
    }

    /// Pass 3 (root to leaves) of joint `j`: its acceleration and `v̇`.
    fn out(&mut self, s_k: &[V6], x: &Transform, from: V6, c: V6, keep: &Keep) -> (V6, Vec<Id>) {
        let moved = self.motion(x, from);
        let mut a = [0, 1, 2, 3, 4, 5].map(|r| self.g.add(moved[r], c[r]));
        if let Some(acc) = keep.free {
            let rel = [0, 1, 2, 3, 4, 5].map(|r| self.g.sub(acc[r], a[r]));
            return (acc, s_k.iter().map(|col| self.dot(col, &rel)).collect());
        }
        let rhs: Vec<Id> = (0..s_k.len())
            .map(|i| {
                let ua = self.dot(&keep.u_cols[i], &a);
                self.g.sub(keep.u[i], ua)
            })
            .collect();
        let qdd: Vec<Id> = (0..s_k.len()).map(|r| self.dot(&keep.dinv[r], &rhs)).collect();
        for (i, col) in s_k.iter().enumerate() {
            for r in 0..6 {
                let t = self.g.mul(col[r], qdd[i]);
                a[r] = self.g.add(a[r], t);
            }
        }
        (a, qdd)
    }

    /// `(0, −g)`: the ground's acceleration.
    fn ground(&mut self, s: &SceneDecl) -> V6 {
        let gravity = self.quantity3(&s.gravity);
        let zero = self.c(0.0);
        join([zero; 3], gravity.map(|x| self.g.neg(x)))
    }
}

/// Where each joint's coordinates and velocities start.
pub(crate) fn offsets(joints: &[Joint]) -> (Vec<usize>, Vec<usize>) {
    kind_offsets(joints.iter().map(|j| j.kind))
}

/// Where each of a tree's joints' coordinates and velocities start, by kind.
pub(crate) fn kind_offsets(kinds: impl Iterator<Item = TreeKind>) -> (Vec<usize>, Vec<usize>) {
    let (mut qa, mut va) = (Vec::new(), Vec::new());
    let (mut at_q, mut at_v) = (0, 0);
    for kind in kinds {
        let (a, b) = kind.sizes();
        qa.push(at_q);
        va.push(at_v);
        at_q += a;
        at_v += b;
    }
    (qa, va)
}

impl Builder {
    /// The joint point its parent's link frame starts from: a number, or
    /// read when the parent's joint is.
    fn inbound(&mut self, joints: &[Joint], j: &Joint) -> V3 {
        match j.parent.map(|p| &joints[p]) {
            None => self.consts3([0.0; 3]),
            Some(Joint { read: Some(k), .. }) => self.geometry(&["rho_child", &k.to_string()]),
            Some(p) => self.consts3(p.rho_c),
        }
    }

    /// A read joint's subspace columns at `q` (`at`: its index in the
    /// tree), from its axes in `geometry`: as [`Builder::columns`] makes
    /// them from numbers.
    fn read_columns(&mut self, kind: TreeKind, at: &str, q: &[Id]) -> Vec<V6> {
        let zero = self.c(0.0);
        let h = self.geometry(&["axis", at]);
        let (turning, sliding) = (join(h, [zero; 3]), join([zero; 3], h));
        let rest_cols: [V3; 3] = [0, 1, 2].map(|c| self.geometry(&["rest", at, &c.to_string()]));
        let back = |b: &mut Builder, x: V3| -> V3 { [0, 1, 2].map(|c| b.dot(&rest_cols[c], &x)) };
        // `rot(h, θ)ᵀ x`: a column turned back by the joint's angle.
        let turned = |b: &mut Builder, x: V3, angle: Id| -> V3 {
            let (c, s) = (b.g.cos(angle), b.g.sin(angle));
            let rot = crate::tree::closure::rotation_about(b, h, c, s);
            b.mtv(&rot, x)
        };
        match kind {
            TreeKind::Revolute => vec![turning],
            TreeKind::Prismatic => vec![sliding],
            TreeKind::Cylindrical => vec![turning, sliding],
            TreeKind::Universal => {
                let s = self.geometry(&["axis_parent", at]);
                let b = back(self, s);
                let first = turned(self, b, q[1]);
                vec![join(first, [zero; 3]), turning]
            }
            TreeKind::Planar => {
                let mut cols: Vec<V6> = [0, 1]
                    .map(|i| {
                        let axis = self.geometry(&["plane", at, &i.to_string()]);
                        let b = back(self, axis);
                        join([zero; 3], turned(self, b, q[2]))
                    })
                    .to_vec();
                cols.push(turning);
                cols
            }
            // No geometry: numbers.
            TreeKind::Spherical | TreeKind::Free | TreeKind::Fixed => {
                subspace(&Joint { kind, ..Joint::spherical() }).into_iter().map(|col| col.map(|x| self.c(x))).collect()
            }
        }
    }

    /// [`Builder::link_inertia`] with `c` as nodes (a read joint's).
    fn link_inertia_at(&mut self, m: Id, ic: &M3, c: V3) -> M6 {
        let zero = self.c(0.0);
        let mut out = [[zero; 6]; 6];
        let cx = [[zero, self.g.neg(c[2]), c[1]], [c[2], zero, self.g.neg(c[0])], [self.g.neg(c[1]), c[0], zero]];
        for r in 0..3 {
            for s in 0..3 {
                let ccx = self.dot(&cx[r], &cx[s]);
                let shift = self.g.mul(ccx, m);
                out[r][s] = self.g.add(ic[r][s], shift);
                let mc = self.g.mul(cx[r][s], m);
                out[r][3 + s] = mc;
                out[3 + s][r] = mc;
            }
            out[3 + r][3 + r] = m;
        }
        out
    }
}

/// `fn forward_dynamics_into`: the whole tree in one straight line up to
/// [`LIMIT`] operations (a joint's points and axes folded where they are
/// numbers, read from `geometry` where they are fields), one kernel per
/// distinct joint and pass above it (numbers only).
pub fn method(s: &SceneDecl, edges: &[TreeEdge], nq: usize, nv: usize) -> Option<(TokenStream, usize)> {
    let joints = written(s, edges)?;
    inline(s, &joints, nq, nv).or_else(|| kernels(s, &joints, nq, nv))
}

/// The joints of a tree whose algorithms the derive writes: each with its
/// points and axes as numbers (folded), or read from the runtime's
/// `TreeGeometry` where they are fields.
pub(crate) fn written(s: &SceneDecl, edges: &[TreeEdge]) -> Option<Vec<Joint>> {
    let parents = parent_edges(s, edges);
    let read = |(k, (e, parent)): (usize, (&TreeEdge, Option<usize>))| {
        let dynamics = e.joint.map_or_else(Default::default, |i| s.joints[i].dynamics);
        joint(s, e, parent).unwrap_or(Joint {
            kind: e.kind,
            parent,
            child: e.ends.1,
            read: Some(k),
            armature: dynamics.armature,
            damping: dynamics.damping,
            stiffness: dynamics.stiffness,
            spring_rest: dynamics.spring_rest,
            ..Joint::spherical()
        })
    };
    Some(edges.iter().zip(parents).enumerate().map(read).collect())
}

/// The whole tree in one function.
fn inline(s: &SceneDecl, joints: &[Joint], nq: usize, nv: usize) -> Option<(TokenStream, usize)> {
    let mut b = Builder::new(Graph::new());
    let q: Vec<Id> = (0..nq).map(|i| b.g.param(format!("q_{i}"))).collect();
    let v: Vec<Id> = (0..nv).map(|i| b.g.param(format!("v_{i}"))).collect();
    let mut tau: Vec<Id> = (0..nv).map(|i| b.g.param(format!("tau_{i}"))).collect();
    let zero = b.c(0.0);
    let n = joints.len();
    let (qa, va) = offsets(joints);
    // A damped or sprung joint's force: `τ − damping · v − stiffness · (q − q₀)`.
    for (k, j) in joints.iter().enumerate() {
        for (i, resist) in passive(&mut b, j, &q[qa[k]..], &v[va[k]..]).into_iter().enumerate() {
            tau[va[k] + i] = b.g.sub(tau[va[k] + i], resist);
        }
    }
    let mut downs: Vec<Down> = Vec::with_capacity(n);
    for (k, j) in joints.iter().enumerate() {
        let parent = j.parent.map(|p| downs[p].vel);
        let (nqk, nvk) = j.kind.sizes();
        let inbound = b.inbound(joints, j);
        let d = b.down(s, j, inbound, &q[qa[k]..qa[k] + nqk], &v[va[k]..va[k] + nvk], parent);
        downs.push(d);
    }
    let mut ia: Vec<M6> = downs.iter().map(|d| d.inertia).collect();
    let mut pa: Vec<V6> = downs.iter().map(|d| d.pa).collect();
    let mut keeps: Vec<Option<Keep>> = (0..n).map(|_| None).collect();
    for k in (0..n).rev() {
        let j = &joints[k];
        let nvk = j.kind.sizes().1;
        let (keep, back) = b.up(j, (&downs[k].s, &downs[k].x), &ia[k], pa[k], downs[k].c, &tau[va[k]..va[k] + nvk]);
        if let (Some(p), Some((ib, fb))) = (j.parent, back) {
            ia[p] = b.add6(&ia[p], &ib);
            pa[p] = [0, 1, 2, 3, 4, 5].map(|r| b.g.add(pa[p][r], fb[r]));
        }
        keeps[k] = Some(keep);
    }
    let ground = b.ground(s);
    let mut acc: Vec<V6> = Vec::with_capacity(n);
    let mut out = vec![zero; nv];
    for (k, j) in joints.iter().enumerate() {
        let from = j.parent.map_or(ground, |p| acc[p]);
        let keep = keeps[k].as_ref()?;
        let (a, qdd) = b.out(&downs[k].s, &downs[k].x, from, downs[k].c, keep);
        for (i, x) in qdd.into_iter().enumerate() {
            out[va[k] + i] = x;
        }
        acc.push(a);
    }
    vector_method(&b, &out, ("forward_dynamics_into", "tau", "tau"), (s.bodies.len(), nq, nv))
}

/// `fn NAME(&self, q, v, THIRD: &[f64; NV], out: &mut [f64; NV]) -> bool`
/// writing the graph's `outputs` (the third input's nodes named `PREFIX_i`),
/// with its operation count; `None` above [`LIMIT`].
fn vector_method(
    b: &Builder,
    outputs: &[Id],
    (name, third, prefix): (&str, &str, &str),
    (nb, nq, nv): (usize, usize, usize),
) -> Option<(TokenStream, usize)> {
    let k = krate();
    let emitted = emit(&b.g, outputs, &scalar());
    if emitted.ops > LIMIT {
        return None;
    }
    let used = used_names(&b.g, &emitted);
    let binds = bindings(b, &used);
    let (qp, vp, tp) = (pattern(&used, "q", nq), pattern(&used, "v", nv), pattern(&used, prefix, nv));
    let (name, third) = (format_ident!("{name}"), format_ident!("{third}"));
    let (body, outputs, ops) = (emitted.body, emitted.outputs, emitted.ops);
    let method = quote! {
        fn #name(
            &self,
            geometry: &#k::relative::TreeGeometry<#nb>,
            q: &[f64; #nq],
            v: &[f64; #nv],
            #third: &[f64; #nv],
            out: &mut [f64; #nv],
        ) -> bool {
            let #qp = *q;
            let #vp = *v;
            let #tp = *#third;
            #(#binds)*
            #body
            *out = [#(#outputs),*];
            true
        }
    };
    Some((method, ops))
}

pub(crate) fn scalar() -> ScalarTy {
    ScalarTy { ty: quote!(f64), krate: krate(), concrete_f64: true }
}

pub(crate) fn used_names(g: &Graph, emitted: &crate::engine::emit::Emitted) -> std::collections::BTreeSet<String> {
    emitted.used_vars.iter().map(|v| g.vars()[v.0 as usize].name.clone()).collect()
}

/// `let p_3: f64 = self.mass;` for each field or named constant used.
pub(crate) fn bindings(b: &Builder, used: &std::collections::BTreeSet<String>) -> Vec<TokenStream> {
    b.bindings
        .iter()
        .filter(|(name, _)| used.contains(name))
        .map(|(name, expr)| {
            let name = format_ident!("{name}");
            quote!(let #name: f64 = #expr;)
        })
        .collect()
}

/// `[q_0, _, q_2]`: the inputs named `prefix_i`, `_` where unused.
pub(crate) fn pattern(used: &std::collections::BTreeSet<String>, prefix: &str, count: usize) -> TokenStream {
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
}

/// Index of `(r, c)`, `r ≤ c`, in a symmetric 6 × 6 matrix packed by rows.
fn packed(r: usize, c: usize) -> usize {
    let (r, c) = if r <= c { (r, c) } else { (c, r) };
    r * 6 - r * (r + 1) / 2 + c
}

/// One kernel's graph: inputs by port, outputs by port.
struct Kernel {
    b: Builder,
    inputs: Vec<(String, usize)>,
    outputs: Vec<(String, Vec<Id>)>,
}

impl Kernel {
    fn new() -> Self {
        Kernel { b: Builder::new(Graph::new()), inputs: Vec::new(), outputs: Vec::new() }
    }

    /// An input port of `n` numbers (`__name: &[f64; n]`).
    fn input(&mut self, name: &str, n: usize) -> Vec<Id> {
        self.inputs.push((name.to_string(), n));
        (0..n).map(|i| self.b.g.param(format!("__{name}_{i}"))).collect()
    }

    fn output(&mut self, name: &str, ids: Vec<Id>) {
        self.outputs.push((name.to_string(), ids));
    }

    fn m3(ids: &[Id]) -> M3 {
        [0, 1, 2].map(|r| [0, 1, 2].map(|c| ids[3 * r + c]))
    }

    fn m6(ids: &[Id]) -> M6 {
        [0, 1, 2, 3, 4, 5].map(|r| [0, 1, 2, 3, 4, 5].map(|c| ids[packed(r, c)]))
    }

    fn v6(ids: &[Id]) -> V6 {
        [0, 1, 2, 3, 4, 5].map(|i| ids[i])
    }

    fn pack(m: &M6) -> Vec<Id> {
        (0..6).flat_map(|r| (r..6).map(move |c| m[r][c])).collect()
    }

    /// `(params) { body }` without a name, for de-duplication; `None` when
    /// the kernel reads a field (kernels are free functions).
    fn print(self) -> Option<(TokenStream, usize)> {
        if !self.b.bindings.is_empty() {
            return None;
        }
        let all: Vec<Id> = self.outputs.iter().flat_map(|(_, ids)| ids.iter().copied()).collect();
        let emitted = emit(&self.b.g, &all, &scalar());
        let used = used_names(&self.b.g, &emitted);
        // A port both read and written is one `&mut` parameter, among the outputs.
        let written = |name: &String| self.outputs.iter().any(|(o, _)| o == name);
        let params_in = self.inputs.iter().filter(|(name, _)| !written(name)).map(|(name, n)| {
            let id = format_ident!("__{name}");
            quote!(#id: &[f64; #n])
        });
        let reads = self.inputs.iter().map(|(name, n)| {
            let (id, pat) = (format_ident!("__{name}"), pattern(&used, &format!("__{name}"), *n));
            quote!(let #pat = *#id;)
        });
        let params_out = self.outputs.iter().map(|(name, ids)| {
            let (id, n) = (format_ident!("__{name}"), ids.len());
            quote!(#id: &mut [f64; #n])
        });
        let mut exprs = emitted.outputs.into_iter();
        let writes: Vec<TokenStream> = self
            .outputs
            .iter()
            .map(|(name, ids)| {
                let id = format_ident!("__{name}");
                let values: Vec<TokenStream> = exprs.by_ref().take(ids.len()).collect();
                quote!(*#id = [#(#values),*];)
            })
            .collect();
        let body = emitted.body;
        Some((quote!((#(#params_in,)* #(#params_out),*) { #(#reads)* #body #(#writes)* }), emitted.ops))
    }
}

/// Kernels, one per distinct joint and pass, and the calls that run them.
struct Kernels {
    items: Vec<TokenStream>,
    by_text: std::collections::HashMap<String, syn::Ident>,
    ops: usize,
}

impl Kernels {
    /// The kernel's name, written once per distinct text.
    fn name(&mut self, pass: &str, kernel: Kernel) -> Option<syn::Ident> {
        let (rest, ops) = kernel.print()?;
        let text = rest.to_string();
        if let Some(name) = self.by_text.get(&text) {
            return Some(name.clone());
        }
        let name = format_ident!("{pass}_{}", self.items.len());
        self.ops += ops;
        self.items.push(quote!(#[inline(never)] fn #name #rest));
        self.by_text.insert(text, name.clone());
        Some(name)
    }
}

fn lit(n: usize) -> proc_macro2::Literal {
    proc_macro2::Literal::usize_unsuffixed(n)
}

/// Above [`LIMIT`]: one kernel per distinct joint and pass (a chain's
/// identical links share theirs), called in tree order from straight-line
/// code over per-joint arrays: the build grows with the distinct joints, the
/// code with the tree. Kernels read no fields (masses, inertias and gravity
/// must be numbers here): `None` otherwise.
fn kernels(s: &SceneDecl, joints: &[Joint], nq: usize, nv: usize) -> Option<(TokenStream, usize)> {
    // A kernel is shared by joints of one text, its subspace constant: a
    // universal joint's turns with θ₂ (the runtime's recursion runs such a
    // tree past the limit).
    // Nor with an armature or damping (the recursion carries them).
    let varying = |j: &Joint| matches!(j.kind, TreeKind::Universal | TreeKind::Planar | TreeKind::Free);
    let own = |j: &Joint| j.armature != 0.0 || j.damping != 0.0 || j.stiffness != 0.0;
    if joints.iter().any(|j| varying(j) || own(j) || j.read.is_some()) {
        return None;
    }
    let (qa, va) = offsets(joints);
    let mut ks = Kernels { items: Vec::new(), by_text: Default::default(), ops: 0 };
    let (mut decls, mut down_calls, mut up_calls, mut out_calls) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for (k, j) in joints.iter().enumerate() {
        decls.push(kernel_decls(k, j));
        down_calls.push(down_call(&mut ks, s, joints, k, (qa[k], va[k]))?);
        up_calls.push(up_call(&mut ks, joints, k, va[k])?);
        out_calls.push(out_call(&mut ks, s, joints, k)?);
    }
    up_calls.reverse();
    let outputs = joints.iter().enumerate().flat_map(|(k, j)| {
        let qdd = var("qdd", k);
        (0..j.kind.sizes().1).map(move |i| {
            let i = lit(i);
            quote!(#qdd[#i])
        })
    });
    let (items, ops) = (ks.items, ks.ops);
    let all = |prefix: &str, n: usize| {
        let ids = (0..n).map(|i| format_ident!("{prefix}_{i}"));
        quote!([#(#ids),*])
    };
    let (qp, vp, tp) = (all("q", nq), all("v", nv), all("tau", nv));
    let (k, nb) = (krate(), s.bodies.len());
    let method = quote! {
        fn forward_dynamics_into(
            &self,
            geometry: &#k::relative::TreeGeometry<#nb>,
            q: &[f64; #nq],
            v: &[f64; #nv],
            tau: &[f64; #nv],
            out: &mut [f64; #nv],
        ) -> bool {
            #(#items)*
            let #qp = *q;
            let #vp = *v;
            let #tp = *tau;
            #(#decls)*
            #(#down_calls)*
            #(#up_calls)*
            #(#out_calls)*
            *out = [#(#outputs),*];
            true
        }
    };
    Some((method, ops))
}

/// Joint `k`'s per-joint array of a kernel's output.
fn var(name: &str, k: usize) -> proc_macro2::Ident {
    format_ident!("{name}_{k}")
}

/// What pass 2 keeps for pass 3 of a joint with `nv` freedoms: `U`'s
/// columns, `D⁻¹` and `u`.
fn keep_len(nv: usize) -> usize {
    6 * nv + nv * nv + nv
}

/// Joint `j`'s origin in its parent's frame, from the parent's joint point.
fn joint_offset(joints: &[Joint], j: &Joint) -> [f64; 3] {
    let inbound = j.parent.map_or([0.0; 3], |p| joints[p].rho_c);
    [0, 1, 2].map(|i| j.rho_p[i] - inbound[i])
}

/// Joint `k`'s arrays: its frame, velocity, bias, articulated force and
/// inertia, what pass 2 keeps, its acceleration and `q̈`.
fn kernel_decls(k: usize, j: &Joint) -> TokenStream {
    let nvk = j.kind.sizes().1;
    let [e, vel, c, pa, ia, keep, acc, qdd] = ["e", "vel", "c", "pa", "ia", "keep", "acc", "qdd"].map(|n| var(n, k));
    let (nvk_l, keep_l) = (lit(nvk), lit(keep_len(nvk)));
    quote! {
        let (mut #e, mut #vel, mut #c, mut #pa) = ([0.0f64; 9], [0.0f64; 6], [0.0f64; 6], [0.0f64; 6]);
        let (mut #ia, mut #keep, mut #acc, mut #qdd) = ([0.0f64; 21], [0.0f64; #keep_l], [0.0f64; 6], [0.0f64; #nvk_l]);
    }
}

/// Pass 1 (root to tips) of joint `k`: its kernel and the call.
fn down_call(
    ks: &mut Kernels,
    s: &SceneDecl,
    joints: &[Joint],
    k: usize,
    (qa, va): (usize, usize),
) -> Option<TokenStream> {
    let j = &joints[k];
    let (nqk, nvk) = j.kind.sizes();
    let qs = (qa..qa + nqk).map(|i| format_ident!("q_{i}"));
    let vs = (va..va + nvk).map(|i| format_ident!("v_{i}"));
    let mut kd = Kernel::new();
    let (q_in, v_in) = (kd.input("q", nqk), kd.input("v", nvk));
    let parent = j.parent.map(|_| Kernel::v6(&kd.input("parent", 6)));
    let inbound = kd.b.inbound(joints, j);
    let d = kd.b.down(s, j, inbound, &q_in, &v_in, parent);
    kd.output("e", d.x.e.iter().flatten().copied().collect());
    kd.output("vel", d.vel.to_vec());
    kd.output("c", d.c.to_vec());
    kd.output("pa", d.pa.to_vec());
    kd.output("ia", Kernel::pack(&d.inertia));
    let name = ks.name("down", kd)?;
    let parent_arg = j.parent.map(|p| {
        let pv = var("vel", p);
        quote!(&#pv,)
    });
    let [e, vel, c, pa, ia] = ["e", "vel", "c", "pa", "ia"].map(|n| var(n, k));
    Some(quote!(#name(&[#(#qs),*], &[#(#vs),*], #parent_arg &mut #e, &mut #vel, &mut #c, &mut #pa, &mut #ia);))
}

/// Pass 2 (tips to root) of joint `k`: its kernel and the call, which
/// adds the joint's articulated inertia and force to its parent's.
fn up_call(ks: &mut Kernels, joints: &[Joint], k: usize, va: usize) -> Option<TokenStream> {
    let j = &joints[k];
    let nvk = j.kind.sizes().1;
    let taus = (va..va + nvk).map(|i| format_ident!("tau_{i}"));
    let mut ku = Kernel::new();
    let ia_in = Kernel::m6(&ku.input("ia", 21));
    let pa_in = Kernel::v6(&ku.input("pa", 6));
    let c_in = Kernel::v6(&ku.input("c", 6));
    let e_in = Kernel::m3(&ku.input("e", 9));
    let tau_in = ku.input("tau", nvk);
    let x = Transform { e: e_in, r: ku.b.consts3(joint_offset(joints, j)) };
    let parent_io = j.parent.map(|_| (Kernel::m6(&ku.input("ia_p", 21)), Kernel::v6(&ku.input("pa_p", 6))));
    let columns = ku.b.columns(j, &[]);
    let (kept, back) = ku.b.up(j, (&columns, &x), &ia_in, pa_in, c_in, &tau_in);
    let mut kept_ids: Vec<Id> = kept.u_cols.iter().flat_map(|col| col.iter().copied()).collect();
    kept_ids.extend(kept.dinv.iter().flatten().copied());
    kept_ids.extend(kept.u.iter().copied());
    ku.output("keep", kept_ids);
    if let (Some((ia_p, pa_p)), Some((ib, fb))) = (parent_io, back) {
        let sum = ku.b.add6(&ia_p, &ib);
        ku.output("ia_p", Kernel::pack(&sum));
        let pa_next: Vec<Id> = (0..6).map(|r| ku.b.g.add(pa_p[r], fb[r])).collect();
        ku.output("pa_p", pa_next);
    }
    let name = ks.name("up", ku)?;
    let to_parent = j.parent.map(|p| {
        let (iap, pap) = (var("ia", p), var("pa", p));
        quote!(, &mut #iap, &mut #pap)
    });
    let [ia, pa, c, e, keep] = ["ia", "pa", "c", "e", "keep"].map(|n| var(n, k));
    Some(quote!(#name(&#ia, &#pa, &#c, &#e, &[#(#taus),*], &mut #keep #to_parent);))
}

/// Pass 3 (root to tips) of joint `k`: its kernel and the call, which
/// gives its acceleration and `q̈`.
fn out_call(ks: &mut Kernels, s: &SceneDecl, joints: &[Joint], k: usize) -> Option<TokenStream> {
    let j = &joints[k];
    let nvk = j.kind.sizes().1;
    let mut ko = Kernel::new();
    let from = match j.parent {
        Some(_) => Kernel::v6(&ko.input("from", 6)),
        None => ko.b.ground(s),
    };
    let e_in = Kernel::m3(&ko.input("e", 9));
    let c_in = Kernel::v6(&ko.input("c", 6));
    let keep_in = ko.input("keep", keep_len(nvk));
    let x = Transform { e: e_in, r: ko.b.consts3(joint_offset(joints, j)) };
    let kept = Keep {
        u_cols: (0..nvk).map(|i| Kernel::v6(&keep_in[6 * i..6 * i + 6])).collect(),
        dinv: (0..nvk).map(|r| keep_in[6 * nvk + nvk * r..6 * nvk + nvk * r + nvk].to_vec()).collect(),
        u: keep_in[6 * nvk + nvk * nvk..].to_vec(),
        free: None,
    };
    let columns = ko.b.columns(j, &[]);
    let (a, qdd_ids) = ko.b.out(&columns, &x, from, c_in, &kept);
    ko.output("acc", a.to_vec());
    ko.output("qdd", qdd_ids);
    let name = ks.name("out", ko)?;
    let from_arg = j.parent.map(|p| {
        let ap = var("acc", p);
        quote!(&#ap,)
    });
    let [e, c, keep, acc, qdd] = ["e", "c", "keep", "acc", "qdd"].map(|n| var(n, k));
    Some(quote!(#name(#from_arg &#e, &#c, &#keep, &mut #acc, &mut #qdd);))
}

impl Builder {
    /// `M⁻¹ b` for a symmetric positive definite 6 × 6 `M` (a free joint's
    /// articulated inertia) by `M = L D Lᵀ`, `L` unit lower triangular: no
    /// square root, six divisions.
    fn solve_spd(&mut self, m: &M6, b: V6) -> V6 {
        let zero = self.c(0.0);
        let (mut l, mut ld, mut d) = ([[zero; 6]; 6], [[zero; 6]; 6], [zero; 6]);
        for j in 0..6 {
            let lj: Vec<Id> = l[j][..j].to_vec();
            let ldj: Vec<Id> = ld[j][..j].to_vec();
            let s = self.dot(&lj, &ldj);
            d[j] = self.g.sub(m[j][j], s);
            for i in j + 1..6 {
                let li: Vec<Id> = l[i][..j].to_vec();
                let s = self.dot(&li, &ldj);
                ld[i][j] = self.g.sub(m[i][j], s);
                l[i][j] = self.g.div(ld[i][j], d[j]);
            }
        }
        let mut y = [zero; 6];
        for i in 0..6 {
            let li: Vec<Id> = l[i][..i].to_vec();
            let s = self.dot(&li, &y[..i]);
            y[i] = self.g.sub(b[i], s);
        }
        let mut x = [zero; 6];
        for i in (0..6).rev() {
            let z = self.g.div(y[i], d[i]);
            let below: Vec<Id> = (i + 1..6).map(|k| l[k][i]).collect();
            let s = self.dot(&below, &x[i + 1..]);
            x[i] = self.g.sub(z, s);
        }
        x
    }

    /// The inverse of a 1 × 1, 2 × 2 or symmetric 3 × 3 matrix (adjugate
    /// over the determinant: one division).
    fn inverse(&mut self, d: &[Vec<Id>]) -> Vec<Vec<Id>> {
        if d.is_empty() {
            return Vec::new();
        }
        let one = self.c(1.0);
        if d.len() == 1 {
            return vec![vec![self.g.div(one, d[0][0])]];
        }
        if d.len() == 2 {
            // [d₁₁ −d₀₁; −d₁₀ d₀₀] / det (a universal joint's).
            let (x, y) = (self.g.mul(d[0][0], d[1][1]), self.g.mul(d[0][1], d[1][0]));
            let det = self.g.sub(x, y);
            let inv_det = self.g.div(one, det);
            let (a, b) = (self.g.mul(d[1][1], inv_det), self.g.mul(d[0][0], inv_det));
            let (c, e) = (self.g.mul(d[0][1], inv_det), self.g.mul(d[1][0], inv_det));
            return vec![vec![a, self.g.neg(c)], vec![self.g.neg(e), b]];
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

/// The inverse dynamics (recursive Newton–Euler) and the mass matrix
/// (composite rigid bodies) written out, each when it has at most
/// [`LIMIT`] operations: what a controller calls, with the same folding as
/// the forward dynamics.
pub fn controller_methods(s: &SceneDecl, edges: &[TreeEdge], nq: usize, nv: usize) -> TokenStream {
    let Some(joints) = written(s, edges) else { return TokenStream::new() };
    let mut out = TokenStream::new();
    out.extend(inverse_dynamics(s, &joints, nq, nv));
    out.extend(mass_matrix(s, &joints, nq, nv));
    out
}

/// Every joint's pass 1 on a fresh graph, `q` and `v` as inputs (`v` held at
/// zero when `moving` is false), and `q`, `v`.
fn downs(
    b: &mut Builder,
    s: &SceneDecl,
    joints: &[Joint],
    nq: usize,
    nv: usize,
    moving: bool,
) -> (Vec<Down>, Vec<Id>, Vec<Id>) {
    let q: Vec<Id> = (0..nq).map(|i| b.g.param(format!("q_{i}"))).collect();
    let v: Vec<Id> = if moving { (0..nv).map(|i| b.g.param(format!("v_{i}"))).collect() } else { vec![b.c(0.0); nv] };
    let (qa, va) = offsets(joints);
    let mut out: Vec<Down> = Vec::with_capacity(joints.len());
    for (k, j) in joints.iter().enumerate() {
        let parent = j.parent.map(|p| out[p].vel);
        let (nqk, nvk) = j.kind.sizes();
        let inbound = b.inbound(joints, j);
        let d = b.down(s, j, inbound, &q[qa[k]..qa[k] + nqk], &v[va[k]..va[k] + nvk], parent);
        out.push(d);
    }
    (out, q, v)
}

/// `fn inverse_dynamics_into`: `τ = Sᵀ f` with `f = I a + v ×* I v` summed
/// from the leaves.
fn inverse_dynamics(s: &SceneDecl, joints: &[Joint], nq: usize, nv: usize) -> Option<TokenStream> {
    let mut b = Builder::new(Graph::new());
    let rnea = newton_euler(&mut b, s, joints, nq, nv);
    let (method, ops) = vector_method(&b, &rnea.tau, ("inverse_dynamics_into", "vdot", "a"), (s.bodies.len(), nq, nv))?;
    let doc = format!(" The recursive Newton–Euler algorithm written out: {ops} operations.");
    Some(quote!(#[doc = #doc] #[inline] #method))
}

/// The inverse dynamics on `b`'s graph: its inputs `q_i`, `v_i` (the
/// accelerations are `a_i`) and the joint forces `τ`.
pub(crate) struct NewtonEuler {
    pub(crate) q: Vec<Id>,
    pub(crate) v: Vec<Id>,
    pub(crate) tau: Vec<Id>,
}

/// What joint `j` resists with, freedom by freedom: `damping · v` plus, on
/// a one-freedom joint, `stiffness · (q − q₀)` (`q`, `v` from its first
/// coordinate and freedom on). Zero nodes where it has neither.
fn passive(b: &mut Builder, j: &Joint, q: &[Id], v: &[Id]) -> Vec<Id> {
    let (damping, stiffness, rest) = (b.c(j.damping), b.c(j.stiffness), b.c(j.spring_rest));
    (0..j.kind.sizes().1)
        .map(|i| {
            let damped = b.g.mul(damping, v[i]);
            if i > 0 || j.stiffness == 0.0 {
                return damped;
            }
            let stretch = b.g.sub(q[0], rest);
            let sprung = b.g.mul(stiffness, stretch);
            b.g.add(damped, sprung)
        })
        .collect()
}

/// `τ(q, v, a)` on `b`'s graph: `τ = Sᵀ f` with `f = I a + v ×* I v`
/// summed from the leaves, armature and damping added.
pub(crate) fn newton_euler(b: &mut Builder, s: &SceneDecl, joints: &[Joint], nq: usize, nv: usize) -> NewtonEuler {
    let (d, q, v) = downs(b, s, joints, nq, nv, true);
    let vdot: Vec<Id> = (0..nv).map(|i| b.g.param(format!("a_{i}"))).collect();
    let (qa, va) = offsets(joints);
    let ground = b.ground(s);
    let mut acc: Vec<V6> = Vec::with_capacity(joints.len());
    let mut force: Vec<V6> = Vec::with_capacity(joints.len());
    for (k, j) in joints.iter().enumerate() {
        let from = j.parent.map_or(ground, |p| acc[p]);
        let moved = b.motion(&d[k].x, from);
        let mut a = [0, 1, 2, 3, 4, 5].map(|r| b.g.add(moved[r], d[k].c[r]));
        for (i, col) in d[k].s.iter().enumerate() {
            for r in 0..6 {
                let t = b.g.mul(col[r], vdot[va[k] + i]);
                a[r] = b.g.add(a[r], t);
            }
        }
        let ia = b.m6v(&d[k].inertia, a);
        force.push([0, 1, 2, 3, 4, 5].map(|r| b.g.add(ia[r], d[k].pa[r])));
        acc.push(a);
    }
    let zero = b.c(0.0);
    let mut tau = vec![zero; nv];
    for (k, j) in joints.iter().enumerate().rev() {
        let armature = b.c(j.armature);
        let resist = passive(b, j, &q[qa[k]..], &v[va[k]..]);
        for (i, col) in d[k].s.iter().enumerate() {
            let own = b.g.mul(armature, vdot[va[k] + i]);
            let t = b.dot(col, &force[k]);
            let t = b.g.add(t, own);
            tau[va[k] + i] = b.g.add(t, resist[i]);
        }
        if let Some(p) = j.parent {
            let back = b.force_back(&d[k].x, force[k]);
            force[p] = [0, 1, 2, 3, 4, 5].map(|r| b.g.add(force[p][r], back[r]));
        }
    }
    NewtonEuler { q, v, tau }
}

/// `fn mass_matrix_into`: composite inertias from the leaves, then each
/// freedom's force carried to the root.
fn mass_matrix(s: &SceneDecl, joints: &[Joint], nq: usize, nv: usize) -> Option<TokenStream> {
    let mut b = Builder::new(Graph::new());
    let (d, _, _) = downs(&mut b, s, joints, nq, nv, false);
    let (_, va) = offsets(joints);
    let mut ic: Vec<Rigid> = d.iter().map(|x| Rigid::of(&x.inertia)).collect();
    for (k, j) in joints.iter().enumerate().rev() {
        if let Some(p) = j.parent {
            let back = b.rigid_back(&d[k].x, &ic[k]);
            ic[p] = b.rigid_add(&ic[p], &back);
        }
    }
    let zero = b.c(0.0);
    let mut m = vec![vec![zero; nv]; nv];
    for k in 0..joints.len() {
        for (i, col) in d[k].s.iter().enumerate() {
            let c = va[k] + i;
            let mut f = b.rigid_mul(&ic[k], *col);
            let mut at = k;
            loop {
                for (r, row_col) in d[at].s.iter().enumerate() {
                    let value = b.dot(row_col, &f);
                    let r = va[at] + r;
                    m[r][c] = value;
                    m[c][r] = value;
                }
                let Some(p) = joints[at].parent else { break };
                f = b.force_back(&d[at].x, f);
                at = p;
            }
            let armature = b.c(joints[k].armature);
            m[c][c] = b.g.add(m[c][c], armature);
        }
    }
    let flat: Vec<Id> = m.iter().flatten().copied().collect();
    let emitted = emit(&b.g, &flat, &scalar());
    if emitted.ops > LIMIT {
        return None;
    }
    let used = used_names(&b.g, &emitted);
    let binds = bindings(&b, &used);
    let qp = pattern(&used, "q", nq);
    let (body, ops) = (emitted.body, emitted.ops);
    let mut outputs = emitted.outputs.into_iter();
    let rows: Vec<TokenStream> = (0..nv)
        .map(|_| {
            let row: Vec<TokenStream> = outputs.by_ref().take(nv).collect();
            quote!([#(#row),*])
        })
        .collect();
    let doc = format!(" The composite-rigid-body algorithm written out: {ops} operations.");
    let (k, nb) = (krate(), s.bodies.len());
    Some(quote! {
        #[doc = #doc]
        #[inline]
        fn mass_matrix_into(&self, geometry: &#k::relative::TreeGeometry<#nb>, q: &[f64; #nq], out: &mut [[f64; #nv]; #nv]) -> bool {
            let #qp = *q;
            #(#binds)*
            #body
            *out = [#(#rows),*];
            true
        }
    })
}
