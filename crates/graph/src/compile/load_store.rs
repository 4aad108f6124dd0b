//! `infer_load_store`: the work steps in execution order — a render pass per render group,
//! with its attachments, load/store ops, subpasses, preserve lists and subpass dependencies; a
//! compute or transfer step per other group; a flush where merging asked for one. Barriers come
//! next (`compile/barriers.rs`).
//!
//! Load: CLEAR when the first use in the render pass clears; DONT_CARE when that use does not
//! need the old content (it covers everything) or there is none; LOAD only when old content
//! exists and is needed. Store: STORE only when a later pass needs the content (it reads it
//! before overwriting it) or the resource is exported; DONT_CARE otherwise; NONE instead of
//! STORE when the render pass only read it (loaded, never written) and the profile has
//! `store_op_none`. Depth and stencil of a combined format get the same ops (seed 001:
//! invalidating only one of D24S8 has no effect).

use crate::declare::{PassDecl, PassId, ResourceDecl, ResourceId, UseKind};
use crate::plan::{
    Attachment, AttachmentIndex, AttachmentRef, FlushReason, InlineVec, RenderPass, Residency,
    Step, Subpass, SubpassDependency, SubpassIndex,
};
use crate::types::{
    AccessFlags, DependencyFlags, Extent2d, Layout, LoadOp, PipelineStages, StoreOp,
};

use super::access::{
    Access, PassAccesses, COLOR_ROLE, DEPTH_STENCIL_ROLES, INPUT_ROLE, RESOLVE_ROLE,
};
use super::lifetimes::ResourceUses;
use super::merge::{Group, GroupKind};

const NONE: u32 = u32::MAX;

/// Attachments a subpass binds (a resolve target only receives the resolve).
const ON_CHIP: u16 = COLOR_ROLE | DEPTH_STENCIL_ROLES | INPUT_ROLE;

/// Per-attachment bookkeeping while the subpasses of one render pass are laid out.
#[derive(Debug, Clone, Copy)]
struct AttachmentTrack {
    /// A later group needs the content (or it is exported).
    needed_after: bool,
    last_subpass: u32,
    last_stages: PipelineStages,
    layout: Layout,
    write: Option<(u32, PipelineStages, AccessFlags)>,
    /// Occupies tile memory (anything but a resolve target).
    on_chip: bool,
}

fn add_dependency(
    deps: &mut Vec<SubpassDependency>,
    src: u32,
    dst: u32,
    src_stages: PipelineStages,
    src_access: AccessFlags,
    dst_stages: PipelineStages,
    dst_access: AccessFlags,
) {
    if let Some(d) = deps
        .iter_mut()
        .find(|d| d.src_subpass.0 == src && d.dst_subpass.0 == dst)
    {
        d.src_stages |= src_stages;
        d.src_access |= src_access;
        d.dst_stages |= dst_stages;
        d.dst_access |= dst_access;
        return;
    }
    deps.push(SubpassDependency {
        src_subpass: SubpassIndex(src),
        dst_subpass: SubpassIndex(dst),
        src_stages,
        src_access,
        dst_stages,
        dst_access,
        flags: DependencyFlags::BY_REGION,
    });
}

/// Everything `infer_load_store` needs to read.
pub(crate) struct LoadStoreInput<'a> {
    pub groups: &'a [Group],
    pub order: &'a [PassId],
    pub accesses: &'a PassAccesses,
    pub passes: &'a [PassDecl],
    pub resources: &'a [ResourceDecl],
    pub residency: &'a [Residency],
    pub uses: &'a ResourceUses,
    /// The profile takes `StoreOp::None`.
    pub store_op_none: bool,
}

