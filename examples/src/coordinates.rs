//! One declaration in both coordinate choices (`#[scene(coordinates =
//! both)]`): the same start stepped by the absolute [`AbsoluteSimulation`] and by the
//! relative [`TreeSimulation`], RK4 at one step size, compared body by body.

use joint_runtime::dynamics::{AbsoluteSimulation, NoLoads, SimulationOptions, SpringDamper};
use joint_runtime::relative::{TreeScene, TreeSimulation};
use joint_runtime::{Scene, SparseJacobian, SystemState};

/// What [`both`] measured.
#[derive(Clone, Debug)]
pub struct Both<const NB: usize> {
    /// The largest difference between the two runs' bodies at the end: positions
    /// (m), rotations (rad), velocities and angular velocities.
    pub worst: f64,
    /// The absolute run's end.
    pub absolute: SystemState<NB>,
    /// The relative run's end, as bodies.
    pub relative: SystemState<NB>,
    /// Total energy at the end: relative, absolute.
    pub energies: (f64, f64),
}

/// Steps `start` (converted to the tree's joints) `steps` times by `h` in both
/// coordinate choices, under `springs`; `each` sees both runs' bodies after
/// every step.
///
/// # Errors
/// A start off the tree's joints, or a failed step, as text.
pub fn both<
    S,
    const NB: usize,
    const NV6: usize,
    const M: usize,
    const NNZ: usize,
    const NQ: usize,
    const NV: usize,
    const NC: usize,
>(
    scene: &S,
    start: &SystemState<NB>,
    springs: &[SpringDamper],
    h: f64,
    steps: usize,
    mut each: impl FnMut(&SystemState<NB>, &SystemState<NB>),
) -> Result<Both<NB>, String>
where
    S: Scene<NB, NV6, M> + SparseJacobian<NB, NNZ> + TreeScene<NB, NQ, NV, NC>,
{
    let mut relative = TreeSimulation::new(scene).and_then(|s| s.with_springs(springs)).map_err(|e| e.to_string())?;
    let mut tree_state = relative.tree().tree_state(start, 1e-12).map_err(|e| e.to_string())?;
    let mut absolute =
        AbsoluteSimulation::new(scene, NoLoads, springs, SimulationOptions::default()).map_err(|e| e.to_string())?;
    let mut state = *start;
    for _ in 0..steps {
        relative.step(&mut tree_state, h).map_err(|e| e.to_string())?;
        absolute.step(&mut state, h).map_err(|e| e.to_string())?;
        each(&relative.tree().system_state(&tree_state), &state);
    }
    let mine = relative.tree().system_state(&tree_state);
    let mut worst = 0.0_f64;
    for (a, b) in mine.bodies.iter().zip(&state.bodies) {
        worst = worst.max((a.r - b.r).norm()).max(a.rotation().angle_to(&b.rotation()));
        worst = worst.max((a.rdot - b.rdot).norm()).max((a.omega - b.omega).norm());
    }
    let energies = (relative.tree().energy(&tree_state).total(), absolute.energy(&state).total());
    Ok(Both { worst, absolute: state, relative: mine, energies })
}
