//! `∂Q/∂q`, `∂Q/∂v` of the dense path.

use nalgebra::SMatrix;

use super::DenseSimulation;
use crate::dynamics::{AppliedLoads, force_column};
use crate::scene::{Scene, SystemState};

impl<S, L, const NB: usize, const NV: usize, const M: usize> DenseSimulation<'_, S, L, NB, NV, M>
where
    S: Scene<NB, NV, M>,
    L: AppliedLoads<NB>,
{
    /// `∂Q/∂q` (along the group increments) and `∂Q/∂v` at `state`.
    pub(super) fn force_derivatives(
        &mut self,
        state: &SystemState<NB>,
    ) -> (SMatrix<f64, NV, NV>, SMatrix<f64, NV, NV>) {
        let (mut dq, mut dv) = (SMatrix::<f64, NV, NV>::zeros(), SMatrix::<f64, NV, NV>::zeros());
        for c in 0..NV {
            for (velocity, out) in [(false, &mut dq), (true, &mut dv)] {
                let column = force_column(&mut self.loads, self.springs, &self.inertias, state, c, velocity);
                out.set_column(c, &column);
            }
        }
        (dq, dv)
    }
}
