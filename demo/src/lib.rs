//! The project's main example on `joint-runtime` alone: a Cardan shaft
//! driven at constant speed, against `tan φ₂ = tan φ₁ / cos β`
//! (`cargo run --release --example cardan`). The other mechanisms, with
//! their tests and reports, are in the `joint-examples` package, which
//! re-exports this one's modules.

pub mod cardan;

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
