//! `resource_lifetimes`: what each resource's uses add up to, walked in execution order once
//! the passes are grouped into steps — its first and last group (what aliasing places), its use
//! roles (its usage flags), whether every use is an attachment, the first group that writes it,
//! and for each group that uses it whether a later group needs what it leaves (what the store
//! op will ask). Then `residencies` says where each resource's memory comes from and
//! `infer_usage` which usage flags it is created with.

use tilegraph_profile::Profile;

use crate::declare::{Origin, PassId, ResourceDecl, ResourceDesc, ResourceId, UseKind};
use crate::plan::{Residency, Usage};
use crate::types::{BufferUsage, ImageUsage};

use super::access::{role, PassAccesses};
use super::dataflow::Dataflow;
use super::merge::{Group, GroupKind};

const NONE: u32 = u32::MAX;

/// One resource's uses in execution order, summarized.
#[derive(Debug, Clone, Copy)]
pub(crate) struct ResourceUse {
    /// First and last group (`NONE`: unused).
    first: u32,
    last: u32,
    /// Every use binds it to a render pass.
    pub attachment_only: bool,
    /// [`UseKind::bit`](crate::declare::UseKind) of every use by a kept pass.
    pub roles: u16,
    /// First group that writes it (`NONE`: none does).
    pub first_write: u32,
    /// The access (index into `PassAccesses::accesses`) that began its use in group `last`.
    last_group_start: u32,
}

impl ResourceUse {
    /// First and last group that use it (`None`: unused).
    pub fn lifetime(&self) -> Option<(u32, u32)> {
        (self.last != NONE).then_some((self.first, self.last))
    }
}

/// What later phases need from each resource's uses in execution order.
#[derive(Debug)]
pub(crate) struct ResourceUses {
    /// Per resource.
    pub resources: Vec<ResourceUse>,
    /// Per access (index into `PassAccesses::accesses`) that begins a group's use of a resource:
    /// the content is needed after the group (the next group that uses it reads it first, or
    /// its content outlives the frame: exported, or imported and only read). A group's later
    /// accesses to the resource are not set.
    pub needed_after: Vec<bool>,
}

/// Each resource's uses in execution order: group after group, pass after pass, every
/// surviving access. `kept_at_end` (per resource): its content must outlive the frame, so the
/// group that uses it last leaves content that is needed.
pub(crate) fn resource_lifetimes(
    groups: &[Group],
    order: &[PassId],
    accesses: &PassAccesses,
    n_resources: usize,
    kept_at_end: &[bool],
) -> ResourceUses {
    let mut uses = ResourceUses {
        resources: vec![
            ResourceUse {
                first: NONE,
                last: NONE,
                attachment_only: true,
                roles: 0,
                first_write: NONE,
                last_group_start: NONE,
            };
            n_resources
        ],
        needed_after: vec![false; accesses.accesses.len()],
    };
    for (g, group) in groups.iter().enumerate() {
        let g = g as u32;
        for &p in &order[group.start..group.end] {
            let first_access = accesses.start_of(p);
            for (k, a) in accesses.of(p).iter().enumerate() {
                let s = &mut uses.resources[a.resource.index()];
                if s.last != g {
                    // The group's first use of the resource decides whether the group before
                    // needed what it left.
                    match uses.needed_after.get_mut(s.last_group_start as usize) {
                        Some(needed) => *needed = a.reads_prior(),
                        None => s.first = g,
                    }
                    s.last = g;
                    s.last_group_start = (first_access + k) as u32;
                }
                s.attachment_only &= !a.non_attachment();
                s.roles |= a.roles;
                if a.writes() && s.first_write == NONE {
                    s.first_write = g;
                }
            }
        }
    }
    // After its last group, a resource's content is needed when it must outlive the frame.
    for (s, &kept) in uses.resources.iter().zip(kept_at_end) {
        if let Some(needed) = uses.needed_after.get_mut(s.last_group_start as usize) {
            *needed = kept;
        }
    }
    uses
}

/// Where each resource's memory comes from.
pub(crate) fn residencies(
    uses: &ResourceUses,
    groups: &[Group],
    resources: &[ResourceDecl],
    exported: &[bool],
    profile: &Profile,
) -> Vec<Residency> {
    resources
        .iter()
        .enumerate()
        .map(|(r, decl)| {
            let life = uses.resources[r].lifetime();
            if matches!(decl.origin, Origin::Imported(_)) {
                Residency::Imported
            } else if life.is_none() {
                Residency::Unused
            } else if exported[r] {
                Residency::Exported
            } else {
                let one_render_pass = life.is_some_and(|(first, last)| {
                    first == last && groups[first as usize].kind == GroupKind::Render
                });
                if one_render_pass
                    && uses.resources[r].attachment_only
                    && profile.render_pass.transient_attachments
                {
                    Residency::Transient
                } else {
                    Residency::FrameLocal
                }
            }
        })
        .collect()
}

