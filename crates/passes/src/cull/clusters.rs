//! Cluster culling (techniques `frustum-clusters`, `hiz-2phase-clusters`): a second stage after
//! each phase's instance culling that tests the clusters of every drawn instance — box against
//! the frustum, back-facing normal cone, and in the late phase the pyramid — and writes one
//! indexed indirect command per run of consecutive surviving clusters, in the unculled order.
//!
//! Three dispatches per phase after the instance test (shaders `cluster_cull.comp`,
//! `cluster_place.comp`, `cluster_emit.comp`): flags and runs per chunk of 64 clusters of an
//! instance (a workgroup each, so a level baked into one mesh is culled by as many workgroups
//! as it has chunks, not by one), added to the instance's entry; the entries' runs placed
//! within their draw group (a workgroup per group, as the instance compaction packs survivors)
//! and, by the last workgroup to finish a list's groups, the groups' within their list; then
//! the commands, a workgroup per chunk, after its instance's earlier chunks' runs (and the
//! entries' runs zeroed for the next culling). The instance compaction does not run: a culled
//! instance's entry has no runs. A run ends at its chunk's end: a run split in two draws the
//! same index ranges in the same order. The scene's index buffer is in cluster order
//! (`tilegraph_scene::Scene::attach_clusters`), so a run is one index range and the frame draws
//! the surviving triangles in the unculled order: images stay bit-equal.

use ash::vk;
use tilegraph_profile::MemoryUse;
use tilegraph_scene::{Scene, SceneCursor};
use tilegraph_vk::ash;
use tilegraph_vk::pipeline::write_buffer_set;
use tilegraph_vk::{Buffer, Context, VkError};

pub use super::cluster_layout::{ClusterLayout, ClusterRoom, CHUNK};
use super::compute::{phase_set, ComputeStage};
use super::triangles::{TriangleInputs, TriangleStage, TriangleStep};
use super::{LISTS_PER_PHASE, LIST_COUNT};
use crate::gpu_scene::{upload, Capacity};

const CULL_SPV: &[u8] = include_bytes!("../../../../shaders/spv/cluster_cull.comp.spv");
const PLACE_SPV: &[u8] = include_bytes!("../../../../shaders/spv/cluster_place.comp.spv");
const EMIT_SPV: &[u8] = include_bytes!("../../../../shaders/spv/cluster_emit.comp.spv");

/// The cluster set's storage buffers: bindings 1-18 (common/cluster.glsl; 18 the runs'
/// first triangles, cluster_emit.comp).
const STORAGE_BINDINGS: u32 = 18;

/// Where the work buffer's chunk lists start (cull.glsl's `WORK_CHUNKS`): after each region's
/// dispatch header (8 words) and the placed-group counter of each phase's eight lists.
const WORK_CHUNKS: u32 = 24;

/// The buffers the cluster stage binds that the instance culling owns.
pub(super) struct Shared<'a> {
    /// Per frame slot: the early and late parameter blocks, the order and the draw groups.
    pub slots: Vec<([vk::Buffer; 2], vk::Buffer, vk::Buffer)>,
    pub draw_ids: vk::Buffer,
    pub visibility: vk::Buffer,
    pub entries: vk::Buffer,
    pub pyramid: vk::Buffer,
    pub levels: vk::Buffer,
    pub scene: &'a Scene,
    /// Knob `triangle_culling`: the triangle stage follows each emit.
    pub triangle_culling: bool,
}

