//! `graph_compile`: compile time of a realistic frame of 10, 100 and 1000 passes.
//!
//! The frame is built from 10-pass "views" (think main view, shadow cascades, reflection
//! probes): GPU culling (against the previous view's HiZ), depth pre-pass, HiZ build, opaque,
//! alpha-tested, transparent, occlusion queries, bloom at half resolution, tonemap, and a debug
//! overlay nobody reads (pruned). Each view samples the previous view's output, and the last
//! one writes the swapchain. Only `compile` is timed (the builder is cloned outside the measurement).

use criterion::{criterion_group, criterion_main, BatchSize, BenchmarkId, Criterion};

mod common;

use common::realistic_frame;
use tilegraph_profile::ProfileSet;

fn graph_compile(c: &mut Criterion) {
    let profiles = ProfileSet::embedded().expect("embedded profiles");
    let profile = profiles
        .get("adreno-7xx")
        .expect("adreno-7xx profile")
        .clone();
    let mut group = c.benchmark_group("graph_compile");
    for passes in [10usize, 100, 1000] {
        let graph = realistic_frame(passes / 10);
        assert_eq!(graph.pass_count(), passes);
        group.bench_with_input(BenchmarkId::from_parameter(passes), &graph, |b, graph| {
            // One fresh clone right before each compile: in an engine the frame is declared and
            // compiled at once, with the declarations still in cache (batching many clones up
            // front would time compile on cold inputs). The timer overhead per iteration is
            // negligible next to 10 µs and more.
            b.iter_batched(
                || graph.clone(),
                |g| g.compile(&profile).expect("the benchmark frame compiles"),
                BatchSize::PerIteration,
            )
        });
    }
    group.finish();
}

criterion_group!(benches, graph_compile);
criterion_main!(benches);
