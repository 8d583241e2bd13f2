//! Robots read from their URDF files (`#[scene(urdf = "..")]`) against
//! Pinocchio: the mass matrix, inverse and forward dynamics at 100 random
//! states per robot (`tests/data/robots/reference.py` wrote the values, with
//! Pinocchio's fixed-base model of each file), equal to 1e-12 of each
//! quantity's largest entry; and 1 s of motion under gravity against
//! Pinocchio's RK4.

use joint_runtime::Scene;
use joint_runtime::nalgebra::{SMatrix, SVector, Vector3};
use joint_runtime::relative::{TreeJointKind, TreeScene, TreeSimulation, TreeState};
use joint_runtime::robot::{JointLimits, LinkFrame};
use serde_json::Value;

/// The five robots of `tests/data/robots`, read from files of one format
/// (`$key = PATH` for each; the floating Solo12's whole `#[scene]` list), and
/// each checked against Pinocchio's values: both formats' modules use it.
macro_rules! robots_against_pinocchio {
    ($key:ident: $pendulum:literal, $ur5:literal, $panda:literal, $solo:literal, floating: [$($floating:tt)*]) => {
        #[derive(Scene)]
        #[scene(gravity = [0, 0, -9.81], $key = $pendulum)]
        struct DoublePendulum;

        #[derive(Scene)]
        #[scene(gravity = [0, 0, -9.81], $key = $ur5)]
        struct Ur5;

        /// The fingers' coupling read as an independent joint, as
        /// Pinocchio's reader does by default (its values are for that model).
        #[derive(Scene)]
        #[scene(gravity = [0, 0, -9.81], $key = $panda, mimic = independent)]
        struct Panda;

        #[derive(Scene)]
        #[scene(gravity = [0, 0, -9.81], $key = $solo)]
        struct Solo12;

        #[derive(Scene)]
        #[scene(gravity = [0, 0, -9.81], $($floating)*)]
        struct Solo12Floating;

        #[test]
        fn double_pendulum_against_pinocchio() {
            $crate::urdf::against_pinocchio(&DoublePendulum, &DoublePendulum::LINKS, "double_pendulum");
        }

        #[test]
        fn ur5_against_pinocchio() {
            $crate::urdf::against_pinocchio(&Ur5, &Ur5::LINKS, "ur5");
        }

        #[test]
        fn panda_against_pinocchio() {
            $crate::urdf::against_pinocchio(&Panda, &Panda::LINKS, "panda");
        }

        #[test]
        fn solo12_fixed_base_against_pinocchio() {
            $crate::urdf::against_pinocchio(&Solo12, &Solo12::LINKS, "solo12");
        }

        #[test]
        fn solo12_floating_base_against_pinocchio() {
            $crate::urdf::against_pinocchio(&Solo12Floating, &Solo12Floating::LINKS, "solo12_floating");
        }

        #[test]
        fn motion_against_pinocchio_rk4() {
            use $crate::urdf::motion_against_pinocchio;
            motion_against_pinocchio(&DoublePendulum, "double_pendulum", 1e-11);
            motion_against_pinocchio(&Ur5, "ur5", 1e-11);
            motion_against_pinocchio(&Panda, "panda", 1e-11);
            motion_against_pinocchio(&Solo12Floating, "solo12_floating", 1e-11);
        }
    };
}
pub(crate) use robots_against_pinocchio;

robots_against_pinocchio!(
    urdf: "data/robots/double_pendulum.urdf", "data/robots/ur5.urdf", "data/robots/panda.urdf", "data/robots/solo12.urdf",
    floating: [urdf = "data/robots/solo12.urdf", floating_base]
);

/// The Panda's file as it says: the second finger follows the first (one row).
#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], urdf = "data/robots/panda.urdf")]
struct PandaCoupled;

/// The UR5 with no `gravity` in its scene: a URDF states none, and the
/// reader takes 9.81 down `z`, as Pinocchio and MuJoCo do.
#[derive(Scene)]
#[scene(urdf = "data/robots/ur5.urdf")]
struct Ur5DefaultGravity;

