//! `merge_render_passes`: group consecutive raster passes into render passes.
//!
//! A raster pass joins the render pass before it when the profile allows merging, the render
//! areas are equal, it shares at least one attachment with the render pass (merging unrelated
//! passes saves no traffic and only grows the tile footprint), and every resource the two share
//! is touched only as an attachment by both (so any read of the earlier pass's output is an
//! input-attachment or attachment read at the same pixel), or only read through descriptors by
//! both, in one layout (a texture both sample). A descriptor read of what another subpass uses
//! as an attachment splits the render pass: it would be outside the attachment's subpass
//! dependencies and its store op. A clear in a later subpass cannot be a load op, so it starts
//! a new render pass. On tilers this keeps intermediate attachments in tile
//! memory; on immediate GPUs (`MergePolicy::Allowed`) the same merge is harmless and keeps plans
//! alike across profiles.
//!
//! Occlusion-query passes, when the profile wants them in a render pass of their own, never
//! share one with other passes, and with `flush_before` a flush precedes them (seed 001).

use tilegraph_profile::{MergePolicy, PassClass, Profile};

use crate::declare::{PassDecl, PassId, PassKind, ResourceId};
use crate::plan::{MergeNote, MergeReason};
use crate::types::{Extent2d, Layout};

use super::validate::Validated;

const NONE: u32 = u32::MAX;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum GroupKind {
    Render,
    Compute,
    Transfer,
}

/// One future step: a render pass of `order[start..end]`, or one compute or transfer pass.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Group {
    pub kind: GroupKind,
    pub start: usize,
    pub end: usize,
    pub render_area: Option<Extent2d>,
    /// Submit before this group.
    pub flush_before: bool,
    /// Every pass in it is of class `OcclusionQuery`.
    pub queries_only: bool,
}

/// How the current render pass touches a resource.
#[derive(Debug, Clone, Copy)]
struct Touch {
    group: u32,
    attachment: bool,
    non_attachment: bool,
    written: bool,
    layout: Layout,
}

fn is_query(pass: &PassDecl) -> bool {
    pass.class == PassClass::OcclusionQuery
}

pub(crate) fn merge_render_passes(
    order: &[PassId],
    validated: &Validated,
    passes: &[PassDecl],
    n_resources: usize,
    profile: &Profile,
) -> (Vec<Group>, Vec<MergeNote>) {
    let policy = &profile.render_pass;
    let queries_alone = profile.passes.occlusion_queries.own_render_pass;
    let mut touch = vec![
        Touch {
            group: NONE,
            attachment: false,
            non_attachment: false,
            written: false,
            layout: Layout::Undefined,
        };
        n_resources
    ];
    let mut groups: Vec<Group> = Vec::with_capacity(order.len());
    let mut notes: Vec<MergeNote> = Vec::new();
    // The last raster pass so far.
    let mut last_raster: Option<PassId> = None;
    for (i, &id) in order.iter().enumerate() {
        let p = id.index();
        let pass = &passes[p];
        let area = validated.render_areas[p];
        let verdict: Option<Result<ResourceId, MergeReason>> = match groups.last() {
            _ if pass.kind != PassKind::Raster => None,
            Some(g) if g.kind == GroupKind::Render => {
                Some(if policy.merge_subpasses == MergePolicy::Never {
                    Err(MergeReason::MergingOff)
                } else if g.render_area != area {
                    Err(MergeReason::RenderArea)
                } else if queries_alone && g.queries_only != is_query(pass) {
                    Err(MergeReason::QueriesApart)
                } else {
                    let g_index = (groups.len() - 1) as u32;
                    let mut shared = None;
                    let mut refusal = None;
                    for a in validated.accesses.of(id) {
                        let t = &touch[a.resource.index()];
                        if t.group != g_index {
                            continue;
                        }
                        if a.clears() {
                            refusal = Some(MergeReason::Clears(a.resource));
                            break;
                        }
                        let same_pixel = !a.non_attachment() && !t.non_attachment;
                        // Otherwise both only read it through descriptors, in one layout. A
                        // descriptor read in one subpass of what is an attachment in another would
                        // be outside the attachment's subpass dependencies and its store op.
                        let shared_reads = !a.writes()
                            && !t.written
                            && a.layout == t.layout
                            && !a.attachment()
                            && !t.attachment;
                        if same_pixel {
                            shared.get_or_insert(a.resource);
                        } else if !shared_reads {
                            refusal = Some(MergeReason::DescriptorAccess(a.resource));
                            break;
                        }
                    }
                    match (refusal, shared) {
                        (Some(r), _) => Err(r),
                        // A pass that shares no attachment with the render pass gains nothing from
                        // joining it and would only add to its tile-memory footprint.
                        (None, None) => Err(MergeReason::NothingShared),
                        (None, Some(r)) => Ok(r),
                    }
                })
            }
            _ => Some(Err(MergeReason::NotAdjacent)),
        };
        if let (Some(v), Some(after)) = (verdict, last_raster) {
            notes.push(MergeNote {
                pass: id,
                after,
                joined: v.is_ok(),
                reason: match v {
                    Ok(r) => MergeReason::SharesAttachment(r),
                    Err(reason) => reason,
                },
            });
        }
        if pass.kind == PassKind::Raster {
            last_raster = Some(id);
        }
        let joins = matches!(verdict, Some(Ok(_)));
        if joins {
            if let Some(g) = groups.last_mut() {
                g.end = i + 1;
                g.queries_only &= is_query(pass);
            }
        } else {
            groups.push(Group {
                kind: match pass.kind {
                    PassKind::Raster => GroupKind::Render,
                    PassKind::Compute => GroupKind::Compute,
                    PassKind::Transfer => GroupKind::Transfer,
                },
                start: i,
                end: i + 1,
                render_area: area,
                flush_before: false,
                queries_only: is_query(pass),
            });
        }
        // Only a render pass can be joined: a compute or transfer group's touches are never
        // looked at.
        if pass.kind != PassKind::Raster {
            continue;
        }
        let g_index = (groups.len() - 1) as u32;
        for a in validated.accesses.of(id) {
            let t = &mut touch[a.resource.index()];
            if t.group != g_index {
                *t = Touch {
                    group: g_index,
                    attachment: a.attachment(),
                    non_attachment: a.non_attachment(),
                    written: a.writes(),
                    layout: a.layout,
                };
            } else {
                t.attachment |= a.attachment();
                t.non_attachment |= a.non_attachment();
                t.written |= a.writes();
                t.layout = a.layout;
            }
        }
    }

    // seed 001: "遮挡查询, 前面加一个flush" — submit before the query render pass.
    if profile.passes.occlusion_queries.flush_before {
        for i in 1..groups.len() {
            if groups[i].queries_only && !groups[i - 1].queries_only {
                groups[i].flush_before = true;
            }
        }
    }
    (groups, notes)
}

