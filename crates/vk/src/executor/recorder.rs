//! Recording one frame of a plan: a [`FrameRecorder`] carries the context, the placed plan,
//! its physical resources, the caller's externals and the frame's command buffer through the
//! plan's steps — barrier batches as one `vkCmdPipelineBarrier2` each, render passes with their
//! subpasses, compute and transfer passes, flushes — and hands each pass to its payload with a
//! [`PassContext`], wrapped in a debug label and (as the frame's `GpuTiming` says) a pair of
//! timestamps. Its lists live in
//! [`RecorderState`], kept by the executor from frame to frame: a steady frame allocates
//! nothing here.

use ash::vk;
use tilegraph_graph::{
    Attachment, BarrierBatch, LoadOp, PassId, Plan, Queue, QueueTransfer, RenderPass, ResourceId,
    Step,
};

use super::render_pass::{clear_value, RenderPassRef, RenderPasses};
use super::resources::{BufferHandle, External, Externals, ImageHandle, Resources};
use super::sync::{buffer_wait, earlier_work, writes_in, FirstUses};
use super::FrameStats;
use crate::error::VkError;
use crate::frames::{FrameRing, FrameToken, QueuePart, Submission};
use crate::queries::QueryRing;
use crate::Context;

/// What a pass's payload gets to record with.
pub struct PassContext<'a> {
    pub ctx: &'a Context,
    pub cb: vk::CommandBuffer,
    pub pass: PassId,
    pub pass_name: &'a str,
    /// Frame-in-flight slot: index per-frame buffers with it.
    pub frame_slot: usize,
    pub frame: u64,
    /// The render pass and subpass this pass records into (raster passes), for pipeline creation.
    pub render_pass: Option<RenderPassRef>,
    pub render_area: vk::Extent2D,
    resources: &'a Resources,
    externals: &'a Externals,
}

impl PassContext<'_> {
    pub fn image(&self, id: impl Into<ResourceId>) -> Result<&ImageHandle, VkError> {
        let id = id.into();
        match self.externals.get(id) {
            Some(External::Image(i)) => Ok(i),
            Some(External::Buffer(_)) => Err(wrong_kind(self.pass_name, id, "an image")),
            None => self
                .resources
                .image(id)
                .ok_or_else(|| missing(self.pass_name, id)),
        }
    }

    pub fn buffer(&self, id: impl Into<ResourceId>) -> Result<BufferHandle, VkError> {
        let id = id.into();
        match self.externals.get(id) {
            Some(External::Buffer(b)) => Ok(*b),
            Some(External::Image(_)) => Err(wrong_kind(self.pass_name, id, "a buffer")),
            None => self
                .resources
                .buffer(id)
                .ok_or_else(|| missing(self.pass_name, id)),
        }
    }

    /// Sets a viewport and scissor covering the render area (depth 0..1).
    pub fn set_full_viewport(&self) {
        let e = self.render_area;
        let viewport = vk::Viewport {
            x: 0.0,
            y: 0.0,
            width: e.width as f32,
            height: e.height as f32,
            min_depth: 0.0,
            max_depth: 1.0,
        };
        let scissor = vk::Rect2D {
            offset: vk::Offset2D::default(),
            extent: e,
        };
        // SAFETY: recording command buffer; dynamic viewport/scissor pipelines.
        unsafe {
            self.ctx.device.cmd_set_viewport(self.cb, 0, &[viewport]);
            self.ctx.device.cmd_set_scissor(self.cb, 0, &[scissor]);
        }
    }
}

/// An image handed in by the caller must be what the render pass was built for: same format,
/// at least the render area (a framebuffer larger than its images is invalid usage).
pub(super) fn check_attachment_image(
    plan: &Plan,
    pass: &str,
    a: &Attachment,
    h: &ImageHandle,
    area: vk::Extent2D,
) -> Result<(), VkError> {
    let format = vk::Format::from_raw(a.format.vk_raw());
    if h.format == format && h.extent.width >= area.width && h.extent.height >= area.height {
        return Ok(());
    }
    let name = plan.resource(a.resource).map_or("?", |r| r.name.as_str());
    Err(VkError::Invalid {
        what: format!("render pass {pass:?}, attachment {name:?}"),
        reason: format!(
            "the image is {:?} {}x{}; the plan needs {:?} of at least {}x{}",
            h.format, h.extent.width, h.extent.height, format, area.width, area.height
        ),
    })
}

fn missing(pass: &str, id: ResourceId) -> VkError {
    VkError::Invalid {
        what: format!("pass {pass:?}"),
        reason: format!(
            "resource #{} has no physical resource (not imported?)",
            id.0
        ),
    }
}

