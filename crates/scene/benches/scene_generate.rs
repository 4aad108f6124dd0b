//! `scene_generate`: generating and flattening procedural scenes, and the per-frame
//! camera-relative instance records. The 1M-instance case is the budget (< 2 s).
//!
//! Run: `cargo bench -p tilegraph-scene --bench scene_generate`

use std::hint::black_box;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion};
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

/// What a game pays on the CPU to move instances of a 1M-instance city: a batch of 10,000
/// transforms (bounds, grid cells, journal), and what a renderer pays once for all records.
fn changes_1m(c: &mut Criterion) {
    let Ok(mut scene) = generate(
        ProceduralKind::City,
        ProceduralParams {
            size: 1_000_000,
            seed: 1,
        },
    ) else {
        return;
    };
    let moves: Vec<_> = (0..10_000u32)
        .filter_map(|i| {
            let id = tilegraph_scene::InstanceId(i * 97 % scene.instances().len() as u32);
            let h = scene.instance_handle(id)?;
            let mut t = scene.instances()[id.index()].transform;
            t.translation.x += 0.5;
            Some((h, t))
        })
        .collect();
    let mut group = c.benchmark_group("scene_changes");
    group.sample_size(20);
    group.bench_function("set_transforms_10k_of_city_1M", |b| {
        b.iter(|| {
            let r = scene.set_transforms(black_box(&moves));
            black_box(r.is_ok())
        })
    });
    group.bench_function("gpu_records_city_1M", |b| {
        b.iter(|| black_box(scene.gpu_records().len()))
    });
    group.finish();
}

criterion_group!(benches, generate_1m, changes_1m);
criterion_main!(benches);