/// The work steps in execution order: one render pass per render group (with its attachments,
/// load/store ops, subpasses and dependencies), one compute or transfer step per other group,
/// and a flush before each group that asks for one.
pub(crate) fn infer_load_store(input: &LoadStoreInput<'_>) -> Vec<Step> {
    let content_from: Vec<u32> = input
        .resources
        .iter()
        .zip(&input.uses.resources)
        .map(|(r, u)| {
            if r.has_initial_content() {
                0
            } else {
                u.first_write.saturating_add(1)
            }
        })
        .collect();
    let mut tables = AttachmentTables {
        content_from,
        attachment_of: vec![(NONE, NONE); input.resources.len()],
        tracks: Vec::new(),
        readers: Vec::new(),
        order: Vec::new(),
    };
    let flushes = input.groups.iter().filter(|g| g.flush_before).count();
    let mut steps = Vec::with_capacity(input.groups.len() + flushes);
    for (g, group) in input.groups.iter().enumerate() {
        if group.flush_before {
            steps.push(Step::Flush(FlushReason::BeforeOcclusionQueries));
        }
        let first = input.order[group.start];
        steps.push(match group.kind {
            GroupKind::Render => {
                let mut rp = RenderPass::empty();
                build_render_pass(input, &mut tables, g as u32, group, &mut rp);
                Step::RenderPass(rp)
            }
            GroupKind::Compute => Step::Compute { pass: first },
            GroupKind::Transfer => Step::Transfer { pass: first },
        });
    }
    steps
}

/// Where each resource is attached and what each attachment has seen: per-frame tables, and
/// lists reused from one render pass to the next.
struct AttachmentTables {
    /// Per resource: the first group that sees content in it (0: imported with content; the
    /// group after its first writer; NONE: never).
    content_from: Vec<u32>,
    /// Per resource: (group, attachment index) of its attachment in the group's render pass.
    attachment_of: Vec<(u32, u32)>,
    tracks: Vec<AttachmentTrack>,
    readers: Vec<(u32, u32, PipelineStages)>,
    /// (first attachment use, access index) of the current pass's attachment accesses.
    order: Vec<(u32, u32)>,
}

