//! Loops in relative coordinates: every joint outside the spanning tree (one
//! that closes a loop, or of a kind without a tree parametrisation) keeps
//! its rows as constraints. They are lowered, exactly as in absolute
//! coordinates (`lower::lower_rows`), onto the bodies' frames as the tree's
//! kinematics makes them: each body's rotation `A_child = A_parent R(q)` and
//! centre `r_child = r_parent + A_parent ρ_parent − A_child ρ_child`,
//! expressions of the joint coordinates with `θ̇ = v` and
//! `ṗ = ½ p ⊗ (0, ω')`. The engine then differentiates them in the tree's
//! own coordinates: `Φ(q, t)`, `J = ∂Φ̇/∂v`, `γ = −dΦ̇/dt` (v held) and `Φ_t`
//! (`TreeScene::closure_rows`). No derivative is written by hand. A tree
//! joint's points and axes are folded into the rows where they are numbers and
//! read from the runtime's `TreeGeometry` where they are fields (`read_joint`,
//! which `aba` shares). A robot file's couplings (a follower joint, URDF's
//! `<mimic>`) join the same rows as `q_f − (m q_l + o)`, linear in the
//! coordinates.
//!
//! A row that the tree keeps by construction folds to a constant: a planar
//! loop's out-of-plane rows, when every joint's axis is normal to the
//! plane. A zero is dropped at compile time (the four-bar's revolute keeps
//! two of its five rows); any other constant means the loop cannot close,
//! and is an error at the joint.

use proc_macro2::{Span, TokenStream};
use quote::quote;

use crate::engine::graph::Id;
use crate::front::scene::SceneDecl;
use crate::front::tree::{TreeEdge, TreeKind, closures};
use crate::generate::{krate, matrix_tokens, print_none, vector_tokens};
use crate::kinematics::{Input, Kinematics, V3};
use crate::lower::{Block, Derived, Naming, lower_rows, param_nodes};
use crate::second_order::SecondOrderNodes;
use crate::tree::aba::{Builder, joint, kind_offsets, parent_edges};
use crate::tree::wrench::BodyRows;

/// A tree's closures derived in its coordinates, their row blocks, their
/// second-order terms (what the constrained dynamics' derivatives take) and
/// their rows on their bodies (what their reactions take).
pub struct Loops {
    /// The rows in the tree's coordinates: `Φ`, `J`, `γ`, `Φ_t`.
    pub derived: Derived,
    /// Each closing joint's, coupling's and contact's rows among them.
    pub blocks: Vec<Block>,
    /// `K = ∂(Jᵀλ)/∂q` and the other second-order terms.
    pub second: Option<SecondOrderNodes>,
    /// The same rows on their two bodies' `ṙ, ω'` (`wrench.rs`).
    pub bodies: BodyRows,
}

/// How a loop is closed: what `wrench.rs` lowers again on the bodies.
pub enum Closing {
    /// A soft weld's six rows (`weld_rows`) between its bodies' points.
    Weld { bodies: [Option<usize>; 2], points: [V3Num; 2], torquescale: f64 },
    /// Joint `joint`'s catalogue rows, those in `kept` (the tree keeps the others).
    Rows { joint: usize, kept: Vec<usize> },
}

/// A constant row at most this far from zero is one the tree keeps (a
/// planar loop's out-of-plane rows fold to exact zeros; this allows for a
/// geometry whose numbers do not close exactly in binary).
const KEPT: f64 = 1e-12;

