//! CPU cost of building the HiZ pyramid with each NPOT mode, at 1920x1080 and 27x13.
//! `cargo bench -p tilegraph-cull --bench hiz_build`

use criterion::{black_box, criterion_group, criterion_main, BenchmarkId, Criterion};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use tilegraph_cull::{DepthConvention, DepthFormat, Extent2d, ExtentExt, HizPyramid, NpotMode};

/// Reverse-Z depth with a few hundred occluder rectangles over a cleared (0) background.
fn depth_buffer(w: u32, h: u32) -> Vec<f32> {
    let mut rng = Pcg64::seed_from_u64(7);
    let mut depth = vec![0.0f32; (w * h) as usize];
    for _ in 0..300 {
        let x0 = rng.random_range(0..w);
        let y0 = rng.random_range(0..h);
        let x1 = (x0 + rng.random_range(0..w / 4 + 1)).min(w - 1);
        let y1 = (y0 + rng.random_range(0..h / 4 + 1)).min(h - 1);
        let d: f32 = rng.random_range(0.0..1.0);
        for y in y0..=y1 {
            for x in x0..=x1 {
                let i = (y * w + x) as usize;
                depth[i] = depth[i].max(d);
            }
        }
    }
    depth
}

fn hiz_build(c: &mut Criterion) {
    let mut group = c.benchmark_group("hiz_build");
    for (w, h) in [(1920u32, 1080u32), (27, 13)] {
        let extent = Extent2d::try_new(w, h).expect("valid bench extent");
        let depth = depth_buffer(w, h);
        for mode in [
            NpotMode::EdgeAware,
            NpotMode::PadToPow2,
            NpotMode::NaiveBuggy,
        ] {
            group.bench_with_input(
                BenchmarkId::new(format!("{mode:?}"), format!("{w}x{h}")),
                &depth,
                |b, depth| {
                    b.iter(|| {
                        HizPyramid::build(
                            black_box(depth),
                            extent,
                            DepthConvention::Reverse,
                            DepthFormat::D32Float,
                            mode,
                        )
                        .expect("valid bench input")
                    })
                },
            );
        }
    }
    group.finish();
}

criterion_group!(benches, hiz_build);
criterion_main!(benches);
