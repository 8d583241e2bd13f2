//! The joint catalogue: each joint is a list of parameters and a list of rows,
//! every row an expression over the four primitives of `CONVENTIONS.md` (and, for
//! drivers, a time function). This table is the only place joints are described;
//! no derivative appears here. User-written rows use the same [`Expr`] language.
//! Beside its rows a joint lists the person-friendly axes that may stand for
//! some of its parameters (`axis1 → f, g`), the vectors that must be
//! perpendicular, and its singularity measure, if it has one.

use std::borrow::Cow;
use std::sync::OnceLock;

/// Where a parameter lives and what it means.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Role {
    /// A direction fixed in body 1 or 2 (index 0 or 1); a constant must not be zero.
    Axis(usize),
    /// A point fixed in body 1 or 2.
    Point(usize),
    /// A scalar (a length, an angle).
    Scalar,
    /// A time function θ(t) (a field whose type implements `TimeFunction`).
    Time,
}

/// A parameter of a joint.
#[derive(Clone, Debug)]
pub struct Param {
    /// The name in the DSL and in `CONVENTIONS.md` (owned for user-declared
    /// parameters).
    pub name: Cow<'static, str>,
    /// Its role.
    pub role: Role,
}

/// A scalar expression of a row.
#[derive(Clone, Debug, PartialEq)]
pub enum Expr {
    /// A number.
    Num(f64),
    /// A scalar parameter.
    Scalar(String),
    /// The value of a time function.
    Time(String),
    /// `a'ᵀ A1ᵀ A2 b'` (dot-1) with `a'` in B1, `b'` in B2.
    Dot1(String, String),
    /// `a'ᵀ A1ᵀ d` (dot-2) with `a'` in B1.
    Dot2(String),
    /// `u · v`.
    Dot(Box<VExpr>, Box<VExpr>),
    /// `a + b`.
    Add(Box<Expr>, Box<Expr>),
    /// `a − b`.
    Sub(Box<Expr>, Box<Expr>),
    /// `a · b`.
    Mul(Box<Expr>, Box<Expr>),
    /// `a / b` (singularity measures only: rows stay polynomial).
    Div(Box<Expr>, Box<Expr>),
    /// `−a`.
    Neg(Box<Expr>),
    /// `sin a`.
    Sin(Box<Expr>),
    /// `cos a`.
    Cos(Box<Expr>),
}

/// A vector expression, in the reference frame's components.
#[derive(Clone, Debug, PartialEq)]
pub enum VExpr {
    /// A body-fixed direction, rotated into the reference frame.
    Axis(String),
    /// A body-fixed point's position.
    Point(String),
    /// A body-fixed vector in its own body's components (not rotated).
    Local(String),
    /// The separation `d` of the joint points `rho1`, `rho2`.
    Separation,
    /// `u + v`.
    Add(Box<VExpr>, Box<VExpr>),
    /// `u − v`.
    Sub(Box<VExpr>, Box<VExpr>),
    /// `u × v`.
    Cross(Box<VExpr>, Box<VExpr>),
    /// `s · u`.
    Scale(Box<Expr>, Box<VExpr>),
    /// `−u`.
    Neg(Box<VExpr>),
}

/// One row, or the block of three rows of the spherical primitive.
#[derive(Clone, Debug, PartialEq)]
pub enum Row {
    /// `d = 0`: three rows.
    Spherical,
    /// One scalar row.
    Scalar(Expr),
    /// A vector equal to zero: three rows (user-written rows only).
    Vector(VExpr),
}

/// Which vector a derived parameter takes from its source axis `a`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Part {
    /// `a` itself.
    Axis,
    /// `b` of `perpendicular_pair(a)`.
    First,
    /// `c` of `perpendicular_pair(a)`.
    Second,
}

impl Part {
    /// The field of `joint_runtime::AxisFrame` that holds this part.
    pub fn field(self) -> &'static str {
        match self {
            Part::Axis => "axis",
            Part::First => "b",
            Part::Second => "c",
        }
    }
}

