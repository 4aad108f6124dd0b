//! The persistent culling state: buffers, pipelines, per-slot inputs, recording and readback.

use ash::vk;
use glam::Mat4;
use tilegraph_profile::MemoryUse;
use tilegraph_scene::{CameraFrame, DepthConvention};
use tilegraph_vk::ash;
use tilegraph_vk::executor::BufferHandle;
use tilegraph_vk::pipeline::write_buffer_set;
use tilegraph_vk::{Buffer, Context, Feature, VkError};

use super::clusters::{cone_steps, ClusterStage, Shared};
use super::compute::{phase_set, ComputeStage};
use super::{
    gpu_planes, sphere_projection, ClusterEarly, CullBounds, CullParams, Culling, GpuLayout,
    LodSettings, Phase, Recheck, Step, LISTS_PER_PHASE, LIST_COUNT,
};
use crate::frame::PassState;
use crate::gpu_scene::Capacity;
use crate::hiz::{HizState, PyramidInfo};

mod draws;
pub use draws::DrawCount;
mod slot;
use slot::SlotInputs;
mod runs;
mod sizes;
mod stats;

/// What a frame's GPU culling drew, read back without waiting once its slot completed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GpuCullCounts {
    /// The frame (the renderer's frame count when it was recorded).
    pub frame: u64,
    /// Indirect commands the colour pass's lists hold (their draw counts).
    pub commands: u32,
    /// Instances they draw.
    pub instances: u32,
    /// Opaque and alpha-tested instances culled (the GPU lists' instances not drawn).
    pub culled: u32,
}

/// The pyramid the culling shaders test against: its buffer and its level table (a
/// [`HizState`]'s, or for `reproject` the reprojected pyramid with the same table).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Occluder {
    pub pyramid: vk::Buffer,
    pub levels: vk::Buffer,
}

impl Occluder {
    pub fn of(hiz: &HizState) -> Self {
        Occluder {
            pyramid: hiz.pyramid.raw,
            levels: hiz.levels.raw,
        }
    }
}

/// A frame's lists as the culling reads them: the scene's buckets in the frame's draw order,
/// the lists' stride, the scene's instance slots.
#[derive(Debug, Clone, Copy)]
pub struct FrameLists<'a> {
    pub groups: &'a [tilegraph_scene::DrawGroup],
    pub stride: u32,
    pub instance_slots: u32,
}

/// What a [`CullState`] is made with besides the scene.
pub struct CullInputs<'a> {
    /// Set 0's layout (the scene's, [`crate::GpuScene`]).
    pub scene_set_layout: vk::DescriptorSetLayout,
    /// Per frame slot, the instances' entries ([`crate::GpuScene::order`]).
    pub orders: &'a [vk::Buffer],
    /// The pyramid the HiZ techniques test against (bound for the shader).
    pub occluder: Option<Occluder>,
    /// What `cull.comp` tests (knob `cull_bounds`).
    pub bounds: CullBounds,
    /// What the cluster stage's early phase draws (knob `cluster_early`).
    pub cluster_early: ClusterEarly,
    /// The longest gap of culled clusters a cluster command draws through (knob `cluster_gap`).
    pub cluster_gap: u32,
    /// Room for instance slots and list entries.
    pub capacity: Capacity,
    /// Per-triangle culling after the cluster stage (knob `triangle_culling`).
    pub triangle_culling: bool,
    /// Level of detail (knobs `lod_error_px`, `lod_hysteresis`).
    pub lod: LodSettings,
}

