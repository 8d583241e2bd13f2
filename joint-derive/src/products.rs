//! `J x` and `Jᵀ y` for one scene, straight-line on its CSR pattern:
//! `SparseJacobian::j_mul_into` and `jt_mul_into`. Every step of a simulation
//! takes several of each; the runtime's CSR walk reads each entry's column
//! from a table, and the factor's six-column blocks multiply the structural
//! zeros. Here each row (or column) is one sum of its nonzero products, the
//! entries the engine folded to constants written as literals (±1 as the
//! input itself). One statement per row: no temporaries, so a large scene's
//! build grows with its nonzeros. Not written above [`LIMIT`] nonzeros: the
//! straight lines cost a 200-body chain's crate 1.5 s of its 13–14 s release
//! build, for a few per cent of a step (the 160-bar chain's RK4 step, with
//! them 227.5 µs, without 238.4: same run, alternating, medians of 5).

use proc_macro2::{Literal, TokenStream};
use quote::{format_ident, quote};

use crate::normal::Csr;

/// One product `value · input`: `values[e]` or the folded constant; `None`
/// for a constant zero.
fn term(csr: &Csr, e: usize, input: &TokenStream) -> Option<TokenStream> {
    match csr.constants[e] {
        Some(0.0) => None,
        Some(1.0) => Some(quote!(#input)),
        Some(-1.0) => Some(quote!(-#input)),
        Some(v) if v.is_finite() => {
            let l = Literal::f64_unsuffixed(v.abs());
            Some(if v < 0.0 { quote!(-(#l * #input)) } else { quote!(#l * #input) })
        }
        // A non-finite constant: read it like any other entry.
        _ => {
            let e = Literal::usize_unsuffixed(e);
            Some(quote!(values[#e] * #input))
        }
    }
}

/// `a + b + …` in the given order; `0.0` for no terms.
fn sum(terms: Vec<TokenStream>) -> TokenStream {
    let mut it = terms.into_iter();
    match it.next() {
        Some(first) => it.fold(first, |s, t| quote!(#s + #t)),
        None => quote!(0.0),
    }
}

/// The slice pattern `[a0, _, a2, …]` of `n` names, `_` where unused.
fn pattern(prefix: &str, n: usize, used: &[bool]) -> TokenStream {
    let names = (0..n).map(|i| {
        if used[i] {
            let id = format_ident!("{prefix}{i}");
            quote!(#id)
        } else {
            quote!(_)
        }
    });
    quote!([#(#names),*])
}

/// Nonzeros of `J` above which the products are not written (a chain of 160
/// spherical joints has 2 874, of 200 3 594: the 160-bar chain keeps them).
const LIMIT: usize = 3_000;

/// Both methods for a scene of `columns` columns; none above [`LIMIT`]
/// nonzeros (the runtime walks the CSR pattern).
pub fn methods(csr: &Csr, columns: usize) -> TokenStream {
    if csr.columns.len() > LIMIT {
        return TokenStream::new();
    }
    let rows = csr.row_starts.len() - 1;
    let nnz = Literal::usize_unsuffixed(csr.columns.len());
    // Entries by column, each in row order, for `Jᵀ y`.
    let mut by_column: Vec<Vec<(usize, usize)>> = vec![Vec::new(); columns];
    for r in 0..rows {
        for e in csr.row_starts[r]..csr.row_starts[r + 1] {
            by_column[csr.columns[e]].push((r, e));
        }
    }
    let x_used: Vec<bool> = by_column.iter().map(|c| !c.is_empty()).collect();
    let y_used: Vec<bool> = (0..rows).map(|r| csr.row_starts[r] < csr.row_starts[r + 1]).collect();
    let (all_rows, all_columns) = (vec![true; rows], vec![true; columns]);

    let j_rows = (0..rows).map(|r| {
        let terms = (csr.row_starts[r]..csr.row_starts[r + 1])
            .filter_map(|e| {
                term(csr, e, &{
                    let x = format_ident!("x{}", csr.columns[e]);
                    quote!(#x)
                })
            })
            .collect();
        let (o, s) = (format_ident!("o{r}"), sum(terms));
        quote!(*#o = #s;)
    });
    let jt_columns = by_column.iter().enumerate().map(|(c, entries)| {
        let terms = entries
            .iter()
            .filter_map(|&(r, e)| {
                term(csr, e, &{
                    let y = format_ident!("y{r}");
                    quote!(#y)
                })
            })
            .collect();
        let (o, s) = (format_ident!("o{c}"), sum(terms));
        quote!(*#o = #s;)
    });
    let (x_pattern, y_pattern) = (pattern("x", columns, &x_used), pattern("y", rows, &y_used));
    let (j_out, jt_out) = (pattern("o", rows, &all_rows), pattern("o", columns, &all_columns));
    quote! {
        #[inline]
        fn j_mul_into(values: &[f64; #nnz], x: &[f64], out: &mut [f64]) -> bool {
            let _ = values;
            let (&#x_pattern, #j_out) = (x, out) else { return false };
            #(#j_rows)*
            true
        }

        #[inline]
        fn jt_mul_into(values: &[f64; #nnz], y: &[f64], out: &mut [f64]) -> bool {
            let _ = values;
            let (&#y_pattern, #jt_out) = (y, out) else { return false };
            #(#jt_columns)*
            true
        }
    }
}
