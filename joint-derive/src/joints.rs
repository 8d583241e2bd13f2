//! The joint catalogue: each joint is a list of parameters and a list of rows,
//! every row one of the four primitives of `CONVENTIONS.md`. This table is the
//! only place joints are described; no derivative appears here.

/// Where a parameter lives and what it means.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Role {
    /// A direction fixed in body 1 or 2 (index 0 or 1); a constant must not be zero.
    Axis(usize),
    /// A point fixed in body 1 or 2.
    Point(usize),
    /// A scalar (a length).
    Scalar,
}

/// A parameter of a joint.
#[derive(Clone, Copy, Debug)]
pub struct Param {
    /// The name in the DSL and in `CONVENTIONS.md`.
    pub name: &'static str,
    /// Its role.
    pub role: Role,
}

/// One row (or block of rows) of a joint.
#[derive(Clone, Copy, Debug)]
pub enum Primitive {
    /// `d = 0`: three rows.
    Spherical,
    /// `a'ᵀ A1ᵀ A2 b' = 0` with `a'` in B1, `b'` in B2.
    Dot1(&'static str, &'static str),
    /// `a'ᵀ A1ᵀ d = 0` with `a'` in B1.
    Dot2(&'static str),
    /// `dᵀ d − L² = 0`.
    Distance(&'static str),
}

/// A joint kind.
#[derive(Debug)]
pub struct JointKind {
    /// The name in the DSL.
    pub name: &'static str,
    /// Its parameters.
    pub params: &'static [Param],
    /// Its rows, in order.
    pub rows: &'static [Primitive],
}

impl JointKind {
    /// The parameter called `name`.
    pub fn param(&self, name: &str) -> Option<&'static Param> {
        self.params.iter().find(|p| p.name == name)
    }
}

const fn axis(name: &'static str, body: usize) -> Param {
    Param { name, role: Role::Axis(body) }
}

const RHO1: Param = Param { name: "rho1", role: Role::Point(0) };
const RHO2: Param = Param { name: "rho2", role: Role::Point(1) };

use Primitive::{Distance, Dot1, Dot2, Spherical};

/// Every joint the derive knows.
pub const CATALOGUE: &[JointKind] = &[
    JointKind { name: "spherical", params: &[RHO1, RHO2], rows: &[Spherical] },
    JointKind {
        name: "universal",
        params: &[axis("s", 0), axis("h", 1), RHO1, RHO2],
        rows: &[Spherical, Dot1("s", "h")],
    },
    JointKind {
        name: "universal_translational",
        params: &[axis("s", 0), axis("h", 1), axis("b", 0), axis("c", 0), RHO1, RHO2],
        rows: &[Dot2("b"), Dot2("c"), Dot1("s", "h")],
    },
    JointKind {
        name: "revolute",
        params: &[axis("f", 0), axis("g", 0), axis("h", 1), RHO1, RHO2],
        rows: &[Spherical, Dot1("f", "h"), Dot1("g", "h")],
    },
    JointKind {
        name: "cylindrical",
        params: &[axis("f", 0), axis("g", 0), axis("h", 1), RHO1, RHO2],
        rows: &[Dot1("f", "h"), Dot1("g", "h"), Dot2("f"), Dot2("g")],
    },
    JointKind {
        name: "translational",
        params: &[axis("f", 0), axis("g", 0), axis("h", 1), axis("k", 1), RHO1, RHO2],
        rows: &[Dot1("f", "h"), Dot1("g", "h"), Dot2("f"), Dot2("g"), Dot1("f", "k")],
    },
    JointKind {
        name: "fixed",
        params: &[axis("f", 0), axis("g", 0), axis("h", 1), axis("k", 1), RHO1, RHO2],
        rows: &[Spherical, Dot1("f", "h"), Dot1("g", "h"), Dot1("f", "k")],
    },
    JointKind {
        name: "planar",
        params: &[axis("f", 0), axis("g", 0), axis("n", 0), axis("h", 1), RHO1, RHO2],
        rows: &[Dot1("f", "h"), Dot1("g", "h"), Dot2("n")],
    },
    JointKind {
        name: "point_on_line",
        params: &[axis("f", 0), axis("g", 0), RHO1, RHO2],
        rows: &[Dot2("f"), Dot2("g")],
    },
    JointKind { name: "point_in_plane", params: &[axis("n", 0), RHO1, RHO2], rows: &[Dot2("n")] },
    JointKind {
        name: "parallel",
        params: &[axis("f", 0), axis("g", 0), axis("h", 1)],
        rows: &[Dot1("f", "h"), Dot1("g", "h")],
    },
    JointKind { name: "perpendicular", params: &[axis("s", 0), axis("h", 1)], rows: &[Dot1("s", "h")] },
    JointKind {
        name: "distance",
        params: &[RHO1, RHO2, Param { name: "length", role: Role::Scalar }],
        rows: &[Distance("length")],
    },
];

/// The joint called `name`.
pub fn lookup(name: &str) -> Option<&'static JointKind> {
    CATALOGUE.iter().find(|k| k.name == name)
}

/// The names, for error messages: "`spherical`, `universal`, ...".
pub fn names() -> String {
    CATALOGUE.iter().map(|k| format!("`{}`", k.name)).collect::<Vec<_>>().join(", ")
}
