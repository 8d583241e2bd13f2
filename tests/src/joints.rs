//! One derived struct per joint and formulation, every parameter a run-time field.

#![allow(missing_docs)]

use joint_runtime::Joint;
use joint_runtime::nalgebra::Vector3;
use serde_json::Value;

use crate::conformance::{FromJson, Group, Typed};

macro_rules! one {
    ($kind:ident, $form:ident, $name:ident, [$($p:ident),*]) => {
        #[derive(Joint, Clone, Debug)]
        #[joint($kind, formulation = $form)]
        pub struct $name<T> { $(pub $p: Vector3<T>),* }

        impl FromJson for $name<f64> {
            fn from_json(v: &Value) -> Result<Self, String> {
                Ok($name { $($p: FromJson::from_json(v.get(stringify!($p)).ok_or(concat!("missing `", stringify!($p), "`"))?)?),* })
            }
        }
    };
}

macro_rules! declare {
    ($kind:ident $fields:tt => $($name:ident = $form:ident),*) => {$( one!($kind, $form, $name, $fields); )*};
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

fn boxed<G: Group + 'static>(g: Result<G, String>) -> Option<Result<Box<dyn Group>, String>> {
    Some(g.map(|g| Box::new(g) as Box<dyn Group>))
}

/// The generated code for `joint` in `formulation`, over `cases`; `None` if there is none.
pub fn group(joint: &str, formulation: &str, cases: &[&Value]) -> Option<Result<Box<dyn Group>, String>> {
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
    }
}
