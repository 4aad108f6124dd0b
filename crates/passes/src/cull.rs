//! GPU-driven culling: frustum, HiZ against last frame's pyramid, and two-phase occlusion
//! culling (seeds 000, 002, 004), as compute passes that write indirect draws.
//!
//! The buffers live as long as the renderer (they carry visibility and the pyramid from frame to
//! frame, and tools read the drawn set back); each frame imports them into its graph, so the
//! graph orders the culling compute, the indirect draws and the pyramid build and puts the
//! barriers between them.

use ash::vk;
use bytemuck::{Pod, Zeroable};
use glam::Mat4;
use tilegraph_cull::{AabbExt, Frustum};
use tilegraph_graph::{
    AccessFlags, BufferId, Import, InitialContent, PassClass, PipelineStages, ResourceState,
};
use tilegraph_profile::MemoryUse;
use tilegraph_scene::{CameraFrame, DepthConvention};
use tilegraph_vk::ash;
use tilegraph_vk::executor::{BufferHandle, PassContext};
use tilegraph_vk::pipeline::{
    allocate_set, create_compute_pipeline, create_pipeline_layout, create_set_layout,
    write_buffer_set, Stage,
};
use tilegraph_vk::{Buffer, Context, Feature, VkError};

pub use crate::setup::Culling;

use crate::draws::DrawList;
use crate::frame::{scene_set, DrawSource, FrameGraph, PassState, Payload};
use crate::hiz::{HizState, PyramidInfo};

/// The culling buffers in one frame's graph. They live as long as the renderer (visibility and
/// the pyramid carry over from frame to frame, tools read the drawn set back), so each frame
/// imports them; the graph then orders the culling dispatches, the indirect draws and the
/// pyramid build, and puts the barriers between them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CullLists {
    pub commands: BufferId,
    pub counts: BufferId,
    pub draw_ids: BufferId,
    pub visibility: BufferId,
    pub pyramid: Option<BufferId>,
}

impl CullLists {
    /// The draws of culling phase `phase` (0: early or only, 1: late).
    pub fn source(self, phase: u32) -> DrawSource {
        DrawSource::Gpu {
            commands: self.commands,
            counts: self.counts,
            draw_ids: self.draw_ids,
            phase,
        }
    }
}

/// Imports `state`'s buffers (and `hiz`'s pyramid) into the frame's graph.
pub fn import_cull_buffers(
    g: &mut FrameGraph,
    state: &CullState,
    hiz: Option<&HizState>,
) -> CullLists {
    // Conservative boundary states: whatever touched them last frame, this frame waits for.
    let any = ResourceState::buffer(
        PipelineStages::ALL_COMMANDS,
        AccessFlags::MEMORY_READ.union(AccessFlags::MEMORY_WRITE),
    );
    let import = |content| Import {
        initial: any,
        content,
        final_state: any,
    };
    let discard = import(InitialContent::Discard);
    let keep = import(InitialContent::Preserve);
    let commands = g.import_buffer("cull-commands", state.commands.size, discard);
    let counts = g.import_buffer("cull-counts", state.counts.size, discard);
    let draw_ids = g.import_buffer("cull-draw-ids", state.draw_ids.size, discard);
    let visibility = g.import_buffer("visibility", state.visibility.size, keep);
    let pyramid = hiz.map(|h| g.import_buffer("hiz-pyramid", h.pyramid.size, keep));
    // What the next frame reads survives this one.
    g.export(visibility);
    if let Some(p) = pyramid {
        g.export(p);
    }
    // Tools read the drawn set back after the frame.
    g.export(counts);
    g.export(draw_ids);
    CullLists {
        commands,
        counts,
        draw_ids,
        visibility,
        pyramid,
    }
}