fn build_render_pass(
    input: &LoadStoreInput<'_>,
    tables: &mut AttachmentTables,
    g: u32,
    group: &Group,
    rp: &mut RenderPass,
) {
    rp.render_area_px = group.render_area.unwrap_or(Extent2d::new(0, 0));
    let RenderPass {
        attachments,
        subpasses,
        dependencies: deps,
        ..
    } = rp;
    subpasses.reserve(group.end - group.start);
    deps.reserve(2 * (group.end - group.start).saturating_sub(1));
    let content_from = &tables.content_from;
    let attachment_of = &mut tables.attachment_of;
    let tracks = &mut tables.tracks;
    tracks.clear();
    // (attachment, subpass, stages) of reads since the attachment's last write.
    let readers = &mut tables.readers;
    readers.clear();

    for (s, &p) in input.order[group.start..group.end].iter().enumerate() {
        let s = s as u32;
        let decl = &input.passes[p.index()];
        let first_access = input.accesses.start_of(p);
        let accesses = input.accesses.of(p);
        // References are stored inline (up to 4 colours, 2 inputs) and spill only beyond that.
        let mut subpass = Subpass {
            pass: p,
            colors: InlineVec::new(),
            resolves: InlineVec::new(),
            depth_stencil: None,
            inputs: InlineVec::new(),
            preserve: InlineVec::new(),
        };
        let mut resolve_refs: Vec<(ResourceId, AttachmentRef)> = Vec::new();
        // The pass's attachment accesses, by their first attachment use.
        let order = &mut tables.order;
        order.clear();
        let mut mixed = false;
        for (k, a) in accesses.iter().enumerate() {
            if a.attachment() {
                // An access that began with a descriptor read (a sampled depth also tested) is
                // attached where its first attachment use is declared.
                let first = if a.non_attachment() {
                    mixed = true;
                    decl.uses
                        .iter()
                        .position(|u| u.resource == a.resource && u.kind.is_attachment())
                        .map_or(a.first_use, |i| i as u32)
                } else {
                    a.first_use
                };
                order.push((first, k as u32));
            }
        }
        if mixed {
            order.sort_unstable();
        }
        let mut inputs_reordered = false;
        for &(_, k) in order.iter() {
            let k = k as usize;
            let a = &accesses[k];
            let r = a.resource.index();
            let (seen_in, slot) = attachment_of[r];
            let index = if seen_in == g {
                slot
            } else {
                let index = attachments.len() as u32;
                attachment_of[r] = (g, index);
                attachments.push(new_attachment(input, decl, r, a, content_from[r] <= g));
                tracks.push(AttachmentTrack {
                    needed_after: input.uses.needed_after[first_access + k],
                    last_subpass: NONE,
                    last_stages: PipelineStages::NONE,
                    layout: a.layout,
                    write: None,
                    on_chip: false,
                });
                index
            };
            let reference = AttachmentRef {
                attachment: AttachmentIndex(index),
                layout: a.layout,
            };
            // Colours and resolve targets write: each is the resource's only use in the pass,
            // so colours come in declaration order. A read can share its access with other
            // reads (an input attachment that is also depth-tested).
            if a.roles & COLOR_ROLE != 0 {
                subpass.colors.push(reference);
            }
            if a.roles & DEPTH_STENCIL_ROLES != 0 {
                subpass.depth_stencil = Some(reference);
            }
            if a.roles & INPUT_ROLE != 0 {
                subpass.inputs.push(reference);
                inputs_reordered |= a.roles != INPUT_ROLE;
            }
            if a.roles & RESOLVE_ROLE != 0 {
                if let Some(UseKind::ResolveTarget { source }) =
                    decl.uses.get(a.first_use as usize).map(|u| u.kind)
                {
                    resolve_refs.push((source, reference));
                }
            }
            let track = &mut tracks[index as usize];
            track.on_chip |= a.roles & ON_CHIP != 0;
            debug_assert!(
                track.last_subpass != s,
                "two accesses to one resource in one pass"
            );
            // Used before and now, not in between: the subpasses between keep it.
            if track.last_subpass != NONE {
                for gap in (track.last_subpass + 1)..s {
                    subpasses[gap as usize]
                        .preserve
                        .push(AttachmentIndex(index));
                }
            }
            track_subpass_use(deps, readers, track, index, s, a);
            if let Some(att) = attachments.get_mut(index as usize) {
                att.final_layout = a.layout;
            }
        }
        if inputs_reordered && subpass.inputs.len() > 1 {
            // An input whose access began with another read: input indices follow the
            // declared input uses.
            let position = |reference: &AttachmentRef| {
                let resource = attachments[reference.attachment.0 as usize].resource;
                decl.uses.iter().position(|u| {
                    u.resource == resource && matches!(u.kind, UseKind::InputAttachment)
                })
            };
            subpass.inputs.sort_by_key(position);
        }
        if !resolve_refs.is_empty() {
            subpass.resolves = subpass
                .colors
                .iter()
                .map(|c| {
                    let color_resource = attachments[c.attachment.0 as usize].resource;
                    resolve_refs
                        .iter()
                        .find(|(source, _)| *source == color_resource)
                        .map(|(_, r)| *r)
                })
                .collect();
        }
        subpasses.push(subpass);
    }
    // Store: a render pass that only read the attachment (loaded, never written) ends with
    // NONE where the profile's drivers take it: no write-back, and no write either, so a pass
    // on the async compute queue may read the same depth meanwhile (DONT_CARE is a write the
    // store makes, and would wait for it). Unless nothing needs it after the render pass and a
    // subpass after its last use drops it (its content undefined there: as good as written).
    // Otherwise: does anything after this render pass need the content?
    let last_subpass = subpasses.len().saturating_sub(1) as u32;
    for (i, att) in attachments.iter_mut().enumerate() {
        let track = tables.tracks.get(i);
        let needed = track.is_some_and(|t| t.needed_after);
        let written = att.load_op != LoadOp::Load || track.is_none_or(|t| t.write.is_some());
        let kept_to_the_end = needed || track.is_some_and(|t| t.last_subpass == last_subpass);
        att.store_op = if !written && input.store_op_none && kept_to_the_end {
            StoreOp::None
        } else if !needed {
            StoreOp::DontCare
        } else {
            StoreOp::Store
        };
        if att.format.has_stencil() {
            // seed 001: depth and stencil of D24S8 are invalidated together or not at all.
            att.stencil_store_op = att.store_op;
        }
        // STORE and DONT_CARE write the attachment at the end of its last subpass: reads in
        // earlier subpasses since its last write must come before that write (a pass that
        // only tests depth after one that also tested it, and a depth nobody keeps).
        if att.store_op != StoreOp::None {
            if let Some(last) = track.map(|t| t.last_subpass).filter(|&l| l != NONE) {
                let (stages, access) = if att.format.is_depth_stencil() {
                    (
                        PipelineStages::LATE_FRAGMENT_TESTS,
                        AccessFlags::DEPTH_STENCIL_ATTACHMENT_WRITE,
                    )
                } else {
                    (
                        PipelineStages::COLOR_ATTACHMENT_OUTPUT,
                        AccessFlags::COLOR_ATTACHMENT_WRITE,
                    )
                };
                for &(att_index, rs, read_stages) in tables.readers.iter() {
                    if att_index == i as u32 && rs != last {
                        add_dependency(
                            deps,
                            rs,
                            last,
                            read_stages,
                            AccessFlags::NONE,
                            stages,
                            access,
                        );
                    }
                }
            }
        }
        // Kept after the render pass: every subpass after its last use preserves it. A
        // subpass that neither uses nor preserves an attachment, and depends on one that used
        // it, leaves its content undefined (VkSubpassDescription): the store would write back
        // garbage.
        if needed {
            let after = track.map_or(NONE, |t| t.last_subpass);
            if after != NONE {
                for later in subpasses.iter_mut().skip(after as usize + 1) {
                    later.preserve.push(AttachmentIndex(i as u32));
                }
            }
        }
    }
    // (Most lists have one entry or none: the sort call is skipped for them.)
    for subpass in subpasses.iter_mut().filter(|s| s.preserve.len() > 1) {
        subpass.preserve.sort_unstable();
    }
    if deps.len() > 1 {
        deps.sort_by_key(|d| (d.src_subpass, d.dst_subpass));
    }
    rp.on_chip_bytes_per_px = rp
        .attachments
        .iter()
        .zip(tables.tracks.iter())
        .filter(|(_, t)| t.on_chip)
        .map(|(a, _)| a.format.bytes_per_pixel() * a.samples.count())
        .sum();
}

