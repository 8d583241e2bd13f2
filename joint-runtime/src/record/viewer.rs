//! A 3D run on disk: the `.glb` and, beside it, a page that plays it in a
//! browser from the file system. The page (`viewer.html`) is the project's
//! own WebGL code, no library, embedded in the crate at build time; the
//! `.glb` goes into it as base64, because a page opened from `file://` may
//! not read the file beside it.

use std::io;
use std::path::{Path, PathBuf};

use super::Trajectory;

/// How [`Trajectory::glb`] and [`Trajectory::write_3d`] draw a run.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize), serde(default))]
#[non_exhaustive]
pub struct GltfOptions {
    /// Frames a second kept in the animation: samples closer in time are
    /// dropped (every sample is kept where they are sparser). A viewer
    /// interpolates between frames, so 50 looks smooth and keeps a 3 s run
    /// at 151 frames whatever its step.
    pub fps: f64,
    /// The page's title, also in the file's `asset.extras`.
    pub title: String,
    /// A grid on the ground (`z = 0`) and the world's axes (x red, y green,
    /// z blue), sized to where the bodies go.
    pub ground: bool,
}

impl Default for GltfOptions {
    fn default() -> Self {
        GltfOptions { fps: 50.0, title: String::new(), ground: true }
    }
}

impl GltfOptions {
    /// Sets [`fps`](Self::fps).
    pub fn with_fps(mut self, fps: f64) -> Self {
        self.fps = fps;
        self
    }
    /// Sets [`title`](Self::title).
    pub fn with_title(mut self, title: &str) -> Self {
        self.title = title.into();
        self
    }
    /// Sets [`ground`](Self::ground).
    pub fn with_ground(mut self, ground: bool) -> Self {
        self.ground = ground;
        self
    }
}

/// What [`Trajectory::write_3d`] wrote.
#[derive(Clone, Debug, PartialEq)]
pub struct Written {
    /// The glTF 2.0 binary.
    pub glb: PathBuf,
    /// The page that plays it: open it in a browser.
    pub page: PathBuf,
    /// The `.glb`'s size in bytes.
    pub bytes: usize,
    /// Frames in the animation.
    pub frames: usize,
    /// Mesh files that could not be read, with the reason (their bodies
    /// drawn as stand-ins).
    pub missing: Vec<String>,
}

impl<const NB: usize> Trajectory<NB> {
    /// Writes the run as `PATH.glb`, a glTF 2.0 binary that any glTF viewer
    /// opens (browsers' viewers, Blender, the operating system's), and
    /// `PATH.html`, a page that plays it offline: drag to orbit, wheel to
    /// zoom, space to pause, a slider to scrub, the time shown; `#t=1.5`
    /// after the page's address opens it paused at 1.5 s. Any extension of
    /// `path` is replaced.
    ///
    /// Each body is a node moved by the recorded samples (at
    /// [`GltfOptions::fps`]), drawn with the shapes of its robot file (URDF
    /// `<visual>`, MJCF `<geom>`, mesh files read as STL, OBJ or Collada),
    /// or, where the file draws nothing or is not a file's scene, as
    /// capsules along its joint points whose radius gives the body its mass
    /// at the density of water. Points joined to the ground are dark dots.
    ///
    /// # Errors
    /// What creating the folder or writing either file returns.
    pub fn write_3d(&self, path: &Path, options: &GltfOptions) -> io::Result<Written> {
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir)?;
        }
        let glb = self.glb(options);
        let (file, page) = (path.with_extension("glb"), path.with_extension("html"));
        std::fs::write(&file, &glb.bytes)?;
        let title = if options.title.is_empty() { "joint-runtime run" } else { &options.title };
        std::fs::write(&page, viewer_page(&glb.bytes, title))?;
        Ok(Written { glb: file, page, bytes: glb.bytes.len(), frames: glb.frames, missing: glb.missing })
    }
}

/// The viewer page that plays `glb` (a [`Glb`](super::Glb)'s bytes), titled
/// `title`: what [`Trajectory::write_3d`] writes beside the `.glb`, for a
/// caller who serves or stores the page itself.
pub fn viewer_page(glb: &[u8], title: &str) -> String {
    const PAGE: &str = include_str!("viewer.html");
    let escaped = title.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;");
    PAGE.replacen("__TITLE__", &escaped, 1).replacen("__GLB_BASE64__", &base64(glb), 1)
}

/// Standard base64 with padding (RFC 4648).
fn base64(bytes: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [chunk[0], chunk.get(1).copied().unwrap_or(0), chunk.get(2).copied().unwrap_or(0)];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for k in 0..4 {
            if k <= chunk.len() {
                out.push(char::from(ALPHABET[((n >> (18 - 6 * k)) & 63) as usize]));
            } else {
                out.push('=');
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_as_rfc_4648_gives_it() {
        // RFC 4648, section 10.
        for (text, code) in [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ] {
            assert_eq!(base64(text.as_bytes()), code);
        }
    }

    #[test]
    fn the_page_holds_the_run_and_its_title() {
        let page = viewer_page(b"glTF", "a <b> & c");
        assert!(page.contains("<title>a &lt;b&gt; &amp; c</title>"));
        assert!(page.contains(">Z2xURg==</script>"));
        assert!(!page.contains("__GLB_BASE64__") && !page.contains("__TITLE__"));
        // Offline: nothing fetched from elsewhere.
        assert!(!page.contains("http://") && !page.contains("https://"), "the page names an address");
    }
}