/// Per resource: its content must outlive the frame. Exports, and imported content that no
/// surviving pass writes: the frame only read it, and a read must not cost the caller what it
/// imported (a static depth buffer tested by decals would otherwise end with a DONT_CARE store).
pub(crate) fn content_kept_at_end(
    resources: &[ResourceDecl],
    exported: &[bool],
    dataflow: &Dataflow,
    alive: &[bool],
    accesses: &PassAccesses,
) -> Vec<bool> {
    let mut kept = exported.to_vec();
    let mut ambiguous = false;
    for (r, decl) in resources.iter().enumerate() {
        // Store ops exist for attachments only, hence images only.
        if kept[r] || decl.desc.image().is_none() || !decl.has_initial_content() {
            continue;
        }
        // The last declared writer tells, unless it was pruned (an earlier one may survive).
        match dataflow.last_writer[r] {
            None => kept[r] = true,
            Some(w) if alive.get(w.index()).copied().unwrap_or(false) => {}
            Some(_) => {
                kept[r] = true;
                ambiguous = true;
            }
        }
    }
    if ambiguous {
        for (p, _) in alive.iter().enumerate().filter(|(_, &a)| a) {
            for a in accesses.of(PassId(p as u32)) {
                if a.writes() && !exported[a.resource.index()] {
                    kept[a.resource.index()] = false;
                }
            }
        }
    }
    kept
}

/// Usage flags from the roles of every surviving access.
pub(crate) fn infer_usage(desc: &ResourceDesc, roles: u16, residency: Residency) -> Usage {
    let has = |kind: UseKind| roles & role(kind) != 0;
    match desc {
        ResourceDesc::Image(_) => {
            let mut u = ImageUsage::NONE;
            if has(UseKind::ColorAttachment { clear: None })
                || has(UseKind::ResolveTarget {
                    source: ResourceId(0),
                })
            {
                u |= ImageUsage::COLOR_ATTACHMENT;
            }
            if has(UseKind::DepthStencilAttachment { clear: None })
                || has(UseKind::DepthStencilReadOnly)
            {
                u |= ImageUsage::DEPTH_STENCIL_ATTACHMENT;
            }
            if has(UseKind::InputAttachment) {
                u |= ImageUsage::INPUT_ATTACHMENT;
            }
            if has(UseKind::Sampled) {
                u |= ImageUsage::SAMPLED;
            }
            if has(UseKind::StorageRead)
                || has(UseKind::StorageWrite)
                || has(UseKind::StorageReadWrite)
            {
                u |= ImageUsage::STORAGE;
            }
            if has(UseKind::TransferSrc) {
                u |= ImageUsage::TRANSFER_SRC;
            }
            if has(UseKind::TransferDst) {
                u |= ImageUsage::TRANSFER_DST;
            }
            if residency == Residency::Transient {
                u |= ImageUsage::TRANSIENT_ATTACHMENT;
            }
            Usage::Image(u)
        }
        ResourceDesc::Buffer(_) => {
            let mut u = BufferUsage::NONE;
            if has(UseKind::Uniform) {
                u |= BufferUsage::UNIFORM_BUFFER;
            }
            if has(UseKind::StorageRead)
                || has(UseKind::StorageWrite)
                || has(UseKind::StorageReadWrite)
            {
                u |= BufferUsage::STORAGE_BUFFER;
            }
            if has(UseKind::Vertex) {
                u |= BufferUsage::VERTEX_BUFFER;
            }
            if has(UseKind::Index) {
                u |= BufferUsage::INDEX_BUFFER;
            }
            if has(UseKind::Indirect) {
                u |= BufferUsage::INDIRECT_BUFFER;
            }
            if has(UseKind::ConditionalPredicate) {
                u |= BufferUsage::CONDITIONAL_RENDERING;
            }
            if has(UseKind::TransferSrc) {
                u |= BufferUsage::TRANSFER_SRC;
            }
            if has(UseKind::TransferDst) {
                u |= BufferUsage::TRANSFER_DST;
            }
            Usage::Buffer(u)
        }
    }
}

#[cfg(test)]
mod tests {
    use crate::testing::*;
    use crate::*;

