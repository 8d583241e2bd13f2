//! The project's main example on `joint-runtime` alone: a Cardan shaft
//! driven at constant speed, against `tan φ₂ = tan φ₁ / cos β`
//! (`cargo run --release --example cardan`). The other mechanisms, with
//! their tests and reports, are in the `joint-examples` package, which
//! re-exports this one's modules.

pub mod cardan;

use std::path::Path;

use joint_runtime::record::{GltfOptions, Trajectory, Written};

/// Writes `trajectory` as a 3D run, `PATH.glb` and the page `PATH.html`
/// that plays it (creating the folder), titled `title`, and prints where
/// the page is and what was left out of it.
///
/// # Errors
/// The I/O error, as text.
pub fn write_animation<const NB: usize>(
    path: &Path,
    trajectory: &Trajectory<NB>,
    title: &str,
) -> Result<Written, String> {
    let written = trajectory
        .write_3d(path, &GltfOptions::default().with_title(title))
        .map_err(|e| format!("writing {}: {e}", path.display()))?;
    let page = written.page.canonicalize().unwrap_or_else(|_| written.page.clone());
    println!(
        "3D run ({:.2} MB, {} frames); see it move: open {} in a browser",
        written.bytes as f64 / 1e6,
        written.frames,
        page.display()
    );
    for m in &written.missing {
        println!("  drawn as a stand-in, its mesh not read: {m}");
    }
    Ok(written)
}
