//! Criterion benchmarks of the generated code: a universal (Cardan) joint's
//! `evaluate`, `phi`, `jacobian` and `gamma` in the `omega_body` and `euler`
//! formulations (all parameters run-time fields), the driven double Cardan
//! shaft's system `evaluate` ([`DoubleCardan`], 3 bodies, 19 rows), and one
//! `Simulation::step` (h = 1 ms, projection on) of the free double Cardan shaft
//! with each integrator.
//!
//! ```text
//! cargo bench -p joint-examples --bench generated            # full measurement
//! cargo bench -p joint-examples --bench generated -- --quick # a rough one, seconds
//! ```

#![allow(missing_docs)] // criterion's macros generate undocumented public items

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use joint_examples::double_cardan::{Arrangement, DoubleCardan, FreeDoubleCardan, Geometry, Phasing};
use joint_runtime::dynamics::{Integrator, NoLoads, Simulation, SimulationOptions};
use joint_runtime::nalgebra::{UnitQuaternion, Vector3, Vector4};
use joint_runtime::{EulerBody, Joint, OmegaBody, Scene, TwoBodies};

/// A universal joint, angular velocities in body components (4 rows, 12 columns).
#[derive(Joint)]
#[joint(universal, formulation = omega_body)]
struct UniversalOmegaBody<T> {
    s: Vector3<T>,
    h: Vector3<T>,
    rho1: Vector3<T>,
    rho2: Vector3<T>,
}

/// The same joint on Euler parameters (4 rows, 14 columns).
#[derive(Joint)]
#[joint(universal, formulation = euler)]
struct UniversalEuler<T> {
    s: Vector3<T>,
    h: Vector3<T>,
    rho1: Vector3<T>,
    rho2: Vector3<T>,
}

/// A bent shaft (30°) turning: the yokes `y'` and `z'`, the cross at the origin.
fn parameters() -> [Vector3<f64>; 4] {
    [Vector3::y(), Vector3::z(), Vector3::new(0.5, 0.0, 0.0), Vector3::new(-0.5, 0.0, 0.0)]
}

fn rotations() -> (UnitQuaternion<f64>, UnitQuaternion<f64>) {
    let bend = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 30f64.to_radians());
    let turn = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), 0.7);
    (turn, bend * turn)
}

fn joints(c: &mut Criterion) {
    let [s, h, rho1, rho2] = parameters();
    let (q1, q2) = rotations();

    let joint = UniversalOmegaBody { s, h, rho1, rho2 };
    let spin = Vector3::new(10.0, 0.3, -0.2);
    let state = TwoBodies::new(
        OmegaBody::from_rotation(Vector3::new(-0.5, 0.0, 0.0), &q1, Vector3::new(0.0, 0.1, 0.0), spin),
        OmegaBody::from_rotation(Vector3::new(0.43, 0.25, 0.0), &q2, Vector3::new(0.0, -0.1, 0.2), spin),
    );
    let mut group = c.benchmark_group("universal omega_body");
    group.bench_function("evaluate", |b| b.iter(|| joint.evaluate(black_box(&state))));
    group.bench_function("phi", |b| b.iter(|| joint.phi(black_box(&state))));
    group.bench_function("jacobian", |b| b.iter(|| joint.jacobian(black_box(&state))));
    group.bench_function("gamma", |b| b.iter(|| joint.gamma(black_box(&state))));
    group.finish();

    let joint = UniversalEuler { s, h, rho1, rho2 };
    let pdot = |q: &UnitQuaternion<f64>| {
        // ṗ = ½ p ⊗ (0, ω'), a consistent Euler-parameter rate.
        let w = q.quaternion() * joint_runtime::nalgebra::Quaternion::new(0.0, spin.x, spin.y, spin.z) * 0.5;
        Vector4::new(w.w, w.i, w.j, w.k)
    };
    let state = TwoBodies::new(
        EulerBody::from_rotation(Vector3::new(-0.5, 0.0, 0.0), &q1, Vector3::new(0.0, 0.1, 0.0), pdot(&q1)),
        EulerBody::from_rotation(Vector3::new(0.43, 0.25, 0.0), &q2, Vector3::new(0.0, -0.1, 0.2), pdot(&q2)),
    );
    let mut group = c.benchmark_group("universal euler");
    group.bench_function("evaluate", |b| b.iter(|| joint.evaluate(black_box(&state))));
    group.bench_function("phi", |b| b.iter(|| joint.phi(black_box(&state))));
    group.bench_function("jacobian", |b| b.iter(|| joint.jacobian(black_box(&state))));
    group.bench_function("gamma", |b| b.iter(|| joint.gamma(black_box(&state))));
    group.finish();
}

fn scenes(c: &mut Criterion) {
    let geometry = Geometry::new(30f64.to_radians(), Arrangement::Z, Phasing::InPhase).expect("a valid bend");
    let driven = DoubleCardan::new(geometry, 10.0);
    let start = driven.initial_state().expect("the reference configuration is consistent");
    c.bench_function("double cardan scene evaluate", |b| b.iter(|| driven.evaluate(black_box(&start))));

    let free = FreeDoubleCardan::new(&geometry);
    for (name, integrator) in
        [("double cardan step rk4", Integrator::Rk4), ("double cardan step midpoint", Integrator::ImplicitMidpoint)]
    {
        let options = SimulationOptions::default().with_integrator(integrator);
        let mut sim = Simulation::new(&free, NoLoads, &[], options).expect("valid options");
        // Every iteration steps from the same start, so the work does not drift.
        c.bench_function(name, |b| {
            b.iter(|| {
                let mut state = start;
                sim.step(&mut state, black_box(1e-3)).expect("a step from a consistent state");
                state
            })
        });
    }
}

criterion_group!(benches, joints, scenes);
criterion_main!(benches);
