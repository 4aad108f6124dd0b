//! Runs of draw groups: a list whose groups are drawn by different pipelines (engine materials,
//! crate::materials) is recorded run by run — consecutive groups of one pipeline — from a frame
//! that kept a command per group (culled groups as empty commands), so that group `k` of the
//! list is command `k`. Draw order is the list's, as with one pipeline.

use tilegraph_vk::ash::vk;
use tilegraph_vk::{Context, VkError};

use super::{ClusterStage, CullState, SlotInputs, LISTS_PER_PHASE};
use crate::cull::clusters::group_slot;
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
        let Some(places) = inputs.group_places.get(start..start + groups) else {
            return Err(VkError::Invalid {
                what: "engine material draws".into(),
                reason: "the frame's culling placed no cluster commands per group".into(),
            });
        };
        let first = (first as usize).min(groups);
        let end = first.saturating_add(count as usize).min(groups);
        // The group's draw count in the places: group_slot(2, region, group).
        let region = list / LISTS_PER_PHASE;
        let count_at =
            |g: usize| 4 * group_slot(inputs.stride, inputs.group_total, 2, region, g as u32);
        let base = u64::from(c.room.cmd_base.get(list as usize).copied().unwrap_or(0));
        for (j, &(place, room)) in places.iter().enumerate().take(end).skip(first) {
            if room == 0 {
                continue;
            }
            let offset = (base + u64::from(place)) * 20;
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
        if inputs.group_places.is_empty() {
            return Ok(None);
        }
        let places = tilegraph_vk::readback::read_buffer(ctx, Self::handle(&c.offsets))?;
        Ok(Some(FixedPlaces {
            places: places
                .chunks_exact(4)
                .map(|w| u32::from_le_bytes([w[0], w[1], w[2], w[3]]))
                .collect(),
            stride: inputs.stride,
            groups: inputs.group_total,
            group_start: inputs.group_start,
            group_count: inputs.group_count,
        }))
    }
}

impl SlotInputs {
    /// What a frame whose lists engine materials draw (`group_runs`) keeps of `layout`: each
    /// draw group's mesh, and with a cluster stage each group's place and room (fixed places).
    pub(super) fn keep_groups(
        &mut self,
        group_runs: bool,
        layout: &GpuLayout,
        clusters: Option<&ClusterStage>,
    ) {
        self.group_meshes.clear();
        self.group_places.clear();
        if !group_runs {
            return;
        }
        self.group_meshes.extend(layout.groups.iter().map(|g| g[2]));
        let Some(c) = clusters else {
            return;
        };
        // Groups come list by list (GpuLayout::fill): each list's places start at 0.
        let mut list = u32::MAX;
        let mut place = 0u32;
        for g in &layout.groups {
            if g[3] % LISTS_PER_PHASE != list {
                list = g[3] % LISTS_PER_PHASE;
                place = 0;
            }
            let room = c.group_room(g[1], g[2]);
            self.group_places.push((place, room));
            place = place.saturating_add(room);
            debug_assert!(
                place <= c.room.capacity[list as usize],
                "list {list}'s groups need more commands than its room holds"
            );
        }
    }
}
