//! Robots read from MJCF files (`#[scene(mjcf = "..")]`): the same robots
//! as `urdf.rs`, written as MJCF by MuJoCo's own compiler
//! (`tests/data/robots/make_mjcf.py`), against the same Pinocchio values.

use joint_runtime::Scene;
use joint_runtime::nalgebra::{SMatrix, SVector, Vector3, Vector4};
use joint_runtime::relative::{TreeSimulation, TreeState};
use joint_runtime::robot::{FileIntegrator, FileOptions, LinkFrame, StateLayout};

super::urdf::robots_against_pinocchio!(
    mjcf: "data/robots/double_pendulum.xml", "data/robots/ur5.xml", "data/robots/panda.xml", "data/robots/solo12.xml",
    floating: [mjcf = "data/robots/solo12_floating.xml"]
);

/// The gravity is the file's (MuJoCo's default where it says nothing); the
/// limits are MuJoCo's import of the URDF's, in radians.
#[test]
#[allow(clippy::approx_constant)] // the file's digits, not 2π
fn gravity_and_limits_from_the_file() {
    let sim = joint_runtime::relative::TreeSimulation::new(&Ur5).unwrap();
    assert_eq!(sim.tree().gravity(), joint_runtime::nalgebra::Vector3::new(0.0, 0.0, -9.81));
    let pan = Ur5::LIMITS[0];
    assert_eq!((pan.name, pan.range, pan.effort), ("shoulder_pan_joint", Some((-6.28319, 6.28319)), Some(150.0)));
    assert_eq!(LinkFrame::find(&Ur5::LINKS, "tool0").unwrap().body, Some(5));
}

/// Each of MJCF's orientations (`euler` on a `<frame>`, `axisangle` on the
/// body, `xyaxes` on its inertia, `zaxis` on a site), in degrees, with
/// `<default>` classes: worked out by hand, the bob's centre is at
/// (0, 0.5, 0.1), its inertia about it diag(0.2, 0.1, 0.25) in world axes,
/// the ball joint at (0, 0.5, 0.5), its damping 0.1 (the main class) and
/// armature 0.01 (the body's `childclass`).
#[derive(Scene)]
#[scene(mjcf = "data/mjcf/ball_pendulum.xml")]
struct BallFromFile;

#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], coordinates = relative)]
#[body(bob, mass = 2.0, inertia = [0.2, 0.1, 0.25])]
#[joint(ball = spherical(ground, bob), rho1 = [0, 0.5, 0.5], rho2 = [0, 0, 0.4], armature = 0.01, damping = 0.1)]
struct BallByHand;

#[test]
fn orientations_and_classes_as_worked_out_by_hand() {
    let (mut file, mut hand) = (TreeSimulation::new(&BallFromFile).unwrap(), TreeSimulation::new(&BallByHand).unwrap());
    let q = Vector4::new(0.9, 0.3, -0.2, 0.25).normalize();
    let state = TreeState::<4, 3> { q, v: Vector3::new(0.7, -1.1, 0.4), t: 0.0 };
    let tau = Vector3::new(0.3, 0.1, -0.2);
    let (a, b) = (file.forward_dynamics(&state, &tau).unwrap(), hand.forward_dynamics(&state, &tau).unwrap());
    assert!((a - b).amax() < 1e-13 * b.amax(), "{a} {b}");
    // Sites are frames: the tip 0.4 below the centre, its z along x (a
    // quarter turn about y); the anchor on the ground.
    let tip = LinkFrame::find(&BallFromFile::LINKS, "tip").unwrap();
    assert_eq!(tip.body, Some(0));
    let expected = [[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]];
    let close = |x: &[f64; 3], y: &[f64; 3]| x.iter().zip(y).all(|(a, b)| (a - b).abs() < 1e-15);
    assert!(close(&tip.origin, &[0.0, 0.0, -0.4]), "{:?}", tip.origin);
    assert!(tip.rotation.iter().zip(&expected).all(|(c, e)| close(c, e)), "{:?}", tip.rotation);
    let anchor = LinkFrame::find(&BallFromFile::LINKS, "anchor").unwrap();
    assert_eq!((anchor.body, anchor.origin), (None, [0.0, 0.0, 1.0]));
    // The joint's data: damping from the main class, armature from the
    // body's `childclass`, the range from degrees.
    let ball = BallFromFile::LIMITS[0];
    assert_eq!((ball.name, ball.damping, ball.armature), ("ball", Some(0.1), Some(0.01)));
    let (lo, hi) = ball.range.unwrap();
    assert!(lo == 0.0 && (hi - std::f64::consts::FRAC_PI_3).abs() < 1e-15);
}

