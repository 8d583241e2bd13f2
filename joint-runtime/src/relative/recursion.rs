//! `∂τ/∂q` and `∂τ/∂v` by recursion, for any tree: Carpentier and
//! Mansard's derivatives of the recursive Newton–Euler algorithm (RSS 2018),
//! in the ground's frame, where moving freedom `m` by `ε` moves everything
//! it carries by the twist `ε Sₘ` and nothing else.
//!
//! What the generated straight line (`TreeScene::inverse_dynamics_derivatives_into`)
//! gives where the derive wrote one, and what every other tree gets: a
//! scene without `second_order`, or one past the straight line's limit.
//!
//! All spatial quantities are in Plücker coordinates at the ground's
//! origin, angular part first. For each freedom `m`: `Sₘ` its twist, `bₘ`
//! and `cₘ` the velocity and acceleration of the frame it moves from (a
//! universal or planar joint's later freedoms move from the earlier ones';
//! every other joint's freedoms all move from the parent, the tangent space
//! turning the child in its own frame), `aₘ` the velocity after it (after
//! the whole joint, for the latter). For each body `l` the Newton–Euler
//! force `f = Y a + v ×* Y v`. Moving freedom `m` gives, for each body it
//! carries,
//!
//! - `∂v = Sₘ × (v − bₘ)`, `∂a = Sₘ × (a − cₘ) − uₘ × (v − bₘ)` with `uₘ = Sₘ × bₘ`,
//! - `∂f = Sₘ ×* f + Y eₘ + B uₘ`, `eₘ = −Sₘ × cₘ + uₘ × bₘ`,
//!   `B = Y (v×) + (Y v)⊼ − (v×*) Y` (`u ×* h = −(h⊼) u`),
//!
//! and raising its velocity `∂v = Sₘ`, `∂f = −B Sₘ − Y wₘ`,
//! `wₘ = Sₘ × (bₘ + aₘ)`. Summed over a subtree these need only the
//! subtree's `F = Σ f`, `Yᶜ = Σ Y` and `Bᶜ = Σ B`; with `τₖ = Sₖᵀ Fₖ` and
//! `∂Sₖ = Sₘ × Sₖ` where `m` moves `k` (cancelling `Sₖᵀ (Sₘ ×* F)`):
//!
//! - `m` moves `k`: `∂τₖ/∂qₘ = Sₖᵀ (Yᶜ eₘ + Bᶜ uₘ)`, `Yᶜ`, `Bᶜ` of `k`'s child;
//! - `m` below `k`: `∂τₖ/∂qₘ = Sₖᵀ (Sₘ ×* Fₘ + Yᶜₘ eₘ + Bᶜₘ uₘ)`, `m`'s child's;
//! - `∂τₖ/∂vₘ = −Sₖᵀ (Bᶜ Sₘ + Yᶜ wₘ)` of the lower of the two children;
//!
//! zero on unrelated branches. Per body a few 6 × 6 products, per pair of
//! related freedoms a few 6-vector dot products: O(bodies × depth).

use nalgebra::{Matrix3, SVector, Vector3, Vector6};

use super::derivatives::InverseDerivatives;
use super::spatial::{cross_force, cross_motion, join, split};
use super::tangent::{at, get, put};
use super::topology::Tree;
use super::{TreeJointKind, TreeState};
use crate::BodyInertia;

/// `m`, a motion at a link frame (turn `r`, origin `o`), in the ground's frame.
#[inline(always)]
fn motion_in_ground(r: &Matrix3<f64>, o: &Vector3<f64>, m: &Vector6<f64>) -> Vector6<f64> {
    let (w, v) = split(m);
    let w = r * w;
    join(&w, &(r * v + o.cross(&w)))
}

/// A body's, or a subtree's sum of, spatial inertia `Y`, `B` and force `F`
/// in the ground's frame, by their parts. `Y = [A m[c]×; −m[c]× m 1]`
/// (`A` symmetric, `m c` the first moment). `B`'s right half is zero and
/// its lower left `2 [p]×`, `p` the linear momentum (`Y v`'s linear part),
/// so a sum keeps the upper left `T` and the momentum.
#[derive(Clone, Copy)]
struct Composite {
    a: Matrix3<f64>,
    moment: Vector3<f64>,
    mass: f64,
    t: Matrix3<f64>,
    momentum: Vector3<f64>,
    force: Vector6<f64>,
}