/// The cluster stage's buffers, pipelines and descriptor sets.
pub struct ClusterStage {
    /// The scene's layout as the last [`Self::follow`] (or the creation) left it.
    pub layout: ClusterLayout,
    /// Where in the scene's changes the layout is.
    cursor: SceneCursor,
    /// What the buffers hold at most.
    pub room: ClusterRoom,
    pub clusters: Buffer,
    pub mesh_clusters: Buffer,
    /// Per mesh, its clusters (as `mesh_clusters` holds them): a draw group's room with fixed
    /// places ([`Self::group_room`]).
    mesh_cluster_counts: Vec<u32>,
    /// Per frame slot, host-visible: the base words of the layout of that slot's frame
    /// (written when the slot comes round after a new layout: frames in flight keep theirs).
    pub base: Vec<Buffer>,
    /// Per frame slot: the layout its base words hold — epoch, slots and chunks
    /// ([`ClusterRoom::base_writes`]); `None`: nothing yet.
    base_written: Vec<Option<(u64, u32, u32)>>,
    /// Per region (early-or-union, late) and cluster instance: drawn or not.
    pub flags: Buffer,
    /// Per cluster instance: visible last frame (two-phase).
    pub visibility: Buffer,
    pub runs: Buffer,
    pub offsets: Buffer,
    pub commands: Buffer,
    /// Per list: the draw count (0-7), then the instances its commands draw (8-15).
    pub counts: Buffer,
    /// Per region: the indirect dispatch of its chunks and their count, then the chunk lists
    /// (cluster.glsl's Work; `cull_clusters.comp` appends; two-phase culling's instance tests
    /// empty the other phase's, single-phase culling's a reset pass).
    pub work: Buffer,
    /// The draw id of cluster command 0 (`CullParams::clusters` x: after the instance lists'
    /// room, however many entries a frame's lists hold), then per command the mesh's triangle
    /// its run starts at (visbuf.vert's DrawRuns, bound in the culled set 0).
    pub run_triangles: Buffer,
    /// The draw id of cluster command 0.
    pub draw_id_base: u32,
    /// `cluster_cull.comp`, `cluster_place.comp`, `cluster_emit.comp`, their layouts and set
    /// pool.
    compute: ComputeStage<3>,
    /// Two per slot: the early (or only) and the late phase.
    sets: Vec<vk::DescriptorSet>,
    /// Per-triangle culling after each emit (knob `triangle_culling`).
    pub triangles: Option<TriangleStage>,
}

/// A buffer of the stage: uploaded from the scene, or made empty.
enum Spec<'a> {
    Upload(&'static str, &'a [u8]),
    Empty(&'static str, u64, vk::BufferUsageFlags),
}

/// The stage's buffers: clusters, mesh ranges, flags, visibility, runs, offsets, commands,
/// counts, work (all destroyed again on an error).
fn make_buffers(
    ctx: &Context,
    room: &ClusterRoom,
    clusters: &tilegraph_scene::clusters::Clusters,
    capacity: Capacity,
) -> Result<[Buffer; 10], VkError> {
    let storage = vk::BufferUsageFlags::STORAGE_BUFFER;
    let total = u64::from(room.total.max(1));
    let stride = u64::from(capacity.stride.max(1));
    let entries = stride * u64::from(LIST_COUNT);
    // Runs per entry of the lists, then per region and chunk (cluster.glsl's chunk_slot).
    let runs = entries + 2 * u64::from(room.chunks);
    // Places per entry of the lists, each entry's group (lists of a phase), then per kind (3),
    // region and draw group (cluster.glsl's group_of_entry and group_slot; kind 2, the groups'
    // draw counts with fixed places, is read as indirect counts).
    let offsets =
        entries + stride * u64::from(LISTS_PER_PHASE) + 6 * u64::from(capacity.groups.max(1));
    let src = vk::BufferUsageFlags::TRANSFER_SRC;
    let dst = vk::BufferUsageFlags::TRANSFER_DST;
    let indirect = vk::BufferUsageFlags::INDIRECT_BUFFER;
    let commands = u64::from(room.commands().max(1));
    let specs = [
        Spec::Upload("clusters", bytemuck::cast_slice(&clusters.clusters)),
        Spec::Upload(
            "mesh clusters",
            bytemuck::cast_slice(&clusters.mesh_clusters),
        ),
        Spec::Empty("cluster flags", 2 * total * 4, storage),
        Spec::Empty("cluster visibility", total * 4, storage | dst),
        Spec::Empty("cluster runs", runs * 4, storage | dst),
        Spec::Empty("cluster offsets", offsets * 4, storage | indirect | src),
        Spec::Empty(
            "cluster commands",
            commands * 20,
            storage | indirect | src | dst,
        ),
        Spec::Empty(
            "cluster counts",
            2 * u64::from(LIST_COUNT) * 4,
            storage | indirect | src,
        ),
        Spec::Empty(
            "cluster work",
            (u64::from(WORK_CHUNKS) + 2 * u64::from(room.chunks)) * 4,
            storage | indirect | dst,
        ),
        Spec::Empty("cluster run triangles", (1 + commands) * 4, storage | dst),
    ];
    // Every buffer is bound whole: none may pass the device's storage buffer range.
    let limit = u64::from(ctx.physical.limits.max_storage_buffer_range);
    for spec in &specs {
        let (name, size) = match spec {
            Spec::Upload(name, bytes) => (*name, bytes.len() as u64),
            Spec::Empty(name, size, _) => (*name, *size),
        };
        if size > limit {
            return Err(VkError::Invalid {
                what: format!("cluster culling's {name}"),
                reason: format!(
                    "{size} bytes for {} cluster instances; this device binds at most {limit} (maxStorageBufferRange)",
                    room.total
                ),
            });
        }
    }
    let mut made = Vec::with_capacity(specs.len());
    for spec in specs {
        let buffer = match spec {
            Spec::Upload(name, bytes) => upload(ctx, name, bytes, storage),
            Spec::Empty(name, size, usage) => {
                ctx.create_buffer(name, size, usage, MemoryUse::GpuOnly)
            }
        };
        match buffer {
            Ok(b) => made.push(b),
            Err(e) => {
                for b in made {
                    ctx.destroy_buffer(b);
                }
                return Err(e);
            }
        }
    }
    <[Buffer; 10]>::try_from(made).map_err(|made| {
        for b in made {
            ctx.destroy_buffer(b);
        }
        VkError::Invalid {
            what: "cluster culling".into(),
            reason: "buffers missing".into(),
        }
    })
}

