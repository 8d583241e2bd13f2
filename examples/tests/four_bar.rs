//! The N-four-bar (IFToMM A02, N = 4): rank drop at the singular position, and
//! 10 s through it again and again without failing, energy and Φ kept.

use joint_examples::coordinates;
use joint_examples::four_bar::{self, COLUMNS, ROWS};
use joint_runtime::Scene;
use joint_runtime::dynamics::Integrator;

#[test]
fn the_horizontal_position_drops_n_more_rows() {
    let scene = four_bar::scene();
    let upright = four_bar::initial_state();
    assert!(scene.phi(&upright).norm() < 1e-15);
    assert_eq!(four_bar::dropped_rows(&scene, &upright), 3 * four_bar::LOOPS, "three redundant rows per planar loop");
    let flat = four_bar::state_at(0.0, 1.0);
    assert!(scene.phi(&flat).norm() < 1e-15);
    assert_eq!(four_bar::dropped_rows(&scene, &flat), 4 * four_bar::LOOPS, "N more at the singular position");
    // Singular values: one zero (mobility 1) upright, N + 1 zeros horizontal.
    let zeros = |s: &[f64]| s.iter().filter(|&&x| x < 1e-10).count();
    let (up, fl) = (four_bar::singular_values(&scene, &upright), four_bar::singular_values(&scene, &flat));
    assert_eq!((up.len(), zeros(&up), zeros(&fl)), (COLUMNS, 1, four_bar::LOOPS + 1));
    assert!(four_bar::critical_singular_value(&scene, &upright) > 0.3);
    assert!(four_bar::critical_singular_value(&scene, &flat) < 1e-12);
    assert_eq!(ROWS, 65);
}

#[test]
fn ten_seconds_through_the_singular_position() {
    let scene = four_bar::scene();
    let run = four_bar::simulate(&scene, &four_bar::initial_state(), Integrator::Rk4, 2e-3, 10.0, 50)
        .expect("no step fails, singular passages included");
    // It turns over and over: ten passages through the horizontal in 10 s.
    assert_eq!(run.singular_passages, 10);
    // Close to the singular position: the critical singular value fell from 0.318
    // (upright) to 3.2e-5 at 1.2e-4 rad from the horizontal.
    assert!(run.min_singular_value < 1e-4, "σ_min = {:e}", run.min_singular_value);
    assert!(run.min_singular_angle.abs() < 1e-3, "closest {:e} rad", run.min_singular_angle);
    // Energy and constraint drift (measured 1.5e-10 and 1.0e-12).
    assert!(run.max_relative_energy_error < 1e-8, "energy {:e}", run.max_relative_energy_error);
    assert!(run.max_constraint <= 1e-10, "|Φ| = {:e}", run.max_constraint);
    assert!(run.max_velocity_constraint < 1e-12, "|J v| = {:e}", run.max_velocity_constraint);
    // Still the parallelogram: no bar left the branch at a bifurcation.
    assert!(run.max_branch_deviation < 1e-8, "branch {:e}", run.max_branch_deviation);
    // B0 after 10 s (measured (0.251386, 0.967887)): on its unit circle.
    let b0 = four_bar::b0(&run.end);
    assert!((b0.norm() - 1.0).abs() < 1e-10);
    assert!((b0.x - 0.251386).abs() < 1e-5 && (b0.y - 0.967887).abs() < 1e-5, "B0 = {b0:?}");
}

#[test]
fn a_step_from_exactly_the_singular_position() {
    let scene = four_bar::scene();
    let flat = four_bar::state_at(0.0, -1.0);
    let run = four_bar::simulate(&scene, &flat, Integrator::Rk4, 1e-3, 2.0, 100).expect("starts on the singularity");
    assert_eq!(run.max_dropped_rows, 16, "the first factorisation drops 4N rows");
    assert!(run.singular_passages >= 2);
    assert!(run.max_relative_energy_error < 1e-5, "energy {:e}", run.max_relative_energy_error);
    assert!(run.max_constraint <= 1e-10);
    assert!(run.max_branch_deviation < 1e-6, "branch {:e}", run.max_branch_deviation);
}

/// The one declaration in relative coordinates (nine crank and coupler
/// angles, the four `right` joints closing the loops, two rows each: the
/// other three are kept by the planar tree and dropped at compile time)
/// against the absolute scene: RK4 at h = 1e-4 for 1 s, through the first
/// singular position, where the closure rows lose four ranks.
#[test]
fn both_coordinate_choices_agree_through_the_singular_position() {
    let (mut passages, mut last) = (0, f64::NAN);
    let both = coordinates::both(&four_bar::scene(), &four_bar::initial_state(), &[], 1e-4, 10_000, |relative, _| {
        let s = four_bar::crank_angle(relative, 0).sin();
        passages += usize::from(s * last < 0.0);
        last = s;
    })
    .expect("both run through it");
    assert!(passages >= 1, "no singular passage in the run");
    assert!(both.worst < 1e-10, "the coordinate choices differ by {:e}", both.worst);
    assert!(four_bar::branch_deviation(&both.relative) < 1e-8);
}
