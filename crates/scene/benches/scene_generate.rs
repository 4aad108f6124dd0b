//! `scene_generate`: generating and flattening procedural scenes, and the per-frame
//! camera-relative instance records. The 1M-instance case is the budget (< 2 s).
//!
//! Run: `cargo bench -p tilegraph-scene --bench scene_generate`

use std::hint::black_box;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion};
use glam::DVec3;
use tilegraph_scene::{generate, ProceduralKind, ProceduralParams};

fn generate_1m(c: &mut Criterion) {
    let mut group = c.benchmark_group("scene_generate");
    // Each 1M sample takes a few hundred ms; ten samples keep the run under a minute.
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(8));
    for kind in ProceduralKind::ALL {
        group.bench_function(format!("{kind}_1M"), |b| {
            b.iter(|| {
                let scene = generate(
                    kind,
                    ProceduralParams {
                        size: 1_000_000,
                        seed: 1,
                    },
                );
                black_box(scene.map(|s| s.instances().len()).unwrap_or(0))
            })
        });
    }
    group.finish();
}

fn gpu_records_1m(c: &mut Criterion) {
    let Ok(scene) = generate(
        ProceduralKind::City,
        ProceduralParams {
            size: 1_000_000,
            seed: 1,
        },
    ) else {
        return;
    };
    let mut out = Vec::with_capacity(scene.instances().len());
    let mut group = c.benchmark_group("scene_frame");
    group.sample_size(20);
    group.bench_function("gpu_instances_city_1M", |b| {
        let eye = DVec3::new(1e6 + 12.5, 1.7, -3.0);
        b.iter(|| {
            scene.write_gpu_instances(black_box(eye), &mut out);
            black_box(out.len())
        })
    });
    // The same records from one and from two threads, for comparison on this machine.
    for threads in [1, 2] {
        group.bench_function(format!("gpu_instances_city_1M_threads_{threads}"), |b| {
            let eye = DVec3::new(1e6 + 12.5, 1.7, -3.0);
            b.iter(|| {
                scene.write_gpu_instances_threads(black_box(eye), &mut out, threads);
                black_box(out.len())
            })
        });
    }
    group.finish();
}

criterion_group!(benches, generate_1m, gpu_records_1m);
criterion_main!(benches);
