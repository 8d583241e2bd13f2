//! Closed loops in relative coordinates: the closure rows the derive writes
//! (the joints outside the tree, composed with its kinematics) against a
//! closed form and differences, and the motion against the same declaration
//! in absolute coordinates.

use super::tree::same_motion;
use joint_runtime::Scene;
use joint_runtime::nalgebra::SVector;
use joint_runtime::relative::{TreeError, TreeScene, TreeSimulation, TreeState};

/// A parallelogram four-bar, upright at zero: crank and rocker 1 m, coupler
/// 1 m; `d` closes the loop. Planar, so three of its five rows are kept by
/// the tree (all axes along z) and dropped at compile time.
#[derive(Scene, Clone, Copy, Debug, Default)]
#[scene(gravity = [0, -9.81, 0], coordinates = both)]
#[body(crank, mass = 1.0, inertia = [0.1, 0.1, 0.1])]
#[body(coupler, mass = 1.5, inertia = [0.1, 0.15, 0.2])]
#[body(rocker, mass = 2.0, inertia = [0.2, 0.1, 0.2])]
#[joint(a = revolute(ground, crank), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0, 0, 0], rho2 = [0, -0.5, 0])]
#[joint(b = revolute(crank, coupler), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0, 0.5, 0], rho2 = [-0.5, 0, 0])]
#[joint(c = revolute(coupler, rocker), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0.5, 0, 0], rho2 = [0, 0.5, 0])]
#[joint(d = revolute(rocker, ground), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0, -0.5, 0], rho2 = [1, 0, 0])]
pub(crate) struct FourBar;

/// A spatial loop: a spherical joint closes it (three rows, none folded).
#[derive(Scene, Clone, Copy, Debug, Default)]
#[scene(gravity = [0, 0, -9.81], coordinates = both)]
#[body(arm, mass = 1.0, inertia = [0.01, 0.08, 0.08])]
#[body(link, mass = 0.5, inertia = [0.004, 0.05, 0.05])]
#[body(lever, mass = 0.8, inertia = [0.006, 0.04, 0.04])]
#[joint(base = revolute(ground, arm), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0, 0, 0], rho2 = [-0.5, 0, 0])]
#[joint(top = spherical(arm, link), rho1 = [0.5, 0, 0], rho2 = [-0.5, 0, 0])]
#[joint(pivot = revolute(ground, lever), axis1 = [1, 0, 0], axis2 = [0, 1, 0], rho1 = [1.5, 0, -0.6], rho2 = [0, 0, -0.3])]
#[joint(tip = spherical(link, lever), rho1 = [0.5, 0, 0], rho2 = [0, 0, 0.3])]
pub(crate) struct Spatial;

#[test]
fn planar_rows_kept_by_the_tree_are_dropped() {
    assert_eq!(<FourBar as TreeScene<3, 3, 3, 2>>::CLOSURES.len(), 1);
    let block = <FourBar as TreeScene<3, 3, 3, 2>>::CLOSURES[0];
    assert_eq!((block.name, block.start, block.rows), ("d", 0, 2));
    assert_eq!(<Spatial as TreeScene<3, 6, 5, 3>>::CLOSURES[0].rows, 3);
}

/// The parallelogram's closed form: the coupler stays level and the rocker
/// turns with the crank, so `Φ = 0` and `J v = 0` there; each column of `J`
/// is the velocity of the rocker's lower end when one joint turns at unit
/// rate and the others are held: `|J e₀| = 1` (about the crank's pivot, 1 m
/// away), `|J e₁| = √(2 + 2 sin θ)` (about the crank's top), `|J e₂| = 1`
/// (about the coupler's end).
#[test]
fn closure_rows_of_the_parallelogram() {
    let theta: f64 = 0.4;
    let state =
        TreeState::<3, 3> { q: SVector::from([theta, -theta, theta]), v: SVector::from([1.0, -1.0, 1.0]), t: 0.0 };
    let rows = TreeSimulation::new(&FourBar).unwrap().closure_rows(&state);
    assert!(rows.phi.amax() < 1e-15, "{}", rows.phi);
    assert!((rows.jacobian * state.v).amax() < 1e-15);
    let norms = [1.0, (2.0 + 2.0 * theta.sin()).sqrt(), 1.0];
    for (i, n) in norms.iter().enumerate() {
        let c = rows.jacobian.column(i).norm();
        assert!((c - n).abs() < 1e-14, "column {i}: {c} against {n}");
    }
}

