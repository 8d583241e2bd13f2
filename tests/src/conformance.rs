//! The conformance runner's logic: read cases, evaluate them through generated
//! code, apply the accuracy test of the conformance README. The vectors live in
//! `conformance/` at the repository's root ([`vectors_dir`]).
//!
//! The case format is defined once here ([`VectorFile`], [`Case`]) and read by
//! serde: fixed-size inputs are arrays, so a malformed file is rejected with
//! the offending line and column rather than deep inside a case.

use std::collections::BTreeMap;
use std::hint::black_box;
use std::path::{Path, PathBuf};
use std::time::Instant;

use joint_runtime::{Drive, EulerBody, Joint, OmegaBody, RelativeState, TwoBodies};
use serde::Deserialize;

use crate::trajectory::{BODY, Coords, Flat};

/// `ε = 2⁻⁵²`.
pub const EPS: f64 = f64::EPSILON;
/// The test's tolerance in units of `ε · max(scale, floor)`.
pub const TOLERANCE: f64 = 256.0;

/// The repository's copy of the conformance vectors, `<repository>/conformance`.
///
/// Found from this package's manifest directory, so that programs and tests
/// read it from any working directory.
pub fn vectors_dir() -> PathBuf {
    // `CARGO_MANIFEST_DIR` is `<repository>/tests`, always absolute.
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap_or(Path::new("..")).join("conformance")
}

/// Reads a vectors file.
///
/// # Errors
/// The file cannot be read, or does not hold cases of the expected shape
/// (serde's message, with line and column).
pub fn load(path: &Path) -> Result<VectorFile, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("reading {}: {e}", path.display()))?;
    serde_json::from_str(&text).map_err(|e| format!("parsing {}: {e}", path.display()))
}

/// Reads `file` (`vectors.json` or `hard.json`) from the repository's
/// [`vectors_dir`]; a test's failure if it cannot.
///
/// # Panics
/// When the file is missing or malformed: the tests have nothing to check.
pub fn vectors(file: &str) -> VectorFile {
    load(&vectors_dir().join(file)).unwrap_or_else(|e| panic!("{e}"))
}

// ---------------------------------------------------------------------------
// The case format.
// ---------------------------------------------------------------------------

/// A vectors file (`vectors.json`, `hard.json`); other top-level keys
/// (`format`) are ignored.
#[derive(Clone, Debug, Deserialize)]
pub struct VectorFile {
    /// The cases, in file order.
    pub cases: Vec<Case>,
}

/// One case: a joint in a formulation at one state, with its reference values.
#[derive(Clone, Debug, Deserialize)]
pub struct Case {
    /// `joint/formulation/regime/NNN`.
    pub id: String,
    /// The joint kind, as in `CONVENTIONS.md`.
    pub joint: String,
    /// The formulation (`euler`, `omega_inertial`, ..., `relative_b2`).
    pub formulation: String,
    /// The joint's parameters.
    pub params: Params,
    /// The state the functions are evaluated at.
    pub state: State,
    /// Φ, J and γ at 60 digits, rounded to f64.
    pub expected: Expected,
    /// Each entry's scale: the sum of the absolute values of its monomials.
    pub scale: Expected,
}

/// A joint's parameters by their names in `CONVENTIONS.md` (each joint has
/// some of them); 3-vectors are in their own body's components.
#[derive(Clone, Copy, Debug, Default, Deserialize)]
pub struct Params {
    /// `s` (B1).
    pub s: Option<[f64; 3]>,
    /// `h` (B2; B1 for `translational_driver`).
    pub h: Option<[f64; 3]>,
    /// `b` (B1).
    pub b: Option<[f64; 3]>,
    /// `c` (B1).
    pub c: Option<[f64; 3]>,
    /// `f` (B1).
    pub f: Option<[f64; 3]>,
    /// `g` (B1).
    pub g: Option<[f64; 3]>,
    /// `k` (B2).
    pub k: Option<[f64; 3]>,
    /// `n` (B1).
    pub n: Option<[f64; 3]>,
    /// `rho1` (B1).
    pub rho1: Option<[f64; 3]>,
    /// `rho2` (B2).
    pub rho2: Option<[f64; 3]>,
    /// `length` (`distance`).
    pub length: Option<f64>,
}

