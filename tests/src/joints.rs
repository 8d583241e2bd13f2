//! One derived struct per joint and formulation, every parameter a run-time field.

#![allow(missing_docs)]

use joint_runtime::nalgebra::Vector3;
use joint_runtime::{Drive, Joint};

use crate::conformance::{Case, FromCase, Group, Typed, required};

macro_rules! one {
    ($kind:ident, $form:ident, $name:ident, [$($p:ident),*]) => {
        one!($kind, $form, $name, [$($p),*] []);
    };
    ($kind:ident, $form:ident, $name:ident, [$($p:ident),*] [$($sc:ident),*]) => {
        one!($kind, $form, $name, [$($p),*] [$($sc),*] []);
    };
    ($kind:ident, $form:ident, $name:ident, [$($p:ident),*] [$($sc:ident),*] [$($time:ident),*]) => {
        #[derive(Joint, Clone, Debug)]
        #[joint($kind, formulation = $form)]
        pub struct $name<T> { $(pub $p: Vector3<T>,)* $(pub $sc: T,)* $(pub $time: Drive,)* }

        /// Built from a whole case: `params`, and `state.drive` for a time function.
        impl FromCase for $name<f64> {
            fn from_case(case: &Case) -> Result<Self, String> {
                let p = &case.params;
                Ok($name {
                    $($p: required(p.$p, stringify!($p))?.into(),)*
                    $($sc: required(p.$sc, stringify!($sc))?,)*
                    $($time: required(case.state.drive, "state.drive")?.into(),)*
                })
            }
        }
    };
}

macro_rules! declare {
    ($kind:ident $fields:tt => $($name:ident = $form:ident),*) => {$( one!($kind, $form, $name, $fields); )*};
    ($kind:ident $fields:tt $scalars:tt => $($name:ident = $form:ident),*) => {$( one!($kind, $form, $name, $fields $scalars); )*};
    ($kind:ident $fields:tt $scalars:tt $time:tt => $($name:ident = $form:ident),*) => {$( one!($kind, $form, $name, $fields $scalars $time); )*};
}

declare!(spherical [rho1, rho2] =>
    SphericalEuler = euler, SphericalOmegaInertial = omega_inertial, SphericalOmegaBody = omega_body,
    SphericalRelativeB1 = relative_b1, SphericalRelativeB2 = relative_b2);
declare!(universal [s, h, rho1, rho2] =>
    UniversalEuler = euler, UniversalOmegaInertial = omega_inertial, UniversalOmegaBody = omega_body,
    UniversalRelativeB1 = relative_b1, UniversalRelativeB2 = relative_b2);
declare!(universal_translational [s, h, b, c, rho1, rho2] =>
    UniversalTranslationalEuler = euler, UniversalTranslationalOmegaInertial = omega_inertial,
    UniversalTranslationalOmegaBody = omega_body, UniversalTranslationalRelativeB1 = relative_b1,
    UniversalTranslationalRelativeB2 = relative_b2);

declare!(revolute [f, g, h, rho1, rho2] =>
    RevoluteEuler = euler, RevoluteOmegaInertial = omega_inertial, RevoluteOmegaBody = omega_body, RevoluteRelativeB1 = relative_b1, RevoluteRelativeB2 = relative_b2);
declare!(cylindrical [f, g, h, rho1, rho2] =>
    CylindricalEuler = euler, CylindricalOmegaInertial = omega_inertial, CylindricalOmegaBody = omega_body, CylindricalRelativeB1 = relative_b1, CylindricalRelativeB2 = relative_b2);
declare!(translational [f, g, h, k, rho1, rho2] =>
    TranslationalEuler = euler, TranslationalOmegaInertial = omega_inertial, TranslationalOmegaBody = omega_body, TranslationalRelativeB1 = relative_b1, TranslationalRelativeB2 = relative_b2);
declare!(fixed [f, g, h, k, rho1, rho2] =>
    FixedEuler = euler, FixedOmegaInertial = omega_inertial, FixedOmegaBody = omega_body, FixedRelativeB1 = relative_b1, FixedRelativeB2 = relative_b2);
