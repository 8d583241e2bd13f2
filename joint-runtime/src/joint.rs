//! The trait every generated joint implements.

use nalgebra::{SMatrix, SVector};

/// The five sets of coordinates a joint's constraint can be written against
/// (`CONVENTIONS.md`, "Formulations").
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
pub enum Formulation {
    /// `r, p` with velocities `ṙ, ṗ`: 7 columns per body, J = ∂Φ/∂q.
    Euler,
    /// `r, p` (unit) with velocities `ṙ, ω`, ω in inertial components: 6 columns per body.
    OmegaInertial,
    /// `r, p` (unit) with velocities `ṙ, ω'`, ω' in the body's own components.
    OmegaBody,
    /// `δ, p_rel` with velocities `δ̇, ω_rel`, ω_rel in B1 components: 6 columns.
    RelativeB1,
    /// `δ, p_rel` with velocities `δ̇, ω_rel`, ω_rel in B2 components: 6 columns.
    RelativeB2,
}

impl Formulation {
    /// All five, in the order of `CONVENTIONS.md`.
    pub const ALL: [Formulation; 5] = [
        Formulation::Euler,
        Formulation::OmegaInertial,
        Formulation::OmegaBody,
        Formulation::RelativeB1,
        Formulation::RelativeB2,
    ];

    /// The name used in `#[joint(formulation = ...)]` and in the conformance vectors.
    pub const fn name(self) -> &'static str {
        match self {
            Formulation::Euler => "euler",
            Formulation::OmegaInertial => "omega_inertial",
            Formulation::OmegaBody => "omega_body",
            Formulation::RelativeB1 => "relative_b1",
            Formulation::RelativeB2 => "relative_b2",
        }
    }
}

impl core::fmt::Display for Formulation {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.name())
    }
}

/// The error of `"…".parse::<Formulation>()`: the name is not one of the five.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ParseFormulationError;

impl core::fmt::Display for ParseFormulationError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(
            "unknown formulation; expected `euler`, `omega_inertial`, `omega_body`, `relative_b1` or `relative_b2`",
        )
    }
}

impl core::error::Error for ParseFormulationError {}

/// Parses the names of [`Formulation::name`], as in `#[joint(formulation = ...)]`.
///
/// ```
/// use joint_runtime::Formulation;
/// assert_eq!("omega_body".parse(), Ok(Formulation::OmegaBody));
/// assert_eq!(Formulation::RelativeB2.to_string(), "relative_b2");
/// assert!("omega".parse::<Formulation>().is_err());
/// ```
impl core::str::FromStr for Formulation {
    type Err = ParseFormulationError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Formulation::ALL.into_iter().find(|f| f.name() == s).ok_or(ParseFormulationError)
    }
}

/// Arithmetic operations in each generated function: every binary `+`, `−`, `×`,
/// `÷` counts one, a negation counts nothing (it folds into the next operation).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Ops {
    /// Operations in `phi`.
    pub phi: usize,
    /// Operations in `phi_t`.
    pub phi_t: usize,
    /// Operations in `jacobian`.
    pub jacobian: usize,
    /// Operations in `gamma`.
    pub gamma: usize,
    /// Operations in the fused `evaluate` (Φ, J and γ from one shared computation).
    pub evaluate: usize,
}

/// Φ, J and γ at one state, from [`Joint::evaluate`].
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(
    feature = "serde",
    serde(bound(
        serialize = "T: nalgebra::Scalar + serde::Serialize",
        deserialize = "T: nalgebra::Scalar + serde::Deserialize<'de>"
    ))
)]
pub struct Evaluation<T, const R: usize, const C: usize> {
    /// The constraint Φ (R rows, in the joint's row order).
    pub phi: SVector<T, R>,
    /// The Jacobian J with Φ̇ = J v + Φ_t (columns in the formulation's order).
    pub jacobian: SMatrix<T, R, C>,
    /// The acceleration right-hand side: J v̇ = γ.
    pub gamma: SVector<T, R>,
}

