//! The renderer's non-blocking counts of what GPU culling drew: copied to the slot's
//! host-visible buffer after the culling, read when the slot comes round again.

use ash::vk;
use tilegraph_vk::ash;
use tilegraph_vk::{Context, VkError};

use super::{CullState, GpuCullCounts, LISTS_PER_PHASE, LIST_COUNT};

impl CullState {
    /// Records the reset of the cluster stage's chunk lists (nothing without one).
    pub fn record_work_reset(&self, ctx: &Context, cb: vk::CommandBuffer) -> Result<(), VkError> {
        if let Some(c) = &self.clusters {
            c.record_work_reset(ctx, cb);
        }
        Ok(())
    }

    /// Records the copy of this frame's counts into frame slot `slot`'s host-visible stats
    /// buffer (the graph made the counts readable by transfers), made visible to the host:
    /// [`CullState::collect`] reads it once the slot's frame has completed.
    pub fn record_stats_copy(
        &self,
        ctx: &Context,
        cb: vk::CommandBuffer,
        slot: usize,
    ) -> Result<(), VkError> {
        let stats = &self.slot(slot)?.stats;
        // The cluster lists' counts have the instance lists' layout (cluster_place.comp).
        let counts = self.clusters.as_ref().map_or(&self.counts, |c| &c.counts);
        let region = [vk::BufferCopy {
            src_offset: 0,
            dst_offset: 0,
            size: stats.size.min(counts.size),
        }];
        // SAFETY: recording outside a render pass; both buffers are live, the region fits both.
        unsafe {
            ctx.device
                .cmd_copy_buffer(cb, counts.raw, stats.raw, &region)
        };
        let to_host = [vk::BufferMemoryBarrier2::default()
            .src_stage_mask(vk::PipelineStageFlags2::COPY)
            .src_access_mask(vk::AccessFlags2::TRANSFER_WRITE)
            .dst_stage_mask(vk::PipelineStageFlags2::HOST)
            .dst_access_mask(vk::AccessFlags2::HOST_READ)
            .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
            .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
            .buffer(stats.raw)
            .offset(0)
            .size(vk::WHOLE_SIZE)];
        ctx.cmd_pipeline_barrier2(
            cb,
            &vk::DependencyInfo::default().buffer_memory_barriers(&to_host),
        )
    }

    /// What the last frame recorded in `slot` drew, read without waiting: call it once the
    /// slot's frame has completed (when the slot is acquired again). `None` before the slot's
    /// first frame, and once read.
    pub fn collect(
        &mut self,
        ctx: &Context,
        slot: usize,
    ) -> Result<Option<GpuCullCounts>, VkError> {
        let Some(inputs) = self.slots.get_mut(slot) else {
            return Ok(None);
        };
        let Some((frame, candidates)) = inputs.pending.take() else {
            return Ok(None);
        };
        ctx.invalidate_mapped(&inputs.stats)?;
        let word = |i: usize| {
            inputs
                .stats
                .mapped()
                .and_then(|b| b.get(4 * i..4 * i + 4))
                .map_or(0, |w| u32::from_le_bytes([w[0], w[1], w[2], w[3]]))
        };
        // The colour pass draws the early (or only) phase's lists: 0-3.
        let per_phase = LISTS_PER_PHASE as usize;
        let commands = (0..per_phase).map(word).sum();
        let instances: u32 = (0..per_phase).map(|l| word(LIST_COUNT as usize + l)).sum();
        Ok(Some(GpuCullCounts {
            frame,
            commands,
            instances,
            culled: candidates.saturating_sub(instances),
        }))
    }
}
