//! Matrices through the `MUJOCO` and `PINOCCHIO` layouts: the mass matrix
//! against MuJoCo's and Pinocchio's own (`library.json`), the dynamics'
//! derivatives and a step's Jacobian in the libraries' coordinates against
//! central differences of the libraries' own maps (their `q ⊕ δ` written
//! here from their documentation: MuJoCo's free position in the world's
//! axes and quaternions turned in their own frames, Pinocchio's free flyer
//! moved along its own axes, `x y z w`, and a continuous joint's `cos, sin`),
//! the floating Solo12's against Pinocchio's `computeABADerivatives` and
//! `computeRNEADerivatives`, and every conversion back to where it started.

use joint_runtime::nalgebra::{Quaternion, SMatrix, SVector, UnitQuaternion, Vector3};
use joint_runtime::relative::{
    ForwardDerivatives, InverseDerivatives, StepJacobian, StepWork, TreeScene, TreeSimulation,
};
use joint_runtime::robot::{Library, LibraryJointKind, StateLayout};

use crate::library::{Branched, Solo, Turned, reference};
use crate::urdf::numbers;

/// The library's `q` moved by the increment `d` on its own tangent.
fn displace<const NQ: usize, const NV: usize>(layout: &StateLayout<NQ, NV>, q: &[f64], d: &[f64]) -> Vec<f64> {
    let mut out = q.to_vec();
    let pinocchio = layout.library() == Library::Pinocchio;
    let read = |x: &[f64]| {
        let raw =
            if pinocchio { Quaternion::new(x[3], x[0], x[1], x[2]) } else { Quaternion::new(x[0], x[1], x[2], x[3]) };
        UnitQuaternion::from_quaternion(raw)
    };
    let write = |e: &UnitQuaternion<f64>, x: &mut [f64]| {
        let order = if pinocchio { [e.i, e.j, e.k, e.w] } else { [e.w, e.i, e.j, e.k] };
        x.copy_from_slice(&order);
    };
    for j in layout.joints() {
        let (q_at, d) = (j.q_at, &d[j.v_at..]);
        match j.kind {
            LibraryJointKind::Hinge | LibraryJointKind::Slide => out[q_at] += d[0],
            LibraryJointKind::Continuous => {
                let angle = q[q_at + 1].atan2(q[q_at]) + d[0];
                (out[q_at], out[q_at + 1]) = (angle.cos(), angle.sin());
            }
            LibraryJointKind::Ball => {
                let turned = read(&q[q_at..q_at + 4]) * UnitQuaternion::new(Vector3::new(d[0], d[1], d[2]));
                write(&turned, &mut out[q_at..q_at + 4]);
            }
            LibraryJointKind::Free => {
                let turn = read(&q[q_at + 3..q_at + 7]);
                let step = Vector3::new(d[0], d[1], d[2]);
                // MuJoCo: the world's axes; Pinocchio: the link's.
                let moved = if pinocchio { turn * step } else { step };
                for i in 0..3 {
                    out[q_at + i] += moved[i];
                }
                write(&(turn * UnitQuaternion::new(Vector3::new(d[3], d[4], d[5]))), &mut out[q_at + 3..q_at + 7]);
            }
        }
    }
    out
}

/// The increment `d` with `q0 ⊕ d = q1` (to the first order, which is what
/// central differences see).
fn difference<const NQ: usize, const NV: usize>(layout: &StateLayout<NQ, NV>, q1: &[f64], q0: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; layout.nv()];
    let pinocchio = layout.library() == Library::Pinocchio;
    let read = |x: &[f64]| {
        let raw =
            if pinocchio { Quaternion::new(x[3], x[0], x[1], x[2]) } else { Quaternion::new(x[0], x[1], x[2], x[3]) };
        UnitQuaternion::from_quaternion(raw)
    };
    for j in layout.joints() {
        let (qa, va) = (j.q_at, j.v_at);
        match j.kind {
            LibraryJointKind::Hinge | LibraryJointKind::Slide => out[va] = q1[qa] - q0[qa],
            LibraryJointKind::Continuous => out[va] = q1[qa + 1].atan2(q1[qa]) - q0[qa + 1].atan2(q0[qa]),
            LibraryJointKind::Ball => {
                let w = (read(&q0[qa..qa + 4]).inverse() * read(&q1[qa..qa + 4])).scaled_axis();
                out[va..va + 3].copy_from_slice(w.as_slice());
            }
            LibraryJointKind::Free => {
                let turn = read(&q0[qa + 3..qa + 7]);
                let moved = Vector3::new(q1[qa] - q0[qa], q1[qa + 1] - q0[qa + 1], q1[qa + 2] - q0[qa + 2]);
                let moved = if pinocchio { turn.inverse() * moved } else { moved };
                out[va..va + 3].copy_from_slice(moved.as_slice());
                let w = (turn.inverse() * read(&q1[qa + 3..qa + 7])).scaled_axis();
                out[va + 3..va + 6].copy_from_slice(w.as_slice());
            }
        }
    }
    out
}

