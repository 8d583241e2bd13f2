//! `∂Q/∂q` and `∂Q/∂v` for the implicit integrators' iteration matrices and
//! the linearisation: exact for gravity (constant), the gyroscopic term and
//! the spring-dampers; for user loads, the user's own directional derivative
//! ([`AppliedLoads::derivative`]) or, where it gives none, central
//! differences of the loads alone.
//!
//! Increments are those of the velocities' layout: `δr` inertial, `δθ'` in
//! body components (`A ← A exp(δθ̃')`), `δṙ`, `δω'`.

use nalgebra::{SVector, Vector3};

use super::{AppliedLoads, Attachment, Loads, SpringDamper};
use crate::analysis::{apply_increment, set_velocities, velocity_vector};
use crate::rotation_matrix;
use crate::scene::SystemState;

/// Relative step of the central differences of user loads.
pub(crate) const LOAD_STEP: f64 = 1e-6;

/// A direction of the state: `(δr, δθ')` and `(δṙ, δω')` per body.
pub type Direction<const NB: usize> = [[Vector3<f64>; 4]; NB];

#[cfg(feature = "alloc")]
/// Column `c` of `∂Q/∂q` (`velocity` false, along the group increment) or of
/// `∂Q/∂v` at `state`: the user loads' own derivative or their central
/// differences, the springs' and the gyroscopic term's exact.
pub(crate) fn force_column<L: AppliedLoads<NB>, const NB: usize, const NV: usize>(
    user: &mut L,
    springs: &[SpringDamper],
    inertias: &[crate::scene::BodyInertia; NB],
    state: &SystemState<NB>,
    c: usize,
    velocity: bool,
) -> SVector<f64, NV> {
    let direction = unit::<NB>(c, velocity);
    let mut loads = Loads::<NB>::default();
    if !user.derivative(state, &direction, &mut loads) {
        loads = load_differences::<L, NB, NV>(user, state, c, velocity);
    }
    spring_derivatives(springs, state, &direction, &mut loads);
    generalised(&loads, inertias, state, &direction)
}

#[cfg(feature = "alloc")]
/// Central differences of the user loads alone along column `c`.
fn load_differences<L: AppliedLoads<NB>, const NB: usize, const NV: usize>(
    user: &mut L,
    state: &SystemState<NB>,
    c: usize,
    velocity: bool,
) -> Loads<NB> {
    let v = velocity_vector::<NB, NV>(state);
    let e = SVector::<f64, NV>::from_fn(|i, _| if i == c { 1.0 } else { 0.0 });
    let speed = if velocity { v.get(c).copied().map_or(0.0, libm::fabs) } else { 0.0 };
    load_differences_along(user, state, &e, velocity, LOAD_STEP * (1.0 + speed))
}

/// Central differences of the user loads alone along `delta` (in the
/// positions, along the group increment, or in the velocities) with the
/// step `step`.
pub(crate) fn load_differences_along<L: AppliedLoads<NB>, const NB: usize, const NV: usize>(
    user: &mut L,
    state: &SystemState<NB>,
    delta: &SVector<f64, NV>,
    velocity: bool,
    step: f64,
) -> Loads<NB> {
    let v = velocity_vector::<NB, NV>(state);
    let mut at = |sign: f64| {
        let mut s = *state;
        if velocity {
            set_velocities(&mut s, &(v + delta * (sign * step)));
        } else {
            apply_increment(&mut s, delta, sign * step);
        }
        let mut loads = Loads::<NB>::default();
        user.apply(&s, &mut loads);
        loads
    };
    let (plus, minus) = (at(1.0), at(-1.0));
    let mut out = Loads::<NB>::default();
    for b in 0..NB {
        out.force[b] = (plus.force[b] - minus.force[b]) / (2.0 * step);
        out.torque[b] = (plus.torque[b] - minus.torque[b]) / (2.0 * step);
    }
    out
}

/// The unit direction of velocity column `c`, in the positions or the velocities.
fn unit<const NB: usize>(c: usize, velocity: bool) -> Direction<NB> {
    let mut d = [[Vector3::zeros(); 4]; NB];
    let (b, k) = (c / 6, c % 6);
    if let Some(body) = d.get_mut(b) {
        body[usize::from(velocity) * 2 + k / 3][k % 3] = 1.0;
    }
    d
}

