//! What the culling state's buffers take: the sizes it makes them with, and what they add up
//! to (`scene-info`'s GPU memory counts the same).

use ash::vk;
use tilegraph_profile::MemoryUse;
use tilegraph_vk::ash;

use super::{CullParams, CullState, SlotInputs, LIST_COUNT};
use crate::gpu_scene::Capacity;

impl CullState {
    /// The shared buffers for `capacity` (`cluster_commands`: the cluster stage's command
    /// slots; `lod_levels`: commands per draw group): name, bytes, usage.
    pub(super) fn buffer_specs(
        capacity: Capacity,
        cluster_commands: u64,
        lod_levels: u32,
    ) -> [(&'static str, u64, vk::BufferUsageFlags); 7] {
        let levels = u64::from(lod_levels.max(1));
        let n = u64::from(capacity.instances.max(1));
        let stride = u64::from(capacity.stride.max(1));
        let lists = u64::from(LIST_COUNT);
        let storage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let indirect = vk::BufferUsageFlags::INDIRECT_BUFFER;
        let src = vk::BufferUsageFlags::TRANSFER_SRC;
        let dst = vk::BufferUsageFlags::TRANSFER_DST;
        [
            (
                "cull commands",
                u64::from(capacity.groups.max(1)) * levels * lists * 20,
                storage | indirect | src,
            ),
            // Draw count, then instances drawn, per list.
            ("cull counts", 2 * lists * 4, storage | indirect | src),
            (
                "cull draw ids",
                (stride * lists + cluster_commands) * 4,
                storage | src,
            ),
            ("visibility", n * 4, storage | dst),
            ("cull entries", stride * lists * 4, storage),
            // At most one group per instance and phase; a count per level.
            ("cull survivors", 2 * n * levels * 4, storage),
            // Bound as the pyramid without one: never written, never read (the levels say 0).
            ("cull no pyramid", 16, storage),
        ]
    }

    /// Device memory of this state's instance-list buffers (what [`Self::list_bytes`] says
    /// they take; the cluster stage's and the pyramid's not counted).
    pub fn memory_bytes(&self) -> u64 {
        let shared = [
            &self.commands,
            &self.counts,
            &self.draw_ids,
            &self.visibility,
            &self.entries,
            &self.survivors,
            &self.no_pyramid,
        ];
        let slots = self
            .slots
            .iter()
            .flat_map(|s| [&s.params[0], &s.params[1], &s.groups, &s.stats]);
        let table = self.lod_table.iter().map(|t| &t.0);
        shared
            .into_iter()
            .chain(slots)
            .chain(table)
            .map(|b| b.size)
            .sum()
    }

    /// Device memory of the instance lists' buffers for `capacity` with `frames_in_flight`
    /// slots (the shared buffers and each slot's parameters, groups and counts).
    pub fn list_bytes(capacity: Capacity, frames_in_flight: usize) -> u64 {
        let shared: u64 = Self::buffer_specs(capacity, 0, 1).iter().map(|s| s.1).sum();
        let slot: u64 = SlotInputs::specs(u64::from(capacity.instances.max(1)))
            .iter()
            .map(|s| s.1)
            .sum();
        shared + slot * frames_in_flight.max(1) as u64
    }
}

impl SlotInputs {
    /// Frame slot buffers for `n` instances: name, bytes, usage, memory.
    pub(super) fn specs(n: u64) -> [(&'static str, u64, vk::BufferUsageFlags, MemoryUse); 4] {
        let uniform = vk::BufferUsageFlags::UNIFORM_BUFFER;
        let storage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let params_size = std::mem::size_of::<CullParams>() as u64;
        let streaming = MemoryUse::Streaming;
        [
            ("params.early", params_size, uniform, streaming),
            ("params.late", params_size, uniform, streaming),
            // At most one group per instance.
            ("groups", n * 20, storage, streaming),
            (
                "stats",
                2 * u64::from(LIST_COUNT) * 4,
                vk::BufferUsageFlags::TRANSFER_DST,
                MemoryUse::Readback,
            ),
        ]
    }
}