fn new_attachment(
    input: &LoadStoreInput<'_>,
    decl: &PassDecl,
    r: usize,
    a: &Access,
    has_content: bool,
) -> Attachment {
    let desc = input.resources[r].desc.image().copied();
    let (format, samples) = match desc {
        Some(d) => (d.format, d.samples),
        // Validation only lets images be attachments.
        None => (
            crate::types::Format::R8G8B8A8_UNORM,
            crate::types::SampleCount::S1,
        ),
    };
    let clear = if a.clears() {
        decl.uses
            .get(a.first_use as usize)
            .and_then(|u| u.kind.clear_value())
    } else {
        None
    };
    let load_op = if clear.is_some() {
        LoadOp::Clear
    } else if a.reads_prior() && has_content {
        LoadOp::Load
    } else {
        LoadOp::DontCare
    };
    let stencil_load_op = if format.has_stencil() {
        // seed 001: depth and stencil of a combined format share the load op.
        load_op
    } else {
        LoadOp::DontCare
    };
    Attachment {
        resource: a.resource,
        format,
        samples,
        load_op,
        store_op: StoreOp::DontCare,
        stencil_load_op,
        stencil_store_op: StoreOp::DontCare,
        initial_layout: a.layout,
        final_layout: a.layout,
        clear: if load_op == LoadOp::Clear {
            clear
        } else {
            None
        },
        residency: input.residency[r],
    }
}

/// Adds the subpass dependencies that a use of an attachment in subpass `s` needs against its
/// earlier uses in the same render pass.
fn track_subpass_use(
    deps: &mut Vec<SubpassDependency>,
    readers: &mut Vec<(u32, u32, PipelineStages)>,
    track: &mut AttachmentTrack,
    index: u32,
    s: u32,
    a: &Access,
) {
    let reads = a.reads_prior() || a.explicit_read();
    let mut synced_last_user = false;
    if let Some((ws, stages, access)) = track.write {
        if ws != s {
            add_dependency(deps, ws, s, stages, access.writes(), a.stages, a.access);
            synced_last_user |= ws == track.last_subpass;
        }
    }
    if a.writes() {
        for &(att, rs, stages) in readers.iter() {
            if att == index && rs != s {
                add_dependency(deps, rs, s, stages, AccessFlags::NONE, a.stages, a.access);
                synced_last_user |= rs == track.last_subpass;
            }
        }
        readers.retain(|&(att, _, _)| att != index);
    }
    // A layout change between subpasses happens inside a dependency.
    if track.last_subpass != NONE && track.layout != a.layout && !synced_last_user {
        add_dependency(
            deps,
            track.last_subpass,
            s,
            track.last_stages,
            AccessFlags::NONE,
            a.stages,
            a.access,
        );
    }
    if a.writes() {
        track.write = Some((s, a.stages, a.access));
    } else if reads {
        readers.push((index, s, a.stages));
    }
    track.last_subpass = s;
    track.last_stages = a.stages;
    track.layout = a.layout;
}