fn wrong_kind(pass: &str, id: ResourceId, want: &str) -> VkError {
    VkError::Invalid {
        what: format!("pass {pass:?}"),
        reason: format!("resource #{} is not {want}", id.0),
    }
}

/// Records one pass. Implemented for closures; a frame's payloads are looked up by [`PassId`].
pub trait RecordPass {
    fn record(&mut self, pass: &mut PassContext<'_>) -> Result<(), VkError>;
}

impl<F: FnMut(&mut PassContext<'_>) -> Result<(), VkError>> RecordPass for F {
    fn record(&mut self, pass: &mut PassContext<'_>) -> Result<(), VkError> {
        self(pass)
    }
}

/// Commands recorded into a frame's command buffer before its first pass (after its opening
/// timestamp), outside any render pass: an upload of what changed since the last frame.
pub type PrologueFn<'a> = dyn FnMut(&Context, vk::CommandBuffer) -> Result<(), VkError> + 'a;

/// The callback that records each pass of a frame (the payloads, looked up by [`PassId`]).
pub type RecordFn<'a> = dyn FnMut(PassId, &mut PassContext<'_>) -> Result<(), VkError> + 'a;

/// What the recorder keeps from frame to frame: its barrier, view and clear lists (reused, so a
/// steady frame allocates nothing) and which resources this frame has touched.
#[derive(Default)]
pub(super) struct RecorderState {
    images: Vec<vk::ImageMemoryBarrier2<'static>>,
    buffers: Vec<vk::BufferMemoryBarrier2<'static>>,
    waited: Vec<ResourceId>,
    views: Vec<vk::ImageView>,
    clears: Vec<vk::ClearValue>,
    pub first_uses: FirstUses,
    /// A plan of two queues: the timeline value each part submitted so far signalled, and the
    /// waits of the frame's last part (left to the caller to submit).
    signalled: Vec<u64>,
    pub last_waits: LastPartWaits,
}

/// One frame's recording.
pub(super) struct FrameRecorder<'a, 'r> {
    pub ctx: &'a Context,
    /// The placed plan (see `resources.rs`).
    pub plan: &'a Plan,
    pub resources: &'a Resources,
    pub externals: &'a Externals,
    pub frames: &'a mut FrameRing,
    pub queries: &'a mut QueryRing,
    pub render_passes: &'a mut RenderPasses,
    pub state: &'a mut RecorderState,
    pub token: &'a mut FrameToken,
    pub stats: &'a mut FrameStats,
    pub record: &'a mut RecordFn<'r>,
    /// The queue the current command buffer is for.
    pub queue: Queue,
}

/// The waits of a frame's last part on the other queue (empty for a plan of one queue):
/// (queue, timeline value, stages that wait).
pub(super) type LastPartWaits = Vec<(Queue, u64, vk::PipelineStageFlags2)>;

impl FrameRecorder<'_, '_> {
    /// Records every step of the plan: a plan of two queues part by part, each part submitted
    /// to its queue (the last is left to the caller, with its waits in
    /// `RecorderState::last_waits`).
    pub fn record_steps(&mut self) -> Result<(), VkError> {
        let plan = self.plan;
        self.state.last_waits.clear();
        if plan.submissions.len() <= 1 {
            return self.record_range(0..plan.steps.len());
        }
        if self.frames.submission() == Submission::Engine {
            return Err(VkError::Invalid {
                what: "plan".into(),
                reason: "a plan of two queues, but the engine submits the frame on one".into(),
            });
        }
        self.state.signalled.clear();
        for (k, sub) in plan.submissions.iter().enumerate() {
            self.queue = sub.queue;
            self.record_range(sub.steps())?;
            if self.releases_transfer() {
                self.barriers(&sub.releases, true)?;
            }
            let RecorderState {
                signalled,
                last_waits: waits,
                ..
            } = &mut *self.state;
            waits.clear();
            for w in &sub.waits {
                let on = plan
                    .submissions
                    .get(w.submission.index())
                    .map_or(Queue::Graphics, |s| s.queue);
                let value = signalled.get(w.submission.index()).copied().unwrap_or(0);
                waits.push((
                    on,
                    value,
                    vk::PipelineStageFlags2::from_raw(w.dst_stages.bits()),
                ));
            }
            let Some(next) = plan.submissions.get(k + 1) else {
                break;
            };
            let part = QueuePart {
                queue: sub.queue,
                waits,
            };
            self.frames
                .submit_part(self.ctx, self.token, &part, next.queue)?;
            signalled.push(self.frames.signaled(sub.queue));
        }
        Ok(())
    }

