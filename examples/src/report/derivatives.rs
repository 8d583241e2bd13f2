//! The robot level of the report: the forward dynamics' derivatives
//! (`∂q̈/∂q`, `∂q̈/∂v`) of the UR5, the Panda and the floating Solo12 read
//! from their URDF files, exact (`forward_dynamics_derivatives`) and by
//! central differences of the forward dynamics at several steps, each timed
//! per call and compared with Pinocchio 4.1's analytical derivatives
//! (`tests/data/robots/<robot>_derivatives.json`, 20 states per robot).

use std::fmt::Write as _;
use std::path::Path;

use joint_runtime::Scene;
use joint_runtime::nalgebra::{SMatrix, SVector};
use joint_runtime::relative::{
    ForwardDerivatives, InverseDerivatives, TreeJointKind, TreeScene, TreeSimulation, TreeState,
};
use serde_json::Value;

use super::variants::median_ns;

/// The UR5 (also the stiff run's robot, `stiff_robot`).
#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], urdf = "../tests/data/robots/ur5.urdf", second_order)]
pub(crate) struct Ur5;

#[derive(Scene)]
#[scene(gravity = [0, 0, -9.81], urdf = "../tests/data/robots/solo12.urdf", floating_base)]
struct Solo12Floating;

/// The central differences' steps compared.
pub const STEPS: [f64; 6] = [1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8];

/// One robot's row: the exact derivatives' and each step's time (ns per
/// call) and worst error (over the largest entry of Pinocchio's matrices).
#[derive(Clone, Debug)]
pub struct Row {
    /// The robot.
    pub robot: &'static str,
    /// Freedoms.
    pub nv: usize,
    /// `(ns, error)` of the exact derivatives.
    pub exact: (f64, f64),
    /// `(ns, error)` of central differences at each of [`STEPS`].
    pub differences: Vec<(f64, f64)>,
}

/// A sample's state and forces in our order, and Pinocchio's `∂q̈/∂q`, `∂q̈/∂v` there.
type Sample<const NQ: usize, const NV: usize> =
    (TreeState<NQ, NV>, SVector<f64, NV>, SMatrix<f64, NV, NV>, SMatrix<f64, NV, NV>);

fn numbers(v: &Value) -> Vec<f64> {
    v.as_array().map(|a| a.iter().filter_map(Value::as_f64).collect()).unwrap_or_default()
}

/// The file's samples mapped to our joints (by name; a floating root is
/// Pinocchio's `root_joint`, its quaternion `x y z w` turned `w` first).
fn samples<S: TreeScene<NB, NQ, NV>, const NB: usize, const NQ: usize, const NV: usize>(
    sim: &TreeSimulation<'_, S, NB, NQ, NV>,
    data: &Value,
) -> Result<Vec<Sample<NQ, NV>>, String> {
    let mut theirs = std::collections::HashMap::new();
    let (mut q_at, mut v_at) = (0, 0);
    for j in data["joints"].as_array().ok_or("no joints")? {
        let name = if j["type"] == "floating" { "free" } else { j["name"].as_str().unwrap_or("") };
        theirs.insert(name.to_string(), (q_at, v_at));
        q_at += j["nq"].as_u64().unwrap_or(0) as usize;
        v_at += j["nv"].as_u64().unwrap_or(0) as usize;
    }
    let (mut q_index, mut v_index) = (Vec::new(), Vec::new());
    for j in sim.tree().joints() {
        let key = if j.name.starts_with("free(") { "free" } else { j.name };
        let &(q, v) = theirs.get(key).ok_or_else(|| format!("joint {key} not in the file"))?;
        let quaternion = j.kind == TreeJointKind::Free;
        for i in 0..j.kind.coordinates() {
            // Pinocchio's [x y z | qx qy qz qw] → ours [x y z | qw qx qy qz].
            q_index.push(if quaternion && i >= 3 { q + 3 + i % 4 } else { q + i });
        }
        v_index.extend((0..j.kind.freedoms()).map(|i| v + i));
    }
    let matrix = |value: &Value| -> SMatrix<f64, NV, NV> {
        let rows: Vec<Vec<f64>> = value.as_array().map(|r| r.iter().map(numbers).collect()).unwrap_or_default();
        SMatrix::from_fn(|r, c| rows.get(v_index[r]).and_then(|row| row.get(v_index[c])).copied().unwrap_or(f64::NAN))
    };
    let mut out = Vec::new();
    for s in data["samples"].as_array().ok_or("no samples")?.iter().take(20) {
        let (q, v, tau) = (numbers(&s["q"]), numbers(&s["v"]), numbers(&s["tau"]));
        let state = TreeState {
            q: SVector::from_fn(|i, _| q.get(q_index[i]).copied().unwrap_or(f64::NAN)),
            v: SVector::from_fn(|i, _| v.get(v_index[i]).copied().unwrap_or(f64::NAN)),
            t: 0.0,
        };
        let tau = SVector::from_fn(|i, _| tau.get(v_index[i]).copied().unwrap_or(f64::NAN));
        out.push((state, tau, matrix(&s["daba_dq"]), matrix(&s["daba_dv"])));
    }
    Ok(out)
}

