//! `#[derive(Joint)]`: the `Joint` impl (and `Singularity`, for joints that
//! have a measure), or `compile_error!` beside a stub impl.

use proc_macro2::{Literal, TokenStream};
use quote::{format_ident, quote};

use crate::engine::emit::ScalarTy;
use crate::front::joint::{self, Declaration, ScalarKind};
use crate::generate::{self, Signature, krate, lints};
use crate::kinematics::{Formulation, Ground};
use crate::lower::{self, Derived};
use crate::second_order::{self, SecondOrderNodes};

/// The derive's entry point: tokens in, tokens out; errors become
/// `compile_error!` beside a stub impl.
pub fn derive(input: &syn::DeriveInput) -> TokenStream {
    match joint::parse(input) {
        Ok(decl) => match lower::derive_rows(&decl) {
            Ok(mut derived) => {
                let second = decl.second_order.then(|| second_order::derive(&mut derived, true, None).dense).flatten();
                print(&decl, &derived, second.as_ref())
            }
            Err(e) => stub(input, e, Some(&decl)),
        },
        Err(failure) => stub(input, failure.error, failure.partial.as_deref()),
    }
}

/// What every impl of `Joint` for a declaration starts with, real or stub.
struct Header {
    /// `impl<..> Joint<S, R, C> for Name<..> where ..`.
    impl_head: TokenStream,
    /// The methods' signature (its prelude touches fields no formula reads).
    signature: Signature,
    /// `type State`, `KIND`, `FORMULATION`.
    items: TokenStream,
    /// The impl's generics (the struct's, a fresh scalar if needed, and bounds).
    generics: syn::Generics,
}