/// The persistent culling state of one renderer.
pub struct CullState {
    pub culling: Culling,
    /// What `cull.comp` tests: the box or the sphere (knob `cull_bounds`).
    pub bounds: CullBounds,
    /// What the cluster stage's early phase draws (knob `cluster_early`).
    pub cluster_early: ClusterEarly,
    /// The longest gap of culled clusters a cluster command draws through (knob `cluster_gap`).
    pub cluster_gap: u32,
    /// Room of the buffers (instance slots, list stride).
    pub capacity: Capacity,
    /// Instance slots of the frame written last (the mark dispatch's size).
    instances: u32,
    pub draw_count: DrawCount,
    pub commands: Buffer,
    pub counts: Buffer,
    pub draw_ids: Buffer,
    pub visibility: Buffer,
    pub entries: Buffer,
    pub survivors: Buffer,
    /// Bound for the pyramid and its levels when there is none (the shader reads neither then;
    /// a buffer nothing writes keeps synchronization validation quiet about the binding).
    no_pyramid: Buffer,
    slots: Vec<SlotInputs>,
    /// Frames written so far (numbers the frames [`CullState::collect`] reports).
    frames_written: u64,
    /// Raster occlusion: the box re-test interval (knob `occlusion_recheck`).
    recheck_interval: u32,
    /// Raster occlusion: the turns of the frame [`Self::write_frame`] wrote last.
    recheck: Recheck,
    /// The layout being written (kept: no allocation per frame).
    pub(super) layout: GpuLayout,
    /// `cull.comp`, `cull_compact.comp`, `cull_commands.comp`, their layouts and set pool.
    compute: ComputeStage<3>,
    /// Two per slot: the early (or only) and the late phase.
    sets: Vec<vk::DescriptorSet>,
    /// The cluster stage of the cluster techniques.
    pub clusters: Option<ClusterStage>,
    /// Keep a command per draw group this frame (engine materials draw runs of groups with
    /// their own pipelines: [`CullState::record_group_run`]).
    pub group_runs: bool,
    /// Per-triangle culling: the index buffer's tail this frame (first index, length).
    pub index_tail: (u32, u32),
    /// Level of detail: the largest projected error in pixels (0 off) and the switching band.
    pub lod: LodSettings,
    /// Level of detail: the scene's level table (`Lods` of cull_body.glsl) and the meshes it
    /// covers; none when off.
    lod_table: Option<(Buffer, u32)>,
    /// The scene's clusters when the tables were uploaded: they grow only by a mesh's copy of
    /// reversed winding (`Scene::prepare_mirroring`), which the tables then lack.
    clusters_uploaded: usize,
    /// Commands per draw group: 1, or with levels of detail one per level (the mesh's own and
    /// [`tilegraph_scene::MAX_LODS`] coarser).
    pub lod_levels: u32,
}

const CULL_SPV: &[u8] = include_bytes!("../../../../../shaders/spv/cull.comp.spv");
const CULL_CLUSTERS_SPV: &[u8] =
    include_bytes!("../../../../../shaders/spv/cull_clusters.comp.spv");
const COMPACT_SPV: &[u8] = include_bytes!("../../../../../shaders/spv/cull_compact.comp.spv");
const COMMANDS_SPV: &[u8] = include_bytes!("../../../../../shaders/spv/cull_commands.comp.spv");
// With levels of detail: a command per group and level.
const COMPACT_LOD_SPV: &[u8] =
    include_bytes!("../../../../../shaders/spv/cull_compact_lod.comp.spv");
const COMMANDS_LOD_SPV: &[u8] =
    include_bytes!("../../../../../shaders/spv/cull_commands_lod.comp.spv");

/// The culling descriptor set's storage buffers (bindings 1-10; 11 and 12 the cluster techniques' base
/// and chunk lists, `cull_clusters.comp`; 13 the level-of-detail table).
const STORAGE_BINDINGS: u32 = 13;

impl PassState for CullState {
    fn destroy(self: Box<Self>, ctx: &Context) {
        self.destroy_all(ctx);
    }
}

/// Destroys what was made before an error.
fn destroy_buffers(ctx: &Context, made: Vec<Buffer>) {
    for b in made {
        ctx.destroy_buffer(b);
    }
}

impl CullState {
    /// Device features GPU culling uses where the device has them: the GPU draw count and
    /// several indirect commands per call ([`DrawCount`]). Without them it still runs.
    pub fn wanted_features() -> [Feature; 2] {
        [Feature::DrawIndirectCount, Feature::MultiDrawIndirect]
    }

