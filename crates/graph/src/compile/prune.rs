//! `prune_unused_passes`: keep what an export needs, drop the rest.
//!
//! The roots are the last writer of every exported resource and every pass declared with
//! `Retention::Always`; a pass is kept when a kept pass reads what it wrote (its producer).
//! Everything else is pruned, with the reason. This is how tilegraph models only what a scene
//! requires: a pass whose output nobody reads costs nothing.

use crate::declare::{PassDecl, PassId, ResourceId, Retention};
use crate::plan::PruneReason;

use super::access::PassAccesses;
use super::dataflow::Dataflow;

#[derive(Debug)]
pub(crate) struct Pruning {
    /// Per declared pass.
    pub alive: Vec<bool>,
    /// Pruned passes in declaration order.
    pub pruned: Vec<(PassId, PruneReason)>,
}

pub(crate) fn prune_unused_passes(
    dataflow: &Dataflow,
    accesses: &PassAccesses,
    passes: &[PassDecl],
    exports: &[ResourceId],
) -> Pruning {
    let n = passes.len();
    let mut alive = vec![false; n];
    let mut stack: Vec<usize> = Vec::with_capacity(n);
    fn keep(p: usize, alive: &mut [bool], stack: &mut Vec<usize>) {
        if !alive[p] {
            alive[p] = true;
            stack.push(p);
        }
    }
    for (p, pass) in passes.iter().enumerate() {
        if pass.retention == Retention::Always {
            keep(p, &mut alive, &mut stack);
        }
    }
    for &e in exports {
        if let Some(Some(w)) = dataflow.last_writer.get(e.index()) {
            keep(w.index(), &mut alive, &mut stack);
        }
    }
    while let Some(p) = stack.pop() {
        for w in dataflow.producers_of(p) {
            keep(w.index(), &mut alive, &mut stack);
        }
    }

    let dead = alive.iter().filter(|&&a| !a).count();
    let mut pruned = Vec::with_capacity(dead);
    if dead == 0 {
        return Pruning { alive, pruned };
    }
    // Consumers of pruned passes are pruned too (a kept consumer would have kept them): list,
    // per pruned producer, the pruned passes that read it, as (producer, consumer) pairs.
    let mut consumed: Vec<(u32, u32)> = Vec::new();
    for q in (0..n).filter(|&q| !alive[q]) {
        for w in dataflow.producers_of(q) {
            if !alive[w.index()] {
                consumed.push((w.0, q as u32));
            }
        }
    }
    consumed.sort_unstable();
    consumed.dedup();
    let mut next = 0;
    for p in (0..n).filter(|&p| !alive[p]) {
        let from = next;
        while consumed.get(next).is_some_and(|&(w, _)| w as usize == p) {
            next += 1;
        }
        let writes = accesses.of(PassId(p as u32)).iter().any(|a| a.writes());
        let reason = if !writes {
            PruneReason::NoOutputs
        } else if from == next {
            PruneReason::OutputsUnused
        } else {
            PruneReason::ConsumersPruned {
                consumers: consumed[from..next]
                    .iter()
                    .map(|&(_, q)| PassId(q))
                    .collect(),
            }
        };
        pruned.push((PassId(p as u32), reason));
    }
    Pruning { alive, pruned }
}

#[cfg(test)]
mod tests {
    use crate::testing::*;
    use crate::*;

    fn pruned(plan: &Plan) -> Vec<(&str, &PruneReason)> {
        plan.pruned
            .iter()
            .map(|c| (c.name.as_str(), &c.reason))
            .collect()
    }

