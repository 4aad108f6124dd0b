//! Executing a compiled [`Plan`], frame after frame:
//!
//! - `resources.rs`: the plan's physical resources (aliased where the plan allows, lazily
//!   allocated where it makes attachments transient) and the caller's [`Externals`];
//! - `render_pass.rs`: `VkRenderPass2` objects and framebuffers, cached per step;
//! - `recorder.rs`: one frame's recording, step by step, each pass handed to its payload;
//! - `sync.rs`: what frames in flight wait for, since they share the physical resources.
//!
//! A steady-state frame allocates nothing: resources, render passes and framebuffers are cached
//! while the plan stays the same, and the recorder's lists are reused.

mod recorder;
mod render_pass;
mod resources;
pub(crate) mod sync;

use std::sync::Arc;

use ash::vk;
use tilegraph_graph::Plan;

pub use crate::frames::Submission;
pub use recorder::{PassContext, PrologueFn, RecordFn, RecordPass};
pub use render_pass::RenderPassRef;
pub use resources::{aspect_of, BufferHandle, External, Externals, ImageHandle, Resources};

use recorder::{FrameRecorder, RecorderState};
use render_pass::RenderPasses;
use resources::build_resources;

use crate::error::VkError;
use crate::frames::{FrameRing, FrameToken, DEFAULT_FRAMES_IN_FLIGHT};
use crate::queries::{FrameTimings, GpuTiming, PassMedian, QueryRing, TimingHistory};
use crate::{Context, FaultSite, Feature};

/// Statistics of one executed frame.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct FrameStats {
    pub frame: u64,
    /// Device-memory allocations made while executing this frame (0 in steady state).
    pub allocations: u64,
    pub render_passes: u32,
    pub subpasses: u32,
    pub barriers: u32,
    pub flushes: u32,
    /// Flush steps of the plan not made because the engine owns submission (the Adreno
    /// profile's flush before occlusion queries: EMBEDDING.md says how an engine makes it).
    pub flushes_left_to_engine: u32,
    /// Whether the resource cache was (re)built this frame.
    pub rebuilt: bool,
    /// Whether aliased resources share memory (false when real requirements forced dedicated
    /// allocations, see [`Resources`]).
    pub aliasing_used: bool,
}

/// The engine's side of a frame it submits itself ([`Executor::record`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct EngineFrame {
    /// A primary command buffer in the recording state, outside any render pass. tilegraph
    /// records into it and neither begins, ends nor submits it.
    pub command_buffer: vk::CommandBuffer,
    /// The engine's frame slot, below the frames in flight the executor was made for: the GPU
    /// has finished the frame last recorded with this slot (the engine waited on its fence).
    pub slot: usize,
}

/// Executes plans frame after frame.
pub struct Executor {
    frames: FrameRing,
    queries: QueryRing,
    history: TimingHistory,
    /// The newest timed frame (valid when `timed`), and the one being collected: swapped, and
    /// sized for the plan's passes when it is built, so collecting allocates nothing.
    latest: FrameTimings,
    timed: bool,
    collecting: FrameTimings,
    /// The plan as last given (its physical resources are `resources`).
    plan: Option<Arc<Plan>>,
    resources: Option<Resources>,
    render_passes: RenderPasses,
    state: RecorderState,
    /// Every render pass created since the last rebuild has a serial at least this.
    render_pass_serial_floor: u64,
    /// Frame number of the first frame recorded with the current resources.
    resources_since: u64,
    /// Render passes recorded by the last frame (for tests and reports).
    pub last_stats: FrameStats,
}

/// What records a frame: commands before its first pass, and each pass.
struct Callbacks<'p, 'a, 'b> {
    prologue: Option<&'p mut PrologueFn<'a>>,
    record: &'p mut RecordFn<'b>,
}

impl Executor {
    pub fn new(ctx: &Context) -> Result<Self, VkError> {
        Self::with_frames(ctx, DEFAULT_FRAMES_IN_FLIGHT, 256)
    }

    /// An executor whose frames the engine submits ([`Executor::record`]), with
    /// `frames_in_flight` slots.
    pub fn for_engine(ctx: &Context, frames_in_flight: usize) -> Result<Self, VkError> {
        Self::build(ctx, frames_in_flight, 256, Submission::Engine)
    }