#[cfg(test)]
mod tests {
    use crate::testing::*;
    use crate::*;

    /// Depth written by the pre-pass, tested read-only by a query pass in a render pass of its
    /// own (adreno-7xx, seed 001), then sampled by a post pass that also reads what the queries
    /// wrote: the query render pass keeps the depth with NONE instead of writing it back.
    #[test]
    fn a_render_pass_that_only_reads_an_attachment_keeps_it_without_a_store() {
        let frame = |profile: &tilegraph_profile::Profile| {
            let mut g = GraphBuilder::new();
            let depth = d24s8(&mut g, "depth");
            let color = rgba8(&mut g, "color");
            let out = swapchain(&mut g);
            g.raster_pass("prepass", PassClass::DepthPrepass, ())
                .depth_stencil_clear(depth, ClearDepthStencil::REVERSE_Z);
            g.raster_pass("opaque", PassClass::Opaque, ())
                .color_clear(color, ClearColor::BLACK)
                .depth_stencil_read_only(depth);
            let visible = g.create_buffer("visible", 1024);
            g.raster_pass("queries", PassClass::OcclusionQuery, ())
                .depth_stencil_read_only(depth)
                .storage_write(visible);
            g.raster_pass("fog", PassClass::Post, ())
                .storage_read(visible)
                .sampled(depth)
                .sampled(color)
                .color(out)
                .coverage(Coverage::Full);
            compile(g, profile)
        };
        let with_none = frame(&tiler());
        let depth = attachments(&with_none, "depth");
        assert_eq!(depth.len(), 2, "{with_none}");
        // Written in the first render pass: stored. Only read in the query pass: NONE.
        assert_eq!(depth[0].store_op, StoreOp::Store);
        assert_eq!(
            (
                depth[1].load_op,
                depth[1].store_op,
                depth[1].stencil_store_op
            ),
            (LoadOp::Load, StoreOp::None, StoreOp::None)
        );

        let mut without = tiler();
        without.render_pass.store_op_none = false;
        let stored = frame(&without);
        assert_eq!(attachments(&stored, "depth")[1].store_op, StoreOp::Store);
        // The write-back of one D24S8 image is all that differs.
        let depth_bytes = 4 * PIXELS;
        assert_eq!(
            stored.traffic.planned.total_bytes() - with_none.traffic.planned.total_bytes(),
            depth_bytes
        );
    }

    #[test]
    fn load_is_clear_dont_care_or_load_from_the_first_use() {
        let mut g = GraphBuilder::new();
        let cleared = rgba8(&mut g, "cleared");
        let covered = rgba8(&mut g, "covered");
        let kept = history(&mut g, "kept");
        let dropped = g.import_image(
            "dropped",
            ImageDesc::new(EXTENT, Format::R8G8B8A8_UNORM),
            Import::SWAPCHAIN,
        );
        for r in [cleared, covered, kept, dropped] {
            g.export(r);
        }
        g.raster_pass("a", PassClass::Opaque, ())
            .color_clear(cleared, ClearColor::BLACK);
        g.raster_pass("b", PassClass::Post, ())
            .color(covered)
            .coverage(Coverage::Full);
        // Blending over imported content that is kept: LOAD. Over discarded content: nothing to
        // load.
        g.raster_pass("c", PassClass::Transparent, ()).color(kept);
        g.raster_pass("d", PassClass::Transparent, ())
            .color(dropped);
        let plan = compile(g, &tiler());
        let load = |name| attachment(&plan, name).load_op;
        assert_eq!(load("cleared"), LoadOp::Clear);
        assert_eq!(
            attachment(&plan, "cleared").clear,
            Some(ClearValue::Color(ClearColor::BLACK))
        );
        assert_eq!(load("covered"), LoadOp::DontCare);
        assert_eq!(load("kept"), LoadOp::Load);
        assert_eq!(load("dropped"), LoadOp::DontCare);
    }

