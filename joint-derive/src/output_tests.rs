//! Expansion snapshots: what `#[derive(Joint)]` generates for representative
//! declarations, pretty-printed, so a change to the engine shows up as a
//! readable diff of generated code (after zerocopy-derive's `output_tests`).
//!
//! Each snapshot starts with a comment line holding the operation counts of the
//! generated impl, then the expansion formatted by `prettyplease`; the input
//! declaration is recorded in the snapshot's `description`.
//!
//! After an intended change to the generated code, re-accept the snapshots with
//!
//! ```text
//! INSTA_UPDATE=always cargo test -p joint-derive --lib output_tests
//! ```
//!
//! and review the diff of `src/snapshots/` before committing.

use quote::ToTokens;
use syn::parse_quote;

/// The derive input as readable source, for the snapshot's description.
///
/// `prettyplease` breaks `#[joint(..., s = [0, 0, 1])]` over many lines (its
/// arguments are not a standard meta), so the attributes are printed on one
/// line each from their tokens and only the struct itself goes through it.
fn describe(input: &syn::DeriveInput) -> String {
    let mut out = String::new();
    for attr in &input.attrs {
        let tokens = attr.meta.to_token_stream().to_string();
        let tidy = tokens.replace(" ,", ",").replace("[ ", "[").replace(" ]", "]");
        out.push_str(&format!("#[{}]\n", tidy_calls(&tidy)));
    }
    let mut item = input.clone();
    item.attrs.clear();
    match syn::parse2::<syn::File>(item.into_token_stream()) {
        Ok(file) => out.push_str(&prettyplease::unparse(&file)),
        Err(e) => panic!("the derive input does not parse as a Rust file: {e}"),
    }
    out
}

/// `rows (dot (s, h))` → `rows(dot(s, h))`: no space between a name and its
/// parenthesis (token streams print one).
fn tidy_calls(tokens: &str) -> String {
    let mut out = String::with_capacity(tokens.len());
    let mut chars = tokens.chars().peekable();
    while let Some(c) = chars.next() {
        let after_name = out.chars().last().is_some_and(|p: char| p.is_alphanumeric() || p == '_');
        if c == ' ' && chars.peek() == Some(&'(') && after_name {
            continue;
        }
        out.push(c);
    }
    out
}

/// The `#[doc = "Operation counts ..."]` line of the generated impl, if any.
fn op_counts(file: &syn::File) -> Option<String> {
    file.items.iter().find_map(|item| {
        let syn::Item::Impl(imp) = item else { return None };
        imp.attrs.iter().find_map(|attr| match &attr.meta {
            syn::Meta::NameValue(nv) if nv.path.is_ident("doc") => match &nv.value {
                syn::Expr::Lit(syn::ExprLit { lit: syn::Lit::Str(s), .. }) => {
                    let text = s.value();
                    let text = text.trim();
                    (text.starts_with("Operation counts") || text.contains("Operations:")).then(|| text.to_owned())
                }
                _ => None,
            },
            _ => None,
        })
    })
}

/// Expands `input`, pretty-prints the result under a header line with the
/// operation counts, and compares it with the stored snapshot `name`.
#[track_caller]
fn check(name: &str, input: syn::DeriveInput) {
    check_with(name, input, crate::derives::joint::derive);
}

fn check_with(name: &str, input: syn::DeriveInput, derive: fn(&syn::DeriveInput) -> proc_macro2::TokenStream) {
    let output = derive(&input);
    let file = match syn::parse2::<syn::File>(output) {
        Ok(file) => file,
        Err(e) => panic!("the expansion of `{name}` does not parse as a Rust file: {e}"),
    };
    let header = match op_counts(&file) {
        Some(counts) => format!("// {counts}"),
        None => "// No operation counts: the declaration is rejected (compile_error! plus stub impl).".to_owned(),
    };
    let text = format!("{header}\n\n{}", prettyplease::unparse(&file));

    let mut settings = insta::Settings::clone_current();
    settings.set_description(describe(&input));
    settings.set_omit_expression(true);
    settings.bind(|| insta::assert_snapshot!(name, text));
}

/// `spherical` with `rho1`, `rho2` as fields, in `formulation`.
fn spherical(formulation: &str) -> syn::DeriveInput {
    let f = syn::Ident::new(formulation, proc_macro2::Span::call_site());
    parse_quote! {
        #[joint(spherical, formulation = #f)]
        struct Ball<T> {
            rho1: Vector3<T>,
            rho2: Vector3<T>,
        }
    }
}

