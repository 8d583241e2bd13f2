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
mod params;
mod rows;
mod scene;

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

/// Derives `joint_runtime::Scene` (and `SparseJacobian`) for a mechanism: its
/// bodies and joints in attributes, run-time data in fields.
///
/// ```ignore
/// #[derive(Scene)]
/// #[scene(gravity = [0, 0, -9.81])]
/// #[body(link, mass = 1.0, inertia = [0.1, 0.1, 0.01])]
/// #[joint(hinge = revolute(ground, link), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho2 = [0, 0, 0.5])]
/// struct Pendulum;
/// ```
#[proc_macro_derive(Scene, attributes(scene, body, joint))]
pub fn derive_scene(input: proc_macro::TokenStream) -> proc_macro::TokenStream {
    let input = syn::parse_macro_input!(input as syn::DeriveInput);
    scene::derive(&input).into()
}