impl Composite {
    const ZERO: Composite = Composite {
        a: Matrix3::new(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
        moment: Vector3::new(0.0, 0.0, 0.0),
        mass: 0.0,
        t: Matrix3::new(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
        momentum: Vector3::new(0.0, 0.0, 0.0),
        force: Vector6::new(0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
    };

    /// `Y x`.
    #[inline(always)]
    fn y(&self, x: &Vector6<f64>) -> Vector6<f64> {
        let (w, v) = split(x);
        join(&(self.a * w + self.moment.cross(&v)), &(v * self.mass - self.moment.cross(&w)))
    }

    /// `B x = [T ω; 2 p × ω]`.
    #[inline(always)]
    fn b(&self, x: &Vector6<f64>) -> Vector6<f64> {
        let w = x.fixed_rows::<3>(0).into_owned();
        join(&(self.t * w), &(self.momentum.cross(&w) * 2.0))
    }

    /// `Bᵀ x = [Tᵀ ω + 2 v × p; 0]`.
    #[inline(always)]
    fn b_transposed(&self, x: &Vector6<f64>) -> Vector6<f64> {
        let (w, v) = split(x);
        join(&(self.t.transpose() * w + v.cross(&self.momentum) * 2.0), &Vector3::zeros())
    }

    #[inline(always)]
    fn add(&mut self, other: &Composite) {
        self.a += other.a;
        self.moment += other.moment;
        self.mass += other.mass;
        self.t += other.t;
        self.momentum += other.momentum;
        self.force += other.force;
    }
}

/// Whether a joint's freedoms move one after another (a universal joint's
/// second axis is the child's, carried by the first; a planar joint turns
/// about a point its slides carry) rather than all from the parent.
fn chained(kind: TreeJointKind) -> bool {
    matches!(kind, TreeJointKind::Universal | TreeJointKind::Planar)
}

/// Each freedom's twist `S`, what its columns need (`u`, `e`, `w`), and
/// the joint it belongs to.
struct Freedoms<const NV: usize> {
    s: [Vector6<f64>; NV],
    u: [Vector6<f64>; NV],
    e: [Vector6<f64>; NV],
    w: [Vector6<f64>; NV],
    joint: [usize; NV],
}

// Every access by an index the tree holds goes through `get`: the indices
// are checked by `Tree::new`, and an access that cannot go out of range
// leaves no panic path for the no-panic proof to find.

/// The ground's frame: no turn, at the origin.
fn frames_root() -> (Matrix3<f64>, Vector3<f64>) {
    (Matrix3::identity(), Vector3::zeros())
}

/// `a · b`, as a sum the no-panic proof reads through.
fn dot6(a: &Vector6<f64>, b: &Vector6<f64>) -> f64 {
    a.iter().zip(b.iter()).map(|(x, y)| x * y).sum()
}

/// `x[i]`, or zero past the end.
fn at6<const N: usize>(x: &[Vector6<f64>; N], i: usize) -> Vector6<f64> {
    x.get(i).copied().unwrap_or_else(Vector6::zeros)
}

impl<const NB: usize, const NQ: usize, const NV: usize> Tree<NB, NQ, NV> {
    /// `τ`, `∂τ/∂q` and `∂τ/∂v` of [`inverse_dynamics`](Self::inverse_dynamics)
    /// at `state` and `vdot` into `out` (its `d_a` untouched): see the module.
    pub(crate) fn recursive_derivatives(
        &self,
        state: &TreeState<NQ, NV>,
        vdot: &SVector<f64, NV>,
        out: &mut InverseDerivatives<NV>,
    ) {
        self.derivatives_pass(state, vdot, &self.gravity, true, out);
    }

    /// `∂(M(q) w)/∂q` (tangent columns) into `out.d_q`: the pass above at
    /// rest with accelerations `w`, no gravity and no springs, which leaves
    /// exactly the mass matrix's part (an impact's `∂(M Δv)/∂q`, in one
    /// pass where differencing two inverse dynamics' derivatives takes two).
    pub(crate) fn mass_product_derivative(
        &self,
        q: &SVector<f64, NQ>,
        w: &SVector<f64, NV>,
        out: &mut InverseDerivatives<NV>,
    ) {
        let rest = TreeState { q: *q, v: SVector::zeros(), t: 0.0 };
        self.derivatives_pass(&rest, w, &Vector3::zeros(), false, out);
    }

    /// The derivatives' pass under `gravity`, the joints' springs included
    /// or not.
    fn derivatives_pass(
        &self,
        state: &TreeState<NQ, NV>,
        vdot: &SVector<f64, NV>,
        gravity: &Vector3<f64>,
        springs: bool,
        out: &mut InverseDerivatives<NV>,
    ) {
        let (fr, subtrees) = self.ground_frame_pass(state, vdot, gravity);
        // Per freedom `k`: `Yᶜᵀ Sₖ`, `Bᶜᵀ Sₖ` of its child's subtree, and the
        // columns it gives the rows above it (`g`: `∂/∂q`, `h`: `∂/∂v`).
        let zero = [Vector6::zeros(); NV];
        let (mut ys, mut bs, mut g, mut h) = (zero, zero, zero, zero);
        let rows = ys.iter_mut().zip(bs.iter_mut()).zip(g.iter_mut().zip(h.iter_mut())).zip(out.tau.iter_mut());
        for (m, (((ys, bs), (g, h)), tau)) in rows.enumerate() {
            let joint = fr.joint.get(m).copied().unwrap_or(NB);
            let c = subtrees.get(joint).copied().unwrap_or(Composite::ZERO);
            let s = at6(&fr.s, m);
            *ys = c.y(&s);
            *bs = c.b_transposed(&s);
            *g = cross_force(&s, &c.force) + c.y(&at6(&fr.e, m)) + c.b(&at6(&fr.u, m));
            *h = c.b(&s) + c.y(&at6(&fr.w, m));
            let position = self.q_at.get(joint).map_or(0.0, |&at| get(&state.q, at));
            *tau = dot6(&s, &c.force) + self.own_force(joint, get(vdot, m), get(&state.v, m), position);
        }
        out.d_q.fill(0.0);
        out.d_v.fill(0.0);
        for m in 0..NV {
            let (s, e, u, w) = (at6(&fr.s, m), at6(&fr.e, m), at6(&fr.u, m), at6(&fr.w, m));
            let (ys_m, bs_m, g_m, h_m) = (at6(&ys, m), at6(&bs, m), at6(&g, m), at6(&h, m));
            let joint = fr.joint.get(m).copied().unwrap_or(NB);
            let chain = self.joints.get(joint).is_some_and(|j| chained(j.kind));
            for k in self.freedoms_of(joint) {
                // Freedom `m` of the same joint moves `k` unless the joint is a
                // chain and `m` comes after `k`.
                let (ys_k, bs_k) = (at6(&ys, k), at6(&bs, k));
                let d_q = if !chain || m <= k { dot6(&ys_k, &e) + dot6(&bs_k, &u) } else { dot6(&at6(&fr.s, k), &g_m) };
                put(&mut out.d_q, k, m, d_q);
                put(&mut out.d_v, k, m, -(dot6(&bs_k, &s) + dot6(&ys_k, &w)));
            }
            let mut above = self.parent.get(joint).copied().flatten();
            while let Some(ja) = above {
                for k in self.freedoms_of(ja) {
                    let s_k = at6(&fr.s, k);
                    put(&mut out.d_q, k, m, dot6(&s_k, &g_m));
                    put(&mut out.d_v, k, m, -dot6(&s_k, &h_m));
                    put(&mut out.d_q, m, k, dot6(&ys_m, &at6(&fr.e, k)) + dot6(&bs_m, &at6(&fr.u, k)));
                    put(&mut out.d_v, m, k, -(dot6(&bs_m, &s_k) + dot6(&ys_m, &at6(&fr.w, k))));
                }
                above = self.parent.get(ja).copied().flatten();
            }
            let (damping, stiffness) = self.joints.get(joint).map_or((0.0, 0.0), |j| (j.damping, j.stiffness));
            let stiffness = if springs { stiffness } else { 0.0 };
            let diagonal = at(&out.d_v, m, m) + damping;
            put(&mut out.d_v, m, m, diagonal);
            // A spring's joint has one freedom, its tangent the coordinate.
            let diagonal = at(&out.d_q, m, m) + stiffness;
            put(&mut out.d_q, m, m, diagonal);
        }
    }

    /// Joint `k`'s freedoms, as indices into `v` (none for a `k` out of range).
    fn freedoms_of(&self, k: usize) -> core::ops::Range<usize> {
        let first = self.v_at.get(k).copied().unwrap_or(NV);
        first..first + self.joints.get(k).map_or(0, |j| j.kind.freedoms())
    }

    /// `τ` and `∂τ/∂q` (tangent columns) of the gravity compensation's joint
    /// forces `Gᶜ(q)` into `out` (nothing without compensation), in closed
    /// form: with `μ = c m` held at each centre `x`, a subtree's wrench about
    /// the ground's origin is `W = (−X × g, −M g)` (`M = Σ μ`, `X = Σ μ x`),
    /// `Gᶜᵢ = sᵢᵀ W`, and freedom `j` moves `sᵢ` by `sⱼ × sᵢ` (when it moves
    /// the axis) and the centres it carries by `ω × x + v`, so
    /// `∂W = (−(ω × X + v M) × g, 0)` over those. O(NV²), every index
    /// through `get`.
    #[inline(always)]
    pub(crate) fn compensation_derivatives(&self, q: &SVector<f64, NQ>, out: &mut InverseDerivatives<NV>) {
        let Some(held) = &self.compensation else { return };
        let g = self.gravity;
        let (mut frames, mut s, mut of) =
            ([(Matrix3::identity(), Vector3::zeros()); NB], [Vector6::zeros(); NV], [NB; NV]);
        let (mut mass, mut moment) = ([0.0; NB], [Vector3::zeros(); NB]);
        for k in 0..NB {
            let x = self.transform(k, q);
            let (rp, op) = self.parent[k].and_then(|p| frames.get(p).copied()).unwrap_or(frames_root());
            let (r, o) = (rp * x.e.transpose(), op + rp * x.r);
            frames[k] = (r, o);
            let subspace = self.subspace_at(k, q);
            for (c, col) in subspace.cols.iter().enumerate().take(subspace.n) {
                let m = self.v_at[k] + c;
                if let (Some(slot), Some(joint)) = (s.get_mut(m), of.get_mut(m)) {
                    (*slot, *joint) = (motion_in_ground(&r, &o, col), k);
                }
            }
            let child = self.joints[k].child;
            let mu = held.get(child).copied().unwrap_or(0.0) * self.mass.get(child).map_or(0.0, |b| b.mass);
            (mass[k], moment[k]) = (mu, (o - r * self.joints[k].rho_child) * mu);
        }
        for k in (0..NB).rev() {
            let (m, x) = (mass[k], moment[k]);
            let p = self.parent[k].unwrap_or(NB);
            if let (Some(pm), Some(px)) = (mass.get_mut(p), moment.get_mut(p)) {
                (*pm, *px) = (*pm + m, *px + x);
            }
        }
        // Whether joint `a` is joint `b` or one of its ancestors.
        let above = |a: usize, b: usize| {
            let mut at = Some(b);
            while let Some(j) = at {
                if j == a {
                    return true;
                }
                at = self.parent.get(j).copied().flatten();
            }
            false
        };
        let subtree =
            |k: usize| (mass.get(k).copied().unwrap_or(0.0), moment.get(k).copied().unwrap_or_else(Vector3::zeros));
        for (i, (&ki, si)) in of.iter().zip(&s).enumerate() {
            let (m_i, x_i) = subtree(ki);
            let w = join(&(-x_i.cross(&g)), &(-g * m_i));
            if let Some(tau) = out.tau.get_mut(i) {
                *tau = dot6(si, &w);
            }
            let chain = self.joints.get(ki).is_some_and(|j| chained(j.kind));
            for (j, (&kj, sj)) in of.iter().zip(&s).enumerate() {
                let moves_axis = if kj == ki { !chain || j < i } else { above(kj, ki) };
                let mut d = if moves_axis { dot6(&cross_motion(sj, si), &w) } else { 0.0 };
                // The centres freedom `j` carries among those under `i`.
                let carried = if above(kj, ki) {
                    Some(ki)
                } else if above(ki, kj) {
                    Some(kj)
                } else {
                    None
                };
                if let Some(set) = carried {
                    let ((m_s, x_s), (omega, v)) = (subtree(set), split(sj));
                    let dx = omega.cross(&x_s) + v * m_s;
                    d += dot6(si, &join(&(-dx.cross(&g)), &Vector3::zeros()));
                }
                put(&mut out.d_q, i, j, d);
            }
        }
    }

    /// A freedom of joint `k`'s own force: armature times its acceleration,
    /// damping times its rate, stiffness times its stretch (`position`, the
    /// joint's first coordinate: a spring's joint has only that one).
    fn own_force(&self, k: usize, acceleration: f64, rate: f64, position: f64) -> f64 {
        self.joints.get(k).map_or(0.0, |j| {
            let spring = if j.stiffness != 0.0 { j.stiffness * (position - j.spring_rest) } else { 0.0 };
            j.armature * acceleration + j.damping * rate + spring
        })
    }

    /// Root to leaves, each freedom's twist and frames in the ground's
    /// frame and each body's Newton–Euler force and `Y`, `B`; then leaves to
    /// root, the subtrees' sums (in one frame, a sum is all a subtree needs).
    fn ground_frame_pass(
        &self,
        state: &TreeState<NQ, NV>,
        vdot: &SVector<f64, NV>,
        gravity: &Vector3<f64>,
    ) -> (Freedoms<NV>, [Composite; NB]) {
        let zero = Vector6::zeros();
        let mut fr = Freedoms { s: [zero; NV], u: [zero; NV], e: [zero; NV], w: [zero; NV], joint: [0; NV] };
        let mut sub = [Composite::ZERO; NB];
        // Each link frame's turn and origin, its body's velocity and acceleration.
        let ground = (Matrix3::identity(), Vector3::zeros(), zero, join(&Vector3::zeros(), &(-gravity)));
        let mut frames = [ground; NB];
        for k in 0..NB {
            let x = self.transform(k, &state.q);
            let (rp, op, vp, ap) = self.parent[k].and_then(|p| frames.get(p).copied()).unwrap_or(ground);
            let (r, o) = (rp * x.e.transpose(), op + rp * x.r);
            let (mut v, mut a) = (vp, ap);
            let subspace = self.subspace_at(k, &state.q);
            let chain = chained(self.joints[k].kind);
            // The frame each freedom moves from: the running one along a chain.
            let mut base = [zero; 6];
            for (c, base) in base.iter_mut().enumerate().take(subspace.n) {
                let m = self.v_at[k] + c;
                let s = motion_in_ground(&r, &o, &subspace.cols[c]);
                let (b, cm) = if chain { (v, a) } else { (vp, ap) };
                let (qd, qdd) = (get(&state.v, m), get(vdot, m));
                let u = cross_motion(&s, &b);
                a += s * qdd + cross_motion(&b, &(s * qd));
                v += s * qd;
                *base = b;
                let e = cross_motion(&u, &b) - cross_motion(&s, &cm);
                fr.record(m, (s, u, e), k);
            }
            for (c, b) in base.iter().enumerate().take(subspace.n) {
                let m = self.v_at[k] + c;
                let s = at6(&fr.s, m);
                let after = if chain { b + s * get(&state.v, m) } else { v };
                if let Some(w) = fr.w.get_mut(m) {
                    *w = cross_motion(&s, &(b + after));
                }
            }
            sub[k] = self.composite(k, (&r, &o), (&v, &a));
            frames[k] = (r, o, v, a);
        }
        for k in (0..NB).rev() {
            if let Some(p) = self.parent[k] {
                let c = sub[k];
                if let Some(parent) = sub.get_mut(p) {
                    parent.add(&c);
                }
            }
        }
        (fr, sub)
    }

    /// Joint `k`'s child as a [`Composite`], its link frame turned by `r`
    /// with origin `o` (the body's axes are the link frame's, its centre at
    /// `−ρ_child` there), moving at `v`, accelerating at `a`:
    /// `A = R I Rᵀ − m [c]×²`, `f = Y a + v ×* Y v`, and
    /// `T = A [ω]× − [ω]× A + m ([c]× [ν]× + [ν]× [c]×) + [n]×` for
    /// `Y v = (n, ·)`, `v = (ω, ν)`.
    #[inline(always)]
    fn composite(
        &self,
        k: usize,
        (r, o): (&Matrix3<f64>, &Vector3<f64>),
        (v, a): (&Vector6<f64>, &Vector6<f64>),
    ) -> Composite {
        let child = self.joints[k].child;
        let body = self.mass.get(child).copied().unwrap_or(BodyInertia { mass: 0.0, inertia: Matrix3::zeros() });
        let m = body.mass;
        let centre = o - r * self.joints[k].rho_child;
        let c = centre.cross_matrix();
        let mut out = Composite {
            a: r * body.inertia * r.transpose() - c * c * m,
            moment: centre * m,
            mass: m,
            t: Matrix3::zeros(),
            momentum: Vector3::zeros(),
            force: Vector6::zeros(),
        };
        let yv = out.y(v);
        out.force = out.y(a) + cross_force(v, &yv);
        out.momentum = yv.fixed_rows::<3>(3).into_owned();
        let (w, nu) = split(v);
        let aw = out.a * w.cross_matrix();
        let cn = nu * centre.transpose();
        let sym = (cn + cn.transpose() - Matrix3::from_diagonal_element(2.0 * centre.dot(&nu))) * m;
        out.t = aw + aw.transpose() + sym + yv.fixed_rows::<3>(0).into_owned().cross_matrix();
        out
    }
}

impl<const NV: usize> Freedoms<NV> {
    /// Freedom `m`'s `S`, `u`, `e`, and its joint `k`.
    fn record(&mut self, m: usize, (s, u, e): (Vector6<f64>, Vector6<f64>, Vector6<f64>), k: usize) {
        if m < NV {
            (self.s[m], self.u[m], self.e[m], self.joint[m]) = (s, u, e, k);
        }
    }
}