/// `universal` with `s`, `h`, `rho1`, `rho2` as fields, in `formulation`.
fn universal(formulation: &str) -> syn::DeriveInput {
    let f = syn::Ident::new(formulation, proc_macro2::Span::call_site());
    parse_quote! {
        #[joint(universal, formulation = #f)]
        struct Cardan<T> {
            s: Vector3<T>,
            h: Vector3<T>,
            rho1: Vector3<T>,
            rho2: Vector3<T>,
        }
    }
}

/// `universal_translational` with `s`, `h`, `b`, `c`, `rho1`, `rho2` as fields,
/// in `formulation`.
fn universal_translational(formulation: &str) -> syn::DeriveInput {
    let f = syn::Ident::new(formulation, proc_macro2::Span::call_site());
    parse_quote! {
        #[joint(universal_translational, formulation = #f)]
        struct CardanSlider<T> {
            s: Vector3<T>,
            h: Vector3<T>,
            b: Vector3<T>,
            c: Vector3<T>,
            rho1: Vector3<T>,
            rho2: Vector3<T>,
        }
    }
}

// --- spherical, every formulation, every parameter a field -------------------

#[test]
fn spherical_euler() {
    check("spherical_euler", spherical("euler"));
}

#[test]
fn spherical_omega_inertial() {
    check("spherical_omega_inertial", spherical("omega_inertial"));
}

#[test]
fn spherical_omega_body() {
    check("spherical_omega_body", spherical("omega_body"));
}

#[test]
fn spherical_relative_b1() {
    check("spherical_relative_b1", spherical("relative_b1"));
}

#[test]
fn spherical_relative_b2() {
    check("spherical_relative_b2", spherical("relative_b2"));
}

// --- universal, every formulation, every parameter a field -------------------

#[test]
fn universal_euler() {
    check("universal_euler", universal("euler"));
}

#[test]
fn universal_omega_inertial() {
    check("universal_omega_inertial", universal("omega_inertial"));
}

#[test]
fn universal_omega_body() {
    check("universal_omega_body", universal("omega_body"));
}

#[test]
fn universal_relative_b1() {
    check("universal_relative_b1", universal("relative_b1"));
}

#[test]
fn universal_relative_b2() {
    check("universal_relative_b2", universal("relative_b2"));
}

// --- universal_translational, every formulation, every parameter a field -----

#[test]
fn universal_translational_euler() {
    check("universal_translational_euler", universal_translational("euler"));
}

#[test]
fn universal_translational_omega_inertial() {
    check("universal_translational_omega_inertial", universal_translational("omega_inertial"));
}

#[test]
fn universal_translational_omega_body() {
    check("universal_translational_omega_body", universal_translational("omega_body"));
}

#[test]
fn universal_translational_relative_b1() {
    check("universal_translational_relative_b1", universal_translational("relative_b1"));
}

#[test]
fn universal_translational_relative_b2() {
    check("universal_translational_relative_b2", universal_translational("relative_b2"));
}

// --- constants folded into the generated code ---------------------------------

#[test]
fn universal_const_axes_omega_body() {
    check(
        "universal_const_axes_omega_body",
        parse_quote! {
            #[joint(universal, formulation = omega_body, s = [0, 0, 1], h = [1, 0, 0])]
            struct Cardan<T> {
                rho1: Vector3<T>,
                rho2: Vector3<T>,
            }
        },
    );
}

#[test]
fn universal_const_axes_euler() {
    check(
        "universal_const_axes_euler",
        parse_quote! {
            #[joint(universal, formulation = euler, s = [0, 0, 1], h = [1, 0, 0])]
            struct Cardan<T> {
                rho1: Vector3<T>,
                rho2: Vector3<T>,
            }
        },
    );
}

#[test]
fn universal_grounded_body1_omega_inertial() {
    check(
        "universal_grounded_body1_omega_inertial",
        parse_quote! {
            #[joint(universal, formulation = omega_inertial, ground = body1, s = [0, 0, 1], rho1 = [0, 0, 0])]
            struct Grounded<T> {
                h: Vector3<T>,
                rho2: Vector3<T>,
            }
        },
    );
}

#[test]
fn universal_translational_const_sliding_direction_omega_body() {
    check(
        "universal_translational_const_sliding_direction_omega_body",
        parse_quote! {
            #[joint(universal_translational, formulation = omega_body, d = [1, 0, 0])]
            struct CardanSlider<T> {
                s: Vector3<T>,
                h: Vector3<T>,
                rho1: Vector3<T>,
                rho2: Vector3<T>,
            }
        },
    );
}

// --- concrete scalar ------------------------------------------------------------

