//! States copied from MuJoCo and Pinocchio through the scenes' `MUJOCO` and
//! `PINOCCHIO` layouts: the libraries' own `q`, `v`, τ, `M` and forward
//! dynamics at random states (`tests/data/robots/library.py` wrote them),
//! on files whose frames differ from the tree's wherever they can (a turned
//! floating base with its centre off its origin, ball joints on turned
//! bodies, a continuous joint, siblings out of name order) and on the
//! floating Solo12's MJCF.

use joint_runtime::Scene;
use joint_runtime::nalgebra::{DMatrix, DVector, SMatrix};
use joint_runtime::relative::{TreeScene, TreeSimulation};
use joint_runtime::robot::{Library, StateError, StateLayout};
use serde_json::Value;

use crate::urdf::numbers;

/// MJCF's frames turned everywhere (`library.xml`).
#[derive(Scene)]
#[scene(mjcf = "data/robots/library.xml")]
pub(crate) struct Turned;

/// URDF's frames turned, a continuous joint, siblings out of name order.
#[derive(Scene)]
#[scene(urdf = "data/robots/library.urdf", floating_base)]
pub(crate) struct Branched;

/// The floating Solo12 as MuJoCo's compiler writes it.
#[derive(Scene)]
#[scene(mjcf = "data/robots/solo12_floating.xml")]
pub(crate) struct Solo;

pub(crate) fn reference(key: &str) -> Value {
    let path = format!("{}/data/robots/library.json", env!("CARGO_MANIFEST_DIR"));
    let all: Value = serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    all[key].clone()
}

/// The largest difference over the largest entry of the reference.
fn relative(ours: &DVector<f64>, theirs: &DVector<f64>) -> f64 {
    (ours - theirs).amax() / theirs.amax()
}

/// Every sample of `key`: the state converted in and back out (the same
/// numbers), the library's `M` as `Tᵀ M T` from ours (`T` the velocity map,
/// its columns `state_from` of unit velocities; `Tᵀ` by `write_forces`),
/// and its forward dynamics from ours (forces in, accelerations out).
/// Returns the worst relative differences `[round trip, M, a]`.
fn against_library<S, const NB: usize, const NQ: usize, const NV: usize>(
    scene: &S,
    layout: &StateLayout<NQ, NV>,
    key: &str,
) -> [f64; 3]
where
    S: TreeScene<NB, NQ, NV>,
{
    let data = reference(key);
    let mut sim = TreeSimulation::new(scene).unwrap();
    let (nq, nv) = (layout.nq(), layout.nv());
    for (ours, theirs) in layout.joints().iter().zip(data["joints"].as_array().unwrap()) {
        assert_eq!(ours.name, theirs["name"].as_str().unwrap(), "{key}: the library's order");
        assert_eq!(
            (ours.q_at, ours.v_at),
            (theirs["q_at"].as_u64().unwrap() as usize, theirs["v_at"].as_u64().unwrap() as usize)
        );
        // Every joint by the library's name, a floating base's too.
        let tree = sim.tree().joint_layout(ours.name).unwrap_or_else(|| panic!("{key}: no joint `{}`", ours.name));
        assert_eq!((tree.q_at, tree.v_at), (ours.tree_q_at, ours.tree_v_at), "{key}: `{}`", ours.name);
    }
    let mut worst = [0.0_f64; 3];
    for s in data["samples"].as_array().unwrap() {
        let (q, v, tau, a) = (numbers(&s["q"]), numbers(&s["v"]), numbers(&s["tau"]), numbers(&s["a"]));
        let state = layout.state_from(&q, &v).unwrap();
        // Back out: the library's own numbers.
        let (mut q_back, mut v_back) = (vec![0.0; nq], vec![0.0; nv]);
        layout.write_state(&state, &mut q_back, &mut v_back).unwrap();
        let back = DVector::from_iterator(nq + nv, q_back.into_iter().chain(v_back));
        let given = DVector::from_iterator(nq + nv, q.iter().chain(&v).copied());
        worst[0] = worst[0].max(relative(&back, &given));
        // M: column i is Tᵀ M T eᵢ.
        let mut m = SMatrix::<f64, NV, NV>::zeros();
        sim.mass_matrix_into(&state.q, &mut m);
        let mut theirs_m = DMatrix::zeros(nv, nv);
        for i in 0..nv {
            let mut unit = vec![0.0; nv];
            unit[i] = 1.0;
            let column = m * layout.state_from(&q, &unit).unwrap().v;
            let mut out = vec![0.0; nv];
            layout.write_forces(&state, &column, &mut out).unwrap();
            theirs_m.set_column(i, &DVector::from_vec(out));
        }
        let rows: Vec<Vec<f64>> = s["mass_matrix"].as_array().unwrap().iter().map(numbers).collect();
        let given_m = DMatrix::from_fn(nv, nv, |r, c| rows[r][c]);
        worst[1] = worst[1].max((theirs_m - &given_m).amax() / given_m.amax());
        // Forward dynamics: their forces in, their accelerations out.
        let accelerations = sim.forward_dynamics(&state, &layout.forces_from(&state, &tau).unwrap()).unwrap();
        let mut out = vec![0.0; nv];
        layout.write_accelerations(&state, &accelerations, &mut out).unwrap();
        worst[2] = worst[2].max(relative(&DVector::from_vec(out), &DVector::from_vec(a.clone())));
        // And their accelerations in: ours.
        let back = layout.accelerations_from(&state, &a).unwrap();
        worst[2] = worst[2].max((back - accelerations).amax() / accelerations.amax());
    }
    eprintln!(
        "{key}: round trip {:.1e}, M {:.1e}, forward dynamics {:.1e} of the largest entry",
        worst[0], worst[1], worst[2]
    );
    for (what, w) in ["round trip", "M", "forward dynamics"].iter().zip(worst) {
        assert!(w < 1e-12, "{key}: {what} off by {w:e}");
    }
    worst
}