    /// `frames_in_flight` frames, each timing up to `max_passes` passes.
    pub fn with_frames(
        ctx: &Context,
        frames_in_flight: usize,
        max_passes: u32,
    ) -> Result<Self, VkError> {
        Self::build(ctx, frames_in_flight, max_passes, Submission::Owned)
    }

    fn build(
        ctx: &Context,
        frames_in_flight: usize,
        max_passes: u32,
        submission: Submission,
    ) -> Result<Self, VkError> {
        // Barriers, timestamps and the subpass dependencies of every render pass are
        // synchronization2 structures: without the feature they would be invalid usage.
        if !ctx.has_feature(Feature::Synchronization2) {
            return Err(VkError::MissingRequired {
                device: ctx.physical.identity.device_name.clone(),
                what: "feature (not enabled; see FeatureRequest::executor)",
                missing: Feature::Synchronization2.to_string(),
            });
        }
        let mut frames = FrameRing::new(ctx, frames_in_flight, submission)?;
        let queries = match QueryRing::new(ctx, frames.frames_in_flight(), max_passes) {
            Ok(q) => q,
            Err(e) => {
                frames.destroy(ctx);
                return Err(e);
            }
        };
        Ok(Executor {
            frames,
            queries,
            history: TimingHistory::default(),
            latest: FrameTimings::default(),
            timed: false,
            collecting: FrameTimings::default(),
            plan: None,
            resources: None,
            render_passes: RenderPasses::default(),
            state: RecorderState::default(),
            render_pass_serial_floor: render_pass::next_serial(),
            resources_since: 0,
            last_stats: FrameStats::default(),
        })
    }

    pub fn frames_in_flight(&self) -> usize {
        self.frames.frames_in_flight()
    }

    /// Who submits this executor's frames.
    pub fn submission(&self) -> Submission {
        self.frames.submission()
    }

    /// Command buffers allocated over all frame slots: one per slot, plus one per flush step of
    /// the plan (reused every frame).
    pub fn command_buffer_count(&self) -> usize {
        self.frames.command_buffer_count()
    }

    /// The slot the next [`Executor::execute`] will record into (per-frame buffers of passes
    /// are indexed by it; the executor guarantees the slot's previous frame has completed by
    /// the time recording starts).
    pub fn next_slot(&self) -> usize {
        self.frames.next_slot()
    }

    /// Waits until the next frame's slot is free and returns it: per-frame buffers of that slot
    /// may be written now, before [`Executor::execute`] records the frame.
    pub fn acquire_slot(&mut self, ctx: &Context) -> Result<usize, VkError> {
        self.frames.wait_next(ctx)
    }

    /// Median GPU time of each timing over every frame collected so far: each pass, or the
    /// one timing named `frame` ([`GpuTiming::Frame`]).
    pub fn medians(&self) -> Vec<PassMedian> {
        self.history.medians()
    }

    /// The most recent frame whose timings were collected.
    pub fn latest_timings(&self) -> Option<&FrameTimings> {
        self.timed.then_some(&self.latest)
    }

    pub fn history(&self) -> &TimingHistory {
        &self.history
    }

    /// Forgets the timings recorded so far (a measurement that starts now).
    pub fn clear_timings(&mut self) {
        self.history = TimingHistory::default();
    }

    /// What the queries of each frame measure ([`GpuTiming::PassStatistics`] until set).
    pub fn timing(&self) -> GpuTiming {
        self.queries.timing()
    }

    /// Measures the next frames with `timing`: waits for the frames in flight (their timings
    /// are collected and then forgotten with the rest, being of the old mode), so the history
    /// holds the new mode's frames only.
    pub fn set_timing(&mut self, ctx: &Context, timing: GpuTiming) -> Result<(), VkError> {
        if timing == self.queries.timing() {
            return Ok(());
        }
        self.collect_all(ctx)?;
        self.queries.set_timing(timing);
        self.clear_timings();
        self.timed = false;
        Ok(())
    }

    /// Physical resources of the current plan (e.g. to read back an exported image).
    pub fn resources(&self) -> Option<&Resources> {
        self.resources.as_ref()
    }