#[test]
fn universal_f64_omega_body() {
    check(
        "universal_f64_omega_body",
        parse_quote! {
            #[joint(universal, formulation = omega_body)]
            struct Cardan {
                s: Vector3<f64>,
                h: Vector3<f64>,
                rho1: Vector3<f64>,
                rho2: Vector3<f64>,
            }
        },
    );
}

#[test]
fn spherical_f64_relative_b1() {
    check(
        "spherical_f64_relative_b1",
        parse_quote! {
            #[joint(spherical, formulation = relative_b1)]
            struct Ball {
                rho1: Vector3<f64>,
                rho2: Vector3<f64>,
            }
        },
    );
}

// --- rejected declarations --------------------------------------------------------

#[test]
fn error_unknown_joint_kind() {
    check(
        "error_unknown_joint_kind",
        parse_quote! {
            #[joint(hinge, formulation = omega_body)]
            struct Hinge<T> {
                rho1: Vector3<T>,
                rho2: Vector3<T>,
            }
        },
    );
}

// --- the rest of the catalogue, one representative each ------------------------

#[test]
fn revolute_omega_body() {
    check(
        "revolute_omega_body",
        parse_quote! {
            #[joint(revolute, formulation = omega_body)]
            struct Hinge<T> {
                f: Vector3<T>,
                g: Vector3<T>,
                h: Vector3<T>,
                rho1: Vector3<T>,
                rho2: Vector3<T>,
            }
        },
    );
}

#[test]
fn revolute_const_axes_omega_body() {
    check(
        "revolute_const_axes_omega_body",
        parse_quote! {
            #[joint(revolute, formulation = omega_body, axis1 = [0, 0, 1], axis2 = [0, 0, 1])]
            struct Hinge<T> {
                rho1: Vector3<T>,
                rho2: Vector3<T>,
            }
        },
    );
}

#[test]
fn translational_omega_body() {
    check(
        "translational_omega_body",
        parse_quote! {
            #[joint(translational, formulation = omega_body)]
            struct Prism<T> {
                f: Vector3<T>,
                g: Vector3<T>,
                h: Vector3<T>,
                k: Vector3<T>,
                rho1: Vector3<T>,
                rho2: Vector3<T>,
            }
        },
    );
}

#[test]
fn distance_omega_body() {
    check(
        "distance_omega_body",
        parse_quote! {
            #[joint(distance, formulation = omega_body)]
            struct Rod<T> {
                rho1: Vector3<T>,
                rho2: Vector3<T>,
                length: T,
            }
        },
    );
}

#[test]
fn point_in_plane_omega_body() {
    check(
        "point_in_plane_omega_body",
        parse_quote! {
            #[joint(point_in_plane, formulation = omega_body)]
            struct Contact<T> {
                n: Vector3<T>,
                rho1: Vector3<T>,
                rho2: Vector3<T>,
            }
        },
    );
}

#[test]
fn rotational_driver_omega_body() {
    check(
        "rotational_driver_omega_body",
        parse_quote! {
            #[joint(rotational_driver, formulation = omega_body)]
            struct Motor<T, F> {
                f: Vector3<T>,
                g: Vector3<T>,
                k: Vector3<T>,
                theta: F,
            }
        },
    );
}

#[test]
fn translational_driver_euler() {
    check(
        "translational_driver_euler",
        parse_quote! {
            #[joint(translational_driver, formulation = euler)]
            struct Actuator<T, F> {
                h: Vector3<T>,
                rho1: Vector3<T>,
                rho2: Vector3<T>,
                x: F,
            }
        },
    );
}

// --- user-written rows -------------------------------------------------------------

#[test]
fn rows_constant_angle_omega_body() {
    check(
        "rows_constant_angle_omega_body",
        parse_quote! {
            #[joint(rows(dot(s, h) - cos(alpha)), formulation = omega_body)]
            struct ConstantAngle<T> {
                #[joint(body1)]
                s: Vector3<T>,
                #[joint(body2)]
                h: Vector3<T>,
                alpha: T,
            }
        },
    );
}

#[test]
fn rows_cable_time_omega_body() {
    check(
        "rows_cable_time_omega_body",
        parse_quote! {
            #[joint(rows(norm2(d) - l * l), formulation = omega_body)]
            struct Cable<T, F> {
                rho1: Vector3<T>,
                rho2: Vector3<T>,
                #[joint(time)]
                l: F,
            }
        },
    );
}

#[test]
fn rows_spherical_dot1_omega_body() {
    check(
        "rows_spherical_dot1_omega_body",
        parse_quote! {
            #[joint(rows(spherical, dot1(s, h)), formulation = omega_body)]
            struct Cardan<T> {
                #[joint(body1)]
                s: Vector3<T>,
                #[joint(body2)]
                h: Vector3<T>,
                rho1: Vector3<T>,
                rho2: Vector3<T>,
            }
        },
    );
}

