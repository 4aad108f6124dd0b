//! Drawing the culled lists: the indirect calls of a list, and how many command slots a list
//! has (a command per draw group and level of detail).

use tilegraph_vk::ash::vk;
use tilegraph_vk::{Context, VkError};

use super::{CullState, DrawCount, LISTS_PER_PHASE};

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
        if let (Some(c), true) = (clusters, !inputs.group_rooms.is_empty()) {
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
        let d = &ctx.device;
        // SAFETY (all three): inside a render pass with a pipeline, vertex/index buffers and
        // sets bound; list `list` holds `slots` >= `groups` commands of 20 bytes from `offset`,
        // every one written by cull_commands.comp this frame.
        match self.draw_count {
            DrawCount::Gpu => unsafe {
                d.cmd_draw_indexed_indirect_count(
                    cb,
                    commands.raw,
                    offset,
                    counts.raw,
                    u64::from(list) * 4,
                    groups,
                    20,
                );
            },
            DrawCount::Fixed { multi_draw: true } => unsafe {
                d.cmd_draw_indexed_indirect(cb, commands.raw, offset, groups, 20);
            },
            DrawCount::Fixed { multi_draw: false } => {
                for k in 0..u64::from(groups) {
                    unsafe {
                        d.cmd_draw_indexed_indirect(cb, commands.raw, offset + 20 * k, 1, 20)
                    };
                }
            }
        }
        Ok(())
    }

    /// Command slots per list: a command per draw group and level of detail.
    pub fn command_slots(&self) -> u32 {
        self.capacity.groups.max(1) * self.lod_levels
    }
}