declare!(planar [f, g, n, h, rho1, rho2] =>
    PlanarEuler = euler, PlanarOmegaInertial = omega_inertial, PlanarOmegaBody = omega_body, PlanarRelativeB1 = relative_b1, PlanarRelativeB2 = relative_b2);
declare!(point_on_line [f, g, rho1, rho2] =>
    PointOnLineEuler = euler, PointOnLineOmegaInertial = omega_inertial, PointOnLineOmegaBody = omega_body, PointOnLineRelativeB1 = relative_b1, PointOnLineRelativeB2 = relative_b2);
declare!(point_in_plane [n, rho1, rho2] =>
    PointInPlaneEuler = euler, PointInPlaneOmegaInertial = omega_inertial, PointInPlaneOmegaBody = omega_body, PointInPlaneRelativeB1 = relative_b1, PointInPlaneRelativeB2 = relative_b2);
declare!(parallel [f, g, h] =>
    ParallelEuler = euler, ParallelOmegaInertial = omega_inertial, ParallelOmegaBody = omega_body, ParallelRelativeB1 = relative_b1, ParallelRelativeB2 = relative_b2);
declare!(perpendicular [s, h] =>
    PerpendicularEuler = euler, PerpendicularOmegaInertial = omega_inertial, PerpendicularOmegaBody = omega_body, PerpendicularRelativeB1 = relative_b1, PerpendicularRelativeB2 = relative_b2);
declare!(distance [rho1, rho2] [length] =>
    DistanceEuler = euler, DistanceOmegaInertial = omega_inertial, DistanceOmegaBody = omega_body, DistanceRelativeB1 = relative_b1, DistanceRelativeB2 = relative_b2);

declare!(rotational_driver [f, g, k] [] [theta] =>
    RotationalDriverEuler = euler, RotationalDriverOmegaInertial = omega_inertial, RotationalDriverOmegaBody = omega_body, RotationalDriverRelativeB1 = relative_b1, RotationalDriverRelativeB2 = relative_b2);
declare!(translational_driver [h, rho1, rho2] [] [x] =>
    TranslationalDriverEuler = euler, TranslationalDriverOmegaInertial = omega_inertial, TranslationalDriverOmegaBody = omega_body, TranslationalDriverRelativeB1 = relative_b1, TranslationalDriverRelativeB2 = relative_b2);

fn boxed<G: Group + 'static>(g: Result<G, String>) -> Option<Result<Box<dyn Group>, String>> {
    Some(g.map(|g| Box::new(g) as Box<dyn Group>))
}