impl Params {
    /// The 3-vector parameters present, with their names.
    pub fn vectors(&self) -> impl Iterator<Item = (&'static str, [f64; 3])> {
        let Params { s, h, b, c, f, g, k, n, rho1, rho2, length: _ } = *self;
        let all = [("s", s), ("h", h), ("b", b), ("c", c), ("f", f), ("g", g), ("k", k), ("n", n)];
        all.into_iter().chain([("rho1", rho1), ("rho2", rho2)]).filter_map(|(name, v)| Some((name, v?)))
    }
}

/// A case's state: `body1` and `body2` (absolute formulations) or `relative`,
/// and `drive` for the two drivers.
#[derive(Clone, Copy, Debug, Deserialize)]
pub struct State {
    /// Body 1 (absolute formulations).
    pub body1: Option<Body>,
    /// Body 2 (absolute formulations).
    pub body2: Option<Body>,
    /// The relative state (`relative_b1`, `relative_b2`).
    pub relative: Option<Relative>,
    /// The time function at the evaluation time (drivers).
    pub drive: Option<DriveValues>,
}

impl State {
    /// The state as flat coordinates ([`crate::trajectory::Coords`]): per body
    /// `r, p, ṙ` and `ω` or `ṗ`; the relative formulations fill body 0 with
    /// `δ, p_rel, δ̇, ω_rel`.
    ///
    /// # Errors
    /// The state has neither a relative state nor both bodies.
    pub fn coords(&self) -> Result<Coords<f64>, String> {
        let mut c = Flat([0.0; 34]);
        if let Some(rel) = &self.relative {
            c.set(0, &rel.delta);
            c.set(3, &rel.p);
            c.set(7, &rel.delta_dot);
            c.set(10, &rel.omega);
            return Ok(c);
        }
        for (b, body) in [(0, &self.body1), (1, &self.body2)] {
            let body = body.as_ref().ok_or_else(|| format!("missing `state.body{}`", b + 1))?;
            let o = BODY * b;
            c.set(o, &body.r);
            c.set(o + 3, &body.p);
            c.set(o + 7, &body.rdot);
            // `omega` or `pdot`, whichever the formulation has.
            if let Some(omega) = &body.omega {
                c.set(o + 10, omega);
            }
            if let Some(pdot) = &body.pdot {
                c.set(o + 13, pdot);
            }
        }
        Ok(c)
    }
}

/// One body's state: `pdot` for `euler`, `omega` (in the formulation's
/// components) for the others.
#[derive(Clone, Copy, Debug, Deserialize)]
pub struct Body {
    /// Position.
    pub r: [f64; 3],
    /// Euler parameters `[e0, e1, e2, e3]`.
    pub p: [f64; 4],
    /// Velocity.
    pub rdot: [f64; 3],
    /// Angular velocity (ω formulations).
    pub omega: Option<[f64; 3]>,
    /// Euler-parameter rates (`euler`).
    pub pdot: Option<[f64; 4]>,
}

/// The relative state of body 2 in body 1's frame.
#[derive(Clone, Copy, Debug, Deserialize)]
pub struct Relative {
    /// `δ`.
    pub delta: [f64; 3],
    /// The relative Euler parameters.
    pub p: [f64; 4],
    /// `δ̇`.
    pub delta_dot: [f64; 3],
    /// The relative angular velocity.
    pub omega: [f64; 3],
}

/// A driver's time function at the evaluation time.
#[derive(Clone, Copy, Debug, Deserialize)]
pub struct DriveValues {
    /// θ.
    pub value: f64,
    /// θ̇.
    pub rate: f64,
    /// θ̈.
    pub accel: f64,
}

impl From<DriveValues> for Drive {
    fn from(d: DriveValues) -> Drive {
        Drive { value: d.value, rate: d.rate, accel: d.accel }
    }
}

/// Φ, J (row-major, rows in the joint's order) and γ of a case: the expected
/// values, or their scales. The lengths depend on the joint and formulation.
#[derive(Clone, Debug, Deserialize)]
pub struct Expected {
    /// Φ.
    pub phi: Vec<f64>,
    /// J, one vector per row.
    pub jacobian: Vec<Vec<f64>>,
    /// γ.
    pub gamma: Vec<f64>,
}

/// `x`, or an error naming the missing input.
///
/// # Errors
/// `x` is `None`.
pub fn required<T>(x: Option<T>, name: &str) -> Result<T, String> {
    x.ok_or_else(|| format!("missing `{name}`"))
}

/// A joint or a state built from a whole case: a joint from `params` (and a
/// driver's `state.drive`), a state from `state`.
pub trait FromCase: Sized {
    /// Builds `Self` from `case`.
    ///
    /// # Errors
    /// An input the type needs is missing from the case.
    fn from_case(case: &Case) -> Result<Self, String>;
}

