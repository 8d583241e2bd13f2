//! References for the generated second-order terms: a joint's by num-dual over
//! its generated `J` and `γ` ([`joint_by_duals`]), a scene's by central
//! differences of its generated `J` and `γ` on the rotation group,
//! Richardson-extrapolated ([`worst_error`]): `p ⊕ δθ' = p ⊗ exp(δθ')` through
//! nalgebra's `UnitQuaternion`, independent of the runtime's own increments.

use joint_runtime::nalgebra::{SMatrix, SVector, UnitQuaternion, Vector3, Vector4};
use joint_runtime::{Joint, Scene, SecondOrder, SystemState};
use num_dual::Dual64;

use crate::trajectory::{Coords, Form, along, lift, with_velocity};

/// `state` moved by `scale` along the unit increment of column `k`, or with
/// velocity column `k` changed by `scale` when `velocity`.
fn moved<const NB: usize>(state: &SystemState<NB>, k: usize, scale: f64, velocity: bool) -> SystemState<NB> {
    let mut s = *state;
    let (b, c) = (k / 6, k % 6);
    let body = &mut s.bodies[b];
    match (velocity, c < 3) {
        (true, true) => body.rdot[c] += scale,
        (true, false) => body.omega[c - 3] += scale,
        (false, true) => body.r[c] += scale,
        (false, false) => {
            let mut axis = Vector3::zeros();
            axis[c - 3] = scale;
            let p = body.p;
            let q = UnitQuaternion::from_quaternion(joint_runtime::nalgebra::Quaternion::new(p[0], p[1], p[2], p[3]));
            let turned = q * UnitQuaternion::from_scaled_axis(axis);
            let w = turned.quaternion();
            body.p = Vector4::new(w.w, w.i, w.j, w.k);
        }
    }
    s
}

/// The derivative of `f` along column `k` by Richardson-extrapolated central
/// differences (error O(ε⁴)).
fn derivative<const NB: usize, const R: usize>(
    state: &SystemState<NB>,
    k: usize,
    velocity: bool,
    f: &dyn Fn(&SystemState<NB>) -> SVector<f64, R>,
) -> SVector<f64, R> {
    let central = |e: f64| (f(&moved(state, k, e, velocity)) - f(&moved(state, k, -e, velocity))) / (2.0 * e);
    let e = 1e-3;
    (central(e / 2.0) * 4.0 - central(e)) / 3.0
}

/// The matrix whose column `k` is the derivative of `f` along column `k`.
fn columns<const NB: usize, const R: usize, const NV: usize>(
    state: &SystemState<NB>,
    velocity: bool,
    f: &dyn Fn(&SystemState<NB>) -> SVector<f64, R>,
) -> SMatrix<f64, R, NV> {
    let mut m = SMatrix::<f64, R, NV>::zeros();
    for k in 0..NV {
        m.set_column(k, &derivative(state, k, velocity, f));
    }
    m
}

/// The second-order terms by differences of the generated `J` and `γ`.
pub fn by_differences<S: Scene<NB, NV, M>, const NB: usize, const NV: usize, const M: usize>(
    scene: &S,
    state: &SystemState<NB>,
    lambda: &SVector<f64, M>,
    u: &SVector<f64, NV>,
) -> SecondOrder<f64, M, NV> {
    SecondOrder {
        stiffness: columns(state, false, &|s| scene.jacobian(s).transpose() * lambda),
        jacobian_q: columns(state, false, &|s| scene.jacobian(s) * u),
        gamma_q: columns(state, false, &|s| scene.gamma(s)),
        gamma_v: columns(state, true, &|s| scene.gamma(s)),
        phi_t_q: columns(state, false, &|s| scene.phi_t(s)),
    }
}