/// The closures' rows derived in the tree's coordinates, and each joint's
/// block of them; `None` for a tree without closures.
pub fn derive(s: &SceneDecl, edges: &[TreeEdge], (nq, nv): (usize, usize)) -> syn::Result<Option<Loops>> {
    let loops = closures(&s.joints, edges);
    if loops.is_empty() && s.couplings.is_empty() && s.contacts.is_empty() {
        return Ok(None);
    }
    let mut k = Kinematics::tree(nq, nv);
    let poses = frames(&mut k, s, edges);
    let mut bindings = Vec::new();
    let (mut phi, mut blocks) = (Vec::new(), Vec::new());
    let mut errors = crate::front::context::Errors::new();
    let mut closings = Vec::new();
    for &i in &loops {
        let j = &s.joints[i];
        // A soft weld's rows are MuJoCo's, not the catalogue's (`weld_rows`).
        if let Some((points, soft)) = s.soft.iter().find(|w| w.joint == j.label()).and_then(|w| Some((w.weld?, w.soft)))
        {
            let start = phi.len();
            let bodies = [j.bodies[0], j.bodies[1]];
            phi.extend(weld_rows(&mut k, &poses, bodies, points, soft.torquescale));
            blocks.push(Block { name: j.label(), start, rows: 6 });
            closings.push(Closing::Weld { bodies, points, torquescale: soft.torquescale });
            continue;
        }
        k.connect(j.bodies[0], j.bodies[1]);
        let prefix = j.prefix();
        let values = param_nodes(&mut k, j.kind, &j.params, Naming::ByField { joint: &prefix }, &mut bindings);
        let rows = lower_rows(&mut k, j.kind, &values, &[], j.kind_span);
        let start = phi.len();
        let mut kept = Vec::new();
        for (n, &row) in rows.phi.iter().enumerate() {
            match k.g.as_const(row) {
                Some(c) if c.abs() <= KEPT => {}
                Some(c) => errors.at(
                    j.name.span(),
                    format!(
                        "joint `{}` cannot close its loop: its row {} is {c} at every position of the tree; \
                         expected joint points and axes that meet",
                        j.label(),
                        n + 1
                    ),
                ),
                None => {
                    phi.push(row);
                    kept.push(n);
                }
            }
        }
        blocks.push(Block { name: j.label(), start, rows: phi.len() - start });
        closings.push(Closing::Rows { joint: i, kept });
    }
    // A follower's row: `q_f − (m q_l + o)`, linear in the coordinates.
    let (qa, _) = kind_offsets(edges.iter().map(|e| e.kind));
    for c in &s.couplings {
        let at = |joint: usize| edges.iter().position(|e| e.joint == Some(joint)).map(|n| k.coords[qa[n]]);
        let (Some(follower), Some(leader)) = (at(c.follower), at(c.leader)) else {
            let message =
                format!("joint `{}` follows another, but one of them closes a loop; expected tree joints", c.name);
            errors.at(s.joints[c.follower].name.span(), message);
            continue;
        };
        let (m, o) = (k.g.constant(c.multiplier), k.g.constant(c.offset));
        let led = k.g.mul(m, leader);
        let target = k.g.add(led, o);
        blocks.push(Block { name: c.name.clone(), start: phi.len(), rows: 1 });
        phi.push(k.g.sub(follower, target));
    }
    errors.finish()?;
    let (mut jacobian, mut gamma, mut phi_t) = (Vec::new(), Vec::new(), Vec::new());
    for &row in &phi {
        let d = k.derive_row(row, None).map_err(|m| syn::Error::new(Span::call_site(), m))?;
        jacobian.push(d.jacobian);
        gamma.push(d.gamma);
        phi_t.push(d.phi_t);
    }
    // Contacts: rows at the velocity level, no position (`contact.rs`).
    for c in &s.contacts {
        blocks.push(Block { name: c.name.to_string(), start: phi.len(), rows: c.rows() });
        for (row, g) in crate::tree::contact::rows(&mut k, &poses, c) {
            let zero = k.g.zero();
            phi.push(zero);
            phi_t.push(zero);
            jacobian.push(row);
            gamma.push(g);
        }
    }
    if phi.is_empty() {
        return Ok(None);
    }
    let mut d = Derived { kinematics: k, phi, phi_t, jacobian, gamma, bindings, singularity: None };
    let second = crate::second_order::derive(&mut d, true, None).dense;
    let bodies = crate::tree::wrench::derive(s, &closings)?;
    Ok(Some(Loops { derived: d, blocks, second, bodies }))
}

