//! Drawing the culled lists: the indirect calls of a list, and how many command slots a list
//! has (a command per draw group and level of detail).

use tilegraph_vk::ash::vk;
use tilegraph_vk::{Context, Feature, VkError};

use tilegraph_profile::IndirectCount;

use super::{CullState, LISTS_PER_PHASE};

impl CullState {
    /// Records list `list`'s draws of frame slot `slot`: one `vkCmdDrawIndexedIndirectCount`,
    /// or with a fixed count one command per draw group.
    pub fn record_draws(
        &self,
        ctx: &Context,
        cb: vk::CommandBuffer,
        slot: usize,
        (list, from_clusters): (u32, bool),
    ) -> Result<(), VkError> {
        let inputs = self.slot(slot)?;
        let groups = inputs
            .group_count
            .get((list % LISTS_PER_PHASE) as usize)
            .copied()
            .unwrap_or(0);
        if groups == 0 {
            return Ok(());
        }
        let slots = u64::from(self.command_slots());
        let clusters = self.clusters.as_ref().filter(|_| from_clusters);
        // Engine materials' frames place cluster commands group by group (runs.rs).
        if let (Some(c), true) = (clusters, !inputs.group_places.is_empty()) {
            return self.record_cluster_groups(ctx, cb, (inputs, c), list, (0, groups));
        }
        let (commands, counts, offset, groups) = match clusters {
            // Cluster lists: the list's commands from its base, up to its capacity.
            Some(c) => {
                let local = (list % LISTS_PER_PHASE) as usize;
                let capacity = c.room.capacity.get(local).copied().unwrap_or(0);
                let base = c.room.cmd_base.get(list as usize).copied().unwrap_or(0);
                if capacity == 0 {
                    return Ok(());
                }
                (&c.commands, &c.counts, u64::from(base) * 20, capacity)
            }
            None => (
                &self.commands,
                &self.counts,
                u64::from(list) * slots * 20,
                groups * self.lod_levels,
            ),
        };
        let count = (counts.raw, u64::from(list) * 4);
        // SAFETY: inside a render pass with a pipeline, buffers and sets bound (this pass's
        // recording); the list holds `slots` >= `groups` commands from `offset` (its capacity,
        // for cluster lists), every one written by cull_commands.comp or the emit this frame
        // (cleared with a fixed count); its count is word `list` of the counts.
        unsafe { self.record_commands(ctx, cb, commands.raw, (offset, groups), Some(count)) };
        Ok(())
    }

    /// Records up to `max` indexed indirect commands of `commands` from byte `offset`: as many
    /// as the GPU wrote at `count` (a buffer and byte offset) where the lists are counted on the
    /// GPU, else all of them (the unused ones empty), in one call where the device draws several
    /// per call.
    ///
    /// # Safety
    /// `cb` is inside a render pass with a pipeline, vertex/index buffers and sets bound; the
    /// `max` commands of 20 bytes from `offset` lie inside `commands`, each one written (or
    /// cleared) this frame, and `count`'s word lies inside its buffer.
    pub(super) unsafe fn record_commands(
        &self,
        ctx: &Context,
        cb: vk::CommandBuffer,
        commands: vk::Buffer,
        (offset, max): (u64, u32),
        count: Option<(vk::Buffer, u64)>,
    ) {
        let d = &ctx.device;
        match (self.draw_count, count) {
            // SAFETY (all three): as the caller promises.
            (DrawCount::Gpu, Some((counts, at))) => unsafe {
                d.cmd_draw_indexed_indirect_count(cb, commands, offset, counts, at, max, 20);
            },
            _ if ctx.has_feature(Feature::MultiDrawIndirect) => unsafe {
                d.cmd_draw_indexed_indirect(cb, commands, offset, max, 20);
            },
            _ => {
                for k in 0..u64::from(max) {
                    unsafe { d.cmd_draw_indexed_indirect(cb, commands, offset + 20 * k, 1, 20) };
                }
            }
        }
    }

    /// Command slots per list: a command per draw group and level of detail.
    pub fn command_slots(&self) -> u32 {
        self.capacity.groups.max(1) * self.lod_levels
    }
}

/// How the culled lists are drawn (chosen when the culling state is made, from the profile's
/// `indirect_count` and the device's features).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DrawCount {
    /// `vkCmdDrawIndexedIndirectCount`: the GPU's count covers the surviving groups only.
    Gpu,
    /// One command per draw group, culled groups with zero instances; `multi_draw`: in one
    /// `vkCmdDrawIndexedIndirect` (else one call per command, without `multiDrawIndirect`).
    Fixed { multi_draw: bool },
}

impl DrawCount {
    /// The mode for `ctx`'s profile and device.
    pub fn for_device(ctx: &Context) -> Self {
        let wanted = ctx.profile().passes.indirect_count == IndirectCount::WhenSupported;
        if wanted && ctx.has_feature(Feature::DrawIndirectCount) {
            DrawCount::Gpu
        } else {
            DrawCount::Fixed {
                multi_draw: ctx.has_feature(Feature::MultiDrawIndirect),
            }
        }
    }
}
