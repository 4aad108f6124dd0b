//! Compiles the benchmark's realistic frame (`benches/common`) `COUNT` times, for counting
//! instructions with callgrind (docs/BENCHMARKS.md, "graph_compile"):
//!
//! ```sh
//! cargo build --release -p tilegraph-graph --example compile_count
//! valgrind --tool=callgrind --toggle-collect='compile_count::compile_once' \
//!     target/release/examples/compile_count 100 20
//! ```
//!
//! prints nothing but the plan's size; callgrind's total divided by `COUNT` is the cost of one
//! compile of a frame of `PASSES` passes. With a third argument `cached`, the frame goes through
//! a `PlanCache` compiled once beforehand, and `cache_once` (toggle on
//! `compile_count::cache_once`) measures what an unchanged frame costs instead: comparing its
//! declarations with the last frame's.

#[path = "../benches/common/mod.rs"]
mod common;

use tilegraph_graph::{CachedFrame, CompiledGraph, GraphBuilder, GraphError, PlanCache};
use tilegraph_profile::{Profile, ProfileSet};

/// One compile, kept out of line so that callgrind counts exactly it (building the graph,
/// cloning it and dropping the plan are outside).
#[inline(never)]
fn compile_once(
    graph: GraphBuilder<u32>,
    profile: &Profile,
) -> Result<CompiledGraph<u32>, GraphError> {
    graph.compile(profile)
}

/// One frame through the cache, out of line for callgrind.
#[inline(never)]
fn cache_once(
    cache: &mut PlanCache,
    graph: GraphBuilder<u32>,
    profile: &Profile,
) -> Result<CachedFrame<u32>, GraphError> {
    cache.compile(graph, profile)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let passes: usize = args.next().map_or(Ok(100), |a| a.parse())?;
    let count: usize = args.next().map_or(Ok(20), |a| a.parse())?;
    let profiles = ProfileSet::embedded()?;
    let profile = profiles.get("adreno-7xx")?;
    let graph = common::realistic_frame(passes.div_ceil(10));
    let mut steps = 0;
    if args.next().as_deref() == Some("cached") {
        let mut cache = PlanCache::new();
        cache.compile(graph.clone(), profile)?;
        let mut reused = 0;
        for _ in 0..count {
            let frame = cache_once(&mut cache, std::hint::black_box(graph.clone()), profile)?;
            reused += usize::from(frame.reused);
        }
        println!(
            "{reused} of {count} frames of {} passes reused their plan",
            graph.pass_count()
        );
        return Ok(());
    }
    for _ in 0..count {
        let compiled = compile_once(std::hint::black_box(graph.clone()), profile)?;
        steps = compiled.plan.steps.len();
    }
    println!(
        "{count} compiles of {} passes: {steps} steps",
        graph.pass_count()
    );
    Ok(())
}
