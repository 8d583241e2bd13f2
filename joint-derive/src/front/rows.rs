//! User-written rows: `#[joint(rows(...))]` parsed as Rust expressions and
//! checked into the row language of [`crate::joints`], keeping each row's span.
//!
//! ```text
//! rows(spherical, dot1(s, h))            primitives
//! rows(dot(s, h) - cos(alpha))           a constant angle between two axes
//! rows(norm2(d) - l * l)                 a cable whose length l(t) is a time function
//! rows(cross(s, h))                      a vector row: three scalar rows
//! ```
//! Names are the joint's parameters (vectors of B1 or B2, points, scalars, time
//! functions) and `d`, the separation of `rho1` and `rho2`. Functions: `dot`,
//! `cross`, `norm2`, `sin`, `cos` (of parameters and time functions),
//! `dot1(a, b)`, `dot2(a)`, `distance(L)`, and `spherical` as a whole row.

use proc_macro2::Span;
use syn::spanned::Spanned;

use crate::joints::{Expr, Role, Row, VExpr};

/// A checked expression: a number or a vector.
enum Typed {
    S(Expr),
    V(VExpr),
}

/// What a name means in a row.
pub struct Names<'a> {
    /// The role of a parameter, if `name` is one.
    pub role: &'a dyn Fn(&str) -> Option<Role>,
    /// Every parameter name, for "did you mean" and the list of what is expected.
    pub all: &'a [&'a str],
}

/// The functions of the row language.
const FUNCTIONS: [&str; 8] = ["dot", "cross", "norm2", "sin", "cos", "dot1", "dot2", "distance"];

/// What a parameter of `role` is, for messages: "an axis of body 2".
fn describe(role: Option<Role>) -> String {
    match role {
        Some(Role::Axis(b)) => format!("an axis of body {}", b + 1),
        Some(Role::Point(b)) => format!("a point of body {}", b + 1),
        Some(Role::Scalar) => "a number".into(),
        Some(Role::Time) => "a time function".into(),
        None => "not a parameter of this joint".into(),
    }
}

fn err<T>(span: Span, message: impl std::fmt::Display) -> syn::Result<T> {
    Err(syn::Error::new(span, message))
}

fn b<T>(x: T) -> Box<T> {
    Box::new(x)
}

/// Checks one row; a vector-valued row stands for its three components.
pub fn row(e: &syn::Expr, names: &Names) -> syn::Result<Row> {
    if let syn::Expr::Path(p) = e
        && p.path.is_ident("spherical")
    {
        return Ok(Row::Spherical);
    }
    Ok(match check(e, names)? {
        // A row of numbers, scalars and time functions only: its Jacobian is zero.
        Typed::S(s) if constant_in_space(&s) => {
            return err(
                e.span(),
                "this row does not depend on the bodies: it constrains nothing; expected a row over their axes, \
                 points or `d`, as in `dot(s, h) - cos(alpha)`",
            );
        }
        Typed::S(s) => Row::Scalar(s),
        Typed::V(v) => Row::Vector(v),
    })
}

/// An argument that must be a number; `form` is the call as it should be written.
fn scalar(e: &syn::Expr, names: &Names, form: &str) -> syn::Result<Expr> {
    match check(e, names)? {
        Typed::S(s) => Ok(s),
        Typed::V(_) => {
            err(e.span(), format!("`{}` takes a number here, found a vector; expected `{form}`", function(form)))
        }
    }
}

/// An argument that must be a vector; `form` is the call as it should be written.
fn vector(e: &syn::Expr, names: &Names, form: &str) -> syn::Result<VExpr> {
    match check(e, names)? {
        Typed::V(v) => Ok(v),
        Typed::S(_) => {
            err(e.span(), format!("`{}` takes a vector here, found a number; expected `{form}`", function(form)))
        }
    }
}

/// `dot` of `dot(u, v)`.
fn function(form: &str) -> &str {
    form.split('(').next().unwrap_or(form)
}

