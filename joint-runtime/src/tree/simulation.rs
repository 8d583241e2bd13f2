//! Stepping a tree: classical RK4 on `(q, v)`, each spherical joint's
//! quaternion integrated as four numbers (`ṗ = ½ p ⊗ (0, ω')`, fourth order)
//! and renormalised after the step.

use nalgebra::{Quaternion, SMatrix, SVector};

use super::topology::{Tree, TreeError};
use super::{TreeJointKind, TreeScene, TreeState};

/// The simulation of a relative-coordinate scene: the scene (its generated
/// articulated-body algorithm, where the derive wrote one) and its tree,
/// checked once.
#[derive(Clone, Debug)]
pub struct TreeSimulation<'a, S, const NB: usize, const NQ: usize, const NV: usize> {
    scene: &'a S,
    tree: Tree<NB, NQ, NV>,
}

impl<'a, S: TreeScene<NB, NQ, NV>, const NB: usize, const NQ: usize, const NV: usize>
    TreeSimulation<'a, S, NB, NQ, NV>
{
    /// The simulation of `scene`; refused when its tree is not valid
    /// ([`TreeError`]: inertias, axes, order).
    pub fn new(scene: &'a S) -> Result<Self, TreeError> {
        Ok(TreeSimulation { scene, tree: Tree::of(scene)? })
    }

    /// The scene.
    pub fn scene(&self) -> &'a S {
        self.scene
    }

    /// `v̇` under joint forces `tau`: the scene's generated articulated-body
    /// algorithm where the derive wrote one, the tree's recursion otherwise
    /// (and when the generated one is not finite, so that a singular
    /// articulated inertia is named by its joint).
    pub fn forward_dynamics(
        &self,
        state: &TreeState<NQ, NV>,
        tau: &SVector<f64, NV>,
    ) -> Result<SVector<f64, NV>, TreeError> {
        let mut out = SVector::<f64, NV>::zeros();
        let (q, v, t) = (&state.q.data.0[0], &state.v.data.0[0], &tau.data.0[0]);
        if self.scene.forward_dynamics_into(q, v, t, &mut out.data.0[0]) && out.iter().all(|x| x.is_finite()) {
            Ok(out)
        } else {
            self.tree.forward_dynamics(state, tau)
        }
    }

    /// The tree: its recursions, energy and conversions.
    pub fn tree(&self) -> &Tree<NB, NQ, NV> {
        &self.tree
    }

    /// The joint forces `τ(q, v, v̇)` (gravity included): the scene's
    /// generated recursive Newton–Euler algorithm where the derive wrote one,
    /// the tree's recursion otherwise.
    pub fn inverse_dynamics(&self, state: &TreeState<NQ, NV>, vdot: &SVector<f64, NV>) -> SVector<f64, NV> {
        let mut out = SVector::<f64, NV>::zeros();
        let (q, v, a) = (&state.q.data.0[0], &state.v.data.0[0], &vdot.data.0[0]);
        if self.scene.inverse_dynamics_into(q, v, a, &mut out.data.0[0]) {
            out
        } else {
            self.tree.inverse_dynamics(state, vdot)
        }
    }

    /// The mass matrix `M(q)` into `out`: the scene's generated
    /// composite-rigid-body algorithm where the derive wrote one, the tree's
    /// recursion otherwise.
    pub fn mass_matrix_into(&self, q: &SVector<f64, NQ>, out: &mut SMatrix<f64, NV, NV>) {
        if !self.scene.mass_matrix_into(&q.data.0[0], &mut out.data.0) {
            self.tree.mass_matrix_into(q, out);
        }
    }

    /// One RK4 step of length `h` with no joint forces.
    pub fn step(&mut self, state: &mut TreeState<NQ, NV>, h: f64) -> Result<(), TreeError> {
        self.step_with(state, h, &SVector::zeros())
    }

    /// One RK4 step of length `h` under joint forces `tau`, held over the step
    /// (a controller's zero-order hold). The state is left unchanged on error.
    pub fn step_with(
        &mut self,
        state: &mut TreeState<NQ, NV>,
        h: f64,
        tau: &SVector<f64, NV>,
    ) -> Result<(), TreeError> {
        if !(h.is_finite() && tau.iter().all(|x| x.is_finite())) {
            return Err(TreeError::NonFinite);
        }
        let rate = |s: &TreeState<NQ, NV>| -> Result<(SVector<f64, NQ>, SVector<f64, NV>), TreeError> {
            Ok((self.tree.coordinate_rates(&s.q, &s.v), self.forward_dynamics(s, tau)?))
        };
        let at = |dq: &SVector<f64, NQ>, dv: &SVector<f64, NV>, c: f64| TreeState {
            q: state.q + dq * c,
            v: state.v + dv * c,
            t: state.t + c,
        };
        let (q1, v1) = rate(state)?;
        let (q2, v2) = rate(&at(&q1, &v1, 0.5 * h))?;
        let (q3, v3) = rate(&at(&q2, &v2, 0.5 * h))?;
        let (q4, v4) = rate(&at(&q3, &v3, h))?;
        let mut next = TreeState {
            q: state.q + (q1 + (q2 + q3) * 2.0 + q4) * (h / 6.0),
            v: state.v + (v1 + (v2 + v3) * 2.0 + v4) * (h / 6.0),
            t: state.t + h,
        };
        self.tree.normalise(&mut next.q);
        if !(next.q.iter().chain(next.v.iter()).all(|x| x.is_finite())) {
            return Err(TreeError::NonFinite);
        }
        *state = next;
        Ok(())
    }
}

impl<const NB: usize, const NQ: usize, const NV: usize> Tree<NB, NQ, NV> {
    /// `q̇(q, v)`: `θ̇ = v` at a revolute joint, `ṗ = ½ p ⊗ (0, ω')` at a
    /// spherical one.
    pub fn coordinate_rates(&self, q: &SVector<f64, NQ>, v: &SVector<f64, NV>) -> SVector<f64, NQ> {
        let mut out = SVector::<f64, NQ>::zeros();
        for (k, j) in self.joints.iter().enumerate() {
            let (qa, va) = (self.q_at[k], self.v_at[k]);
            match j.kind {
                TreeJointKind::Revolute => out[qa] = v[va],
                TreeJointKind::Spherical => {
                    let p = Quaternion::new(q[qa], q[qa + 1], q[qa + 2], q[qa + 3]);
                    let w = Quaternion::new(0.0, v[va], v[va + 1], v[va + 2]);
                    let d = p * w * 0.5;
                    out.fixed_rows_mut::<4>(qa).copy_from(&nalgebra::Vector4::new(d.w, d.i, d.j, d.k));
                }
            }
        }
        out
    }

    /// Every spherical joint's quaternion back to unit length.
    pub fn normalise(&self, q: &mut SVector<f64, NQ>) {
        for (k, j) in self.joints.iter().enumerate() {
            if j.kind == TreeJointKind::Spherical {
                let mut p = q.fixed_rows_mut::<4>(self.q_at[k]);
                let n = p.norm();
                if n > 0.0 {
                    p /= n;
                }
            }
        }
    }
}