/// A four-bar closed by `connect`, against the same written as attributes
/// (points from the centres worked out by hand): the same motion. MuJoCo
/// would soften the `connect`; `equality = hard` reads it as an ideal joint.
#[derive(Scene)]
#[scene(mjcf = "data/mjcf/four_bar.xml", equality = hard)]
struct FourBarFromFile;

#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], coordinates = relative)]
#[body(crank, mass = 1.0, inertia = [0.09, 0.09, 0.01])]
#[body(coupler, mass = 2.0, inertia = [0.1, 0.6, 0.55, 0, -0.05, 0])]
#[body(rocker, mass = 1.5, inertia = [0.3, 0.3, 0.02])]
#[joint(a = revolute(ground, crank), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0, 0, 0], rho2 = [0, 0, -0.5])]
#[joint(b = revolute(crank, coupler), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0, 0, 0.5], rho2 = [-1, 0, -0.25])]
#[joint(d = revolute(ground, rocker), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [2, 0, 0], rho2 = [0, 0, -0.75])]
#[joint(c = spherical(coupler, rocker), rho1 = [1, 0, 0.25], rho2 = [0, 0, 0.75])]
struct FourBarByHand;

#[test]
fn connect_closes_a_loop_as_a_ball_joint() {
    let (mut file, mut hand) =
        (TreeSimulation::new(&FourBarFromFile).unwrap(), TreeSimulation::new(&FourBarByHand).unwrap());
    let mut guess = file.tree().zero_state();
    guess.v = SVector::from([1.0, -0.5, 0.7]);
    let mut x = file.assemble(&guess).unwrap();
    let mut y = x;
    for _ in 0..500 {
        file.step(&mut x, 1e-3).unwrap();
        hand.step(&mut y, 1e-3).unwrap();
    }
    let worst = (x.q - y.q).amax().max((x.v - y.v).amax());
    eprintln!("four-bar by connect against attributes after 0.5 s: {worst:.1e} (q {:?})", x.q.as_slice());
    assert!(worst < 1e-12, "{worst:e}");
    assert!(x.q.amax() > 0.1, "it moved: {:?}", x.q.as_slice());
    let closed = file.closure_rows(&x).phi.amax();
    assert!(closed < 1e-10, "the loop stays closed: {closed:e}");
}

/// `weld` holds the elbow: the double pendulum swings as the rigid one
/// (the lower link a body without joints).
#[derive(Scene)]
#[scene(mjcf = "data/mjcf/welded_pendulum.xml", equality = hard)]
struct Welded;

#[derive(Scene)]
#[scene(mjcf = "data/mjcf/rigid_pendulum.xml")]
struct Rigid;

#[test]
fn weld_makes_two_bodies_one() {
    let (mut welded, mut rigid) = (TreeSimulation::new(&Welded).unwrap(), TreeSimulation::new(&Rigid).unwrap());
    let (mut x, mut y) = (welded.tree().zero_state(), rigid.tree().zero_state());
    x.q[0] = 0.7;
    y.q[0] = 0.7;
    for _ in 0..1000 {
        welded.step(&mut x, 1e-3).unwrap();
        rigid.step(&mut y, 1e-3).unwrap();
    }
    let (dq, dv) = ((x.q[0] - y.q[0]).abs(), (x.v[0] - y.v[0]).abs());
    eprintln!("welded against rigid after 1 s: shoulder {dq:.1e}, rate {dv:.1e}; elbow {:.1e}", x.q[1].abs());
    assert!(dq < 1e-10 && dv < 1e-10 && x.q[1].abs() < 1e-10, "{dq:e} {dv:e} {:e}", x.q[1]);
    assert!((y.q[0] - 0.7).abs() > 0.1, "it swung");
}

