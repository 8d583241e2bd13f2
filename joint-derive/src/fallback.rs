//! What the derive emits when the declaration is wrong: the errors, and a stub
//! impl so that the struct's other uses do not pile further errors on the first.

use proc_macro2::TokenStream;
use quote::{format_ident, quote};

use crate::dsl::Declaration;
use crate::expand;

/// `compile_error!` for every error, plus a stub: an impl of `Joint` with the
/// right state type and shape when the joint kind and formulation were
/// understood (so `joint.evaluate(&state)` elsewhere type-checks), a marker impl
/// otherwise. Its bodies are never run: the crate does not compile.
pub fn expand(input: &syn::DeriveInput, error: syn::Error, partial: Option<&Declaration>) -> TokenStream {
    let errors = error.to_compile_error();
    let ident = &input.ident;
    let Some(decl) = partial else {
        let (impl_generics, ty_generics, where_clause) = input.generics.split_for_impl();
        return quote! {
            #errors
            impl #impl_generics ::joint_runtime::__private::FallbackJoint for #ident #ty_generics #where_clause {}
        };
    };
    let (rows, cols) = expand::shape(decl);
    let head = expand::impl_header(decl, rows, cols);
    let (impl_head, state_ty, scalar) = (&head.impl_head, &head.state_ty, &head.scalar);
    let (r, c) = (proc_macro2::Literal::usize_unsuffixed(rows), proc_macro2::Literal::usize_unsuffixed(cols));
    let kind = decl.kind.name;
    let variant = format_ident!("{}", decl.formulation.variant());
    let k = quote!(::joint_runtime);
    quote! {
        #errors
        #[allow(unused_variables, clippy::all)]
        #impl_head {
            type State = #state_ty;
            const KIND: &'static str = #kind;
            const FORMULATION: #k::Formulation = #k::Formulation::#variant;
            const OPS: #k::Ops = #k::Ops { phi: 0, phi_t: 0, jacobian: 0, gamma: 0, evaluate: 0 };
            fn phi(&self, state: &Self::State) -> #k::__private::SVector<#scalar, #r> { loop {} }
            fn phi_t(&self, state: &Self::State) -> #k::__private::SVector<#scalar, #r> { loop {} }
            fn jacobian(&self, state: &Self::State) -> #k::__private::SMatrix<#scalar, #r, #c> { loop {} }
            fn gamma(&self, state: &Self::State) -> #k::__private::SVector<#scalar, #r> { loop {} }
            fn evaluate(&self, state: &Self::State) -> #k::Evaluation<#scalar, #r, #c> { loop {} }
        }
    }
}

/// The inherent constants a scene gets beside its bodies' indices.
pub const SIZE_CONSTANTS: [&str; 4] = ["NB", "NV", "ROWS", "BLOCKS"];

/// What a stub `Scene` needs: each body's name and its index constant, and
/// the number of rows.
pub struct SceneShape {
    /// `(name, constant)` per body, in state order.
    pub bodies: Vec<(String, syn::Ident)>,
    /// Rows of all joints.
    pub rows: usize,
}

/// `compile_error!` for every error of a `#[derive(Scene)]`, plus, when the
/// bodies and the number of rows are known, a stub impl of `Scene` of that
/// shape and the inherent constants, so that the scene's uses (a `Simulation`,
/// `Shaft::INPUT`) type-check and one mistake gives one message.
pub fn scene(input: &syn::DeriveInput, error: syn::Error, shape: Option<SceneShape>) -> TokenStream {
    let errors = error.to_compile_error();
    let Some(SceneShape { bodies, rows }) = shape else { return errors };
    let ident = &input.ident;
    let (ig, tg, wc) = input.generics.split_for_impl();
    let lit = proc_macro2::Literal::usize_unsuffixed;
    let (nb, nv, m) = (lit(bodies.len()), lit(6 * bodies.len()), lit(rows));
    let names = bodies.iter().map(|(name, _)| name);
    // A constant that clashes (the error being reported) is left out here.
    let mut seen: Vec<String> = SIZE_CONSTANTS.map(String::from).to_vec();
    let mut indices = Vec::new();
    for (i, (_, constant)) in bodies.iter().enumerate() {
        if !seen.contains(&constant.to_string()) {
            seen.push(constant.to_string());
            let i = lit(i);
            indices.push(quote!(pub const #constant: usize = #i;));
        }
    }
    let k = quote!(::joint_runtime);
    let state = quote!(#k::SystemState<#nb>);
    quote! {
        #errors
        #[automatically_derived]
        #[allow(unused_variables, dead_code, clippy::all)]
        impl #ig #ident #tg #wc {
            #(#indices)*
            pub const NB: usize = #nb;
            pub const NV: usize = #nv;
            pub const ROWS: usize = #m;
            pub const BLOCKS: &'static [#k::RowBlock] = &[];
        }
        #[automatically_derived]
        #[allow(unused_variables, clippy::all)]
        impl #ig #k::Scene<#nb, #nv, #m> for #ident #tg #wc {
            const BODIES: [&'static str; #nb] = [#(#names),*];
            const BLOCKS: &'static [#k::RowBlock] = &[];
            const OPS: #k::Ops = #k::Ops { phi: 0, phi_t: 0, jacobian: 0, gamma: 0, evaluate: 0 };
            fn phi(&self, state: &#state) -> #k::__private::SVector<f64, #m> { loop {} }
            fn phi_t(&self, state: &#state) -> #k::__private::SVector<f64, #m> { loop {} }
            fn jacobian(&self, state: &#state) -> #k::__private::SMatrix<f64, #m, #nv> { loop {} }
            fn gamma(&self, state: &#state) -> #k::__private::SVector<f64, #m> { loop {} }
            fn evaluate(&self, state: &#state) -> #k::Evaluation<f64, #m, #nv> { loop {} }
            fn inertias(&self) -> [#k::BodyInertia; #nb] { loop {} }
            fn gravity(&self) -> #k::nalgebra::Vector3<f64> { loop {} }
        }
    }
}