/// Parameters a person would give instead of others: an axis from which
/// perpendicular vectors are derived (at compile time for a constant, by
/// `joint_runtime::AxisFrame::new` once for a field).
#[derive(Clone, Debug)]
pub struct Derivation {
    /// The axis a person gives (`axis1`, `axis2`, `d`).
    pub source: &'static str,
    /// The body it is fixed in.
    pub body: usize,
    /// The joint's parameters it stands for.
    pub outputs: Vec<(&'static str, Part)>,
}

/// A joint kind.
#[derive(Clone, Debug)]
pub struct JointKind {
    /// The name in the DSL.
    pub name: &'static str,
    /// Its parameters.
    pub params: Vec<Param>,
    /// Its rows, in order.
    pub rows: Vec<Row>,
    /// Axes that may be given instead of some parameters.
    pub derivations: Vec<Derivation>,
    /// Pairs of same-body vectors that must be perpendicular (checked for constants).
    pub perpendicular: Vec<(&'static str, &'static str)>,
    /// A measure of the distance from the configurations where the rows lose
    /// rank: 1 at the nominal geometry, 0 at the singularity.
    pub singularity: Option<Singularity>,
}

/// A generated measure of how far a joint is from losing rank.
#[derive(Clone, Debug)]
pub struct Singularity {
    /// The measure.
    pub measure: Expr,
    /// The configurations where it is zero, for the docs.
    pub zero_when: &'static str,
}

impl JointKind {
    /// The number of scalar rows (a vector row is three).
    pub fn row_count(&self) -> usize {
        self.rows.iter().map(|r| if matches!(r, Row::Scalar(_)) { 1 } else { 3 }).sum()
    }

    /// The parameter called `name`.
    pub fn param(&self, name: &str) -> Option<&Param> {
        self.params.iter().find(|p| p.name == name)
    }

    /// The derivation whose source is `name`.
    pub fn derivation(&self, name: &str) -> Option<&Derivation> {
        self.derivations.iter().find(|d| d.source == name)
    }

    /// The derivation that can stand for parameter `name`.
    pub fn derived_from(&self, name: &str) -> Option<&Derivation> {
        self.derivations.iter().find(|d| d.outputs.iter().any(|(o, _)| *o == name))
    }
}

fn axis(name: &'static str, body: usize) -> Param {
    Param { name: Cow::Borrowed(name), role: Role::Axis(body) }
}

fn points() -> [Param; 2] {
    [
        Param { name: Cow::Borrowed("rho1"), role: Role::Point(0) },
        Param { name: Cow::Borrowed("rho2"), role: Role::Point(1) },
    ]
}

/// `dot1(a, b)`.
pub fn dot1(a: &str, b: &str) -> Expr {
    Expr::Dot1(a.into(), b.into())
}

/// `dot2(a)`.
pub fn dot2(a: &str) -> Expr {
    Expr::Dot2(a.into())
}

/// `dᵀd − L²`.
pub fn distance(length: &str) -> Expr {
    let d = || Box::new(VExpr::Separation);
    let l = || Box::new(Expr::Scalar(length.into()));
    Expr::Sub(Box::new(Expr::Dot(d(), d())), Box::new(Expr::Mul(l(), l())))
}

fn kind(name: &'static str, params: Vec<Param>, rows: Vec<Row>) -> JointKind {
    JointKind { name, params, rows, derivations: Vec::new(), perpendicular: Vec::new(), singularity: None }
}

/// `source` (fixed in `body`) stands for `outputs`.
fn derive(source: &'static str, body: usize, outputs: &[(&'static str, Part)]) -> Derivation {
    Derivation { source, body, outputs: outputs.to_vec() }
}

/// Adds the person-friendly axes and the perpendicularity checks of a joint.
fn axes(mut k: JointKind, derivations: Vec<Derivation>, perpendicular: &[(&'static str, &'static str)]) -> JointKind {
    k.derivations = derivations;
    k.perpendicular = perpendicular.to_vec();
    k
}

fn b<T>(x: T) -> Box<T> {
    Box::new(x)
}

fn norm_sq(v: VExpr) -> Expr {
    Expr::Dot(b(v.clone()), b(v))
}

fn cross(u: VExpr, v: VExpr) -> VExpr {
    VExpr::Cross(b(u), b(v))
}

fn ax(n: &str) -> VExpr {
    VExpr::Axis(n.into())
}

fn local(n: &str) -> VExpr {
    VExpr::Local(n.into())
}

/// `|a × b|² / (|a|² |b|²)`: the squared sine of the angle between the axes
/// (dot-1 rows lose rank when the axes become parallel).
fn sine_sq(a: &str, c: &str) -> Singularity {
    let num = norm_sq(cross(ax(a), ax(c)));
    let den = Expr::Mul(b(norm_sq(local(a))), b(norm_sq(local(c))));
    Singularity {
        measure: Expr::Div(b(num), b(den)),
        zero_when: "the two axes become parallel, where the dot-1 row's gradient vanishes; an assembled joint keeps \
                    them perpendicular, so a Cardan shaft's 90° bend is a singularity of the mechanism (its system \
                    Jacobian), which the scene analyses detect, not of these rows",
    }
}