/// A soft weld's six rows as MuJoCo 4.0 makes them: its points apart
/// (`p₁ − p₂`, the world's axes), then its orientation error, the vector
/// part of the quaternion of `E = A₂ᵀ A₁` times `torquescale`:
/// `vee(E − Eᵀ) / (4w)`, `w = ½ √(1 + tr E)`. MuJoCo's quaternion is
/// `q̄₂ q₁ q_rel` in its bodies' frames; ours differ from them by constant
/// turns, which `q_rel` (the file's pose) cancels up to one conjugation:
/// the same rows turned, which leaves its accelerations as they are (the
/// three share their weight and the impedance reads their norm). No row is
/// dropped: a row the tree keeps by construction is a zero with a zero `J`.
pub(crate) fn weld_rows(
    k: &mut Kinematics,
    poses: &[crate::tree::contact::Pose],
    bodies: [Option<usize>; 2],
    points: [V3Num; 2],
    torquescale: f64,
) -> Vec<Id> {
    // Its points apart: each `r + A ρ`, as a contact's point is.
    let unit = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let [p1, p2] = [0, 1].map(|n| {
        let end = crate::front::contact::ContactEnd { body: bodies[n], rotation: unit, point: points[n] };
        crate::tree::contact::point(k, poses, &end)
    });
    let mut rows: Vec<Id> = (0..3).map(|i| k.g.sub(p1[i], p2[i])).collect();
    if torquescale == 0.0 {
        rows.extend([k.g.zero(); 3]);
        return rows;
    }
    let identity = unit.map(|row| row.map(|x| k.g.constant(x)));
    let turn = |b: Option<usize>| b.and_then(|b| poses.get(b)).map_or(identity, |pose| pose.0);
    let (a1, a2) = (turn(bodies[0]), turn(bodies[1]));
    // E = A₂ᵀ A₁, entry (r, c) = Σ A₂[i][r] A₁[i][c].
    let e = [0, 1, 2].map(|r| {
        [0, 1, 2].map(|c| {
            let terms: Vec<Id> = (0..3).map(|i| k.g.mul(a2[i][r], a1[i][c])).collect();
            k.g.sum(&terms)
        })
    });
    let one = k.g.constant(1.0);
    let trace = k.g.sum(&[one, e[0][0], e[1][1], e[2][2]]);
    let root = k.g.sqrt(trace);
    // 4w = 2 √(1 + tr E); torquescale folded in.
    let scale = k.g.constant(2.0 / torquescale);
    let denominator = k.g.mul(scale, root);
    for (a, b) in [((2, 1), (1, 2)), ((0, 2), (2, 0)), ((1, 0), (0, 1))] {
        let d = k.g.sub(e[a.0][a.1], e[b.0][b.1]);
        rows.push(k.g.div(d, denominator));
    }
    rows
}

/// A point's three numbers.
pub(crate) type V3Num = [f64; 3];