/// Armature and damping as MuJoCo 4.0 has them (`tests/data/mjcf/reference.py`:
/// `mj_fullM`, `mj_forward`'s `qacc` under applied joint forces, `mj_inverse`),
/// on the Panda with every joint's own values and on the ball pendulum.
#[derive(Scene)]
#[scene(mjcf = "data/mjcf/panda_damped.xml")]
struct PandaDamped;

/// Every sample of `key` through the scene's `MUJOCO` layout (MuJoCo's
/// `qpos` has a joint's `ref` at the file's pose; a ball joint on a turned
/// body turns the link's frame): `M` as `Tᵀ M T`, the forward dynamics'
/// `qacc` and the inverse dynamics' `qfrc_inverse`, each to 1e-12 of its
/// largest entry.
fn against_mujoco<S, const NB: usize, const NQ: usize, const NV: usize>(
    scene: &S,
    layout: &StateLayout<NQ, NV>,
    key: &str,
) -> [f64; 3]
where
    S: joint_runtime::relative::TreeScene<NB, NQ, NV>,
{
    let path = format!("{}/data/mjcf/reference.json", env!("CARGO_MANIFEST_DIR"));
    let data: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    let numbers =
        |v: &serde_json::Value| -> Vec<f64> { v.as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect() };
    let mut sim = TreeSimulation::new(scene).unwrap();
    let mut worst = [0.0_f64; 3];
    for s in data[key].as_array().unwrap() {
        let (q, v) = (numbers(&s["q"]), numbers(&s["v"]));
        let state = layout.state_from(&q, &v).unwrap();
        let theirs = |k: &str| SVector::<f64, NV>::from_iterator(numbers(&s[k]));
        let scale = |x: &SVector<f64, NV>| x.amax().max(f64::MIN_POSITIVE);
        let mut m = SMatrix::<f64, NV, NV>::zeros();
        sim.mass_matrix_into(&state.q, &mut m);
        let mut theirs_m = SMatrix::<f64, NV, NV>::zeros();
        for i in 0..NV {
            let mut unit = vec![0.0; NV];
            unit[i] = 1.0;
            let mut column = [0.0; NV];
            layout.write_forces(&state, &(m * layout.state_from(&q, &unit).unwrap().v), &mut column).unwrap();
            theirs_m.set_column(i, &SVector::<f64, NV>::from(column));
        }
        let given =
            SMatrix::<f64, NV, NV>::from_iterator(s["mass_matrix"].as_array().unwrap().iter().flat_map(numbers));
        worst[0] = worst[0].max((theirs_m - given).amax() / given.amax());
        let tau = layout.forces_from(&state, theirs("tau").as_slice()).unwrap();
        let mut qacc = [0.0; NV];
        layout.write_accelerations(&state, &sim.forward_dynamics(&state, &tau).unwrap(), &mut qacc).unwrap();
        let qacc = SVector::<f64, NV>::from(qacc);
        worst[1] = worst[1].max((qacc - theirs("qacc")).amax() / scale(&theirs("qacc")));
        let a = layout.accelerations_from(&state, theirs("a").as_slice()).unwrap();
        let mut inverse = [0.0; NV];
        layout.write_forces(&state, &sim.inverse_dynamics(&state, &a), &mut inverse).unwrap();
        let inverse = SVector::<f64, NV>::from(inverse);
        worst[2] = worst[2].max((inverse - theirs("inverse")).amax() / scale(&theirs("inverse")));
    }
    eprintln!(
        "{key} against MuJoCo: M {:.1e}, forward {:.1e}, inverse {:.1e} of the largest entry",
        worst[0], worst[1], worst[2]
    );
    for (what, w) in ["M", "forward dynamics", "inverse dynamics"].iter().zip(worst) {
        assert!(w < 1e-12, "{key}: {what} off by {w:e}");
    }
    worst
}