fn two_bodies<B>(state: &State, body: impl Fn(&Body) -> Result<B, String>) -> Result<TwoBodies<B>, String> {
    let body1 = body(required(state.body1.as_ref(), "body1")?)?;
    Ok(TwoBodies::new(body1, body(required(state.body2.as_ref(), "body2")?)?))
}

impl FromCase for TwoBodies<EulerBody<f64>> {
    fn from_case(case: &Case) -> Result<Self, String> {
        two_bodies(&case.state, |b| {
            let pdot = required(b.pdot, "pdot")?.into();
            Ok(EulerBody { r: b.r.into(), p: b.p.into(), rdot: b.rdot.into(), pdot })
        })
    }
}

impl FromCase for TwoBodies<OmegaBody<f64>> {
    fn from_case(case: &Case) -> Result<Self, String> {
        two_bodies(&case.state, |b| {
            let omega = required(b.omega, "omega")?.into();
            Ok(OmegaBody { r: b.r.into(), p: b.p.into(), rdot: b.rdot.into(), omega })
        })
    }
}

impl FromCase for RelativeState<f64> {
    fn from_case(case: &Case) -> Result<Self, String> {
        let v = required(case.state.relative.as_ref(), "relative")?;
        Ok(RelativeState {
            delta: v.delta.into(),
            p: v.p.into(),
            delta_dot: v.delta_dot.into(),
            omega: v.omega.into(),
            t: 0.0,
        })
    }
}

// ---------------------------------------------------------------------------
// Evaluating cases.
// ---------------------------------------------------------------------------

/// What the generated code computed for one case (a case of the `--emit` document).
#[derive(Clone, Debug, serde::Serialize)]
pub struct Output {
    /// The case id.
    pub id: String,
    /// Φ.
    pub phi: Vec<f64>,
    /// J, row-major.
    pub jacobian: Vec<Vec<f64>>,
    /// γ.
    pub gamma: Vec<f64>,
}

/// States whose inputs can be overwritten one component at a time, to feed the
/// generated code NaN and infinities (JSON cannot hold them).
pub trait Poison {
    /// The state's input fields, as `body1.r`, `body2.omega`, `delta`, ...
    /// (`euler` has `pdot` where the ω formulations have `omega`).
    fn fields(&self) -> &'static [&'static str];
    /// Sets component `i` of `field` to `x`; `false` if there is no such input.
    fn poison(&mut self, field: &str, i: usize, x: f64) -> bool;
}

fn set<const N: usize>(v: &mut joint_runtime::nalgebra::SVector<f64, N>, i: usize, x: f64) -> bool {
    v.get_mut(i).map(|c| *c = x).is_some()
}

impl Poison for TwoBodies<EulerBody<f64>> {
    fn fields(&self) -> &'static [&'static str] {
        &["body1.r", "body1.p", "body1.rdot", "body1.pdot", "body2.r", "body2.p", "body2.rdot", "body2.pdot"]
    }
    fn poison(&mut self, field: &str, i: usize, x: f64) -> bool {
        let (b, f) = match field.split_once('.') {
            Some(("body1", f)) => (&mut self.body1, f),
            Some(("body2", f)) => (&mut self.body2, f),
            _ => return false,
        };
        match f {
            "r" => set(&mut b.r, i, x),
            "p" => set(&mut b.p, i, x),
            "rdot" => set(&mut b.rdot, i, x),
            "pdot" => set(&mut b.pdot, i, x),
            _ => false,
        }
    }
}

impl Poison for TwoBodies<OmegaBody<f64>> {
    fn fields(&self) -> &'static [&'static str] {
        &["body1.r", "body1.p", "body1.rdot", "body1.omega", "body2.r", "body2.p", "body2.rdot", "body2.omega"]
    }
    fn poison(&mut self, field: &str, i: usize, x: f64) -> bool {
        let (b, f) = match field.split_once('.') {
            Some(("body1", f)) => (&mut self.body1, f),
            Some(("body2", f)) => (&mut self.body2, f),
            _ => return false,
        };
        match f {
            "r" => set(&mut b.r, i, x),
            "p" => set(&mut b.p, i, x),
            "rdot" => set(&mut b.rdot, i, x),
            "omega" => set(&mut b.omega, i, x),
            _ => false,
        }
    }
}