/// Declares the culling of the early (or only) phase of `culling`: the counts reset, then the
/// dispatch that writes the indirect lists. Frustum and HiZ test every instance (HiZ against
/// last frame's pyramid); two-phase culling's early phase draws last frame's visible set;
/// raster occlusion turns the flags its boxes wrote into lists.
pub fn add_cull(g: &mut FrameGraph, lists: CullLists, culling: Culling) {
    let two_phase = culling == Culling::HizTwoPhase;
    let counts = lists.counts;
    let reset: Payload = Box::new(move |pc, _| zero_fill(pc, counts));
    g.transfer_pass("cull-reset", PassClass::Compute, reset)
        .transfer_dst(lists.counts);
    let mut c = g.compute_pass(
        if two_phase { "cull-early" } else { "cull" },
        PassClass::Compute,
        dispatch(0),
    );
    c.storage_read_write(lists.counts)
        .storage_write(lists.commands)
        .storage_write(lists.draw_ids);
    if two_phase {
        c.storage_read(lists.visibility);
    }
    if culling == Culling::RasterOcclusion {
        // cull.comp's visibility binding is writable (the late phase writes it), so
        // synchronization validation counts the dispatch as a writer.
        c.storage_read_write(lists.visibility);
    }
    if let (Culling::Hiz, Some(p)) = (culling, lists.pyramid) {
        c.storage_read(p);
    }
}

/// Declares two-phase culling's late phase: the instances the early phase left out, tested
/// against the pyramid of the early phase's depth; the newly visible ones are appended to the
/// lists and become next frame's early set.
pub fn add_cull_late(g: &mut FrameGraph, lists: CullLists) {
    let mut c = g.compute_pass("cull-late", PassClass::Compute, dispatch(1));
    c.storage_read_write(lists.counts)
        .storage_read_write(lists.commands)
        .storage_write(lists.draw_ids)
        .storage_read_write(lists.visibility);
    if let Some(p) = lists.pyramid {
        c.storage_read(p);
    }
}

/// The culling dispatch `which` (0 early or only, 1 late).
fn dispatch(which: usize) -> Payload {
    Box::new(move |pc, res| {
        let set = scene_set(pc, res)?;
        let culling = res.states.require::<CullState>(pc.pass_name)?;
        culling.record_dispatch(pc.ctx, pc.cb, set, pc.frame_slot, which)
    })
}

/// Zeroes a whole buffer (the graph put it in TRANSFER_DST use for the pass).
pub fn zero_fill(pc: &PassContext<'_>, buffer: BufferId) -> Result<(), VkError> {
    let b = pc.buffer(buffer)?;
    // SAFETY: recording outside a render pass; the buffer is live and a transfer destination.
    unsafe {
        pc.ctx
            .device
            .cmd_fill_buffer(pc.cb, b.raw, 0, vk::WHOLE_SIZE, 0)
    };
    Ok(())
}

/// Draw lists the culling shader writes: opaque and alpha-tested, single- and double-sided,
/// for the early (or only) phase and the late phase.
pub const LISTS_PER_PHASE: u32 = 4;
pub const LIST_COUNT: u32 = 2 * LISTS_PER_PHASE;

/// List index of a class (0 opaque, 1 alpha-tested) and sidedness in a phase (0 early/only,
/// 1 late).
pub fn list_index(class: u32, double_sided: bool, phase: u32) -> u32 {
    phase * LISTS_PER_PHASE + class * 2 + u32::from(double_sided)
}

/// `CullParams` of `shaders/cull.comp` (std140).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct CullParams {
    pub planes: [[f32; 4]; 6],
    pub hiz_view_proj: [[f32; 4]; 4],
    /// x instances, y phase, z HiZ levels (0 = none), w 1 for reverse-Z.
    pub info: [u32; 4],
    /// x, y pyramid level-0 size; z list stride.
    pub screen: [u32; 4],
}

/// The phase argument of `cull.comp`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Phase {
    Frustum = 0,
    HizPrevious = 1,
    Early = 2,
    Late = 3,
}

