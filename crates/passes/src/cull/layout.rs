//! The draw groups the culling shaders work through: the scene's buckets, list by list.

use tilegraph_scene::DrawGroup;

/// The scene's buckets as draw groups of the GPU lists. Refilled in place each frame (one
/// entry per bucket, not per instance): no allocation once it has the scene's size.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct GpuLayout {
    /// The draw groups, list by list: `[position, len, mesh, list, first]` (`Group` of
    /// cull.glsl; `first`: the list's entries in the groups before it), one per non-empty
    /// bucket, in draw order.
    pub groups: Vec<[u32; 5]>,
    /// Per list of a phase: its first group.
    pub group_start: [u32; 4],
    /// Per list of a phase: its number of groups.
    pub group_count: [u32; 4],
    /// Entries of a phase's lists: the instances GPU culling decides for.
    pub entries: u32,
    /// Entries per list.
    pub stride: u32,
}

impl GpuLayout {
    /// Refills the layout from this frame's `groups` (the scene's buckets in draw order, list
    /// by list) of lists of `stride` entries.
    pub fn fill(&mut self, groups: &[DrawGroup], stride: u32) {
        self.groups.clear();
        self.group_start = [0; 4];
        self.group_count = [0; 4];
        self.entries = 0;
        self.stride = stride;
        let mut first = [0u32; 4];
        for g in groups {
            let l = g.list as usize % 4;
            if self.group_count[l] == 0 {
                self.group_start[l] = self.groups.len() as u32;
            }
            self.group_count[l] += 1;
            self.entries += g.len;
            self.groups
                .push([g.position, g.len, g.mesh, g.list, first[l]]);
            first[l] += g.len;
        }
        // Groups come list by list (crate::draws::order_groups); a list with none starts where
        // the next would.
        let mut at = 0;
        for l in 0..4 {
            if self.group_count[l] == 0 {
                self.group_start[l] = at;
            }
            at = self.group_start[l] + self.group_count[l];
        }
    }
}