/// Joint springs as MuJoCo 4.0 has them (`stiffness`, `springref`, `ref`;
/// `tests/data/mjcf/reference.py`): the Panda with every joint's own, and
/// a hand-written file with a spring in degrees, one from a class, one on a
/// slide, beside a damped joint and a ball joint on a turned body.
#[derive(Scene)]
#[scene(mjcf = "data/mjcf/panda_springs.xml")]
struct PandaSprings;

#[derive(Scene)]
#[scene(mjcf = "data/mjcf/springs.xml")]
struct Springs;

/// `<compiler settotalmass="30">`: every mass and inertia scaled by one
/// factor, as MuJoCo 4.0's compiler does (it calls the attribute deprecated,
/// and still applies it).
#[derive(Scene)]
#[scene(mjcf = "data/mjcf/panda_total.xml")]
struct PandaTotal;

#[test]
fn a_total_mass_scales_every_body_as_mujoco_does() {
    against_mujoco(&PandaTotal, &PandaTotal::MUJOCO, "panda_total");
    let (plain, total) = (TreeSimulation::new(&Panda).unwrap(), TreeSimulation::new(&PandaTotal).unwrap());
    let (mut m, mut n) = (SMatrix::<f64, 9, 9>::zeros(), SMatrix::<f64, 9, 9>::zeros());
    let q = SVector::from([0.1, -0.4, 0.3, -1.8, 0.2, 1.1, 0.5, 0.02, 0.02]);
    plain.mass_matrix_into(&q, &mut m);
    total.mass_matrix_into(&q, &mut n);
    let factor = n[(0, 0)] / m[(0, 0)];
    assert!((n - m * factor).amax() < 1e-12 * n.amax() && factor > 1.0, "{factor}");
}

/// Gravity compensation (`gravcomp`) on some of the Panda's bodies, each its
/// own fraction, as MuJoCo 4.0 has it (`qfrc_gravcomp` among its passive
/// forces); the derivatives carry it (against central differences).
#[derive(Scene)]
#[scene(mjcf = "data/mjcf/panda_gravcomp.xml")]
struct PandaHeld;

#[test]
fn gravity_compensation_as_mujoco_has_it() {
    against_mujoco(&PandaHeld, &PandaHeld::MUJOCO, "panda_gravcomp");
    let sim = TreeSimulation::new(&PandaHeld).unwrap();
    let mut state = sim.tree().zero_state();
    state.q = SVector::from([0.3, -0.7, 0.4, -1.9, 0.5, 1.3, -0.2, 0.01, 0.03]);
    state.v = SVector::from([0.2, -0.1, 0.3, 0.1, -0.4, 0.2, 0.5, 0.01, -0.02]);
    let mut d = joint_runtime::relative::InverseDerivatives::zeros();
    let a = SVector::from([0.1, 0.2, -0.3, 0.4, -0.5, 0.6, -0.7, 0.1, 0.2]);
    sim.inverse_dynamics_derivatives(&state, &a, &mut d).unwrap();
    assert!((d.tau - sim.inverse_dynamics(&state, &a)).amax() < 1e-12);
    let eps = 1e-6;
    for i in 0..9 {
        let (mut up, mut down) = (state, state);
        up.q[i] += eps;
        down.q[i] -= eps;
        let column = (sim.inverse_dynamics(&up, &a) - sim.inverse_dynamics(&down, &a)) / (2.0 * eps);
        assert!((column - d.d_q.column(i)).amax() < 1e-7 * d.d_q.amax(), "column {i}");
    }
    // Its energy: the held fraction of the weight stores none, and the total
    // stays put along a motion.
    let mut moving = TreeSimulation::new(&PandaHeld).unwrap();
    let (start, mut end) = (moving.energy(&state).total(), state);
    for _ in 0..200 {
        moving.step(&mut end, 1e-3).unwrap();
    }
    let drift = (moving.energy(&end).total() - start).abs() / moving.energy(&state).kinetic;
    assert!(drift < 1e-8, "{drift:e}");
    let rest = |c: &TreeState<9, 9>| sim.energy(c).gravity;
    let mut lifted = state;
    lifted.q[1] += 0.3;
    let plain = TreeSimulation::new(&Panda).unwrap();
    assert!(
        (rest(&lifted) - rest(&state)).abs() < (plain.energy(&lifted).gravity - plain.energy(&state).gravity).abs()
    );
}

