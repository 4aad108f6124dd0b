//! Frames in flight: each slot has its own command pool, command buffer and fence, so the CPU
//! records frame N+1 while the GPU runs frame N, and nothing a slot used is touched again before
//! its fence says the GPU is done with it.
//!
//! An engine that owns submission ([`Submission::Engine`]) brings its own command buffer and
//! frame slot instead: it vouches that the GPU finished the frame last recorded for that slot
//! (it waited on its own fence), which is all tilegraph needs to reuse the slot's buffers and read
//! its queries. Its slots have no pool and no fence; waiting for every frame is a device wait.
//!
//! A plan of two queues (async compute) is submitted in parts, in plan order, each part to its
//! queue, waiting on the other queue's timeline semaphore for the values its plan waits name
//! and signalling its own; the last part (graphics, after the async queue's last) carries the
//! slot's fence.

use ash::vk;
use tilegraph_graph::Queue;

use crate::error::{VkError, VkResultExt};
use crate::{Context, FaultSite};

/// Default number of frames in flight.
pub const DEFAULT_FRAMES_IN_FLIGHT: usize = 2;

struct FrameSlot {
    pool: vk::CommandPool,
    /// The async compute queue's pool where its family is not `pool`'s (else null), and its
    /// command buffers, recycled like `cbs`.
    async_pool: vk::CommandPool,
    async_cbs: Vec<vk::CommandBuffer>,
    async_begun: usize,
    /// This frame submitted work to the async compute queue.
    async_submitted: bool,
    /// Every command buffer allocated from `pool`; a frame records into them in turn (one more
    /// per flush) and the pool reset recycles them all.
    cbs: Vec<vk::CommandBuffer>,
    /// How many of `cbs` this frame has begun (the token holds the one recording).
    begun: usize,
    fence: vk::Fence,
    /// This frame submitted part of its work (a flush).
    flushed: bool,
    /// The frame was abandoned after an error: when its fence signals, nothing is reported.
    abandoned: bool,
    /// Whether work was submitted with this fence since it was last waited for.
    in_flight: bool,
    /// A frame found complete by [`FrameRing::wait_next`] and not yet reported by `begin`.
    completed: Option<u64>,
    /// Frame number last recorded into the slot.
    frame: u64,
}

/// Who submits the recorded frames.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Submission {
    /// tilegraph: its own command buffers, fences and queue submits.
    Owned,
    /// The engine: it hands tilegraph a command buffer in the recording state and its frame
    /// slot, submits the buffer itself on the context's queue, in recording order, and
    /// re-uses a slot only after the GPU finished the frame last recorded for it.
    Engine,
}

/// The ring of frame slots.
pub struct FrameRing {
    slots: Vec<FrameSlot>,
    next_frame: u64,
    submission: Submission,
    /// Per queue (graphics, async compute): a timeline semaphore counting its submitted parts,
    /// and the last value signalled; null without async compute.
    timelines: [vk::Semaphore; 2],
    signaled: [u64; 2],
    /// The semaphore waits of the part being submitted (kept: a steady frame allocates
    /// nothing).
    wait_infos: Vec<vk::SemaphoreSubmitInfo<'static>>,
}

/// One part of a frame for [`FrameRing::submit_part`]: its queue and the other queue's
/// timeline values it waits for, each with the stages that wait.
#[derive(Debug, Clone, Copy)]
pub struct QueuePart<'a> {
    pub queue: Queue,
    pub waits: &'a [(Queue, u64, vk::PipelineStageFlags2)],
}

const fn timeline_slot(q: Queue) -> usize {
    match q {
        Queue::Graphics => 0,
        Queue::AsyncCompute => 1,
    }
}

/// The slot being recorded: its command buffer is in the recording state.
#[derive(Debug, Clone, Copy)]
pub struct FrameToken {
    pub slot: usize,
    pub frame: u64,
    pub cb: vk::CommandBuffer,
    /// The frame previously recorded into this slot, now known complete, if any (its query
    /// results can be read without waiting).
    pub completed_frame: Option<u64>,
}

