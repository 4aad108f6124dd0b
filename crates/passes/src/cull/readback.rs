//! Reading the culled lists back (tests and tools; waits for the GPU).

use tilegraph_vk::{Context, VkError};

use super::clusters::group_slot;
use super::{CullState, DrawCount, LISTS_PER_PHASE, LIST_COUNT};

/// One indirect command of the culled lists, read back.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct IndirectDraw {
    pub index_count: u32,
    pub first_index: u32,
    /// The instance ids it draws, in draw order (empty: a culled group of a fixed count).
    pub instances: Vec<u32>,
}

/// The GPU lists of the last frame, read back for tests and tools.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct GpuLists {
    pub draw_count: DrawCount,
    /// Per list ([`list_index`]), the commands its draw count covers.
    pub lists: Vec<Vec<IndirectDraw>>,
    /// Per instance slot, its entry in the unculled order of the last frame written
    /// (`u32::MAX`: in no GPU list).
    pub order: Vec<u32>,
    /// Entries per list of the last frame (entry `e` is in list `e / stride`).
    pub stride: u32,
}

impl GpuLists {
    /// Triangles the colour pass draws: the early-or-only phase's lists (after a late phase,
    /// the union of both).
    pub fn colour_triangles(&self) -> u64 {
        self.lists
            .iter()
            .take(LISTS_PER_PHASE as usize)
            .flatten()
            .map(|d| u64::from(d.index_count / 3) * d.instances.len() as u64)
            .sum()
    }
}

impl CullState {
    /// The last frame's lists as the GPU left them (reads the counts, commands and draw ids
    /// back; waits).
    /// With cluster culling, the cluster commands: each draws one instance's index range
    /// (from each draw group's fixed place where engine materials drew frame slot `slot`'s
    /// frame group by group). `order`: the instances' entries of that frame (the scene's,
    /// [`crate::GpuScene`]).
    pub fn read_lists(
        &self,
        ctx: &Context,
        order: Vec<u32>,
        slot: usize,
    ) -> Result<GpuLists, VkError> {
        let (counts, commands) = match &self.clusters {
            Some(c) => (&c.counts, &c.commands),
            None => (&self.counts, &self.commands),
        };
        let counts = tilegraph_vk::readback::read_buffer(ctx, Self::handle(counts))?;
        let commands = tilegraph_vk::readback::read_buffer(ctx, Self::handle(commands))?;
        let ids = tilegraph_vk::readback::read_buffer(ctx, Self::handle(&self.draw_ids))?;
        let word = |b: &[u8], i: usize| {
            b.get(4 * i..4 * i + 4)
                .map_or(0, |w| u32::from_le_bytes([w[0], w[1], w[2], w[3]]))
        };
        let slots = self.command_slots() as usize;
        // Per list: where its commands start and how many it can hold.
        let place = |list: usize| match &self.clusters {
            Some(c) => (
                c.room.cmd_base.get(list).copied().unwrap_or(0) as usize,
                c.room.capacity.get(list % 4).copied().unwrap_or(0) as usize,
            ),
            None => (list * slots, slots),
        };
        // With fixed places, each list's commands are its groups' runs, each from its place.
        let fixed = self.fixed_places(ctx, slot)?;
        let lists = (0..LIST_COUNT as usize)
            .map(|list| {
                let (base, capacity) = place(list);
                let n = (word(&counts, list) as usize).min(capacity);
                let slots: Vec<usize> = match &fixed {
                    Some(f) => f.slots(list, base, capacity),
                    None => (base..base + n).collect(),
                };
                slots
                    .into_iter()
                    .map(|at| {
                        let (count, first) =
                            (word(&commands, 5 * at + 1), word(&commands, 5 * at + 4));
                        IndirectDraw {
                            index_count: word(&commands, 5 * at),
                            first_index: word(&commands, 5 * at + 2),
                            instances: (first..first.saturating_add(count))
                                .map(|i| word(&ids, i as usize))
                                .collect(),
                        }
                    })
                    .collect()
            })
            .collect();
        Ok(GpuLists {
            draw_count: self.draw_count,
            lists,
            order,
            stride: self.layout.stride,
        })
    }

    /// The instances drawn by frame slot `slot`'s frame: the ids each list's commands cover
    /// (waits).
    pub fn drawn_instances(&self, ctx: &Context, slot: usize) -> Result<Vec<u32>, VkError> {
        let lists = self.read_lists(ctx, Vec::new(), slot)?;
        let mut out: Vec<u32> = lists
            .lists
            .iter()
            .flatten()
            .flat_map(|d| d.instances.iter().copied())
            .collect();
        out.sort_unstable();
        out.dedup();
        Ok(out)
    }
}

/// The cluster stage's places of a frame drawn group by group, read back: per draw group and
/// region its first command (kind 0) and its draw count (kind 2), common/cluster.glsl's
/// `group_slot`.
pub(in crate::cull) struct FixedPlaces {
    pub(in crate::cull) places: Vec<u32>,
    pub(in crate::cull) stride: u32,
    pub(in crate::cull) groups: u32,
    pub(in crate::cull) group_start: [u32; 4],
    pub(in crate::cull) group_count: [u32; 4],
}

impl FixedPlaces {
    /// The command slots of list `list` (its commands from `base`, at most `capacity`), in draw
    /// order.
    fn slots(&self, list: usize, base: usize, capacity: usize) -> Vec<usize> {
        let (region, local) = (
            list / LISTS_PER_PHASE as usize,
            list % LISTS_PER_PHASE as usize,
        );
        let at = |kind: u32, g: usize| {
            let i = group_slot(self.stride, self.groups, kind, region as u32, g as u32);
            let i = usize::try_from(i).unwrap_or(usize::MAX);
            self.places.get(i).copied().unwrap_or(0) as usize
        };
        let start = self.group_start[local] as usize;
        let end = start + self.group_count[local] as usize;
        (start..end)
            .flat_map(|g| {
                let first = at(0, g).min(capacity);
                let n = at(2, g).min(capacity - first);
                base + first..base + first + n
            })
            .collect()
    }
}
