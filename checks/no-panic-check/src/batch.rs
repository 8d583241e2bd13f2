//! The batch functions of `joint_runtime::batch` for the universal joint in
//! `omega_body`: scalar, SIMD lanes from scalar states (pack, evaluate, unpack;
//! the mixed-time split and the padded tail included) in `f64 × 4` and
//! `f32 × 8`, and the structure-of-arrays path.

use joint_runtime::batch::{BatchError, LaneReport, WideF32x8, WideF64x4, evaluate_batch, evaluate_batch_simd};
use joint_runtime::{Evaluation, OmegaBody, TwoBodies};
use joint_tests::joints::UniversalOmegaBody;

type State<T> = TwoBodies<OmegaBody<T>>;

checked! {
    fn scalar_f64(
        joint: &UniversalOmegaBody<f64>,
        states: &[State<f64>],
        out: &mut [Evaluation<f64, 4, 12>],
    ) -> Result<(), BatchError> {
        evaluate_batch(joint, states, out)
    }
    fn simd_f64x4(
        joint: &UniversalOmegaBody<WideF64x4>,
        states: &[State<f64>],
        out: &mut [Evaluation<f64, 4, 12>],
    ) -> Result<LaneReport, BatchError> {
        evaluate_batch_simd(joint, states, out)
    }
    fn simd_f32x8(
        joint: &UniversalOmegaBody<WideF32x8>,
        states: &[State<f32>],
        out: &mut [Evaluation<f32, 4, 12>],
    ) -> Result<LaneReport, BatchError> {
        evaluate_batch_simd(joint, states, out)
    }
    fn packed_f64x4(
        joint: &UniversalOmegaBody<WideF64x4>,
        states: &[State<WideF64x4>],
        out: &mut [Evaluation<WideF64x4, 4, 12>],
    ) -> Result<(), BatchError> {
        evaluate_batch(joint, states, out)
    }
}