    /// The buffers, pipelines and descriptor sets of `culling` for `scene`'s instances;
    /// `occluder`: the pyramid the HiZ techniques test against (bound for the shader). A cluster
    /// technique needs the scene's clusters attached.
    pub fn new(
        ctx: &Context,
        culling: Culling,
        scene: &tilegraph_scene::Scene,
        inputs: CullInputs<'_>,
    ) -> Result<Self, VkError> {
        let CullInputs {
            scene_set_layout,
            orders,
            occluder,
            bounds,
            cluster_early,
            cluster_gap,
            capacity,
            triangle_culling,
            lod,
        } = inputs;
        let lods = scene
            .clusters()
            .filter(|c| lod.error_px > 0.0 && c.has_lods())
            .map(|c| (c.lods.as_slice(), c.mesh_clusters.len() as u32));
        let lod_levels = if lods.is_some() {
            1 + tilegraph_scene::MAX_LODS as u32
        } else {
            1
        };
        // The cluster commands' draw ids follow the instance lists'.
        let cluster_commands = if culling.clusters() {
            let layout =
                super::clusters::ClusterLayout::of(scene).ok_or_else(|| VkError::Invalid {
                    what: format!("culling {}", culling.name()),
                    reason: match scene.clusters() {
                        None => format!(
                            "scene {} has no clusters (attach them: tilegraph_scene::clusters)",
                            scene.name()
                        ),
                        Some(_) => format!(
                            "scene {}'s instances hold 2^32 clusters or more",
                            scene.name()
                        ),
                    },
                })?;
            u64::from(
                super::clusters::ClusterRoom::for_layout(&layout, capacity.instances).commands(),
            )
        } else {
            0
        };
        let specs = Self::buffer_specs(capacity, cluster_commands, lod_levels);
        let mut made: Vec<Buffer> = Vec::with_capacity(specs.len());
        for (name, size, usage) in specs {
            match ctx.create_buffer(name, size, usage, MemoryUse::GpuOnly) {
                Ok(b) => made.push(b),
                Err(e) => {
                    destroy_buffers(ctx, made);
                    return Err(e);
                }
            }
        }
        let [commands, counts, draw_ids, visibility, entries, survivors, no_pyramid]: [Buffer; 7] =
            match made.try_into() {
                Ok(b) => b,
                Err(made) => {
                    destroy_buffers(ctx, made);
                    return Err(VkError::Invalid {
                        what: "cull".into(),
                        reason: "buffers missing".into(),
                    });
                }
            };
        let draw_count = DrawCount::for_device(ctx);
        log::info!("GPU culling draws with {draw_count:?}");
        // Vulkan objects start null and are filled in; on error `destroy` frees what exists
        // (destroying VK_NULL_HANDLE is a no-op).
        let mut state = CullState {
            culling,
            bounds,
            cluster_early,
            cluster_gap,
            capacity,
            instances: 0,
            draw_count,
            commands,
            counts,
            draw_ids,
            visibility,
            entries,
            survivors,
            no_pyramid,
            slots: Vec::new(),
            frames_written: 0,
            recheck_interval: 1,
            recheck: Recheck::new(1, 0),
            layout: GpuLayout::default(),
            compute: ComputeStage::EMPTY,
            sets: Vec::new(),
            clusters: None,
            group_runs: false,
            index_tail: (0, 0),
            lod,
            lod_table: None,
            clusters_uploaded: scene.clusters().map_or(0, |c| c.clusters.len()),
            lod_levels,
        };
        // A new renderer's visibility starts empty, not as whatever the memory held (another
        // renderer's last frame, say): two-phase culling's first early phase draws nothing and
        // its late phase everything the frustum keeps, on every run alike. Once, at creation,
        // so that no frame's declaration differs.
        let zeroed = lods
            .map_or(Ok(()), |(table, meshes)| {
                let storage = vk::BufferUsageFlags::STORAGE_BUFFER;
                let b = crate::gpu_scene::upload(
                    ctx,
                    "lod table",
                    bytemuck::cast_slice(table),
                    storage,
                )?;
                state.lod_table = Some((b, meshes));
                Ok(())
            })
            .and_then(|()| state.init(ctx, scene_set_layout, orders, occluder))
            .and_then(|()| {
                if !culling.clusters() {
                    return Ok(());
                }
                let shared = Shared {
                    slots: state
                        .slots
                        .iter()
                        .zip(orders)
                        .map(|(s, &order)| {
                            ([s.params[0].raw, s.params[1].raw], order, s.groups.raw)
                        })
                        .collect(),
                    draw_ids: state.draw_ids.raw,
                    visibility: state.visibility.raw,
                    entries: state.entries.raw,
                    pyramid: occluder.map_or(state.no_pyramid.raw, |o| o.pyramid),
                    levels: occluder.map_or(state.no_pyramid.raw, |o| o.levels),
                    scene,
                    triangle_culling,
                };
                state.clusters = ClusterStage::new(ctx, &shared, capacity, scene_set_layout)?;
                // cull_clusters.comp lists each phase's chunks: the cluster base and the work
                // lists at bindings 11 and 12.
                if let Some(c) = &state.clusters {
                    for (i, &set) in state.sets.iter().enumerate() {
                        let ssbo = vk::DescriptorType::STORAGE_BUFFER;
                        write_buffer_set(
                            ctx,
                            set,
                            &[(11, ssbo, c.base_raw(i / 2)?), (12, ssbo, c.work.raw)],
                        );
                    }
                }
                Ok(())
            })
            .and_then(|()| {
                let visibility = state.visibility.raw;
                ctx.submit_and_wait(|cb| {
                    // SAFETY: outside a render pass; the buffer is new, unused by the GPU, and a
                    // transfer destination.
                    unsafe {
                        ctx.device
                            .cmd_fill_buffer(cb, visibility, 0, vk::WHOLE_SIZE, 0)
                    };
                    Ok(())
                })
            });
        match zeroed {
            Ok(()) => Ok(state),
            Err(e) => {
                state.destroy_all(ctx);
                Err(e)
            }
        }
    }