/// The name `e` is, if it is a single identifier.
fn ident(e: &syn::Expr) -> Option<&syn::Ident> {
    match e {
        syn::Expr::Path(p) => p.path.get_ident(),
        _ => None,
    }
}

/// A name that must be an axis of `body` (for `dot1`, `dot2`); `form` is the call
/// as it should be written.
fn axis_of(e: &syn::Expr, names: &Names, body: usize, form: &str) -> syn::Result<String> {
    let want = format!("an axis of body {}", body + 1);
    let Some(id) = ident(e) else {
        return err(e.span(), format!("expected the name of {want} here, as in `{form}`"));
    };
    match (names.role)(&id.to_string()) {
        Some(Role::Axis(b)) if b == body => Ok(id.to_string()),
        role => err(id.span(), format!("`{id}` is {}, expected {want} here, as in `{form}`", describe(role))),
    }
}

/// Whether an expression is made of numbers, scalars and time functions only
/// (what `sin` and `cos` may take).
fn constant_in_space(e: &Expr) -> bool {
    match e {
        Expr::Num(_) | Expr::Scalar(_) | Expr::Time(_) => true,
        Expr::Add(a, c) | Expr::Sub(a, c) | Expr::Mul(a, c) | Expr::Div(a, c) => {
            constant_in_space(a) && constant_in_space(c)
        }
        Expr::Neg(a) | Expr::Sin(a) | Expr::Cos(a) => constant_in_space(a),
        Expr::Dot1(..) | Expr::Dot2(_) | Expr::Dot(..) => false,
    }
}

fn args(call: &syn::ExprCall, n: usize, form: &str) -> syn::Result<Vec<syn::Expr>> {
    let a: Vec<syn::Expr> = call.args.iter().cloned().collect();
    if a.len() != n {
        let span = call.paren_token.span.join();
        return err(
            span,
            format!(
                "`{}` takes {n} argument{}, found {}; expected `{form}`",
                function(form),
                if n == 1 { "" } else { "s" },
                a.len()
            ),
        );
    }
    Ok(a)
}

fn check(e: &syn::Expr, names: &Names) -> syn::Result<Typed> {
    use syn::{Expr as E, UnOp};
    match e {
        E::Paren(p) => check(&p.expr, names),
        E::Group(g) => check(&g.expr, names),
        E::Lit(l) => match &l.lit {
            syn::Lit::Int(i) => Ok(Typed::S(Expr::Num(i.base10_parse::<f64>()?))),
            syn::Lit::Float(f) => Ok(Typed::S(Expr::Num(f.base10_parse::<f64>()?))),
            _ => err(l.span(), "expected a number, a parameter or a function such as `dot(u, v)`"),
        },
        E::Path(p) => check_path(p, names),
        E::Unary(u) if matches!(u.op, UnOp::Neg(_)) => Ok(match check(&u.expr, names)? {
            Typed::S(s) => Typed::S(Expr::Neg(b(s))),
            Typed::V(v) => Typed::V(VExpr::Neg(b(v))),
        }),
        E::Binary(bin) => check_binary(bin, names),
        E::Call(call) => check_call(call, names),
        _ => err(e.span(), "expected a row: numbers, parameters, `d`, `+ - *` and functions such as `dot(u, v)`"),
    }
}