/// One of the cluster dispatches.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ClusterStep {
    /// `cluster_cull.comp`: a workgroup per chunk flags its clusters and counts their runs.
    Cull,
    /// `cluster_place.comp`: a workgroup per draw group and region places its entries' runs;
    /// the last of a list's places its groups and writes its counts.
    Place,
    /// `cluster_emit.comp`: a workgroup per chunk writes its runs' commands.
    Emit,
    /// Per-triangle culling of the commands just written (knob `triangle_culling`).
    Triangles(TriangleStep),
}

/// Where kind `kind` of draw group `group` of region `region` sits in the places buffer
/// (common/cluster.glsl's `group_slot`), in words, for lists of `stride` entries and `groups`
/// draw groups a phase (both at least 1, as the shaders read them).
pub(super) fn group_slot(stride: u32, groups: u32, kind: u32, region: u32, group: u32) -> u64 {
    let (stride, groups) = (u64::from(stride.max(1)), u64::from(groups.max(1)));
    12 * stride + u64::from(2 * kind + region) * groups + u64::from(group)
}

impl ClusterStage {
    /// The most commands a draw group of `len` entries of `mesh` can need (cluster.glsl's
    /// `group_room`): a run holds one cluster at least.
    pub fn group_room(&self, len: u32, mesh: u32) -> u32 {
        let clusters = self.mesh_cluster_counts.get(mesh as usize).copied();
        len.saturating_mul(clusters.unwrap_or(0))
    }