    /// Records and submits one frame of `plan`. `record(pass_id, ctx)` records each pass;
    /// `externals` gives the physical resources of the plan's imported resources.
    ///
    /// The physical resources, render passes and framebuffers are built for a plan once and
    /// reused while the plan stays the same: the same `Arc` (a caller that reuses its compiled
    /// plan pays one pointer comparison per frame), or an equal plan compiled anew. A different
    /// plan waits for the frames in flight and rebuilds.
    pub fn execute(
        &mut self,
        ctx: &Context,
        plan: &Arc<Plan>,
        externals: &Externals,
        record: &mut RecordFn<'_>,
    ) -> Result<FrameStats, VkError> {
        self.run(ctx, plan, externals, None, None, record)
    }

    /// [`Executor::execute`] with a `prologue` recorded before the first pass.
    pub fn execute_with(
        &mut self,
        ctx: &Context,
        plan: &Arc<Plan>,
        externals: &Externals,
        prologue: &mut PrologueFn<'_>,
        record: &mut RecordFn<'_>,
    ) -> Result<FrameStats, VkError> {
        self.run(ctx, plan, externals, None, Some(prologue), record)
    }

    /// Records one frame of `plan` into the engine's command buffer (an executor made with
    /// [`Executor::for_engine`]), as [`Executor::execute`] does but submitting nothing: the
    /// engine submits `frame.command_buffer` on the context's queue, after every earlier
    /// frame's, and waits for it before it hands the same slot again. A plan step that would
    /// flush is counted in [`FrameStats::flushes_left_to_engine`] instead. After an error the
    /// command buffer holds part of a frame (perhaps inside a render pass): the engine resets
    /// it and does not submit it.
    pub fn record(
        &mut self,
        ctx: &Context,
        plan: &Arc<Plan>,
        externals: &Externals,
        frame: EngineFrame,
        record: &mut RecordFn<'_>,
    ) -> Result<FrameStats, VkError> {
        self.run(ctx, plan, externals, Some(frame), None, record)
    }

    /// [`Executor::record`] with a `prologue` recorded before the first pass.
    pub fn record_with(
        &mut self,
        ctx: &Context,
        plan: &Arc<Plan>,
        externals: &Externals,
        frame: EngineFrame,
        prologue: &mut PrologueFn<'_>,
        record: &mut RecordFn<'_>,
    ) -> Result<FrameStats, VkError> {
        self.run(ctx, plan, externals, Some(frame), Some(prologue), record)
    }

    fn run(
        &mut self,
        ctx: &Context,
        plan: &Arc<Plan>,
        externals: &Externals,
        engine: Option<EngineFrame>,
        prologue: Option<&mut PrologueFn<'_>>,
        record: &mut RecordFn<'_>,
    ) -> Result<FrameStats, VkError> {
        let allocations_before = ctx.allocation_count();
        let mut stats = FrameStats::default();
        let mut token = self.begin(ctx, engine)?;
        // The slot is the frame's from here: a failure ends it (nothing of it is submitted).
        let callbacks = Callbacks { prologue, record };
        let result = self.run_token(ctx, plan, externals, &mut token, &mut stats, callbacks);
        match result {
            Ok(()) => {}
            Err(e) => {
                if let Err(gave_up) = self.frames.abandon(ctx, &token) {
                    log::error!("giving up the frame after \"{e}\": {gave_up}");
                }
                return Err(e);
            }
        }
        // A plan of two queues ends with a graphics part after the async queue's last.
        let last = (plan.submissions.len() > 1).then_some(crate::frames::QueuePart {
            queue: tilegraph_graph::Queue::Graphics,
            waits: &self.state.last_waits,
        });
        self.frames.submit_last(ctx, token, last.as_ref())?;
        stats.frame = token.frame;
        stats.allocations = ctx.allocation_count() - allocations_before;
        stats.aliasing_used = self.resources.as_ref().is_some_and(|r| r.aliasing_used());
        self.last_stats.clone_from(&stats);
        Ok(stats)
    }

    /// Starts a frame in the next slot of ours, or the engine's.
    fn begin(&mut self, ctx: &Context, engine: Option<EngineFrame>) -> Result<FrameToken, VkError> {
        match engine {
            None => self.frames.begin(ctx),
            Some(f) => self.frames.begin_engine(f.slot, f.command_buffer),
        }
    }