impl FrameSlot {
    /// A slot of the engine's: it brings the command buffer, and its fence is its own.
    fn engines() -> Self {
        FrameSlot {
            pool: vk::CommandPool::null(),
            async_pool: vk::CommandPool::null(),
            async_cbs: Vec::new(),
            async_begun: 0,
            async_submitted: false,
            cbs: Vec::new(),
            begun: 0,
            fence: vk::Fence::null(),
            flushed: false,
            abandoned: false,
            in_flight: false,
            completed: None,
            frame: 0,
        }
    }
}

/// The most frames a ring keeps in flight: each holds command buffers, fences and per-frame
/// buffers, and past three or four frames only latency grows.
pub const MAX_FRAMES_IN_FLIGHT: usize = 16;

impl FrameRing {
    /// A ring of `frames_in_flight` frames (1 to [`MAX_FRAMES_IN_FLIGHT`]; 0 is taken as 1).
    pub fn new(
        ctx: &Context,
        frames_in_flight: usize,
        submission: Submission,
    ) -> Result<Self, VkError> {
        if frames_in_flight > MAX_FRAMES_IN_FLIGHT {
            return Err(VkError::Invalid {
                what: "frames in flight".into(),
                reason: format!("{frames_in_flight}: at most {MAX_FRAMES_IN_FLIGHT}"),
            });
        }
        let mut ring = FrameRing {
            slots: Vec::new(),
            next_frame: 0,
            submission,
            timelines: [vk::Semaphore::null(); 2],
            signaled: [0; 2],
            wait_infos: Vec::new(),
        };
        if submission == Submission::Owned && ctx.async_queue.is_some() {
            for t in &mut ring.timelines {
                let mut kind = vk::SemaphoreTypeCreateInfo::default()
                    .semaphore_type(vk::SemaphoreType::TIMELINE)
                    .initial_value(0);
                let info = vk::SemaphoreCreateInfo::default().push_next(&mut kind);
                // SAFETY: valid device with timeline semaphores (Context enables async
                // compute only with them).
                match unsafe { ctx.device.create_semaphore(&info, None) } {
                    Ok(s) => *t = s,
                    Err(r) => {
                        ring.destroy(ctx);
                        return Err(VkError::call("vkCreateSemaphore", r));
                    }
                }
            }
        }
        for i in 0..frames_in_flight.max(1) {
            let slot = match submission {
                Submission::Owned => Self::slot(ctx, i),
                Submission::Engine => Ok(FrameSlot::engines()),
            };
            match slot {
                Ok(s) => ring.slots.push(s),
                Err(e) => {
                    ring.destroy(ctx);
                    return Err(e);
                }
            }
        }
        Ok(ring)
    }

