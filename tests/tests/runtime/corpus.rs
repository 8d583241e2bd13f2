//! A corpus of public robot files read as they are shipped: eighteen of
//! MuJoCo Menagerie's MJCF files (fixed arms and a hand; floating
//! quadrupeds, humanoids and a mobile manipulator), byte copies under
//! `tests/data/robots/corpus/` (its `LICENSES.md` says where each came
//! from), against MuJoCo 4.0's own numbers
//! (`tests/data/robots/corpus/reference.py`): at random states inside the
//! joints' ranges, `M` (`mj_fullM`), the forward dynamics (`mj_forward`'s
//! `qacc` under `qfrc_applied`) and the inverse dynamics (`mj_inverse`'s
//! `qfrc_inverse`), each to 1e-12 of its largest entry.
//!
//! Nothing in the files is edited, so what they hold acts as shipped: their
//! classes, armature and damping (a `<freejoint/>` under a damped
//! `childclass` too); ranges and `frictionloss` are data, actuators are not
//! read, and the meshes are not here (drawn as stand-ins; the dynamics never
//! read geoms). The script switched off in MuJoCo what the scenes do not
//! model (contacts, constraints, actuation; its docstring says why), so what
//! is compared is the tree's dynamics as [`TreeSimulation::new`] builds it
//! from the file.

use std::sync::OnceLock;

use joint_runtime::Scene;
use joint_runtime::nalgebra::{SMatrix, SVector};
use joint_runtime::relative::{TreeScene, TreeSimulation, TreeState};
use joint_runtime::robot::{LibraryJointKind, StateLayout};
use serde_json::Value;

/// The reference values, read once for every test (the file is large).
fn reference() -> &'static Value {
    static DATA: OnceLock<Value> = OnceLock::new();
    DATA.get_or_init(|| {
        let path = format!("{}/data/robots/corpus/reference.json", env!("CARGO_MANIFEST_DIR"));
        serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
    })
}

/// A JSON array of numbers as `f64`s.
fn numbers(v: &Value) -> Vec<f64> {
    v.as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect()
}

/// The layout's joints are MuJoCo's, in MuJoCo's order: names, kinds and
/// the addresses in `qpos` and `qvel`; sizes too. A state copied through a
/// layout whose order differed would still convert, into the wrong joints.
fn same_joints<const NQ: usize, const NV: usize>(layout: &StateLayout<NQ, NV>, data: &Value, key: &str) {
    let theirs = data["joints"].as_array().unwrap();
    assert_eq!(layout.joints().len(), theirs.len(), "{key}: the number of joints");
    assert_eq!((layout.nq(), layout.nv()), (data["nq"].as_u64().unwrap() as usize, NV), "{key}: nq, nv");
    assert_eq!(data["nv"].as_u64().unwrap() as usize, NV, "{key}: nv");
    for (ours, theirs) in layout.joints().iter().zip(theirs) {
        let kind = match theirs["type"].as_str().unwrap() {
            "free" => LibraryJointKind::Free,
            "ball" => LibraryJointKind::Ball,
            "slide" => LibraryJointKind::Slide,
            _ => LibraryJointKind::Hinge,
        };
        // MuJoCo leaves an unnamed `<freejoint/>` without a name; the scene
        // calls it `free(BODY)`, as it does a floating body's joint anywhere.
        let name = match theirs["name"].as_str().unwrap() {
            "" => format!("free({})", theirs["body"].as_str().unwrap()),
            named => named.to_owned(),
        };
        assert_eq!(ours.name, name, "{key}: MuJoCo's order");
        let at = |k: &str| theirs[k].as_u64().unwrap() as usize;
        assert_eq!((ours.kind, ours.q_at, ours.v_at), (kind, at("q_at"), at("v_at")), "{key}: `{name}`");
    }
}

/// MuJoCo's `M` from the tree's: `Tᵀ M T`, `T` the velocity map (its
/// columns `state_from` of unit velocities, `Tᵀ` by `write_forces`).
fn mass_matrix_as_theirs<S, const NB: usize, const NQ: usize, const NV: usize>(
    sim: &TreeSimulation<'_, S, NB, NQ, NV>,
    layout: &StateLayout<NQ, NV>,
    q: &[f64],
    state: &TreeState<NQ, NV>,
) -> SMatrix<f64, NV, NV>
where
    S: TreeScene<NB, NQ, NV>,
{
    let mut m = SMatrix::<f64, NV, NV>::zeros();
    sim.mass_matrix_into(&state.q, &mut m);
    let mut theirs = SMatrix::<f64, NV, NV>::zeros();
    for i in 0..NV {
        let mut unit = [0.0; NV];
        unit[i] = 1.0;
        let mut column = [0.0; NV];
        layout.write_forces(state, &(m * layout.state_from(q, &unit).unwrap().v), &mut column).unwrap();
        theirs.set_column(i, &SVector::<f64, NV>::from(column));
    }
    theirs
}

/// MuJoCo's `M` from the stored lower triangle (row `i` its first `i + 1`
/// entries), mirrored.
fn stored_mass_matrix<const NV: usize>(rows: &Value) -> SMatrix<f64, NV, NV> {
    let rows: Vec<Vec<f64>> = rows.as_array().unwrap().iter().map(numbers).collect();
    SMatrix::<f64, NV, NV>::from_fn(|r, c| if c <= r { rows[r][c] } else { rows[c][r] })
}