    /// Whether ownership transfers are recorded: exclusive sharing between two families.
    fn releases_transfer(&self) -> bool {
        self.plan.queue_sharing == tilegraph_profile::QueueSharing::Exclusive
            && self
                .ctx
                .async_queue
                .is_some_and(|q| q.family != self.ctx.queue_family)
    }

    /// The queue family of `q`.
    fn family(&self, q: Queue) -> u32 {
        match (q, self.ctx.async_queue) {
            (Queue::AsyncCompute, Some(a)) => a.family,
            _ => self.ctx.queue_family,
        }
    }

    /// Records `range` of the plan's steps.
    fn record_range(&mut self, range: std::ops::Range<usize>) -> Result<(), VkError> {
        let plan = self.plan;
        let start = range.start;
        for (offset, step) in plan.steps.get(range).unwrap_or(&[]).iter().enumerate() {
            let step_index = start + offset;
            match step {
                Step::Barriers(batch) => {
                    self.stats.barriers += batch.len() as u32;
                    self.barriers(batch, false)?;
                }
                Step::Flush(_) => match self.frames.submission() {
                    Submission::Owned => {
                        self.stats.flushes += 1;
                        self.frames.flush(self.ctx, self.token)?;
                    }
                    Submission::Engine => self.stats.flushes_left_to_engine += 1,
                },
                Step::Compute { pass } | Step::Transfer { pass } => {
                    self.wait_for_earlier_frames(std::slice::from_ref(pass).iter().copied())?;
                    self.state.first_uses.mark(plan, *pass);
                    let name = plan.pass(*pass).map_or("?", |p| p.name.as_str());
                    self.run_pass(*pass, name, None, vk::Extent2D::default(), true)?;
                }
                Step::RenderPass(rp) => {
                    self.stats.render_passes += 1;
                    self.stats.subpasses += rp.subpasses.len() as u32;
                    self.wait_for_earlier_frames(rp.subpasses.iter().map(|s| s.pass))?;
                    for s in &rp.subpasses {
                        self.state.first_uses.mark(plan, s.pass);
                    }
                    self.render_pass(step_index, rp)?;
                }
            }
        }
        Ok(())
    }

    /// The stages of all earlier work, for the waits on earlier frames (`sync.rs`).
    fn earlier_work(&self) -> vk::PipelineStageFlags2 {
        earlier_work(self.ctx.has_feature(crate::Feature::ConditionalRendering))
    }

