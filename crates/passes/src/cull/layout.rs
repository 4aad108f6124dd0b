//! Where the CPU draw list's instances sit in the GPU lists.

use super::list_index;
use crate::draws::DrawList;

/// Where the CPU draw list's instances sit in the GPU lists, in the order the CPU list draws
/// them (single-sided draws of a class first, then double-sided, as [`crate::recording`]
/// records them). Refilled in place each frame: no allocation once it has the scene's size.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct GpuLayout {
    /// Per instance: its entry, `list * stride + position` (phase 0 lists); `u32::MAX` for
    /// blended instances (not culled on the GPU).
    pub order: Vec<u32>,
    /// The draw groups, list by list: `[position, len, mesh, list]` (`Group` of cull.glsl),
    /// one per CPU instanced draw.
    pub groups: Vec<[u32; 4]>,
    /// Per list of a phase: its first group.
    pub group_start: [u32; 4],
    /// Per list of a phase: its number of groups.
    pub group_count: [u32; 4],
    /// Entries of a phase's lists: the instances GPU culling decides for.
    pub entries: u32,
}

impl GpuLayout {
    /// Refills the layout for `draws`.
    pub fn fill(&mut self, draws: &DrawList, instance_count: usize) {
        let stride = instance_count.max(1) as u32;
        self.order.clear();
        self.order.resize(instance_count, u32::MAX);
        self.groups.clear();
        self.entries = 0;
        for (class, list_draws) in [(0u32, &draws.opaque), (1, &draws.alpha_tested)] {
            for sided in [false, true] {
                let list = list_index(class, sided, 0);
                self.group_start[list as usize] = self.groups.len() as u32;
                let mut position = 0u32;
                for d in list_draws.iter().filter(|d| d.double_sided == sided) {
                    let start = position;
                    for k in d.first_instance..d.first_instance + d.instance_count {
                        if let Some(&id) = draws.instances.get(k as usize) {
                            if let Some(o) = self.order.get_mut(id as usize) {
                                *o = list * stride + position;
                                position += 1;
                            }
                        }
                    }
                    if position > start {
                        self.groups.push([start, position - start, d.mesh, list]);
                    }
                }
                self.group_count[list as usize] =
                    self.groups.len() as u32 - self.group_start[list as usize];
                self.entries += position;
            }
        }
    }
}