/// `(h · (f × g))² / (|h|² |f × g|²)`: the squared cosine between `h` and the
/// normal of `f, g` (the two dot-1 rows lose rank when `h` falls into their plane).
fn axis_alignment() -> Singularity {
    let fg = || cross(ax("f"), ax("g"));
    let t = Expr::Dot(b(ax("h")), b(fg()));
    let num = Expr::Mul(b(t.clone()), b(t));
    let den = Expr::Mul(b(norm_sq(local("h"))), b(norm_sq(cross(local("f"), local("g")))));
    Singularity {
        measure: Expr::Div(b(num), b(den)),
        zero_when: "`h` lies in the plane of `f` and `g` (the body-2 axis turned 90° away from the joint axis)",
    }
}

/// `det[f × h, g × h, f × k]² / (|f|⁴ |g|² |h|⁴ |k|²)`: the rotational rows of a
/// joint that locks all three rotations.
fn rotation_lock() -> Singularity {
    let (fh, gh, fk) = (cross(ax("f"), ax("h")), cross(ax("g"), ax("h")), cross(ax("f"), ax("k")));
    let det = Expr::Dot(b(fh), b(cross(gh, fk)));
    let num = Expr::Mul(b(det.clone()), b(det));
    let (f2, g2, h2, k2) = (norm_sq(local("f")), norm_sq(local("g")), norm_sq(local("h")), norm_sq(local("k")));
    let den = Expr::Mul(
        b(Expr::Mul(b(Expr::Mul(b(f2.clone()), b(f2))), b(g2))),
        b(Expr::Mul(b(Expr::Mul(b(h2.clone()), b(h2))), b(k2))),
    );
    Singularity {
        measure: Expr::Div(b(num), b(den)),
        zero_when: "the three rotational rows `f×h, g×h, f×k` become linearly dependent (a half-turn misalignment)",
    }
}

/// `|d|² / L²`: the distance row's gradient `2 dᵀ(…)` vanishes with `d`.
fn separation_over_length(length: &str) -> Singularity {
    let l = || b(Expr::Scalar(length.into()));
    Singularity {
        measure: Expr::Div(b(norm_sq(VExpr::Separation)), b(Expr::Mul(l(), l()))),
        zero_when: "the two points coincide (`d = 0`: the row's gradient vanishes)",
    }
}

fn with(mut k: JointKind, s: Singularity) -> JointKind {
    k.singularity = Some(s);
    k
}

fn with_points(mut params: Vec<Param>) -> Vec<Param> {
    params.extend(points());
    params
}

