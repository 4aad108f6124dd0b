//! Runs of draw groups: a list whose groups are drawn by different pipelines (engine materials,
//! crate::materials) is recorded run by run — consecutive groups of one pipeline — from a frame
//! that kept a command per group (culled groups as empty commands), so that group `k` of the
//! list is command `k`. Draw order is the list's, as with one pipeline.

use tilegraph_vk::ash::vk;
use tilegraph_vk::{Context, VkError};

use super::{ClusterStage, CullState, SlotInputs, LISTS_PER_PHASE};
use crate::cull::layout::GpuLayout;
use crate::cull::readback::FixedPlaces;

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
    /// kept a command per group: [`CullState::group_runs`]), of the cluster stage's lists
    /// (`from_clusters`) or the instance compaction's.
    pub fn record_group_run(
        &self,
        ctx: &Context,
        cb: vk::CommandBuffer,
        slot: usize,
        (list, from_clusters): (u32, bool),
        (first, count): (u32, u32),
    ) -> Result<(), VkError> {
        let inputs = self.slot(slot)?;
        let refuse = |reason: &str| VkError::Invalid {
            what: "engine material draws".into(),
            reason: reason.into(),
        };
        if let Some(c) = self.clusters.as_ref().filter(|_| from_clusters) {
            return self.record_cluster_groups(ctx, cb, (inputs, c), list, (first, count));
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
        // SAFETY: inside a render pass with the pipeline, buffers and sets bound; commands
        // `first..first + count` of the list lie inside its `slots`, written this frame.
        unsafe { self.record_commands(ctx, cb, self.commands.raw, (offset, count), None) };
        Ok(())
    }

    /// Records groups `first..first + count` of cluster list `list` of a frame with fixed
    /// places: each group one indirect call from its place, of its runs.
    pub(super) fn record_cluster_groups(
        &self,
        ctx: &Context,
        cb: vk::CommandBuffer,
        (inputs, c): (&SlotInputs, &ClusterStage),
        list: u32,
        (first, count): (u32, u32),
    ) -> Result<(), VkError> {
        let local = (list % LISTS_PER_PHASE) as usize;
        let start = inputs.group_start.get(local).copied().unwrap_or(0) as usize;
        let groups = inputs.group_count.get(local).copied().unwrap_or(0) as usize;
        let Some(rooms) = inputs.group_rooms.get(start..start + groups) else {
            return Err(VkError::Invalid {
                what: "engine material draws".into(),
                reason: "the frame's culling placed no cluster commands per group".into(),
            });
        };
        let first = (first as usize).min(groups);
        let end = first.saturating_add(count as usize).min(groups);
        // cluster.glsl's group_slot(2, region, group): the group's draw count in the places.
        let stride = u64::from(inputs.stride.max(1));
        let groups_x = u64::from(inputs.group_total.max(1));
        let region = u64::from(list / LISTS_PER_PHASE);
        let count_at = |g: usize| 4 * (12 * stride + (4 + region) * groups_x + g as u64);
        let base = u64::from(c.room.cmd_base.get(list as usize).copied().unwrap_or(0));
        let mut place = base + rooms[..first].iter().map(|&r| u64::from(r)).sum::<u64>();
        for (j, &room) in rooms.iter().enumerate().take(end).skip(first) {
            let offset = place * 20;
            place += u64::from(room);
            if room == 0 {
                continue;
            }
            let count = (c.offsets.raw, count_at(start + j));
            // SAFETY: inside a render pass with the pipeline, buffers and sets bound; the
            // group's room of commands from `offset` lies inside the list's capacity (the rooms
            // of a list's groups sum to at most it: keep_groups), each one written or cleared
            // this frame; its count is group_slot(2, region, group) of the places.
            unsafe { self.record_commands(ctx, cb, c.commands.raw, (offset, room), Some(count)) };
        }
        Ok(())
    }

    /// Where the cluster commands of frame slot `slot`'s frame sit when engine materials drew
    /// it group by group (fixed places; `None`: packed), read back.
    pub(in crate::cull) fn fixed_places(
        &self,
        ctx: &Context,
        slot: usize,
    ) -> Result<Option<FixedPlaces>, VkError> {
        let (Some(c), Ok(inputs)) = (&self.clusters, self.slot(slot)) else {
            return Ok(None);
        };
        if inputs.group_rooms.is_empty() {
            return Ok(None);
        }
        let places = tilegraph_vk::readback::read_buffer(ctx, Self::handle(&c.offsets))?;
        Ok(Some(FixedPlaces {
            places: places
                .chunks_exact(4)
                .map(|w| u32::from_le_bytes([w[0], w[1], w[2], w[3]]))
                .collect(),
            stride: inputs.stride.max(1) as usize,
            groups: inputs.group_total.max(1) as usize,
            group_start: inputs.group_start,
            group_count: inputs.group_count,
        }))
    }
}

impl SlotInputs {
    /// What a frame whose lists engine materials draw (`group_runs`) keeps of `layout`: each
    /// draw group's mesh, and with a cluster stage each group's room (fixed places).
    pub(super) fn keep_groups(
        &mut self,
        group_runs: bool,
        layout: &GpuLayout,
        clusters: Option<&ClusterStage>,
    ) {
        self.group_meshes.clear();
        self.group_rooms.clear();
        if !group_runs {
            return;
        }
        self.group_meshes.extend(layout.groups.iter().map(|g| g[2]));
        let Some(c) = clusters else {
            return;
        };
        self.group_rooms
            .extend(layout.groups.iter().map(|g| c.group_room(g[1], g[2])));
        debug_assert!(
            (0..4).all(|l| {
                let start = layout.group_start[l] as usize;
                let end = start + layout.group_count[l] as usize;
                let rooms = self.group_rooms.get(start..end).unwrap_or(&[]);
                rooms.iter().map(|&r| u64::from(r)).sum::<u64>() <= u64::from(c.room.capacity[l])
            }),
            "a list's groups need more commands than its room holds"
        );
    }
}
