//! The wrench every joint carries, in relative coordinates, loops and
//! contacts included; equal to the absolute engine's
//! [`AbsoluteSimulation::reactions`](crate::dynamics::AbsoluteSimulation::reactions)
//! (force in the world's components through the body's centre, torque about
//! it in the body's).
//!
//! A closure's rows act on the tree as `Jᵀλ`, which does not say how each
//! body is loaded; the derive writes the same rows on their two bodies'
//! `ṙ, ω'` ([`TreeScene::closure_body_rows`]), so a closure's wrench on a
//! body is `J_bᵀ λ` with the tree's `λ` (`M v̇ + b = τ + Jᵀλ`; the absolute
//! engine's multipliers have the other sign, its reactions are `−J_bᵀ λ`).
//! A tree joint's reaction is then the recursive Newton–Euler algorithm's
//! force on its child at the constrained `v̇`, with the closures' wrenches
//! among the loads. Where rows are redundant (a planar loop in space, an
//! overconstrained linkage) the split of the force among them is not
//! determined by the dynamics: here, as in the absolute engine, dropped
//! rows carry none, but the two engines may keep different rows.

use nalgebra::{SVector, Vector6};

use super::simulation::finite_inputs;
use super::{TreeError, TreeScene, TreeSimulation, TreeState};
use crate::RowBlock;
use crate::dynamics::{AppliedLoads, Reaction};

impl<
    S: TreeScene<NB, NQ, NV, NC>,
    L: AppliedLoads<NB>,
    const NB: usize,
    const NQ: usize,
    const NV: usize,
    const NC: usize,