/// Frustum planes of a camera-relative view-projection, for the shader (absent far plane of an
/// infinite projection becomes a plane every point passes).
pub fn gpu_planes(view_proj: Mat4, convention: DepthConvention) -> Result<[[f32; 4]; 6], VkError> {
    let f =
        Frustum::from_clip_from_world(&view_proj, convention).map_err(|e| VkError::Invalid {
            what: "frustum".into(),
            reason: e.to_string(),
        })?;
    Ok(f.gpu_planes().map(|p| p.to_array()))
}

/// The persistent culling state of one renderer.
pub struct CullState {
    pub culling: Culling,
    pub instance_count: u32,
    pub commands: Buffer,
    pub counts: Buffer,
    pub draw_ids: Buffer,
    pub visibility: Buffer,
    params: Vec<Buffer>,
    /// Per frame slot: each instance's entry in the lists in CPU draw order (`Order` of cull.comp).
    order: Vec<Buffer>,
    /// The order being written (kept: no allocation per frame).
    order_scratch: Vec<u32>,
    set_layout: vk::DescriptorSetLayout,
    pub pipeline_layout: vk::PipelineLayout,
    pipeline: vk::Pipeline,
    pool: vk::DescriptorPool,
    sets: Vec<vk::DescriptorSet>,
}

const CULL_SPV: &[u8] = include_bytes!("../../../shaders/spv/cull.comp.spv");

impl PassState for CullState {
    fn destroy(self: Box<Self>, ctx: &Context) {
        self.destroy_all(ctx);
    }
}

impl CullState {
    /// Device features GPU culling needs.
    pub fn required_features() -> [Feature; 2] {
        [Feature::DrawIndirectCount, Feature::MultiDrawIndirect]
    }