impl Poison for RelativeState<f64> {
    fn fields(&self) -> &'static [&'static str] {
        &["delta", "p", "delta_dot", "omega"]
    }
    fn poison(&mut self, field: &str, i: usize, x: f64) -> bool {
        match field {
            "delta" => set(&mut self.delta, i, x),
            "p" => set(&mut self.p, i, x),
            "delta_dot" => set(&mut self.delta_dot, i, x),
            "omega" => set(&mut self.omega, i, x),
            _ => false,
        }
    }
}

/// A group of cases of one joint and formulation, ready to evaluate.
pub trait Group {
    /// Evaluates every case.
    fn run(&self) -> Vec<Output>;
    /// The state's input fields (see [`Poison::fields`]).
    fn fields(&self) -> &'static [&'static str];
    /// Evaluates every case with component `i` of input `field` set to `x`.
    fn run_poisoned(&self, field: &str, i: usize, x: f64) -> Vec<Output>;
    /// Median ns per fused evaluation over the group's states.
    fn time(&self) -> f64;
    /// Operations in the fused evaluation.
    fn ops(&self) -> usize;
}

/// The cases of one generated joint type.
pub struct Typed<J: Joint<f64, R, C>, const R: usize, const C: usize> {
    cases: Vec<(String, J, J::State)>,
}

impl<J: Joint<f64, R, C>, const R: usize, const C: usize> Typed<J, R, C>
where
    J: FromCase,
    J::State: FromCase,
{
    /// Builds each case's joint and state.
    ///
    /// # Errors
    /// A case lacks an input of this joint or formulation.
    pub fn new(cases: &[&Case]) -> Result<Self, String> {
        let cases = cases
            .iter()
            .map(|c| {
                let joint = J::from_case(c).map_err(|e| format!("{}: params: {e}", c.id))?;
                let state = J::State::from_case(c).map_err(|e| format!("{}: state: {e}", c.id))?;
                Ok((c.id.clone(), joint, state))
            })
            .collect::<Result<_, String>>()?;
        Ok(Typed { cases })
    }
}

fn output<J: Joint<f64, R, C>, const R: usize, const C: usize>(id: &str, j: &J, s: &J::State) -> Output {
    let e = j.evaluate(s);
    Output {
        id: id.to_string(),
        phi: e.phi.iter().copied().collect(),
        jacobian: (0..R).map(|r| (0..C).map(|c| e.jacobian[(r, c)]).collect()).collect(),
        gamma: e.gamma.iter().copied().collect(),
    }
}

impl<J: Joint<f64, R, C>, const R: usize, const C: usize> Group for Typed<J, R, C>
where
    J::State: Poison + Clone,
{
    fn run(&self) -> Vec<Output> {
        self.cases.iter().map(|(id, j, s)| output(id, j, s)).collect()
    }

    fn fields(&self) -> &'static [&'static str] {
        self.cases.first().map_or(&[], |(_, _, s)| s.fields())
    }

    fn run_poisoned(&self, field: &str, i: usize, x: f64) -> Vec<Output> {
        self.cases
            .iter()
            .filter_map(|(id, j, s)| {
                let mut s = s.clone();
                s.poison(field, i, x).then(|| output(id, j, &s))
            })
            .collect()
    }

    fn time(&self) -> f64 {
        let n = self.cases.len().max(1);
        let once = || {
            for (_, j, s) in &self.cases {
                black_box(j.evaluate(black_box(s)));
            }
        };
        // Calibrate to about 2 ms a repetition, then take the median of 9.
        let mut iters = 1usize;
        loop {
            let t = Instant::now();
            for _ in 0..iters {
                once();
            }
            if t.elapsed().as_secs_f64() > 2e-3 || iters > 1 << 24 {
                break;
            }
            iters *= 2;
        }
        let mut samples: Vec<f64> = (0..9)
            .map(|_| {
                let t = Instant::now();
                for _ in 0..iters {
                    once();
                }
                t.elapsed().as_secs_f64() * 1e9 / (iters * n) as f64
            })
            .collect();
        samples.sort_by(f64::total_cmp);
        samples[samples.len() / 2]
    }

    fn ops(&self) -> usize {
        J::OPS.evaluate
    }
}

