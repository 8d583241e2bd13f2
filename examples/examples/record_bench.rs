//! What a 3D run costs to write: the Panda's PD run (`joint_examples::panda`),
//! 3 s at 1 kHz with its bodies recorded at every step (3001 samples), written
//! as a `.glb` at 50 frames a second with the arm's own meshes (ten Collada
//! files, 10.5 MB, read at the first write and kept for the process), and its
//! viewer page: the size, and the median of 11 writes after the first, which
//! reads the meshes and is shown apart.
//!
//! ```text
//! cargo run --release -p joint-examples --features bench --example record_bench
//! ```

use std::time::Instant;

use joint_examples::panda::{self, Joints, Panda};
use joint_runtime::record::{GltfOptions, Trajectory};
use joint_runtime::relative::{TreeSimulation, TreeState};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut sim = TreeSimulation::new(&Panda).map_err(|e| format!("{e:?}"))?;
    let target = Joints::from(panda::TARGET);
    let mut state = TreeState { q: Joints::from(panda::READY), v: Joints::zeros(), t: 0.0 };
    let mut run = Trajectory::new(&Panda);
    for k in 0..=3000 {
        run.record(&sim.system_state(&state));
        if k < 3000 {
            let (tau, _) = panda::control(&sim, &state, &target);
            sim.step_with(&mut state, 1e-3, &tau).map_err(|e| format!("{e:?}"))?;
        }
    }
    let options = GltfOptions::default();
    let timed = |f: &mut dyn FnMut() -> usize| {
        let start = Instant::now();
        let n = f();
        (start.elapsed().as_secs_f64() * 1e3, n)
    };
    let (cold, bytes) = timed(&mut || run.glb(&options).bytes.len());
    let mut times: Vec<f64> = (0..11).map(|_| timed(&mut || run.glb(&options).bytes.len()).0).collect();
    times.sort_by(f64::total_cmp);
    let glb = run.glb(&options);
    let page = timed(&mut || joint_runtime::record::viewer_page(&glb.bytes, "Panda").len());
    println!("Panda, 3 s at 1 kHz: {} samples -> {} frames at {} fps", run.samples().len(), glb.frames, options.fps);
    println!(
        "  .glb: {:.2} MB, written in {:.1} ms (median of 11; {:.1}-{:.1} ms); the first write, reading the meshes: {cold:.1} ms",
        bytes as f64 / 1e6,
        times[5],
        times[0],
        times[10]
    );
    println!("  page: {:.2} MB, made in {:.1} ms", page.1 as f64 / 1e6, page.0);
    Ok(())
}