#[test]
fn states_copied_from_mujoco() {
    assert_eq!(Turned::MUJOCO.library(), Library::MuJoCo);
    against_library(&Turned, &Turned::MUJOCO, "library_mujoco");
    against_library(&Solo, &Solo::MUJOCO, "solo12_mujoco");
}

#[test]
fn states_copied_from_pinocchio() {
    assert_eq!(Branched::PINOCCHIO.library(), Library::Pinocchio);
    against_library(&Branched, &Branched::PINOCCHIO, "library_pinocchio");
}

/// Forces pass through `forces_from` as the same power on every velocity:
/// `τ_oursᵀ v_ours = τ_theirsᵀ v_theirs`.
#[test]
fn forces_keep_their_power() {
    let data = reference("library_mujoco");
    let s = &data["samples"][3];
    let (q, v, tau) = (numbers(&s["q"]), numbers(&s["v"]), numbers(&s["tau"]));
    let layout = Turned::MUJOCO;
    let state = layout.state_from(&q, &v).unwrap();
    let ours = layout.forces_from(&state, &tau).unwrap();
    let theirs: f64 = tau.iter().zip(&v).map(|(a, b)| a * b).sum();
    assert!((ours.dot(&state.v) - theirs).abs() < 1e-13 * theirs.abs().max(1.0));
}

#[test]
fn wrong_vectors_are_refused_by_name() {
    let layout = Branched::PINOCCHIO;
    let q = vec![0.0; layout.nq()];
    let v = vec![0.0; layout.nv() + 1];
    assert_eq!(
        layout.state_from(&q, &v).unwrap_err(),
        StateError::Length { what: "v", expected: layout.nv(), found: layout.nv() + 1 }
    );
    // All zeros: the floating base's quaternion has no length.
    let err = layout.state_from(&q, &vec![0.0; layout.nv()]).unwrap_err();
    assert_eq!(err, StateError::NotUnit { joint: "root_joint" });
    assert_eq!(err.to_string(), "joint `root_joint`'s quaternion (or cos, sin) has zero or non-finite length");
}