    #[test]
    fn store_only_what_a_later_pass_or_an_export_reads() {
        let mut g = GraphBuilder::new();
        let depth = d24s8(&mut g, "depth");
        let color = rgba8(&mut g, "color");
        let out = swapchain(&mut g);
        g.raster_pass("opaque", PassClass::Opaque, ())
            .color_clear(color, ClearColor::BLACK)
            .depth_stencil_clear(depth, ClearDepthStencil::REVERSE_Z);
        g.raster_pass("post", PassClass::Post, ())
            .sampled(color)
            .color(out)
            .coverage(Coverage::Full);
        let plan = compile(g, &tiler());
        assert_eq!(attachment(&plan, "color").store_op, StoreOp::Store);
        assert_eq!(attachment(&plan, "depth").store_op, StoreOp::DontCare);
        assert_eq!(attachment(&plan, "swapchain").store_op, StoreOp::Store);
    }

    #[test]
    fn content_overwritten_before_it_is_read_is_not_stored() {
        let mut g = GraphBuilder::new();
        let scratch = rgba8(&mut g, "scratch");
        let a = rgba8(&mut g, "a");
        let b = rgba8(&mut g, "b");
        g.export(a);
        g.export(b);
        g.raster_pass("first", PassClass::Opaque, ())
            .color_clear(scratch, ClearColor::BLACK)
            .color_clear(a, ClearColor::BLACK);
        g.raster_pass("second", PassClass::Opaque, ())
            .color_clear(scratch, ClearColor::TRANSPARENT);
        g.raster_pass("third", PassClass::Post, ())
            .sampled(scratch)
            .color(b)
            .coverage(Coverage::Full);
        let plan = compile(g, &tiler());
        let stores: Vec<StoreOp> = attachments(&plan, "scratch")
            .iter()
            .map(|a| a.store_op)
            .collect();
        assert_eq!(stores, [StoreOp::DontCare, StoreOp::Store]);
    }

    #[test]
    fn depth_and_stencil_are_invalidated_together() {
        // seed 001: invalidating only the depth or the stencil of D24S8 has no effect.
        for (format, stencil) in [
            (Format::D24_UNORM_S8_UINT, true),
            (Format::D32_SFLOAT_S8_UINT, true),
            (Format::D32_SFLOAT, false),
        ] {
            let mut g = GraphBuilder::new();
            let depth = g.create_image("depth", ImageDesc::new(EXTENT, format));
            let out = swapchain(&mut g);
            g.raster_pass("opaque", PassClass::Opaque, ())
                .color_clear(out, ClearColor::BLACK)
                .depth_stencil_clear(depth, ClearDepthStencil::REVERSE_Z);
            g.raster_pass("fog", PassClass::Post, ())
                .sampled(depth)
                .color(out);
            let plan = compile(g, &tiler());
            let a = attachment(&plan, "depth");
            assert_eq!((a.load_op, a.store_op), (LoadOp::Clear, StoreOp::Store));
            let expected = if stencil {
                (a.load_op, a.store_op)
            } else {
                (LoadOp::DontCare, StoreOp::DontCare)
            };
            assert_eq!(
                (a.stencil_load_op, a.stencil_store_op),
                expected,
                "{format}"
            );
        }
    }