    fn run_token(
        &mut self,
        ctx: &Context,
        plan: &Arc<Plan>,
        externals: &Externals,
        token: &mut FrameToken,
        stats: &mut FrameStats,
        callbacks: Callbacks<'_, '_, '_>,
    ) -> Result<(), VkError> {
        let Callbacks { prologue, record } = callbacks;
        ctx.injected_fault_at(
            FaultSite::FrameStart,
            "recording the frame (injected fault)",
        )?;
        if token.completed_frame.is_some() {
            self.collect_slot(ctx, token.slot)?;
        }
        match &self.plan {
            Some(current) if Arc::ptr_eq(current, plan) => {}
            Some(current) if **current == **plan => self.plan = Some(Arc::clone(plan)),
            _ => {
                self.rebuild(ctx, plan, token.frame)?;
                stats.rebuilt = true;
            }
        }
        self.queries
            .begin_frame(ctx, token.cb, token.slot, token.frame)?;
        if let Some(prologue) = prologue {
            prologue(ctx, token.cb)?;
        }
        let Some(resources) = self.resources.as_ref() else {
            return Err(VkError::Invalid {
                what: "executor".into(),
                reason: "no resources".into(),
            });
        };
        // The placed plan: same passes and render passes, barriers for the real layout.
        let placed = resources.placed().unwrap_or(plan);
        // Resources created by the graph were last touched by an earlier frame (same memory);
        // the first frame after a rebuild has no earlier user.
        self.state
            .first_uses
            .begin(placed.resources.len(), token.frame > self.resources_since);
        FrameRecorder {
            ctx,
            plan: placed,
            resources,
            externals,
            frames: &mut self.frames,
            queries: &mut self.queries,
            render_passes: &mut self.render_passes,
            state: &mut self.state,
            token,
            stats,
            record,
            queue: tilegraph_graph::Queue::Graphics,
        }
        .record_steps()?;
        self.queries.end_frame(ctx, token.cb, token.slot)
    }

    /// A different plan: waits for every frame in flight, then builds its resources for the
    /// frames from `frame` on.
    fn rebuild(&mut self, ctx: &Context, plan: &Arc<Plan>, frame: u64) -> Result<(), VkError> {
        self.collect_all(ctx)?;
        if let Some(old) = self.resources.take() {
            old.destroy(ctx);
        }
        std::mem::take(&mut self.render_passes).destroy(ctx);
        self.render_pass_serial_floor = render_pass::next_serial();
        // No plan until the new one is built: if building fails, the next call rebuilds
        // (whichever plan it brings) instead of finding no resources for the old one.
        self.plan = None;
        self.resources = Some(build_resources(ctx, plan)?);
        self.plan = Some(Arc::clone(plan));
        // Room for the plan's passes in everything timing them, so that recording and
        // collecting its frames allocate nothing.
        let names = || plan.passes.iter().map(|p| p.name.as_str());
        self.queries.reserve(names());
        self.history.reserve(names());
        self.collecting.reserve(names());
        self.latest.reserve(names());
        self.resources_since = frame;
        Ok(())
    }

    /// Reads a completed slot's timings into the history and makes them the latest.
    fn collect_slot(&mut self, ctx: &Context, slot: usize) -> Result<(), VkError> {
        if self.queries.collect_into(ctx, slot, &mut self.collecting)? {
            self.history.record(&self.collecting);
            std::mem::swap(&mut self.latest, &mut self.collecting);
            self.timed = true;
        }
        Ok(())
    }

    fn collect_all(&mut self, ctx: &Context) -> Result<(), VkError> {
        let done = self.frames.wait_all(ctx)?;
        let mut frames: Vec<u64> = done;
        frames.sort_unstable();
        for f in frames {
            if let Some(slot) = self.frames.slot_of(f) {
                self.collect_slot(ctx, slot)?;
            }
        }
        Ok(())
    }

    /// Waits for every frame in flight and collects its timings (call before reading results
    /// that the last frame wrote, or before reporting medians).
    pub fn finish(&mut self, ctx: &Context) -> Result<(), VkError> {
        self.collect_all(ctx)
    }