    /// One batch: `release`, the release halves at the end of a part (recorded only where the
    /// families differ); the acquire halves in a step's batch carry the families where they
    /// differ and are plain barriers where not.
    fn barriers(&mut self, batch: &BarrierBatch, release: bool) -> Result<(), VkError> {
        let (plan, externals, resources) = (self.plan, self.externals, self.resources);
        // What earlier frames did is behind the frame's first graphics part, which the async
        // queue's first part waits on: only the graphics queue widens first uses.
        let earlier = if self.queue == Queue::Graphics {
            self.earlier_work()
        } else {
            vk::PipelineStageFlags2::NONE
        };
        let transfers = self.releases_transfer();
        let family_of = [
            self.family(Queue::Graphics),
            self.family(Queue::AsyncCompute),
        ];
        let family = |q: Queue| match q {
            Queue::Graphics => family_of[0],
            Queue::AsyncCompute => family_of[1],
        };
        let families = |t: Option<QueueTransfer>| match t {
            Some(t) if transfers => (family(t.from), family(t.to)),
            _ => (vk::QUEUE_FAMILY_IGNORED, vk::QUEUE_FAMILY_IGNORED),
        };
        let state = &mut *self.state;
        state.images.clear();
        state.buffers.clear();
        for b in &batch.images {
            let h = image_of(externals, resources, b.resource)
                .ok_or_else(|| missing("barrier", b.resource))?;
            let old_layout = vk::ImageLayout::from_raw(b.old_layout.vk_raw());
            let mut src_s = vk::PipelineStageFlags2::from_raw(b.src_stages.bits());
            let mut src_a = vk::AccessFlags2::from_raw(b.src_access.bits());
            if state.first_uses.widens(plan, b.resource) && !earlier.is_empty() {
                src_s |= earlier;
                src_a |= writes_in(old_layout);
            }
            let (src_family, dst_family) = families(b.queue_transfer);
            if release && src_family == dst_family {
                continue;
            }
            state.images.push(
                vk::ImageMemoryBarrier2::default()
                    .src_queue_family_index(src_family)
                    .dst_queue_family_index(dst_family)
                    .src_stage_mask(src_s)
                    .src_access_mask(src_a)
                    .dst_stage_mask(vk::PipelineStageFlags2::from_raw(b.dst_stages.bits()))
                    .dst_access_mask(vk::AccessFlags2::from_raw(b.dst_access.bits()))
                    .old_layout(old_layout)
                    .new_layout(vk::ImageLayout::from_raw(b.new_layout.vk_raw()))
                    .image(h.raw)
                    .subresource_range(vk::ImageSubresourceRange {
                        aspect_mask: h.aspect,
                        base_mip_level: 0,
                        level_count: h.mip_levels,
                        base_array_layer: 0,
                        layer_count: 1,
                    }),
            );
        }
        for b in &batch.buffers {
            let h = buffer_of(externals, resources, b.resource)
                .ok_or_else(|| missing("barrier", b.resource))?;
            let mut src_s = vk::PipelineStageFlags2::from_raw(b.src_stages.bits());
            let mut src_a = vk::AccessFlags2::from_raw(b.src_access.bits());
            if state.first_uses.widens(plan, b.resource) && !earlier.is_empty() {
                src_s |= earlier;
                src_a |= vk::AccessFlags2::MEMORY_WRITE;
            }
            let (src_family, dst_family) = families(b.queue_transfer);
            if release && src_family == dst_family {
                continue;
            }
            state.buffers.push(
                vk::BufferMemoryBarrier2::default()
                    .src_queue_family_index(src_family)
                    .dst_queue_family_index(dst_family)
                    .src_stage_mask(src_s)
                    .src_access_mask(src_a)
                    .dst_stage_mask(vk::PipelineStageFlags2::from_raw(b.dst_stages.bits()))
                    .dst_access_mask(vk::AccessFlags2::from_raw(b.dst_access.bits()))
                    .buffer(h.raw)
                    .size(vk::WHOLE_SIZE),
            );
        }
        if state.images.is_empty() && state.buffers.is_empty() {
            return Ok(());
        }
        let info = vk::DependencyInfo::default()
            .image_memory_barriers(&state.images)
            .buffer_memory_barriers(&state.buffers);
        self.ctx.cmd_pipeline_barrier2(self.token.cb, &info)
    }

    /// Before a step: the graph-owned buffers its passes use that this frame has not touched
    /// yet wait for all earlier work, when earlier frames used them (see `sync.rs`).
    fn wait_for_earlier_frames(
        &mut self,
        passes: impl Iterator<Item = PassId>,
    ) -> Result<(), VkError> {
        let (plan, externals, resources) = (self.plan, self.externals, self.resources);
        let earlier = self.earlier_work();
        let state = &mut *self.state;
        // On the async queue earlier frames are behind its wait on the frame's start.
        if !state.first_uses.reused() || self.queue != Queue::Graphics {
            return Ok(());
        }
        state.buffers.clear();
        state.waited.clear();
        for u in passes.filter_map(|p| plan.pass(p)).flat_map(|p| &p.uses) {
            let id = u.resource;
            if state.waited.contains(&id) || !state.first_uses.is_fresh_owned(plan, id) {
                continue;
            }
            let Some(h) = buffer_of(externals, resources, id) else {
                continue;
            };
            state.waited.push(id);
            state.buffers.push(buffer_wait(h.raw, earlier));
        }
        if state.buffers.is_empty() {
            return Ok(());
        }
        let info = vk::DependencyInfo::default().buffer_memory_barriers(&state.buffers);
        self.ctx.cmd_pipeline_barrier2(self.token.cb, &info)
    }