#[cfg(test)]
mod tests {
    use crate::testing::*;
    use crate::*;

    /// Subpass pass names of each render pass.
    fn render_passes(plan: &Plan) -> Vec<Vec<&str>> {
        plan.render_passes()
            .map(|(_, rp)| {
                rp.subpasses
                    .iter()
                    .map(|s| plan.pass(s.pass).map_or("?", |p| p.name.as_str()))
                    .collect()
            })
            .collect()
    }

    #[test]
    fn same_pixel_chains_merge_unless_the_profile_says_never() {
        let merged = [vec!["prepass", "opaque", "post"]];
        assert_eq!(
            render_passes(&compile(same_pixel_chain().0, &tiler())),
            merged
        );
        // Immediate GPUs: allowed, and done the same way.
        assert_eq!(
            render_passes(&compile(same_pixel_chain().0, &desktop())),
            merged
        );
        assert_eq!(
            render_passes(&compile(same_pixel_chain().0, &never_merge())),
            [vec!["prepass"], vec!["opaque"], vec!["post"]]
        );
    }

    #[test]
    fn sampling_an_earlier_output_splits_the_render_pass() {
        let mut g = GraphBuilder::new();
        let color = rgba8(&mut g, "color");
        let out = swapchain(&mut g);
        g.raster_pass("opaque", PassClass::Opaque, ())
            .color_clear(color, ClearColor::BLACK);
        g.raster_pass("blur", PassClass::Post, ())
            .sampled(color)
            .color(out)
            .coverage(Coverage::Full);
        assert_eq!(
            render_passes(&compile(g, &tiler())),
            [vec!["opaque"], vec!["blur"]]
        );
    }

    /// A subpass may sample what another subpass reads as a depth attachment only in a render
    /// pass of its own: the sampler read would be outside the attachment's subpass
    /// dependencies, and its store op could discard the depth before the read. Plain texture
    /// reads shared by both subpasses still merge.
    #[test]
    fn sampling_another_subpasses_attachment_splits_the_render_pass() {
        let mut g = GraphBuilder::new();
        let depth = d24s8(&mut g, "depth");
        let env = history(&mut g, "environment");
        let out = swapchain(&mut g);
        let ao = rgba8(&mut g, "ao");
        g.export(ao);
        g.raster_pass("prepass", PassClass::DepthPrepass, ())
            .depth_stencil_clear(depth, ClearDepthStencil::REVERSE_Z);
        g.compute_pass("ao", PassClass::Compute, ())
            .sampled(depth)
            .storage_write(ao);
        g.raster_pass("opaque", PassClass::Opaque, ())
            .color_clear(out, ClearColor::BLACK)
            .sampled(env)
            .depth_stencil_read_only(depth);
        g.raster_pass("fog", PassClass::Transparent, ())
            .color(out)
            .sampled(env)
            .sampled(depth);
        let plan = compile(g, &tiler());
        assert_eq!(
            render_passes(&plan),
            [vec!["prepass"], vec!["opaque"], vec!["fog"]]
        );

        let mut g = GraphBuilder::new();
        let env = history(&mut g, "environment");
        let out = swapchain(&mut g);
        g.raster_pass("opaque", PassClass::Opaque, ())
            .color_clear(out, ClearColor::BLACK)
            .sampled(env);
        g.raster_pass("fog", PassClass::Transparent, ())
            .color(out)
            .sampled(env);
        assert_eq!(
            render_passes(&compile(g, &tiler())),
            [vec!["opaque", "fog"]]
        );
    }