    fn init(
        &mut self,
        ctx: &Context,
        scene_set_layout: vk::DescriptorSetLayout,
        orders: &[vk::Buffer],
        occluder: Option<Occluder>,
    ) -> Result<(), VkError> {
        let n = u64::from(self.capacity.instances.max(1));
        let slots = orders.len().max(1) as u32;
        let shaders = [
            if self.culling.clusters() {
                ("cull_clusters.comp", CULL_CLUSTERS_SPV)
            } else {
                ("cull.comp", CULL_SPV)
            },
            if self.lod_levels > 1 {
                ("cull_compact_lod.comp", COMPACT_LOD_SPV)
            } else {
                ("cull_compact.comp", COMPACT_SPV)
            },
            if self.lod_levels > 1 {
                ("cull_commands_lod.comp", COMMANDS_LOD_SPV)
            } else {
                ("cull_commands.comp", COMMANDS_SPV)
            },
        ];
        self.compute
            .init(ctx, scene_set_layout, STORAGE_BINDINGS, shaders, 2 * slots)?;
        for slot in 0..slots {
            let inputs = SlotInputs::new(ctx, slot, n)?;
            self.slots.push(inputs);
        }
        // Without a pyramid the shader never reads bindings 5 and 6.
        let pyramid = occluder.map_or(self.no_pyramid.raw, |o| o.pyramid);
        let levels = occluder.map_or(self.no_pyramid.raw, |o| o.levels);
        for i in 0..2 * slots as usize {
            let order = orders.get(i / 2).copied().unwrap_or(vk::Buffer::null());
            let set = self.write_set(ctx, i, pyramid, levels, order)?;
            self.sets.push(set);
        }
        Ok(())
    }

    fn slot(&self, slot: usize) -> Result<&SlotInputs, VkError> {
        self.slots.get(slot).ok_or_else(|| VkError::Invalid {
            what: "cull".into(),
            reason: format!("no inputs for frame slot {slot}"),
        })
    }