/// A name: a parameter (by its role) or `d`.
fn check_path(p: &syn::ExprPath, names: &Names) -> syn::Result<Typed> {
    let Some(id) = p.path.get_ident() else {
        return err(p.span(), "expected a parameter name, `d`, or a function such as `dot(u, v)`");
    };
    let name = id.to_string();
    match (names.role)(&name) {
        Some(Role::Axis(_)) => Ok(Typed::V(VExpr::Axis(name))),
        Some(Role::Point(_)) => Ok(Typed::V(VExpr::Point(name))),
        Some(Role::Scalar) => Ok(Typed::S(Expr::Scalar(name))),
        Some(Role::Time) => Ok(Typed::S(Expr::Time(name))),
        None if name == "d" => Ok(Typed::V(VExpr::Separation)),
        None if name == "spherical" => err(
            id.span(),
            "`spherical` is a whole row (three rows); expected it on its own, as in `rows(spherical, dot1(s, h))`",
        ),
        None => {
            let all: Vec<String> = names.all.iter().map(|n| format!("`{n}`")).collect();
            err(
                id.span(),
                format!(
                    "unknown name `{name}` in a row{}; expected a parameter of this joint ({}) or `d`",
                    super::names::did_you_mean(&name, names.all.iter().copied().chain(["d"])),
                    all.join(", ")
                ),
            )
        }
    }
}

/// `+`, `-`, `*` on numbers and vectors; no division.
fn check_binary(bin: &syn::ExprBinary, names: &Names) -> syn::Result<Typed> {
    use syn::BinOp;
    let (l, r) = (check(&bin.left, names)?, check(&bin.right, names)?);
    match (&bin.op, l, r) {
        (BinOp::Add(_), Typed::S(x), Typed::S(y)) => Ok(Typed::S(Expr::Add(b(x), b(y)))),
        (BinOp::Sub(_), Typed::S(x), Typed::S(y)) => Ok(Typed::S(Expr::Sub(b(x), b(y)))),
        (BinOp::Mul(_), Typed::S(x), Typed::S(y)) => Ok(Typed::S(Expr::Mul(b(x), b(y)))),
        (BinOp::Add(_), Typed::V(x), Typed::V(y)) => Ok(Typed::V(VExpr::Add(b(x), b(y)))),
        (BinOp::Sub(_), Typed::V(x), Typed::V(y)) => Ok(Typed::V(VExpr::Sub(b(x), b(y)))),
        (BinOp::Mul(_), Typed::S(x), Typed::V(y)) | (BinOp::Mul(_), Typed::V(y), Typed::S(x)) => {
            Ok(Typed::V(VExpr::Scale(b(x), b(y))))
        }
        (BinOp::Mul(_), Typed::V(_), Typed::V(_)) => {
            err(bin.op.span(), "cannot multiply two vectors; expected `dot(u, v)` or `cross(u, v)`")
        }
        (BinOp::Add(_) | BinOp::Sub(_), l, _) => {
            let (verb, side) = if matches!(bin.op, BinOp::Add(_)) { ("add", "to") } else { ("subtract", "from") };
            let (what, other) =
                if matches!(l, Typed::V(_)) { ("a number", "a vector") } else { ("a vector", "a number") };
            err(
                bin.op.span(),
                format!(
                    "cannot {verb} {what} {side} {other}; expected both sides vectors or both numbers, as in `dot(s, h) - 1`"
                ),
            )
        }
        (BinOp::Div(_), ..) => err(
            bin.op.span(),
            "rows take no division (Φ stays polynomial); expected the row multiplied out, as in `a - b * c` for `a / b - c`",
        ),
        _ => err(bin.op.span(), "unknown operator in a row; expected `+`, `-` or `*`"),
    }
}