    /// The stage for `shared.scene`'s clusters (`None` without them) and lists of `capacity`.
    pub(super) fn new(
        ctx: &Context,
        shared: &Shared<'_>,
        capacity: Capacity,
        scene_set_layout: vk::DescriptorSetLayout,
    ) -> Result<Option<Self>, VkError> {
        let (Some(layout), Some(clusters)) =
            (ClusterLayout::of(shared.scene), shared.scene.clusters())
        else {
            return Ok(None);
        };
        let room = ClusterRoom::for_layout(&layout, capacity.instances);
        let mesh_cluster_counts = clusters.mesh_clusters.iter().map(|r| r[1]).collect();
        let [clusters, mesh_clusters, flags, visibility, runs, offsets, commands, counts, work, run_triangles] =
            make_buffers(ctx, &room, clusters, capacity)?;
        let mut stage = ClusterStage {
            layout,
            cursor: shared.scene.cursor(),
            room,
            clusters,
            mesh_clusters,
            mesh_cluster_counts,
            base: Vec::new(),
            base_written: Vec::new(),
            flags,
            visibility,
            runs,
            offsets,
            commands,
            counts,
            work,
            run_triangles,
            draw_id_base: capacity.stride.max(1).saturating_mul(LIST_COUNT),
            compute: ComputeStage::EMPTY,
            sets: Vec::new(),
            triangles: None,
        };
        match stage.init(ctx, shared, scene_set_layout) {
            Ok(()) => Ok(Some(stage)),
            Err(e) => {
                stage.destroy(ctx);
                Err(e)
            }
        }
    }

    fn init(
        &mut self,
        ctx: &Context,
        shared: &Shared<'_>,
        scene_set_layout: vk::DescriptorSetLayout,
    ) -> Result<(), VkError> {
        // Nothing was found occluded before the first frame: every cluster of an instance
        // visible last frame is a candidate for the early phase. The entries' runs start at
        // zero (each emit zeroes them once placed, for the next culling to add to).
        // Both phases' work starts empty: two-phase culling then empties each phase's in the
        // other's instance test (cull_body.glsl's reset_other_work), single-phase culling in a
        // transfer at the frame's start.
        let (visibility, runs, work) = (self.visibility.raw, self.runs.raw, self.work.raw);
        let (run_triangles, draw_id_base) = (self.run_triangles.raw, self.draw_id_base);
        let header = work_header();
        ctx.submit_and_wait(|cb| {
            // SAFETY: outside a render pass; the buffers are new and transfer destinations, the
            // work buffer holds at least the header (make_buffers).
            unsafe {
                ctx.device
                    .cmd_fill_buffer(cb, visibility, 0, vk::WHOLE_SIZE, 1);
                ctx.device.cmd_fill_buffer(cb, runs, 0, vk::WHOLE_SIZE, 0);
                ctx.device
                    .cmd_update_buffer(cb, work, 0, bytemuck::cast_slice(&header));
                ctx.device
                    .cmd_update_buffer(cb, run_triangles, 0, &draw_id_base.to_le_bytes());
            };
            Ok(())
        })?;
        for slot in 0..shared.slots.len() {
            let b = ctx.create_buffer(
                &format!("cluster base[{slot}]"),
                self.room.base_bytes(),
                vk::BufferUsageFlags::STORAGE_BUFFER,
                MemoryUse::Streaming,
            )?;
            self.base.push(b);
            self.base_written.push(None);
        }
        let shaders = [
            ("cluster_cull.comp", CULL_SPV),
            ("cluster_place.comp", PLACE_SPV),
            ("cluster_emit.comp", EMIT_SPV),
        ];
        let sets = 2 * shared.slots.len() as u32;
        self.compute
            .init(ctx, scene_set_layout, STORAGE_BINDINGS, shaders, sets)?;
        let ssbo = vk::DescriptorType::STORAGE_BUFFER;
        for (slot, (params, order, groups)) in shared.slots.iter().enumerate() {
            let base = self.base_raw(slot)?;
            for p in params {
                let set = self.compute.allocate_set(ctx)?;
                write_buffer_set(
                    ctx,
                    set,
                    &[
                        (0, vk::DescriptorType::UNIFORM_BUFFER, *p),
                        (1, ssbo, self.commands.raw),
                        (2, ssbo, self.counts.raw),
                        (3, ssbo, shared.draw_ids),
                        (4, ssbo, shared.visibility),
                        (5, ssbo, shared.pyramid),
                        (6, ssbo, shared.levels),
                        (7, ssbo, *order),
                        (8, ssbo, shared.entries),
                        (9, ssbo, self.clusters.raw),
                        (10, ssbo, self.mesh_clusters.raw),
                        (11, ssbo, base),
                        (12, ssbo, self.flags.raw),
                        (13, ssbo, self.visibility.raw),
                        (14, ssbo, self.runs.raw),
                        (15, ssbo, self.offsets.raw),
                        (16, ssbo, *groups),
                        (17, ssbo, self.work.raw),
                        (18, ssbo, self.run_triangles.raw),
                    ],
                );
                self.sets.push(set);
            }
        }
        if shared.triangle_culling {
            let inputs = TriangleInputs {
                params: shared.slots.iter().map(|s| s.0).collect(),
                commands: self.commands.raw,
                counts: self.counts.raw,
                draw_ids: shared.draw_ids,
                pyramid: shared.pyramid,
                levels: shared.levels,
                offsets: self.offsets.raw,
                command_slots: self.room.commands(),
            };
            self.triangles = Some(TriangleStage::new(ctx, &inputs, scene_set_layout)?);
        }
        Ok(())
    }