/// `J` against central differences of `Φ` along each freedom, `γ` against
/// differences of `J v` along the motion, on the spatial loop at a state off
/// the closure (the rows are functions of any state).
#[test]
fn closure_derivatives_against_differences() {
    let state = TreeState::<6, 5> {
        q: SVector::from([0.3, 0.9, 0.1, -0.3, 0.2, -0.7]),
        v: SVector::from([0.7, -0.4, 1.1, 0.3, -0.9]),
        t: 0.0,
    };
    let sim = TreeSimulation::new(&Spatial).unwrap();
    let rows = sim.closure_rows(&state);
    let eps = 1e-6;
    for i in 0..5 {
        let mut dv = SVector::<f64, 5>::zeros();
        dv[i] = 1.0;
        let along = |c: f64| {
            let q = sim.tree().displaced(&state.q, &(dv * c));
            sim.closure_rows(&TreeState { q, ..state }).phi
        };
        let diff = (along(eps) - along(-eps)) / (2.0 * eps);
        assert!(
            (diff - rows.jacobian.column(i)).amax() < 1e-8,
            "column {i}: {diff} against {}",
            rows.jacobian.column(i)
        );
    }
    let jv = |c: f64| {
        let q = sim.tree().displaced(&state.q, &(state.v * c));
        sim.closure_rows(&TreeState { q, ..state }).jacobian * state.v
    };
    let diff = -(jv(eps) - jv(-eps)) / (2.0 * eps);
    assert!((diff - rows.gamma).amax() < 1e-7, "{diff} against {}", rows.gamma);
}

#[test]
fn loops_move_alike_in_both_coordinate_choices() {
    // The parallelogram swinging down from 0.3 rad with the crank at 1 rad/s.
    let start = TreeState::<3, 3> { q: SVector::from([0.3, -0.3, 0.3]), v: SVector::from([1.0, -1.0, 1.0]), t: 0.0 };
    let moved = same_motion(&FourBar, start, 5000, (1e-10, 1e-8));
    assert!(moved > 0.2, "the rocker moved {moved} m only");
    // The spatial loop assembled from a guess (the arm turned 0.5 rad, the
    // link back 1.2 rad about z, the lever 0.3 rad), then let fall.
    let sim = TreeSimulation::new(&Spatial).unwrap();
    let (c, s) = (0.6_f64.cos(), -(0.6_f64.sin()));
    let guess = TreeState::<6, 5> { q: SVector::from([0.5, c, 0.0, 0.0, s, 0.3]), v: SVector::zeros(), t: 0.0 };
    let start = sim.assemble(&guess).unwrap();
    assert!(sim.closure_rows(&start).phi.amax() < 1e-12);
    let moved = same_motion(&Spatial, start, 5000, (1e-10, 1e-8));
    assert!(moved > 0.05, "the lever moved {moved} m only");
}

/// A start off its loop is refused by the closing joint's name: a step
/// never closes its start unasked; `assemble` does.
#[test]
fn a_loop_that_cannot_close_is_named() {
    let mut sim = TreeSimulation::new(&FourBar).unwrap();
    // Crank and rocker turned opposite ways: the rocker's end 0.8 m from its pivot.
    let mut state = TreeState::<3, 3> { q: SVector::from([0.4, 0.0, -0.8]), v: SVector::zeros(), t: 0.0 };
    let before = state;
    match sim.step(&mut state, 1e-3) {
        Err(TreeError::NotAssembled { joint: "d", misfit }) => assert!(misfit > 0.5, "{misfit}"),
        other => panic!("expected the open loop at `d` refused, got {other:?}"),
    }
    assert_eq!(state, before);
    // Slightly open (1e-6 rad at the rocker): refused by a step, closed by `assemble`.
    let mut near = TreeState::<3, 3> { q: SVector::from([0.4, -0.4, 0.4 + 1e-6]), v: SVector::zeros(), t: 0.0 };
    assert!(matches!(sim.step(&mut near, 1e-3), Err(TreeError::NotAssembled { joint: "d", .. })));
    near = sim.assemble(&near).unwrap();
    assert!(sim.step(&mut near, 1e-3).is_ok());
    // Far off, full Newton finds the parallelogram nearby.
    let closed = sim.assemble(&before).unwrap();
    assert!(sim.closure_rows(&closed).phi.amax() < 1e-12 && (closed.q[0] + closed.q[1]).abs() < 1e-12);
}