#[test]
fn a_urdf_scene_falls_down_z_unless_it_says_otherwise() {
    let said = TreeSimulation::new(&Ur5).unwrap();
    let default = TreeSimulation::new(&Ur5DefaultGravity).unwrap();
    assert_eq!(default.tree().gravity(), joint_runtime::nalgebra::Vector3::new(0.0, 0.0, -9.81));
    let mut state = said.tree().zero_state();
    state.q[1] = -1.2;
    let zero = joint_runtime::nalgebra::SVector::zeros();
    assert_eq!(default.inverse_dynamics(&state, &zero), said.inverse_dynamics(&state, &zero));
    assert!(said.inverse_dynamics(&state, &zero).amax() > 1.0, "gravity holds the arm");
}

/// Pinocchio's `q` copied into ours joint by joint through
/// `Tree::layout` (names and offsets) is what the hand-written map gives.
fn copied_by_layout<S: TreeScene<NB, NQ, NV>, const NB: usize, const NQ: usize, const NV: usize>(
    scene: &S,
    robot: &str,
) {
    let data = reference(robot);
    let sim = TreeSimulation::new(scene).unwrap();
    let (mut theirs, mut at) = (std::collections::HashMap::new(), 0);
    for j in data["joints"].as_array().unwrap() {
        let n = j["nq"].as_u64().unwrap() as usize;
        theirs.insert(j["name"].as_str().unwrap().to_string(), (at, n));
        at += n;
    }
    let q = numbers(&data["samples"][0]["q"]);
    let mut ours = SVector::<f64, NQ>::zeros();
    for l in sim.tree().layout().iter().filter(|l| l.nq > 0) {
        let (at, n) = theirs[l.name];
        assert_eq!(n, l.nq, "{robot}: joint `{}`", l.name);
        ours.rows_mut(l.q_at, n).copy_from_slice(&q[at..at + n]);
    }
    assert_eq!(ours, our_q::<NQ>(&joint_map(&sim, &data), &q), "{robot}");
}

#[test]
fn layouts_copy_pinocchio_states_by_name() {
    copied_by_layout(&Ur5, "ur5");
    copied_by_layout(&Panda, "panda");
    copied_by_layout(&Solo12, "solo12");
}

/// The double pendulum with its file's `<dynamics damping="0.05">` in the
/// dynamics (`file_damping`): the joint forces gain `0.05 q̇` each.
#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], urdf = "data/robots/double_pendulum.urdf", file_damping)]
struct DampedPendulum;

#[test]
fn file_damping_puts_the_urdf_damping_in_the_dynamics() {
    let (plain, damped) =
        (TreeSimulation::new(&DoublePendulum).unwrap(), TreeSimulation::new(&DampedPendulum).unwrap());
    let mut state = plain.tree().zero_state();
    state.q[0] = 0.4;
    state.v = SVector::from([1.0, -2.0]);
    let zero = SVector::zeros();
    let gained = damped.inverse_dynamics(&state, &zero) - plain.inverse_dynamics(&state, &zero);
    assert!((gained - state.v * 0.05).amax() < 1e-15, "{gained}");
}

