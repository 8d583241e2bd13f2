//! The animations the examples write, rendered with a pure-Rust SVG renderer
//! (resvg): the bodies' pixels move between two frames, and a viewer that does
//! not animate shows the first frame.

use joint_examples::{bricard, four_bar};
use joint_runtime::dynamics::Integrator;
use joint_runtime::record::{SvgOptions, Trajectory, View, body_colour};
use resvg::{tiny_skia, usvg};

/// The picture's pixels, RGB (the background is opaque white).
fn render(svg: &str) -> (u32, Vec<[u8; 3]>) {
    let tree = usvg::Tree::from_str(svg, &usvg::Options::default()).expect("valid SVG");
    let size = tree.size().to_int_size();
    let mut pixmap = tiny_skia::Pixmap::new(size.width(), size.height()).expect("a size");
    resvg::render(&tree, tiny_skia::Transform::default(), &mut pixmap.as_mut());
    (size.width(), pixmap.pixels().iter().map(|p| [p.red(), p.green(), p.blue()]).collect())
}

fn rgb(hex: &str) -> [u8; 3] {
    let byte = |i: usize| u8::from_str_radix(&hex[i..i + 2], 16).expect("hex");
    [byte(1), byte(3), byte(5)]
}

/// The pixels drawn in body `body`'s colour: their count and centroid.
fn body_pixels((width, pixels): &(u32, Vec<[u8; 3]>), body: usize) -> (usize, [f64; 2]) {
    let want = rgb(body_colour(body));
    let (mut n, mut sum) = (0, [0.0, 0.0]);
    for (i, p) in pixels.iter().enumerate() {
        let distance: u32 = p.iter().zip(want).map(|(&a, b)| u32::from(a.abs_diff(b))).sum();
        if distance < 24 {
            n += 1;
            sum[0] += (i as u32 % width) as f64;
            sum[1] += (i as u32 / width) as f64;
        }
    }
    (n, [sum[0] / n.max(1) as f64, sum[1] / n.max(1) as f64])
}

/// Every body of `bodies` is drawn in both frames and its centroid moves by
/// more than `min_move` pixels; the animated file renders as its first frame.
fn check_motion<const NB: usize>(
    run: &Trajectory<NB>,
    options: &SvgOptions,
    min_move: f64,
    bodies: std::ops::Range<usize>,
) {
    let frames = run.samples().len().min(options.max_frames);
    let first = render(&run.svg_frame(0, options).expect("a first frame"));
    let last = render(&run.svg_frame(frames - 1, options).expect("a last frame"));
    for body in bodies {
        let ((n0, c0), (n1, c1)) = (body_pixels(&first, body), body_pixels(&last, body));
        assert!(n0 > 50 && n1 > 50, "body {body} drawn: {n0} and {n1} pixels");
        let moved = (c1[0] - c0[0]).hypot(c1[1] - c0[1]);
        assert!(moved > min_move, "body {body} moved {moved:.1} px ({c0:?} -> {c1:?})");
    }
    assert!(first != last, "the frames differ");
    assert!(render(&run.svg(options)) == first, "a still viewer shows the first frame");
}

#[test]
fn bricard_bars_move_on_screen() {
    let scene = bricard::scene();
    let run = bricard::simulate(&scene, Integrator::Rk4, 1e-3, 2.0, 20).expect("runs");
    check_motion(&run.trajectory, &SvgOptions::default(), 2.0, 0..5);
}

#[test]
fn four_bar_cranks_move_on_screen() {
    let scene = four_bar::scene();
    let run = four_bar::simulate(&scene, &four_bar::initial_state(), Integrator::Rk4, 1e-3, 1.0, 20).expect("runs");
    check_motion(&run.trajectory, &SvgOptions::default().with_view(View::xy()), 2.0, 0..3);
}

/// The arm's seven links (each drawn from its centre to its link frames'
/// origins) are seen to move; the fingers are a few pixels.
#[test]
fn panda_links_move_on_screen() {
    let run = joint_examples::panda::simulate(1.0, 1e-3).expect("runs");
    let options = SvgOptions::default().with_view(View::isometric()).with_size(1000, 640);
    check_motion(&run.trajectory, &options, 2.0, 0..7);
}