    /// A static depth buffer (baked once, imported every frame with its content) that the frame
    /// only tests against: nothing in the frame changed it, so nothing may discard it, exported
    /// or not. Written by the frame and not exported, it is the caller's to lose.
    #[test]
    fn an_import_the_frame_only_reads_keeps_its_content() {
        let frame = |write_it: bool, profile: &tilegraph_profile::Profile| {
            let mut g = GraphBuilder::new();
            let baked = g.import_image(
                "baked_depth",
                ImageDesc::new(EXTENT, Format::D24_UNORM_S8_UINT),
                Import {
                    initial: ResourceState::image(
                        Layout::DepthStencilReadOnly,
                        PipelineStages::NONE,
                        AccessFlags::NONE,
                    ),
                    content: InitialContent::Preserve,
                    final_state: ResourceState::image(
                        Layout::DepthStencilReadOnly,
                        PipelineStages::NONE,
                        AccessFlags::NONE,
                    ),
                },
            );
            let out = swapchain(&mut g);
            if write_it {
                g.raster_pass("stamp", PassClass::Opaque, ())
                    .depth_stencil(baked);
            }
            g.raster_pass("decals", PassClass::Transparent, ())
                .depth_stencil_read_only(baked)
                .color(out)
                .coverage(Coverage::Full);
            compile(g, profile)
        };
        let mut no_none = tiler();
        no_none.render_pass.store_op_none = false;
        for (profile, kept) in [(tiler(), StoreOp::None), (no_none, StoreOp::Store)] {
            let plan = frame(false, &profile);
            let baked = attachment(&plan, "baked_depth");
            assert_eq!(baked.load_op, LoadOp::Load, "{plan}");
            assert_eq!(
                (baked.store_op, baked.stencil_store_op),
                (kept, kept),
                "{plan}"
            );
        }
        let written = frame(true, &tiler());
        assert_eq!(
            attachment(&written, "baked_depth").store_op,
            StoreOp::DontCare,
            "{written}"
        );

        // A later writer that is pruned changes nothing: what survives decides.
        for survivor_writes in [false, true] {
            let mut g = GraphBuilder::new();
            let baked = g.import_image(
                "baked_depth",
                ImageDesc::new(EXTENT, Format::D24_UNORM_S8_UINT),
                Import {
                    initial: ResourceState::image(
                        Layout::DepthStencilAttachment,
                        PipelineStages::NONE,
                        AccessFlags::NONE,
                    ),
                    content: InitialContent::Preserve,
                    final_state: ResourceState::image(
                        Layout::DepthStencilAttachment,
                        PipelineStages::NONE,
                        AccessFlags::NONE,
                    ),
                },
            );
            let out = swapchain(&mut g);
            let unread = rgba8(&mut g, "unread");
            let mut decals = g.raster_pass("decals", PassClass::Opaque, ());
            decals.color(out).coverage(Coverage::Full);
            if survivor_writes {
                decals.depth_stencil(baked);
            } else {
                decals.depth_stencil_read_only(baked);
            }
            g.raster_pass("nobody_reads", PassClass::Other, ())
                .depth_stencil(baked)
                .color(unread);
            let plan = compile(g, &tiler());
            assert_eq!(plan.pruned.len(), 1, "{plan}");
            let expected = if survivor_writes {
                StoreOp::DontCare
            } else {
                StoreOp::None
            };
            assert_eq!(
                attachment(&plan, "baked_depth").store_op,
                expected,
                "{plan}"
            );
        }
    }

    #[test]
    fn attachments_that_never_leave_the_render_pass_are_transient_on_tilers() {
        let build = || {
            let mut g = GraphBuilder::new();
            let depth = d24s8(&mut g, "depth");
            let out = swapchain(&mut g);
            g.raster_pass("opaque", PassClass::Opaque, ())
                .color_clear(out, ClearColor::BLACK)
                .depth_stencil_clear(depth, ClearDepthStencil::REVERSE_Z);
            g
        };
        let plan = compile(build(), &tiler());
        let depth = plan.resource_by_name("depth").cloned();
        assert_eq!(
            depth.as_ref().map(|d| d.residency),
            Some(Residency::Transient)
        );
        assert_eq!(
            depth.as_ref().map(|d| d.usage),
            Some(Usage::Image(
                ImageUsage::DEPTH_STENCIL_ATTACHMENT | ImageUsage::TRANSIENT_ATTACHMENT
            ))
        );
        let block = depth
            .and_then(|d| d.memory)
            .map(|m| plan.aliasing.blocks[m.block.0 as usize].class);
        assert_eq!(block, Some(MemoryClass::LazilyAllocated));
        assert_eq!(attachment(&plan, "depth").residency, Residency::Transient);

        // No lazily allocated memory on desktop: ordinary (aliasable) memory, still not stored.
        let plan = compile(build(), &desktop());
        let depth = plan.resource_by_name("depth");
        assert_eq!(depth.map(|d| d.residency), Some(Residency::FrameLocal));
        assert_eq!(
            depth.map(|d| d.usage),
            Some(Usage::Image(ImageUsage::DEPTH_STENCIL_ATTACHMENT))
        );
        assert_eq!(attachment(&plan, "depth").store_op, StoreOp::DontCare);
    }
}