/// Every body's frame from the tree's coordinates, in body order (also
/// returned: the contacts' rows start from them). A joint whose points and
/// axes are numbers is folded; any other reads them from the runtime's
/// `TreeGeometry` (its unit axis and rest rotation made once).
fn frames(k: &mut Kinematics, s: &SceneDecl, edges: &[TreeEdge]) -> Vec<crate::tree::contact::Pose> {
    let (qa, va) = kind_offsets(edges.iter().map(|e| e.kind));
    let (q, v) = (k.coords.clone(), k.velocities.clone());
    let mut b = Builder::new(std::mem::take(&mut k.g));
    let mut reads = Vec::new();
    let (zero, one) = (b.g.zero(), b.g.constant(1.0));
    let identity = [[one, zero, zero], [zero, one, zero], [zero, zero, one]];
    let mut poses: Vec<([[Id; 3]; 3], [Id; 3])> = Vec::with_capacity(edges.len());
    let mut by_body = vec![(identity, [zero; 3]); s.bodies.len()];
    let (mut spins, mut offsets) = (Vec::new(), Vec::new());
    for (n, (e, parent)) in edges.iter().zip(parent_edges(s, edges)).enumerate() {
        let (nq, nv) = e.kind.sizes();
        let (qj, vj) = (&q[qa[n]..qa[n] + nq], &v[va[n]..va[n] + nv]);
        let (a_p, r_p) = parent.map_or((identity, [zero; 3]), |p| poses[p]);
        let (rel, rho_p, rho_c) = match joint(s, e, parent) {
            Some(j) => {
                let rel = b.relative(&j, qj);
                let rho_p = j.rho_p.map(|x| b.g.constant(x));
                (rel, b.slid(&j, rho_p, qj), j.rho_c.map(|x| b.g.constant(x)))
            }
            None => read_joint(&mut b, e.kind, n, qj, &mut |b, p| read(b, &mut reads, p)),
        };
        let a: [[Id; 3]; 3] = [0, 1, 2].map(|r| [0, 1, 2].map(|c| b.dot(&a_p[r], &[rel[0][c], rel[1][c], rel[2][c]])));
        let (out, back) = (b.mv(&a_p, rho_p), b.mv(&a, rho_c));
        let r = [0, 1, 2].map(|i| {
            let t = b.g.add(r_p[i], out[i]);
            b.g.sub(t, back[i])
        });
        poses.push((a, r));
        by_body[e.ends.1] = (a, r);
        if e.kind == TreeKind::Free {
            // ḋ = R u: the offset's rate from the point's velocity in the
            // child's components.
            let moved: [Id; 3] = [0, 1, 2].map(|i| b.dot(&rel[i], &vj[..3]));
            offsets.push((qj[..3].to_vec(), moved));
        }
        spins.push((qj.to_vec(), vj.to_vec()));
    }
    k.g = b.g;
    k.inputs.extend(reads);
    for (d, rates) in offsets {
        d.iter().zip(rates).for_each(|(&d, rate)| k.rate(d, rate));
    }
    for (qj, vj) in spins {
        match (qj.as_slice(), vj.as_slice()) {
            (&[p0, p1, p2, p3], &[w0, w1, w2]) => k.spin([p0, p1, p2, p3], [w0, w1, w2]),
            (&[_, _, _, p0, p1, p2, p3], &[_, _, _, w0, w1, w2]) => k.spin([p0, p1, p2, p3], [w0, w1, w2]),
            // An angle or a slide per velocity (revolute, universal, prismatic).
            (angles, rates) => angles.iter().zip(rates).for_each(|(&q, &v)| k.rate(q, v)),
        }
    }
    for &(a, r) in &by_body {
        k.frame(a, r);
    }
    by_body
}

/// Edge `n`'s rotation relative to its parent and its two joint points (the
/// parent's moved by the joint's slides), read from `geometry`:
/// `R₀ rot(h, θ)` for a revolute joint, `R₀` for a prismatic or fixed one,
/// `rot(s, θ₁) R₀ rot(h, θ₂)` for a universal one, the normalised
/// quaternion's matrix for a spherical one. `read` gives a vector of the
/// geometry at a path (`["rest", "3", "0"]`): the closures read it through
/// their inputs, the written-out dynamics through their bindings.
pub(crate) fn read_joint(
    b: &mut Builder,
    kind: TreeKind,
    n: usize,
    q: &[Id],
    read: &mut dyn FnMut(&mut Builder, &[&str]) -> V3,
) -> ([[Id; 3]; 3], V3, V3) {
    let at = n.to_string();
    let rho_p = read(b, &["rho_parent", &at]);
    let rho_c = read(b, &["rho_child", &at]);
    if kind == TreeKind::Spherical {
        return (b.relative(&crate::tree::aba::Joint::spherical(), q), rho_p, rho_c);
    }
    let h = read(b, &["axis", &at]);
    let columns: [V3; 3] = [0, 1, 2].map(|c| read(b, &["rest", &at, &c.to_string()]));
    let rest: [[Id; 3]; 3] = [0, 1, 2].map(|r| [0, 1, 2].map(|c| columns[c][r]));
    if kind == TreeKind::Fixed {
        return (rest, rho_p, rho_c);
    }
    // `a = R₀ h`, the axis in the parent's frame, along which a prismatic
    // joint slides by its coordinate, a cylindrical one by its second.
    let slid = |b: &mut Builder, d: Id| {
        let a = b.mv(&rest, h);
        [0, 1, 2].map(|i| {
            let t = b.g.mul(a[i], d);
            b.g.add(rho_p[i], t)
        })
    };
    if kind == TreeKind::Prismatic {
        return (rest, slid(b, q[0]), rho_c);
    }
    let turn = |b: &mut Builder, axis: V3, angle: Id| {
        let (c, s) = (b.g.cos(angle), b.g.sin(angle));
        rotation_about(b, axis, c, s)
    };
    let times = |b: &mut Builder, x: &[[Id; 3]; 3], y: &[[Id; 3]; 3]| -> [[Id; 3]; 3] {
        [0, 1, 2].map(|r| [0, 1, 2].map(|j| b.dot(&x[r], &[y[0][j], y[1][j], y[2][j]])))
    };
    let (rho_p, angle) = match kind {
        TreeKind::Cylindrical => (slid(b, q[1]), q[0]),
        TreeKind::Planar => {
            // The point moved along the parent's in-plane axes.
            let plane: [V3; 2] = [0, 1].map(|i| read(b, &["plane", &at, &i.to_string()]));
            let moved = [0, 1, 2].map(|r| {
                let (x, y) = (b.g.mul(plane[0][r], q[0]), b.g.mul(plane[1][r], q[1]));
                let t = b.g.add(rho_p[r], x);
                b.g.add(t, y)
            });
            (moved, q[2])
        }
        _ => (rho_p, q[0]),
    };
    let rel = if kind == TreeKind::Universal {
        // rot(s, θ₁) R₀ rot(h, θ₂), `s` the parent's axis.
        let s = read(b, &["axis_parent", &at]);
        let (first, second) = (turn(b, s, q[0]), turn(b, h, q[1]));
        let turned = times(b, &first, &rest);
        times(b, &turned, &second)
    } else {
        let second = turn(b, h, angle);
        times(b, &rest, &second)
    };
    (rel, rho_p, rho_c)
}