/// The largest difference over the largest entry of `theirs`.
fn off<const R: usize, const C: usize>(ours: &SMatrix<f64, R, C>, theirs: &SMatrix<f64, R, C>) -> f64 {
    (ours - theirs).amax() / theirs.amax().max(1e-300)
}

/// The columns of `f`'s central differences along each of the `NV`
/// directions, `f` giving the library's `NV` numbers: the five-point rule
/// (error `O(h⁴)`, about 1e-12 of the entries at `h = 1e-3`, plus round-off
/// `1e-16 / h`).
fn differences<const NV: usize>(f: impl Fn(usize, f64) -> Vec<f64>) -> SMatrix<f64, NV, NV> {
    let h = 1e-3;
    let mut out = SMatrix::<f64, NV, NV>::zeros();
    for i in 0..NV {
        let [a, b, c, d] = [2.0 * h, h, -h, -2.0 * h].map(|e| f(i, e));
        for r in 0..NV {
            out[(r, i)] = (8.0 * (b[r] - c[r]) - (a[r] - d[r])) / (12.0 * h);
        }
    }
    out
}

/// A unit vector of `n`, scaled.
fn unit(n: usize, i: usize, s: f64) -> Vec<f64> {
    let mut e = vec![0.0; n];
    e[i] = s;
    e
}