    fn write_set(
        &self,
        ctx: &Context,
        index: usize,
        pyramid: vk::Buffer,
        levels: vk::Buffer,
        order: vk::Buffer,
    ) -> Result<vk::DescriptorSet, VkError> {
        let inputs = self.slot(index / 2)?;
        // The pool holds a set per parameter block.
        let set = self.compute.allocate_set(ctx)?;
        let ssbo = vk::DescriptorType::STORAGE_BUFFER;
        write_buffer_set(
            ctx,
            set,
            &[
                (
                    0,
                    vk::DescriptorType::UNIFORM_BUFFER,
                    inputs.params[index % 2].raw,
                ),
                (1, ssbo, self.commands.raw),
                (2, ssbo, self.counts.raw),
                (3, ssbo, self.draw_ids.raw),
                (4, ssbo, self.visibility.raw),
                (5, ssbo, pyramid),
                (6, ssbo, levels),
                (7, ssbo, order),
                (8, ssbo, self.entries.raw),
                (9, ssbo, inputs.groups.raw),
                (10, ssbo, self.survivors.raw),
                (
                    13,
                    ssbo,
                    self.lod_table
                        .as_ref()
                        .map_or(self.no_pyramid.raw, |t| t.0.raw),
                ),
            ],
        );
        Ok(set)
    }

    /// Follows the scene's changes in the cluster layout, where the cluster stage's buffers
    /// hold the result (`ClusterStage::follow`: the changes' cost); false where new buffers
    /// are needed (also for clusters the stage's and the level tables lack). True without
    /// a cluster stage or level table.
    pub fn follow_clusters(&mut self, scene: &tilegraph_scene::Scene) -> bool {
        let tables = self.clusters.is_none() && self.lod_table.is_none()
            || scene.clusters().map_or(0, |c| c.clusters.len()) == self.clusters_uploaded;
        tables && self.clusters.as_mut().is_none_or(|c| c.follow(scene))
    }

    /// Raster occlusion: test a box drawn last frame again once every `interval` frames.
    pub fn set_recheck_interval(&mut self, interval: u32) {
        self.recheck_interval = interval.max(1);
    }

    /// Raster occlusion: the turns of the frame [`Self::write_frame`] wrote last (the boxes'
    /// vertex shader must skip the same instances).
    pub fn recheck(&self) -> Recheck {
        self.recheck
    }