/// A vector of `geometry` at `path` (`rest`, `3`, `0`: `geometry.rest[3][0]`).
fn read(b: &mut Builder, reads: &mut Vec<Input>, path: &[&str]) -> V3 {
    let name = path.join("_");
    let vars = ["x", "y", "z"].map(|c| b.g.param(format!("{name}_{c}")));
    reads.push(Input { root: "geometry", path: path.iter().map(|p| p.to_string()).collect(), vars: vars.to_vec() });
    vars
}

/// `rot(h, θ) = c I + s [h]× + (1 − c) h hᵀ` for a unit `h` of nodes.
pub(crate) fn rotation_about(b: &mut Builder, h: V3, c: Id, s: Id) -> [[Id; 3]; 3] {
    let one = b.g.constant(1.0);
    let omc = b.g.sub(one, c);
    [0, 1, 2].map(|i| {
        [0, 1, 2].map(|j| {
            let hh = b.g.mul(h[i], h[j]);
            let outer = b.g.mul(omc, hh);
            if i == j {
                return b.g.add(c, outer);
            }
            // [h]×[i][j] = −ε_ijk h_k.
            let k = 3 - i - j;
            let sh = b.g.mul(s, h[k]);
            if (i + 1) % 3 == j { b.g.sub(outer, sh) } else { b.g.add(outer, sh) }
        })
    })
}