/// A function of the row language.
fn check_call(call: &syn::ExprCall, names: &Names) -> syn::Result<Typed> {
    let Some(fname) = ident(&call.func) else {
        return err(call.func.span(), "expected a function name, as in `dot(s, h)`");
    };
    match fname.to_string().as_str() {
        "dot" => {
            let a = args(call, 2, "dot(u, v)")?;
            let (u, v) = (vector(&a[0], names, "dot(u, v)")?, vector(&a[1], names, "dot(u, v)")?);
            Ok(Typed::S(Expr::Dot(b(u), b(v))))
        }
        "cross" => {
            let a = args(call, 2, "cross(u, v)")?;
            let (u, v) = (vector(&a[0], names, "cross(u, v)")?, vector(&a[1], names, "cross(u, v)")?);
            Ok(Typed::V(VExpr::Cross(b(u), b(v))))
        }
        "norm2" => {
            let a = args(call, 1, "norm2(u)")?;
            let u = vector(&a[0], names, "norm2(u)")?;
            Ok(Typed::S(Expr::Dot(b(u.clone()), b(u))))
        }
        "sin" | "cos" => {
            let form = format!("{fname}(alpha)");
            let a = args(call, 1, &form)?;
            let x = scalar(&a[0], names, &form)?;
            if !constant_in_space(&x) {
                return err(
                    a[0].span(),
                    format!(
                        "`{fname}` of the bodies' coordinates is not allowed (Φ stays polynomial in them); \
                         expected numbers, scalars and time functions only, as in `{form}`"
                    ),
                );
            }
            Ok(Typed::S(if fname == "sin" { Expr::Sin(b(x)) } else { Expr::Cos(b(x)) }))
        }
        "dot1" => {
            let a = args(call, 2, "dot1(s, h)")?;
            // Both arguments in the wrong order: one mistake, one message.
            if let (Some(x), Some(y)) = (ident(&a[0]), ident(&a[1]))
                && (names.role)(&x.to_string()) == Some(Role::Axis(1))
                && (names.role)(&y.to_string()) == Some(Role::Axis(0))
            {
                return err(
                    call.paren_token.span.join(),
                    format!(
                        "the arguments of `dot1` are swapped: `{x}` is an axis of body 2 and `{y}` of body 1; \
                         expected `dot1({y}, {x})`"
                    ),
                );
            }
            let (x, y) = (axis_of(&a[0], names, 0, "dot1(s, h)")?, axis_of(&a[1], names, 1, "dot1(s, h)")?);
            Ok(Typed::S(Expr::Dot1(x, y)))
        }
        "dot2" => {
            let a = args(call, 1, "dot2(b)")?;
            Ok(Typed::S(Expr::Dot2(axis_of(&a[0], names, 0, "dot2(b)")?)))
        }
        "distance" => {
            let a = args(call, 1, "distance(length)")?;
            let l = scalar(&a[0], names, "distance(length)")?;
            let d = || b(VExpr::Separation);
            Ok(Typed::S(Expr::Sub(b(Expr::Dot(d(), d())), b(Expr::Mul(b(l.clone()), b(l))))))
        }
        other => err(
            fname.span(),
            format!(
                "unknown function `{other}`{}; expected one of {}",
                super::names::did_you_mean(other, FUNCTIONS),
                FUNCTIONS.map(|f| format!("`{f}`")).join(", ")
            ),
        ),
    }
}

/// Whether a row reads the separation `d` (and so needs `rho1`, `rho2`).
pub fn uses_separation(r: &Row) -> bool {
    fn e(x: &Expr) -> bool {
        match x {
            Expr::Dot2(_) => true,
            Expr::Dot(u, v) => ve(u) || ve(v),
            Expr::Add(a, c) | Expr::Sub(a, c) | Expr::Mul(a, c) | Expr::Div(a, c) => e(a) || e(c),
            Expr::Neg(a) | Expr::Sin(a) | Expr::Cos(a) => e(a),
            Expr::Num(_) | Expr::Scalar(_) | Expr::Time(_) | Expr::Dot1(..) => false,
        }
    }
    fn ve(v: &VExpr) -> bool {
        match v {
            VExpr::Separation => true,
            VExpr::Add(a, c) | VExpr::Sub(a, c) | VExpr::Cross(a, c) => ve(a) || ve(c),
            VExpr::Scale(s, a) => e(s) || ve(a),
            VExpr::Neg(a) => ve(a),
            VExpr::Axis(_) | VExpr::Point(_) | VExpr::Local(_) => false,
        }
    }
    match r {
        Row::Spherical => true,
        Row::Scalar(x) => e(x),
        Row::Vector(v) => ve(v),
    }
}
