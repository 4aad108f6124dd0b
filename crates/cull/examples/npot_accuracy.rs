//! Accuracy of the two NPOT fixes (and the naive reduction) against the exact per-pixel test.
//!
//! For each viewport: a reverse-Z depth buffer of random screen-space occluder rectangles over
//! a cleared background; then random test rects (log-uniform sizes from 1 px to the screen,
//! uniform positions and depths). Each test rect is classified by the brute-force test over
//! level-0 pixels (`exact_is_occluded`) and by the HiZ test of each mode. Prints a markdown table.
//!
//! `cargo run --release -p tilegraph-cull --example npot_accuracy`

use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use tilegraph_cull::{
    exact_is_occluded, CullError, DepthConvention, DepthFormat, Extent2d, ExtentExt, HizOutcome,
    HizPyramid, NpotMode, PixelRect,
};

const RECTS_PER_VIEWPORT: usize = 20_000;

fn depth_buffer(w: u32, h: u32, rng: &mut Pcg64) -> Vec<f32> {
    let mut depth = vec![0.0f32; (w * h) as usize];
    for _ in 0..40 {
        let x0 = rng.random_range(0..w);
        let y0 = rng.random_range(0..h);
        let x1 = (x0 + rng.random_range(0..w / 2 + 1)).min(w - 1);
        let y1 = (y0 + rng.random_range(0..h / 2 + 1)).min(h - 1);
        let d: f32 = rng.random_range(0.2..1.0);
        for y in y0..=y1 {
            for x in x0..=x1 {
                let i = (y * w + x) as usize;
                depth[i] = depth[i].max(d);
            }
        }
    }
    depth
}

fn log_uniform(rng: &mut Pcg64, max: u32) -> i32 {
    let l: f64 = rng.random_range(0.0..=f64::from(max).ln());
    l.exp() as i32
}

#[derive(Default)]
struct Counts {
    culled: u32,
    wrongly_culled: u32,
    texels_read: u64,
}

fn main() -> Result<(), CullError> {
    let conv = DepthConvention::Reverse;
    let format = DepthFormat::D32Float;
    let modes = [
        NpotMode::EdgeAware,
        NpotMode::PadToPow2,
        NpotMode::NaiveBuggy,
    ];
    println!("| viewport | exact occluded | EdgeAware culls | PadToPow2 culls | NaiveBuggy culls (wrong) | texels read per test (edge / pad) |");
    println!("|---|---|---|---|---|---|");
    for (w, h) in [
        (27u32, 13u32),
        (640, 480),
        (641, 479),
        (1280, 720),
        (1920, 1080),
        (4096, 1),
    ] {
        let extent = Extent2d::try_new(w, h)?;
        let mut rng = Pcg64::seed_from_u64(u64::from(w) * 7919 + u64::from(h));
        let depth = depth_buffer(w, h, &mut rng);
        let pyramids: Vec<HizPyramid> = modes
            .iter()
            .map(|&m| HizPyramid::build(&depth, extent, conv, format, m))
            .collect::<Result<_, _>>()?;
        let mut exact_occluded = 0u32;
        let mut counts: Vec<Counts> = modes.iter().map(|_| Counts::default()).collect();
        for _ in 0..RECTS_PER_VIEWPORT {
            let (rw, rh) = (log_uniform(&mut rng, w), log_uniform(&mut rng, h));
            let x0 = rng.random_range(0..w as i32);
            let y0 = rng.random_range(0..h as i32);
            let rect = PixelRect::new(x0, y0, x0 + rw.max(1) - 1, y0 + rh.max(1) - 1)?;
            let nearest: f32 = rng.random_range(0.0..1.0);
            let exact =
                exact_is_occluded(&depth, extent, conv, format, rect, nearest)? == Some(true);
            exact_occluded += u32::from(exact);
            for (p, c) in pyramids.iter().zip(counts.iter_mut()) {
                let out = p.test_rect(rect, nearest)?;
                if let HizOutcome::Occluded(probe) | HizOutcome::Visible(probe) = out {
                    c.texels_read += u64::from(probe.texels.texel_count());
                }
                if out.is_culled() {
                    c.culled += 1;
                    c.wrongly_culled += u32::from(!exact);
                }
            }
        }
        let pct = |n: u32| 100.0 * f64::from(n) / f64::from(exact_occluded.max(1));
        for (m, c) in modes.iter().zip(&counts) {
            if *m != NpotMode::NaiveBuggy {
                assert_eq!(c.wrongly_culled, 0, "{m:?} culled a visible rect");
            }
        }
        println!(
            "| {w}x{h} | {exact_occluded} / {RECTS_PER_VIEWPORT} | {} ({:.1}%) | {} ({:.1}%) | {} ({} wrong) | {:.2} / {:.2} |",
            counts[0].culled,
            pct(counts[0].culled),
            counts[1].culled,
            pct(counts[1].culled),
            counts[2].culled,
            counts[2].wrongly_culled,
            counts[0].texels_read as f64 / RECTS_PER_VIEWPORT as f64,
            counts[1].texels_read as f64 / RECTS_PER_VIEWPORT as f64,
        );
    }
    Ok(())
}
