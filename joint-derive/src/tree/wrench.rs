//! The closures' rows on their bodies: what a loop's reactions need in
//! relative coordinates.
//!
//! In the tree's coordinates a closure's force acts on the joints as `Jᵀλ`,
//! which does not say how it loads each body (a four-bar's relative twist
//! at its cut spans three of the six directions). So the rows are lowered a
//! second time, as the absolute scene lowers them (`lower::derive_scene`):
//! on the bodies' own frames, each body's centre and Euler parameters an
//! input and `ṙ`, `ω'` (its own components) its velocities, giving each
//! row's blocks `J_b = ∂Φ̇/∂(ṙ, ω')` on its two bodies. At the tree's state
//! these are the same rows (`J = J_b X(q)`, the chain rule through the
//! tree's kinematics), so the closure's wrench on its bodies is `J_bᵀ λ`
//! with the tree's `λ`: force in the world's components through the centre,
//! torque in the body's, as the absolute engine's reactions are. Rows the
//! tree keeps by construction are left out here too (`Closing::Rows`); a
//! coupling's row acts on two joints, not on bodies, and has no block.

use proc_macro2::TokenStream;
use quote::quote;

use crate::engine::grad;
use crate::engine::graph::Id;
use crate::front::scene::SceneDecl;
use crate::generate::{krate, matrix_tokens, print_none};
use crate::kinematics::{Formulation, Kinematics};
use crate::lower::{Derived, Naming, lower_rows, param_nodes};
use crate::tree::closure::{Closing, weld_rows};

/// The closures' rows on their bodies: `derived.jacobian` holds each row's
/// twelve entries (its first body's `ṙ, ω'`, then its second's; zeros for
/// the ground or a coupling), `ends` each block's two bodies.
pub struct BodyRows {
    /// The rows' twelve body columns, on their own kinematics.
    pub derived: Derived,
    /// Each closure block's bodies, `None` for the ground.
    pub ends: Vec<[Option<usize>; 2]>,
}

/// The rows of `closings` (in the tree's order), then the couplings' and
/// the contacts', on the bodies' frames.
pub fn derive(s: &SceneDecl, closings: &[Closing]) -> syn::Result<BodyRows> {
    let names: Vec<String> = s.bodies.iter().map(|b| b.label().replace('[', "_").replace(']', "")).collect();
    let mut k = Kinematics::scene(Formulation::OmegaBody, &names);
    let poses: Vec<_> = (0..s.bodies.len()).map(|b| k.pose(b)).collect();
    let mut bindings = Vec::new();
    let (mut lowered_rows, mut ends) = (Vec::new(), Vec::new());
    for closing in closings {
        let (bodies, phi) = match closing {
            Closing::Weld { bodies, points, torquescale } => {
                (*bodies, weld_rows(&mut k, &poses, *bodies, *points, *torquescale))
            }
            Closing::Rows { joint, kept } => {
                let j = &s.joints[*joint];
                k.connect(j.bodies[0], j.bodies[1]);
                let prefix = j.prefix();
                let values = param_nodes(&mut k, j.kind, &j.params, Naming::ByField { joint: &prefix }, &mut bindings);
                let lowered = lower_rows(&mut k, j.kind, &values, &[], j.kind_span);
                ([j.bodies[0], j.bodies[1]], kept.iter().map(|&n| lowered.phi[n]).collect())
            }
        };
        lowered_rows.extend(phi.into_iter().map(|row| (row, bodies)));
        ends.push(bodies);
    }
    // The body-frame rules, as the absolute scene derives its J with: built
    // once every row is lowered, their memo shared by all rows.
    let mut rules = k.body_view().unwrap_or_else(|| k.rules.clone());
    let velocities = k.velocities.clone();
    let mut rows = Vec::new();
    for (row, bodies) in lowered_rows {
        let rate = rules.dt(&mut k.g, row);
        let full = grad(&mut k.g, rate, &velocities);
        rows.push(twelve(&mut k, full, bodies));
    }
    for _ in &s.couplings {
        let zero = k.g.zero();
        rows.push(vec![zero; 12]);
        ends.push([None, None]);
    }
    for c in &s.contacts {
        let bodies = c.ends.map(|e| e.body);
        for (row, _) in crate::tree::contact::rows(&mut k, &poses, c) {
            rows.push(twelve(&mut k, row, bodies));
        }
        ends.push(bodies);
    }
    let derived = Derived {
        kinematics: k,
        phi: Vec::new(),
        phi_t: Vec::new(),
        jacobian: rows,
        gamma: Vec::new(),
        bindings,
        singularity: None,
    };
    Ok(BodyRows { derived, ends })
}

/// A row of the scene's `6 NB` columns cut to its two bodies' twelve.
fn twelve(k: &mut Kinematics, row: Vec<Id>, bodies: [Option<usize>; 2]) -> Vec<Id> {
    let zero = k.g.zero();
    bodies.iter().flat_map(|b| (0..6).map(|c| b.map_or(zero, |b| row[6 * b + c])).collect::<Vec<_>>()).collect()
}

/// `const CLOSURE_ENDS` and `fn closure_body_rows(&self, state) -> SMatrix<f64, NC, 12>`.
pub fn print(rows: &BodyRows, nb: usize) -> TokenStream {
    let k = krate();
    let d = &rows.derived;
    let nc = d.jacobian.len();
    let outputs: Vec<Id> = (0..12).flat_map(|c| d.jacobian.iter().map(move |row| row[c])).collect();
    let (body, outs, ops) = print_none(d, &crate::tree::aba::scalar()).emit(&outputs);
    let matrix = matrix_tokens(&outs, nc);
    let some = |b: Option<usize>| match b {
        Some(b) => quote!(::core::option::Option::Some(#b)),
        None => quote!(::core::option::Option::None),
    };
    let ends = rows.ends.iter().map(|[a, b]| {
        let (a, b) = (some(*a), some(*b));
        quote!([#a, #b])
    });
    let doc = format!(" The closures' rows on their bodies' `ṙ, ω'`, derived by the engine: {ops} operations.");
    let (nc, nb) = (proc_macro2::Literal::usize_unsuffixed(nc), proc_macro2::Literal::usize_unsuffixed(nb));
    quote! {
        const CLOSURE_ENDS: &'static [[::core::option::Option<usize>; 2]] = &[#(#ends),*];
        #[doc = #doc]
        #[inline]
        fn closure_body_rows(&self, state: &#k::SystemState<#nb>) -> #k::nalgebra::SMatrix<f64, #nc, 12> {
            #body
            #matrix
        }
    }
}