/// The larger of the two matrices' worst differences over their largest entries.
fn error<const NV: usize>(
    ours: (&SMatrix<f64, NV, NV>, &SMatrix<f64, NV, NV>),
    sample: (&SMatrix<f64, NV, NV>, &SMatrix<f64, NV, NV>),
) -> f64 {
    let one = |a: &SMatrix<f64, NV, NV>, b: &SMatrix<f64, NV, NV>| (a - b).amax() / b.amax();
    one(ours.0, sample.0).max(one(ours.1, sample.1))
}

/// Central differences of the forward dynamics at `state`, step `h` (scaled as `linearise`'s).
fn differenced<S: TreeScene<NB, NQ, NV>, const NB: usize, const NQ: usize, const NV: usize>(
    sim: &TreeSimulation<'_, S, NB, NQ, NV>,
    state: &TreeState<NQ, NV>,
    tau: &SVector<f64, NV>,
    h: f64,
) -> (SMatrix<f64, NV, NV>, SMatrix<f64, NV, NV>) {
    let (mut d_q, mut d_v) = (SMatrix::<f64, NV, NV>::zeros(), SMatrix::<f64, NV, NV>::zeros());
    let f = |s: &TreeState<NQ, NV>| sim.tree_dynamics(s, tau).unwrap_or_else(|_| SVector::repeat(f64::NAN));
    for i in 0..NV {
        let e = SVector::<f64, NV>::from_fn(|r, _| if r == i { h } else { 0.0 });
        let (plus, minus) = (
            TreeState { q: sim.tree().displaced(&state.q, &e), ..*state },
            TreeState { q: sim.tree().displaced(&state.q, &-e), ..*state },
        );
        d_q.set_column(i, &((f(&plus) - f(&minus)) / (2.0 * h)));
        let hv = h * (1.0 + state.v[i].abs());
        let ev = e * (hv / h);
        d_v.set_column(
            i,
            &((f(&TreeState { v: state.v + ev, ..*state }) - f(&TreeState { v: state.v - ev, ..*state })) / (2.0 * hv)),
        );
    }
    (d_q, d_v)
}

fn row<S: TreeScene<NB, NQ, NV>, const NB: usize, const NQ: usize, const NV: usize>(
    scene: &S,
    robot: &'static str,
    dir: &Path,
) -> Result<Row, String> {
    let path = dir.join(format!("{robot}_derivatives.json"));
    let text = std::fs::read_to_string(&path).map_err(|e| format!("reading {}: {e}", path.display()))?;
    let data: Value = serde_json::from_str(&text).map_err(|e| e.to_string())?;
    let sim = TreeSimulation::new(scene).map_err(|e| e.to_string())?;
    let samples = samples(&sim, &data)?;
    let (mut work, mut d) = (InverseDerivatives::zeros(), ForwardDerivatives::zeros());
    let mut worst = 0.0_f64;
    for (state, tau, dq, dv) in &samples {
        sim.forward_dynamics_derivatives(state, tau, &mut work, &mut d).map_err(|e| e.to_string())?;
        worst = worst.max(error((&d.d_q, &d.d_v), (dq, dv)));
    }
    let (state, tau, ..) = samples.first().ok_or("no samples")?;
    let ns = median_ns(1, || {
        let _ = std::hint::black_box(sim.forward_dynamics_derivatives(state, tau, &mut work, &mut d));
    });
    let mut differences = Vec::new();
    for h in STEPS {
        let worst = samples.iter().map(|(s, t, dq, dv)| {
            let (a, b) = differenced(&sim, s, t, h);
            error((&a, &b), (dq, dv))
        });
        let worst = worst.fold(0.0_f64, f64::max);
        let ns = median_ns(1, || {
            std::hint::black_box(differenced(&sim, state, tau, h));
        });
        differences.push((ns, worst));
    }
    Ok(Row { robot, nv: NV, exact: (ns, worst), differences })
}

/// Every robot's row; `dir` holds the reference files.
pub fn measure(dir: &Path) -> Result<Vec<Row>, String> {
    Ok(vec![
        row(&Ur5, "ur5", dir)?,
        row(&crate::ilqr::PandaArm, "panda", dir)?,
        row(&Solo12Floating, "solo12_floating", dir)?,
    ])
}

/// The report's section.
pub fn section(rows: &[Row]) -> String {
    let mut s = String::from(
        "## Robot level: the dynamics' derivatives\n\n`∂q̈/∂q` and `∂q̈/∂v` of robots read from their URDF files \
         (`report::derivatives`), exact (`forward_dynamics_derivatives`, which also gives `q̈` and `M⁻¹`) and by \
         central differences of the forward dynamics along the tangent space (`2 · 2 NV` articulated-body calls; \
         the velocity step scaled by `1 + |v|`), at 20 states per robot against Pinocchio 4.1's \
         `computeABADerivatives` (`tests/data/robots/`). **Time**: median ns per call at the first state. \
         **Error**: the worst difference over the largest entry of Pinocchio's matrix.\n\n| robot (nv) | exact |",
    );
    for h in STEPS {
        let _ = write!(s, " h = {h:.0e} |");
    }
    s.push_str("\n|---|---|");
    s.push_str(&"---|".repeat(STEPS.len()));
    s.push('\n');
    for r in rows {
        let _ = write!(s, "| {} ({}) | {:.0} ns · {:.1e} |", r.robot, r.nv, r.exact.0, r.exact.1);
        for (ns, e) in &r.differences {
            let _ = write!(s, " {ns:.0} ns · {e:.1e} |");
        }
        s.push('\n');
    }
    s.push('\n');
    s
}