#[cfg(feature = "alloc")]
/// The derivative of `Q` along `direction`: the loads' derivative `loads`
/// (springs and user loads) with the gyroscopic term's, `−(δω' × J ω' + ω' × J δω')`.
fn generalised<const NB: usize, const NV: usize>(
    loads: &Loads<NB>,
    inertias: &[crate::scene::BodyInertia; NB],
    state: &SystemState<NB>,
    direction: &Direction<NB>,
) -> SVector<f64, NV> {
    let mut q = SVector::<f64, NV>::zeros();
    for (b, ((body, inertia), d)) in state.bodies.iter().zip(inertias.iter()).zip(direction.iter()).enumerate() {
        if 6 * b + 6 > NV {
            break;
        }
        let (w, dw) = (body.omega, d[3]);
        let torque = loads.torque[b] - dw.cross(&(inertia.inertia * w)) - w.cross(&(inertia.inertia * dw));
        q.fixed_rows_mut::<3>(6 * b).copy_from(&loads.force[b]);
        q.fixed_rows_mut::<3>(6 * b + 3).copy_from(&torque);
    }
    q
}

/// An attachment's position and velocity and their derivatives along `direction`.
struct PointTangent {
    x: Vector3<f64>,
    v: Vector3<f64>,
    dx: Vector3<f64>,
    dv: Vector3<f64>,
    /// The body and the body-fixed point, for the moment.
    on: Option<(usize, Vector3<f64>)>,
}

fn point_tangent<const NB: usize>(
    state: &SystemState<NB>,
    end: &Attachment,
    direction: &Direction<NB>,
) -> PointTangent {
    let (zero, none) = (Vector3::zeros(), None);
    match *end {
        Attachment::Ground(x) => PointTangent { x, v: zero, dx: zero, dv: zero, on: none },
        Attachment::Body { body, point } => match (state.bodies.get(body), direction.get(body)) {
            (Some(s), Some(d)) => {
                let a = rotation_matrix(&s.p);
                let spin = s.omega.cross(&point);
                PointTangent {
                    x: s.r + a * point,
                    v: s.rdot + a * spin,
                    // A ← A exp(δθ̃'): δ(A p') = A (δθ' × p').
                    dx: d[0] + a * d[1].cross(&point),
                    dv: d[2] + a * (d[1].cross(&spin) + d[3].cross(&point)),
                    on: Some((body, point)),
                }
            }
            _ => PointTangent { x: zero, v: zero, dx: zero, dv: zero, on: none },
        },
    }
}

/// Adds the derivative of every spring-damper's loads along `direction`:
/// tension `T = k (L − L₀) + c u·(v_b − v_a)` along `u = d / L`, the force
/// `±u T` at each end and its moment `p' × Aᵀ F` about the body's centre.
fn spring_derivatives<const NB: usize>(
    springs: &[SpringDamper],
    state: &SystemState<NB>,
    direction: &Direction<NB>,
    loads: &mut Loads<NB>,
) {
    for s in springs {
        let (a, b) = (point_tangent(state, &s.a, direction), point_tangent(state, &s.b, direction));
        let d = b.x - a.x;
        let len = d.norm();
        if len.is_nan() || len <= 1e-12 {
            continue;
        }
        let u = d / len;
        let (dd, rel, drel) = (b.dx - a.dx, b.v - a.v, b.dv - a.dv);
        let dlen = u.dot(&dd);
        let du = (dd - u * dlen) / len;
        let tension = s.stiffness * (len - s.rest_length) + s.damping * u.dot(&rel);
        let dtension = s.stiffness * dlen + s.damping * (du.dot(&rel) + u.dot(&drel));
        let (force, dforce) = (u * tension, du * tension + u * dtension);
        for (end, sign) in [(&a, 1.0), (&b, -1.0)] {
            let Some((body, point)) = end.on else { continue };
            let (Some(f), Some(t), Some(st), Some(dir)) =
                (loads.force.get_mut(body), loads.torque.get_mut(body), state.bodies.get(body), direction.get(body))
            else {
                continue;
            };
            let at = rotation_matrix(&st.p).transpose();
            // δ(Aᵀ F) = Aᵀ δF − δθ' × Aᵀ F.
            let body_force = at * force * sign;
            *f += dforce * sign;
            *t += point.cross(&(at * dforce * sign - dir[1].cross(&body_force)));
        }
    }
}

