//! The blocks of `J W Jᵀ` (`W` the inverse mass matrix) on the block factor's
//! pattern, written straight-line for one scene: `SparseJacobian::
//! normal_blocks_into`. The runtime forms the same blocks from dense 6-column
//! blocks of `J` (`J W` per joint side, then `(J W) Jᵀ` per shared body); here
//! the engine sees which entries of `J` are structurally zero or constant, so
//! the products with them are never written, and it shares each `J W` row
//! between the blocks that read it. A diagonal block is symmetric: its upper
//! triangle is computed and mirrored. Not written above 5 000 operations
//! (`LIMIT`: rustc's time on one long function grows faster than its length);
//! the runtime forms the blocks there.

use std::collections::BTreeSet;

use proc_macro2::{Literal, TokenStream};
use quote::{format_ident, quote};

use crate::engine::emit::{self, ScalarTy};
use crate::engine::order::Elimination;
use crate::engine::{Graph, Id};

/// The scene's Jacobian as the derive knows it: CSR rows, each entry's
/// column and, where the engine folded it, its constant value.
pub struct Csr {
    pub row_starts: Vec<usize>,
    pub columns: Vec<usize>,
    pub constants: Vec<Option<f64>>,
}

/// A joint's block of rows and the bodies it connects (`None`: the ground).
pub struct JointRows {
    pub start: usize,
    pub rows: usize,
    pub bodies: [Option<usize>; 2],
}

/// A 6 × 6 block of nodes, row-major: rows past a joint's are zero.
type Block = [[Id; 6]; 6];

/// The graph of the blocks and the inputs it reads.
struct Normal {
    g: Graph,
}

impl Normal {
    /// `J`'s block of joint `j` on body side `side`.
    fn jacobian(&mut self, csr: &Csr, values: &[Id], j: &JointRows, side: usize) -> Block {
        let zero = self.g.zero();
        let mut block = [[zero; 6]; 6];
        for (r, row) in block.iter_mut().enumerate().take(j.rows.min(6)) {
            let (a, b) = (csr.row_starts[j.start + r], csr.row_starts[j.start + r + 1]);
            for e in a..b {
                let body = csr.columns[e] / 6;
                // The first side on that body, as the runtime's scatter.
                if j.bodies.iter().position(|x| *x == Some(body)) == Some(side) {
                    row[csr.columns[e] % 6] = values[e];
                }
            }
        }
        block
    }

    /// `J W` of a block: translational columns times `1/m`, rotational ones
    /// times the inverse inertia, in the runtime's order of operations.
    fn times_metric(&mut self, j: &Block, w: &[Id; 10]) -> Block {
        let mut out = *j;
        for (row, o) in j.iter().zip(out.iter_mut()) {
            for c in 0..3 {
                o[c] = self.g.mul(row[c], w[0]);
            }
            for c in 0..3 {
                let terms = [0, 1, 2].map(|q| self.g.mul(row[3 + q], w[1 + 3 * q + c]));
                let first = self.g.add(terms[0], terms[1]);
                o[3 + c] = self.g.add(first, terms[2]);
            }
        }
        out
    }

    /// The variables of body `b`'s inverse mass: `1/m`, then `J'⁻¹` row by row.
    fn metric(&mut self, b: usize) -> [Id; 10] {
        let names =
            [format!("inv_mass_{b}")].into_iter().chain((0..9).map(|i| format!("inv_inertia_{b}_{}{}", i / 3, i % 3)));
        let ids: Vec<Id> = names.map(|name| self.g.param(name)).collect();
        std::array::from_fn(|i| ids[i])
    }

    /// Entry `(x, y)` of a block `(i, k)`: `Σ_b (J W)_i,b[x] · J_k,b[y]` over
    /// the bodies the two joints share, from the rows `[J W]_i[x]` and
    /// `J_k[y]` of each joint's two sides.
    fn shared_dot(&mut self, rows: &[[[Id; 6]; 2]; 2], bodies: [[Option<usize>; 2]; 2]) -> Id {
        let mut sum = self.g.zero();
        for (si, a) in bodies[0].iter().enumerate() {
            for (sk, b) in bodies[1].iter().enumerate() {
                if a.is_some() && a == b {
                    let dot = self.dot(&rows[0][si], &rows[1][sk]);
                    sum = self.g.add(sum, dot);
                }
            }
        }
        sum
    }

    /// `Σ_c a[c] b[c]`, in column order.
    fn dot(&mut self, a: &[Id; 6], b: &[Id; 6]) -> Id {
        let terms = [0, 1, 2, 3, 4, 5].map(|c| self.g.mul(a[c], b[c]));
        terms.into_iter().reduce(|s, t| self.g.add(s, t)).unwrap_or(terms[0])
    }
}

/// Above this many operations the method is not written and the factor forms
/// the blocks itself: rustc's time on one long straight-line function grows
/// faster than its length, and the gain (a sixth of a step's instructions on
/// a 10-bar chain) does not pay for it on a large scene. Measured on a crate
/// holding a chain and an RK4 step, release build: 40 bars (4 524
/// operations) 3.3 s → 3.6 s; 80 bars (9 084) 5.1 s → 7.2 s; 200 bars
/// (22 764) 10.2 s → 17.3 s.
const LIMIT: usize = 5_000;

