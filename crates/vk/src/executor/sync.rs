//! Synchronisation across frames. Frames in flight share the plan's physical resources, and
//! queue submissions are not ordered by themselves, so each frame waits for the earlier ones
//! wherever it first touches what they may still use:
//!
//! - a graph-owned resource's first barrier in a frame also waits for all earlier work
//!   ([`earlier_work`] stages and `MEMORY_WRITE` added to its source scope: a graph-owned image
//!   starts each frame `UNDEFINED`, where the layout table allows any access);
//! - a graph-owned buffer whose first use has no barrier in the plan (nothing earlier in the
//!   frame touched it) gets one before its step;
//! - an attachment that starts `UNDEFINED` in a render pass gets an external subpass
//!   dependency into the first subpass that uses it, so its load op waits too.
//!
//! The first frame after the resources were (re)built has no earlier user and skips the first
//! two.

use ash::vk;
use tilegraph_graph::{Layout, PassId, Plan, RenderPass, Residency, ResourceId};

/// Which graph-owned resources this frame has touched so far.
#[derive(Debug, Default)]
pub(super) struct FirstUses {
    /// Earlier frames may still use this frame's resources.
    reused: bool,
    seen: Vec<bool>,
}

impl FirstUses {
    /// A new frame of a plan with `n_resources` resources; `reused`: an earlier frame recorded
    /// with the same resources.
    pub fn begin(&mut self, n_resources: usize, reused: bool) {
        self.reused = reused;
        self.seen.clear();
        self.seen.resize(n_resources, false);
    }

    pub fn reused(&self) -> bool {
        self.reused
    }

    /// Whether the source scope of a plan barrier on `id` widens to all earlier work: the
    /// frame's first touch of a resource the graph owns, when earlier frames used it.
    pub fn widens(&mut self, plan: &Plan, id: ResourceId) -> bool {
        let owned = is_owned(plan, id);
        let Some(seen) = self.seen.get_mut(id.index()) else {
            return false;
        };
        let first = owned && !*seen;
        *seen = true;
        self.reused && first
    }

    /// Whether `id` is a graph-owned resource this frame has not touched yet.
    pub fn is_fresh_owned(&self, plan: &Plan, id: ResourceId) -> bool {
        !self.seen.get(id.index()).copied().unwrap_or(true) && is_owned(plan, id)
    }

    /// Records every resource `pass` uses as touched.
    pub fn mark(&mut self, plan: &Plan, pass: PassId) {
        if let Some(p) = plan.pass(pass) {
            for u in &p.uses {
                if let Some(s) = self.seen.get_mut(u.resource.index()) {
                    *s = true;
                }
            }
        }
    }
}

/// A resource whose memory the executor owns (and so shares between frames in flight).
fn is_owned(plan: &Plan, id: ResourceId) -> bool {
    plan.resource(id).is_some_and(|r| {
        matches!(
            r.residency,
            Residency::FrameLocal | Residency::Exported | Residency::Transient
        )
    })
}

/// Every stage a graph can declare work in — what "all earlier work" of the frames in flight
/// means here. Spelled out rather than `ALL_COMMANDS`, which the best-practices checks flag as
/// a stall of everything; the same scope for what tilegraph records. `conditional`: the
/// device has conditional rendering enabled (its stage bit needs the feature).
pub fn earlier_work(conditional: bool) -> vk::PipelineStageFlags2 {
    let all = vk::PipelineStageFlags2::DRAW_INDIRECT
        | vk::PipelineStageFlags2::VERTEX_INPUT
        | vk::PipelineStageFlags2::PRE_RASTERIZATION_SHADERS
        | vk::PipelineStageFlags2::FRAGMENT_SHADER
        | vk::PipelineStageFlags2::EARLY_FRAGMENT_TESTS
        | vk::PipelineStageFlags2::LATE_FRAGMENT_TESTS
        | vk::PipelineStageFlags2::COLOR_ATTACHMENT_OUTPUT
        | vk::PipelineStageFlags2::COMPUTE_SHADER
        | vk::PipelineStageFlags2::ALL_TRANSFER;
    if conditional {
        all | vk::PipelineStageFlags2::CONDITIONAL_RENDERING_EXT
    } else {
        all
    }
}