    #[test]
    fn msaa_stays_on_chip_and_only_the_resolve_is_written() {
        let mut g = GraphBuilder::new();
        let msaa = g.create_image(
            "msaa",
            ImageDesc::new(EXTENT, Format::R8G8B8A8_UNORM).with_samples(SampleCount::S4),
        );
        let msaa_depth = g.create_image(
            "msaa_depth",
            ImageDesc::new(EXTENT, Format::D24_UNORM_S8_UINT).with_samples(SampleCount::S4),
        );
        let resolved = rgba8(&mut g, "resolved");
        g.export(resolved);
        g.raster_pass("opaque", PassClass::Opaque, ())
            .color_clear(msaa, ClearColor::BLACK)
            .depth_stencil_clear(msaa_depth, ClearDepthStencil::REVERSE_Z)
            .resolve(msaa, resolved);
        let plan = compile(g, &tiler());
        assert_eq!(attachment(&plan, "msaa").store_op, StoreOp::DontCare);
        assert_eq!(attachment(&plan, "msaa").residency, Residency::Transient);
        let r = attachment(&plan, "resolved");
        assert_eq!((r.load_op, r.store_op), (LoadOp::DontCare, StoreOp::Store));
        let Some((_, rp)) = plan.render_passes().next() else {
            panic!("no render pass")
        };
        let subpass = &rp.subpasses[0];
        assert_eq!(subpass.colors.len(), 1);
        assert_eq!(subpass.resolves.len(), 1);
        assert_eq!(
            subpass.resolves[0].map(|r| rp.attachments[r.attachment.0 as usize].resource),
            plan.resource_by_name("resolved").map(|r| r.id)
        );
        // Only the resolved image reaches memory; the resolve target takes no tile memory.
        assert_eq!(plan.traffic.planned.resolve_write_bytes, PIXELS * 4);
        assert_eq!(plan.traffic.planned.total_bytes(), PIXELS * 4);
        assert_eq!(rp.on_chip_bytes_per_px, 4 * 4 + 4 * 4);
    }

    #[test]
    fn preserved_attachments_and_subpass_dependencies() {
        let mut g = GraphBuilder::new();
        let depth = d24s8(&mut g, "depth");
        let color = rgba8(&mut g, "color");
        let out = swapchain(&mut g);
        g.raster_pass("prepass", PassClass::DepthPrepass, ())
            .depth_stencil_clear(depth, ClearDepthStencil::REVERSE_Z);
        g.raster_pass("opaque", PassClass::Opaque, ())
            .color_clear(color, ClearColor::BLACK)
            .depth_stencil_read_only(depth);
        g.raster_pass("post", PassClass::Post, ())
            .input(color)
            .color(out)
            .coverage(Coverage::Full);
        g.raster_pass("decals", PassClass::Post, ())
            .color(out)
            .depth_stencil_read_only(depth);
        let plan = compile(g, &tiler());
        let Some((_, rp)) = plan.render_passes().next() else {
            panic!("no render pass")
        };
        assert_eq!(rp.subpasses.len(), 4);
        // depth (attachment #0) is used by subpasses 0, 1 and 3: subpass 2 must keep it.
        assert_eq!(rp.subpasses[2].preserve.as_slice(), [AttachmentIndex(0)]);
        let deps: Vec<(u32, u32)> = rp
            .dependencies
            .iter()
            .map(|d| (d.src_subpass.0, d.dst_subpass.0))
            .collect();
        // (1, 3): depth is not kept (DONT_CARE), and that store is a write at the end of
        // subpass 3 that must come after subpass 1's depth test.
        assert_eq!(deps, [(0, 1), (0, 3), (1, 2), (1, 3), (2, 3)]);
        let store_dep = rp.dependencies[3];
        assert_eq!(store_dep.dst_stages, PipelineStages::LATE_FRAGMENT_TESTS);
        assert_eq!(
            store_dep.dst_access,
            AccessFlags::DEPTH_STENCIL_ATTACHMENT_WRITE
        );
        assert_eq!(store_dep.src_access, AccessFlags::NONE);
        let input_dep = rp.dependencies[2];
        assert_eq!(
            input_dep.src_stages,
            PipelineStages::COLOR_ATTACHMENT_OUTPUT
        );
        assert_eq!(input_dep.src_access, AccessFlags::COLOR_ATTACHMENT_WRITE);
        assert_eq!(input_dep.dst_stages, PipelineStages::FRAGMENT_SHADER);
        assert_eq!(input_dep.dst_access, AccessFlags::INPUT_ATTACHMENT_READ);
        assert_eq!(input_dep.flags, DependencyFlags::BY_REGION);
    }