/// The header of the `Joint` impl of `decl` with `rows` rows and `cols` columns.
fn header(decl: &Declaration, rows: usize, cols: usize) -> Header {
    let k = krate();
    let (r, c) = (Literal::usize_unsuffixed(rows), Literal::usize_unsuffixed(cols));
    let scalar = match &decl.scalar {
        ScalarKind::Generic(t) | ScalarKind::Concrete(t) => quote!(#t),
        ScalarKind::Any => quote!(__JointScalar),
    };
    let body_ty = match decl.formulation {
        Formulation::Euler => quote!(#k::EulerBody<#scalar>),
        _ => quote!(#k::OmegaBody<#scalar>),
    };
    let state_ty = match (decl.formulation.is_relative(), decl.ground) {
        (true, _) => quote!(#k::RelativeState<#scalar>),
        (false, Ground::None) => quote!(#k::TwoBodies<#body_ty>),
        (false, _) => quote!(#k::OneBody<#body_ty>),
    };
    // The impl's generics: the struct's own, a fresh scalar parameter if the
    // struct names none, the scalar bound, and a `TimeFunction` bound per driver field.
    let mut generics = decl.generics.clone();
    if let ScalarKind::Any = decl.scalar {
        generics.params.push(syn::parse_quote!(__JointScalar));
    }
    let wc = generics.make_where_clause();
    if !matches!(decl.scalar, ScalarKind::Concrete(_)) {
        wc.predicates.push(syn::parse_quote!(#scalar: #k::__private::SimdRealField + ::core::marker::Copy));
    }
    for ty in &decl.time_fields {
        wc.predicates.push(syn::parse_quote!(#ty: #k::TimeFunction));
    }
    let ident = &decl.ident;
    let (_, ty_generics, _) = decl.generics.split_for_impl();
    let (impl_generics, _, where_clause) = generics.split_for_impl();
    let impl_head = quote!(impl #impl_generics #k::Joint<#scalar, #r, #c> for #ident #ty_generics #where_clause);
    let kind = decl.kind.name;
    let variant = format_ident!("{}", decl.formulation.variant());
    let items = quote! {
        type State = #state_ty;
        const KIND: &'static str = #kind;
        const FORMULATION: #k::Formulation = #k::Formulation::#variant;
    };
    let touch = decl.unused_fields.iter().map(|f| quote!(let _ = &self.#f;));
    let signature = Signature { state: quote!(Self::State), scalar, rows, cols, prelude: quote!(#(#touch)*) };
    Header { impl_head, signature, items, generics }
}

/// The impls for a derived joint.
fn print(decl: &Declaration, d: &Derived, second: Option<&SecondOrderNodes>) -> TokenStream {
    let (rows, cols) = (d.phi.len(), d.kinematics.velocities.len());
    debug_assert_eq!(lower::shape(decl), (rows, cols), "rows and columns from the declaration alone");
    let head = header(decl, rows, cols);
    let (impl_head, signature, items) = (&head.impl_head, &head.signature, &head.items);
    let concrete_f64 = matches!(&decl.scalar, ScalarKind::Concrete(t) if t == "f64");
    let sty = ScalarTy { ty: signature.scalar.clone(), krate: krate(), concrete_f64 };
    let printed = generate::print(d, &sty, None);
    let (ops, methods, lints) = (generate::ops_const(Some(&printed)), signature.methods(Some(&printed)), lints());
    let (second_method, second_ops) = match second {
        Some(nodes) => generate::second_order_method(signature, &printed, nodes),
        None => (TokenStream::new(), 0),
    };
    let second_text = if second.is_some() { format!(", second_order {second_ops}") } else { String::new() };
    let doc = format!(" Operation counts (binary + − ×): {}{second_text}.", printed.ops_text());
    let singularity = singularity(decl, d, &printed, &head);
    quote! {
        #[doc = #doc]
        #lints
        #impl_head {
            #items
            #ops
            #methods
            #second_method
        }
        #singularity
    }
}

/// `impl Singularity` for a joint with a measure.
fn singularity(decl: &Declaration, d: &Derived, printed: &generate::Printed, head: &Header) -> TokenStream {
    let (Some(node), Some(s)) = (d.singularity, &decl.kind.singularity) else { return TokenStream::new() };
    let (body, out, ops) = printed.emit(&[node]);
    let out = &out[0];
    let zero_when = format!("Zero when {}.", s.zero_when);
    let doc = format!(" {ops} operations. {zero_when}");
    let sig = &head.signature;
    let (k, scalar, prelude, lints) = (krate(), &sig.scalar, &sig.prelude, lints());
    let (r, c) = (Literal::usize_unsuffixed(sig.rows), Literal::usize_unsuffixed(sig.cols));
    let ident = &decl.ident;
    let (_, ty_generics, _) = decl.generics.split_for_impl();
    let (impl_generics, _, where_clause) = head.generics.split_for_impl();
    quote! {
        #[doc = #doc]
        #lints
        impl #impl_generics #k::Singularity<#scalar, #r, #c> for #ident #ty_generics #where_clause {
            const ZERO_WHEN: &'static str = #zero_when;
            #[inline]
            fn singularity(&self, state: &Self::State) -> #scalar {
                #prelude #body #out
            }
        }
    }
}

/// `compile_error!` for every error, plus a stub: an impl of `Joint` with the
/// right state type and shape when the joint kind and formulation were
/// understood (so `joint.evaluate(&state)` elsewhere type-checks), a marker impl
/// otherwise.
fn stub(input: &syn::DeriveInput, error: syn::Error, partial: Option<&Declaration>) -> TokenStream {
    let errors = error.to_compile_error();
    let Some(decl) = partial else {
        let ident = &input.ident;
        let (impl_generics, ty_generics, where_clause) = input.generics.split_for_impl();
        return quote! {
            #errors
            impl #impl_generics ::joint_runtime::__private::FallbackJoint for #ident #ty_generics #where_clause {}
        };
    };
    let (rows, cols) = lower::shape(decl);
    let Header { impl_head, signature, items, .. } = header(decl, rows, cols);
    let (ops, methods, lints) = (generate::ops_const(None), signature.methods(None), lints());
    quote! {
        #errors
        #lints
        #impl_head {
            #items
            #ops
            #methods
        }
    }
}
