//! Runs of draw groups: a list whose groups are drawn by different pipelines (engine materials,
//! crate::materials) is recorded run by run — consecutive groups of one pipeline — from a frame
//! that kept a command per group (culled groups as empty commands), so that group `k` of the
//! list is command `k`. Draw order is the list's, as with one pipeline.

use tilegraph_vk::ash::vk;
use tilegraph_vk::{Context, VkError};

use super::{CullState, LISTS_PER_PHASE};

impl CullState {
    /// The mesh of each of list `list`'s draw groups in slot `slot`'s frame, in draw order.
    pub fn group_meshes(&self, slot: usize, list: u32) -> Result<&[u32], VkError> {
        let inputs = self.slot(slot)?;
        let local = (list % LISTS_PER_PHASE) as usize;
        let start = inputs.group_start.get(local).copied().unwrap_or(0) as usize;
        let count = inputs.group_count.get(local).copied().unwrap_or(0) as usize;
        Ok(inputs.group_meshes.get(start..start + count).unwrap_or(&[]))
    }

    /// Records groups `first..first + count` of list `list` (slot `slot`'s frame, which must have
    /// kept a command per group: [`CullState::group_runs`]).
    pub fn record_group_run(
        &self,
        ctx: &Context,
        cb: vk::CommandBuffer,
        slot: usize,
        list: u32,
        (first, count): (u32, u32),
    ) -> Result<(), VkError> {
        let inputs = self.slot(slot)?;
        let refuse = |reason: &str| VkError::Invalid {
            what: "engine material draws".into(),
            reason: reason.into(),
        };
        if self.clusters.is_some() {
            return Err(refuse(
                "cluster culling draws clusters, not the lists' groups: engine materials are \
                 drawn with instance culling (none, frustum, hiz, hiz-2phase, reproject)",
            ));
        }
        if !inputs.kept_every_group {
            return Err(refuse("the frame's culling kept no command per group"));
        }
        let local = (list % LISTS_PER_PHASE) as usize;
        let groups = inputs.group_count.get(local).copied().unwrap_or(0);
        if count == 0 || first + count > groups {
            return Ok(());
        }
        // With levels of detail a group is `lod_levels` consecutive commands.
        let slots = u64::from(self.command_slots());
        let levels = self.lod_levels.max(1);
        let offset = (u64::from(list) * slots + u64::from(first * levels)) * 20;
        let count = count * levels;
        let d = &ctx.device;
        if ctx.has_feature(tilegraph_vk::Feature::MultiDrawIndirect) {
            // SAFETY: inside a render pass with the pipeline, buffers and sets bound; commands
            // `first..first + count` of the list lie inside its `slots`, written this frame.
            unsafe { d.cmd_draw_indexed_indirect(cb, self.commands.raw, offset, count, 20) };
        } else {
            for k in 0..u64::from(count) {
                // SAFETY: as above, one command at a time.
                unsafe {
                    d.cmd_draw_indexed_indirect(cb, self.commands.raw, offset + 20 * k, 1, 20)
                };
            }
        }
        Ok(())
    }
}
