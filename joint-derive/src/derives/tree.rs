//! `#[scene(coordinates = relative)]`: the `TreeScene` impl (the joints in
//! tree order, each with its parent and child, joint points and axes) and the
//! alias of its state, `NameTreeState = TreeState<NQ, NV>`. For `relative`
//! nothing of the absolute path is derived or compiled; `coordinates = both`
//! writes both from one declaration. The algorithms themselves are written by
//! the `tree` room (`aba`, `closure`, `contact`, `derivatives`).

use proc_macro2::{Literal, TokenStream};
use quote::{format_ident, quote};

use super::scene::{const_vector, inertia, vector};
use crate::front::resolve::{FieldShape, Source};
use crate::front::scene::{JointDecl, SceneDecl};
use crate::front::tree::{TreeEdge, TreeKind};
use crate::generate::{krate, lints};

/// The tree's sizes: coordinates and velocities.
pub fn sizes(edges: &[TreeEdge]) -> (usize, usize) {
    edges.iter().map(|e| e.kind.sizes()).fold((0, 0), |(q, v), (a, b)| (q + a, v + b))
}

pub use crate::tree::closure::Loops;

/// The closures of a scene with a tree (joints outside it) derived in the
/// tree's coordinates; `None` without a tree or without closures.
pub fn closures(s: &SceneDecl) -> syn::Result<Option<Loops>> {
    match &s.tree {
        Some(edges) => crate::tree::closure::derive(s, edges, sizes(edges)),
        None => Ok(None),
    }
}

