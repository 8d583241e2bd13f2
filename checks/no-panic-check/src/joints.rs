//! Every derived joint of `joint_tests::joints` (each catalogue kind in each of
//! the five formulations, every parameter a run-time field): `phi`, `phi_t`,
//! `jacobian`, `gamma` and `evaluate`, at `f64`; and at `f32` for every
//! non-driver kind in one formulation each (all five formulations appear).

use core::hint::black_box;

use joint_runtime::nalgebra::{SMatrix, SVector};
use joint_runtime::{Evaluation, Joint};
use joint_tests::joints::*;

use crate::guard::{Guard, guarded};

/// `joint.phi(state)` under the guard `G`.
#[inline(never)]
fn phi<G: Guard, J: Joint<T, R, C>, T, const R: usize, const C: usize>(joint: &J, state: &J::State) -> SVector<T, R> {
    guarded::<G, _>(|| joint.phi(state))
}

/// `joint.phi_t(state)` under the guard `G`.
#[inline(never)]
fn phi_t<G: Guard, J: Joint<T, R, C>, T, const R: usize, const C: usize>(joint: &J, state: &J::State) -> SVector<T, R> {
    guarded::<G, _>(|| joint.phi_t(state))
}

/// `joint.jacobian(state)` under the guard `G`.
#[inline(never)]
fn jacobian<G: Guard, J: Joint<T, R, C>, T, const R: usize, const C: usize>(
    joint: &J,
    state: &J::State,
) -> SMatrix<T, R, C> {
    guarded::<G, _>(|| joint.jacobian(state))
}

/// `joint.gamma(state)` under the guard `G`.
#[inline(never)]
fn gamma<G: Guard, J: Joint<T, R, C>, T, const R: usize, const C: usize>(joint: &J, state: &J::State) -> SVector<T, R> {
    guarded::<G, _>(|| joint.gamma(state))
}

/// `joint.evaluate(state)` under the guard `G`.
#[inline(never)]
fn evaluate<G: Guard, J: Joint<T, R, C>, T, const R: usize, const C: usize>(
    joint: &J,
    state: &J::State,
) -> Evaluation<T, R, C> {
    guarded::<G, _>(|| joint.evaluate(state))
}

/// One module per (joint, scalar) with a guard per function, named in the link
/// error; `keep()` instantiates the five wrappers and takes their addresses.
macro_rules! joints {
    ($($module:ident: $ty:ty),* $(,)?) => {
        $(
            #[allow(non_snake_case)]
            mod $module {
                use super::*;

                guard_type!(Phi, concat!("`<", stringify!($ty), " as Joint>::phi`"));
                guard_type!(PhiT, concat!("`<", stringify!($ty), " as Joint>::phi_t`"));
                guard_type!(Jacobian, concat!("`<", stringify!($ty), " as Joint>::jacobian`"));
                guard_type!(Gamma, concat!("`<", stringify!($ty), " as Joint>::gamma`"));
                guard_type!(Evaluate, concat!("`<", stringify!($ty), " as Joint>::evaluate`"));

                pub fn keep() -> usize {
                    black_box(phi::<Phi, $ty, _, _, _> as fn(&$ty, &_) -> _);
                    black_box(phi_t::<PhiT, $ty, _, _, _> as fn(&$ty, &_) -> _);
                    black_box(jacobian::<Jacobian, $ty, _, _, _> as fn(&$ty, &_) -> _);
                    black_box(gamma::<Gamma, $ty, _, _, _> as fn(&$ty, &_) -> _);
                    black_box(evaluate::<Evaluate, $ty, _, _, _> as fn(&$ty, &_) -> _);
                    5
                }
            }
        )*

        /// Instantiates every joint's wrappers; returns their number.
        pub fn keep() -> usize {
            0 $(+ $module::keep())*
        }
    };
}

