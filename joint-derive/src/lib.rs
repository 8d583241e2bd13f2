//! `#[derive(Joint)]`: joint declarations in, constraint code out.
//!
//! Use it through `joint-runtime`, which re-exports it and holds the trait the
//! generated code implements. The pipeline is thin: `dsl` parses the
//! declaration (keeping spans for errors), `kinematics` and `joints` state Φ
//! over the symbolic `engine`, which differentiates, simplifies, shares common
//! subexpressions and prints Rust.

mod dsl;
mod engine;
mod expand;
mod fallback;
mod joints;
mod kinematics;
mod rows;

#[cfg(test)]
mod output_tests;

/// Derives `joint_runtime::Joint` for a joint declaration.
///
/// ```ignore
/// #[derive(Joint)]
/// #[joint(universal, formulation = omega_body, s = [0, 0, 1])]
/// struct Cardan<T> { h: Vector3<T>, rho1: Vector3<T>, rho2: Vector3<T> }
/// ```
///
/// See the `joint-runtime` documentation for the whole language.
#[proc_macro_derive(Joint, attributes(joint))]
pub fn derive_joint(input: proc_macro::TokenStream) -> proc_macro::TokenStream {
    let input = syn::parse_macro_input!(input as syn::DeriveInput);
    expand::derive(&input).into()
}
