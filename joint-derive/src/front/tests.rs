//! The two derives word a shared mistake identically: each case is written
//! once for `#[derive(Joint)]` and once for `#[derive(Scene)]`, and their
//! `compile_error!` messages must be equal (for a missing parameter, up to the
//! hint on how to give it, which differs by derive).

use proc_macro2::{TokenStream, TokenTree};

/// The messages of the `compile_error!`s in `tokens`, in order.
fn messages(tokens: TokenStream) -> Vec<String> {
    let mut out = Vec::new();
    let mut previous: Vec<TokenTree> = Vec::new();
    for t in tokens {
        if let TokenTree::Group(g) = &t
            && matches!(previous.as_slice(), [.., TokenTree::Ident(i), TokenTree::Punct(p)] if i == "compile_error" && p.as_char() == '!')
        {
            let lit: syn::LitStr = syn::parse2(g.stream()).expect("compile_error! holds a string");
            out.push(lit.value());
        }
        previous.push(t);
    }
    out
}

/// The messages of a joint declared with `#[joint(KIND, formulation = omega_body, ARGS)]`
/// and of a scene joint `#[joint(j = KIND(ground, link), ARGS)]`.
fn both(kind: &str, args: &str) -> (Vec<String>, Vec<String>) {
    let joint: syn::DeriveInput =
        syn::parse_str(&format!("#[joint({kind}, formulation = omega_body, {args})] struct J;")).expect("joint input");
    let scene: syn::DeriveInput = syn::parse_str(&format!(
        "#[body(link, mass = 1.0, inertia = [1, 1, 1])] #[joint(j = {kind}(ground, link), {args})] struct S;"
    ))
    .expect("scene input");
    (messages(crate::derives::joint::derive(&joint)), messages(crate::derives::scene::derive(&scene)))
}

#[track_caller]
fn same(kind: &str, args: &str) {
    let (joint, scene) = both(kind, args);
    assert!(!joint.is_empty(), "no error for `{kind}, {args}`");
    assert_eq!(joint, scene, "`{kind}, {args}`");
}

const POINTS: &str = "rho1 = [0, 0, 0], rho2 = [0, 0, 1]";

#[test]
fn unknown_parameter() {
    same("universal", &format!("s = [0, 0, 1], hh = [0, 1, 0], {POINTS}"));
}

#[test]
fn unknown_parameter_with_nothing_missing() {
    same("spherical", &format!("{POINTS}, lenght = 2.0"));
}

#[test]
fn unknown_joint() {
    same("univrsal", POINTS);
}

#[test]
fn zero_axis() {
    same("universal", &format!("s = [0, 0, 0], h = [0, 1, 0], {POINTS}"));
}

#[test]
fn wrong_number_of_components() {
    same("spherical", "rho1 = [0, 0], rho2 = [0, 0, 1]");
}

#[test]
fn number_for_a_vector() {
    same("spherical", "rho1 = 1.0, rho2 = [0, 0, 1]");
}

#[test]
fn non_finite() {
    same("spherical", "rho1 = [0, 1.0 / 0.0, 0], rho2 = [0, 0, 1]");
}

#[test]
fn given_twice() {
    same("spherical", &format!("{POINTS}, rho1 = [1, 0, 0]"));
}

#[test]
fn not_perpendicular() {
    same("revolute", &format!("f = [1, 0, 0], g = [1, 1, 0], h = [0, 0, 1], {POINTS}"));
}

#[test]
fn axis_with_some_derived_vectors() {
    same("revolute", &format!("axis1 = [0, 0, 1], f = [1, 0, 0], axis2 = [0, 0, 1], {POINTS}"));
}

#[test]
fn named_constant_in_an_axis_to_split() {
    same("revolute", &format!("axis1 = [0, 0, TILT], axis2 = [0, 0, 1], {POINTS}"));
}

#[test]
fn missing_parameter_up_to_the_hint() {
    let (joint, scene) = both("universal", &format!("s = [0, 0, 1], {POINTS}"));
    let head =
        |m: &Vec<String>| m.iter().map(|x| x.split(';').next().unwrap_or_default().to_string()).collect::<Vec<_>>();
    assert_eq!(head(&joint), ["missing parameter `h` of `universal`"]);
    assert_eq!(head(&joint), head(&scene));
}

#[test]
fn arithmetic_and_named_constants_are_accepted() {
    let (joint, scene) = both("spherical", "rho1 = [0.007 - 0.00092, -RA, consts::D / 2.0], rho2 = [0, 0, 1]");
    assert!(joint.is_empty() && scene.is_empty(), "{joint:?} {scene:?}");
}

#[test]
fn dropping_unreported_errors_is_a_bug() {
    let result = std::panic::catch_unwind(|| {
        let mut errors = super::context::Errors::new();
        errors.at(proc_macro2::Span::call_site(), "lost");
    });
    assert!(result.is_err(), "an unreported error must not be dropped silently");
}