    fn slot(ctx: &Context, i: usize) -> Result<FrameSlot, VkError> {
        let d = &ctx.device;
        let info = vk::CommandPoolCreateInfo::default()
            .queue_family_index(ctx.queue_family)
            .flags(vk::CommandPoolCreateFlags::TRANSIENT);
        // SAFETY: valid device and queue family.
        let pool = unsafe { d.create_command_pool(&info, None) }.vk("vkCreateCommandPool")?;
        let alloc = vk::CommandBufferAllocateInfo::default()
            .command_pool(pool)
            .level(vk::CommandBufferLevel::PRIMARY)
            .command_buffer_count(1);
        // SAFETY: pool is live.
        let cb = match unsafe { d.allocate_command_buffers(&alloc) } {
            Ok(v) if !v.is_empty() => v[0],
            Ok(_) => vk::CommandBuffer::null(),
            Err(r) => {
                // SAFETY: unused pool.
                unsafe { d.destroy_command_pool(pool, None) };
                return Err(VkError::call("vkAllocateCommandBuffers", r));
            }
        };
        // SAFETY: valid device; created signalled-free, first wait is skipped by `in_flight`.
        let fence = match unsafe { d.create_fence(&vk::FenceCreateInfo::default(), None) } {
            Ok(f) => f,
            Err(r) => {
                // SAFETY: unused pool.
                unsafe { d.destroy_command_pool(pool, None) };
                return Err(VkError::call("vkCreateFence", r));
            }
        };
        ctx.set_name(cb, &format!("frame slot {i}"));
        let async_family = ctx
            .async_queue
            .map(|q| q.family)
            .filter(|&f| f != ctx.queue_family);
        let async_pool = match async_family {
            Some(family) => {
                let info = vk::CommandPoolCreateInfo::default()
                    .queue_family_index(family)
                    .flags(vk::CommandPoolCreateFlags::TRANSIENT);
                // SAFETY: valid device and queue family (one of the device's queues).
                match unsafe { d.create_command_pool(&info, None) } {
                    Ok(p) => p,
                    Err(r) => {
                        // SAFETY: unused fence and pool.
                        unsafe {
                            d.destroy_fence(fence, None);
                            d.destroy_command_pool(pool, None);
                        }
                        return Err(VkError::call("vkCreateCommandPool", r));
                    }
                }
            }
            None => vk::CommandPool::null(),
        };
        Ok(FrameSlot {
            pool,
            async_pool,
            async_cbs: Vec::new(),
            async_begun: 0,
            async_submitted: false,
            cbs: vec![cb],
            begun: 1,
            fence,
            flushed: false,
            abandoned: false,
            in_flight: false,
            completed: None,
            frame: 0,
        })
    }

    pub fn frames_in_flight(&self) -> usize {
        self.slots.len()
    }

    /// Command buffers allocated over all slots.
    pub fn command_buffer_count(&self) -> usize {
        self.slots.iter().map(|s| s.cbs.len()).sum()
    }

    pub fn submission(&self) -> Submission {
        self.submission
    }

    /// The frame number the next [`FrameRing::begin`] hands out.
    pub fn next_frame(&self) -> u64 {
        self.next_frame
    }

    /// The slot the next frame will use.
    pub fn next_slot(&self) -> usize {
        (self.next_frame % self.slots.len() as u64) as usize
    }

    /// Waits until the GPU is done with the next slot's previous frame, so its per-frame
    /// buffers may be rewritten, and returns the slot. `begin` does this too; call it first when
    /// the CPU must write the slot's data before recording.
    pub fn wait_next(&mut self, ctx: &Context) -> Result<usize, VkError> {
        self.expect(Submission::Owned)?;
        let slot = self.next_slot();
        let s = &mut self.slots[slot];
        if s.in_flight {
            ctx.injected_fault_at(FaultSite::FenceWait, "vkWaitForFences (injected fault)")?;
            // SAFETY: the fence was submitted with this slot's last frame.
            unsafe { ctx.device.wait_for_fences(&[s.fence], true, u64::MAX) }
                .vk("vkWaitForFences")?;
            // SAFETY: signalled fence, no pending submission uses it.
            unsafe { ctx.device.reset_fences(&[s.fence]) }.vk("vkResetFences")?;
            s.in_flight = false;
            s.completed = (!s.abandoned).then_some(s.frame);
        }
        Ok(slot)
    }