/// The `TreeScene` impl and the state alias.
pub fn print(
    input: &syn::DeriveInput,
    s: &SceneDecl,
    edges: &[TreeEdge],
    generics: &syn::Generics,
    loops: Option<&Loops>,
) -> TokenStream {
    let k = krate();
    let nb = Literal::usize_unsuffixed(s.bodies.len());
    let joints = edges.iter().map(|e| match e.joint {
        Some(i) => joint(&s.joints[i], e),
        None => free(s, e),
    });
    let inertias = s.bodies.iter().map(|b| inertia(&b.mass, &b.inertia));
    let gravity = vector(&s.gravity);
    let (nq, nv) = sizes(edges);
    let aba = crate::tree::aba::method(s, edges, nq, nv).map(|(method, ops)| {
        let doc = format!(" The articulated-body algorithm written out: {ops} operations.");
        quote!(#[doc = #doc] #[inline] #method)
    });
    let controller = crate::tree::aba::controller_methods(s, edges, nq, nv);
    // `second_order`: the dynamics' derivatives, what a linearisation needs.
    let written = s.second_order.and_then(|_| crate::tree::aba::written(s, edges));
    let (derivatives, second, fallback) = match &written {
        Some(joints) => {
            let (first, ops) = crate::tree::derivatives::method(s, joints, nq, nv);
            // Past the limit `second_order` changes nothing on a tree alone: say so.
            let fallback = match (&first, s.second_order) {
                (None, Some(at)) if !s.absolute => Some(falls_back(at, ops)),
                _ => None,
            };
            (first, crate::tree::derivatives::second_method(s, joints, (nq, nv), ops), fallback)
        }
        None => (None, None, None),
    };
    let (closure, nc) = loops.map_or((TokenStream::new(), 0), |l| {
        let (mut rows, nc) = crate::tree::closure::print(&l.derived, &l.blocks, l.second.as_ref(), s);
        rows.extend(crate::tree::wrench::print(&l.bodies, s.bodies.len()));
        (rows, nc)
    });
    // A file's gravity compensation (MJCF `gravcomp`), its bodies first.
    let held = s.file.as_ref().map(|f| f.compensation.clone()).unwrap_or_default();
    let compensation = held.iter().any(|&c| c != 0.0).then(|| {
        let all = (0..s.bodies.len()).map(|b| held.get(b).copied().unwrap_or(0.0));
        quote!(fn tree_compensation(&self) -> [f64; #nb] { [#(#all),*] })
    });
    // A file's data, reachable from generic code (`S::STATE_LAYOUT`, `S::LINKS`..).
    let file = s.file.as_ref().map(|data| {
        let layout = super::scene::library_layout(s, data).map(|(name, _)| {
            quote!(const STATE_LAYOUT: ::core::option::Option<#k::robot::StateLayout<#nq, #nv>> =
                ::core::option::Option::Some(Self::#name);)
        });
        quote! {
            #layout
            const LINKS: &'static [#k::robot::LinkFrame] = &Self::LINKS;
            const LIMITS: &'static [#k::robot::JointLimits] = &Self::LIMITS;
            const OPTIONS: #k::robot::FileOptions = Self::OPTIONS;
        }
    });
    let body = quote! {
        #file
        fn tree_joints(&self) -> [#k::relative::TreeJoint; #nb] { [#(#joints),*] }
        fn tree_inertias(&self) -> [#k::BodyInertia; #nb] { [#(#inertias),*] }
        fn tree_gravity(&self) -> #k::nalgebra::Vector3<f64> { #gravity }
        #compensation
        #aba
        #controller
        #derivatives
        #second
        #closure
    };
    let mut out = wrap(input, generics, s.bodies.len(), (nq, nv, nc), body);
    out.extend(fallback);
    out
}

/// A warning at `second_order` (rustc's only channel for a derive's
/// warning on stable: a deprecated item used at the option's span) where
/// the tree's derivatives would take `ops` operations, past what the derive
/// writes out: the runtime's recursion gives them, the same numbers, so the
/// option does nothing on this scene.
fn falls_back(at: proc_macro2::Span, ops: usize) -> TokenStream {
    let limit = crate::tree::derivatives::FIRST_LIMIT;
    let note = format!(
        "`second_order` writes a tree's derivatives out up to {limit} operations; this tree's would take {ops}, so \
         the runtime's recursion gives them (the same numbers, faster at this size) and the option changes \
         nothing here: remove it"
    );
    quote::quote_spanned! {at=>
        const _: () = {
            #[deprecated(note = #note)]
            #[allow(non_upper_case_globals)]
            const second_order: () = ();
            second_order
        };
    }
}

/// The impl around `body` (the stub's too) and the alias.
pub fn wrap(
    input: &syn::DeriveInput,
    generics: &syn::Generics,
    bodies: usize,
    (nq, nv, nc): (usize, usize, usize),
    body: TokenStream,
) -> TokenStream {
    let (k, lints, vis, ident) = (krate(), lints(), &input.vis, &input.ident);
    let lit = Literal::usize_unsuffixed;
    let (nb, nq, nv, nc) = (lit(bodies), lit(nq), lit(nv), lit(nc));
    let (ig, tg, wc) = generics.split_for_impl();
    let alias = format_ident!("{}TreeState", ident);
    let doc = format!(
        " The state of [`{ident}`] in relative coordinates: its tree joints' coordinates and velocities, and the time."
    );
    quote! {
        #[doc = #doc]
        #vis type #alias = #k::relative::TreeState<#nq, #nv>;

        #lints
        impl #ig #k::relative::TreeScene<#nb, #nq, #nv, #nc> for #ident #tg #wc {
            #body
        }
    }
}

/// One `TreeJoint { .. }`.
fn joint(j: &JointDecl, e: &TreeEdge) -> TokenStream {
    let k = krate();
    let name = j.label();
    let (parent, child) = if e.reversed { (j.bodies[1], j.bodies[0]) } else { (j.bodies[0], j.bodies[1]) };
    let parent = match parent {
        Some(i) => {
            let i = Literal::usize_unsuffixed(i);
            quote!(::core::option::Option::Some(#i))
        }
        None => quote!(::core::option::Option::None),
    };
    let child = Literal::usize_unsuffixed(child.unwrap_or(0));
    let (rho1, rho2) = (param(j, "rho1"), param(j, "rho2"));
    let (axis1, axis2) = match e.kind {
        TreeKind::Revolute | TreeKind::Prismatic | TreeKind::Cylindrical | TreeKind::Planar | TreeKind::Fixed => {
            (first_axis(j), param(j, "h"))
        }
        TreeKind::Universal => (param(j, "s"), param(j, "h")),
        TreeKind::Spherical | TreeKind::Free => (zero(), zero()),
    };
    // The second axes that lock a prismatic joint's turn: `g` and `k`.
    let (lock1, lock2) = match e.kind {
        TreeKind::Prismatic | TreeKind::Fixed => (param(j, "g"), param(j, "k")),
        // The parent's first in-plane axis: body 1's `f`; the runtime picks one for body 2.
        TreeKind::Planar => (param(j, "f"), zero()),
        _ => (zero(), zero()),
    };
    let (rho_p, rho_c, axis_p, axis_c) =
        if e.reversed { (rho2, rho1, axis2, axis1) } else { (rho1, rho2, axis1, axis2) };
    let (lock_p, lock_c) = if e.reversed { (lock2, lock1) } else { (lock1, lock2) };
    let (armature, damping) = (j.dynamics.armature, j.dynamics.damping);
    let (stiffness, spring_rest) = (j.dynamics.stiffness, j.dynamics.spring_rest);
    let kind = match e.kind {
        TreeKind::Revolute => quote!(Revolute),
        TreeKind::Spherical => quote!(Spherical),
        TreeKind::Prismatic => quote!(Prismatic),
        TreeKind::Universal => quote!(Universal),
        TreeKind::Fixed => quote!(Fixed),
        TreeKind::Cylindrical => quote!(Cylindrical),
        TreeKind::Planar => quote!(Planar),
        TreeKind::Free => quote!(Free),
    };
    quote! {
        #k::relative::TreeJoint {
            name: #name,
            kind: #k::relative::TreeJointKind::#kind,
            parent: #parent,
            child: #child,
            rho_parent: #rho_p,
            rho_child: #rho_c,
            axis_parent: #axis_p,
            axis_child: #axis_c,
            lock_parent: #lock_p,
            lock_child: #lock_c,
            armature: #armature,
            damping: #damping,
            stiffness: #stiffness,
            spring_rest: #spring_rest,
        }
    }
}

/// The name of body `body`'s free joint: the file's (Pinocchio's `root_joint`
/// for a URDF's floating base, an MJCF `<freejoint name>`), so that the tree
/// and the library layout name it alike; `free(BODY)` where no file names it.
pub(super) fn floating_name(s: &SceneDecl, body: usize) -> String {
    let named = s
        .file
        .as_ref()
        .and_then(|f| f.library.1.iter().find(|j| j.kind == "free" && j.body == body && !j.name.is_empty()));
    match named {
        Some(j) => j.name.clone(),
        None => format!("free({})", s.bodies[body].label()),
    }
}

/// The free joint of a floating body (named by [`floating_name`]): from the
/// ground's origin to its centre of mass.
fn free(s: &SceneDecl, e: &TreeEdge) -> TokenStream {
    let k = krate();
    let name = floating_name(s, e.ends.1);
    let child = Literal::usize_unsuffixed(e.ends.1);
    let z = zero();
    quote! {
        #k::relative::TreeJoint {
            name: #name,
            kind: #k::relative::TreeJointKind::Free,
            parent: ::core::option::Option::None,
            child: #child,
            rho_parent: #z,
            rho_child: #z,
            axis_parent: #z,
            axis_child: #z,
            lock_parent: #z,
            lock_child: #z,
            armature: 0.0,
            damping: 0.0,
            stiffness: 0.0,
            spring_rest: 0.0,
        }
    }
}

fn zero() -> TokenStream {
    let k = krate();
    quote!(#k::nalgebra::Vector3::zeros())
}

/// A vector parameter: numbers, a field, or a part of an `AxisFrame` field.
fn param(j: &JointDecl, name: &str) -> TokenStream {
    match j.params.iter().find(|p| p.name == name).map(|p| &p.source) {
        Some(Source::Const(v, _)) => const_vector(v),
        Some(Source::Field { member, shape: FieldShape::FramePart(part), .. }) => {
            let part = format_ident!("{}", part.field());
            quote!(self.#member.#part)
        }
        Some(Source::Field { member, .. }) => quote!(self.#member),
        None => zero(),
    }
}

/// The revolute axis on the joint's first body: `f × g` (`axis1`, made unit
/// by `perpendicular_pair`), folded when both are numbers.
fn first_axis(j: &JointDecl) -> TokenStream {
    let known = |n: &str| j.params.iter().find(|p| p.name == n).and_then(|p| p.source.known());
    if let (Some(f), Some(g)) = (known("f"), known("g"))
        && f.len() == 3
        && g.len() == 3
    {
        let c = crate::front::geometry::cross3([f[0], f[1], f[2]], [g[0], g[1], g[2]]);
        let numbers: Vec<_> = c.iter().map(|x| crate::front::attr::Number::Known(*x)).collect();
        return const_vector(&numbers);
    }
    let (f, g) = (param(j, "f"), param(j, "g"));
    quote!((#f).cross(&(#g)))
}
