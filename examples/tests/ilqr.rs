//! iLQR on the exact step Jacobians (`joint_examples::ilqr`): the cost falls
//! at every iteration, the targets are reached, and central differences of
//! the step lead the same iterations to the same costs.

use joint_examples::ilqr::{self, Acrobot, Derivatives, PandaArm};
use joint_runtime::relative::TreeSimulation;

#[test]
fn the_panda_reaches_its_target() {
    let mut sim = TreeSimulation::new(&PandaArm).unwrap();
    let problem = ilqr::panda_problem(&sim);
    let exact = ilqr::solve(&mut sim, &problem, 12, Derivatives::Exact).unwrap();
    let costs: Vec<f64> = exact.iterations.iter().map(|i| i.cost).collect();
    assert!(costs.windows(2).all(|w| w[1] <= w[0]) && costs[0] < exact.initial_cost);
    assert!(exact.cost() < 1e-2 * exact.initial_cost, "{} of {}", exact.cost(), exact.initial_cost);
    let end = exact.states.last().unwrap();
    let (error, rate) = ((end.q - problem.target.0).amax(), end.v.amax());
    eprintln!(
        "Panda: cost {:.3e} → {:.3e}, joint error {error:.1e} rad, rate {rate:.1e}",
        exact.initial_cost,
        exact.cost()
    );
    assert!(error < 1e-3 && rate < 2e-2, "{error} {rate}");
    // Differences of the step take the same path (to their own error, 1e-5).
    let differenced = ilqr::solve(&mut sim, &problem, 3, Derivatives::Differences).unwrap();
    for (a, b) in exact.iterations.iter().zip(&differenced.iterations) {
        assert!((a.cost - b.cost).abs() < 1e-5 * a.cost, "{} {}", a.cost, b.cost);
    }
}

#[test]
fn the_acrobot_swings_up_on_its_elbow() {
    let mut sim = TreeSimulation::new(&Acrobot).unwrap();
    let problem = ilqr::acrobot_problem();
    let exact = ilqr::solve(&mut sim, &problem, 150, Derivatives::Exact).unwrap();
    let costs: Vec<f64> = exact.iterations.iter().map(|i| i.cost).collect();
    assert!(costs.windows(2).all(|w| w[1] <= w[0]));
    let end = exact.states.last().unwrap();
    let (error, rate) = ((end.q - problem.target.0).amax(), end.v.amax());
    eprintln!(
        "acrobot: cost {:.3e} → {:.3e}, off upright {error:.1e} rad, rate {rate:.1e}",
        exact.initial_cost,
        exact.cost()
    );
    assert!(exact.cost() < 0.05 * exact.initial_cost);
    assert!(error < 2e-2 && rate < 5e-2, "{error} {rate}");
    // The shoulder is never driven: the controls are the elbow's alone.
    assert_eq!(problem.actuation.column(0).as_slice(), &[0.0, 1.0]);
}