    fn render_pass(&mut self, step_index: usize, rp: &RenderPass) -> Result<(), VkError> {
        let plan = self.plan;
        let first_name = rp
            .subpasses
            .first()
            .and_then(|s| plan.pass(s.pass))
            .map_or("render pass", |p| p.name.as_str());
        let (raw_rp, serial) = self
            .render_passes
            .render_pass(self.ctx, step_index, rp, first_name)?;
        let extent = vk::Extent2D {
            width: rp.render_area_px.width_px,
            height: rp.render_area_px.height_px,
        };
        // A render pass of one subpass is timed whole, its load and store operations (an
        // attachment's clear, its write-back) with it; the subpasses of a merged render pass
        // are timed inside it, each from its first command.
        let whole = match rp.subpasses.as_slice() {
            [only] => Some(plan.pass(only.pass).map_or("?", |p| p.name.as_str())),
            _ => None,
        };
        let timed_whole = match whole {
            Some(name) => {
                let graphics = self.graphics_queries();
                self.queries.begin_pass(
                    self.ctx,
                    self.token.cb,
                    self.token.slot,
                    (name, graphics),
                )?
            }
            None => None,
        };
        let (externals, resources) = (self.externals, self.resources);
        let state = &mut *self.state;
        state.views.clear();
        for a in &rp.attachments {
            let h = image_of(externals, resources, a.resource)
                .ok_or_else(|| missing(first_name, a.resource))?;
            check_attachment_image(plan, first_name, a, h, extent)?;
            state.views.push(h.view);
        }
        let fb =
            self.render_passes
                .framebuffer(self.ctx, step_index, raw_rp, &state.views, extent)?;
        // Clear values up to the last attachment that clears, none when nothing does
        // (best practices: ClearValueWithoutLoadOpClear).
        let clearing = rp
            .attachments
            .iter()
            .rposition(|a| a.load_op == LoadOp::Clear || a.stencil_load_op == LoadOp::Clear)
            .map_or(0, |i| i + 1);
        state.clears.clear();
        state
            .clears
            .extend(rp.attachments[..clearing].iter().map(clear_value));
        let begin = vk::RenderPassBeginInfo::default()
            .render_pass(raw_rp)
            .framebuffer(fb)
            .render_area(vk::Rect2D {
                offset: vk::Offset2D::default(),
                extent,
            })
            .clear_values(&state.clears);
        let sp_begin = vk::SubpassBeginInfo::default().contents(vk::SubpassContents::INLINE);
        let cb = self.token.cb;
        // SAFETY: recording, outside any render pass; the framebuffer matches the render pass.
        unsafe {
            self.ctx
                .device
                .cmd_begin_render_pass2(cb, &begin, &sp_begin)
        };
        for (i, s) in rp.subpasses.iter().enumerate() {
            if i > 0 {
                // SAFETY: inside the render pass, more subpasses remain.
                unsafe {
                    self.ctx
                        .device
                        .cmd_next_subpass2(cb, &sp_begin, &vk::SubpassEndInfo::default())
                };
            }
            let name = plan.pass(s.pass).map_or("?", |p| p.name.as_str());
            let target = RenderPassRef {
                handle: raw_rp,
                subpass: i as u32,
                serial,
            };
            self.run_pass(s.pass, name, Some(target), extent, whole.is_none())?;
        }
        // SAFETY: matches cmd_begin_render_pass2.
        unsafe {
            self.ctx
                .device
                .cmd_end_render_pass2(cb, &vk::SubpassEndInfo::default())
        };
        self.queries
            .end_pass(self.ctx, cb, self.token.slot, timed_whole)
    }

    /// Whether the current queue counts graphics pipeline statistics (not a compute-only one).
    fn graphics_queries(&self) -> bool {
        self.queue == Queue::Graphics
            || self
                .ctx
                .async_queue
                .is_some_and(|a| a.family == self.ctx.queue_family)
    }

    /// Records one pass through its payload, in a debug label (and, when `timed`, between two
    /// timestamps if the frame times its passes).
    fn run_pass(
        &mut self,
        pass: PassId,
        name: &str,
        render_pass: Option<RenderPassRef>,
        render_area: vk::Extent2D,
        timed: bool,
    ) -> Result<(), VkError> {
        let (ctx, cb, slot) = (self.ctx, self.token.cb, self.token.slot);
        ctx.begin_label(cb, name);
        let graphics = self.graphics_queries();
        let q = if timed {
            self.queries.begin_pass(ctx, cb, slot, (name, graphics))?
        } else {
            None
        };
        let mut pc = PassContext {
            ctx,
            cb,
            pass,
            pass_name: name,
            frame_slot: slot,
            frame: self.token.frame,
            render_pass,
            render_area,
            resources: self.resources,
            externals: self.externals,
        };
        let r = (self.record)(pass, &mut pc);
        self.queries.end_pass(ctx, cb, slot, q)?;
        ctx.end_label(cb);
        r
    }
}

/// The physical image of `id`: the caller's, or the graph's.
fn image_of<'x>(
    externals: &'x Externals,
    resources: &'x Resources,
    id: ResourceId,
) -> Option<&'x ImageHandle> {
    match externals.get(id) {
        Some(External::Image(h)) => Some(h),
        Some(External::Buffer(_)) => None,
        None => resources.image(id),
    }
}

/// The physical buffer of `id`: the caller's, or the graph's.
fn buffer_of(externals: &Externals, resources: &Resources, id: ResourceId) -> Option<BufferHandle> {
    match externals.get(id) {
        Some(External::Buffer(b)) => Some(*b),
        Some(External::Image(_)) => None,
        None => resources.buffer(id),
    }
}
