//! The 3D runs as a person sees them: the viewer page that `write_3d` writes
//! beside the `.glb`, opened from the file system in headless Chromium (no
//! network), screenshot at two times of the Panda's PD run and of the
//! N-four-bar, and the pictures checked: not blank, the bodies inside the
//! frame, the two times differing where the bodies moved. Each `.glb` is
//! also checked by the Khronos glTF validator (`checks/gltf`, npm), which
//! must find no error.
//!
//! Chromium and the validator are found on the machine (`CHROMIUM`, else
//! `chromium` or `chromium-browser` on the path; `checks/gltf/node_modules`
//! from `npm ci`). Where one is missing the test says so and checks only
//! the files, unless `JOINT_BROWSER_TESTS=require` (set by `.ci/run`, which
//! installs both), where a missing one fails it.
//!
//! The Panda's picture at its start, with the ground, is what the README
//! shows (`guide/src/images/panda.png`): the test writes it to
//! `target/tmp/viewer/panda_pd_still.png`.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use joint_examples::{four_bar, panda};
use joint_runtime::dynamics::Integrator;
use joint_runtime::record::{GltfOptions, Trajectory, Written};

/// Where the runs and pictures go.
fn folder() -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("viewer");
    std::fs::create_dir_all(&dir).expect("the test's folder");
    dir
}

fn required() -> bool {
    std::env::var("JOINT_BROWSER_TESTS").is_ok_and(|v| v == "require")
}

/// Chromium, if the machine has it.
fn chromium() -> Option<PathBuf> {
    let named = std::env::var_os("CHROMIUM").map(PathBuf::from);
    let on_path = ["chromium", "chromium-browser", "google-chrome"].into_iter().find_map(|name| {
        std::env::var_os("PATH")
            .and_then(|paths| std::env::split_paths(&paths).map(|p| p.join(name)).find(|p| p.is_file()))
    });
    let found = named.or(on_path);
    assert!(found.is_some() || !required(), "JOINT_BROWSER_TESTS=require and no Chromium (set CHROMIUM)");
    found
}

/// A picture of `page` at time `t`, `width × height` pixels, as RGBA rows.
fn screenshot(browser: &Path, page: &Path, t: f64, name: &str) -> Picture {
    let out = folder().join(format!("{name}.png"));
    let _ = std::fs::remove_file(&out);
    let profile = folder().join(format!("profile-{name}"));
    let address = format!("file://{}#t={t}", page.canonicalize().expect("the page").display());
    // Software WebGL (SwiftShader), no network at all (the page needs none;
    // without these flags Chromium tries Google's hosts at every start).
    let mut child = Command::new(browser)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu-sandbox",
            "--use-gl=angle",
            "--use-angle=swiftshader",
            "--enable-unsafe-swiftshader",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--no-first-run",
            "--no-default-browser-check",
            "--hide-scrollbars",
            "--window-size=960,640",
            "--virtual-time-budget=5000",
        ])
        .arg(format!("--user-data-dir={}", profile.display()))
        .arg(format!("--screenshot={}", out.display()))
        .arg(&address)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .expect("Chromium starts");
    let start = Instant::now();
    while child.try_wait().expect("Chromium runs").is_none() {
        if start.elapsed() > Duration::from_secs(90) {
            let _ = child.kill();
            panic!("Chromium took more than 90 s on {address}");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    Picture::read(&out)
}

/// A screenshot's pixels.
struct Picture {
    width: usize,
    height: usize,
    rgb: Vec<[u8; 3]>,
}

impl Picture {
    fn read(path: &Path) -> Picture {
        let file = std::fs::File::open(path).unwrap_or_else(|e| panic!("no screenshot at {}: {e}", path.display()));
        let mut decoder = png::Decoder::new(std::io::BufReader::new(file));
        decoder.set_transformations(png::Transformations::EXPAND | png::Transformations::STRIP_16);
        let mut reader = decoder.read_info().expect("a PNG");
        let mut buffer = vec![0; reader.output_buffer_size().expect("its size")];
        let info = reader.next_frame(&mut buffer).expect("its pixels");
        let channels = info.color_type.samples();
        let rgb = buffer[..info.buffer_size()].chunks_exact(channels).map(|p| [p[0], p[1], p[2]]).collect();
        Picture { width: info.width as usize, height: info.height as usize, rgb }
    }

    /// The drawing's area: below the title, above the controls.
    fn scene(&self) -> impl Iterator<Item = (usize, usize)> + '_ {
        (60..self.height.saturating_sub(70)).flat_map(move |y| (0..self.width).map(move |x| (x, y)))
    }

    fn at(&self, (x, y): (usize, usize)) -> [u8; 3] {
        self.rgb[y * self.width + x]
    }
}

/// Far from the page's background (`#e9ebee`): a body's pixel (the runs
/// here are drawn without the ground's grid).
fn body_pixel(c: [u8; 3]) -> bool {
    let background = [0xe9, 0xeb, 0xee];
    c.iter().zip(background).map(|(&a, b)| (i32::from(a) - b).abs()).max().unwrap_or(0) > 12
}