/// Pinocchio's values for `robot`.
pub(crate) fn reference(robot: &str) -> Value {
    let path = format!("{}/data/robots/{robot}.json", env!("CARGO_MANIFEST_DIR"));
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

pub(crate) fn numbers(v: &Value) -> Vec<f64> {
    v.as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect()
}

/// The largest difference over the largest entry of the reference.
fn relative(ours: impl Iterator<Item = f64>, theirs: impl Iterator<Item = f64>) -> f64 {
    let (mut diff, mut scale) = (0.0_f64, 0.0_f64);
    for (a, b) in ours.zip(theirs) {
        diff = diff.max((a - b).abs());
        scale = scale.max(b.abs());
    }
    diff / scale.max(f64::MIN_POSITIVE)
}

/// Where each of our joints' coordinates and velocities are in Pinocchio's
/// vectors (the file's joints found by name; a floating root is Pinocchio's
/// `root_joint`), and how many.
pub(crate) fn joint_map<S, const NB: usize, const NQ: usize, const NV: usize>(
    sim: &TreeSimulation<'_, S, NB, NQ, NV>,
    data: &Value,
) -> Vec<(TreeJointKind, usize, usize)>
where
    S: TreeScene<NB, NQ, NV>,
{
    let (mut q_at, mut v_at) = (0, 0);
    let mut theirs = std::collections::HashMap::new();
    for j in data["joints"].as_array().unwrap() {
        let name = if j["type"] == "floating" { "free" } else { j["name"].as_str().unwrap() };
        theirs.insert(name.to_string(), (q_at, v_at));
        q_at += j["nq"].as_u64().unwrap() as usize;
        v_at += j["nv"].as_u64().unwrap() as usize;
    }
    assert_eq!((q_at, v_at), (NQ, NV), "the same coordinates and freedoms");
    // The floating base by its kind: Pinocchio's `root_joint`, an MJCF file's own name.
    let key = |j: &joint_runtime::relative::TreeJoint| match j.kind {
        TreeJointKind::Free => "free".to_string(),
        _ => j.name.to_string(),
    };
    sim.tree().joints().iter().map(|j| (j.kind, theirs[&key(j)].0, theirs[&key(j)].1)).collect()
}

/// Pinocchio's `q` in ours: a free joint's quaternion `[x, y, z, w]` first
/// `w`; its position is the base's origin, here its centre of mass (the
/// robots' bases have theirs at the origin of their frames).
pub(crate) fn our_q<const NQ: usize>(map: &[(TreeJointKind, usize, usize)], q: &[f64]) -> SVector<f64, NQ> {
    let mut out = SVector::<f64, NQ>::zeros();
    let mut at = 0;
    for &(kind, theirs, _) in map {
        let n = kind.coordinates();
        for i in 0..n {
            out[at + i] = q[theirs + i];
        }
        if kind == TreeJointKind::Free {
            let (x, y, z, w) = (q[theirs + 3], q[theirs + 4], q[theirs + 5], q[theirs + 6]);
            out.fixed_rows_mut::<4>(at + 3).copy_from(&joint_runtime::nalgebra::Vector4::new(w, x, y, z));
        }
        at += n;
    }
    out
}

/// Pinocchio's velocity-like vector in ours (a free joint's velocities are
/// the same: its base frame's, local components).
pub(crate) fn our_v<const NV: usize>(map: &[(TreeJointKind, usize, usize)], v: &[f64]) -> SVector<f64, NV> {
    let mut out = SVector::<f64, NV>::zeros();
    let mut at = 0;
    for &(kind, _, theirs) in map {
        for i in 0..kind.freedoms() {
            out[at + i] = v[theirs + i];
        }
        at += kind.freedoms();
    }
    out
}

/// Every sample of `robot`: `M`, `τ = RNEA(q, v, a)`, `q̈ = ABA(q, v,
/// τ)`, and the position and Jacobian of a point on one of its links
/// (`links`: the scene's `LINKS`); returns the largest relative differences.
pub(crate) fn against_pinocchio<S, const NB: usize, const NQ: usize, const NV: usize>(
    scene: &S,
    links: &[LinkFrame],
    robot: &str,
) -> [f64; 6]
where
    S: TreeScene<NB, NQ, NV>,
{
    let data = reference(robot);
    let mut sim = TreeSimulation::new(scene).unwrap();
    let map = joint_map(&sim, &data);
    let mut index = vec![0; NV];
    let mut at = 0;
    for &(kind, _, theirs) in &map {
        for i in 0..kind.freedoms() {
            index[at + i] = theirs + i;
        }
        at += kind.freedoms();
    }
    let link = LinkFrame::find(links, data["frame"]["link"].as_str().unwrap()).unwrap();
    let point = Vector3::from_iterator(numbers(&data["frame"]["point"]));
    let body = link.body.unwrap();
    let mut worst = [0.0_f64; 6];
    for s in data["samples"].as_array().unwrap() {
        let v = |key: &str| our_v::<NV>(&map, &numbers(&s[key]));
        let state = TreeState::<NQ, NV> { q: our_q(&map, &numbers(&s["q"])), v: v("v"), t: 0.0 };
        let mut m = SMatrix::<f64, NV, NV>::zeros();
        sim.mass_matrix_into(&state.q, &mut m);
        let rows: Vec<Vec<f64>> = s["mass_matrix"].as_array().unwrap().iter().map(numbers).collect();
        let theirs = (0..NV * NV).map(|i| rows[index[i % NV]][index[i / NV]]);
        worst[0] = worst[0].max(relative(m.iter().copied(), theirs));
        let tau = sim.inverse_dynamics(&state, &v("a"));
        worst[1] = worst[1].max(relative(tau.iter().copied(), v("rnea").iter().copied()));
        let qdd = sim.forward_dynamics(&state, &v("tau")).unwrap();
        worst[2] = worst[2].max(relative(qdd.iter().copied(), v("aba").iter().copied()));
        let (turn, origin) = link.pose(&sim.system_state(&state));
        let at = origin + turn * point;
        worst[3] = worst[3].max(relative(at.iter().copied(), numbers(&s["point_position"]).into_iter()));
        let jacobian = sim.tree().point_jacobian(&state.q, body, &link.point(&point)).unwrap();
        let rows: Vec<Vec<f64>> = s["point_jacobian"].as_array().unwrap().iter().map(numbers).collect();
        let theirs = (0..3 * NV).map(|i| rows[i % 3][index[i / 3]]);
        worst[4] = worst[4].max(relative(jacobian.fixed_rows::<3>(3).iter().copied(), theirs));
        // The link frame's velocity: its origin's Jacobian times v.
        let (omega, velocity) = link.velocity(&sim.system_state(&state));
        let origin = sim.tree().point_jacobian(&state.q, body, &link.point(&Vector3::zeros())).unwrap() * state.v;
        let ours = omega.iter().chain(velocity.iter()).copied();
        worst[5] = worst[5].max(relative(ours, origin.iter().copied()));
    }
    eprintln!(
        "{robot}: M {:.1e}, RNEA {:.1e}, ABA {:.1e}, point {:.1e}, its Jacobian {:.1e} of the largest entry; the \
         link's velocity against its Jacobian {:.1e}",
        worst[0], worst[1], worst[2], worst[3], worst[4], worst[5]
    );
    for (what, w) in ["M", "RNEA", "ABA", "point", "point Jacobian", "frame velocity"].iter().zip(worst) {
        assert!(w < 1e-12, "{robot}: {what} off by {w:e} of its largest entry");
    }
    worst
}

/// 1 s under gravity from the first sample at rest, RK4 at h = 1e-4 on both
/// sides: the same coordinates and rates to `bound`.
pub(crate) fn motion_against_pinocchio<S, const NB: usize, const NQ: usize, const NV: usize>(
    scene: &S,
    robot: &str,
    bound: f64,
) where
    S: TreeScene<NB, NQ, NV>,
{
    let data = reference(robot);
    let mut sim = TreeSimulation::new(scene).unwrap();
    let map = joint_map(&sim, &data);
    let motion = &data["motion"];
    let h = motion["h"].as_f64().unwrap();
    let steps = (motion["t"].as_f64().unwrap() / h).round() as usize;
    let mut state = TreeState::<NQ, NV> { q: our_q(&map, &numbers(&motion["q0"])), v: SVector::zeros(), t: 0.0 };
    for _ in 0..steps {
        sim.step(&mut state, h).unwrap();
    }
    let (q1, v1) = (our_q::<NQ>(&map, &numbers(&motion["q1"])), our_v::<NV>(&map, &numbers(&motion["v1"])));
    let (dq, dv) = ((state.q - q1).amax(), (state.v - v1).amax());
    eprintln!("{robot}: after 1 s, q to {dq:.1e}, v to {dv:.1e} (|v| up to {:.2})", v1.amax());
    assert!(dq < bound && dv < bound, "{robot}: q off by {dq:e}, v by {dv:e}");
}

/// The file's limits and friction, as data by the joints' names.
#[test]
#[allow(clippy::approx_constant)] // the file's digits, not 2π
fn limits_as_the_files_give_them() {
    let pan = Ur5::LIMITS[0];
    assert_eq!(
        pan,
        JointLimits {
            name: "shoulder_pan_joint",
            range: Some((-6.28318530718, 6.28318530718)),
            effort: Some(150.0),
            velocity: Some(3.15),
            damping: Some(0.0),
            friction: Some(0.0),
            armature: None,
        }
    );
    assert_eq!(Ur5::LIMITS.len(), 6);
    let first = Panda::LIMITS[0];
    assert_eq!((first.name, first.range, first.damping), ("panda_joint1", Some((-2.8973, 2.8973)), Some(0.003)));
    // Every link is a frame: the ground's `world`, massless `tool0` on the last body.
    let world = LinkFrame::find(&Ur5::LINKS, "world").unwrap();
    assert_eq!((world.body, world.origin), (None, [0.0; 3]));
    assert_eq!(LinkFrame::find(&Ur5::LINKS, "tool0").unwrap().body, Some(5));
    assert_eq!(Ur5::LINKS.len(), 11);
}

/// The UR5 with a payload declared beside its file: a body of the
/// attributes welded to the file's `wrist_3_link` by name, 0.1 m along y
/// from that link's centre.
#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], urdf = "data/robots/ur5.urdf")]
#[body(payload, mass = 2.0, inertia = [0.01, 0.02, 0.03])]
#[joint(grip = fixed(wrist_3_link, payload), axis1 = [0, 0, 1], axis2 = [0, 0, 1], rho1 = [0, 0.1, 0], rho2 = [0, 0, 0])]
struct Ur5Payload;

/// The payload adds `m Jpᵀ Jp + Jωᵀ (R I Rᵀ) Jω` to the arm's mass matrix
/// and `m Jpᵀ (−g)` to the torques that hold it (Jp, Jω: the payload
/// centre's Jacobian on the arm alone, itself checked against Pinocchio).
#[test]
fn a_payload_beside_the_file() {
    let (arm, held) = (TreeSimulation::new(&Ur5).unwrap(), TreeSimulation::new(&Ur5Payload).unwrap());
    assert_eq!(held.tree().joints().len(), 7, "the arm's six and the weld");
    let inertia = SMatrix::<f64, 3, 3>::from_diagonal(&Vector3::new(0.01, 0.02, 0.03));
    let (mut worst_m, mut worst_g) = (0.0_f64, 0.0_f64);
    for k in 0..20 {
        let q = SVector::<f64, 6>::from_fn(|i, _| ((k * 6 + i) as f64 * 0.7137).sin() * 2.5);
        let state = TreeState::<6, 6> { q, v: SVector::zeros(), t: 0.0 };
        let j = arm.tree().point_jacobian(&q, 5, &Vector3::new(0.0, 0.1, 0.0)).unwrap();
        let (jw, jp) = (j.fixed_rows::<3>(0), j.fixed_rows::<3>(3));
        let turn = held.system_state(&state).bodies[6].rotation();
        let world = turn.to_rotation_matrix().matrix() * inertia * turn.to_rotation_matrix().matrix().transpose();
        let (mut m, mut mp) = (SMatrix::<f64, 6, 6>::zeros(), SMatrix::<f64, 6, 6>::zeros());
        arm.mass_matrix_into(&q, &mut m);
        held.mass_matrix_into(&q, &mut mp);
        let expected = m + 2.0 * jp.transpose() * jp + jw.transpose() * world * jw;
        worst_m = worst_m.max((mp - expected).amax() / expected.amax());
        let hold = arm.inverse_dynamics(&state, &SVector::zeros());
        let hold_payload = held.inverse_dynamics(&state, &SVector::zeros());
        let expected = hold + 2.0 * jp.transpose() * Vector3::new(0.0, 0.0, 9.81);
        worst_g = worst_g.max((hold_payload - expected).amax() / expected.amax());
    }
    eprintln!("UR5 with a payload: M to {worst_m:.1e}, holding torques to {worst_g:.1e} of the largest entry");
    assert!(worst_m < 1e-13 && worst_g < 1e-13, "{worst_m:e} {worst_g:e}");
}

/// A `<mimic>` follower is a row `q₈ − q₇ = 0`: the coupled Panda's
/// accelerations are Gauss's, `T (Tᵀ M T)⁻¹ Tᵀ (τ − C)` with `T` the map
/// from the eight free coordinates to the nine, from the independent arm's
/// `M` and `C` (checked against Pinocchio); and the fingers stay together.
#[test]
fn mimic_is_a_row_of_the_tree() {
    let (free, mut coupled) = (TreeSimulation::new(&Panda).unwrap(), TreeSimulation::new(&PandaCoupled).unwrap());
    let mut t = SMatrix::<f64, 9, 8>::zeros();
    for i in 0..8 {
        t[(i, i)] = 1.0;
    }
    t[(8, 7)] = 1.0;
    let mut worst = 0.0_f64;
    for k in 0..20 {
        let wave = |i: usize, scale: f64| ((k * 9 + i) as f64 * 0.6173).sin() * scale;
        let mut state = TreeState::<9, 9> {
            q: SVector::from_fn(|i, _| wave(i, 1.5)),
            v: SVector::from_fn(|i, _| wave(i + 40, 2.0)),
            t: 0.0,
        };
        state.q[7] = 0.02 + wave(3, 0.01);
        (state.q[8], state.v[8]) = (state.q[7], state.v[7]);
        let tau = SVector::<f64, 9>::from_fn(|i, _| wave(i + 90, 5.0));
        let mut m = SMatrix::<f64, 9, 9>::zeros();
        free.mass_matrix_into(&state.q, &mut m);
        let bias = free.inverse_dynamics(&state, &SVector::zeros());
        let reduced = (t.transpose() * m * t).cholesky().unwrap();
        let expected = t * reduced.solve(&(t.transpose() * (tau - bias)));
        let ours = coupled.forward_dynamics(&state, &tau).unwrap();
        worst = worst.max((ours - expected).amax() / expected.amax());
    }
    let mut state = coupled.tree().zero_state();
    (state.q[1], state.q[7], state.q[8]) = (0.4, 0.03, 0.03);
    for _ in 0..500 {
        coupled.step(&mut state, 1e-3).unwrap();
    }
    let apart = (state.q[8] - state.q[7]).abs();
    eprintln!(
        "Panda with its mimic row: accelerations to {worst:.1e} of Gauss's; fingers apart by {apart:.1e} after 0.5 s"
    );
    assert!(worst < 1e-12 && apart < 1e-12, "{worst:e} {apart:e}");
    assert_eq!(<PandaCoupled as TreeScene<9, 9, 9, 1>>::CLOSURES[0].name, "panda_finger_joint2");
}

/// The UR5 in both coordinate choices from one file: the absolute engine
/// (six coordinates per body, each joint's rows as constraints) and the
/// tree.
#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], urdf = "data/robots/ur5.urdf", coordinates = both)]
struct Ur5Both;

/// From the same start, 0.5 s of free swing under gravity (RK4, h = 0.25
/// ms on both sides): the same bodies' positions and velocities to 1e-10.
#[test]
fn a_file_in_both_coordinates_agrees() {
    use joint_runtime::dynamics::{NoLoads, Simulation, SimulationOptions};
    let mut absolute = Simulation::new(&Ur5Both, NoLoads, &[], SimulationOptions::default()).unwrap();
    let mut tree = TreeSimulation::new(&Ur5Both).unwrap();
    let mut r = TreeState::<6, 6> { q: SVector::from([0.3, -1.2, 0.8, -0.5, 1.1, 0.2]), v: SVector::zeros(), t: 0.0 };
    let mut a = absolute.state_of(&tree.system_state(&r)).unwrap();
    for _ in 0..2000 {
        absolute.step(&mut a, 2.5e-4).unwrap();
        tree.step(&mut r, 2.5e-4).unwrap();
    }
    let bodies = tree.system_state(&r);
    let mut worst = 0.0_f64;
    for (x, y) in a.bodies.iter().zip(&bodies.bodies) {
        worst = worst.max((x.r - y.r).amax()).max((x.rdot - y.rdot).amax());
        worst =
            worst.max((x.rotation().to_rotation_matrix().matrix() - y.rotation().to_rotation_matrix().matrix()).amax());
    }
    let moved = (r.q - SVector::from([0.3, -1.2, 0.8, -0.5, 1.1, 0.2])).amax();
    eprintln!(
        "UR5 from its file, absolute against relative after 0.5 s: {worst:.1e} (joints moved up to {moved:.2} rad)"
    );
    assert!(worst < 1e-10 && moved > 0.1, "{worst:e}");
}