/// `fn closure_rows(&self, state) -> ClosureRows<NC, NV>` and the closures'
/// row blocks (`CLOSURES`), with the number of rows.
pub fn print(d: &Derived, blocks: &[Block], second: Option<&SecondOrderNodes>, s: &SceneDecl) -> (TokenStream, usize) {
    let bodies = s.bodies.len();
    let k = krate();
    let rows = d.phi.len();
    let nv = d.kinematics.velocities.len();
    let p = print_none(d, &crate::tree::aba::scalar());
    let mut outputs = d.phi.clone();
    outputs.extend((0..nv).flat_map(|c| d.jacobian.iter().map(move |row| row[c])));
    outputs.extend(&d.gamma);
    outputs.extend(&d.phi_t);
    let (body, outs, ops) = p.emit(&outputs);
    let (phi, rest) = outs.split_at(rows);
    let (jac, rest) = rest.split_at(rows * nv);
    let (gamma, phi_t) = rest.split_at(rows);
    let (phi, jac, gamma, phi_t) =
        (vector_tokens(phi), matrix_tokens(jac, rows), vector_tokens(gamma), vector_tokens(phi_t));
    let contacts = contacts(s, blocks);
    let soft = soft(s, blocks);
    let blocks = blocks.iter().map(|b| {
        let (name, start, n) = (&b.name, b.start, b.rows);
        quote!(#k::RowBlock { name: #name, start: #start, rows: #n })
    });
    // Rows linear in the coordinates (a file's couplings): J constant, no γ,
    // no Φ_t; the runtime's exact derivatives cover these.
    let g = &d.kinematics.g;
    let zero = |id: &Id| g.as_const(*id) == Some(0.0);
    let linear = d.jacobian.iter().flatten().all(|id| g.as_const(*id).is_some())
        && d.gamma.iter().all(zero)
        && d.phi_t.iter().all(zero);
    let doc = format!(" The closures' rows in the tree's coordinates, derived by the engine: {ops} operations.");
    let second = second.and_then(|nodes| second_method(d, nodes, s));
    let (nc, nv) = (proc_macro2::Literal::usize_unsuffixed(rows), proc_macro2::Literal::usize_unsuffixed(nv));
    let nq = proc_macro2::Literal::usize_unsuffixed(d.kinematics.coords.len());
    let nb = proc_macro2::Literal::usize_unsuffixed(bodies);
    // Said only where true (the trait's default is `false`).
    let linear = linear.then(|| {
        quote!(
            const LINEAR_CLOSURES: bool = true;
        )
    });
    let method = quote! {
        const CLOSURES: &'static [#k::RowBlock] = &[#(#blocks),*];
        #contacts
        #soft
        #linear
        #[doc = #doc]
        #[inline]
        fn closure_rows(
            &self,
            state: &#k::relative::TreeState<#nq, #nv>,
            geometry: &#k::relative::TreeGeometry<#nb>,
        ) -> #k::relative::ClosureRows<#nc, #nv> {
            #body
            #k::relative::ClosureRows { phi: #phi, jacobian: #jac, gamma: #gamma, phi_t: #phi_t }
        }
        #second
    };
    (method, rows)
}

/// Past this many operations the closures' second-order terms are not
/// written (rustc's time grows faster than a function's length) and the
/// constrained dynamics' derivatives say `NotDerived`.
pub const SECOND_LIMIT: usize = 60_000;

/// `fn closure_second_order`: the closures' `K = ∂(Jᵀλ)/∂q`, `∂(J u)/∂q`,
/// `∂γ/∂q`, `∂γ/∂v`, `∂Φ_t/∂q` (tangent columns), `None` past the limit.
fn second_method(d: &Derived, nodes: &SecondOrderNodes, s: &SceneDecl) -> Option<TokenStream> {
    let k = krate();
    let p = print_none(d, &crate::tree::aba::scalar());
    let (body, outs, ops) = p.emit(&nodes.all());
    if ops > SECOND_LIMIT {
        return None;
    }
    let (rows, nv) = (d.phi.len(), d.kinematics.velocities.len());
    let (stiffness, rest) = outs.split_at(nv * nv);
    let (jacobian_q, rest) = rest.split_at(rows * nv);
    let (gamma_q, rest) = rest.split_at(rows * nv);
    let (gamma_v, phi_t_q) = rest.split_at(rows * nv);
    let (stiffness, jacobian_q) = (matrix_tokens(stiffness, nv), matrix_tokens(jacobian_q, rows));
    let (gamma_q, gamma_v, phi_t_q) =
        (matrix_tokens(gamma_q, rows), matrix_tokens(gamma_v, rows), matrix_tokens(phi_t_q, rows));
    let lit = proc_macro2::Literal::usize_unsuffixed;
    let (nc, nvl, nq, nb) = (lit(rows), lit(nv), lit(d.kinematics.coords.len()), lit(s.bodies.len()));
    let doc = format!(" The closures' second-order terms, derived by the engine: {ops} operations.");
    Some(quote! {
        #[doc = #doc]
        #[inline]
        fn closure_second_order(
            &self,
            state: &#k::relative::TreeState<#nq, #nvl>,
            geometry: &#k::relative::TreeGeometry<#nb>,
            lambda: &#k::nalgebra::SVector<f64, #nc>,
            u: &#k::nalgebra::SVector<f64, #nvl>,
        ) -> ::core::option::Option<#k::SecondOrder<f64, #nc, #nvl>> {
            #body
            ::core::option::Option::Some(#k::SecondOrder {
                stiffness: #stiffness, jacobian_q: #jacobian_q, gamma_q: #gamma_q, gamma_v: #gamma_v, phi_t_q: #phi_t_q,
            })
        }
    })
}