/// At `key`'s first samples: the mass matrix against the library's, the
/// forward and inverse dynamics' derivatives against central differences
/// of the library-side maps, and every conversion back. Returns the worst
/// `[M, forward, inverse, round trips]`.
fn derivatives_in_library<S, const NB: usize, const NQ: usize, const NV: usize>(
    scene: &S,
    layout: &StateLayout<NQ, NV>,
    key: &str,
) -> [f64; 4]
where
    S: TreeScene<NB, NQ, NV>,
{
    let data = reference(key);
    // `forward_dynamics` takes `&mut self` (its workspace); the closures share it.
    let cell = std::cell::RefCell::new(TreeSimulation::new(scene).unwrap());
    let mut worst = [0.0_f64; 4];
    for s in data["samples"].as_array().unwrap().iter().take(4) {
        let (q, v, tau_l, a_l) = (numbers(&s["q"]), numbers(&s["v"]), numbers(&s["tau"]), numbers(&s["a"]));
        let state = layout.state_from(&q, &v).unwrap();
        let mut m = SMatrix::<f64, NV, NV>::zeros();
        cell.borrow().mass_matrix_into(&state.q, &mut m);
        let rows: Vec<Vec<f64>> = s["mass_matrix"].as_array().unwrap().iter().map(numbers).collect();
        let theirs = SMatrix::<f64, NV, NV>::from_fn(|r, c| rows[r][c]);
        worst[0] = worst[0].max(off(&layout.mass_matrix_to(&state, &m), &theirs));
        worst[3] = worst[3].max(off(&layout.mass_matrix_from(&state, &theirs), &m));
        // Forward dynamics on the library's side: its q, v, τ in, its q̈ out.
        let forward = |q: &[f64], v: &[f64], tau: &[f64]| {
            let state = layout.state_from(q, v).unwrap();
            let a = cell.borrow_mut().forward_dynamics(&state, &layout.forces_from(&state, tau).unwrap()).unwrap();
            let mut out = vec![0.0; NV];
            layout.write_accelerations(&state, &a, &mut out).unwrap();
            out
        };
        let tau = layout.forces_from(&state, &tau_l).unwrap();
        let (mut work, mut tree) = (InverseDerivatives::zeros(), ForwardDerivatives::zeros());
        cell.borrow().forward_dynamics_derivatives(&state, &tau, &mut work, &mut tree).unwrap();
        let ours = layout.forward_derivatives_to(&state, &tau, &tree);
        let d_q = differences::<NV>(|i, e| forward(&displace(layout, &q, &unit(NV, i, e)), &v, &tau_l));
        let d_v = differences::<NV>(|i, e| forward(&q, &add(&v, &unit(NV, i, e)), &tau_l));
        let d_tau = differences::<NV>(|i, e| forward(&q, &v, &add(&tau_l, &unit(NV, i, e))));
        let qdd = SVector::<f64, NV>::from_vec(forward(&q, &v, &tau_l));
        for (o, t) in [(ours.d_q, d_q), (ours.d_v, d_v), (ours.d_tau, d_tau)] {
            worst[1] = worst[1].max(off(&o, &t));
        }
        worst[1] = worst[1].max(off(&ours.qdd, &qdd));
        let back = layout.forward_derivatives_from(&state, &tau, &ours);
        for (o, t) in [(back.d_q, tree.d_q), (back.d_v, tree.d_v), (back.d_tau, tree.d_tau)] {
            worst[3] = worst[3].max(off(&o, &t));
        }
        worst[3] = worst[3].max(off(&back.qdd, &tree.qdd));
        // Inverse dynamics on the library's side: its q, v, q̈ in, its τ out.
        let inverse = |q: &[f64], v: &[f64], a: &[f64]| {
            let state = layout.state_from(q, v).unwrap();
            let tau = cell.borrow().inverse_dynamics(&state, &layout.accelerations_from(&state, a).unwrap());
            let mut out = vec![0.0; NV];
            layout.write_forces(&state, &tau, &mut out).unwrap();
            out
        };
        let a = layout.accelerations_from(&state, &a_l).unwrap();
        let mut tree = InverseDerivatives::zeros();
        cell.borrow().inverse_dynamics_derivatives(&state, &a, &mut tree).unwrap();
        let ours = layout.inverse_derivatives_to(&state, &a, &tree);
        let d_q = differences::<NV>(|i, e| inverse(&displace(layout, &q, &unit(NV, i, e)), &v, &a_l));
        let d_v = differences::<NV>(|i, e| inverse(&q, &add(&v, &unit(NV, i, e)), &a_l));
        for (o, t) in [(ours.d_q, d_q), (ours.d_v, d_v), (ours.d_a, theirs)] {
            worst[2] = worst[2].max(off(&o, &t));
        }
        let back = layout.inverse_derivatives_from(&state, &a, &ours);
        for (o, t) in [(back.d_q, tree.d_q), (back.d_v, tree.d_v), (back.d_a, tree.d_a)] {
            worst[3] = worst[3].max(off(&o, &t));
        }
    }
    eprintln!(
        "{key}: M {:.1e}, forward derivatives {:.1e}, inverse {:.1e} (differences), round trips {:.1e}",
        worst[0], worst[1], worst[2], worst[3]
    );
    // The five-point rule leaves about 1e-10 of the entries.
    let bounds = [1e-12, 2e-9, 2e-9, 1e-11];
    for (what, (w, b)) in
        ["M", "forward derivatives", "inverse derivatives", "round trips"].iter().zip(worst.iter().zip(bounds))
    {
        assert!(*w < b, "{key}: {what} off by {w:e}");
    }
    worst
}

fn add(x: &[f64], y: &[f64]) -> Vec<f64> {
    x.iter().zip(y).map(|(a, b)| a + b).collect()
}

#[test]
fn derivatives_in_mujocos_coordinates() {
    derivatives_in_library(&Turned, &Turned::MUJOCO, "library_mujoco");
    derivatives_in_library(&Solo, &Solo::MUJOCO, "solo12_mujoco");
}

#[test]
fn derivatives_in_pinocchios_coordinates() {
    derivatives_in_library(&Branched, &Branched::PINOCCHIO, "library_pinocchio");
}

