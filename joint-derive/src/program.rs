//! The block factor's schedule unrolled for one scene:
//! `SparseJacobian::factor_program` and `solve_program`. The runtime builds
//! the same schedule into arrays at `new` and interprets it (a look-up per
//! block, a dispatch on each block's sizes); here the derive, which fixed the
//! elimination order and the pattern, writes one call per block operation
//! with the block sizes as const generics and the slots as constants
//! (`FactorArrays`'s steps in the runtime's `absolute/factor/program.rs`). The
//! calls are in the interpreter's order, so both give the same bits. Not
//! written above 1 500 block operations (`LIMIT`): the interpreter runs there.

use proc_macro2::{Literal, TokenStream};
use quote::quote;

use crate::engine::order::Elimination;
use crate::normal::JointRows;

/// Above this many block operations the program is not written and the
/// factor interprets its schedule: each call is inlined into one function,
/// and rustc's time on it grows faster than its length.
const LIMIT: usize = 1_500;

fn lit(x: usize) -> Literal {
    Literal::usize_unsuffixed(x)
}

/// The factor's slots: per elimination position, the diagonal, then the
/// positions below in ascending order (the runtime's numbering).
struct Slots {
    /// `column[k]`: `(row position, slot)` of column `k`, the diagonal first.
    column: Vec<Vec<(usize, usize)>>,
}

impl Slots {
    fn new(e: &Elimination) -> Self {
        let mut at = 0;
        let column = e
            .below
            .iter()
            .enumerate()
            .map(|(k, below)| {
                std::iter::once(k)
                    .chain(below.iter().copied())
                    .map(|i| {
                        at += 1;
                        (i, at - 1)
                    })
                    .collect()
            })
            .collect();
        Slots { column }
    }

    /// The slot of `(i, k)`, if the pattern has it.
    fn of(&self, i: usize, k: usize) -> Option<usize> {
        self.column[k].iter().find(|&&(r, _)| r == i).map(|&(_, s)| s)
    }

    /// The products that update slot `(i, k)`: `(rows of j, slot (i, j),
    /// slot (k, j))` for `j < k` ascending, as the runtime schedules them.
    fn updates(&self, i: usize, k: usize) -> Vec<(usize, usize, usize)> {
        (0..k).filter_map(|j| Some((j, self.of(i, j)?, self.of(k, j)?))).collect()
    }
}

/// Both methods; `None` above [`LIMIT`] block operations.
pub fn methods(joints: &[JointRows], e: &Elimination) -> Option<(TokenStream, usize)> {
    let slots = Slots::new(e);
    let rows = |position: usize| joints[e.order[position]].rows;
    let start = |position: usize| joints[e.order[position]].start;
    let n = e.order.len();
    let (mut factor, mut calls) = (Vec::new(), 0usize);
    let update = |i: usize, k: usize, s: usize, out: &mut Vec<TokenStream>| {
        for (j, a, b) in slots.updates(i, k) {
            let (ri, rk, rj, s, a, b) = (lit(rows(i)), lit(rows(k)), lit(rows(j)), lit(s), lit(a), lit(b));
            out.push(quote!(f.update::<#ri, #rk, #rj>(#s, #a, #b);));
        }
    };
    for k in 0..n {
        let d = slots.column[k][0].1;
        update(k, k, d, &mut factor);
        let (r, kk, dd, st) = (lit(rows(k)), lit(k), lit(d), lit(start(k)));
        factor.push(quote!(dropped = f.diagonal::<#r>(#kk, #dd, #st, tolerance, keep, dropped);));
        for &(i, s) in &slots.column[k][1..] {
            update(i, k, s, &mut factor);
            let (ri, ss) = (lit(rows(i)), lit(s));
            factor.push(quote!(f.below::<#ri, #r>(#kk, #dd, #ss);));
        }
    }
    calls += factor.len();
    let largest = (0..n).map(|k| {
        let (r, d) = (lit(rows(k)), lit(slots.column[k][0].1));
        quote!(largest = f.largest_diagonal::<#r>(#d, largest);)
    });
    let mut solve = Vec::new();
    for k in 0..n {
        let (r, kk, d, st) = (lit(rows(k)), lit(k), lit(slots.column[k][0].1), lit(start(k)));
        solve.push(quote!(c = f.load::<#r>(b, #st);));
        // Row k of L: the slots (k, j), j < k ascending.
        for j in 0..k {
            if let Some(s) = slots.of(k, j) {
                let (rj, s, j) = (lit(rows(j)), lit(s), lit(j));
                solve.push(quote!(f.forward_update::<#r, #rj>(#s, #j, &mut c);));
            }
        }
        solve.push(quote!(f.forward::<#r>(#kk, #d, &c);));
    }
    for k in (0..n).rev() {
        let (r, kk, d, st) = (lit(rows(k)), lit(k), lit(slots.column[k][0].1), lit(start(k)));
        solve.push(quote!(c = f.z(#kk);));
        for &(i, s) in &slots.column[k][1..] {
            let (ri, s, i) = (lit(rows(i)), lit(s), lit(i));
            solve.push(quote!(f.backward_update::<#ri, #r>(#s, #i, &mut c);));
        }
        solve.push(quote!(f.backward::<#r>(#kk, #d, #st, &c, b);));
    }
    calls += solve.len();
    if calls > LIMIT || n == 0 {
        return None;
    }
    // One `let` each for `c` and the counters: a large scene's thousands
    // of nested scopes would crash rustc's debug info.
    let methods = quote! {
        #[inline]
        fn factor_program(factor: &mut Self::Factor, tolerance: f64, keep: bool) -> ::core::option::Option<usize> {
            let f = factor;
            let mut largest = 0.0f64;
            #(#largest)*
            let tolerance = if tolerance > 0.0 { tolerance * largest } else { 0.0 };
            let mut dropped = 0usize;
            #(#factor)*
            ::core::option::Option::Some(f.sort_dropped(dropped))
        }

        #[inline]
        fn solve_program(factor: &mut Self::Factor, b: &mut [f64]) -> bool {
            let f = factor;
            let mut c: [f64; 6];
            #(#solve)*
            true
        }
    };
    Some((methods, calls))
}
