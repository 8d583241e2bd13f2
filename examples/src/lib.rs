//! Mechanisms built with `joint-runtime`, each a library module with a test that
//! asserts its numbers (`examples/tests/`) and a program that prints and plots it
//! (`cargo run --release --example NAME`).

pub mod bricard;
pub mod cardan;
pub mod coordinates;
pub mod double_cardan;
pub mod four_bar;
pub mod pendulum_chain;
pub mod press;
pub mod report;
pub mod scaling;
pub mod steering;

use std::path::Path;

use joint_runtime::record::{SvgOptions, Trajectory};

/// Writes `trajectory` as an animated SVG at `path`, creating its directory.
///
/// # Errors
/// The I/O error, as text.
pub fn write_animation<const NB: usize>(
    path: &Path,
    trajectory: &Trajectory<NB>,
    options: &SvgOptions,
) -> Result<(), String> {
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).map_err(|e| format!("creating {}: {e}", dir.display()))?;
    }
    std::fs::write(path, trajectory.svg(options)).map_err(|e| format!("writing {}: {e}", path.display()))
}
