//! Tests of the generated code, and the conformance runner they share.
//!
//! [`conformance`] evaluates the cases of the repository's `conformance/*.json`
//! through derive-generated code with run-time parameters and applies the
//! accuracy test of the conformance README. [`trajectory`] holds the exact trajectories and
//! comparisons of the derivative tests, [`scenes`] the mechanisms of the analysis
//! and dynamics tests, [`random`] the deterministic random states of the batch
//! tests and benchmark.

/// The repository's README, whose examples run as doctests here (the crate
/// READMEs are their crates' own docs).
#[cfg(doctest)]
#[doc = include_str!("../../README.md")]
struct RepositoryReadme;

/// The guide's chapters (`guide/src/`), whose examples run as doctests here:
/// `mdbook test` cannot link the workspace's crates (the derives, nalgebra), so
/// the guide is tested as this crate's documentation (`cargo test -p joint-tests --doc`).
#[cfg(doctest)]
mod guide {
    /// The introduction: what the guide covers and how it is tested.
    #[doc = include_str!("../../guide/src/README.md")]
    struct Introduction;

    /// Joints and formulations: the catalogue, its accuracy, singularities, what is generated.
    #[doc = include_str!("../../guide/src/joints-and-formulations.md")]
    struct JointsAndFormulations;

    /// Mechanisms: scenes, rows of bodies and joints, the block factor, the analyses.
    #[doc = include_str!("../../guide/src/mechanisms.md")]
    struct Mechanisms;

    /// Coordinates: absolute and relative, loops closed by rows, `coordinates = both`.
    #[doc = include_str!("../../guide/src/coordinates.md")]
    struct Coordinates;

    /// Robots from their URDF and MJCF files (paths relative to this crate's directory).
    #[doc = include_str!("../../guide/src/robots-from-files.md")]
    struct RobotsFromFiles;

    /// Integrators and error control, stiff robots, code over any engine.
    #[doc = include_str!("../../guide/src/integrators-and-error-control.md")]
    struct IntegratorsAndErrorControl;

    /// Derivatives of a robot's dynamics, second-order terms, linearisation.
    #[doc = include_str!("../../guide/src/derivatives-and-linearisation.md")]
    struct DerivativesAndLinearisation;

    /// Contacts and closed loops: constrained dynamics, forces, impacts and their derivatives.
    #[doc = include_str!("../../guide/src/contacts-and-closed-loops.md")]
    struct ContactsAndClosedLoops;

    /// Control loops: no_std, no allocation, no panic.
    #[doc = include_str!("../../guide/src/control-loops.md")]
    struct ControlLoops;

    /// Batches in SIMD lanes and on rayon's pool.
    #[doc = include_str!("../../guide/src/batches.md")]
    struct Batches;

    /// A run as a 3D file and a page that plays it.
    #[doc = include_str!("../../guide/src/seeing-a-run.md")]
    struct SeeingARun;

    /// The example programs, what each checks and measured.
    #[doc = include_str!("../../guide/src/examples.md")]
    struct Examples;

    /// The conventions in brief.
    #[doc = include_str!("../../guide/src/conventions.md")]
    struct Conventions;

    /// Performance: every timing table and the commands that reproduce it.
    #[doc = include_str!("../../guide/src/performance.md")]
    struct Performance;
}

pub mod conformance;
pub mod joints;
pub mod random;
pub mod scenes;
pub mod second_order;
pub mod trajectory;