/// A pendulum held up in full (`gravcomp="1"`): at rest anywhere, its
/// joint carrying nothing.
#[derive(Scene)]
#[scene(mjcf = "data/mjcf/held_pendulum.xml")]
struct HeldPendulum;

#[test]
fn a_fully_held_pendulum_floats_and_its_joint_carries_nothing() {
    let mut sim = TreeSimulation::new(&HeldPendulum).unwrap();
    let state = TreeState { q: SVector::from([0.8]), v: SVector::zeros(), t: 0.0 };
    let qdd = sim.forward_dynamics(&state, &SVector::zeros()).unwrap();
    assert!(qdd.amax() < 1e-14, "{qdd}");
    let reaction = sim.reactions(&state, &SVector::zeros()).unwrap()[0];
    assert!(reaction.force.amax() < 1e-14 && reaction.torque.amax() < 1e-14, "{reaction:?}");
    assert!(sim.inverse_dynamics(&state, &SVector::zeros()).amax() < 1e-15);
}

#[test]
fn joint_springs_as_mujoco_has_them() {
    against_mujoco(&PandaSprings, &PandaSprings::MUJOCO, "panda_springs");
    against_mujoco(&Springs, &Springs::MUJOCO, "springs");
    // The file's `<option timestep integrator>`, as data; none in the Panda's,
    // which MuJoCo steps by its defaults (0.002 s, Euler).
    let asked = FileOptions { timestep: Some(0.002), integrator: Some(FileIntegrator::ImplicitFast) };
    let defaults = FileOptions { timestep: Some(0.002), integrator: Some(FileIntegrator::Euler) };
    assert_eq!((Springs::OPTIONS, PandaSprings::OPTIONS), (asked, defaults));
    // `ref` is MuJoCo's coordinate at the file's pose, the tree's zero.
    let shoulder = Springs::MUJOCO.joints()[0];
    assert_eq!((shoulder.name, shoulder.offset), ("shoulder", 10f64.to_radians()));
    // The range is in the tree's coordinate; the spring's energy is ½ k x².
    let sim = TreeSimulation::new(&Springs).unwrap();
    let mut state = sim.tree().zero_state();
    state.q[0] = 0.3;
    let stretch = 0.3 - (15f64 - 10.0).to_radians();
    let rail = 0.0 - (0.05 + 0.02);
    let wrist = 0.0 - (-20f64).to_radians();
    let elastic = 0.5 * (30.0 * stretch * stretch + 200.0 * rail * rail + 4.0 * wrist * wrist);
    assert!((sim.energy(&state).elastic - elastic).abs() < 1e-14, "{}", sim.energy(&state).elastic);
}

#[test]
fn armature_and_damping_as_mujoco_has_them() {
    against_mujoco(&PandaDamped, &PandaDamped::MUJOCO, "panda_damped");
    against_mujoco(&BallFromFile, &BallFromFile::MUJOCO, "ball_pendulum");
    // The file's values are also data.
    let j3 = PandaDamped::LIMITS[2];
    assert_eq!((j3.name, j3.armature), ("panda_joint3", Some(0.03)));
}

/// `<equality joint>` is a row: `joint2 = 0.1 − 0.5 joint1`. The coupled
/// pendulum's accelerations are Gauss's `T (Tᵀ M T)⁻¹ Tᵀ (τ − C)`,
/// `T = [1; −0.5]`, from the same file read with `mimic = independent`
/// (`equality = hard`: an ideal row, where MuJoCo's would be soft).
#[derive(Scene)]
#[scene(mjcf = "data/mjcf/coupled_pendulum.xml", equality = hard)]
struct CoupledPendulum;

