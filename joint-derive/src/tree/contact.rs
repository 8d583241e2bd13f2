//! A contact's rows in the tree's coordinates (`#[contact(..)]`, see
//! `front::contact`): written at the velocity level, as rigid contacts are in
//! the robot world, then differentiated by the engine like a loop's rows.
//!
//! For a point `p = r + A ρ` on body 1 (minus the same on body 2) the rows'
//! velocity is `Ψ = ṗ` in the world's axes or `R_fᵀ ṗ` in the contact
//! frame's (`R_f = A R_link`). `J = ∂Ψ/∂v`; `γ = −p̈` at `v̇ = 0`, the
//! classical acceleration, in the same axes (`R_fᵀ p̈` in the frame's: the
//! frame's rotation held, as Pinocchio's `LOCAL` contact has it, so that
//! the two choices give the same `v̇` and forces that differ by `R_f`
//! alone). A frame's rows are its twist in its own axes, `[R_fᵀ ṗ; ω]` with
//! `[ω]× = R_fᵀ Ṙ_f`, and `γ = −d/dt` of it at `v̇ = 0` (its spatial
//! acceleration); in the world's axes both halves turned by `R_f`. The rows
//! hold no position (`Φ = 0`): a contact holds where it is when it is
//! made, so only its velocity and acceleration are rows.

use crate::engine::grad;
use crate::engine::graph::Id;
use crate::front::contact::{Axes, ContactDecl, ContactEnd, ContactKind};
use crate::kinematics::{Kinematics, V3};

/// A body's rotation and centre as expressions of the tree's coordinates.
pub type Pose = ([[Id; 3]; 3], V3);

/// The rows of contact `c`: each one's `J` row and `γ`. `poses` holds every
/// body's pose, in body order.
pub fn rows(k: &mut Kinematics, poses: &[Pose], c: &ContactDecl) -> Vec<(Vec<Id>, Id)> {
    let [first, second] = c.ends;
    let frame = frame(k, poses, &first);
    let p1 = point(k, poses, &first);
    let p2 = point(k, poses, &second);
    let rate: V3 = [0, 1, 2].map(|i| {
        let (a, b) = (k.rules.dt(&mut k.g, p1[i]), k.rules.dt(&mut k.g, p2[i]));
        k.g.sub(a, b)
    });
    let velocities = k.velocities.clone();
    let (psi, gamma): (Vec<Id>, Vec<Id>) = match c.kind {
        ContactKind::Point => {
            let accel: V3 = rate.map(|x| {
                let d = k.rules.dt(&mut k.g, x);
                k.g.neg(d)
            });
            match c.axes {
                Axes::World => (rate.to_vec(), accel.to_vec()),
                Axes::Local => (turn_back(k, &frame, rate).to_vec(), turn_back(k, &frame, accel).to_vec()),
            }
        }
        ContactKind::Frame => {
            // The twist in the frame's axes and its spatial acceleration.
            let linear = turn_back(k, &frame, rate);
            let spin = spin(k, &frame);
            let twist: Vec<Id> = linear.into_iter().chain(spin).collect();
            let accel: Vec<Id> = twist
                .iter()
                .map(|&x| {
                    let d = k.rules.dt(&mut k.g, x);
                    k.g.neg(d)
                })
                .collect();
            match c.axes {
                Axes::Local => (twist, accel),
                Axes::World => {
                    let halves = |k: &mut Kinematics, x: &[Id]| -> Vec<Id> {
                        let (a, b) = ([x[0], x[1], x[2]], [x[3], x[4], x[5]]);
                        turn(k, &frame, a).into_iter().chain(turn(k, &frame, b)).collect()
                    };
                    (halves(k, &twist), halves(k, &accel))
                }
            }
        }
    };
    psi.iter().zip(gamma).map(|(&row, gamma)| (grad(&mut k.g, row, &velocities), gamma)).collect()
}

/// The contact frame's axes in the world's: `A R_link`.
fn frame(k: &mut Kinematics, poses: &[Pose], end: &ContactEnd) -> [[Id; 3]; 3] {
    let Some(b) = end.body else {
        return end.rotation.map(|row| row.map(|x| k.g.constant(x)));
    };
    let a = poses[b].0;
    let link = end.rotation.map(|row| row.map(|x| k.g.constant(x)));
    [0, 1, 2].map(|r| {
        [0, 1, 2].map(|c| {
            let terms: Vec<Id> = (0..3).map(|i| k.g.mul(a[r][i], link[i][c])).collect();
            k.g.sum(&terms)
        })
    })
}

/// The contact point in the world: `r + A ρ` (on the ground, `ρ` itself).
pub fn point(k: &mut Kinematics, poses: &[Pose], end: &ContactEnd) -> V3 {
    let rho = end.point.map(|x| k.g.constant(x));
    let Some(b) = end.body else { return rho };
    let (a, r) = poses[b];
    [0, 1, 2].map(|i| {
        let terms: Vec<Id> = (0..3).map(|j| k.g.mul(a[i][j], rho[j])).collect();
        let turned = k.g.sum(&terms);
        k.g.add(r[i], turned)
    })
}

/// `Rᵀ x`: a world vector in the frame's axes.
fn turn_back(k: &mut Kinematics, r: &[[Id; 3]; 3], x: V3) -> V3 {
    [0, 1, 2].map(|c| {
        let terms: Vec<Id> = (0..3).map(|i| k.g.mul(r[i][c], x[i])).collect();
        k.g.sum(&terms)
    })
}

/// `R x`: a vector in the frame's axes in the world's.
fn turn(k: &mut Kinematics, r: &[[Id; 3]; 3], x: V3) -> V3 {
    [0, 1, 2].map(|i| {
        let terms: Vec<Id> = (0..3).map(|c| k.g.mul(r[i][c], x[c])).collect();
        k.g.sum(&terms)
    })
}

/// The frame's angular velocity in its own axes: `[ω]× = Rᵀ Ṙ`, so
/// `ω_x = R_{:,2}·Ṙ_{:,1}`, `ω_y = R_{:,0}·Ṙ_{:,2}`, `ω_z = R_{:,1}·Ṙ_{:,0}`.
fn spin(k: &mut Kinematics, r: &[[Id; 3]; 3]) -> V3 {
    let rate: [[Id; 3]; 3] = r.map(|row| row.map(|x| k.rules.dt(&mut k.g, x)));
    [(2, 1), (0, 2), (1, 0)].map(|(a, b)| {
        let terms: Vec<Id> = (0..3).map(|i| k.g.mul(r[i][a], rate[i][b])).collect();
        k.g.sum(&terms)
    })
}
