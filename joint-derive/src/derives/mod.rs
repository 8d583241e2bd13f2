//! The two derives: each reads its declaration (front end), lowers it, and
//! prints its impls with the shared generator, or, on error, its stub. The
//! stub has the impls' shape (sizes from the declaration alone, where it can
//! be read), so code that uses the type still type-checks: each mistake is
//! one `compile_error!` at its span, not a cascade of type errors after it.

pub mod joint;
pub mod scene;
pub mod tree;