    #[test]
    fn passes_whose_writes_reach_no_export_are_pruned_with_the_reason() {
        let mut g = GraphBuilder::new();
        let ssao = rgba8(&mut g, "ssao");
        let blurred = rgba8(&mut g, "ssao_blurred");
        let debug = rgba8(&mut g, "debug");
        let out = swapchain(&mut g);
        let ssao_pass = g
            .raster_pass("ssao", PassClass::Other, ())
            .color_clear(ssao, ClearColor::BLACK)
            .id();
        let blur = g
            .raster_pass("ssao_blur", PassClass::Other, ())
            .sampled(ssao)
            .color(blurred)
            .coverage(Coverage::Full)
            .id();
        g.raster_pass("stats", PassClass::Other, ())
            .sampled(ssao)
            .render_area(EXTENT);
        g.raster_pass("debug", PassClass::Other, ())
            .color_clear(debug, ClearColor::BLACK);
        g.raster_pass("post", PassClass::Post, ())
            .color_clear(out, ClearColor::BLACK);
        let plan = compile(g, &tiler());
        assert_eq!(order(&plan), ["post"]);
        assert_eq!(
            pruned(&plan),
            [
                (
                    "ssao",
                    &PruneReason::ConsumersPruned {
                        consumers: vec![blur, PassId(2)]
                    }
                ),
                ("ssao_blur", &PruneReason::OutputsUnused),
                ("stats", &PruneReason::NoOutputs),
                ("debug", &PruneReason::OutputsUnused),
            ]
        );
        assert_eq!(plan.pruned[0].id, ssao_pass);
        // What pruned passes alone used is not allocated.
        for name in ["ssao", "ssao_blurred", "debug"] {
            let r = plan.resource_by_name(name).map(|r| (r.residency, r.memory));
            assert_eq!(r, Some((Residency::Unused, None)), "{name}");
        }
    }

    #[test]
    fn a_write_overwritten_before_anyone_reads_it_is_pruned() {
        let mut g = GraphBuilder::new();
        let out = swapchain(&mut g);
        g.raster_pass("splash", PassClass::Other, ())
            .color_clear(out, ClearColor::BLACK);
        g.raster_pass("post", PassClass::Post, ())
            .color(out)
            .coverage(Coverage::Full);
        let plan = compile(g, &tiler());
        assert_eq!(order(&plan), ["post"]);
        assert_eq!(pruned(&plan), [("splash", &PruneReason::OutputsUnused)]);
    }

    #[test]
    fn drawing_over_old_content_keeps_its_writer() {
        let mut g = GraphBuilder::new();
        let out = swapchain(&mut g);
        g.raster_pass("scene", PassClass::Opaque, ())
            .color_clear(out, ClearColor::BLACK);
        g.raster_pass("ui", PassClass::Post, ()).color(out);
        let plan = compile(g, &tiler());
        assert_eq!(order(&plan), ["scene", "ui"]);
        assert!(plan.pruned.is_empty());
    }

    #[test]
    fn passes_with_effects_outside_the_graph_are_kept() {
        let mut g = GraphBuilder::new();
        let depth = d24s8(&mut g, "depth");
        let out = swapchain(&mut g);
        g.raster_pass("prepass", PassClass::DepthPrepass, ())
            .depth_stencil_clear(depth, ClearDepthStencil::REVERSE_Z);
        g.raster_pass("queries", PassClass::OcclusionQuery, ())
            .depth_stencil_read_only(depth)
            .retention(Retention::Always);
        g.raster_pass("post", PassClass::Post, ())
            .color_clear(out, ClearColor::BLACK);
        let plan = compile(g, &tiler());
        // Kept although nothing reads what it writes; the profile's class order puts occlusion
        // queries last (seed 001), after post, so post can share the scene's render pass.
        assert_eq!(order(&plan), ["prepass", "post", "queries"]);
    }

    #[test]
    fn pruned_payloads_are_dropped_and_the_rest_come_back_in_plan_order() {
        let mut g: GraphBuilder<&str> = GraphBuilder::new();
        let tmp = g.create_image("tmp", ImageDesc::new(EXTENT, Format::R8G8B8A8_UNORM));
        let out = g.import_image(
            "swapchain",
            ImageDesc::new(EXTENT, Format::B8G8R8A8_SRGB),
            Import::SWAPCHAIN,
        );
        g.export(out);
        let unused = g
            .raster_pass("unused", PassClass::Other, "unused payload")
            .color_clear(tmp, ClearColor::BLACK)
            .id();
        let post = g
            .raster_pass("post", PassClass::Post, "post payload")
            .color_clear(out, ClearColor::BLACK)
            .id();
        let mut compiled = g.compile(&tiler()).unwrap();
        assert_eq!(compiled.payload(unused), None);
        assert_eq!(compiled.payload(post), Some(&"post payload"));
        assert_eq!(compiled.take_payload(post), Some("post payload"));
        assert_eq!(compiled.payload(post), None);
    }
}