/// `const SOFT`: a file's equalities as MuJoCo softens them, each with its
/// block (loops first, then couplings, then contacts), `solref`, `solimp`
/// and whose inverse weights scale it; `None` where none is soft.
fn soft(s: &SceneDecl, blocks: &[Block]) -> Option<TokenStream> {
    let k = krate();
    let first_coupling = blocks.len() - s.contacts.len() - s.couplings.len();
    let f = proc_macro2::Literal::f64_suffixed;
    let some = |t: TokenStream| quote!(::core::option::Option::Some(#t));
    let none = quote!(::core::option::Option::None);
    let item = |block: usize, soft: &crate::front::files::Soft, weight: TokenStream| {
        let (solref, solimp) = (soft.solref.map(f), soft.solimp.map(f));
        quote!(#k::relative::SoftEquality {
            block: #block,
            solref: [#(#solref),*],
            solimp: [#(#solimp),*],
            weight: #k::relative::InverseWeight::#weight,
        })
    };
    let mut items = Vec::new();
    for (n, b) in blocks[..first_coupling].iter().enumerate() {
        let Some(j) = s.soft.iter().find(|j| j.joint == b.name) else { continue };
        let ends = j.ends.map(|end| match end {
            Some((body, p)) => {
                let p = p.map(f);
                some(quote!((#body, [#(#p),*])))
            }
            None => none.clone(),
        });
        let weight = if j.weld.is_some() { quote!(Weld([#(#ends),*])) } else { quote!(Bodies([#(#ends),*])) };
        items.push(item(n, &j.soft, weight));
    }
    let edges = s.tree.as_deref().unwrap_or(&[]);
    let (_, va) = kind_offsets(edges.iter().map(|e| e.kind));
    let freedom = |joint: usize| match edges.iter().position(|e| e.joint == Some(joint)) {
        Some(n) => {
            let at = va[n];
            some(quote!(#at))
        }
        None => none.clone(),
    };
    for (i, c) in s.couplings.iter().enumerate() {
        let Some(soft) = &c.soft else { continue };
        let (a, b) = (freedom(c.follower), freedom(c.leader));
        items.push(item(first_coupling + i, soft, quote!(Freedoms([#a, #b]))));
    }
    (!items.is_empty()).then(|| quote!(const SOFT: &'static [#k::relative::SoftEquality] = &[#(#items),*];))
}

/// `const CONTACTS`: each contact's block among the closures', its kind and axes.
fn contacts(s: &SceneDecl, blocks: &[Block]) -> Option<TokenStream> {
    use crate::front::contact::{Axes, ContactKind};
    if s.contacts.is_empty() {
        return None;
    }
    let k = krate();
    let first = blocks.len() - s.contacts.len();
    let items = s.contacts.iter().enumerate().map(|(i, c)| {
        let block = first + i;
        let kind = match c.kind {
            ContactKind::Point => quote!(Point),
            ContactKind::Frame => quote!(Frame),
        };
        let axes = match c.axes {
            Axes::World => quote!(World),
            Axes::Local => quote!(Local),
        };
        let body = c.ends[0].body.unwrap_or(0);
        let other = match c.ends[1].body {
            Some(b) => quote!(::core::option::Option::Some(#b)),
            None => quote!(::core::option::Option::None),
        };
        quote!(#k::relative::Contact {
            block: #block,
            kind: #k::relative::ContactKind::#kind,
            axes: #k::relative::ContactAxes::#axes,
            body: #body,
            other: #other,
        })
    });
    Some(quote!(const CONTACTS: &'static [#k::relative::Contact] = &[#(#items),*];))
}