/// The bodies' pixels and their bounding box.
fn bodies(p: &Picture) -> (usize, [usize; 4]) {
    let mut box_ = [usize::MAX, usize::MAX, 0, 0];
    let mut n = 0;
    for xy in p.scene().filter(|&xy| body_pixel(p.at(xy))) {
        n += 1;
        box_ = [box_[0].min(xy.0), box_[1].min(xy.1), box_[2].max(xy.0), box_[3].max(xy.1)];
    }
    (n, box_)
}

/// Checks the pictures of `written` at `times`: bodies there and framed,
/// the second differing from the first inside the bodies' boxes.
fn look(browser: &Path, written: &Written, times: [f64; 2], name: &str) {
    let [a, b] = times.map(|t| screenshot(browser, &written.page, t, &format!("{name}_{t}")));
    let area = a.scene().count();
    for (p, t) in [(&a, times[0]), (&b, times[1])] {
        let (n, [x0, y0, x1, y1]) = bodies(p);
        let fraction = n as f64 / area as f64;
        assert!(fraction > 0.002, "{name} at t = {t}: {:.2} % of the picture is bodies: blank", 100.0 * fraction);
        assert!(fraction < 0.6, "{name} at t = {t}: {:.0} % of the picture is bodies: not framed", 100.0 * fraction);
        assert!(x0 > 5 && x1 + 5 < p.width && y0 > 60 && y1 + 75 < p.height, "{name} at t = {t}: cut by the frame");
    }
    let ([ax0, ay0, ax1, ay1], [bx0, by0, bx1, by1]) = (bodies(&a).1, bodies(&b).1);
    let inside =
        |(x, y): (usize, usize)| x >= ax0.min(bx0) && x <= ax1.max(bx1) && y >= ay0.min(by0) && y <= ay1.max(by1);
    let changed: Vec<(usize, usize)> = a.scene().filter(|&xy| a.at(xy) != b.at(xy)).collect();
    let moved = changed.iter().filter(|&&xy| inside(xy)).count();
    assert!(moved as f64 > 0.002 * area as f64, "{name}: the pictures at {times:?} hardly differ ({moved} pixels)");
    assert!(moved as f64 > 0.95 * changed.len() as f64, "{name}: pixels changed away from the bodies");
}

/// The Khronos validator's verdict on `glb`: no error (where it is installed).
fn validate(glb: &Path) {
    let checks = Path::new(env!("CARGO_MANIFEST_DIR")).join("../checks/gltf");
    if !checks.join("node_modules/gltf-validator").is_dir() {
        assert!(!required(), "JOINT_BROWSER_TESTS=require and no validator: run `npm ci` in checks/gltf");
        eprintln!("glTF validator not installed (npm ci in checks/gltf): {} not validated", glb.display());
        return;
    }
    let out = Command::new("node").arg(checks.join("validate.mjs")).arg(glb).output().expect("node runs");
    let report = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success() && report.contains(" 0 errors"), "the validator on {}:\n{report}", glb.display());
}

fn write<const NB: usize>(run: &Trajectory<NB>, (name, title): (&str, &str), ground: bool) -> Written {
    let options = GltfOptions::default().with_title(title).with_ground(ground);
    let written = run.write_3d(&folder().join(name), &options).expect("written");
    assert!(written.missing.is_empty(), "{:?}", written.missing);
    validate(&written.glb);
    written
}

#[test]
fn panda_and_four_bar_seen_moving_in_a_browser() {
    let panda = panda::simulate(1.0, 1e-3).expect("the Panda's run");
    let scene = four_bar::scene();
    let four_bar =
        four_bar::simulate(&scene, &four_bar::initial_state(), Integrator::Rk4, 2e-3, 2.0, 10).expect("its run");
    let arm = write(&panda.trajectory, ("panda_pd", "Panda"), false);
    let bars = write(&four_bar.trajectory, ("four_bar", "N-four-bar"), false);
    // Below the bound for a 3 s run at 1 kHz (5 MB): the meshes are most of it.
    assert!(arm.bytes < 5_000_000, "{} bytes", arm.bytes);
    let title = "Panda from its URDF: PD + gravity compensation at 1 kHz";
    let still = write(&panda.trajectory, ("panda_pd_with_ground", title), true);
    let Some(browser) = chromium() else {
        eprintln!("no Chromium (set CHROMIUM or install chromium): the pictures are not checked");
        return;
    };
    // The arm's largest move is in its first 0.3 s; the bars swing through theirs in 1 s.
    look(&browser, &arm, [0.0, 0.3], "panda_pd");
    look(&browser, &bars, [0.0, 1.0], "four_bar");
    let picture = screenshot(&browser, &still.page, 0.3, "panda_pd_still");
    assert!(bodies(&picture).0 > 0);
}
