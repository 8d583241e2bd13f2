//! The derive's straight-line solver pieces against the block factor's own:
//! the blocks of `J W Jᵀ` (`SparseJacobian::normal_blocks_into`, against the
//! factor's, formed from dense 6-column blocks of `J`), the products `J x`,
//! `Jᵀ y` (`j_mul_into`, `jt_mul_into`, against a walk of the CSR entries)
//! and the unrolled schedule (`factor_program`, `solve_program`, against the
//! factor's interpreter). The same scene behind a wrapper that forwards
//! everything but the generated pieces gives the same dynamics, the same
//! redundant rows and the same steps to round-off; without only the program,
//! the same bits (it calls the interpreter's kernels in its order). On scenes
//! with redundant rows (Bricard, the double Cardan's bearings), closed loops
//! whose elimination fills in (the ladder), and one large enough (200 bodies)
//! that the derive groups its statements and writes no program.

use joint_examples::{bricard, double_cardan, four_bar, scaling};
use joint_runtime::analysis::InverseMass;
use joint_runtime::dynamics::{AbsoluteSimulation, NoLoads, SimulationOptions};
use joint_runtime::nalgebra::{SMatrix, SVector, Vector3};
use joint_runtime::{BodyInertia, Evaluation, Ops, RowBlock, Scene, SparseJacobian, SystemState};

/// `S` with only the generated pieces `NORMAL` (the blocks of `J W Jᵀ` and
/// the products) and `PROGRAM` (the unrolled factorisation and solve); the
/// factor does the rest itself.
struct Wrapped<'a, S, const NORMAL: bool, const PROGRAM: bool>(&'a S);

/// Nothing generated: the factor's own blocks, products and schedule.
type Unformed<'a, S> = Wrapped<'a, S, false, false>;