> TreeSimulation<'_, S, NB, NQ, NV, NC, L>
{
    /// Each tree joint's reaction on its child at `state` under joint forces
    /// `tau`, the springs, the user's loads and the closures' forces acting:
    /// entry `k` is joint `k`'s (tree order; its child is
    /// `tree().joints()[k].child`), the whole wrench the parent exerts
    /// through it, the joint's own forces included (their share along its
    /// freedoms is `tau`). As the absolute
    /// [`AbsoluteSimulation::reactions`](crate::dynamics::AbsoluteSimulation::reactions)
    /// gives them: force in inertial components through the child's centre
    /// of mass, torque about it in the child's components; the parent
    /// feels the opposite. A loop's closing joint, a contact: see
    /// [`closure_reactions`](Self::closure_reactions).
    ///
    /// ```
    /// use joint_runtime::Scene;
    /// use joint_runtime::nalgebra::SVector;
    /// use joint_runtime::relative::{TreeScene, TreeSimulation, TreeState};
    ///
    /// /// A bar pinned at one end about y, its other end on a point contact.
    /// #[derive(Scene)]
    /// #[scene(gravity = [0, 0, -9.81])]
    /// #[body(bar, mass = 2.0, inertia = [0.001, 0.1, 0.1])]
    /// #[joint(pin = revolute(ground, bar), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0, 0, 0], rho2 = [-0.5, 0, 0])]
    /// #[contact(tip = point(bar), at = [0.5, 0, 0])]
    /// struct Propped;
    ///
    /// let mut sim = TreeSimulation::new(&Propped)?;
    /// let state = TreeState { q: SVector::from([0.0]), v: SVector::from([0.0]), t: 0.0 };
    /// // The pin and the tip each hold half the bar's weight.
    /// let pin = sim.reactions(&state, &SVector::zeros())?[0];
    /// let lambda = sim.closure_forces(&state, &SVector::zeros())?;
    /// let tip = sim.closure_reactions(&state, &lambda, &Propped::CLOSURES[0])[Propped::BAR];
    /// assert!((pin.force.z - 9.81).abs() < 1e-12 && (tip.force.z - 9.81).abs() < 1e-12);
    /// # Ok::<(), joint_runtime::relative::TreeError>(())
    /// ```
    pub fn reactions(
        &mut self,
        state: &TreeState<NQ, NV>,
        tau: &SVector<f64, NV>,
    ) -> Result<[Reaction; NB], TreeError> {
        finite_inputs(state, &[tau.as_slice()])?;
        let (vdot, lambda, _) = self.constrained_forces(state, tau, None)?;
        let mut external = self.body_wrenches(state);
        if let Some(held) = self.tree().compensation_wrenches(&state.q) {
            external.iter_mut().zip(held).for_each(|(e, h)| *e += h);
        }
        let tree = self.tree();
        let poses = tree.link_poses(&state.q);
        if NC > 0 {
            let closures = self.closure_wrenches(state, &lambda, None);
            for ((e, joint), (turn, _)) in external.iter_mut().zip(tree.joints()).zip(&poses) {
                let Some(w) = closures.get(joint.child) else { continue };
                // In the child's link frame, the moment about the joint point.
                let f = turn.inverse() * w.force;
                let n = w.torque - joint.rho_child.cross(&f);
                *e += Vector6::new(n.x, n.y, n.z, f.x, f.y, f.z);
            }
        }
        let (_, f) = tree.joint_wrenches(state, &vdot, Some(&external));
        let mut out = [Reaction::default(); NB];
        for (((wrench, (a, _)), joint), slot) in f.iter().zip(&poses).zip(tree.joints()).zip(out.iter_mut()) {
            let (n, force) = (wrench.fixed_rows::<3>(0).into_owned(), wrench.fixed_rows::<3>(3).into_owned());
            // The moment moved from the joint point to the centre of mass.
            let torque = n + joint.rho_child.cross(&force);
            *slot = Reaction { force: a * force, torque };
        }
        Ok(out)
    }

    /// The closure rows' forces `λ` at `state` under joint forces `tau`, the
    /// springs and the user's loads acting, as a step's dynamics solve them
    /// (every block holding, the options' stabilisation, redundant rows
    /// given none): `M v̇ + b = τ + Jᵀλ`, in [`TreeScene::CLOSURES`]' row
    /// order. Zero-sized without closures.
    pub fn closure_forces(
        &mut self,
        state: &TreeState<NQ, NV>,
        tau: &SVector<f64, NV>,
    ) -> Result<SVector<f64, NC>, TreeError> {
        finite_inputs(state, &[tau.as_slice()])?;
        Ok(self.constrained_forces(state, tau, None)?.1)
    }

    /// The reaction of the closure `block` (one of [`TreeScene::CLOSURES`]:
    /// a loop's closing joint, a contact; a file's coupling acts on joints
    /// and loads no body) on every body at `state`, from the forces `lambda`
    /// of [`closure_forces`](Self::closure_forces) or
    /// [`constrained_dynamics`](Self::constrained_dynamics): `J_bᵀ λ` split by
    /// body, the same numbers as the absolute engine's
    /// [`reactions`](crate::dynamics::AbsoluteSimulation::reactions) of the
    /// joint (see the module's note on redundant rows). A block that is not
    /// the scene's gives zeros.
    pub fn closure_reactions(
        &self,
        state: &TreeState<NQ, NV>,
        lambda: &SVector<f64, NC>,
        block: &RowBlock,
    ) -> [Reaction; NB] {
        self.closure_wrenches(state, lambda, Some(block))
    }

    /// The joint named `joint`'s reaction on every body at `state` under
    /// joint forces `tau`: on its two bodies (zeros elsewhere), as the
    /// absolute engine's [`reactions`](crate::dynamics::AbsoluteSimulation::reactions)
    /// of its block gives them. A tree joint's on its child is
    /// [`reactions`](Self::reactions)' entry, its parent feels the
    /// opposite wrench at the joint point; a loop's closing joint's and a
    /// contact's are [`closure_reactions`](Self::closure_reactions)'. `None`
    /// for a name that is neither (a floating body's free joint has none).
    pub fn joint_reaction(
        &mut self,
        state: &TreeState<NQ, NV>,
        tau: &SVector<f64, NV>,
        joint: &str,
    ) -> Result<Option<[Reaction; NB]>, TreeError> {
        if let Some(block) = S::CLOSURES.iter().find(|b| b.name == joint) {
            let lambda = self.closure_forces(state, tau)?;
            return Ok(Some(self.closure_wrenches(state, &lambda, Some(block))));
        }
        let Some(k) = self.tree().joints().iter().position(|j| j.name == joint) else { return Ok(None) };
        let on_child = self.reactions(state, tau)?;
        let (Some(tree_joint), Some(&reaction)) = (self.tree().joints().get(k), on_child.get(k)) else {
            return Ok(None);
        };
        let bodies = self.tree().system_state(state).bodies;
        let mut out = [Reaction::default(); NB];
        let Some(child) = bodies.get(tree_joint.child) else { return Ok(None) };
        if let Some(slot) = out.get_mut(tree_joint.child) {
            *slot = reaction;
        }
        if let (Some(p), Some(parent)) = (tree_joint.parent, tree_joint.parent.and_then(|p| bodies.get(p))) {
            // The moment about the joint point, then about the parent's centre, in its axes.
            let to_point = child.rotation() * tree_joint.rho_child;
            let at_point = child.rotation() * reaction.torque - to_point.cross(&reaction.force);
            let arm = child.r + to_point - parent.r;
            let torque = parent.rotation().inverse() * (-at_point - arm.cross(&reaction.force));
            if let Some(slot) = out.get_mut(p) {
                *slot = Reaction { force: -reaction.force, torque };
            }
        }
        Ok(Some(out))
    }

    /// `J_bᵀ λ` on every body from the closure blocks (only `block` when given).
    fn closure_wrenches(
        &self,
        state: &TreeState<NQ, NV>,
        lambda: &SVector<f64, NC>,
        block: Option<&RowBlock>,
    ) -> [Reaction; NB] {
        let mut out = [Reaction::default(); NB];
        if NC == 0 {
            return out;
        }
        let rows = self.scene.closure_body_rows(&self.tree().system_state(state));
        for (ends, b) in S::CLOSURE_ENDS.iter().zip(S::CLOSURES) {
            if block.is_some_and(|only| only != b) {
                continue;
            }
            for r in b.start..b.start.saturating_add(b.rows).min(NC) {
                let l = lambda.get(r).copied().unwrap_or(0.0);
                for (e, end) in ends.iter().enumerate() {
                    let Some(body) = end.and_then(|n| out.get_mut(n)) else { continue };
                    for i in 0..3 {
                        let at = |c: usize| rows.get((r, 6 * e + c)).copied().unwrap_or(0.0);
                        body.force[i] += at(i) * l;
                        body.torque[i] += at(3 + i) * l;
                    }
                }
            }
        }
        out
    }
}