    /// Waits for the next slot's previous frame (normally long finished), resets its command pool
    /// and begins recording.
    pub fn begin(&mut self, ctx: &Context) -> Result<FrameToken, VkError> {
        let slot = self.wait_next(ctx)?;
        let frame = self.next_frame;
        let s = &mut self.slots[slot];
        let completed_frame = s.completed.take();
        // SAFETY: the GPU finished every command buffer of this pool (fence above).
        unsafe {
            ctx.device
                .reset_command_pool(s.pool, vk::CommandPoolResetFlags::empty())
        }
        .vk("vkResetCommandPool")?;
        if s.async_pool != vk::CommandPool::null() {
            // SAFETY: as above: the fence covers the async parts (the last part joins them).
            unsafe {
                ctx.device
                    .reset_command_pool(s.async_pool, vk::CommandPoolResetFlags::empty())
            }
            .vk("vkResetCommandPool")?;
        }
        s.async_begun = 0;
        s.async_submitted = false;
        let cb = s.cbs.first().copied().ok_or_else(|| VkError::Invalid {
            what: "frame ring".into(),
            reason: "the slot has no command buffer".into(),
        })?;
        s.begun = 1;
        s.flushed = false;
        s.abandoned = false;
        let begin = vk::CommandBufferBeginInfo::default()
            .flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT);
        // SAFETY: reset command buffer.
        unsafe { ctx.device.begin_command_buffer(cb, &begin) }.vk("vkBeginCommandBuffer")?;
        s.frame = frame;
        self.next_frame += 1;
        Ok(FrameToken {
            slot,
            frame,
            cb,
            completed_frame,
        })
    }

    /// Begins frame recording into the engine's `cb` (recording) for its slot `slot`, whose
    /// previous frame the engine vouches has completed.
    pub fn begin_engine(
        &mut self,
        slot: usize,
        cb: vk::CommandBuffer,
    ) -> Result<FrameToken, VkError> {
        self.expect(Submission::Engine)?;
        let n = self.slots.len();
        if cb == vk::CommandBuffer::null() {
            return Err(VkError::Invalid {
                what: "engine frame".into(),
                reason: "the command buffer is null".into(),
            });
        }
        let s = self.slots.get_mut(slot).ok_or_else(|| VkError::Invalid {
            what: "engine frame".into(),
            reason: format!(
                "slot {slot} out of the {n} frames in flight the renderer was made for"
            ),
        })?;
        let completed_frame = (s.in_flight && !s.abandoned).then_some(s.frame);
        s.in_flight = false;
        s.abandoned = false;
        s.completed = None;
        let frame = self.next_frame;
        s.frame = frame;
        self.next_frame += 1;
        Ok(FrameToken {
            slot,
            frame,
            cb,
            completed_frame,
        })
    }

    /// The engine's frame is recorded: it submits it.
    pub fn end_engine(&mut self, token: &FrameToken) {
        if let Some(s) = self.slots.get_mut(token.slot) {
            s.in_flight = true;
        }
    }

    fn expect(&self, submission: Submission) -> Result<(), VkError> {
        if self.submission == submission {
            return Ok(());
        }
        Err(VkError::Invalid {
            what: "frame ring".into(),
            reason: match submission {
                Submission::Owned => {
                    "the engine submits this renderer's frames: record them into its command buffer"
                        .into()
                }
                Submission::Engine => {
                    "this renderer submits its own frames: it takes no command buffer".into()
                }
            },
        })
    }

    fn slot_mut(&mut self, slot: usize) -> Result<&mut FrameSlot, VkError> {
        self.slots.get_mut(slot).ok_or_else(|| VkError::Invalid {
            what: "frame ring".into(),
            reason: format!("slot {slot} does not exist"),
        })
    }

    /// The device queue a part of `queue` goes to.
    fn device_queue(ctx: &Context, queue: Queue) -> vk::Queue {
        match (queue, ctx.async_queue) {
            (Queue::AsyncCompute, Some(a)) => a.queue,
            _ => ctx.queue,
        }
    }

    /// `part`'s waits (into `wait_infos`) and its signal, the next value of its queue's
    /// timeline.
    fn part_sync(&mut self, part: &QueuePart<'_>) -> vk::SemaphoreSubmitInfo<'static> {
        let timelines = self.timelines;
        self.wait_infos.clear();
        self.wait_infos
            .extend(part.waits.iter().map(|&(q, value, stages)| {
                vk::SemaphoreSubmitInfo::default()
                    .semaphore(timelines[timeline_slot(q)])
                    .value(value)
                    .stage_mask(stages)
            }));
        let k = timeline_slot(part.queue);
        self.signaled[k] += 1;
        vk::SemaphoreSubmitInfo::default()
            .semaphore(self.timelines[k])
            .value(self.signaled[k])
            .stage_mask(vk::PipelineStageFlags2::ALL_COMMANDS)
    }

    /// The timeline value the last part submitted to `queue` signalled.
    pub fn signaled(&self, queue: Queue) -> u64 {
        self.signaled[timeline_slot(queue)]
    }

    /// Submits the commands recorded so far as `part` (waiting on the other queue's timeline
    /// for its values, signalling its own: the value is [`FrameRing::signaled`] after), and
    /// continues recording in a fresh command buffer for `next`'s queue family.
    pub fn submit_part(
        &mut self,
        ctx: &Context,
        token: &mut FrameToken,
        part: &QueuePart<'_>,
        next: Queue,
    ) -> Result<(), VkError> {
        self.expect(Submission::Owned)?;
        if self.timelines[0] == vk::Semaphore::null() {
            return Err(VkError::Invalid {
                what: "frame ring".into(),
                reason: "a plan of two queues on a context without async compute".into(),
            });
        }
        // SAFETY: recording command buffer of this slot.
        unsafe { ctx.device.end_command_buffer(token.cb) }.vk("vkEndCommandBuffer")?;
        let signal = self.part_sync(part);
        let cbs = [vk::CommandBufferSubmitInfo::default().command_buffer(token.cb)];
        let signals = [signal];
        let submit = vk::SubmitInfo2::default()
            .wait_semaphore_infos(&self.wait_infos)
            .command_buffer_infos(&cbs)
            .signal_semaphore_infos(&signals);
        ctx.queue_submit2(
            Self::device_queue(ctx, part.queue),
            &[submit],
            vk::Fence::null(),
        )?;
        let s = self.slot_mut(token.slot)?;
        s.flushed = true;
        s.async_submitted |= part.queue == Queue::AsyncCompute;
        let own_pool = next == Queue::AsyncCompute && s.async_pool != vk::CommandPool::null();
        let cb = if own_pool {
            begin_next(ctx, s.async_pool, &mut s.async_cbs, &mut s.async_begun)?
        } else {
            begin_next(ctx, s.pool, &mut s.cbs, &mut s.begun)?
        };
        token.cb = cb;
        Ok(())
    }

    /// Ends recording and submits; the slot's fence signals when the GPU is done.
    pub fn submit(&mut self, ctx: &Context, token: FrameToken) -> Result<(), VkError> {
        self.submit_last(ctx, token, None)
    }

    /// [`FrameRing::submit`] of a frame's last part (`part`: its waits on the other queue, in
    /// a plan of two queues).
    pub fn submit_last(
        &mut self,
        ctx: &Context,
        token: FrameToken,
        part: Option<&QueuePart<'_>>,
    ) -> Result<(), VkError> {
        if self.submission == Submission::Engine {
            self.end_engine(&token);
            return Ok(());
        }
        let fence = self
            .slots
            .get(token.slot)
            .ok_or_else(|| VkError::Invalid {
                what: "frame ring".into(),
                reason: format!("slot {} does not exist", token.slot),
            })?
            .fence;
        let timelines = self.timelines[0] != vk::Semaphore::null();
        let sync = part
            .filter(|_| timelines)
            .map(|p| (p.queue, self.part_sync(p)));
        let submitted = (|| {
            // SAFETY: the command buffer is recording (begin or flush gave it to this token).
            unsafe { ctx.device.end_command_buffer(token.cb) }.vk("vkEndCommandBuffer")?;
            ctx.injected_fault_at(FaultSite::Submit, "vkQueueSubmit (injected fault)")?;
            if let Some((queue, signal)) = &sync {
                let cbs = [vk::CommandBufferSubmitInfo::default().command_buffer(token.cb)];
                let signals = [*signal];
                let submit = vk::SubmitInfo2::default()
                    .wait_semaphore_infos(&self.wait_infos)
                    .command_buffer_infos(&cbs)
                    .signal_semaphore_infos(&signals);
                return ctx.queue_submit2(Self::device_queue(ctx, *queue), &[submit], fence);
            }
            let cbs = [token.cb];
            let submit = vk::SubmitInfo::default().command_buffers(&cbs);
            // SAFETY: executable command buffer, unsignalled fence.
            unsafe { ctx.device.queue_submit(ctx.queue, &[submit], fence) }.vk("vkQueueSubmit")
        })();
        match submitted {
            Ok(()) => {
                if let Some(s) = self.slots.get_mut(token.slot) {
                    s.in_flight = true;
                }
                Ok(())
            }
            Err(e) => {
                // Whatever was flushed earlier in the frame still runs: track it as for any
                // frame given up, and report the submit's error.
                if let Err(gave_up) = self.abandon(ctx, &token) {
                    log::error!("giving up the frame after \"{e}\": {gave_up}");
                }
                Err(e)
            }
        }
    }

    /// Submits the commands recorded so far and continues recording in a fresh command buffer of
    /// the same slot (seed 001: a flush before the occlusion-query render pass on Adreno).
    pub fn flush(&mut self, ctx: &Context, token: &mut FrameToken) -> Result<(), VkError> {
        self.expect(Submission::Owned)?;
        let s = self.slot_mut(token.slot)?;
        // SAFETY: recording command buffer of this slot.
        unsafe { ctx.device.end_command_buffer(token.cb) }.vk("vkEndCommandBuffer")?;
        let cbs = [token.cb];
        let submit = vk::SubmitInfo::default().command_buffers(&cbs);
        // SAFETY: executable command buffer; no fence: the slot's fence covers the final submit,
        // and queue order makes it cover this one too.
        unsafe {
            ctx.device
                .queue_submit(ctx.queue, &[submit], vk::Fence::null())
        }
        .vk("vkQueueSubmit")?;
        s.flushed = true;
        // The next command buffer of the slot: allocated once, recycled by every pool reset.
        let cb = begin_next(ctx, s.pool, &mut s.cbs, &mut s.begun)?;
        // The slot's final submit uses the new buffer.
        token.cb = cb;
        Ok(())
    }

    /// Gives up the frame being recorded (after an error): nothing more of it is submitted. If
    /// part of it was flushed to the GPU, an empty submission with the slot's fence tracks that
    /// work (its fence signals after everything submitted before it), so the slot waits for it
    /// before its pool is reset or resources are destroyed; the frame is never reported complete.
    pub fn abandon(&mut self, ctx: &Context, token: &FrameToken) -> Result<(), VkError> {
        let Some(s) = self.slots.get_mut(token.slot) else {
            return Ok(());
        };
        s.abandoned = true;
        if self.submission == Submission::Engine {
            // The engine does not submit a frame whose recording failed (EMBEDDING.md); the
            // slot holds nothing to read.
            s.in_flight = true;
            return Ok(());
        }
        if s.flushed {
            let tracked = if s.async_submitted {
                // The fence waits for the async queue's parts too.
                let waits = [vk::SemaphoreSubmitInfo::default()
                    .semaphore(self.timelines[1])
                    .value(self.signaled[1])
                    .stage_mask(vk::PipelineStageFlags2::ALL_COMMANDS)];
                let submit = vk::SubmitInfo2::default().wait_semaphore_infos(&waits);
                ctx.queue_submit2(ctx.queue, &[submit], s.fence)
            } else {
                // SAFETY: unsignalled fence of this slot (waited and reset before `begin`).
                unsafe { ctx.device.queue_submit(ctx.queue, &[], s.fence) }.vk("vkQueueSubmit")
            };
            match tracked {
                Ok(()) => s.in_flight = true,
                Err(e) => {
                    // The fence cannot track the flushed work: wait for the whole device, so
                    // none of it still runs when the slot's pool is reset or resources go.
                    // SAFETY: plain wait.
                    if let Err(idle) = unsafe { ctx.device.device_wait_idle() } {
                        log::error!("vkDeviceWaitIdle after a failed submit: {idle}");
                    }
                    return Err(e);
                }
            }
        }
        Ok(())
    }

    /// Waits for every slot (before reading results or tearing down).
    pub fn wait_all(&mut self, ctx: &Context) -> Result<Vec<u64>, VkError> {
        let mut done = Vec::new();
        if self.submission == Submission::Engine {
            // No fence of ours tracks the engine's submissions: wait for the device (the
            // engine's queue is not in use meanwhile: Context::adopt's contract).
            if self.slots.iter().any(|s| s.in_flight) {
                ctx.wait_idle()?;
            }
            for s in &mut self.slots {
                if std::mem::take(&mut s.in_flight) && !s.abandoned {
                    done.push(s.frame);
                }
            }
            return Ok(done);
        }
        for s in &mut self.slots {
            if let Some(f) = s.completed.take() {
                done.push(f);
            }
            if s.in_flight {
                // SAFETY: fence submitted with this slot's last frame.
                unsafe { ctx.device.wait_for_fences(&[s.fence], true, u64::MAX) }
                    .vk("vkWaitForFences")?;
                // SAFETY: signalled, unused.
                unsafe { ctx.device.reset_fences(&[s.fence]) }.vk("vkResetFences")?;
                s.in_flight = false;
                s.completed = None;
                if !s.abandoned {
                    done.push(s.frame);
                }
            }
        }
        Ok(done)
    }

    /// Slot that recorded `frame`, if it is still the last frame of that slot.
    pub fn slot_of(&self, frame: u64) -> Option<usize> {
        self.slots.iter().position(|s| s.frame == frame)
    }

    pub fn destroy(&mut self, ctx: &Context) {
        for s in self.slots.drain(..) {
            // SAFETY: caller waited for the GPU (wait_all or device idle).
            unsafe {
                ctx.device.destroy_fence(s.fence, None);
                ctx.device.destroy_command_pool(s.pool, None);
                if s.async_pool != vk::CommandPool::null() {
                    ctx.device.destroy_command_pool(s.async_pool, None);
                }
            }
        }
        for t in &mut self.timelines {
            if *t != vk::Semaphore::null() {
                // SAFETY: the caller waited for the GPU: no submission uses it.
                unsafe { ctx.device.destroy_semaphore(*t, None) };
                *t = vk::Semaphore::null();
            }
        }
    }
}