joints! {
    SphericalEuler_f64: SphericalEuler<f64>,
    SphericalOmegaInertial_f64: SphericalOmegaInertial<f64>,
    SphericalOmegaBody_f64: SphericalOmegaBody<f64>,
    SphericalRelativeB1_f64: SphericalRelativeB1<f64>,
    SphericalRelativeB2_f64: SphericalRelativeB2<f64>,
    UniversalEuler_f64: UniversalEuler<f64>,
    UniversalOmegaInertial_f64: UniversalOmegaInertial<f64>,
    UniversalOmegaBody_f64: UniversalOmegaBody<f64>,
    UniversalRelativeB1_f64: UniversalRelativeB1<f64>,
    UniversalRelativeB2_f64: UniversalRelativeB2<f64>,
    UniversalTranslationalEuler_f64: UniversalTranslationalEuler<f64>,
    UniversalTranslationalOmegaInertial_f64: UniversalTranslationalOmegaInertial<f64>,
    UniversalTranslationalOmegaBody_f64: UniversalTranslationalOmegaBody<f64>,
    UniversalTranslationalRelativeB1_f64: UniversalTranslationalRelativeB1<f64>,
    UniversalTranslationalRelativeB2_f64: UniversalTranslationalRelativeB2<f64>,
    RevoluteEuler_f64: RevoluteEuler<f64>,
    RevoluteOmegaInertial_f64: RevoluteOmegaInertial<f64>,
    RevoluteOmegaBody_f64: RevoluteOmegaBody<f64>,
    RevoluteRelativeB1_f64: RevoluteRelativeB1<f64>,
    RevoluteRelativeB2_f64: RevoluteRelativeB2<f64>,
    CylindricalEuler_f64: CylindricalEuler<f64>,
    CylindricalOmegaInertial_f64: CylindricalOmegaInertial<f64>,
    CylindricalOmegaBody_f64: CylindricalOmegaBody<f64>,
    CylindricalRelativeB1_f64: CylindricalRelativeB1<f64>,
    CylindricalRelativeB2_f64: CylindricalRelativeB2<f64>,
    TranslationalEuler_f64: TranslationalEuler<f64>,
    TranslationalOmegaInertial_f64: TranslationalOmegaInertial<f64>,
    TranslationalOmegaBody_f64: TranslationalOmegaBody<f64>,
    TranslationalRelativeB1_f64: TranslationalRelativeB1<f64>,
    TranslationalRelativeB2_f64: TranslationalRelativeB2<f64>,
    FixedEuler_f64: FixedEuler<f64>,
    FixedOmegaInertial_f64: FixedOmegaInertial<f64>,
    FixedOmegaBody_f64: FixedOmegaBody<f64>,
    FixedRelativeB1_f64: FixedRelativeB1<f64>,
    FixedRelativeB2_f64: FixedRelativeB2<f64>,
    PlanarEuler_f64: PlanarEuler<f64>,
    PlanarOmegaInertial_f64: PlanarOmegaInertial<f64>,
    PlanarOmegaBody_f64: PlanarOmegaBody<f64>,
    PlanarRelativeB1_f64: PlanarRelativeB1<f64>,
    PlanarRelativeB2_f64: PlanarRelativeB2<f64>,
    PointOnLineEuler_f64: PointOnLineEuler<f64>,
    PointOnLineOmegaInertial_f64: PointOnLineOmegaInertial<f64>,
    PointOnLineOmegaBody_f64: PointOnLineOmegaBody<f64>,
    PointOnLineRelativeB1_f64: PointOnLineRelativeB1<f64>,
    PointOnLineRelativeB2_f64: PointOnLineRelativeB2<f64>,
    PointInPlaneEuler_f64: PointInPlaneEuler<f64>,
    PointInPlaneOmegaInertial_f64: PointInPlaneOmegaInertial<f64>,
    PointInPlaneOmegaBody_f64: PointInPlaneOmegaBody<f64>,
    PointInPlaneRelativeB1_f64: PointInPlaneRelativeB1<f64>,
    PointInPlaneRelativeB2_f64: PointInPlaneRelativeB2<f64>,
    ParallelEuler_f64: ParallelEuler<f64>,
    ParallelOmegaInertial_f64: ParallelOmegaInertial<f64>,
    ParallelOmegaBody_f64: ParallelOmegaBody<f64>,
    ParallelRelativeB1_f64: ParallelRelativeB1<f64>,
    ParallelRelativeB2_f64: ParallelRelativeB2<f64>,
    PerpendicularEuler_f64: PerpendicularEuler<f64>,
    PerpendicularOmegaInertial_f64: PerpendicularOmegaInertial<f64>,
    PerpendicularOmegaBody_f64: PerpendicularOmegaBody<f64>,
    PerpendicularRelativeB1_f64: PerpendicularRelativeB1<f64>,
    PerpendicularRelativeB2_f64: PerpendicularRelativeB2<f64>,
    DistanceEuler_f64: DistanceEuler<f64>,
    DistanceOmegaInertial_f64: DistanceOmegaInertial<f64>,
    DistanceOmegaBody_f64: DistanceOmegaBody<f64>,
    DistanceRelativeB1_f64: DistanceRelativeB1<f64>,
    DistanceRelativeB2_f64: DistanceRelativeB2<f64>,
    RotationalDriverEuler_f64: RotationalDriverEuler<f64>,
    RotationalDriverOmegaInertial_f64: RotationalDriverOmegaInertial<f64>,
    RotationalDriverOmegaBody_f64: RotationalDriverOmegaBody<f64>,
    RotationalDriverRelativeB1_f64: RotationalDriverRelativeB1<f64>,
    RotationalDriverRelativeB2_f64: RotationalDriverRelativeB2<f64>,
    TranslationalDriverEuler_f64: TranslationalDriverEuler<f64>,
    TranslationalDriverOmegaInertial_f64: TranslationalDriverOmegaInertial<f64>,
    TranslationalDriverOmegaBody_f64: TranslationalDriverOmegaBody<f64>,
    TranslationalDriverRelativeB1_f64: TranslationalDriverRelativeB1<f64>,
    TranslationalDriverRelativeB2_f64: TranslationalDriverRelativeB2<f64>,

    SphericalEuler_f32: SphericalEuler<f32>,
    UniversalOmegaBody_f32: UniversalOmegaBody<f32>,
    UniversalTranslationalOmegaInertial_f32: UniversalTranslationalOmegaInertial<f32>,
    RevoluteRelativeB1_f32: RevoluteRelativeB1<f32>,
    CylindricalRelativeB2_f32: CylindricalRelativeB2<f32>,
    TranslationalEuler_f32: TranslationalEuler<f32>,
    FixedOmegaBody_f32: FixedOmegaBody<f32>,
    PlanarOmegaInertial_f32: PlanarOmegaInertial<f32>,
    PointOnLineRelativeB2_f32: PointOnLineRelativeB2<f32>,
    PointInPlaneEuler_f32: PointInPlaneEuler<f32>,
    ParallelRelativeB1_f32: ParallelRelativeB1<f32>,
    PerpendicularOmegaBody_f32: PerpendicularOmegaBody<f32>,
    DistanceEuler_f32: DistanceEuler<f32>,
}