    /// Records dispatch `step` of phase `which` (0 early or only, 1 late) over the frame's
    /// `groups` draw groups; the graph put the barriers around it.
    pub(super) fn record_dispatch(
        &self,
        ctx: &Context,
        cb: vk::CommandBuffer,
        scene_set: vk::DescriptorSet,
        slot: usize,
        (which, groups): (usize, u32),
        step: ClusterStep,
    ) -> Result<(), VkError> {
        let set = phase_set(&self.sets, slot, which, "cluster culling")?;
        let sets = [scene_set, set];
        let regions = which as u32 + 1; // the late phase places the union's runs again
                                        // The chunk steps run over the phase's chunk list, a workgroup per chunk (at most
                                        // 65,535, the least maxComputeWorkGroupCount: a workgroup then takes several).
        let listed = |pipeline| {
            let offset = 16 * which as u64;
            self.compute
                .dispatch_indirect(ctx, cb, pipeline, sets, (self.work.raw, offset));
        };
        match step {
            ClusterStep::Cull => listed(self.compute.pipelines[0]),
            ClusterStep::Place => self.compute.dispatch(
                ctx,
                cb,
                self.compute.pipelines[1],
                sets,
                (regions * groups.max(1), 1),
            ),
            ClusterStep::Emit => listed(self.compute.pipelines[2]),
            ClusterStep::Triangles(step) => {
                let t = self.triangles.as_ref().ok_or_else(|| VkError::Invalid {
                    what: "triangle culling".into(),
                    reason: "the cluster stage has no triangle stage".into(),
                })?;
                t.record_dispatch(ctx, cb, scene_set, slot, which, step)?;
            }
        }
        Ok(())
    }

    /// Frame slot `slot`'s base words buffer.
    pub(super) fn base_raw(&self, slot: usize) -> Result<vk::Buffer, VkError> {
        self.base
            .get(slot)
            .map(|b| b.raw)
            .ok_or_else(|| VkError::Invalid {
                what: "cluster culling".into(),
                reason: format!("no base words for frame slot {slot}"),
            })
    }

    /// Follows the scene's changes since the last call (instances that came or went: new
    /// slots appended, freed ones reused in place, else every slot laid out anew;
    /// [`ClusterLayout::follow`]) where the buffers hold the result: each frame slot's base
    /// words follow when the slot comes round ([`Self::write_base`]); the flags, runs and
    /// work lists are the frame's own, and the cluster visibility only guides
    /// `cluster_early = clusters`' early phase (the late phase tests every cluster of every
    /// visible instance), so nothing else needs to change. False where the result does not fit
    /// (or the scene lost its clusters): new buffers are needed.
    pub(super) fn follow(&mut self, scene: &Scene) -> bool {
        let followed = self.layout.follow(scene, scene.changes_since(self.cursor));
        self.cursor = scene.cursor();
        followed && self.room.holds(&self.layout)
    }

