//! `#[derive(Scene)]`: the `Scene` and `SparseJacobian` impls of a mechanism and
//! its inherent constants (bodies by name, sizes), or `compile_error!` beside a
//! stub of the same shape.
//!
//! Beside Φ, Φ_t, J (dense and CSR) and γ, `SparseJacobian` carries the block
//! structure the runtime's absolute engine runs on, fixed here: each joint's
//! bodies, the minimum-degree order and factor pattern of the joint blocks of
//! `J M⁻¹ Jᵀ` (`ELIMINATION`, `FACTOR_STARTS`, `FACTOR_BELOW`), the implicit
//! integrators' saddle-point order and pattern (`KKT_ORDER`, ...) and the
//! sizes of every array (`Factor`, `Kkt`), so that the runtime needs no
//! allocator; and, under their limits, the straight-line `normal_blocks_into`,
//! `j_mul_into`, `jt_mul_into` and factor programs. Past 20 000 dense Jacobian
//! entries the dense `jacobian` and `evaluate` are written over the sparse
//! values (`__private::dense_from_csr`), so that the code grows with the
//! nonzeros. Every scene also gets its `Simulate` impl, which names the one
//! `Simulation`'s engine: `AbsoluteSimulation`, or `TreeSimulation` for
//! `coordinates = relative` (`derives/tree.rs` writes the tree's impl); a scene
//! from a robot file gets its `LINKS`, `LIMITS` and library layout
//! (`MUJOCO` or `PINOCCHIO`).

use proc_macro2::{Literal, TokenStream};
use quote::quote;

use super::tree::Loops;
use crate::engine::emit::ScalarTy;
use crate::front::attr::Number;
use crate::front::files::{FileData, FileLink, FileShape, Library};

use crate::front::resolve::Source;
use crate::front::scene::{self, BodyName, Quantity, SIZE_CONSTANTS, SceneDecl, SceneShape};
use crate::generate::{self, Printed, Signature, krate, lints};
use crate::lower::{self, Block, Derived};
use crate::second_order::{self, Terms};