/// The worst error of one case in units of `ε · max(scale, floor)`, or `Err`
/// when an entry whose scale is 0 is not exactly zero, or a shape is wrong.
pub fn case_error(case: &Case, got: &Output) -> Result<f64, String> {
    let (expected, scale) = (&case.expected, &case.scale);
    let mut worst: f64 = 0.0;
    let mut check = |what: &str, got: &[f64], want: &[f64], scale: &[f64], floor: f64| -> Result<(), String> {
        if got.len() != want.len() || scale.len() != want.len() {
            return Err(format!("{what}: {} entries, expected {}", got.len(), want.len()));
        }
        for i in 0..want.len() {
            // An entry whose scale is 0 is zero for every input: the generated
            // code must emit an exact zero there (the floor does not apply).
            if scale[i] == 0.0 {
                if got[i] != 0.0 || want[i] != 0.0 {
                    return Err(format!("{what}[{i}] should be exactly 0, got {:e}", got[i]));
                }
                continue;
            }
            let s = scale[i].max(floor);
            let err = (got[i] - want[i]).abs();
            // NaN compares false: count it as infinitely wrong.
            let units = if err.is_nan() { f64::INFINITY } else { err / (EPS * s) };
            worst = worst.max(units);
        }
        Ok(())
    };
    check("phi", &got.phi, &expected.phi, &scale.phi, 0.0)?;
    check("gamma", &got.gamma, &expected.gamma, &scale.gamma, 0.0)?;
    let (jw, js) = (&expected.jacobian, &scale.jacobian);
    if jw.len() != got.jacobian.len() {
        return Err(format!("jacobian: {} rows, expected {}", got.jacobian.len(), jw.len()));
    }
    if js.len() != jw.len() {
        return Err(format!("jacobian scale: {} rows, expected {}", js.len(), jw.len()));
    }
    for (r, ((row, want), srow)) in got.jacobian.iter().zip(jw).zip(js).enumerate() {
        let floor = srow.iter().copied().fold(0.0, f64::max) / 64.0;
        check(&format!("jacobian[{r}]"), row, want, srow, floor)?;
    }
    Ok(worst)
}

/// Per joint and formulation: the worst error, the number of cases, and failures.
#[derive(Default, Debug)]
pub struct Summary {
    /// Worst error in units of `ε · scale`, per `(joint, formulation)`.
    pub worst: BTreeMap<(String, String), (f64, usize)>,
    /// Failed cases with the reason.
    pub failures: Vec<String>,
    /// Groups with no generated code.
    pub missing: Vec<String>,
    /// Outputs, in case order.
    pub outputs: Vec<Output>,
    /// `(joint, formulation, ns per evaluation, ops)` when timed.
    pub timings: Vec<(String, String, f64, usize)>,
}

/// The cases by `(joint, formulation)`, in file order within a group;
/// with `joints`, only those joints.
pub fn groups<'a>(cases: &'a [Case], joints: Option<&[String]>) -> BTreeMap<(String, String), Vec<&'a Case>> {
    let mut groups: BTreeMap<(String, String), Vec<&Case>> = BTreeMap::new();
    for c in cases.iter().filter(|c| joints.is_none_or(|js| js.contains(&c.joint))) {
        groups.entry((c.joint.clone(), c.formulation.clone())).or_default().push(c);
    }
    groups
}

/// Runs every case of a vectors file (optionally only some joints).
///
/// # Errors
/// A case lacks an input its joint or formulation needs.
pub fn run(doc: &VectorFile, joints: Option<&[String]>, time: bool) -> Result<Summary, String> {
    let mut summary = Summary::default();
    for ((joint, form), cases) in groups(&doc.cases, joints) {
        let group = match crate::joints::group(&joint, &form, &cases) {
            None => {
                summary.missing.push(format!("{joint}/{form}"));
                continue;
            }
            Some(g) => g?,
        };
        let outputs = group.run();
        let mut worst: f64 = 0.0;
        for (case, out) in cases.iter().zip(&outputs) {
            match case_error(case, out) {
                Ok(e) if e <= TOLERANCE => worst = worst.max(e),
                Ok(e) => {
                    worst = worst.max(e);
                    summary.failures.push(format!("{}: error {e:.1} ε·scale", out.id));
                }
                Err(msg) => summary.failures.push(format!("{}: {msg}", out.id)),
            }
        }
        if time {
            summary.timings.push((joint.clone(), form.clone(), group.time(), group.ops()));
        }
        summary.worst.insert((joint, form), (worst, cases.len()));
        summary.outputs.extend(outputs);
    }
    Ok(summary)
}

/// The `--emit` document: `{"cases": [{"id", "phi", "jacobian", "gamma"}, ..]}`.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct Emitted<'a> {
    /// What was computed, case by case.
    pub cases: &'a [Output],
}