/// One RK4 step's exact Jacobian in the library's coordinates, against
/// central differences of the library-side step (its state in, the
/// tree's step under the forces `T₀ᵀ τ_l`, its state out), and back.
fn step_in_library<S, const NB: usize, const NQ: usize, const NV: usize>(
    scene: &S,
    layout: &StateLayout<NQ, NV>,
    key: &str,
) -> f64
where
    S: TreeScene<NB, NQ, NV>,
{
    let data = reference(key);
    let sim = TreeSimulation::new(scene).unwrap();
    let (nq, h) = (layout.nq(), 1e-3);
    let s = &data["samples"][1];
    let (q, v, tau_l) = (numbers(&s["q"]), numbers(&s["v"]), numbers(&s["tau"]));
    // The step (`rk4_step_jacobian` takes `step_with`'s, on `&self`).
    let step = |q: &[f64], v: &[f64], tau: &[f64]| {
        let mut state = layout.state_from(q, v).unwrap();
        let forces = layout.forces_from(&state, tau).unwrap();
        let (mut work, mut unused) = (StepWork::new(), StepJacobian::zeros());
        sim.rk4_step_jacobian(&mut state, h, &forces, &mut work, &mut unused).unwrap();
        let (mut q1, mut v1) = (vec![0.0; nq], vec![0.0; NV]);
        layout.write_state(&state, &mut q1, &mut v1).unwrap();
        (q1, v1)
    };
    let start = layout.state_from(&q, &v).unwrap();
    let tau = layout.forces_from(&start, &tau_l).unwrap();
    let (mut work, mut tree) = (StepWork::new(), StepJacobian::zeros());
    let mut end = start;
    sim.rk4_step_jacobian(&mut end, h, &tau, &mut work, &mut tree).unwrap();
    let ours = layout.step_jacobian_to((&start, &tau), &end, &tree);
    let (q1, v1) = step(&q, &v, &tau_l);
    let around = |(qe, ve): (Vec<f64>, Vec<f64>)| -> [Vec<f64>; 2] {
        [difference(layout, &qe, &q1), add(&ve, &v1.iter().map(|x| -x).collect::<Vec<_>>())]
    };
    let columns = |f: &dyn Fn(usize, f64) -> (Vec<f64>, Vec<f64>)| {
        let q_part = differences::<NV>(|i, e| around(f(i, e))[0].clone());
        let v_part = differences::<NV>(|i, e| around(f(i, e))[1].clone());
        (q_part, v_part)
    };
    let (q_q, v_q) = columns(&|i, e| step(&displace(layout, &q, &unit(NV, i, e)), &v, &tau_l));
    let (q_v, v_v) = columns(&|i, e| step(&q, &add(&v, &unit(NV, i, e)), &tau_l));
    let (q_tau, v_tau) = columns(&|i, e| step(&q, &v, &add(&tau_l, &unit(NV, i, e))));
    let theirs = [q_q, q_v, q_tau, v_q, v_v, v_tau];
    let mine = [ours.q_q, ours.q_v, ours.q_tau, ours.v_q, ours.v_v, ours.v_tau];
    let worst = mine.iter().zip(&theirs).map(|(o, t)| (o - t).amax() / t.amax().max(1.0)).fold(0.0, f64::max);
    let back = layout.step_jacobian_from((&start, &tau), &end, &ours);
    let again = [back.q_q, back.q_v, back.q_tau, back.v_q, back.v_v, back.v_tau];
    let before = [tree.q_q, tree.q_v, tree.q_tau, tree.v_q, tree.v_v, tree.v_tau];
    let round = again.iter().zip(&before).map(|(o, t)| (o - t).amax()).fold(0.0, f64::max);
    eprintln!("{key}: RK4 step Jacobian {worst:.1e} off differences, round trip {round:.1e}");
    assert!(worst < 1e-9 && round < 1e-11, "{key}: step Jacobian {worst:e}, round trip {round:e}");
    worst
}

#[test]
fn step_jacobians_in_the_libraries_coordinates() {
    step_in_library(&Turned, &Turned::MUJOCO, "library_mujoco");
    step_in_library(&Solo, &Solo::MUJOCO, "solo12_mujoco");
    step_in_library(&Branched, &Branched::PINOCCHIO, "library_pinocchio");
}