/// The derive's entry point.
pub fn derive(input: &syn::DeriveInput) -> TokenStream {
    let parsed = scene::parse(input);
    // A file the scene was read from is included, so that cargo rebuilds
    // the crate when the file changes.
    let files = parsed.as_ref().map_or_else(|_| Vec::new(), |s| s.files.clone());
    let mut out = expand(input, parsed);
    out.extend(files.iter().map(|path| {
        quote!(
            const _: &[u8] = ::core::include_bytes!(#path);
        )
    }));
    out
}

/// The impls of a parsed declaration, or the stub.
fn expand(input: &syn::DeriveInput, parsed: syn::Result<SceneDecl>) -> TokenStream {
    // A tree's closures (joints outside it), derived in its coordinates.
    let loops = match parsed.as_ref().map(super::tree::closures) {
        Ok(Err(e)) => {
            // The declaration parsed: the stub takes the tree's own sizes
            // (shape() alone counts every tree-kind joint, loops included).
            let mut shape = scene::shape(input);
            if let (Some(shape), Ok(SceneDecl { tree: Some(edges), .. })) = (&mut shape, &parsed) {
                shape.tree = Some(super::tree::sizes(edges));
            }
            return stub(input, e, shape);
        }
        Ok(Ok(loops)) => loops,
        Err(_) => None,
    };
    // `coordinates = relative`: the tree alone, nothing of the absolute path
    // derived or compiled.
    if let Ok(s @ SceneDecl { absolute: false, tree: Some(edges), .. }) = &parsed {
        return tree_only(input, s, edges, loops.as_ref());
    }
    let derived = parsed.and_then(|s| lower::derive_scene(&s).map(|d| (s, d)));
    let with_second = derived.map(|(s, (mut d, blocks))| {
        let second = s.second_order.map(|_| {
            // Above the limit only the sparse blocks: a dense K of a large scene
            // would not fit on a stack.
            let dense = d.phi.len() * d.kinematics.velocities.len() <= DENSE_LIMIT;
            second_order::derive(&mut d, dense, Some(&joint_columns(&s, &blocks)))
        });
        (s, d, blocks, second)
    });
    match with_second {
        Ok((s, d, blocks, second)) => print(input, &s, &d, &blocks, second.as_ref(), loops.as_ref()),
        Err(e) => stub(input, e, scene::shape(input)),
    }
}

/// Each joint's rows and the bodies it connects (the ground left out, each
/// body once): the sparse second-order layout.
fn joint_columns(s: &SceneDecl, blocks: &[Block]) -> Vec<(std::ops::Range<usize>, Vec<usize>)> {
    s.joints
        .iter()
        .zip(blocks)
        .map(|(j, b)| {
            let mut bodies: Vec<usize> = j.bodies.iter().flatten().copied().collect();
            bodies.dedup();
            (b.start..b.start + b.rows, bodies)
        })
        .collect()
}

/// The sizes every impl of a scene shares.
struct Sizes {
    nb: Literal,
    nv: Literal,
    m: Literal,
    signature: Signature,
}

fn sizes(bodies: usize, rows: usize) -> Sizes {
    let k = krate();
    let lit = Literal::usize_unsuffixed;
    let nb = lit(bodies);
    let state = quote!(#k::SystemState<#nb>);
    let signature = Signature { state, scalar: quote!(f64), rows, cols: 6 * bodies, prelude: TokenStream::new() };
    Sizes { nb, nv: lit(6 * bodies), m: lit(rows), signature }
}

/// The inherent constants: each body's index by name (an array for a row of
/// bodies), and the sizes.
fn inherent(bodies: &[BodyName], z: &Sizes, blocks: &TokenStream) -> TokenStream {
    let k = krate();
    let indices = body_indices(bodies);
    let (nb, nv, m) = (&z.nb, &z.nv, &z.m);
    quote! {
        #(#indices)*
        /// Number of bodies (`NB` of `Scene<NB, NV, M>`).
        pub const NB: usize = #nb;
        /// Velocity columns, 6 per body (`NV`).
        pub const NV: usize = #nv;
        /// Constraint rows (`M`).
        pub const ROWS: usize = #m;
        /// Each joint's block of rows, in row order (as `Scene::BLOCKS`).
        pub const BLOCKS: &'static [#k::RowBlock] = #blocks;
    }
}

/// Each body's index by name (an array for a row of bodies).
fn body_indices(bodies: &[BodyName]) -> Vec<TokenStream> {
    // A constant that clashes (an error being reported) is left out.
    let mut seen: Vec<String> = SIZE_CONSTANTS.map(String::from).to_vec();
    let mut indices = Vec::new();
    for (i, b) in bodies.iter().enumerate() {
        if seen.contains(&b.constant.to_string()) {
            continue;
        }
        seen.push(b.constant.to_string());
        let constant = &b.constant;
        if b.element {
            let members: Vec<usize> =
                (i..bodies.len()).filter(|&x| bodies[x].element && bodies[x].constant == b.constant).collect();
            let n = Literal::usize_unsuffixed(members.len());
            let members = members.into_iter().map(Literal::usize_unsuffixed);
            let name = b.label.split('[').next().unwrap_or_default();
            let doc = format!(" The indices of bodies `{name}[0]`, `{name}[1]`, ... in the state's `bodies`.");
            indices.push(quote!(#[doc = #doc] pub const #constant: [usize; #n] = [#(#members),*];));
        } else {
            let (doc, i) =
                (format!(" The index of body `{}` in the state's `bodies`.", b.label), Literal::usize_unsuffixed(i));
            indices.push(quote!(#[doc = #doc] pub const #constant: usize = #i;));
        }
    }
    indices
}

/// `type NameState = SystemState<NB>`, beside the struct with its visibility:
/// the state of the scene without its size spelled out (an inherent associated
/// type is not stable Rust; strum's `NameIter` is the precedent for a named item).
fn state_alias(input: &syn::DeriveInput, nb: &Literal) -> TokenStream {
    let (k, vis) = (krate(), &input.vis);
    let alias = quote::format_ident!("{}State", input.ident);
    let doc = format!(" The state of [`{}`]: its bodies' positions and velocities, and the time.", input.ident);
    quote! {
        #[doc = #doc]
        #vis type #alias = #k::SystemState<#nb>;
    }
}

fn print(
    input: &syn::DeriveInput,
    s: &SceneDecl,
    d: &Derived,
    blocks: &[Block],
    second: Option<&Terms>,
    loops: Option<&Loops>,
) -> TokenStream {
    let k = krate();
    let z = sizes(s.bodies.len(), d.phi.len());
    let sty = ScalarTy { ty: quote!(f64), krate: k.clone(), concrete_f64: true };
    // The sparse Jacobian first (its printer's bindings do not depend on the methods).
    let (mut sparse, csr, sparse_ops) = sparse_jacobian(d, &generate::print_none(d, &sty), &z);
    let nnz = Literal::usize_unsuffixed(csr.columns.len());
    let elimination = elimination(s);
    sparse.extend(block_structure(s, &elimination, &nnz, &z.m));
    sparse.extend(kkt_structure(s));
    let rows = joint_rows(s, blocks);
    sparse.extend(terms_type(&rows));
    let normal = crate::normal::method(&csr, &rows, &elimination, s.bodies.len(), &k);
    let mut normal_text = match normal {
        Some((method, ops)) => {
            sparse.extend(method);
            format!(", normal blocks {ops}")
        }
        None => String::new(),
    };
    if let Some((methods, calls)) = crate::program::methods(&rows, &elimination) {
        sparse.extend(methods);
        normal_text.push_str(&format!(", factor program {calls} block operations"));
    }
    sparse.extend(crate::products::methods(&csr, 6 * s.bodies.len()));
    let large = (d.phi.len() * 6 * s.bodies.len() > DENSE_LIMIT).then(|| from_sparse(d, &z, &nnz, sparse_ops));
    let printed = generate::print(d, &sty, large.as_ref());
    let blocks = blocks.iter().map(|b| {
        let (name, start, rows) = (&b.name, Literal::usize_unsuffixed(b.start), Literal::usize_unsuffixed(b.rows));
        quote!(#k::RowBlock { name: #name, start: #start, rows: #rows })
    });
    let blocks = quote!(&[#(#blocks),*]);
    let bodies = s.body_names();
    let body_names = bodies.iter().map(|b| &b.label);
    let inherent = inherent(&bodies, &z, &blocks);
    let inertias = s.bodies.iter().map(|b| inertia(&b.mass, &b.inertia));
    let gravity = vector(&s.gravity);
    let points = joint_points(s);
    let ident = &input.ident;
    let generics = generics_of(input, s);
    let tree = s.tree.as_ref().map(|edges| super::tree::print(input, s, edges, &generics, loops));
    let (ig, tg, wc) = generics.split_for_impl();
    let (second_method, helpers, second_text) = second_order_methods(&z, &printed, second);
    let doc = format!(
        " {} bodies, {} rows, {} columns; {nnz} structurally nonzero Jacobian entries. Operations: {}, sparse jacobian {sparse_ops}{normal_text}{second_text}.",
        s.bodies.len(),
        d.phi.len(),
        6 * s.bodies.len(),
        printed.ops_text()
    );
    let (nb, nv, m, lints) = (&z.nb, &z.nv, &z.m, lints());
    let (ops, methods) = (generate::ops_const(Some(&printed)), z.signature.methods(Some(&printed)));
    let alias = state_alias(input, nb);
    // Contacts are rows of the tree alone: a `both` scene that has them runs
    // on the tree, where they hold (the absolute impls stay, for pictures).
    let engine = match (&s.tree, s.contacts.is_empty()) {
        (Some(edges), false) => {
            let (nq, nv) = super::tree::sizes(edges);
            Engine::Tree([s.bodies.len(), nq, nv, loops.map_or(0, |l| l.derived.phi.len())])
        }
        _ => Engine::Absolute([s.bodies.len(), 6 * s.bodies.len(), d.phi.len(), csr.columns.len()]),
    };
    let simulate = simulate(input, &generics, engine);
    let file = file_constants(input, &generics, s);
    let visuals = s.file.as_ref().map(|_| quote!(const VISUALS: &'static [#k::robot::Visual] = &Self::VISUALS;));
    quote! {
        #alias
        #tree
        #simulate
        #file

        #[doc = #doc]
        #lints
        impl #ig #k::Scene<#nb, #nv, #m> for #ident #tg #wc {
            const BODIES: [&'static str; #nb] = [#(#body_names),*];
            const BLOCKS: &'static [#k::RowBlock] = #blocks;
            #ops
            #methods
            #second_method
            fn inertias(&self) -> [#k::BodyInertia; #nb] { [#(#inertias),*] }
            fn gravity(&self) -> #k::nalgebra::Vector3<f64> { #gravity }
            fn joint_points(&self, visit: &mut dyn FnMut(#k::JointPoint)) { #(#points)* }
            #visuals
        }

        /// The scene's sizes and its bodies by name, without spelling out
        /// `Scene<NB, NV, ROWS>`.
        #lints
        impl #ig #ident #tg #wc { #inherent #helpers }

        #lints
        impl #ig #k::SparseJacobian<#nb, #nnz> for #ident #tg #wc { #sparse }
    }
}

/// The dense `second_order` method, the sparse `second_order_values` one
/// with its helpers, and their operation counts for the doc line.
fn second_order_methods(
    z: &Sizes,
    printed: &generate::Printed<'_>,
    second: Option<&Terms>,
) -> (TokenStream, TokenStream, String) {
    let (mut second_method, second_ops) = match second.and_then(|t| t.dense.as_ref()) {
        Some(nodes) => generate::second_order_method(&z.signature, printed, nodes),
        None => (TokenStream::new(), 0),
    };
    let (values, helpers, values_ops) = match second.and_then(|t| t.sparse.as_ref()) {
        Some(nodes) => generate::second_order_values_method(&z.signature, printed, nodes),
        None => (TokenStream::new(), TokenStream::new(), 0),
    };
    second_method.extend(values);
    let second_text = match second {
        Some(t) if t.dense.is_some() => format!(", second_order {second_ops}, second_order_values {values_ops}"),
        Some(_) => format!(", second_order_values {values_ops}"),
        None => String::new(),
    };
    (second_method, helpers, second_text)
}

/// The engine the one `Simulation` runs for a scene: absolute coordinates
/// (`NB, NV, M, NNZ`) or the tree (`NB, NQ, NV, NC`).
enum Engine {
    Absolute([usize; 4]),
    Tree([usize; 4]),
}

/// `Simulate` for the scene: the engine its coordinates call for, so that
/// `Simulation::new(&scene, ..)` makes it whichever the scene declares.
fn simulate(input: &syn::DeriveInput, generics: &syn::Generics, engine: Engine) -> TokenStream {
    let (k, lints, ident) = (krate(), lints(), &input.ident);
    let (_, tg, _) = generics.split_for_impl();
    let mut with = generics.clone();
    with.params.insert(0, syn::parse_quote!('__a));
    with.params.push(syn::parse_quote!(__L));
    let lit = |n: [usize; 4]| n.map(Literal::usize_unsuffixed);
    let nb = Literal::usize_unsuffixed(match engine {
        Engine::Absolute([nb, ..]) | Engine::Tree([nb, ..]) => nb,
    });
    let wc = with.make_where_clause();
    wc.predicates.push(syn::parse_quote!(#ident #tg: '__a));
    wc.predicates.push(syn::parse_quote!(__L: #k::dynamics::AppliedLoads<#nb>));
    let (ig, _, wc) = with.split_for_impl();
    let (ty, error, make) = match engine {
        Engine::Absolute(n) => {
            let [nb, nv, m, nnz] = lit(n);
            (
                quote!(#k::dynamics::AbsoluteSimulation<'__a, Self, __L, #nb, #nv, #m, #nnz>),
                quote!(#k::analysis::AnalysisError),
                quote!(#k::dynamics::AbsoluteSimulation::new(self, loads, springs, options)),
            )
        }
        Engine::Tree(n) => {
            let [nb, nq, nv, nc] = lit(n);
            (
                quote!(#k::relative::TreeSimulation<'__a, Self, #nb, #nq, #nv, #nc, __L>),
                quote!(#k::relative::TreeError),
                quote!(#k::relative::TreeSimulation::new(self)?.with_springs(springs)?.with_loads(loads).with_options(options)),
            )
        }
    };
    quote! {
        #lints
        impl #ig #k::dynamics::Simulate<'__a, __L> for #ident #tg #wc {
            type Engine = #ty;
            type Error = #error;
            fn engine(
                &'__a self,
                loads: __L,
                springs: &'__a [#k::dynamics::SpringDamper],
                options: #k::dynamics::SimulationOptions,
            ) -> ::core::result::Result<Self::Engine, Self::Error> {
                #make
            }
        }
    }
}

/// A robot file's links and limits as the scene's inherent constants
/// `LINKS` and `LIMITS`, by the file's names.
fn file_constants(input: &syn::DeriveInput, generics: &syn::Generics, s: &SceneDecl) -> TokenStream {
    let Some(data) = &s.file else { return TokenStream::new() };
    let (k, lints, ident) = (krate(), lints(), &input.ident);
    let (ig, tg, wc) = generics.split_for_impl();
    let some = |x: Option<TokenStream>| match x {
        Some(x) => quote!(::core::option::Option::Some(#x)),
        None => quote!(::core::option::Option::None),
    };
    let links = data.links.iter().map(link_frame);
    let visuals: Vec<TokenStream> = data.links.iter().flat_map(visuals).collect();
    let nv = visuals.len();
    let limits = data.limits.iter().map(|(name, l)| {
        let range = some(l.range.map(|(a, b)| quote!((#a, #b))));
        let [effort, velocity, damping, friction, armature] =
            [l.effort, l.velocity, l.damping, l.friction, l.armature].map(|x| some(x.map(|x| quote!(#x))));
        quote! {
            #k::robot::JointLimits {
                name: #name, range: #range, effort: #effort, velocity: #velocity, damping: #damping,
                friction: #friction, armature: #armature,
            }
        }
    });
    let (nl, nj) = (data.links.len(), data.limits.len());
    let library = library_layout(s, data).map(|(_, constant)| constant);
    let timestep = some(data.options.timestep.map(|h| quote!(#h)));
    let integrator = some(data.options.integrator.as_deref().map(|name| {
        let variant = match name {
            "Euler" => quote!(Euler),
            "RK4" => quote!(Rk4),
            "implicit" => quote!(Implicit),
            _ => quote!(ImplicitFast),
        };
        quote!(#k::robot::FileIntegrator::#variant)
    }));
    quote! {
        /// What the robot's file says beyond the dynamics, by its names.
        #lints
        impl #ig #ident #tg #wc {
            /// Every link's frame on its body, in the file's order.
            pub const LINKS: [#k::robot::LinkFrame; #nl] = [#(#links),*];
            /// What each link looks like (URDF `<visual>`, MJCF `<geom>`), on its body, in the file's order.
            pub const VISUALS: [#k::robot::Visual; #nv] = [#(#visuals),*];
            /// Each moving joint's limits and friction from the file, in the file's order.
            pub const LIMITS: [#k::robot::JointLimits; #nj] = [#(#limits),*];
            /// What the file asks of the step (MJCF's `<option timestep integrator>`): data.
            pub const OPTIONS: #k::robot::FileOptions =
                #k::robot::FileOptions { timestep: #timestep, integrator: #integrator };
            #library
        }
    }
}

/// A link's frame on its body, as the runtime's `LinkFrame`.
fn link_frame(l: &FileLink) -> TokenStream {
    let k = krate();
    let body = match l.body {
        Some(b) => quote!(::core::option::Option::Some(#b)),
        None => quote!(::core::option::Option::None),
    };
    let (name, r) = (&l.name, &l.rotation);
    let columns = (0..3).map(|c| {
        let (x, y, z) = (r[0][c], r[1][c], r[2][c]);
        quote!([#x, #y, #z])
    });
    let [x, y, z] = l.origin;
    quote!(#k::robot::LinkFrame { name: #name, body: #body, rotation: [#(#columns),*], origin: [#x, #y, #z] })
}

/// A link's visuals, each on its body, as the runtime's `Visual`s.
fn visuals(l: &FileLink) -> Vec<TokenStream> {
    let k = krate();
    let body = match l.body {
        Some(b) => quote!(::core::option::Option::Some(#b)),
        None => quote!(::core::option::Option::None),
    };
    let triple = |[x, y, z]: [f64; 3]| quote!([#x, #y, #z]);
    let on = |v| crate::front::files::on_body(&(l.rotation, l.origin), v);
    l.visuals
        .iter()
        .map(|v| {
            let (r, origin) = on(v);
            let columns = (0..3).map(|c| triple([r[0][c], r[1][c], r[2][c]]));
            let origin = triple(origin);
            let shape = match &v.shape {
                FileShape::Box(h) => { let h = triple(*h); quote!(Box(#h)) }
                FileShape::Sphere(r) => quote!(Sphere(#r)),
                FileShape::Cylinder(r, h) => quote!(Cylinder(#r, #h)),
                FileShape::Capsule(r, h) => quote!(Capsule(#r, #h)),
                FileShape::Ellipsoid(a) => { let a = triple(*a); quote!(Ellipsoid(#a)) }
                FileShape::Plane([x, y]) => quote!(Plane([#x, #y])),
                FileShape::Mesh { file, scale } => { let s = triple(*scale); quote!(Mesh { file: #file, scale: #s }) }
            };
            let rgba = match v.rgba {
                Some([r, g, b, a]) => quote!(::core::option::Option::Some([#r, #g, #b, #a])),
                None => quote!(::core::option::Option::None),
            };
            quote! {
                #k::robot::Visual {
                    body: #body, rotation: [#(#columns),*], origin: #origin, shape: #k::robot::Shape::#shape, rgba: #rgba,
                }
            }
        })
        .collect()
}

/// `MUJOCO` (an MJCF file) or `PINOCCHIO` (a URDF): the file's moving
/// joints in the library's order, where each sits in its vectors and in the
/// tree's: the constant's name and its definition. Nothing without a tree
/// (absolute coordinates).
pub(super) fn library_layout(s: &SceneDecl, data: &FileData) -> Option<(TokenStream, TokenStream)> {
    let (Some(edges), (library, joints)) = (&s.tree, &data.library) else { return None };
    let k = krate();
    // The tree's offsets, joint by joint in its order.
    let (mut tree_q, mut tree_v, mut placed) = (0, 0, Vec::new());
    for e in edges {
        placed.push((e.joint, e.ends.1, tree_q, tree_v));
        let (nq, nv) = e.kind.sizes();
        (tree_q, tree_v) = (tree_q + nq, tree_v + nv);
    }
    let (mut q_at, mut v_at, mut rows) = (0_usize, 0_usize, Vec::new());
    for j in joints {
        let found = placed.iter().find(|p| match j.joint {
            Some(i) => p.0 == Some(i),
            None => p.0.is_none() && p.1 == j.body,
        });
        let (Some(&(_, _, tq, tv)), Some(link)) = (found, data.links.get(j.link)) else { return None };
        let (kind, (nq, nv)) = match j.kind {
            "free" => (quote!(Free), (7, 6)),
            "ball" => (quote!(Ball), (4, 3)),
            "continuous" => (quote!(Continuous), (2, 1)),
            "slide" => (quote!(Slide), (1, 1)),
            _ => (quote!(Hinge), (1, 1)),
        };
        let name = if j.kind == "free" { super::tree::floating_name(s, j.body) } else { j.name.clone() };
        let (link, offset) = (link_frame(link), j.offset);
        rows.push(quote! {
            #k::robot::LibraryJoint {
                name: #name, kind: #k::robot::LibraryJointKind::#kind, q_at: #q_at, v_at: #v_at,
                tree_q_at: #tq, tree_v_at: #tv, offset: #offset, link: #link,
            }
        });
        (q_at, v_at) = (q_at + nq, v_at + nv);
    }
    // A scene that adds moving joints to its file's has freedoms no library
    // vector holds: no layout.
    if v_at != tree_v {
        return None;
    }
    let (constant, variant, doc) = match library {
        Library::MuJoCo => (
            quote!(MUJOCO),
            quote!(MuJoCo),
            " The state as MuJoCo writes it (`qpos`, `qvel`, `qacc`, `qfrc_*`): converted both ways.",
        ),
        Library::Pinocchio => (
            quote!(PINOCCHIO),
            quote!(Pinocchio),
            " The state as Pinocchio writes it (`q`, `v`, `a`, `tau`): converted both ways.",
        ),
    };
    let definition = quote! {
        #[doc = #doc]
        pub const #constant: #k::robot::StateLayout<#tree_q, #tree_v> = #k::robot::StateLayout::__from_derive(
            #k::robot::Library::#variant, #q_at, #v_at, &[#(#rows),*],
        );
    };
    Some((constant, definition))
}

/// The struct's generics with a `TimeFunction` bound on each time-function field's type.
fn generics_of(input: &syn::DeriveInput, s: &SceneDecl) -> syn::Generics {
    let k = krate();
    let mut generics = input.generics.clone();
    let wc = generics.make_where_clause();
    for ty in &s.time_types {
        wc.predicates.push(syn::parse_quote!(#ty: #k::TimeFunction));
    }
    generics
}

/// A `coordinates = relative` scene: the bodies' indices, `NB`, the absolute
/// state's alias (for the conversions) and the tree.
fn tree_only(
    input: &syn::DeriveInput,
    s: &SceneDecl,
    edges: &[crate::front::tree::TreeEdge],
    loops: Option<&Loops>,
) -> TokenStream {
    let (ident, lints) = (&input.ident, lints());
    let generics = generics_of(input, s);
    let (ig, tg, wc) = generics.split_for_impl();
    let nb = Literal::usize_unsuffixed(s.bodies.len());
    let indices = body_indices(&s.body_names());
    let alias = state_alias(input, &nb);
    let tree = super::tree::print(input, s, edges, &generics, loops);
    let (nq, nv) = super::tree::sizes(edges);
    let nc = loops.map_or(0, |l| l.derived.phi.len());
    let simulate = simulate(input, &generics, Engine::Tree([s.bodies.len(), nq, nv, nc]));
    let file = file_constants(input, &generics, s);
    quote! {
        #alias
        #tree
        #simulate
        #file

        /// The scene's bodies by name and their number.
        #lints
        impl #ig #ident #tg #wc {
            #(#indices)*
            /// Number of bodies.
            pub const NB: usize = #nb;
        }
    }
}

/// Above this many entries of `J` (`M × NV`, about a 33-body chain), the dense
/// `jacobian` and `evaluate` are written over the sparse Jacobian, so that the
/// generated code and the build grow with the nonzeros, not with `M × NV`.
const DENSE_LIMIT: usize = 20_000;

/// The dense methods of a large scene over its sparse ones.
fn from_sparse(d: &Derived, z: &Sizes, nnz: &Literal, sparse_ops: usize) -> generate::FromSparse {
    let (k, nb, nv, m) = (krate(), &z.nb, &z.nv, &z.m);
    let scene = quote!(<Self as #k::Scene<#nb, #nv, #m>>);
    let sparse = quote!(<Self as #k::SparseJacobian<#nb, #nnz>>);
    let jacobian = quote! {
        #k::__private::dense_from_csr(#sparse::ROW_STARTS, &#sparse::COLUMNS, &#sparse::jacobian_values(self, state))
    };
    let evaluate = quote! {
        #k::Evaluation { phi: #scene::phi(self, state), jacobian: #scene::jacobian(self, state), gamma: #scene::gamma(self, state) }
    };
    let count = |outputs: &[crate::engine::Id]| crate::engine::emit::count_ops(&d.kinematics.g, outputs);
    let ops = [sparse_ops, count(&d.phi) + sparse_ops + count(&d.gamma)];
    generate::FromSparse { jacobian, evaluate, ops }
}

/// Each joint's rows and bodies, in `BLOCKS` order.
fn joint_rows(s: &SceneDecl, blocks: &[Block]) -> Vec<crate::normal::JointRows> {
    s.joints
        .iter()
        .zip(blocks)
        .map(|(j, b)| crate::normal::JointRows { start: b.start, rows: b.rows, bodies: j.bodies })
        .collect()
}

/// The sparse form: the entries of J that are not structurally zero, row by
/// row (CSR), and the function that computes them. Returns the items, the
/// pattern (with the entries the engine folded to constants) and the
/// function's operation count.
fn sparse_jacobian(d: &Derived, printed: &Printed, z: &Sizes) -> (TokenStream, crate::normal::Csr, usize) {
    let mut row_starts = vec![0usize];
    let (mut columns, mut entries) = (Vec::new(), Vec::new());
    for row in &d.jacobian {
        for (c, &e) in row.iter().enumerate() {
            if d.kinematics.g.as_const(e) != Some(0.0) {
                columns.push(c);
                entries.push(e);
            }
        }
        row_starts.push(columns.len());
    }
    let nnz = Literal::usize_unsuffixed(columns.len());
    let (body, values, ops) = printed.emit(&entries);
    let constants = entries.iter().map(|&e| d.kinematics.g.as_const(e)).collect();
    let csr = crate::normal::Csr { row_starts, columns, constants };
    let row_starts = csr.row_starts.iter().map(|&x| Literal::usize_unsuffixed(x));
    let columns = csr.columns.iter().map(|&x| Literal::usize_unsuffixed(x));
    let state = &z.signature.state;
    let items = quote! {
        const ROW_STARTS: &'static [usize] = &[#(#row_starts),*];
        const COLUMNS: [usize; #nnz] = [#(#columns),*];
        #[inline]
        fn jacobian_values_into(&self, state: &#state, out: &mut [f64; #nnz]) { #body *out = [#(#values),*]; }
    };
    (items, csr, ops)
}

/// The elimination order of the joint blocks of `J M⁻¹ Jᵀ` (two blocks are
/// coupled when their joints share a body) and its fill: fixed here.
fn elimination(s: &SceneDecl) -> crate::engine::order::Elimination {
    let adjacency: Vec<Vec<usize>> = s
        .joints
        .iter()
        .map(|a| {
            let shares =
                |b: &crate::front::scene::JointDecl| a.bodies.iter().flatten().any(|x| b.bodies.contains(&Some(*x)));
            s.joints.iter().enumerate().filter(|(_, b)| shares(b)).map(|(i, _)| i).collect()
        })
        .collect();
    crate::engine::order::minimum_degree(&adjacency)
}

/// The joints' bodies and the elimination order `e` of the joint blocks of
/// `J M⁻¹ Jᵀ`, with the pattern of its block factor: fixed at compile time.
fn block_structure(s: &SceneDecl, e: &crate::engine::order::Elimination, nnz: &Literal, m: &Literal) -> TokenStream {
    let bodies = |j: &crate::front::scene::JointDecl| {
        j.bodies.map(|b| match b {
            Some(i) => {
                let i = Literal::usize_unsuffixed(i);
                quote!(::core::option::Option::Some(#i))
            }
            None => quote!(::core::option::Option::None),
        })
    };
    let block_bodies = s.joints.iter().map(|j| {
        let [a, b] = bodies(j);
        quote!([#a, #b])
    });
    let mut starts = vec![0];
    let mut below = Vec::new();
    for b in &e.below {
        below.extend(b.iter().copied());
        starts.push(below.len());
    }
    let [n, slots, updates, shared] = factor_sizes(s, e).map(Literal::usize_unsuffixed);
    let (order, starts, below) = (usize_slice(&e.order), usize_slice(&starts), usize_slice(&below));
    let k = krate();
    quote! {
        const BLOCK_BODIES: &'static [[::core::option::Option<usize>; 2]] = &[#(#block_bodies),*];
        const ELIMINATION: &'static [usize] = #order;
        const FACTOR_STARTS: &'static [usize] = #starts;
        const FACTOR_BELOW: &'static [usize] = #below;
        /// Joint blocks, factor slots, scheduled updates, shared-body terms,
        /// Jacobian entries, rows.
        type Factor = #k::absolute::FactorArrays<#n, #slots, #updates, #shared, #nnz, #m>;
    }
}

/// The implicit integrators' saddle-point matrix `[S Jᵀ; J T 0]`: bodies
/// (nodes `0..NB`) and joints (node `NB + j`), bodies coupled where a joint
/// joins two, eliminated by minimum degree with each joint after its bodies
/// (every pivot block is then a nonsingular saddle-point matrix): its order,
/// its fill and the sizes of its arrays, fixed here so that the runtime
/// stores it without an allocator. The runtime's `absolute/kkt/pattern.rs`
/// finds the same pattern for a scene with more couplings (springs).
fn kkt_structure(s: &SceneDecl) -> TokenStream {
    let nb = s.bodies.len();
    let n = nb + s.joints.len();
    let (mut adjacency, mut after) = (vec![Vec::new(); n], vec![Vec::new(); n]);
    for (j, joint) in s.joints.iter().enumerate() {
        let bodies: Vec<usize> = joint.bodies.iter().flatten().copied().collect();
        for &b in &bodies {
            adjacency[nb + j].push(b);
            adjacency[b].push(nb + j);
        }
        if let [a, b] = bodies[..] {
            adjacency[a].push(b);
            adjacency[b].push(a);
        }
        after[nb + j] = bodies;
    }
    let e = crate::engine::order::minimum_degree_after(&adjacency, &after);
    let (mut starts, mut below) = (vec![0], Vec::new());
    for b in &e.below {
        below.extend(b.iter().copied());
        starts.push(below.len());
    }
    let updates: usize = e.below.iter().map(|b| b.len() * b.len()).sum();
    let [n, a, u] = [n, below.len(), updates].map(Literal::usize_unsuffixed);
    let (order, starts, below, k) = (usize_slice(&e.order), usize_slice(&starts), usize_slice(&below), krate());
    quote! {
        const KKT_ORDER: &'static [usize] = #order;
        const KKT_STARTS: &'static [usize] = #starts;
        const KKT_BELOW: &'static [usize] = #below;
        /// Nodes, block pairs below the diagonal, Schur updates.
        type Kkt<__Entry: #k::absolute::KktEntry> = #k::absolute::KktArrays<__Entry, #n, #a, #u>;
    }
}

/// Where the implicit integrators keep the second-order terms: as many as
/// the runtime's `SecondOrderLayout` lays out (each joint's stiffness block,
/// `w × w` over its `w` columns, six per distinct body, and four row
/// sections of `w` per row).
fn terms_type(rows: &[crate::normal::JointRows]) -> TokenStream {
    let len: usize = rows
        .iter()
        .map(|j| {
            let w = match j.bodies {
                [Some(a), Some(b)] if a != b => 12,
                [None, None] => 0,
                _ => 6,
            };
            w * w + 4 * w * j.rows
        })
        .sum();
    let (len, k) = (Literal::usize_unsuffixed(len), krate());
    quote! {
        /// The second-order terms' count.
        type Terms = #k::absolute::TermArray<#len>;
    }
}

/// `&[a, b, ...]`, a constant slice of indices.
fn usize_slice(v: &[usize]) -> TokenStream {
    let v = v.iter().map(|&x| Literal::usize_unsuffixed(x));
    quote!(&[#(#v),*])
}

/// The block factor's sizes, as the runtime's schedule counts them: joint
/// blocks; slots (diagonal and below, fill included); updates (each column
/// `j` with `m` slots below the diagonal updates `m (m + 1) / 2` later
/// slots); the bodies each slot's two joints share, side by side.
fn factor_sizes(s: &SceneDecl, e: &crate::engine::order::Elimination) -> [usize; 4] {
    let n = s.joints.len();
    let slots = n + e.below.iter().map(Vec::len).sum::<usize>();
    let updates = e.below.iter().map(|b| b.len() * (b.len() + 1) / 2).sum();
    let bodies = |position: usize| e.order.get(position).and_then(|&j| s.joints.get(j)).map(|j| j.bodies);
    let shares = |i: usize, k: usize| match (bodies(i), bodies(k)) {
        (Some(a), Some(b)) => a.iter().flatten().map(|x| b.iter().filter(|y| **y == Some(*x)).count()).sum(),
        _ => 0,
    };
    let shared = (0..n)
        .map(|k| shares(k, k) + e.below.get(k).map_or(0, |b| b.iter().map(|&i| shares(i, k)).sum::<usize>()))
        .sum();
    [n, slots, updates, shared]
}

/// A number as generated code writes it.
fn number(n: &Number) -> TokenStream {
    match n {
        Number::Known(x) => {
            let x = Literal::f64_suffixed(*x);
            quote!(#x)
        }
        Number::Named(e) => generate::named_f64(e),
    }
}

/// A 3-vector of numbers (missing components zero; the parser checked the
/// length) or a field.
pub(super) fn vector(q: &Quantity) -> TokenStream {
    match q {
        Quantity::Const(v) => const_vector(v),
        Quantity::Field(f) => quote!(self.#f),
    }
}

pub(super) fn const_vector(v: &[Number]) -> TokenStream {
    let k = krate();
    let [x, y, z] = [0, 1, 2].map(|i| v.get(i).map_or_else(|| quote!(0.0f64), number));
    quote!(#k::nalgebra::Vector3::new(#x, #y, #z))
}

/// `BodyInertia { mass, inertia }`: principal moments or six entries.
pub(super) fn inertia(mass: &Quantity, inertia: &Quantity) -> TokenStream {
    let k = krate();
    let mass = match mass {
        Quantity::Const(v) => v.first().map_or_else(|| quote!(1.0f64), number),
        Quantity::Field(f) => quote!(self.#f),
    };
    let inertia = match inertia {
        Quantity::Const(v) if v.len() == 6 => {
            let [xx, yy, zz, xy, xz, yz] = [0, 1, 2, 3, 4, 5].map(|i| number(&v[i]));
            quote!(#k::nalgebra::Matrix3::new(#xx, #xy, #xz, #xy, #yy, #yz, #xz, #yz, #zz))
        }
        q => {
            let v = vector(q);
            quote!(#k::nalgebra::Matrix3::from_diagonal(&#v))
        }
    };
    quote!(#k::BodyInertia { mass: #mass, inertia: #inertia })
}

/// One `visit(JointPoint { .. })` per joint point (`rho1`, `rho2`) in declaration
/// order: what a trajectory recorder draws. A point on the ground is inertial.
fn joint_points(s: &SceneDecl) -> Vec<TokenStream> {
    let k = krate();
    let mut calls = Vec::new();
    for j in &s.joints {
        let name = j.label();
        for (param, body) in [("rho1", j.bodies[0]), ("rho2", j.bodies[1])] {
            let Some(p) = j.params.iter().find(|p| p.name == param) else { continue };
            let point = match &p.source {
                Source::Const(v, _) => const_vector(v),
                Source::Field { member, .. } => quote!(self.#member),
            };
            let body = match body {
                Some(i) => {
                    let i = Literal::usize_unsuffixed(i);
                    quote!(::core::option::Option::Some(#i))
                }
                None => quote!(::core::option::Option::None),
            };
            calls.push(quote!(visit(#k::JointPoint { joint: #name, body: #body, point: #point });));
        }
    }
    calls
}

/// A robot file's constants in a stub, empty (the file did not read): so
/// that a program that uses them (`Robot::MUJOCO.state_from(..)`) gets the
/// file's error alone. `tree`: the stub's tree sizes, for the layout.
fn stub_file_constants(format: &str, tree: Option<(usize, usize)>) -> TokenStream {
    let k = krate();
    let layout = tree.map(|(nq, nv)| {
        let (nq, nv) = (Literal::usize_unsuffixed(nq), Literal::usize_unsuffixed(nv));
        let (constant, library) =
            if format == "urdf" { (quote!(PINOCCHIO), quote!(Pinocchio)) } else { (quote!(MUJOCO), quote!(MuJoCo)) };
        quote! {
            /// The library's state layout (none: the file did not read).
            pub const #constant: #k::robot::StateLayout<#nq, #nv> =
                #k::robot::StateLayout::__from_derive(#k::robot::Library::#library, 0, 0, &[]);
        }
    });
    quote! {
        /// Every link's frame (none: the file did not read).
        pub const LINKS: [#k::robot::LinkFrame; 0] = [];
        /// What each link looks like (none: the file did not read).
        pub const VISUALS: [#k::robot::Visual; 0] = [];
        /// Each moving joint's limits (none: the file did not read).
        pub const LIMITS: [#k::robot::JointLimits; 0] = [];
        /// What the file asks of the step (nothing: it did not read).
        pub const OPTIONS: #k::robot::FileOptions = #k::robot::FileOptions { timestep: ::core::option::Option::None, integrator: ::core::option::Option::None };
        #layout
    }
}

/// `compile_error!` for every error, plus, when the bodies and the number of
/// rows are known, a stub `Scene` (and `SparseJacobian`) of that shape and the
/// inherent constants, so
/// that the scene's uses (a `Simulation`, `Shaft::INPUT`) type-check and one
/// mistake gives one message.
fn stub(input: &syn::DeriveInput, error: syn::Error, shape: Option<SceneShape>) -> TokenStream {
    let errors = error.to_compile_error();
    let Some(SceneShape { bodies, rows, tree, absolute, file }) = shape else { return errors };
    let (k, z, lints) = (krate(), sizes(bodies.len(), rows), lints());
    let ident = &input.ident;
    let (ig, tg, wc) = input.generics.split_for_impl();
    let names = bodies.iter().map(|b| &b.label);
    let inherent = inherent(&bodies, &z, &quote!(&[]));
    let file = file.map(|format| stub_file_constants(format, tree.filter(|_| !absolute)));
    let (nb, nv, m) = (&z.nb, &z.nv, &z.m);
    let (ops, methods) = (generate::ops_const(None), z.signature.methods(None));
    let alias = state_alias(input, nb);
    let engine = match tree {
        Some((nq, nv)) if !absolute => Engine::Tree([bodies.len(), nq, nv, 0]),
        _ => Engine::Absolute([bodies.len(), 6 * bodies.len(), rows, 0]),
    };
    let simulate = simulate(input, &input.generics, engine);
    let tree = tree.map(|sizes| {
        let body = quote! {
            fn tree_joints(&self) -> [#k::relative::TreeJoint; #nb] { loop {} }
            fn tree_inertias(&self) -> [#k::BodyInertia; #nb] { loop {} }
            fn tree_gravity(&self) -> #k::nalgebra::Vector3<f64> { loop {} }
        };
        super::tree::wrap(input, &input.generics, bodies.len(), (sizes.0, sizes.1, 0), body)
    });
    quote! {
        #errors
        #alias
        #tree
        #simulate
        #lints
        impl #ig #ident #tg #wc { #inherent #file }
        #lints
        impl #ig #k::Scene<#nb, #nv, #m> for #ident #tg #wc {
            const BODIES: [&'static str; #nb] = [#(#names),*];
            const BLOCKS: &'static [#k::RowBlock] = &[];
            #ops
            #methods
            fn inertias(&self) -> [#k::BodyInertia; #nb] { loop {} }
            fn gravity(&self) -> #k::nalgebra::Vector3<f64> { loop {} }
        }
        #lints
        impl #ig #k::SparseJacobian<#nb, 0> for #ident #tg #wc {
            const ROW_STARTS: &'static [usize] = &[];
            const COLUMNS: [usize; 0] = [];
            const BLOCK_BODIES: &'static [[::core::option::Option<usize>; 2]] = &[];
            const ELIMINATION: &'static [usize] = &[];
            const FACTOR_STARTS: &'static [usize] = &[];
            const FACTOR_BELOW: &'static [usize] = &[];
            type Factor = #k::absolute::FactorArrays<0, 0, 0, 0, 0, 0>;
            const KKT_ORDER: &'static [usize] = &[];
            const KKT_STARTS: &'static [usize] = &[];
            const KKT_BELOW: &'static [usize] = &[];
            type Kkt<__Entry: #k::absolute::KktEntry> = #k::absolute::KktArrays<__Entry, 0, 0, 0>;
            type Terms = #k::absolute::TermArray<0>;
            fn jacobian_values_into(&self, _: &#k::SystemState<#nb>, _: &mut [f64; 0]) { loop {} }
        }
    }
}