    #[test]
    fn an_input_attachment_must_match_the_render_area() {
        let mut g = GraphBuilder::new();
        let color = rgba8(&mut g, "color");
        let half = g.create_image(
            "half",
            ImageDesc::new(Extent2d::new(32, 16), Format::R8G8B8A8_UNORM),
        );
        g.export(half);
        g.raster_pass("opaque", PassClass::Opaque, ())
            .color_clear(color, ClearColor::BLACK);
        g.raster_pass("downsample", PassClass::Post, ())
            .input(color)
            .color(half)
            .coverage(Coverage::Full);
        let err = compile_err(g, &tiler());
        // The input attachment must match the render area too: an input read is at the same
        // pixel.
        assert!(matches!(err, GraphError::ExtentMismatch { .. }), "{err}");
    }

    #[test]
    fn a_clear_after_the_first_subpass_starts_a_render_pass() {
        let mut g = GraphBuilder::new();
        let depth = d24s8(&mut g, "depth");
        let out = swapchain(&mut g);
        g.raster_pass("world", PassClass::Opaque, ())
            .color_clear(out, ClearColor::BLACK)
            .depth_stencil_clear(depth, ClearDepthStencil::REVERSE_Z);
        // The weapon view model clears depth and draws over the world.
        g.raster_pass("view_model", PassClass::Transparent, ())
            .color(out)
            .depth_stencil_clear(depth, ClearDepthStencil::REVERSE_Z);
        let plan = compile(g, &tiler());
        assert_eq!(render_passes(&plan), [vec!["world"], vec!["view_model"]]);
        assert_eq!(attachments(&plan, "depth")[0].store_op, StoreOp::DontCare);
    }

    #[test]
    fn unrelated_passes_of_one_size_stay_apart() {
        let mut g = GraphBuilder::new();
        let a = rgba8(&mut g, "a");
        let b = rgba8(&mut g, "b");
        g.export(a);
        g.export(b);
        g.raster_pass("one", PassClass::Opaque, ())
            .color_clear(a, ClearColor::BLACK);
        g.raster_pass("two", PassClass::Opaque, ())
            .color_clear(b, ClearColor::BLACK);
        assert_eq!(
            render_passes(&compile(g, &tiler())),
            [vec!["one"], vec!["two"]]
        );
    }

    fn frame_with_queries() -> GraphBuilder<()> {
        let mut g = GraphBuilder::new();
        let depth = d24s8(&mut g, "depth");
        let out = swapchain(&mut g);
        g.raster_pass("opaque", PassClass::Opaque, ())
            .color_clear(out, ClearColor::BLACK)
            .depth_stencil_clear(depth, ClearDepthStencil::REVERSE_Z);
        g.raster_pass("queries", PassClass::OcclusionQuery, ())
            .depth_stencil_read_only(depth)
            .retention(Retention::Always);
        g.raster_pass("transparent", PassClass::Transparent, ())
            .color(out)
            .depth_stencil_read_only(depth);
        g
    }

    #[test]
    fn occlusion_queries_get_their_own_render_pass_after_a_flush_on_adreno() {
        // seed 001: queries in a render pass of their own, after a flush, so the driver picks
        // direct mode for it.
        let plan = compile(frame_with_queries(), &tiler());
        assert_eq!(
            render_passes(&plan),
            [vec!["opaque", "transparent"], vec!["queries"]]
        );
        let kinds: Vec<&str> = plan.steps.iter().map(Step::name).collect();
        let flush = kinds.iter().position(|&k| k == "flush");
        let queries = plan.pass_by_name("queries").map(|p| p.step.index());
        assert!(
            matches!((flush, queries), (Some(f), Some(q)) if f < q && f > 0),
            "{kinds:?}"
        );
        // Depth now leaves the first render pass for the queries: the plan shows the cost.
        assert_eq!(attachments(&plan, "depth")[0].store_op, StoreOp::Store);
        assert_eq!(attachments(&plan, "depth")[1].load_op, LoadOp::Load);

        // Mali keeps queries with the drawing: one render pass, no flush.
        let mali = compile(frame_with_queries(), &profile("mali-valhall"));
        assert_eq!(
            render_passes(&mali),
            [vec!["opaque", "transparent", "queries"]]
        );
        assert!(!mali.steps.iter().any(|s| matches!(s, Step::Flush(_))));
    }
}
