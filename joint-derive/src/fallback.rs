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
