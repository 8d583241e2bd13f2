//! The two derives: each reads its declaration (front end), lowers it, and
//! prints its impls with the shared generator, or, on error, its stub.

pub mod joint;
pub mod scene;
pub mod tree;