    /// Forgets every framebuffer made with an image view the caller handed in. For a recreated
    /// swapchain: call [`Executor::finish`] first (frames in flight may still use the old
    /// views), destroy the old images and views, then call this before the next `execute`: the
    /// driver may give a new view the handle of a destroyed one, and a framebuffer cached under
    /// that handle would still reference the destroyed view.
    pub fn forget_external_views(&mut self, ctx: &Context) -> Result<(), VkError> {
        self.collect_all(ctx)?;
        let owned: Vec<vk::ImageView> = self
            .resources
            .as_ref()
            .map(|r| r.owned_views().collect())
            .unwrap_or_default();
        // No frame is in flight (collected above).
        self.render_passes
            .retain_framebuffers(ctx, |v| owned.contains(&v));
        Ok(())
    }

    /// Render passes of the current plan have serials of at least this
    /// ([`RenderPassRef::serial`]); pipelines cached for lower serials belong to render passes
    /// already destroyed, and no frame in flight uses them (the executor waited for every frame
    /// before it rebuilt): they may be destroyed.
    pub fn render_pass_serial_floor(&self) -> u64 {
        self.render_pass_serial_floor
    }

    /// Framebuffers cached for the current plan.
    pub fn framebuffer_count(&self) -> usize {
        self.render_passes.framebuffer_count()
    }

    /// Waits for the GPU and frees everything.
    pub fn destroy(mut self, ctx: &Context) {
        if let Err(e) = self.frames.wait_all(ctx) {
            log::error!("waiting for frames at teardown: {e}");
        }
        if let Some(r) = self.resources.take() {
            r.destroy(ctx);
        }
        std::mem::take(&mut self.render_passes).destroy(ctx);
        self.queries.destroy(ctx);
        self.frames.destroy(ctx);
    }
}

#[cfg(test)]
mod flag_tests {
    //! The executor hands the graph's flag bits to Vulkan unchanged (`from_raw(bits())`): every
    //! graph flag must have Vulkan's value.
    use ash::vk;
    use tilegraph_graph::{AccessFlags, BufferUsage, ImageUsage, PipelineStages};