    /// Writes slot `slot`'s culling inputs for `frame`: each instance's entry in the lists in
    /// the CPU list's draw order and the draw groups (so the culled frame draws its survivors
    /// in the unculled order), and both phases' parameters. After a camera cut, single-phase
    /// HiZ tests nothing against the previous pyramid (another view's depth would cull at
    /// random): that frame is frustum-culled only.
    pub fn write_frame(
        &mut self,
        ctx: &Context,
        slot: usize,
        frame: &CameraFrame,
        lists: FrameLists<'_>,
        extent: (u32, u32),
        pyramid: Option<PyramidInfo>,
    ) -> Result<(), VkError> {
        let m = &frame.current;
        self.layout.fill(lists.groups, lists.stride);
        self.instances = lists.instance_slots;
        let stride = self.layout.stride.max(1);
        let planes = gpu_planes(m.view_projection, m.depth)?;
        let levels = pyramid.map_or(0, |p| p.levels);
        let (pw, ph) = pyramid.map_or(extent, |p| p.extent_px);
        let reverse = u32::from(m.depth == DepthConvention::Reverse);
        let n = self.instances;
        let layout = &self.layout;
        let total = layout.groups.len() as u32;
        // A command per group, culled ones empty: the fixed draw count, and frames whose lists
        // engine materials draw in runs of groups (runs.rs).
        let keep_empty =
            u32::from(matches!(self.draw_count, DrawCount::Fixed { .. }) || self.group_runs);
        let spheres = u32::from(self.bounds == CullBounds::Sphere);
        let d16 =
            u32::from(pyramid.is_some_and(|p| p.format == tilegraph_cull::DepthFormat::D16Unorm));
        // Cluster culling: where its commands and draw ids go, entries per list, and the cone
        // test (perspective views only: an orthographic view's direction is not modelled).
        if let Some(c) = &mut self.clusters {
            c.write_base(ctx, slot)?;
        }
        let [c1, c2, c3] = self.clusters.as_ref().map_or([0; 3], |c| {
            let [first_chunks, chunk_instances] = c.room.chunk_words();
            [first_chunks, chunk_instances, c.room.chunks]
        });
        let (cluster_info, cmd_base) = match &self.clusters {
            Some(c) => {
                let cone = u32::from(sphere_projection(m.projection).0[2] == 1.0);
                let whole_early = u32::from(self.cluster_early == ClusterEarly::Instances);
                // A chunk holds 64 clusters: a longer gap is a whole chunk.
                let gap = self.cluster_gap.min(63);
                // Engine materials draw the lists group by group: fixed places (runs.rs).
                let fixed = u32::from(self.group_runs);
                let b = c.room.cmd_base;
                (
                    [
                        c.draw_id_base,
                        cone | (whole_early << 1) | (fixed << 2) | (gap << 8),
                        c.room.total,
                        cone_steps(
                            m.projection,
                            extent,
                            ctx.physical.limits.sub_pixel_precision_bits,
                        )
                        .to_bits(),
                    ],
                    [[b[0], b[1], b[2], b[3]], [b[4], b[5], b[6], b[7]]],
                )
            }
            None => ([0; 4], [[0; 4]; 2]),
        };
        let triangles = self
            .clusters
            .as_ref()
            .and_then(|c| c.triangles.as_ref())
            .map_or([0; 4], |t| {
                t.params(
                    self.index_tail,
                    ctx.physical.limits.sub_pixel_precision_bits,
                )
            });
        // The pyramid's frame as the sphere test sees it: last frame's view (moved to the
        // current eye, as `reproject` is) for single-phase HiZ, this frame's for the late phase.
        let previous_view = frame.previous.view
            * Mat4::from_translation((frame.current.eye - frame.previous.eye).as_vec3());
        // Level of detail: pixels per unit of length, P11 * H / 2 (over the distance where clip
        // w grows with depth: perspective, off-centre or not).
        let half_height = 0.5 * extent.1 as f32;
        let lod_meshes = self.lod_table.as_ref().map_or(0, |t| t.1);
        let lod = if lod_meshes > 0 {
            let perspective = m.projection.z_axis.w != 0.0;
            [
                self.lod.error_px,
                m.projection.y_axis.y.abs() * half_height,
                if perspective { 1.0 } else { 0.0 },
                self.lod.hysteresis,
            ]
        } else {
            [0.0; 4]
        };
        // Last frame's levels steer this frame's (the hysteresis), but after a cut or at first.
        let lod_history = u32::from(lod_meshes > 0 && !frame.cut && self.frames_written > 0);
        // Raster occlusion's early phase reads the box flags with this frame's turns.
        self.recheck = Recheck::new(self.recheck_interval, self.frames_written);
        let recheck = (self.culling == Culling::RasterOcclusion).then(|| self.recheck.packed());
        let params = |phase: Phase, view_proj: Mat4, levels: u32, previous: bool| {
            let (view, projection) = if previous {
                (previous_view, frame.previous.projection)
            } else {
                (m.view, m.projection)
            };
            let (hiz_proj, hiz_depth) = sphere_projection(projection);
            CullParams {
                planes,
                hiz_view_proj: view_proj.to_cols_array_2d(),
                info: [n, phase as u32, levels, reverse],
                screen: [pw, ph, stride, spheres],
                groups: [total.max(1), keep_empty, d16, recheck.unwrap_or(0)],
                group_start: layout.group_start,
                group_count: layout.group_count,
                hiz_view: view.to_cols_array_2d(),
                hiz_proj,
                hiz_depth,
                clusters: cluster_info,
                cmd_base,
                commands: [self.command_slots(), c1, c2, c3],
                triangles,
                lod,
                lod_info: [self.lod_levels, lod_meshes, lod_history, 0],
            }
        };
        let first = match self.culling.base() {
            // This frame's matrices against last frame's depth moved into this frame's view
            // (ReprojectState, written under the same conditions).
            Culling::Reproject => params(
                Phase::HizPrevious,
                m.view_projection,
                if pyramid.is_some_and(|p| p.built_from == Some(m.depth)) && !frame.cut {
                    levels
                } else {
                    0
                },
                false,
            ),
            Culling::Hiz => params(
                Phase::HizPrevious,
                frame.reproject,
                if pyramid.is_some_and(|p| p.built_from == Some(m.depth)) && !frame.cut {
                    levels
                } else {
                    0
                },
                true,
            ),
            // Raster occlusion: the early phase reads this frame's flags.
            Culling::HizTwoPhase | Culling::RasterOcclusion => {
                params(Phase::Early, m.view_projection, 0, false)
            }
            _ => params(Phase::Frustum, m.view_projection, 0, false),
        };
        let late = params(Phase::Late, m.view_projection, levels, false);
        let (group_count, groups) = (layout.group_count, &layout.groups);
        let entries = layout.entries;
        let inputs = self.slots.get_mut(slot).ok_or_else(|| VkError::Invalid {
            what: "cull".into(),
            reason: format!("no inputs for frame slot {slot}"),
        })?;
        ctx.write_mapped(&mut inputs.groups, 0, bytemuck::cast_slice(groups))?;
        inputs.stride = stride;
        let [early_params, late_params] = &mut inputs.params;
        ctx.write_mapped(early_params, 0, bytemuck::bytes_of(&first))?;
        ctx.write_mapped(late_params, 0, bytemuck::bytes_of(&late))?;
        inputs.group_count = group_count;
        inputs.group_start = layout.group_start;
        inputs.group_total = total;
        // Kept only for engine materials' runs: a frame without them allocates nothing here.
        inputs.keep_groups(self.group_runs, layout, self.clusters.as_ref());
        inputs.kept_every_group = keep_empty == 1;
        inputs.pending = Some((self.frames_written, entries));
        self.frames_written += 1;
        Ok(())
    }

