//! The front end: attributes in, checked declarations out, in typed phases (after
//! thiserror's and serde's derives):
//!
//! ```text
//! syn::DeriveInput ─ attr ─▶ attribute AST (spans kept; slots report duplicates)
//!                  ─ joint / scene ─▶ parameters given, by name
//!                  ─ resolve ─▶ every parameter of the joint, checked (one resolver
//!                               for both derives, so a mistake is worded once)
//! ```
//!
//! Errors go to one [`context::Errors`], which cannot be dropped unreported. Nothing
//! here knows the engine: the arrows run front end → lowering → code generation.
//!
//! A robot file (`files`, read by `urdf` or `mjcf`, put in the scene's terms by
//! `robot`) enters `scene` as its attributes would; `tree` picks a relative
//! scene's spanning tree; `rows` and `custom` read a joint written as rows.

pub mod attr;
pub mod contact;
pub mod context;
pub mod custom;
pub mod files;
pub mod geometry;
pub mod joint;
#[cfg(feature = "mjcf")]
pub mod mjcf;
pub mod names;
pub mod resolve;
#[cfg(any(feature = "urdf", feature = "mjcf"))]
pub mod robot;
pub mod rows;
pub mod scene;
pub mod tree;
#[cfg(feature = "urdf")]
pub mod urdf;
#[cfg(any(feature = "urdf", feature = "mjcf"))]
pub mod visuals;

#[cfg(test)]
mod tests;