/// The largest difference between the generated terms and the differences,
/// each relative to `1 +` the largest entry of its matrix, with the name of
/// the worst term.
pub fn worst_error<S: Scene<NB, NV, M>, const NB: usize, const NV: usize, const M: usize>(
    scene: &S,
    state: &SystemState<NB>,
    lambda: &SVector<f64, M>,
    u: &SVector<f64, NV>,
) -> (f64, &'static str) {
    let generated = scene.second_order(state, lambda, u).expect("the scene was derived with `second_order`");
    let fd = by_differences(scene, state, lambda, u);
    let rel = |a: &[f64], b: &[f64]| {
        let scale = 1.0 + b.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        a.iter().zip(b).fold(0.0f64, |m, (x, y)| m.max((x - y).abs())) / scale
    };
    [
        (rel(generated.stiffness.as_slice(), fd.stiffness.as_slice()), "stiffness"),
        (rel(generated.jacobian_q.as_slice(), fd.jacobian_q.as_slice()), "jacobian_q"),
        (rel(generated.gamma_q.as_slice(), fd.gamma_q.as_slice()), "gamma_q"),
        (rel(generated.gamma_v.as_slice(), fd.gamma_v.as_slice()), "gamma_v"),
        (rel(generated.phi_t_q.as_slice(), fd.phi_t_q.as_slice()), "phi_t_q"),
    ]
    .into_iter()
    .fold((0.0, ""), |w, x| if x.0 > w.0 { x } else { w })
}

/// Every entry of a joint's generated second-order terms (`K`, `∂(J u)/∂q`,
/// `∂γ/∂q`, `∂γ/∂v`, each column-major).
pub fn joint_generated<J: Joint<f64, R, C>, const R: usize, const C: usize>(
    joint: &J,
    state: &J::State,
    lambda: &SVector<f64, R>,
    u: &SVector<f64, C>,
) -> Vec<f64> {
    let s = joint.second_order(state, lambda, u).expect("the joint is derived with `second_order`");
    [s.stiffness.as_slice(), s.jacobian_q.as_slice(), s.gamma_q.as_slice(), s.gamma_v.as_slice(), s.phi_t_q.as_slice()]
        .concat()
}

/// The same entries by num-dual over the generated `jacobian` and `gamma` of
/// `jd` (the joint in `Dual64`) at the coordinates `c` and time `t`: column `k`
/// is the derivative of `Jᵀλ`, `J u` or γ along the exact group curve
/// `q ⊕ τ e_k` (the trajectory of [`along`] with velocity `e_k`, the velocities
/// then put back and held), or along `v + τ e_k` for `∂γ/∂v`.
pub fn joint_by_duals<Fo: Form<C>, J, const R: usize, const C: usize>(
    jd: &J,
    c: &Coords<f64>,
    t: f64,
    lambda: &SVector<f64, R>,
    u: &SVector<f64, C>,
) -> Vec<f64>
where
    J: Joint<Dual64, R, C, State = Fo::State<Dual64>>,
{
    let tau = Dual64::from_re(0.0).derivative();
    let v = Fo::velocity(c).map(Dual64::from_re);
    let (lambda, u) = (lambda.map(Dual64::from_re), u.map(Dual64::from_re));
    let eps = |x: Dual64| x.eps;
    let (mut stiffness, mut jacobian_q) = (SMatrix::<f64, C, C>::zeros(), SMatrix::<f64, R, C>::zeros());
    let (mut gamma_q, mut gamma_v) = (SMatrix::<f64, R, C>::zeros(), SMatrix::<f64, R, C>::zeros());
    let mut phi_t_q = SMatrix::<f64, R, C>::zeros();
    for col in 0..C {
        let e = SVector::<f64, C>::from_fn(|i, _| if i == col { 1.0 } else { 0.0 });
        let moved = along(&with_velocity(c, &e), Fo::ROT, tau);
        let s = Fo::build(&with_velocity(&moved, &v), t);
        let j = jd.jacobian(&s);
        stiffness.set_column(col, &(j.transpose() * lambda).map(eps));
        jacobian_q.set_column(col, &(j * u).map(eps));
        gamma_q.set_column(col, &jd.gamma(&s).map(eps));
        phi_t_q.set_column(col, &jd.phi_t(&s).map(eps));
        let faster = with_velocity(&c.map(lift::<Dual64>), &(v + e.map(Dual64::from_re) * tau));
        gamma_v.set_column(col, &jd.gamma(&Fo::build(&faster, t)).map(eps));
    }
    [stiffness.as_slice(), jacobian_q.as_slice(), gamma_q.as_slice(), gamma_v.as_slice(), phi_t_q.as_slice()].concat()
}
