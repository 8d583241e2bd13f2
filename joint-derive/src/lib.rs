//! `#[derive(Joint)]` and `#[derive(Scene)]`: joint declarations in, constraint
//! code out.
//!
//! Use it through `joint-runtime`, which re-exports it and holds the traits the
//! generated code implements. The arrows run one way: the front end (`front`)
//! reads and checks the attributes, lowering (`lower`) states Φ over the
//! symbolic `engine` through `kinematics` and the `joints` catalogue and
//! derives the rest, `generate` prints the methods, and the two `derives` put
//! their impls together.

mod derives;
mod engine;
mod front;
mod generate;
mod joints;
mod kinematics;
mod lower;
mod normal;
mod products;
mod program;
mod second_order;
mod tree;

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
    derives::joint::derive(&input).into()
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
///
/// `#[scene(..)]` options: `gravity = [x, y, z]`, `coordinates = relative |
/// absolute | both` (relative, a tree of the joints' freedoms, unless the
/// scene says otherwise), `second_order`, and for a robot's file (features `urdf`,
/// `mjcf`) `urdf = "path"` or `mjcf = "path"` (relative to the crate, or else to the source file),
/// `floating_base` (URDF: the root link floats), `file_damping` (URDF: its
/// `<dynamics damping>` in the dynamics), `mimic = coupled |
/// independent` (a file's followers as rows, the default, or as free joints)
/// and `equality = hard` (MJCF: its `<equality>`s as ideal constraints, which
/// departs from MuJoCo; without it they are soft, as MuJoCo makes them).
/// A tree joint in relative coordinates may add `armature = A`,
/// `damping = D` and, on a revolute or translational joint, a spring:
/// `stiffness = K` and `spring_rest = Q0` (its force `−K (q − Q0)`). See the `joint-runtime` documentation for the whole language.
#[proc_macro_derive(Scene, attributes(scene, body, joint, contact))]
pub fn derive_scene(input: proc_macro::TokenStream) -> proc_macro::TokenStream {
    let input = syn::parse_macro_input!(input as syn::DeriveInput);
    derives::scene::derive(&input).into()
}