#[derive(Scene)]
#[scene(mjcf = "data/mjcf/coupled_pendulum.xml", mimic = independent)]
struct UncoupledPendulum;

#[test]
fn a_joint_equality_is_a_row() {
    let mut coupled = TreeSimulation::new(&CoupledPendulum).unwrap();
    let free = TreeSimulation::new(&UncoupledPendulum).unwrap();
    let t = SVector::<f64, 2>::new(1.0, -0.5);
    let mut worst = 0.0_f64;
    for k in 0..10 {
        let x = f64::from(k) * 0.37 - 1.5;
        let state = TreeState::<2, 2> {
            q: SVector::from([x, 0.1 - 0.5 * x]),
            v: SVector::from([0.8 - x, -0.5 * (0.8 - x)]),
            t: 0.0,
        };
        let tau = SVector::<f64, 2>::new(0.02 * x, -0.01);
        let mut m = SMatrix::<f64, 2, 2>::zeros();
        free.mass_matrix_into(&state.q, &mut m);
        let bias = free.inverse_dynamics(&state, &SVector::zeros());
        let expected = t * (t.dot(&(tau - bias)) / t.dot(&(m * t)));
        let ours = coupled.forward_dynamics(&state, &tau).unwrap();
        worst = worst.max((ours - expected).amax() / expected.amax());
    }
    eprintln!("pendulum coupled by <equality joint>: accelerations to {worst:.1e} of Gauss's");
    assert!(worst < 1e-12, "{worst:e}");
}

/// The coupled pendulum linearised on its coupling: one freedom, and its
/// `A` has the trace and determinant of the reduced system's
/// `[[0, 1], [∂f/∂s, ∂f/∂w]]`, `f(s, w) = tᵀ (−C) / tᵀ M t` at
/// `q = (s, 0.1 − 0.5 s)`, `v = t w`, from the uncoupled file's `M` and `C`
/// (both by differences: to 1e-6).
#[test]
fn a_coupled_pendulum_linearises_on_its_coupling() {
    let mut coupled = TreeSimulation::new(&CoupledPendulum).unwrap();
    let free = TreeSimulation::new(&UncoupledPendulum).unwrap();
    let t = SVector::<f64, 2>::new(1.0, -0.5);
    let at = |s: f64, w: f64| TreeState::<2, 2> { q: SVector::from([s, 0.1 - 0.5 * s]), v: t * w, t: 0.0 };
    let f = |s: f64, w: f64| {
        let mut m = SMatrix::<f64, 2, 2>::zeros();
        free.mass_matrix_into(&at(s, w).q, &mut m);
        -t.dot(&free.inverse_dynamics(&at(s, w), &SVector::zeros())) / t.dot(&(m * t))
    };
    let (s, w, h) = (0.4, 0.3, 1e-5);
    let (dfds, dfdw) = ((f(s + h, w) - f(s - h, w)) / (2.0 * h), (f(s, w + h) - f(s, w - h)) / (2.0 * h));
    let lin = coupled.linearise(&at(s, w), &SVector::zeros()).unwrap();
    assert_eq!((lin.freedoms, lin.a.shape()), (1, (2, 2)));
    let (trace, det) = (lin.a.trace(), lin.a.determinant());
    eprintln!("coupled pendulum: trace {trace:.9} against {dfdw:.9}, determinant {det:.9} against {:.9}", -dfds);
    assert!((trace - dfdw).abs() < 1e-6 * dfdw.abs().max(1.0) && (det + dfds).abs() < 1e-6 * dfds.abs());
    // The input: a unit torque on the shoulder moves the reduced rate by tᵀ e₀ / tᵀ M t (times |t|).
    let mut m = SMatrix::<f64, 2, 2>::zeros();
    free.mass_matrix_into(&at(s, w).q, &mut m);
    let expected = t.norm() / t.dot(&(m * t));
    assert!((lin.b[(1, 0)].abs() - expected).abs() < 1e-9 * expected, "{} {expected}", lin.b[(1, 0)]);
}