    /// The buffers, pipeline and descriptor sets of `culling` for `instance_count` instances;
    /// `hiz`: the pyramid the HiZ techniques test against (bound for the shader).
    pub fn new(
        ctx: &Context,
        culling: Culling,
        instance_count: u32,
        scene_set_layout: vk::DescriptorSetLayout,
        frames_in_flight: usize,
        hiz: Option<&HizState>,
    ) -> Result<Self, VkError> {
        let n = u64::from(instance_count.max(1));
        let storage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let indirect = vk::BufferUsageFlags::INDIRECT_BUFFER;
        let src = vk::BufferUsageFlags::TRANSFER_SRC;
        let dst = vk::BufferUsageFlags::TRANSFER_DST;
        let specs = [
            (
                "cull commands",
                n * u64::from(LIST_COUNT) * 20,
                storage | indirect | src,
            ),
            (
                "cull counts",
                u64::from(LIST_COUNT) * 4,
                storage | indirect | dst | src,
            ),
            (
                "cull draw ids",
                n * u64::from(LIST_COUNT) * 4,
                storage | src,
            ),
            ("visibility", n * 4, storage | dst),
        ];
        let mut made: Vec<Buffer> = Vec::with_capacity(specs.len());
        for (name, size, usage) in specs {
            match ctx.create_buffer(name, size, usage, MemoryUse::GpuOnly) {
                Ok(b) => made.push(b),
                Err(e) => {
                    for b in made {
                        ctx.destroy_buffer(b);
                    }
                    return Err(e);
                }
            }
        }
        let mut made = made.into_iter();
        let (Some(commands), Some(counts), Some(draw_ids), Some(visibility)) =
            (made.next(), made.next(), made.next(), made.next())
        else {
            return Err(VkError::Invalid {
                what: "cull".into(),
                reason: "buffers missing".into(),
            });
        };
        // Vulkan objects start null and are filled in; on error `destroy` frees what exists
        // (destroying VK_NULL_HANDLE is a no-op).
        let mut state = CullState {
            culling,
            instance_count,
            commands,
            counts,
            draw_ids,
            visibility,
            params: Vec::new(),
            order: Vec::new(),
            order_scratch: Vec::new(),
            set_layout: vk::DescriptorSetLayout::null(),
            pipeline_layout: vk::PipelineLayout::null(),
            pipeline: vk::Pipeline::null(),
            pool: vk::DescriptorPool::null(),
            sets: Vec::new(),
        };
        match state.init(ctx, scene_set_layout, frames_in_flight, hiz) {
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
        frames_in_flight: usize,
        hiz: Option<&HizState>,
    ) -> Result<(), VkError> {
        let n = u64::from(self.instance_count.max(1));
        let c = vk::ShaderStageFlags::COMPUTE;
        let ssbo = vk::DescriptorType::STORAGE_BUFFER;
        self.set_layout = create_set_layout(
            ctx,
            &[
                (0, vk::DescriptorType::UNIFORM_BUFFER, c),
                (1, ssbo, c),
                (2, ssbo, c),
                (3, ssbo, c),
                (4, ssbo, c),
                (5, ssbo, c),
                (6, ssbo, c),
                (7, ssbo, c),
            ],
        )?;
        self.pipeline_layout =
            create_pipeline_layout(ctx, &[scene_set_layout, self.set_layout], None)?;
        self.pipeline = create_compute_pipeline(
            ctx,
            &Stage {
                name: "cull.comp",
                spirv: CULL_SPV,
                specialization: &[],
            },
            self.pipeline_layout,
        )?;
        let slots = frames_in_flight.max(1) as u32;
        let sizes = [
            vk::DescriptorPoolSize {
                ty: vk::DescriptorType::UNIFORM_BUFFER,
                descriptor_count: 4 * slots,
            },
            vk::DescriptorPoolSize {
                ty: ssbo,
                descriptor_count: 28 * slots,
            },
        ];
        let pool_info = vk::DescriptorPoolCreateInfo::default()
            .max_sets(4 * slots)
            .pool_sizes(&sizes);
        // SAFETY: valid create info.
        self.pool = unsafe { ctx.device.create_descriptor_pool(&pool_info, None) }
            .map_err(|r| VkError::call("vkCreateDescriptorPool", r))?;
        // Two parameter blocks per slot: the early (or only) and the late dispatch.
        for i in 0..2 * slots {
            let b = ctx.create_buffer(
                &format!("cull params[{i}]"),
                std::mem::size_of::<CullParams>() as u64,
                vk::BufferUsageFlags::UNIFORM_BUFFER,
                MemoryUse::Streaming,
            )?;
            self.params.push(b);
        }
        for i in 0..slots {
            let b = ctx.create_buffer(
                &format!("cull order[{i}]"),
                n * 4,
                vk::BufferUsageFlags::STORAGE_BUFFER,
                MemoryUse::Streaming,
            )?;
            self.order.push(b);
        }
        // Without a pyramid the shader never reads bindings 5 and 6; bind small live buffers.
        let pyramid = hiz.map_or(self.counts.raw, |h| h.pyramid.raw);
        let levels = hiz.map_or(self.counts.raw, |h| h.levels.raw);
        for i in 0..2 * slots as usize {
            let set = self.write_set(ctx, i, pyramid, levels)?;
            self.sets.push(set);
        }
        Ok(())
    }

    fn write_set(
        &self,
        ctx: &Context,
        index: usize,
        pyramid: vk::Buffer,
        levels: vk::Buffer,
    ) -> Result<vk::DescriptorSet, VkError> {
        // The pool holds a set per parameter block.
        let set = allocate_set(ctx, self.pool, self.set_layout)?;
        let order = self.order.get(index / 2).ok_or_else(|| VkError::Invalid {
            what: "cull".into(),
            reason: format!("no order buffer for set {index}"),
        })?;
        let ssbo = vk::DescriptorType::STORAGE_BUFFER;
        write_buffer_set(
            ctx,
            set,
            &[
                (
                    0,
                    vk::DescriptorType::UNIFORM_BUFFER,
                    self.params[index].raw,
                ),
                (1, ssbo, self.commands.raw),
                (2, ssbo, self.counts.raw),
                (3, ssbo, self.draw_ids.raw),
                (4, ssbo, self.visibility.raw),
                (5, ssbo, pyramid),
                (6, ssbo, levels),
                (7, ssbo, order.raw),
            ],
        );
        Ok(set)
    }

    /// Writes the parameters of the dispatch `which` (0 early/only, 1 late) of frame slot `slot`.
    pub fn write_params(
        &mut self,
        ctx: &Context,
        slot: usize,
        which: usize,
        params: &CullParams,
    ) -> Result<(), VkError> {
        let i = 2 * slot + which;
        let b = self.params.get_mut(i).ok_or_else(|| VkError::Invalid {
            what: "cull params".into(),
            reason: format!("slot {slot}"),
        })?;
        ctx.write_mapped(b, 0, bytemuck::bytes_of(params))
    }

    /// Writes frame slot `slot`'s draw order: for each instance, its list entry
    /// (`list * stride + position`, see [`gpu_order`]).
    pub fn write_order(
        &mut self,
        ctx: &Context,
        slot: usize,
        order: &[u32],
    ) -> Result<(), VkError> {
        let b = self.order.get_mut(slot).ok_or_else(|| VkError::Invalid {
            what: "cull order".into(),
            reason: format!("slot {slot}"),
        })?;
        ctx.write_mapped(b, 0, bytemuck::cast_slice(order))
    }

    /// Writes slot `slot`'s culling inputs for `frame`: each instance's entry in the lists in
    /// the CPU list's draw order (so the culled frame draws its survivors in the unculled
    /// order), and both dispatches' parameters. After a camera cut, single-phase HiZ tests
    /// nothing against the previous pyramid (another view's depth would cull at random): that
    /// frame is frustum-culled only.
    pub fn write_frame(
        &mut self,
        ctx: &Context,
        slot: usize,
        frame: &CameraFrame,
        draws: &DrawList,
        extent: (u32, u32),
        pyramid: Option<PyramidInfo>,
    ) -> Result<(), VkError> {
        let m = &frame.current;
        let mut order = std::mem::take(&mut self.order_scratch);
        gpu_order_into(draws, self.instance_count as usize, &mut order);
        let written = self.write_order(ctx, slot, &order);
        self.order_scratch = order;
        written?;
        let planes = gpu_planes(m.view_projection, m.depth)?;
        let levels = pyramid.map_or(0, |p| p.levels);
        let (pw, ph) = pyramid.map_or(extent, |p| p.extent_px);
        let reverse = u32::from(m.depth == DepthConvention::Reverse);
        let n = self.instance_count;
        let params = |phase: Phase, view_proj: Mat4, levels: u32| CullParams {
            planes,
            hiz_view_proj: view_proj.to_cols_array_2d(),
            info: [n, phase as u32, levels, reverse],
            screen: [pw, ph, n.max(1), 0],
        };
        let first = match self.culling {
            Culling::Hiz => params(
                Phase::HizPrevious,
                frame.reproject,
                if pyramid.is_some_and(|p| p.built_from == Some(m.depth)) && !frame.cut {
                    levels
                } else {
                    0
                },
            ),
            // Raster occlusion: the early phase reads this frame's flags.
            Culling::HizTwoPhase | Culling::RasterOcclusion => {
                params(Phase::Early, m.view_projection, 0)
            }
            _ => params(Phase::Frustum, m.view_projection, 0),
        };
        self.write_params(ctx, slot, 0, &first)?;
        self.write_params(
            ctx,
            slot,
            1,
            &params(Phase::Late, m.view_projection, levels),
        )
    }

    /// Records the culling dispatch (the graph put the barriers around it).
    pub fn record_dispatch(
        &self,
        ctx: &Context,
        cb: vk::CommandBuffer,
        scene_set: vk::DescriptorSet,
        slot: usize,
        which: usize,
    ) -> Result<(), VkError> {
        let set = *self
            .sets
            .get(2 * slot + which)
            .ok_or_else(|| VkError::Invalid {
                what: "cull".into(),
                reason: format!("no set for slot {slot}"),
            })?;
        let groups = self.instance_count.div_ceil(64).max(1);
        // SAFETY: recording outside a render pass; pipeline, layout and sets are live.
        unsafe {
            ctx.device
                .cmd_bind_pipeline(cb, vk::PipelineBindPoint::COMPUTE, self.pipeline);
            ctx.device.cmd_bind_descriptor_sets(
                cb,
                vk::PipelineBindPoint::COMPUTE,
                self.pipeline_layout,
                0,
                &[scene_set, set],
                &[],
            );
            ctx.device.cmd_dispatch(cb, groups, 1, 1);
        }
        Ok(())
    }

    /// Records one `vkCmdDrawIndexedIndirectCount` per list.
    pub fn record_draws(&self, ctx: &Context, cb: vk::CommandBuffer, list: u32) {
        let stride = u64::from(self.instance_count.max(1));
        // SAFETY: inside a render pass with a pipeline, vertex/index buffers and sets bound;
        // commands hold `stride` entries per list; the count is at most `stride` (one per instance).
        unsafe {
            ctx.device.cmd_draw_indexed_indirect_count(
                cb,
                self.commands.raw,
                u64::from(list) * stride * 20,
                self.counts.raw,
                u64::from(list) * 4,
                self.instance_count.max(1),
                20,
            );
        }
    }

    pub fn handle(b: &Buffer) -> BufferHandle {
        BufferHandle {
            raw: b.raw,
            size: b.size,
        }
    }

    /// The instances drawn by the last frame: entries whose command has instanceCount 1 (reads
    /// the counts, commands and draw ids back; waits).
    pub fn drawn_instances(&self, ctx: &Context) -> Result<Vec<u32>, VkError> {
        let counts = tilegraph_vk::readback::read_buffer(ctx, Self::handle(&self.counts))?;
        let commands = tilegraph_vk::readback::read_buffer(ctx, Self::handle(&self.commands))?;
        let ids = tilegraph_vk::readback::read_buffer(ctx, Self::handle(&self.draw_ids))?;
        let word = |b: &[u8], i: usize| {
            b.get(4 * i..4 * i + 4)
                .map_or(0, |w| u32::from_le_bytes([w[0], w[1], w[2], w[3]]))
        };
        let stride = self.instance_count.max(1) as usize;
        let mut out = Vec::new();
        for list in 0..LIST_COUNT as usize {
            let n = (word(&counts, list) as usize).min(stride);
            out.extend(
                (0..n)
                    .map(|k| list * stride + k)
                    .filter(|&at| word(&commands, 5 * at + 1) == 1)
                    .map(|at| word(&ids, at)),
            );
        }
        out.sort_unstable();
        out.dedup();
        Ok(out)
    }

    fn destroy_all(self, ctx: &Context) {
        // SAFETY: the GPU is idle (caller's guarantee); null handles are ignored.
        unsafe {
            ctx.device.destroy_pipeline(self.pipeline, None);
            ctx.device
                .destroy_pipeline_layout(self.pipeline_layout, None);
            ctx.device.destroy_descriptor_pool(self.pool, None);
            ctx.device
                .destroy_descriptor_set_layout(self.set_layout, None);
        }
        for b in [self.commands, self.counts, self.draw_ids, self.visibility]
            .into_iter()
            .chain(self.params)
            .chain(self.order)
        {
            ctx.destroy_buffer(b);
        }
    }
}

/// CPU plane-test frustum culling (the reference's conservative test) of every instance, in
/// camera-relative f64 bounds: `mask[i]` = not rejected. Used for blended geometry, which the
/// GPU lists leave to the CPU so it can be sorted back to front.
pub fn cpu_frustum_mask(
    scene: &tilegraph_scene::Scene,
    m: &tilegraph_scene::FrameMatrices,
) -> Result<Vec<bool>, VkError> {
    let mut mask = Vec::new();
    cpu_frustum_mask_into(scene, m, &mut mask)?;
    Ok(mask)
}

/// [`cpu_frustum_mask`] into `mask` (cleared and refilled: no allocation once it has the
/// scene's length).
pub fn cpu_frustum_mask_into(
    scene: &tilegraph_scene::Scene,
    m: &tilegraph_scene::FrameMatrices,
    mask: &mut Vec<bool>,
) -> Result<(), VkError> {
    let invalid = |e: tilegraph_cull::CullError| VkError::Invalid {
        what: "frustum".into(),
        reason: e.to_string(),
    };
    let frustum = Frustum::from_clip_from_world(&m.view_projection, m.depth).map_err(invalid)?;
    mask.clear();
    for inst in scene.instances() {
        let b = inst.bounds.aabb();
        let aabb = tilegraph_cull::Aabb::from_world_f64(b.min, b.max, m.eye).map_err(invalid)?;
        mask.push(!matches!(
            frustum.test_aabb(&aabb).map_err(invalid)?,
            tilegraph_cull::PlaneTest::Outside(_)
        ));
    }
    Ok(())
}

/// Each instance's entry in the GPU lists, in the order the CPU draw list draws it (single-sided
/// draws of a class first, then double-sided, as [`crate::recording`] records them): `list *
/// stride + position`, `u32::MAX` for blended instances (not culled on the GPU).
pub fn gpu_order(draws: &crate::draws::DrawList, instance_count: usize) -> Vec<u32> {
    let mut order = Vec::new();
    gpu_order_into(draws, instance_count, &mut order);
    order
}

/// [`gpu_order`] into `order` (refilled in place).
pub fn gpu_order_into(draws: &crate::draws::DrawList, instance_count: usize, order: &mut Vec<u32>) {
    let stride = instance_count.max(1) as u32;
    order.clear();
    order.resize(instance_count, u32::MAX);
    for (class, list_draws) in [(0u32, &draws.opaque), (1, &draws.alpha_tested)] {
        for sided in [false, true] {
            let list = list_index(class, sided, 0);
            let mut position = 0u32;
            for d in list_draws.iter().filter(|d| d.double_sided == sided) {
                for k in d.first_instance..d.first_instance + d.instance_count {
                    if let Some(&id) = draws.instances.get(k as usize) {
                        if let Some(o) = order.get_mut(id as usize) {
                            *o = list * stride + position;
                            position += 1;
                        }
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cli_spellings_round_trip() {
        for c in [
            Culling::None,
            Culling::Frustum,
            Culling::Hiz,
            Culling::HizTwoPhase,
            Culling::Oq,
            Culling::OqConditional,
            Culling::RasterOcclusion,
        ] {
            assert_eq!(Culling::parse(c.name()), Some(c));
        }
        assert_eq!(
            Culling::parse("oq-conditional"),
            Some(Culling::OqConditional)
        );
        assert_eq!(
            Culling::parse("raster-occlusion"),
            Some(Culling::RasterOcclusion)
        );
        assert_eq!(Culling::parse("occlusion"), None);
    }

    #[test]
    fn same_frame_occlusion_techniques_need_a_prepass_and_the_right_path() {
        assert!(Culling::OqConditional.needs_prepass() && Culling::OqConditional.uses_queries());
        assert!(!Culling::OqConditional.uses_gpu_lists());
        assert!(
            Culling::RasterOcclusion.needs_prepass() && Culling::RasterOcclusion.uses_gpu_lists()
        );
        assert!(!Culling::Oq.needs_prepass() && !Culling::Oq.uses_gpu_lists());
    }
}
