//! The Solo12 standing, shifting its weight and lifting a foot
//! (`joint_examples::solo_stance`): what a stance must be.

use joint_examples::solo_stance::{self, PHASES};

/// Feet are pushed, never pulled, while they hold; the lifted foot rises and
/// carries nothing; the held feet stay where they are; the base follows its
/// target; touchdown is an impact.
#[test]
fn the_robot_stands_shifts_and_lifts_a_foot() {
    let run = solo_stance::simulate(3.0, 1e-3).unwrap();
    let first = run.samples[0];
    let (mut least_push, mut slip, mut lift) = (f64::INFINITY, 0.0_f64, 0.0_f64);
    // Where each held foot was put down (the lifted one lands elsewhere).
    let mut anchors = first.feet;
    for (k, s) in run.samples.iter().enumerate() {
        for foot in 0..4 {
            let held = foot != 0 || s.front_left_down;
            if held {
                if foot == 0 && k > 0 && !run.samples[k - 1].front_left_down {
                    anchors[0] = s.feet[0];
                }
                least_push = least_push.min(s.forces[foot].z);
                slip = slip.max((s.feet[foot] - anchors[foot]).norm());
            } else {
                assert_eq!(s.forces[foot].norm(), 0.0);
            }
        }
        lift = lift.max(s.feet[0].z - first.feet[0].z);
    }
    // The weight over the three other feet while the foot is up: their forces sum to it.
    let mid = run.samples.iter().find(|s| s.t >= 0.5 * (PHASES[1] + PHASES[2]) + 0.1).unwrap();
    let weight: f64 = mid.forces.iter().map(|f| f.z).sum();
    let end = run.samples.last().unwrap();
    eprintln!(
        "Solo12 stance: least push {least_push:.2} N, weight on three feet {weight:.2} N, foot lifted {:.1} mm, \
         held feet slipped {:.2e} m, touchdown jump {:.3} (rad or m)/s, base {:.1} mm from home at the end",
        lift * 1e3,
        slip,
        run.touchdown_jump,
        (end.base - first.base).norm() * 1e3
    );
    assert!(least_push > 1.0, "a held foot was pulled: {least_push}");
    assert!(lift > 0.03, "the foot rose by {lift} m");
    assert!(slip < 1e-4, "a held foot slipped by {slip} m");
    assert!(run.touchdown_jump > 0.0);
    assert!((end.base - first.base).norm() < 5e-3);
    // Total mass from the file, through the forces at rest.
    assert!((weight - first.forces.iter().map(|f| f.z).sum::<f64>()).abs() < 0.5);
}