/// The second-order terms at one state, from `second_order` of a joint or a
/// scene derived with the `second_order` option (`CONVENTIONS.md`,
/// "Second-order terms"): what the exact Newton matrix of an implicit
/// integrator and a linearisation are made of.
///
/// Each `∂/∂q` is the derivative along an increment `δ` of the coordinates laid
/// out as the velocities: `δr` for a position, `δθ` for a rotation (the group
/// increment `p ⊕ δθ` in the components the formulation gives ω in), `δp` in
/// `euler`. Column `k` of a `∂/∂q` is the derivative along the `k`-th unit
/// increment.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
#[cfg_attr(feature = "serde", serde(bound(serialize = "T: nalgebra::Scalar + serde::Serialize")))]
pub struct SecondOrder<T, const R: usize, const C: usize> {
    /// The tangent stiffness `K(q, λ) = ∂(Jᵀλ)/∂q` (`C × C`).
    pub stiffness: SMatrix<T, C, C>,
    /// `∂(J u)/∂q` with `u` held.
    pub jacobian_q: SMatrix<T, R, C>,
    /// `∂γ/∂q` with the velocities held.
    pub gamma_q: SMatrix<T, R, C>,
    /// `∂γ/∂v` (γ is quadratic in the velocities).
    pub gamma_v: SMatrix<T, R, C>,
    /// `∂Φ_t/∂q` (zero but for drivers).
    pub phi_t_q: SMatrix<T, R, C>,
}

/// A joint whose constraint functions were generated by `#[derive(Joint)]`.
///
/// `T` is the scalar, `R` the number of constraint rows and `C` the number of
/// velocity columns (7 per free body in `euler`, 6 per free body in the ω
/// formulations, 6 in the relative ones). Every function is a straight-line
/// evaluation: no allocation, no branch on the data, no panic.
pub trait Joint<T, const R: usize, const C: usize> {
    /// The state the functions read: [`TwoBodies`](crate::TwoBodies),
    /// [`OneBody`](crate::OneBody) (one body grounded) or
    /// [`RelativeState`](crate::RelativeState).
    type State;
    /// The joint kind, as written in the derive (`"universal"`, ...).
    const KIND: &'static str;
    /// The formulation the code was generated for.
    const FORMULATION: Formulation;
    /// Operation counts of the generated functions.
    const OPS: Ops;
    /// Number of constraint rows (`R`).
    const ROWS: usize = R;
    /// Number of velocity columns (`C`).
    const COLS: usize = C;
    /// The constraint Φ.
    fn phi(&self, state: &Self::State) -> SVector<T, R>;
    /// The explicit time derivative Φ_t (zero unless the joint is driven).
    fn phi_t(&self, state: &Self::State) -> SVector<T, R>;
    /// The Jacobian J (Φ̇ = J v + Φ_t).
    fn jacobian(&self, state: &Self::State) -> SMatrix<T, R, C>;
    /// The acceleration right-hand side γ (J v̇ = γ).
    fn gamma(&self, state: &Self::State) -> SVector<T, R>;
    /// Φ, J and γ together, sharing every common subexpression.
    fn evaluate(&self, state: &Self::State) -> Evaluation<T, R, C>;
    /// The second-order terms at `state` with multipliers `lambda` (for
    /// `∂(Jᵀλ)/∂q`) and a velocity-shaped `u` (for `∂(J u)/∂q`): `Some` when the
    /// derive was given `second_order`, `None` (the default) otherwise, so a
    /// joint that needs only Φ, J and γ compiles no more than those.
    fn second_order(
        &self,
        state: &Self::State,
        lambda: &SVector<T, R>,
        u: &SVector<T, C>,
    ) -> Option<SecondOrder<T, R, C>> {
        let _ = (state, lambda, u);
        None
    }
}

/// A joint whose rows can lose rank, with a generated measure of the distance
/// from that configuration: 1 at the nominal geometry, 0 at the singularity.
///
/// Solvers can watch it and report the singularity instead of returning the
/// garbage a rank-deficient Jacobian gives.
pub trait Singularity<T, const R: usize, const C: usize>: Joint<T, R, C> {
    /// The configurations at which [`Singularity::singularity`] is zero.
    const ZERO_WHEN: &'static str;
    /// The measure at `state` (for a universal joint, the squared sine of the
    /// angle between the yoke axes).
    fn singularity(&self, state: &Self::State) -> T;
}
