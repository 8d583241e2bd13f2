//! The conformance runner's logic: read cases, evaluate them through generated
//! code, apply the accuracy test of `shared/conformance/README.md`.

use std::collections::BTreeMap;
use std::hint::black_box;
use std::time::Instant;

use joint_runtime::nalgebra::{Vector3, Vector4};
use joint_runtime::{EulerBody, Joint, OmegaBody, RelativeState, TwoBodies};
use serde_json::Value;

/// `ε = 2⁻⁵²`.
pub const EPS: f64 = f64::EPSILON;
/// The test's tolerance in units of `ε · max(scale, floor)`.
pub const TOLERANCE: f64 = 256.0;

/// What the generated code computed for one case.
#[derive(Clone, Debug)]
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

/// Reads a case's inputs into a value.
pub trait FromJson: Sized {
    /// Parses `v`.
    fn from_json(v: &Value) -> Result<Self, String>;
}

fn numbers(v: &Value, what: &str) -> Result<Vec<f64>, String> {
    v.as_array()
        .ok_or_else(|| format!("`{what}` is not an array"))?
        .iter()
        .map(|x| x.as_f64().ok_or_else(|| format!("`{what}` holds a non-number")))
        .collect()
}

fn field<'a>(v: &'a Value, key: &str) -> Result<&'a Value, String> {
    v.get(key).ok_or_else(|| format!("missing `{key}`"))
}

impl FromJson for Vector3<f64> {
    fn from_json(v: &Value) -> Result<Self, String> {
        match numbers(v, "vector")?.as_slice() {
            [x, y, z] => Ok(Vector3::new(*x, *y, *z)),
            other => Err(format!("expected 3 numbers, found {}", other.len())),
        }
    }
}

impl FromJson for Vector4<f64> {
    fn from_json(v: &Value) -> Result<Self, String> {
        match numbers(v, "vector")?.as_slice() {
            [a, b, c, d] => Ok(Vector4::new(*a, *b, *c, *d)),
            other => Err(format!("expected 4 numbers, found {}", other.len())),
        }
    }
}

impl FromJson for joint_runtime::Drive {
    fn from_json(v: &Value) -> Result<Self, String> {
        let number = |k: &str| field(v, k)?.as_f64().ok_or_else(|| format!("`{k}` is not a number"));
        Ok(joint_runtime::Drive { value: number("value")?, rate: number("rate")?, accel: number("accel")? })
    }
}

impl FromJson for f64 {
    fn from_json(v: &Value) -> Result<Self, String> {
        v.as_f64().ok_or_else(|| "expected a number".to_string())
    }
}

impl FromJson for EulerBody<f64> {
    fn from_json(v: &Value) -> Result<Self, String> {
        Ok(EulerBody {
            r: FromJson::from_json(field(v, "r")?)?,
            p: FromJson::from_json(field(v, "p")?)?,
            rdot: FromJson::from_json(field(v, "rdot")?)?,
            pdot: FromJson::from_json(field(v, "pdot")?)?,
        })
    }
}

impl FromJson for OmegaBody<f64> {
    fn from_json(v: &Value) -> Result<Self, String> {
        Ok(OmegaBody {
            r: FromJson::from_json(field(v, "r")?)?,
            p: FromJson::from_json(field(v, "p")?)?,
            rdot: FromJson::from_json(field(v, "rdot")?)?,
            omega: FromJson::from_json(field(v, "omega")?)?,
        })
    }
}

impl<B: FromJson> FromJson for TwoBodies<B> {
    fn from_json(v: &Value) -> Result<Self, String> {
        Ok(TwoBodies::new(B::from_json(field(v, "body1")?)?, B::from_json(field(v, "body2")?)?))
    }
}

impl FromJson for RelativeState<f64> {
    fn from_json(v: &Value) -> Result<Self, String> {
        let v = field(v, "relative")?;
        Ok(RelativeState {
            delta: FromJson::from_json(field(v, "delta")?)?,
            p: FromJson::from_json(field(v, "p")?)?,
            delta_dot: FromJson::from_json(field(v, "delta_dot")?)?,
            omega: FromJson::from_json(field(v, "omega")?)?,
            t: 0.0,
        })
    }
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
    J: FromJson,
    J::State: FromJson,
{
    /// Parses the cases.
    pub fn new(cases: &[&Value]) -> Result<Self, String> {
        let cases = cases
            .iter()
            .map(|c| {
                let id = c.get("id").and_then(Value::as_str).unwrap_or("?").to_string();
                // The whole case: parameters, and a driver's time-function values.
                let joint = J::from_json(c).map_err(|e| format!("{id}: params: {e}"))?;
                let state = J::State::from_json(field(c, "state")?).map_err(|e| format!("{id}: state: {e}"))?;
                Ok((id, joint, state))
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

/// The worst error of one case in units of `ε · max(scale, floor)`, or `None`
/// when an entry whose scale is 0 is not exactly zero, or a shape is wrong.
pub fn case_error(case: &Value, got: &Output) -> Result<f64, String> {
    let expected = field(case, "expected")?;
    let scale = field(case, "scale")?;
    let mut worst: f64 = 0.0;
    let mut check = |what: &str, got: &[f64], want: &Value, scale: &Value, floor: f64| -> Result<(), String> {
        let (want, scale) = (numbers(want, what)?, numbers(scale, what)?);
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
    check("phi", &got.phi, field(expected, "phi")?, field(scale, "phi")?, 0.0)?;
    check("gamma", &got.gamma, field(expected, "gamma")?, field(scale, "gamma")?, 0.0)?;
    let (jw, js) = (
        field(expected, "jacobian")?.as_array().ok_or("jacobian is not an array")?,
        field(scale, "jacobian")?.as_array().ok_or("jacobian scale is not an array")?,
    );
    if jw.len() != got.jacobian.len() {
        return Err(format!("jacobian: {} rows, expected {}", got.jacobian.len(), jw.len()));
    }
    for (r, row) in got.jacobian.iter().enumerate() {
        let srow = numbers(&js[r], "jacobian scale")?;
        let floor = srow.iter().copied().fold(0.0, f64::max) / 64.0;
        check(&format!("jacobian[{r}]"), row, &jw[r], &js[r], floor)?;
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

/// Runs every case of a vectors file (optionally only some joints).
pub fn run(doc: &Value, joints: Option<&[String]>, time: bool) -> Result<Summary, String> {
    let cases = field(doc, "cases")?.as_array().ok_or("`cases` is not an array")?;
    let mut groups: BTreeMap<(String, String), Vec<&Value>> = BTreeMap::new();
    for c in cases {
        let joint = field(c, "joint")?.as_str().ok_or("`joint` is not a string")?.to_string();
        if joints.is_some_and(|js| !js.contains(&joint)) {
            continue;
        }
        let form = field(c, "formulation")?.as_str().ok_or("`formulation` is not a string")?.to_string();
        groups.entry((joint, form)).or_default().push(c);
    }
    let mut summary = Summary::default();
    for ((joint, form), cases) in groups {
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

/// The `--emit` document.
pub fn emit_json(outputs: &[Output]) -> Value {
    let cases: Vec<Value> = outputs
        .iter()
        .map(|o| serde_json::json!({"id": o.id, "phi": o.phi, "jacobian": o.jacobian, "gamma": o.gamma}))
        .collect();
    serde_json::json!({ "cases": cases })
}
