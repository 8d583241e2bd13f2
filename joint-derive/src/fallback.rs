//! What the derive emits when the declaration is wrong: the errors, and a stub
//! impl so that the struct's other uses do not pile further errors on the first.

use proc_macro2::TokenStream;
use quote::quote;

/// `compile_error!` for every error, plus an impl of `Joint` whose bodies are
/// never reached (the crate does not compile).
pub fn expand(input: &syn::DeriveInput, error: syn::Error) -> TokenStream {
    let errors = error.to_compile_error();
    let ident = &input.ident;
    let (impl_generics, ty_generics, where_clause) = input.generics.split_for_impl();
    quote! {
        #errors
        #[allow(unused_variables, clippy::all)]
        impl #impl_generics ::joint_runtime::__private::FallbackJoint for #ident #ty_generics #where_clause {}
    }
}
