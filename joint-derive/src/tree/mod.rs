//! A relative scene's own code, the derive's tree room: what it writes for
//! the scene's spanning tree and what closes it.
//!
//! - `aba`: the articulated-body algorithm, Newton–Euler and the mass
//!   matrix written out for the tree;
//! - `closure`: the rows of the joints outside the tree (loops, a file's
//!   couplings) and of the contacts, and their second-order terms, derived
//!   by the engine in the tree's coordinates;
//! - `contact`: a contact's rows at the velocity level;
//! - `derivatives`: the inverse dynamics' derivatives written out
//!   (`second_order`);
//! - `wrench`: the closures' rows again on their bodies' own velocities,
//!   what their reactions need.
//!
//! `derives::tree` prints the `TreeScene` impl from them.

pub mod aba;
pub mod closure;
pub mod contact;
pub mod derivatives;
pub mod wrench;