/// The writes an image found in `layout` may still have pending, named by the kind of work
/// that leaves an image there rather than as `MEMORY_WRITE` (which the best-practices table of
/// accesses per layout flags). A render pass that leaves an attachment read-only still stored
/// it, and render passes have no outgoing external dependency to make that store available:
/// read-only attachment layouts name the attachment write. Transfer-source and present layouts
/// are left by reads (a copy, presentation), whose own barriers made earlier writes available.
pub fn writes_in(layout: vk::ImageLayout) -> vk::AccessFlags2 {
    match layout {
        vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL | vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL => {
            vk::AccessFlags2::COLOR_ATTACHMENT_WRITE
        }
        vk::ImageLayout::DEPTH_STENCIL_ATTACHMENT_OPTIMAL
        | vk::ImageLayout::DEPTH_ATTACHMENT_OPTIMAL
        | vk::ImageLayout::DEPTH_STENCIL_READ_ONLY_OPTIMAL
        | vk::ImageLayout::DEPTH_READ_ONLY_OPTIMAL => {
            vk::AccessFlags2::DEPTH_STENCIL_ATTACHMENT_WRITE
        }
        vk::ImageLayout::TRANSFER_DST_OPTIMAL => vk::AccessFlags2::TRANSFER_WRITE,
        vk::ImageLayout::TRANSFER_SRC_OPTIMAL | vk::ImageLayout::PRESENT_SRC_KHR => {
            vk::AccessFlags2::NONE
        }
        _ => vk::AccessFlags2::MEMORY_WRITE,
    }
}

/// The reads and writes an image in `layout` may be the target of (the best-practices table):
/// the destination of a barrier that hands it back to work of unknown kind.
pub fn accesses_in(layout: vk::ImageLayout) -> vk::AccessFlags2 {
    match layout {
        vk::ImageLayout::TRANSFER_SRC_OPTIMAL => vk::AccessFlags2::TRANSFER_READ,
        vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL => {
            vk::AccessFlags2::SHADER_READ | vk::AccessFlags2::INPUT_ATTACHMENT_READ
        }
        vk::ImageLayout::PRESENT_SRC_KHR => vk::AccessFlags2::NONE,
        l => writes_in(l) | vk::AccessFlags2::MEMORY_READ,
    }
}

/// The barrier a graph-owned buffer gets before the step that first uses it in a frame when
/// the plan puts none there: after all earlier work (`stages`, [`earlier_work`]).
pub(super) fn buffer_wait(
    buffer: vk::Buffer,
    stages: vk::PipelineStageFlags2,
) -> vk::BufferMemoryBarrier2<'static> {
    vk::BufferMemoryBarrier2::default()
        .src_stage_mask(stages)
        .src_access_mask(vk::AccessFlags2::MEMORY_WRITE)
        .dst_stage_mask(stages)
        .dst_access_mask(vk::AccessFlags2::MEMORY_READ | vk::AccessFlags2::MEMORY_WRITE)
        .buffer(buffer)
        .size(vk::WHOLE_SIZE)
}

/// The subpasses that first use an attachment starting `UNDEFINED`, each once: each gets an
/// external dependency ([`external_dependency`]).
pub(super) fn first_subpasses_of_undefined_attachments(rp: &RenderPass) -> Vec<u32> {
    let mut into: Vec<u32> = Vec::new();
    for (i, a) in rp.attachments.iter().enumerate() {
        if a.initial_layout != Layout::Undefined {
            continue;
        }
        let i = i as u32;
        let first = rp.subpasses.iter().position(|s| {
            s.colors
                .iter()
                .chain(s.inputs.iter())
                .chain(s.depth_stencil.iter())
                .any(|r| r.attachment.0 == i)
                || s.resolves.iter().flatten().any(|r| r.attachment.0 == i)
        });
        if let Some(f) = first.map(|f| f as u32) {
            if !into.contains(&f) {
                into.push(f);
            }
        }
    }
    into
}

/// The scopes of that external dependency: all earlier writes (`stages`, [`earlier_work`]),
/// before any attachment access of the subpass.
pub(super) fn external_dependency(stages: vk::PipelineStageFlags2) -> vk::MemoryBarrier2<'static> {
    vk::MemoryBarrier2::default()
        .src_stage_mask(stages)
        .src_access_mask(vk::AccessFlags2::MEMORY_WRITE)
        .dst_stage_mask(
            vk::PipelineStageFlags2::EARLY_FRAGMENT_TESTS
                | vk::PipelineStageFlags2::LATE_FRAGMENT_TESTS
                | vk::PipelineStageFlags2::COLOR_ATTACHMENT_OUTPUT
                | vk::PipelineStageFlags2::FRAGMENT_SHADER,
        )
        .dst_access_mask(
            vk::AccessFlags2::DEPTH_STENCIL_ATTACHMENT_READ
                | vk::AccessFlags2::DEPTH_STENCIL_ATTACHMENT_WRITE
                | vk::AccessFlags2::COLOR_ATTACHMENT_READ
                | vk::AccessFlags2::COLOR_ATTACHMENT_WRITE
                | vk::AccessFlags2::INPUT_ATTACHMENT_READ,
        )
}