/// A Jacobian keeps its products, `J_l v_l = J v`, and comes back.
fn products_kept<const NQ: usize, const NV: usize>(layout: &StateLayout<NQ, NV>, key: &str) {
    let data = reference(key);
    let s = &data["samples"][2];
    let (q, v) = (numbers(&s["q"]), numbers(&s["v"]));
    let state = layout.state_from(&q, &v).unwrap();
    let j = SMatrix::<f64, 3, NV>::from_fn(|r, c| ((r * 7 + c * 3) % 5) as f64 - 2.0);
    let on_library = layout.jacobian_to(&state, &j);
    let (ours, theirs) = (j * state.v, on_library * SVector::<f64, NV>::from_vec(v));
    assert!((ours - theirs).amax() < 1e-13 * ours.amax().max(1.0), "{key}");
    assert!((layout.jacobian_from(&state, &on_library) - j).amax() < 1e-13, "{key}");
    // The velocity map is the same as the state's conversion.
    let t = layout.tangent_map(&state);
    let mut written = (vec![0.0; layout.nq()], vec![0.0; NV]);
    layout.write_state(&state, &mut written.0, &mut written.1).unwrap();
    assert!((t * state.v - SVector::<f64, NV>::from_vec(written.1)).amax() < 1e-13, "{key}");
}

#[test]
fn jacobians_keep_their_products() {
    products_kept(&Turned::MUJOCO, "library_mujoco");
    products_kept(&Branched::PINOCCHIO, "library_pinocchio");
}

/// The floating Solo12 from its URDF, as Pinocchio's reader builds it.
#[derive(joint_runtime::Scene)]
#[scene(gravity = [0, 0, -9.81], urdf = "data/robots/solo12.urdf", floating_base)]
struct Solo12Floating;

/// Pinocchio's own derivatives (`computeABADerivatives`,
/// `computeRNEADerivatives`, `solo12_floating_derivatives.json`), read in
/// Pinocchio's order and tangent as they are, against ours converted by
/// `PINOCCHIO`: no index map, no sign or frame written by hand.
#[test]
fn derivatives_equal_pinocchios_through_the_layout() {
    const NV: usize = 18;
    let data = crate::urdf::reference("solo12_floating_derivatives");
    let (layout, sim) = (Solo12Floating::PINOCCHIO, TreeSimulation::new(&Solo12Floating).unwrap());
    let matrix = |value: &serde_json::Value| {
        let rows: Vec<Vec<f64>> = value.as_array().unwrap().iter().map(numbers).collect();
        SMatrix::<f64, NV, NV>::from_fn(|r, c| rows[r][c])
    };
    let vector = |value: &serde_json::Value| SVector::<f64, NV>::from_vec(numbers(value));
    let mut worst = 0.0_f64;
    for s in data["samples"].as_array().unwrap() {
        let state = layout.state_from(&numbers(&s["q"]), &numbers(&s["v"])).unwrap();
        let tau = layout.forces_from(&state, &numbers(&s["tau"])).unwrap();
        let (mut work, mut tree) = (InverseDerivatives::zeros(), ForwardDerivatives::zeros());
        sim.forward_dynamics_derivatives(&state, &tau, &mut work, &mut tree).unwrap();
        let ours = layout.forward_derivatives_to(&state, &tau, &tree);
        worst = worst.max(off(&ours.qdd, &vector(&s["aba"])));
        for (o, key) in [(ours.d_q, "daba_dq"), (ours.d_v, "daba_dv"), (ours.d_tau, "minv")] {
            worst = worst.max(off(&o, &matrix(&s[key])));
        }
        let a = layout.accelerations_from(&state, &numbers(&s["a"])).unwrap();
        let mut tree = InverseDerivatives::zeros();
        sim.inverse_dynamics_derivatives(&state, &a, &mut tree).unwrap();
        let ours = layout.inverse_derivatives_to(&state, &a, &tree);
        worst = worst.max(off(&ours.tau, &vector(&s["rnea"])));
        for (o, key) in [(ours.d_q, "drnea_dq"), (ours.d_v, "drnea_dv")] {
            worst = worst.max(off(&o, &matrix(&s[key])));
        }
    }
    eprintln!("solo12 floating through PINOCCHIO: {worst:.1e} of the largest entry off Pinocchio's");
    // As `tree_derivatives.rs` bounds M⁻¹'s products on this robot.
    assert!(worst < 2e-12, "{worst:e}");
}
