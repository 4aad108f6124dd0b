//! What the CPU wrote for the GPU lists of one frame slot's frame: its parameter blocks, draw
//! groups and counts, and what its draws need to know of them.

use tilegraph_vk::{Buffer, Context, VkError};

use super::destroy_buffers;

/// Per frame slot: what the CPU wrote for the GPU lists of that slot's frame.
pub(super) struct SlotInputs {
    pub(super) params: [Buffer; 2],
    /// The draw groups (`Groups` of common/cull.glsl).
    pub(super) groups: Buffer,
    /// Entries per list of the slot's frame (the scene's stride then).
    pub(super) stride: u32,
    /// Groups per list of a phase, as written (what the draws of that frame cover).
    pub(super) group_count: [u32; 4],
    /// Groups per phase.
    pub(super) group_total: u32,
    /// The counts buffer as the slot's frame left it (`cull-stats` copies it; host-visible).
    pub(super) stats: Buffer,
    /// The frame whose counts `stats` will hold, and the instances it culled on the GPU.
    pub(super) pending: Option<(u64, u32)>,
    /// The mesh of each draw group, list by list as `group_start` / `group_count` say, and
    /// whether the frame kept a command per group (`runs.rs`: engine materials' runs).
    pub(super) group_meshes: Vec<u32>,
    /// With cluster culling and engine materials (fixed places, `runs.rs`): per draw group,
    /// in the frame's order, its first command within its list (the rooms of the list's groups
    /// before it) and its room — the most commands it can need — as `cluster_place.comp`
    /// counts them.
    pub(super) group_places: Vec<(u32, u32)>,
    pub(super) group_start: [u32; 4],
    pub(super) kept_every_group: bool,
}

impl SlotInputs {
    /// Frame slot `slot`'s parameter blocks and groups for up to `n` instances.
    pub(super) fn new(ctx: &Context, slot: u32, n: u64) -> Result<Self, VkError> {
        let specs = Self::specs(n);
        let mut made = Vec::with_capacity(specs.len());
        for (what, size, usage, memory) in specs {
            let name = format!("cull {what}[{slot}]");
            match ctx.create_buffer(&name, size, usage, memory) {
                Ok(b) => made.push(b),
                Err(e) => {
                    destroy_buffers(ctx, made);
                    return Err(e);
                }
            }
        }
        match <[Buffer; 4]>::try_from(made) {
            Ok([early, late, groups, stats]) => Ok(SlotInputs {
                params: [early, late],
                groups,
                stride: 1,
                group_count: [0; 4],
                group_total: 0,
                stats,
                pending: None,
                group_meshes: Vec::new(),
                group_places: Vec::new(),
                group_start: [0; 4],
                kept_every_group: false,
            }),
            Err(made) => {
                destroy_buffers(ctx, made);
                Err(VkError::Invalid {
                    what: "cull".into(),
                    reason: "slot buffers missing".into(),
                })
            }
        }
    }
}