    /// The layout of the phases' descriptor sets (binding 0 the phase's parameters, 5 and 6
    /// the pyramid and its levels: what `cull_tests.glsl` reads).
    pub fn phase_set_layout(&self) -> vk::DescriptorSetLayout {
        self.compute.set_layout
    }

    /// Frame slot `slot`'s set of phase `which` (0 early or only, 1 late).
    pub fn phase_set(&self, slot: usize, which: usize) -> Option<vk::DescriptorSet> {
        self.sets.get(2 * slot + which).copied()
    }

    /// Records dispatch `step` of phase `which` (0 early or only, 1 late); the graph put the
    /// barriers around it.
    pub(super) fn record_dispatch(
        &self,
        ctx: &Context,
        cb: vk::CommandBuffer,
        scene_set: vk::DescriptorSet,
        slot: usize,
        which: usize,
        step: Step,
    ) -> Result<(), VkError> {
        let set = phase_set(&self.sets, slot, which, "cull")?;
        let inputs = self.slot(slot)?;
        let phases = which as u32 + 1; // the late phase compacts the early lists again
        let (pipeline, groups) = match step {
            Step::Mark => (
                self.compute.pipelines[0],
                self.instances.div_ceil(64).max(1),
            ),
            Step::Compact => (self.compute.pipelines[1], phases * inputs.group_total),
            Step::Commands => (self.compute.pipelines[2], phases * LISTS_PER_PHASE),
            Step::Cluster(step) => {
                let Some(c) = &self.clusters else {
                    return Err(VkError::Invalid {
                        what: "cluster culling".into(),
                        reason: "the culling state has no cluster stage".into(),
                    });
                };
                return c.record_dispatch(
                    ctx,
                    cb,
                    scene_set,
                    slot,
                    (which, inputs.group_total),
                    step,
                );
            }
        };
        self.compute
            .dispatch(ctx, cb, pipeline, [scene_set, set], (groups, 1));
        Ok(())
    }

    pub fn handle(b: &Buffer) -> BufferHandle {
        BufferHandle {
            raw: b.raw,
            size: b.size,
        }
    }

    fn destroy_all(self, ctx: &Context) {
        if let Some(c) = self.clusters {
            c.destroy(ctx);
        }
        if let Some((t, _)) = self.lod_table {
            ctx.destroy_buffer(t);
        }
        self.compute.destroy(ctx);
        let buffers = [
            self.commands,
            self.counts,
            self.draw_ids,
            self.visibility,
            self.entries,
            self.survivors,
            self.no_pyramid,
        ];
        for b in buffers
            .into_iter()
            .chain(self.slots.into_iter().flat_map(|s| {
                let [a, b] = s.params;
                [a, b, s.groups, s.stats]
            }))
        {
            ctx.destroy_buffer(b);
        }
    }
}