    /// Attachment indices follow each image's first attachment use, also when its access
    /// began with a descriptor read (soft particles sample the depth they test).
    #[test]
    fn attachments_are_numbered_by_their_first_attachment_use() {
        let mut g = GraphBuilder::new();
        let depth = d24s8(&mut g, "depth");
        let out = swapchain(&mut g);
        g.raster_pass("prepass", PassClass::DepthPrepass, ())
            .depth_stencil_clear(depth, ClearDepthStencil::REVERSE_Z);
        g.raster_pass("particles", PassClass::Transparent, ())
            .sampled(depth)
            .color_clear(out, ClearColor::BLACK)
            .depth_stencil_read_only(depth);
        let plan = compile(g, &tiler());
        let Some((_, rp)) = plan.render_passes().nth(1) else {
            panic!("no second render pass: {plan}")
        };
        let names: Vec<&str> = rp
            .attachments
            .iter()
            .filter_map(|a| plan.resource(a.resource))
            .map(|r| r.name.as_str())
            .collect();
        assert_eq!(names, ["swapchain", "depth"], "{plan}");
        assert_eq!(
            rp.subpasses[0].depth_stencil.map(|r| r.attachment),
            Some(AttachmentIndex(1))
        );
    }

    /// Input attachment indices follow the declared input uses, also when an input's access
    /// began with another read of the same image (a depth buffer tested, then read as input).
    #[test]
    fn input_attachments_keep_their_declared_order() {
        let mut g = GraphBuilder::new();
        let depth = d24s8(&mut g, "depth");
        let color = rgba8(&mut g, "color");
        let out = swapchain(&mut g);
        g.raster_pass("gbuffer", PassClass::Opaque, ())
            .color_clear(color, ClearColor::BLACK)
            .depth_stencil_clear(depth, ClearDepthStencil::REVERSE_Z);
        g.raster_pass("lighting", PassClass::Post, ())
            .depth_stencil_read_only(depth)
            .input(color)
            .input(depth)
            .color(out)
            .coverage(Coverage::Full);
        let plan = compile(g, &tiler());
        let Some((_, rp)) = plan.render_passes().next() else {
            panic!("no render pass")
        };
        assert_eq!(rp.subpasses.len(), 2, "{plan}");
        let names = |refs: &[AttachmentRef]| -> Vec<String> {
            refs.iter()
                .filter_map(|r| plan.resource(rp.attachments[r.attachment.0 as usize].resource))
                .map(|r| r.name.clone())
                .collect()
        };
        assert_eq!(names(&rp.subpasses[1].inputs), ["color", "depth"]);
        assert_eq!(
            rp.subpasses[1].depth_stencil.map(|r| r.layout),
            Some(Layout::DepthStencilReadOnly)
        );
    }

    /// An attachment stored after the render pass must survive the subpasses after its last
    /// use: a later subpass that depends on one that used it, and neither uses nor preserves it,
    /// leaves its content undefined. Depth, exported here, ends its use in subpass 1.
    #[test]
    fn a_stored_attachment_is_preserved_after_its_last_use() {
        let frame = |export_depth: bool| {
            let (mut g, depth) = same_pixel_chain();
            if export_depth {
                g.export(depth);
            }
            compile(g, &tiler())
        };
        let plan = frame(true);
        let Some((_, rp)) = plan.render_passes().next() else {
            panic!("no render pass")
        };
        assert_eq!(rp.subpasses.len(), 3, "{plan}");
        let depth = rp
            .attachments
            .iter()
            .position(|a| plan.resource(a.resource).is_some_and(|r| r.name == "depth"))
            .map(|i| AttachmentIndex(i as u32));
        assert_eq!(attachment(&plan, "depth").store_op, StoreOp::Store);
        assert_eq!(
            rp.subpasses[2].preserve.as_slice(),
            depth.as_slice(),
            "{plan}"
        );
        // Not kept: nothing to preserve.
        let plan = frame(false);
        let Some((_, rp)) = plan.render_passes().next() else {
            panic!("no render pass")
        };
        assert_eq!(attachment(&plan, "depth").store_op, StoreOp::DontCare);
        assert!(rp.subpasses.iter().all(|s| s.preserve.is_empty()), "{plan}");
    }
}