fn build() -> Vec<JointKind> {
    use Row::{Scalar as S, Spherical};
    let time = |name: &'static str| Param { name: Cow::Borrowed(name), role: Role::Time };
    // Rotational driver: sin(angle − θ) = (g·k) cos θ − (f·k) sin θ, the angle of
    // `k` measured from `f` towards `g`.
    let theta = || Box::new(Expr::Time("theta".into()));
    let rotational = Expr::Sub(
        Box::new(Expr::Mul(Box::new(dot1("g", "k")), Box::new(Expr::Cos(theta())))),
        Box::new(Expr::Mul(Box::new(dot1("f", "k")), Box::new(Expr::Sin(theta())))),
    );
    let translational = Expr::Sub(Box::new(dot2("h")), Box::new(Expr::Time("x".into())));
    let joints = vec![
        kind("spherical", points().to_vec(), vec![Spherical]),
        with(
            kind("universal", with_points(vec![axis("s", 0), axis("h", 1)]), vec![Spherical, S(dot1("s", "h"))]),
            sine_sq("s", "h"),
        ),
        with(
            kind(
                "universal_translational",
                with_points(vec![axis("s", 0), axis("h", 1), axis("b", 0), axis("c", 0)]),
                vec![S(dot2("b")), S(dot2("c")), S(dot1("s", "h"))],
            ),
            sine_sq("s", "h"),
        ),
        with(
            kind(
                "revolute",
                with_points(vec![axis("f", 0), axis("g", 0), axis("h", 1)]),
                vec![Spherical, S(dot1("f", "h")), S(dot1("g", "h"))],
            ),
            axis_alignment(),
        ),
        with(
            kind(
                "cylindrical",
                with_points(vec![axis("f", 0), axis("g", 0), axis("h", 1)]),
                vec![S(dot1("f", "h")), S(dot1("g", "h")), S(dot2("f")), S(dot2("g"))],
            ),
            axis_alignment(),
        ),
        with(
            kind(
                "translational",
                with_points(vec![axis("f", 0), axis("g", 0), axis("h", 1), axis("k", 1)]),
                vec![S(dot1("f", "h")), S(dot1("g", "h")), S(dot2("f")), S(dot2("g")), S(dot1("f", "k"))],
            ),
            rotation_lock(),
        ),
        with(
            kind(
                "fixed",
                with_points(vec![axis("f", 0), axis("g", 0), axis("h", 1), axis("k", 1)]),
                vec![Spherical, S(dot1("f", "h")), S(dot1("g", "h")), S(dot1("f", "k"))],
            ),
            rotation_lock(),
        ),
        with(
            kind(
                "planar",
                with_points(vec![axis("f", 0), axis("g", 0), axis("n", 0), axis("h", 1)]),
                vec![S(dot1("f", "h")), S(dot1("g", "h")), S(dot2("n"))],
            ),
            axis_alignment(),
        ),
        kind("point_on_line", with_points(vec![axis("f", 0), axis("g", 0)]), vec![S(dot2("f")), S(dot2("g"))]),
        kind("point_in_plane", with_points(vec![axis("n", 0)]), vec![S(dot2("n"))]),
        with(
            kind(
                "parallel",
                vec![axis("f", 0), axis("g", 0), axis("h", 1)],
                vec![S(dot1("f", "h")), S(dot1("g", "h"))],
            ),
            axis_alignment(),
        ),
        with(kind("perpendicular", vec![axis("s", 0), axis("h", 1)], vec![S(dot1("s", "h"))]), sine_sq("s", "h")),
        with(
            kind(
                "distance",
                with_points(vec![Param { name: Cow::Borrowed("length"), role: Role::Scalar }]),
                vec![S(distance("length"))],
            ),
            separation_over_length("length"),
        ),
        kind("rotational_driver", vec![axis("f", 0), axis("g", 0), axis("k", 1), time("theta")], vec![S(rotational)]),
        kind("translational_driver", with_points(vec![axis("h", 0), time("x")]), vec![S(translational)]),
    ];
    joints.into_iter().map(person_axes).collect()
}

/// The axes a person may give instead of a joint's vectors, and the pairs of
/// its vectors that must be perpendicular.
fn person_axes(k: JointKind) -> JointKind {
    use Part::{Axis, First, Second};
    // The axis of a joint in B1 gives the perpendicular pair `f, g`; in B2 it is
    // `h` itself, and `k` is the second of its pair, so that in the configuration
    // where both bodies' frames coincide `f ⟂ k` (and a driver's angle is 0).
    let pair1 = || derive("axis1", 0, &[("f", First), ("g", Second)]);
    let axis2 = || derive("axis2", 1, &[("h", Axis)]);
    let fg: &[(&'static str, &'static str)] = &[("f", "g")];
    match k.name {
        "universal_translational" => axes(k, vec![derive("d", 0, &[("b", First), ("c", Second)])], &[("b", "c")]),
        "revolute" | "cylindrical" | "parallel" => axes(k, vec![pair1(), axis2()], fg),
        "point_on_line" => axes(k, vec![pair1()], fg),
        "translational" | "fixed" => {
            axes(k, vec![pair1(), derive("axis2", 1, &[("h", Axis), ("k", Second)])], &[("f", "g"), ("h", "k")])
        }
        "planar" => axes(
            k,
            vec![derive("axis1", 0, &[("f", First), ("g", Second), ("n", Axis)]), axis2()],
            &[("f", "g"), ("f", "n"), ("g", "n")],
        ),
        "rotational_driver" => axes(k, vec![pair1(), derive("axis2", 1, &[("k", First)])], fg),
        _ => k,
    }
}

/// Every joint the derive knows.
pub fn catalogue() -> &'static [JointKind] {
    static CATALOGUE: OnceLock<Vec<JointKind>> = OnceLock::new();
    CATALOGUE.get_or_init(build)
}

/// The joint called `name`.
pub fn lookup(name: &str) -> Option<&'static JointKind> {
    catalogue().iter().find(|k| k.name == name)
}

/// The names, for error messages: "`spherical`, `universal`, ...".
pub fn names() -> String {
    catalogue().iter().map(|k| format!("`{}`", k.name)).collect::<Vec<_>>().join(", ")
}
