//! The error context of one derive: every mistake of a run is collected, and the
//! context cannot be dropped with errors unreported (after serde's `Ctxt`).

use proc_macro2::Span;

/// Errors found so far. Call [`Errors::finish`] exactly once; dropping the
/// context without it is a bug in the derive, caught by a panic at expansion
/// time in every test that reaches the code path.
pub struct Errors {
    found: Option<Vec<syn::Error>>,
}

impl Errors {
    /// An empty context.
    pub fn new() -> Self {
        Errors { found: Some(Vec::new()) }
    }

    fn found(&mut self) -> &mut Vec<syn::Error> {
        self.found.get_or_insert_with(Vec::new)
    }

    /// Records an error at `span`.
    pub fn at(&mut self, span: Span, message: impl std::fmt::Display) {
        self.found().push(syn::Error::new(span, message));
    }

    /// Records an error spanning every token of `tokens` (a whole type, say).
    pub fn spanned(&mut self, tokens: impl quote::ToTokens, message: impl std::fmt::Display) {
        self.found().push(syn::Error::new_spanned(tokens, message));
    }

    /// Records a parse error.
    pub fn push(&mut self, e: syn::Error) {
        self.found().push(e);
    }

    /// Whether nothing is wrong so far.
    pub fn is_empty(&self) -> bool {
        self.found.as_ref().is_none_or(Vec::is_empty)
    }

    /// All errors combined, or `Ok` if none; the context is spent.
    pub fn finish(mut self) -> syn::Result<()> {
        let mut iter = self.found.take().unwrap_or_default().into_iter();
        match iter.next() {
            None => Ok(()),
            Some(mut first) => {
                iter.for_each(|e| first.combine(e));
                Err(first)
            }
        }
    }
}

impl Drop for Errors {
    fn drop(&mut self) {
        if self.found.is_some() && !std::thread::panicking() {
            panic!("the derive dropped its errors unreported: call `Errors::finish`");
        }
    }
}