/// Begins the next command buffer of `pool` this frame (`cbs[*begun]`, allocated once and
/// recycled by every reset of the pool).
fn begin_next(
    ctx: &Context,
    pool: vk::CommandPool,
    cbs: &mut Vec<vk::CommandBuffer>,
    begun: &mut usize,
) -> Result<vk::CommandBuffer, VkError> {
    let cb = match cbs.get(*begun) {
        Some(&cb) => cb,
        None => {
            let alloc = vk::CommandBufferAllocateInfo::default()
                .command_pool(pool)
                .level(vk::CommandBufferLevel::PRIMARY)
                .command_buffer_count(1);
            // SAFETY: live pool; its buffers are freed with it.
            let cb = unsafe { ctx.device.allocate_command_buffers(&alloc) }
                .vk("vkAllocateCommandBuffers")?;
            let cb = cb.first().copied().ok_or_else(|| VkError::Invalid {
                what: "frame ring".into(),
                reason: "no command buffer allocated".into(),
            })?;
            cbs.push(cb);
            cb
        }
    };
    *begun += 1;
    let begin =
        vk::CommandBufferBeginInfo::default().flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT);
    // SAFETY: a fresh command buffer, or one reset with its pool (the slot's fence waited).
    unsafe { ctx.device.begin_command_buffer(cb, &begin) }.vk("vkBeginCommandBuffer")?;
    Ok(cb)
}
