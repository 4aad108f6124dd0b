//! Synchronisation across frames. Frames in flight share the plan's physical resources, and
//! queue submissions are not ordered by themselves, so each frame waits for the earlier ones
//! wherever it first touches what they may still use:
//!
//! - a graph-owned resource's first barrier in a frame also waits for all earlier work
//!   (`ALL_COMMANDS` / `MEMORY_WRITE` added to its source scope);
//! - a graph-owned buffer whose first use has no barrier in the plan (nothing earlier in the
//!   frame touched it) gets one before its step;
//! - an attachment that starts `UNDEFINED` in a render pass gets an external subpass
//!   dependency into the first subpass that uses it, so its load op waits too.
//!
//! The first frame after the resources were (re)built has no earlier user and skips the first
//! two.

use ash::vk;
use tilegraph_graph::{
    AccessFlags, Layout, PassId, PipelineStages, Plan, RenderPass, Residency, ResourceId,
};

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

    /// The source scope of a plan barrier on `id`: widened to all earlier work when this is the
    /// frame's first touch of a resource the graph owns and earlier frames used it.
    pub fn barrier_source(
        &mut self,
        plan: &Plan,
        id: ResourceId,
        stages: PipelineStages,
        access: AccessFlags,
    ) -> (PipelineStages, AccessFlags) {
        let owned = is_owned(plan, id);
        let Some(seen) = self.seen.get_mut(id.index()) else {
            return (stages, access);
        };
        let first = owned && !*seen;
        *seen = true;
        if self.reused && first {
            (
                stages.union(PipelineStages::ALL_COMMANDS),
                access.union(AccessFlags::MEMORY_WRITE),
            )
        } else {
            (stages, access)
        }
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

/// The barrier a graph-owned buffer gets before the step that first uses it in a frame when
/// the plan puts none there.
pub(super) fn buffer_wait(buffer: vk::Buffer) -> vk::BufferMemoryBarrier2<'static> {
    vk::BufferMemoryBarrier2::default()
        .src_stage_mask(vk::PipelineStageFlags2::ALL_COMMANDS)
        .src_access_mask(vk::AccessFlags2::MEMORY_WRITE)
        .dst_stage_mask(vk::PipelineStageFlags2::ALL_COMMANDS)
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

/// The scopes of that external dependency: all earlier writes, before any attachment access
/// of the subpass.
pub(super) fn external_dependency() -> vk::MemoryBarrier2<'static> {
    vk::MemoryBarrier2::default()
        .src_stage_mask(vk::PipelineStageFlags2::ALL_COMMANDS)
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