/// The generated code for `joint` in `formulation`, over `cases`; `None` if there is none.
pub fn group(joint: &str, formulation: &str, cases: &[&Case]) -> Option<Result<Box<dyn Group>, String>> {
    macro_rules! table {
        ($(($j:literal, $f:literal) => $t:ident),* $(,)?) => {
            match (joint, formulation) {
                $(($j, $f) => boxed(Typed::<$t<f64>, _, _>::new(cases)),)*
                _ => None,
            }
        };
    }
    table! {
        ("spherical", "euler") => SphericalEuler,
        ("spherical", "omega_inertial") => SphericalOmegaInertial,
        ("spherical", "omega_body") => SphericalOmegaBody,
        ("spherical", "relative_b1") => SphericalRelativeB1,
        ("spherical", "relative_b2") => SphericalRelativeB2,
        ("universal", "euler") => UniversalEuler,
        ("universal", "omega_inertial") => UniversalOmegaInertial,
        ("universal", "omega_body") => UniversalOmegaBody,
        ("universal", "relative_b1") => UniversalRelativeB1,
        ("universal", "relative_b2") => UniversalRelativeB2,
        ("universal_translational", "euler") => UniversalTranslationalEuler,
        ("universal_translational", "omega_inertial") => UniversalTranslationalOmegaInertial,
        ("universal_translational", "omega_body") => UniversalTranslationalOmegaBody,
        ("universal_translational", "relative_b1") => UniversalTranslationalRelativeB1,
        ("universal_translational", "relative_b2") => UniversalTranslationalRelativeB2,
        ("revolute", "euler") => RevoluteEuler,
        ("revolute", "omega_inertial") => RevoluteOmegaInertial,
        ("revolute", "omega_body") => RevoluteOmegaBody,
        ("revolute", "relative_b1") => RevoluteRelativeB1,
        ("revolute", "relative_b2") => RevoluteRelativeB2,
        ("cylindrical", "euler") => CylindricalEuler,
        ("cylindrical", "omega_inertial") => CylindricalOmegaInertial,
        ("cylindrical", "omega_body") => CylindricalOmegaBody,
        ("cylindrical", "relative_b1") => CylindricalRelativeB1,
        ("cylindrical", "relative_b2") => CylindricalRelativeB2,
        ("translational", "euler") => TranslationalEuler,
        ("translational", "omega_inertial") => TranslationalOmegaInertial,
        ("translational", "omega_body") => TranslationalOmegaBody,
        ("translational", "relative_b1") => TranslationalRelativeB1,
        ("translational", "relative_b2") => TranslationalRelativeB2,
        ("fixed", "euler") => FixedEuler,
        ("fixed", "omega_inertial") => FixedOmegaInertial,
        ("fixed", "omega_body") => FixedOmegaBody,
        ("fixed", "relative_b1") => FixedRelativeB1,
        ("fixed", "relative_b2") => FixedRelativeB2,
        ("planar", "euler") => PlanarEuler,
        ("planar", "omega_inertial") => PlanarOmegaInertial,
        ("planar", "omega_body") => PlanarOmegaBody,
        ("planar", "relative_b1") => PlanarRelativeB1,
        ("planar", "relative_b2") => PlanarRelativeB2,
        ("point_on_line", "euler") => PointOnLineEuler,
        ("point_on_line", "omega_inertial") => PointOnLineOmegaInertial,
        ("point_on_line", "omega_body") => PointOnLineOmegaBody,
        ("point_on_line", "relative_b1") => PointOnLineRelativeB1,
        ("point_on_line", "relative_b2") => PointOnLineRelativeB2,
        ("point_in_plane", "euler") => PointInPlaneEuler,
        ("point_in_plane", "omega_inertial") => PointInPlaneOmegaInertial,
        ("point_in_plane", "omega_body") => PointInPlaneOmegaBody,
        ("point_in_plane", "relative_b1") => PointInPlaneRelativeB1,
        ("point_in_plane", "relative_b2") => PointInPlaneRelativeB2,
        ("parallel", "euler") => ParallelEuler,
        ("parallel", "omega_inertial") => ParallelOmegaInertial,
        ("parallel", "omega_body") => ParallelOmegaBody,
        ("parallel", "relative_b1") => ParallelRelativeB1,
        ("parallel", "relative_b2") => ParallelRelativeB2,
        ("perpendicular", "euler") => PerpendicularEuler,
        ("perpendicular", "omega_inertial") => PerpendicularOmegaInertial,
        ("perpendicular", "omega_body") => PerpendicularOmegaBody,
        ("perpendicular", "relative_b1") => PerpendicularRelativeB1,
        ("perpendicular", "relative_b2") => PerpendicularRelativeB2,
        ("distance", "euler") => DistanceEuler,
        ("distance", "omega_inertial") => DistanceOmegaInertial,
        ("distance", "omega_body") => DistanceOmegaBody,
        ("distance", "relative_b1") => DistanceRelativeB1,
        ("distance", "relative_b2") => DistanceRelativeB2,
        ("rotational_driver", "euler") => RotationalDriverEuler,
        ("rotational_driver", "omega_inertial") => RotationalDriverOmegaInertial,
        ("rotational_driver", "omega_body") => RotationalDriverOmegaBody,
        ("rotational_driver", "relative_b1") => RotationalDriverRelativeB1,
        ("rotational_driver", "relative_b2") => RotationalDriverRelativeB2,
        ("translational_driver", "euler") => TranslationalDriverEuler,
        ("translational_driver", "omega_inertial") => TranslationalDriverOmegaInertial,
        ("translational_driver", "omega_body") => TranslationalDriverOmegaBody,
        ("translational_driver", "relative_b1") => TranslationalDriverRelativeB1,
        ("translational_driver", "relative_b2") => TranslationalDriverRelativeB2,
    }
}