/// The method for a scene of `bodies` bodies, with its operation count:
/// every slot's `rows × columns` entries, in the factor's slot order (per
/// elimination position: the diagonal, then the blocks below); `None` above
/// [`LIMIT`].
pub fn method(
    csr: &Csr,
    joints: &[JointRows],
    e: &Elimination,
    bodies: usize,
    krate: &TokenStream,
) -> Option<(TokenStream, usize)> {
    let mut n = Normal { g: Graph::new() };
    let values: Vec<Id> = csr
        .constants
        .iter()
        .enumerate()
        .map(|(i, c)| match c {
            Some(v) => n.g.constant(*v),
            None => n.g.param(format!("j{i}")),
        })
        .collect();
    let metric: Vec<[Id; 10]> = (0..bodies).map(|b| n.metric(b)).collect();
    let (mut jb, mut jw) = (Vec::new(), Vec::new());
    for j in joints {
        let sides = [0, 1].map(|side| n.jacobian(csr, &values, j, side));
        let products = [0, 1].map(|side| match j.bodies[side].and_then(|b| metric.get(b)) {
            Some(w) => n.times_metric(&sides[side], w),
            None => sides[side],
        });
        jb.push(sides);
        jw.push(products);
    }
    let (outputs, places) = n.blocks(e, joints, (&jb, &jw));
    let ops = emit::count_ops(&n.g, &outputs);
    if ops > LIMIT {
        return None;
    }
    let sty = ScalarTy { ty: quote!(f64), krate: krate.clone(), concrete_f64: true };
    let emitted = emit::emit(&n.g, &outputs, &sty);
    let used: BTreeSet<u32> = emitted.used_vars.iter().map(|v| v.0).collect();
    let bind = |ids: &[Id]| -> Vec<TokenStream> {
        ids.iter()
            .map(|&id| match n.g.as_var(id) {
                Some(v) if used.contains(&v.0) => {
                    let name = format_ident!("{}", n.g.vars()[v.0 as usize].name);
                    quote!(#name)
                }
                _ => quote!(_),
            })
            .collect()
    };
    // One `let` for all inputs: every `let` opens a scope, and a large
    // scene's thousands of nested scopes crash rustc's debug info.
    let values_pattern = bind(&values);
    let metric_patterns = metric.iter().map(|w| {
        let names = bind(w);
        quote!([#(#names),*])
    });
    let metric_reads = (0..bodies).map(|b| {
        let b = Literal::usize_unsuffixed(b);
        quote!(w[#b].entries())
    });
    let binds = quote! {
        let [#(#values_pattern),*] = *values;
        let (#(#metric_patterns,)*) = (#(#metric_reads,)*);
    };
    let body = emitted.body;
    let stores = places.iter().zip(&emitted.outputs).map(|(&(s, x, y, mirror), v)| {
        let (s, at) = (Literal::usize_unsuffixed(s), Literal::usize_unsuffixed(6 * x + y));
        let mirrored = mirror.then(|| {
            let other = Literal::usize_unsuffixed(6 * y + x);
            quote!(l[#s][#other] = l[#s][#at];)
        });
        quote!(l[#s][#at] = #v; #mirrored)
    });
    let (nb, nnz) = (Literal::usize_unsuffixed(bodies), Literal::usize_unsuffixed(csr.columns.len()));
    let method = quote! {
        #[inline]
        fn normal_blocks_into(
            values: &[f64; #nnz],
            w: &[#krate::__private::InverseMass; #nb],
            factor: &mut Self::Factor,
        ) -> bool {
            let l = factor.blocks_mut();
            #binds
            #body
            #(#stores)*
            true
        }
    };
    Some((method, ops))
}

/// Where an output goes: the factor's slot, row, column, and whether the
/// entry is mirrored across a diagonal block.
type Place = (usize, usize, usize, bool);

impl Normal {
    /// Every block `J_i W J_kᵀ` of the factor's pattern as outputs, each
    /// with its place: slot, row, column, and whether to mirror it.
    fn blocks(
        &mut self,
        e: &Elimination,
        joints: &[JointRows],
        (jb, jw): (&[[Block; 2]], &[[Block; 2]]),
    ) -> (Vec<Id>, Vec<Place>) {
        let (mut outputs, mut places, mut slot) = (Vec::new(), Vec::new(), 0usize);
        for (k, below) in e.below.iter().enumerate() {
            for i in std::iter::once(k).chain(below.iter().copied()) {
                let (bi, bk) = (e.order[i], e.order[k]);
                let (ji, jk) = (&joints[bi], &joints[bk]);
                for x in 0..ji.rows {
                    // A diagonal block's upper triangle, mirrored.
                    for y in (if i == k { x } else { 0 })..jk.rows {
                        let rows = [jw[bi].map(|side| side[x]), jb[bk].map(|side| side[y])];
                        outputs.push(self.shared_dot(&rows, [ji.bodies, jk.bodies]));
                        places.push((slot, x, y, i == k && x != y));
                    }
                }
                slot += 1;
            }
        }
        (outputs, places)
    }
}