    /// Brings frame slot `slot`'s base words to the layout: what was appended since they were
    /// written, or all of them after a new layout (the slot's last frame is complete: its
    /// parameters are being written too).
    pub(super) fn write_base(&mut self, ctx: &Context, slot: usize) -> Result<(), VkError> {
        let now = (self.layout.epoch, self.layout.slots(), self.layout.chunks());
        let written = self.base_written.get(slot).copied().flatten();
        if written == Some(now) {
            return Ok(());
        }
        let buffer = self.base.get_mut(slot).ok_or_else(|| VkError::Invalid {
            what: "cluster culling".into(),
            reason: format!("no base words for frame slot {slot}"),
        })?;
        for (at, words) in self.room.base_writes(&self.layout, written) {
            if !words.is_empty() {
                ctx.write_mapped(buffer, 4 * at as usize, bytemuck::cast_slice(words))?;
            }
        }
        if let Some(w) = self.base_written.get_mut(slot) {
            *w = Some(now);
        }
        Ok(())
    }

    /// Records the reset of both regions' chunk lists (the graph made the work buffer a
    /// transfer destination): no chunk, one workgroup row; and of the lists' placed-group
    /// counters (cull.glsl's `WORK_CHUNKS`). Single-phase culling's, every frame.
    pub(super) fn record_work_reset(&self, ctx: &Context, cb: vk::CommandBuffer) {
        let header = work_header();
        // SAFETY: recording outside a render pass; the buffer is live, a transfer destination,
        // and holds at least the header (make_buffers).
        unsafe {
            ctx.device
                .cmd_update_buffer(cb, self.work.raw, 0, bytemuck::cast_slice(&header))
        };
    }

    pub(super) fn destroy(self, ctx: &Context) {
        self.compute.destroy(ctx);
        if let Some(t) = self.triangles {
            t.destroy(ctx);
        }
        for b in [
            self.clusters,
            self.mesh_clusters,
            self.flags,
            self.visibility,
            self.runs,
            self.offsets,
            self.commands,
            self.counts,
            self.work,
            self.run_triangles,
        ]
        .into_iter()
        .chain(self.base)
        {
            ctx.destroy_buffer(b);
        }
    }
}

/// The work buffer's empty header: per region no chunk and one workgroup row, every list's
/// placed-group counter zero (cull.glsl's `WORK_CHUNKS`).
fn work_header() -> [u32; WORK_CHUNKS as usize] {
    let mut header = [0u32; WORK_CHUNKS as usize];
    header[..8].copy_from_slice(&[0, 1, 1, 0, 0, 1, 1, 0]);
    header
}

/// The cone test's snapping scale (`CullParams::clusters.w`): sub-pixel steps per unit of
/// lateral offset at distance 1 — the smaller focal length in pixels of `extent` (the one that
/// turns a pixel into more of the world) times
/// 2^`sub_pixel_bits` (`tilegraph_scene::cone::back_facing`). 0 (no cone test) for a projection
/// without a focal length.
pub(crate) fn cone_steps(projection: glam::Mat4, extent: (u32, u32), sub_pixel_bits: u32) -> f32 {
    let fx = projection.x_axis.x.abs() * extent.0 as f32 * 0.5;
    let fy = projection.y_axis.y.abs() * extent.1 as f32 * 0.5;
    let steps = fx.min(fy) * (1u64 << sub_pixel_bits.min(16)) as f32;
    if steps.is_finite() {
        steps
    } else {
        0.0
    }
}

#[cfg(test)]
mod cone_tests {
    use super::cone_steps;

    #[test]
    fn cone_steps_are_the_focal_length_in_sub_pixel_steps() {
        // 90° vertical field of view: P11 = 1, 1080 rows: 540 px per unit at distance 1.
        let p = glam::Mat4::perspective_rh(std::f32::consts::FRAC_PI_2, 16.0 / 9.0, 0.1, 100.0);
        let s = cone_steps(p, (1920, 1080), 8);
        assert!((s - 540.0 * 256.0).abs() < 1.0, "{s}");
        // Four bits (Vulkan's minimum): sixteen times coarser.
        assert!((cone_steps(p, (1920, 1080), 4) - 540.0 * 16.0).abs() < 0.1);
    }
}