    #[test]
    fn graph_flags_have_vulkan_values() {
        type S = vk::PipelineStageFlags2;
        let stages = [
            (PipelineStages::TOP_OF_PIPE, S::TOP_OF_PIPE),
            (PipelineStages::DRAW_INDIRECT, S::DRAW_INDIRECT),
            (PipelineStages::VERTEX_INPUT, S::VERTEX_INPUT),
            (PipelineStages::VERTEX_SHADER, S::VERTEX_SHADER),
            (PipelineStages::FRAGMENT_SHADER, S::FRAGMENT_SHADER),
            (
                PipelineStages::EARLY_FRAGMENT_TESTS,
                S::EARLY_FRAGMENT_TESTS,
            ),
            (PipelineStages::LATE_FRAGMENT_TESTS, S::LATE_FRAGMENT_TESTS),
            (
                PipelineStages::COLOR_ATTACHMENT_OUTPUT,
                S::COLOR_ATTACHMENT_OUTPUT,
            ),
            (PipelineStages::COMPUTE_SHADER, S::COMPUTE_SHADER),
            (PipelineStages::ALL_TRANSFER, S::ALL_TRANSFER),
            (PipelineStages::BOTTOM_OF_PIPE, S::BOTTOM_OF_PIPE),
            (PipelineStages::HOST, S::HOST),
            (PipelineStages::ALL_GRAPHICS, S::ALL_GRAPHICS),
            (PipelineStages::ALL_COMMANDS, S::ALL_COMMANDS),
            (
                PipelineStages::CONDITIONAL_RENDERING,
                S::CONDITIONAL_RENDERING_EXT,
            ),
            (PipelineStages::COPY, S::COPY),
            (PipelineStages::RESOLVE, S::RESOLVE),
            (PipelineStages::BLIT, S::BLIT),
            (PipelineStages::CLEAR, S::CLEAR),
            (PipelineStages::INDEX_INPUT, S::INDEX_INPUT),
            (
                PipelineStages::VERTEX_ATTRIBUTE_INPUT,
                S::VERTEX_ATTRIBUTE_INPUT,
            ),
            (
                PipelineStages::PRE_RASTERIZATION_SHADERS,
                S::PRE_RASTERIZATION_SHADERS,
            ),
        ];
        for (graph, vulkan) in stages {
            assert_eq!(graph.bits(), vulkan.as_raw(), "{vulkan:?}");
        }
        type A = vk::AccessFlags2;
        let access = [
            (AccessFlags::INDIRECT_COMMAND_READ, A::INDIRECT_COMMAND_READ),
            (AccessFlags::INDEX_READ, A::INDEX_READ),
            (AccessFlags::VERTEX_ATTRIBUTE_READ, A::VERTEX_ATTRIBUTE_READ),
            (AccessFlags::UNIFORM_READ, A::UNIFORM_READ),
            (AccessFlags::INPUT_ATTACHMENT_READ, A::INPUT_ATTACHMENT_READ),
            (AccessFlags::SHADER_READ, A::SHADER_READ),
            (AccessFlags::SHADER_WRITE, A::SHADER_WRITE),
            (AccessFlags::COLOR_ATTACHMENT_READ, A::COLOR_ATTACHMENT_READ),
            (
                AccessFlags::COLOR_ATTACHMENT_WRITE,
                A::COLOR_ATTACHMENT_WRITE,
            ),
            (
                AccessFlags::DEPTH_STENCIL_ATTACHMENT_READ,
                A::DEPTH_STENCIL_ATTACHMENT_READ,
            ),
            (
                AccessFlags::DEPTH_STENCIL_ATTACHMENT_WRITE,
                A::DEPTH_STENCIL_ATTACHMENT_WRITE,
            ),
            (AccessFlags::TRANSFER_READ, A::TRANSFER_READ),
            (AccessFlags::TRANSFER_WRITE, A::TRANSFER_WRITE),
            (AccessFlags::HOST_READ, A::HOST_READ),
            (AccessFlags::HOST_WRITE, A::HOST_WRITE),
            (AccessFlags::MEMORY_READ, A::MEMORY_READ),
            (AccessFlags::MEMORY_WRITE, A::MEMORY_WRITE),
            (
                AccessFlags::CONDITIONAL_RENDERING_READ,
                A::CONDITIONAL_RENDERING_READ_EXT,
            ),
            (AccessFlags::SHADER_SAMPLED_READ, A::SHADER_SAMPLED_READ),
            (AccessFlags::SHADER_STORAGE_READ, A::SHADER_STORAGE_READ),
            (AccessFlags::SHADER_STORAGE_WRITE, A::SHADER_STORAGE_WRITE),
        ];
        for (graph, vulkan) in access {
            assert_eq!(graph.bits(), vulkan.as_raw(), "{vulkan:?}");
        }
        type B = vk::BufferUsageFlags;
        let buffers = [
            (BufferUsage::TRANSFER_SRC, B::TRANSFER_SRC),
            (BufferUsage::TRANSFER_DST, B::TRANSFER_DST),
            (BufferUsage::UNIFORM_BUFFER, B::UNIFORM_BUFFER),
            (BufferUsage::STORAGE_BUFFER, B::STORAGE_BUFFER),
            (BufferUsage::INDEX_BUFFER, B::INDEX_BUFFER),
            (BufferUsage::VERTEX_BUFFER, B::VERTEX_BUFFER),
            (BufferUsage::INDIRECT_BUFFER, B::INDIRECT_BUFFER),
            (
                BufferUsage::CONDITIONAL_RENDERING,
                B::CONDITIONAL_RENDERING_EXT,
            ),
        ];
        for (graph, vulkan) in buffers {
            assert_eq!(graph.bits(), vulkan.as_raw(), "{vulkan:?}");
        }
        type I = vk::ImageUsageFlags;
        let images = [
            (ImageUsage::TRANSFER_SRC, I::TRANSFER_SRC),
            (ImageUsage::TRANSFER_DST, I::TRANSFER_DST),
            (ImageUsage::SAMPLED, I::SAMPLED),
            (ImageUsage::STORAGE, I::STORAGE),
            (ImageUsage::COLOR_ATTACHMENT, I::COLOR_ATTACHMENT),
            (
                ImageUsage::DEPTH_STENCIL_ATTACHMENT,
                I::DEPTH_STENCIL_ATTACHMENT,
            ),
            (ImageUsage::TRANSIENT_ATTACHMENT, I::TRANSIENT_ATTACHMENT),
            (ImageUsage::INPUT_ATTACHMENT, I::INPUT_ATTACHMENT),
        ];
        for (graph, vulkan) in images {
            assert_eq!(graph.bits(), vulkan.as_raw(), "{vulkan:?}");
        }
    }
}