/// A scene: one graph for a driven Cardan shaft (bearings, the joint, a motor),
/// with a field-based bent bearing axis; shows the system functions, the
/// compile-time sparse pattern and the per-joint row blocks.
#[test]
fn scene_cardan_shaft() {
    check_with(
        "scene_cardan_shaft",
        parse_quote! {
            #[scene(gravity = [0, 0, -9.81], coordinates = absolute)]
            #[body(input, mass = 1.0, inertia = [0.01, 0.1, 0.1])]
            #[body(output, mass = 1.0, inertia = [0.01, 0.1, 0.1])]
            #[joint(bearing_in = revolute(ground, input), axis1 = [1, 0, 0], axis2 = [1, 0, 0], rho1 = [0, 0, 0], rho2 = [0, 0, 0])]
            #[joint(bearing_out = revolute(ground, output), axis1 = bend, axis2 = [1, 0, 0], rho1 = out_centre, rho2 = [0, 0, 0])]
            #[joint(cardan = universal(input, output), s = [0, 1, 0], h = [0, 0, 1], rho1 = [1, 0, 0], rho2 = [-1, 0, 0])]
            #[joint(motor = rotational_driver(ground, input), axis1 = [1, 0, 0], axis2 = [1, 0, 0], theta = drive)]
            struct Shaft<F> {
                bend: AxisFrame<f64>,
                out_centre: Vector3<f64>,
                drive: F,
            }
        },
        crate::derives::scene::derive,
    );
}

/// A four-bar in relative coordinates: the tree's written-out dynamics and
/// the closing joint `d` as closure rows in the tree's angles (two of its
/// five rows: the planar tree keeps the other three, folded to zero).
#[test]
fn scene_four_bar_relative() {
    check_with(
        "scene_four_bar_relative",
        parse_quote! {
            #[scene(gravity = [0, -9.81, 0], coordinates = relative)]
            #[body(crank, mass = 1.0, inertia = [0.1, 0.1, 0.1])]
            #[body(coupler, mass = 1.5, inertia = [0.1, 0.15, 0.2])]
            #[body(rocker, mass = 2.0, inertia = [0.2, 0.1, 0.2])]
            #[joint(a = revolute(ground, crank), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0, 0, 0], rho2 = [0, -0.5, 0])]
            #[joint(b = revolute(crank, coupler), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0, 0.5, 0], rho2 = [-0.5, 0, 0])]
            #[joint(c = revolute(coupler, rocker), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0.5, 0, 0], rho2 = [0, 0.5, 0])]
            #[joint(d = revolute(rocker, ground), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0, -0.5, 0], rho2 = [1, 0, 0])]
            struct FourBar;
        },
        crate::derives::scene::derive,
    );
}

/// The derive's own time on chains of 80, 160 and 320 bodies (a build-time
/// regression guard to run by hand: `cargo test -p joint-derive --lib
/// time_large_scene -- --ignored --nocapture`; a debug build, as cargo builds
/// proc macros for release builds too).
#[test]
#[ignore]
fn time_large_scene() {
    for n in [80usize, 160, 320] {
        let src = format!(
            "#[body(link[{n}], mass = 1.0, inertia = [0.0833, 0.0833, 0.001])] \
             #[joint(top = spherical(ground, link[0]), rho1 = [0, 0, 0], rho2 = [0, 0, 0.5])] \
             #[joint(hinge[i in 1..{n}] = spherical(link[i - 1], link[i]), rho1 = [0, 0, -0.5], rho2 = [0, 0, 0.5])] struct Chain;"
        );
        let input: syn::DeriveInput = syn::parse_str(&src).expect("parses");
        let t = std::time::Instant::now();
        let out = crate::derives::scene::derive(&input);
        println!("N={n}: derive {:.2} s, {} bytes of tokens", t.elapsed().as_secs_f64(), out.to_string().len());
    }
}

// --- second-order terms ------------------------------------------------------

/// A point on a body-fixed line, in `omega_body`, with its second-order terms:
/// what `second_order` adds to the impl.
#[test]
fn point_on_line_second_order() {
    check(
        "point_on_line_second_order",
        parse_quote! {
            #[joint(point_on_line, formulation = omega_body, second_order)]
            struct Rail<T> {
                f: Vector3<T>,
                g: Vector3<T>,
                rho1: Vector3<T>,
                rho2: Vector3<T>,
            }
        },
    );
}