/// One spring-damper's share of column `c` of `∂Q/∂q` (`velocity` false) or
/// `∂Q/∂v`: the derivative of its loads on each body (the sparse path's
/// iteration matrix, which visits only the columns of the spring's bodies).
pub(crate) fn spring_column<const NB: usize>(
    spring: &SpringDamper,
    state: &SystemState<NB>,
    c: usize,
    velocity: bool,
) -> Loads<NB> {
    let mut loads = Loads::<NB>::default();
    spring_derivatives(core::slice::from_ref(spring), state, &unit::<NB>(c, velocity), &mut loads);
    loads
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::OmegaBody;
    use crate::dynamics::{NoLoads, generalised_forces};
    use crate::scene::BodyInertia;
    use nalgebra::{Matrix3, UnitQuaternion};

    /// Two tumbling bodies, a spring-damper between them and one to the ground:
    /// the exact `∂Q/∂q`, `∂Q/∂v` against Richardson-extrapolated central
    /// differences of `generalised_forces` (gyroscopic terms included).
    #[test]
    fn spring_and_gyroscopic_derivatives_match_differences() {
        let body = |r: Vector3<f64>, axis: Vector3<f64>, v: Vector3<f64>, w: Vector3<f64>| {
            OmegaBody::from_rotation(r, &UnitQuaternion::from_scaled_axis(axis), v, w)
        };
        let state = SystemState {
            bodies: [
                body(
                    Vector3::new(0.1, 0.2, 0.3),
                    Vector3::new(0.3, -0.2, 0.5),
                    Vector3::new(0.4, -1.0, 0.2),
                    Vector3::new(1.0, 2.0, -0.5),
                ),
                body(
                    Vector3::new(1.1, -0.4, 0.2),
                    Vector3::new(-0.6, 0.1, 0.2),
                    Vector3::new(-0.3, 0.5, 0.9),
                    Vector3::new(-2.0, 0.3, 1.5),
                ),
            ],
            t: 0.0,
        };
        let springs = [
            SpringDamper {
                a: Attachment::Body { body: 0, point: Vector3::new(0.2, -0.1, 0.3) },
                b: Attachment::Body { body: 1, point: Vector3::new(-0.3, 0.2, 0.1) },
                stiffness: 500.0,
                damping: 3.0,
                rest_length: 0.4,
            },
            SpringDamper {
                a: Attachment::Ground(Vector3::new(0.5, 1.0, -0.5)),
                b: Attachment::Body { body: 1, point: Vector3::new(0.1, 0.4, -0.2) },
                stiffness: 200.0,
                damping: 1.0,
                rest_length: 0.7,
            },
        ];
        let inertias = [
            BodyInertia { mass: 1.0, inertia: Matrix3::new(0.3, 0.01, 0.0, 0.01, 0.2, 0.02, 0.0, 0.02, 0.1) },
            BodyInertia { mass: 2.0, inertia: Matrix3::from_diagonal(&Vector3::new(0.5, 0.4, 0.3)) },
        ];
        let gravity = Vector3::new(0.0, 0.0, -9.81);
        let q = |s: &SystemState<2>| generalised_forces::<_, 2, 12>(&mut NoLoads, &springs, &inertias, &gravity, s);
        let v = velocity_vector::<2, 12>(&state);
        let mut worst = 0.0f64;
        for c in 0..12 {
            for velocity in [false, true] {
                let direction = unit::<2>(c, velocity);
                let mut loads = Loads::<2>::default();
                spring_derivatives(&springs, &state, &direction, &mut loads);
                let exact = generalised::<2, 12>(&loads, &inertias, &state, &direction);
                let e = SVector::<f64, 12>::from_fn(|i, _| if i == c { 1.0 } else { 0.0 });
                let at = |h: f64| {
                    let mut s = state;
                    if velocity {
                        set_velocities(&mut s, &(v + e * h));
                    } else {
                        apply_increment(&mut s, &e, h);
                    }
                    q(&s)
                };
                let central = |h: f64| (at(h) - at(-h)) / (2.0 * h);
                let fd = (central(5e-4) * 4.0 - central(1e-3)) / 3.0;
                worst = worst.max((exact - fd).amax() / (1.0 + fd.amax()));
            }
        }
        assert!(worst < 1e-10, "worst {worst:e}");
    }
}