/// Every sample of `key` through the scene's `MUJOCO` layout: `M` as
/// `Tᵀ M T`, the forward dynamics (MuJoCo's `tau` in, its `qacc` out) and
/// the inverse dynamics (its `a` in, its `qfrc_inverse` out). Returns the
/// worst relative differences `[M, forward, inverse]`, each the largest
/// difference over the reference's largest entry, after asserting them
/// under 1e-12.
fn against_mujoco<S, const NB: usize, const NQ: usize, const NV: usize>(
    scene: &S,
    layout: &StateLayout<NQ, NV>,
    key: &str,
) -> [f64; 3]
where
    S: TreeScene<NB, NQ, NV>,
{
    let data = &reference()[key];
    same_joints(layout, data, key);
    let mut sim = TreeSimulation::new(scene).unwrap();
    let mut worst = [0.0_f64; 3];
    for s in data["samples"].as_array().unwrap() {
        let (q, v) = (numbers(&s["q"]), numbers(&s["v"]));
        let state = layout.state_from(&q, &v).unwrap();
        let theirs = |k: &str| SVector::<f64, NV>::from_iterator(numbers(&s[k]));
        let relative = |ours: SVector<f64, NV>, theirs: SVector<f64, NV>| (ours - theirs).amax() / theirs.amax();
        let given = stored_mass_matrix::<NV>(&s["mass_matrix"]);
        let m = mass_matrix_as_theirs(&sim, layout, &q, &state);
        worst[0] = worst[0].max((m - given).amax() / given.amax());
        // And through the layout's matrix conversion.
        let mut tree_m = SMatrix::<f64, NV, NV>::zeros();
        sim.mass_matrix_into(&state.q, &mut tree_m);
        worst[0] = worst[0].max((layout.mass_matrix_to(&state, &tree_m) - given).amax() / given.amax());
        let tau = layout.forces_from(&state, theirs("tau").as_slice()).unwrap();
        let mut qacc = [0.0; NV];
        layout.write_accelerations(&state, &sim.forward_dynamics(&state, &tau).unwrap(), &mut qacc).unwrap();
        worst[1] = worst[1].max(relative(SVector::from(qacc), theirs("qacc")));
        let a = layout.accelerations_from(&state, theirs("a").as_slice()).unwrap();
        let mut inverse = [0.0; NV];
        layout.write_forces(&state, &sim.inverse_dynamics(&state, &a), &mut inverse).unwrap();
        worst[2] = worst[2].max(relative(SVector::from(inverse), theirs("inverse")));
    }
    eprintln!(
        "{key} ({}) against MuJoCo: M {:.1e}, forward {:.1e}, inverse {:.1e} of the largest entry",
        data["file"].as_str().unwrap(),
        worst[0],
        worst[1],
        worst[2]
    );
    for (what, w) in ["M", "forward dynamics", "inverse dynamics"].iter().zip(worst) {
        assert!(w < 1e-12, "{key}: {what} off by {w:e}");
    }
    worst
}

/// One scene per file and one test per scene, named by the reference's key.
macro_rules! corpus {
    ($($test:ident: $scene:ident = $path:literal, $key:literal;)*) => {$(
        #[derive(Scene)]
        #[scene(mjcf = $path)]
        struct $scene;

        #[test]
        fn $test() {
            against_mujoco(&$scene, &$scene::MUJOCO, $key);
        }
    )*};
}

corpus! {
    panda_against_mujoco: Panda = "data/robots/corpus/franka_emika_panda/panda_nohand.xml", "panda";
    ur5e_against_mujoco: Ur5e = "data/robots/corpus/universal_robots_ur5e/ur5e.xml", "ur5e";
    gen3_against_mujoco: Gen3 = "data/robots/corpus/kinova_gen3/gen3.xml", "gen3";
    iiwa14_against_mujoco: Iiwa14 = "data/robots/corpus/kuka_iiwa_14/iiwa14.xml", "iiwa14";
    sawyer_against_mujoco: Sawyer = "data/robots/corpus/rethink_robotics_sawyer/sawyer.xml", "sawyer";
    xarm7_against_mujoco: Xarm7 = "data/robots/corpus/ufactory_xarm7/xarm7_nohand.xml", "xarm7";
    z1_against_mujoco: Z1 = "data/robots/corpus/unitree_z1/z1.xml", "z1";
    shadow_hand_against_mujoco: ShadowHand = "data/robots/corpus/shadow_hand/right_hand.xml", "shadow_hand";
    go1_against_mujoco: Go1 = "data/robots/corpus/unitree_go1/go1.xml", "go1";
    go2_against_mujoco: Go2 = "data/robots/corpus/unitree_go2/go2.xml", "go2";
    a1_against_mujoco: A1 = "data/robots/corpus/unitree_a1/a1.xml", "a1";
    anymal_c_against_mujoco: AnymalC = "data/robots/corpus/anybotics_anymal_c/anymal_c.xml", "anymal_c";
    spot_against_mujoco: Spot = "data/robots/corpus/boston_dynamics_spot/spot.xml", "spot";
    barkour_v0_against_mujoco: BarkourV0 = "data/robots/corpus/google_barkour_v0/barkour_v0.xml", "barkour_v0";
    h1_against_mujoco: H1 = "data/robots/corpus/unitree_h1/h1.xml", "h1";
    g1_against_mujoco: G1 = "data/robots/corpus/unitree_g1/g1.xml", "g1";
    t1_against_mujoco: T1 = "data/robots/corpus/booster_t1/t1.xml", "t1";
    tiago_against_mujoco: Tiago = "data/robots/corpus/pal_tiago/tiago.xml", "tiago";
}