impl<S: Scene<NB, NV, M>, const NB: usize, const NV: usize, const M: usize, const A: bool, const B: bool>
    Scene<NB, NV, M> for Wrapped<'_, S, A, B>
{
    const BODIES: [&'static str; NB] = S::BODIES;
    const BLOCKS: &'static [RowBlock] = S::BLOCKS;
    const OPS: Ops = S::OPS;
    fn phi(&self, state: &SystemState<NB>) -> SVector<f64, M> {
        self.0.phi(state)
    }
    fn phi_t(&self, state: &SystemState<NB>) -> SVector<f64, M> {
        self.0.phi_t(state)
    }
    fn jacobian(&self, state: &SystemState<NB>) -> SMatrix<f64, M, NV> {
        self.0.jacobian(state)
    }
    fn gamma(&self, state: &SystemState<NB>) -> SVector<f64, M> {
        self.0.gamma(state)
    }
    fn evaluate(&self, state: &SystemState<NB>) -> Evaluation<f64, M, NV> {
        self.0.evaluate(state)
    }
    fn inertias(&self) -> [BodyInertia; NB] {
        self.0.inertias()
    }
    fn gravity(&self) -> Vector3<f64> {
        self.0.gravity()
    }
}

impl<S: SparseJacobian<NB, NNZ>, const NB: usize, const NNZ: usize, const NORMAL: bool, const PROGRAM: bool>
    SparseJacobian<NB, NNZ> for Wrapped<'_, S, NORMAL, PROGRAM>
{
    const ROW_STARTS: &'static [usize] = S::ROW_STARTS;
    const COLUMNS: [usize; NNZ] = S::COLUMNS;
    const BLOCK_BODIES: &'static [[Option<usize>; 2]] = S::BLOCK_BODIES;
    const ELIMINATION: &'static [usize] = S::ELIMINATION;
    const FACTOR_STARTS: &'static [usize] = S::FACTOR_STARTS;
    const FACTOR_BELOW: &'static [usize] = S::FACTOR_BELOW;
    type Factor = S::Factor;
    const KKT_ORDER: &'static [usize] = S::KKT_ORDER;
    const KKT_STARTS: &'static [usize] = S::KKT_STARTS;
    const KKT_BELOW: &'static [usize] = S::KKT_BELOW;
    type Kkt<T: joint_runtime::absolute::KktEntry> = S::Kkt<T>;
    type Terms = S::Terms;
    fn jacobian_values_into(&self, state: &SystemState<NB>, out: &mut [f64; NNZ]) {
        self.0.jacobian_values_into(state, out);
    }
    fn normal_blocks_into(values: &[f64; NNZ], w: &[InverseMass; NB], factor: &mut Self::Factor) -> bool {
        NORMAL && S::normal_blocks_into(values, w, factor)
    }
    fn j_mul_into(values: &[f64; NNZ], x: &[f64], out: &mut [f64]) -> bool {
        NORMAL && S::j_mul_into(values, x, out)
    }
    fn jt_mul_into(values: &[f64; NNZ], y: &[f64], out: &mut [f64]) -> bool {
        NORMAL && S::jt_mul_into(values, y, out)
    }
    fn factor_program(factor: &mut Self::Factor, tolerance: f64, keep: bool) -> Option<usize> {
        if PROGRAM { S::factor_program(factor, tolerance, keep) } else { None }
    }
    fn solve_program(factor: &mut Self::Factor, b: &mut [f64]) -> bool {
        PROGRAM && S::solve_program(factor, b)
    }
}

/// `|a − b| ≤ tol (1 + max |b|)` entry by entry.
#[track_caller]
fn close(what: &str, a: &[f64], b: &[f64], tol: f64) {
    let scale = 1.0 + b.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    for (i, (x, y)) in a.iter().zip(b).enumerate() {
        assert!((x - y).abs() <= tol * scale, "{what}[{i}]: generated {x:e}, formed {y:e}");
    }
}

/// The dynamics at `state`, then `steps` RK4 steps with projection, with the
/// generated blocks and with the formed ones; `redundant` rows are dropped
/// (where the count is known independently).
fn same<S, const NB: usize, const NV: usize, const M: usize, const NNZ: usize>(
    scene: &S,
    mut state: SystemState<NB>,
    steps: usize,
    redundant: Option<usize>,
) where
    S: Scene<NB, NV, M> + SparseJacobian<NB, NNZ>,
{
    let options = SimulationOptions::default();
    let unformed: Unformed<S> = Wrapped(scene);
    let mut generated = AbsoluteSimulation::new(scene, NoLoads, &[], options).expect("generated");
    let mut formed = AbsoluteSimulation::new(&unformed, NoLoads, &[], options).expect("formed");
    let (a, b) = (generated.dynamics(&state).expect("generated"), formed.dynamics(&state).expect("formed"));
    assert_eq!(a.redundant, b.redundant);
    if let Some(n) = redundant {
        assert_eq!(a.redundant.len(), n);
    }
    close("v̇", a.vdot.as_slice(), b.vdot.as_slice(), 1e-11);
    close("λ", a.lambda.as_slice(), b.lambda.as_slice(), 1e-11);
    // Without only the program: the interpreter's kernels in its order.
    let interpreted = Wrapped::<S, true, false>(scene);
    let mut schedule = AbsoluteSimulation::new(&interpreted, NoLoads, &[], options).expect("interpreted");
    let c = schedule.dynamics(&state).expect("interpreted");
    assert_eq!((c.vdot, c.lambda, &c.redundant), (a.vdot, a.lambda, &a.redundant));
    let (mut other, mut third) = (state, state);
    for _ in 0..steps {
        generated.step(&mut state, 1e-3).expect("generated step");
        formed.step(&mut other, 1e-3).expect("formed step");
        schedule.step(&mut third, 1e-3).expect("interpreted step");
    }
    assert_eq!(state, third);
    for (x, y) in state.bodies.iter().zip(&other.bodies) {
        close("r", x.r.as_slice(), y.r.as_slice(), 1e-10);
        close("ω'", x.omega.as_slice(), y.omega.as_slice(), 1e-9);
    }
}

/// `J x` and `Jᵀ y` against the dense Jacobian, at a state off the
/// constraints (every entry of `J` in play).
fn products<S, const NB: usize, const NV: usize, const M: usize, const NNZ: usize>(scene: &S, state: &SystemState<NB>)
where
    S: Scene<NB, NV, M> + SparseJacobian<NB, NNZ>,
{
    let (values, dense) = (scene.jacobian_values(state), scene.jacobian(state));
    let x = SVector::<f64, NV>::from_fn(|i, _| 1.0 + (i as f64 * 0.37).sin());
    let y = SVector::<f64, M>::from_fn(|i, _| (i as f64 * 0.61).cos() - 0.25);
    let (mut jx, mut jty) = (SVector::<f64, M>::repeat(f64::NAN), SVector::<f64, NV>::repeat(f64::NAN));
    assert!(S::j_mul_into(&values, x.as_slice(), jx.as_mut_slice()));
    assert!(S::jt_mul_into(&values, y.as_slice(), jty.as_mut_slice()));
    close("J x", jx.as_slice(), (dense * x).as_slice(), 1e-14);
    close("Jᵀ y", jty.as_slice(), (dense.transpose() * y).as_slice(), 1e-14);
    // Other lengths are refused, not read past or half written.
    assert!(!S::j_mul_into(&values, &x.as_slice()[1..], jx.as_mut_slice()));
    assert!(!S::jt_mul_into(&values, y.as_slice(), &mut jty.as_mut_slice()[1..]));
}

#[test]
fn products_against_the_dense_jacobian() {
    let mut state = bricard::initial_state();
    state.bodies[1].r.x += 0.1;
    products(&bricard::scene(), &state);
    products(&four_bar::scene(), &four_bar::initial_state());
    products(&Ladder8, &scaling::ladder_start::<17>());
}

#[test]
fn bricard_with_its_redundant_row() {
    same(&bricard::scene(), bricard::initial_state(), 50, Some(1));
}

#[test]
fn four_bar() {
    same(&four_bar::scene(), four_bar::initial_state(), 50, None);
}

#[test]
fn double_cardan_with_its_bearings() {
    let geometry = double_cardan::Geometry::new(0.4, double_cardan::Arrangement::W, double_cardan::Phasing::InPhase)
        .expect("valid bend");
    let shaft = double_cardan::DoubleCardan::new(geometry, 10.0);
    same(&shaft, shaft.initial_state().expect("consistent start"), 50, None);
}

joint_examples::ladder_scene!(Ladder8, 8, 9);
joint_examples::chain_scene!(Chain200, 200);

#[test]
fn a_ladder_of_eight_loops_whose_elimination_fills_in() {
    same(&Ladder8, scaling::ladder_start::<17>(), 50, Some(3 * 8));
}

#[test]
fn a_200_body_chain() {
    same(&Chain200, scaling::chain_start::<200>(), 20, Some(0));
}
