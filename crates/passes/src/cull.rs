//! GPU-driven culling: frustum, HiZ against last frame's pyramid, and two-phase occlusion
//! culling (seeds 000, 002, 004), as compute passes that write compacted indirect draws.
//!
//! Each culling phase is three dispatches (docs/ARCHITECTURE.md, "ordered compaction"):
//! `cull.comp` marks every instance's fixed entry in the unculled draw order,
//! `cull_compact.comp` packs the survivors of each draw group (one mesh's run of entries, the
//! CPU list's instanced draw) in that order, and `cull_commands.comp` writes one instanced
//! command per group that kept an instance, in group order, with the draw count. The culled
//! frame therefore draws its survivors in the unculled order (images stay bit-equal), and the
//! command processor walks survivors only. Where the device or the profile does without
//! `drawIndirectCount`, every group keeps its command (zero instances when culled) and the CPU
//! draws the list's group count.
//!
//! The buffers live as long as the renderer (they carry visibility and the pyramid from frame to
//! frame, and tools read the drawn set back); each frame imports them into its graph, so the
//! graph orders the dispatches, the indirect draws and the pyramid build and puts the barriers
//! between them.

use ash::vk;
use bytemuck::{Pod, Zeroable};
use glam::Mat4;
use tilegraph_cull::{AabbExt, Frustum};
use tilegraph_graph::{
    AccessFlags, BufferId, Import, InitialContent, PassClass, PipelineStages, ResourceState,
};
use tilegraph_profile::{IndirectCount, MemoryUse};
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
    /// Per list entry: 0 culled, instance id + 1 drawn (`cull.comp` → `cull_compact.comp`).
    pub entries: BufferId,
    /// Per draw group and phase: how many instances survived (→ `cull_commands.comp`).
    pub survivors: BufferId,
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
    let entries = g.import_buffer("cull-entries", state.entries.size, discard);
    let survivors = g.import_buffer("cull-survivors", state.survivors.size, discard);
    let pyramid = hiz.map(|h| g.import_buffer("hiz-pyramid", h.pyramid.size, keep));
    // What the next frame reads survives this one.
    g.export(visibility);
    if let Some(p) = pyramid {
        g.export(p);
    }
    // Tools read the drawn set back after the frame.
    g.export(counts);
    g.export(commands);
    g.export(draw_ids);
    CullLists {
        commands,
        counts,
        draw_ids,
        visibility,
        entries,
        survivors,
        pyramid,
    }
}

/// The three dispatches of a culling phase.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Step {
    /// `cull.comp`: one thread per instance marks its entries.
    Mark,
    /// `cull_compact.comp`: one workgroup per draw group packs its survivors.
    Compact,
    /// `cull_commands.comp`: one workgroup per list writes its commands and count.
    Commands,
}

/// Declares the culling of the early (or only) phase of `culling`: the dispatches that write the
/// indirect lists (and empty the late lists, which a late phase fills). Frustum and HiZ test every instance (HiZ against
/// last frame's pyramid); two-phase culling's early phase draws last frame's visible set;
/// raster occlusion turns the flags its boxes wrote into lists.
pub fn add_cull(g: &mut FrameGraph, lists: CullLists, culling: Culling) {
    let two_phase = culling == Culling::HizTwoPhase;
    let name = if two_phase { "cull-early" } else { "cull" };
    let mut c = g.compute_pass(name, PassClass::Compute, dispatch(0, Step::Mark));
    c.storage_write(lists.entries);
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
    let (compact, commands) = if two_phase {
        ("cull-early-compact", "cull-early-commands")
    } else {
        ("cull-compact", "cull-commands")
    };
    add_compaction(g, lists, 0, [compact, commands]);
}

/// The compaction of phase `which` (0 early or only, 1 late): survivors packed per group, then
/// the commands and counts.
fn add_compaction(g: &mut FrameGraph, lists: CullLists, which: usize, names: [&'static str; 2]) {
    g.compute_pass(names[0], PassClass::Compute, dispatch(which, Step::Compact))
        .storage_read(lists.entries)
        .storage_write(lists.draw_ids)
        .storage_write(lists.survivors);
    g.compute_pass(
        names[1],
        PassClass::Compute,
        dispatch(which, Step::Commands),
    )
    .storage_read(lists.survivors)
    .storage_write(lists.commands)
    .storage_write(lists.counts);
}

/// Declares two-phase culling's late phase: the instances the early phase left out, tested
/// against the pyramid of the early phase's depth; the newly visible ones get the late lists
/// (the late depth pass) and join the early lists (the colour pass draws the union), and become
/// next frame's early set.
pub fn add_cull_late(g: &mut FrameGraph, lists: CullLists) {
    let mut c = g.compute_pass("cull-late", PassClass::Compute, dispatch(1, Step::Mark));
    c.storage_read_write(lists.entries)
        .storage_read_write(lists.visibility);
    if let Some(p) = lists.pyramid {
        c.storage_read(p);
    }
    add_compaction(g, lists, 1, ["cull-late-compact", "cull-late-commands"]);
}

/// The culling dispatch `step` of phase `which` (0 early or only, 1 late).
fn dispatch(which: usize, step: Step) -> Payload {
    Box::new(move |pc, res| {
        let set = scene_set(pc, res)?;
        let culling = res.states.require::<CullState>(pc.pass_name)?;
        culling.record_dispatch(pc.ctx, pc.cb, set, pc.frame_slot, which, step)
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

/// `CullParams` of `shaders/common/cull.glsl` (std140).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct CullParams {
    pub planes: [[f32; 4]; 6],
    pub hiz_view_proj: [[f32; 4]; 4],
    /// x instances, y phase, z HiZ levels (0 = none), w 1 for reverse-Z.
    pub info: [u32; 4],
    /// x, y pyramid level-0 size; z list stride.
    pub screen: [u32; 4],
    /// x draw groups per phase (at least 1), y 1 = keep empty commands (fixed draw count).
    pub groups: [u32; 4],
    /// Per list of a phase: its first draw group.
    pub group_start: [u32; 4],
    /// Per list of a phase: its number of draw groups.
    pub group_count: [u32; 4],
}

/// The phase argument of `cull.comp`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Phase {
    Frustum = 0,
    HizPrevious = 1,
    Early = 2,
    Late = 3,
}

/// How the culled lists are drawn (chosen when the culling state is made, from the profile's
/// `indirect_count` and the device's features).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DrawCount {
    /// `vkCmdDrawIndexedIndirectCount`: the GPU's count covers the surviving groups only.
    Gpu,
    /// One command per draw group, culled groups with zero instances; `multi_draw`: in one
    /// `vkCmdDrawIndexedIndirect` (else one call per command, without `multiDrawIndirect`).
    Fixed { multi_draw: bool },
}

impl DrawCount {
    /// The mode for `ctx`'s profile and device.
    pub fn for_device(ctx: &Context) -> Self {
        let wanted = ctx.profile().passes.indirect_count == IndirectCount::WhenSupported;
        if wanted && ctx.has_feature(Feature::DrawIndirectCount) {
            DrawCount::Gpu
        } else {
            DrawCount::Fixed {
                multi_draw: ctx.has_feature(Feature::MultiDrawIndirect),
            }
        }
    }
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
    /// Per instance, its entry in the unculled order of the last frame written
    /// ([`GpuLayout::order`]).
    pub order: Vec<u32>,
}

/// Per frame slot: what the CPU wrote for the GPU lists of that slot's frame.
struct SlotInputs {
    params: [Buffer; 2],
    /// Each instance's entry (`Order` of cull.comp).
    order: Buffer,
    /// The draw groups (`Groups` of common/cull.glsl).
    groups: Buffer,
    /// Groups per list of a phase, as written (what the draws of that frame cover).
    group_count: [u32; 4],
    /// Groups per phase.
    group_total: u32,
}

/// The persistent culling state of one renderer.
pub struct CullState {
    pub culling: Culling,
    pub instance_count: u32,
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
    /// The layout being written (kept: no allocation per frame).
    layout: GpuLayout,
    set_layout: vk::DescriptorSetLayout,
    pub pipeline_layout: vk::PipelineLayout,
    /// `cull.comp`, `cull_compact.comp`, `cull_commands.comp`.
    pipelines: [vk::Pipeline; 3],
    pool: vk::DescriptorPool,
    /// Two per slot: the early (or only) and the late phase.
    sets: Vec<vk::DescriptorSet>,
}

const CULL_SPV: &[u8] = include_bytes!("../../../shaders/spv/cull.comp.spv");
const COMPACT_SPV: &[u8] = include_bytes!("../../../shaders/spv/cull_compact.comp.spv");
const COMMANDS_SPV: &[u8] = include_bytes!("../../../shaders/spv/cull_commands.comp.spv");

/// The culling descriptor set's storage buffers (bindings 1-10).
const STORAGE_BINDINGS: u32 = 10;

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

    /// The buffers, pipelines and descriptor sets of `culling` for `instance_count` instances;
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
        let lists = u64::from(LIST_COUNT);
        let storage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let indirect = vk::BufferUsageFlags::INDIRECT_BUFFER;
        let src = vk::BufferUsageFlags::TRANSFER_SRC;
        let dst = vk::BufferUsageFlags::TRANSFER_DST;
        let specs = [
            ("cull commands", n * lists * 20, storage | indirect | src),
            ("cull counts", lists * 4, storage | indirect | src),
            ("cull draw ids", n * lists * 4, storage | src),
            ("visibility", n * 4, storage | dst),
            ("cull entries", n * lists * 4, storage),
            // At most one group per instance and phase.
            ("cull survivors", 2 * n * 4, storage),
            // Bound as the pyramid without one: never written, never read (the levels say 0).
            ("cull no pyramid", 16, storage),
        ];
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
            instance_count,
            draw_count,
            commands,
            counts,
            draw_ids,
            visibility,
            entries,
            survivors,
            no_pyramid,
            slots: Vec::new(),
            layout: GpuLayout::default(),
            set_layout: vk::DescriptorSetLayout::null(),
            pipeline_layout: vk::PipelineLayout::null(),
            pipelines: [vk::Pipeline::null(); 3],
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
        let mut bindings = vec![(0, vk::DescriptorType::UNIFORM_BUFFER, c)];
        bindings.extend((1..=STORAGE_BINDINGS).map(|b| (b, ssbo, c)));
        self.set_layout = create_set_layout(ctx, &bindings)?;
        self.pipeline_layout =
            create_pipeline_layout(ctx, &[scene_set_layout, self.set_layout], None)?;
        let stages = [
            ("cull.comp", CULL_SPV),
            ("cull_compact.comp", COMPACT_SPV),
            ("cull_commands.comp", COMMANDS_SPV),
        ];
        for (pipeline, (name, spirv)) in self.pipelines.iter_mut().zip(stages) {
            *pipeline = create_compute_pipeline(
                ctx,
                &Stage {
                    name,
                    spirv,
                    specialization: &[],
                },
                self.pipeline_layout,
            )?;
        }
        let slots = frames_in_flight.max(1) as u32;
        let sizes = [
            vk::DescriptorPoolSize {
                ty: vk::DescriptorType::UNIFORM_BUFFER,
                descriptor_count: 2 * slots,
            },
            vk::DescriptorPoolSize {
                ty: ssbo,
                descriptor_count: 2 * STORAGE_BINDINGS * slots,
            },
        ];
        let pool_info = vk::DescriptorPoolCreateInfo::default()
            .max_sets(2 * slots)
            .pool_sizes(&sizes);
        // SAFETY: valid create info.
        self.pool = unsafe { ctx.device.create_descriptor_pool(&pool_info, None) }
            .map_err(|r| VkError::call("vkCreateDescriptorPool", r))?;
        for slot in 0..slots {
            let inputs = SlotInputs::new(ctx, slot, n)?;
            self.slots.push(inputs);
        }
        // Without a pyramid the shader never reads bindings 5 and 6.
        let pyramid = hiz.map_or(self.no_pyramid.raw, |h| h.pyramid.raw);
        let levels = hiz.map_or(self.no_pyramid.raw, |h| h.levels.raw);
        for i in 0..2 * slots as usize {
            let set = self.write_set(ctx, i, pyramid, levels)?;
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
    ) -> Result<vk::DescriptorSet, VkError> {
        let inputs = self.slot(index / 2)?;
        // The pool holds a set per parameter block.
        let set = allocate_set(ctx, self.pool, self.set_layout)?;
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
                (7, ssbo, inputs.order.raw),
                (8, ssbo, self.entries.raw),
                (9, ssbo, inputs.groups.raw),
                (10, ssbo, self.survivors.raw),
            ],
        );
        Ok(set)
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
        draws: &DrawList,
        extent: (u32, u32),
        pyramid: Option<PyramidInfo>,
    ) -> Result<(), VkError> {
        let m = &frame.current;
        self.layout.fill(draws, self.instance_count as usize);
        let planes = gpu_planes(m.view_projection, m.depth)?;
        let levels = pyramid.map_or(0, |p| p.levels);
        let (pw, ph) = pyramid.map_or(extent, |p| p.extent_px);
        let reverse = u32::from(m.depth == DepthConvention::Reverse);
        let n = self.instance_count;
        let layout = &self.layout;
        let total = layout.groups.len() as u32;
        let keep_empty = u32::from(matches!(self.draw_count, DrawCount::Fixed { .. }));
        let params = |phase: Phase, view_proj: Mat4, levels: u32| CullParams {
            planes,
            hiz_view_proj: view_proj.to_cols_array_2d(),
            info: [n, phase as u32, levels, reverse],
            screen: [pw, ph, n.max(1), 0],
            groups: [total.max(1), keep_empty, 0, 0],
            group_start: layout.group_start,
            group_count: layout.group_count,
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
        let late = params(Phase::Late, m.view_projection, levels);
        let (group_count, order, groups) = (layout.group_count, &layout.order, &layout.groups);
        let inputs = self.slots.get_mut(slot).ok_or_else(|| VkError::Invalid {
            what: "cull".into(),
            reason: format!("no inputs for frame slot {slot}"),
        })?;
        ctx.write_mapped(&mut inputs.order, 0, bytemuck::cast_slice(order))?;
        ctx.write_mapped(&mut inputs.groups, 0, bytemuck::cast_slice(groups))?;
        let [early_params, late_params] = &mut inputs.params;
        ctx.write_mapped(early_params, 0, bytemuck::bytes_of(&first))?;
        ctx.write_mapped(late_params, 0, bytemuck::bytes_of(&late))?;
        inputs.group_count = group_count;
        inputs.group_total = total;
        Ok(())
    }

    /// Records dispatch `step` of phase `which` (0 early or only, 1 late); the graph put the
    /// barriers around it.
    fn record_dispatch(
        &self,
        ctx: &Context,
        cb: vk::CommandBuffer,
        scene_set: vk::DescriptorSet,
        slot: usize,
        which: usize,
        step: Step,
    ) -> Result<(), VkError> {
        let set = *self
            .sets
            .get(2 * slot + which)
            .ok_or_else(|| VkError::Invalid {
                what: "cull".into(),
                reason: format!("no set for slot {slot}"),
            })?;
        let inputs = self.slot(slot)?;
        let phases = which as u32 + 1; // the late phase compacts the early lists again
        let (pipeline, groups) = match step {
            Step::Mark => (self.pipelines[0], self.instance_count.div_ceil(64)),
            Step::Compact => (self.pipelines[1], phases * inputs.group_total),
            Step::Commands => (self.pipelines[2], phases * LISTS_PER_PHASE),
        };
        if groups == 0 {
            return Ok(());
        }
        // SAFETY: recording outside a render pass; pipeline, layout and sets are live.
        unsafe {
            ctx.device
                .cmd_bind_pipeline(cb, vk::PipelineBindPoint::COMPUTE, pipeline);
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

    /// Records list `list`'s draws of frame slot `slot`: one `vkCmdDrawIndexedIndirectCount`,
    /// or with a fixed count one command per draw group.
    pub fn record_draws(
        &self,
        ctx: &Context,
        cb: vk::CommandBuffer,
        slot: usize,
        list: u32,
    ) -> Result<(), VkError> {
        let groups = self
            .slot(slot)?
            .group_count
            .get((list % LISTS_PER_PHASE) as usize)
            .copied()
            .unwrap_or(0);
        if groups == 0 {
            return Ok(());
        }
        let stride = u64::from(self.instance_count.max(1));
        let offset = u64::from(list) * stride * 20;
        let d = &ctx.device;
        // SAFETY (all three): inside a render pass with a pipeline, vertex/index buffers and
        // sets bound; list `list` holds `stride` >= `groups` commands of 20 bytes from `offset`,
        // every one written by cull_commands.comp this frame.
        match self.draw_count {
            DrawCount::Gpu => unsafe {
                d.cmd_draw_indexed_indirect_count(
                    cb,
                    self.commands.raw,
                    offset,
                    self.counts.raw,
                    u64::from(list) * 4,
                    groups,
                    20,
                );
            },
            DrawCount::Fixed { multi_draw: true } => unsafe {
                d.cmd_draw_indexed_indirect(cb, self.commands.raw, offset, groups, 20);
            },
            DrawCount::Fixed { multi_draw: false } => {
                for k in 0..u64::from(groups) {
                    unsafe {
                        d.cmd_draw_indexed_indirect(cb, self.commands.raw, offset + 20 * k, 1, 20)
                    };
                }
            }
        }
        Ok(())
    }

    pub fn handle(b: &Buffer) -> BufferHandle {
        BufferHandle {
            raw: b.raw,
            size: b.size,
        }
    }

    /// The last frame's lists as the GPU left them (reads the counts, commands and draw ids
    /// back; waits).
    pub fn read_lists(&self, ctx: &Context) -> Result<GpuLists, VkError> {
        let counts = tilegraph_vk::readback::read_buffer(ctx, Self::handle(&self.counts))?;
        let commands = tilegraph_vk::readback::read_buffer(ctx, Self::handle(&self.commands))?;
        let ids = tilegraph_vk::readback::read_buffer(ctx, Self::handle(&self.draw_ids))?;
        let word = |b: &[u8], i: usize| {
            b.get(4 * i..4 * i + 4)
                .map_or(0, |w| u32::from_le_bytes([w[0], w[1], w[2], w[3]]))
        };
        let stride = self.instance_count.max(1) as usize;
        let lists = (0..LIST_COUNT as usize)
            .map(|list| {
                let n = (word(&counts, list) as usize).min(stride);
                (0..n)
                    .map(|k| {
                        let at = list * stride + k;
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
            order: self.layout.order.clone(),
        })
    }

    /// The instances drawn by the last frame: the ids each list's commands cover (waits).
    pub fn drawn_instances(&self, ctx: &Context) -> Result<Vec<u32>, VkError> {
        let lists = self.read_lists(ctx)?;
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

    fn destroy_all(self, ctx: &Context) {
        // SAFETY: the GPU is idle (caller's guarantee); null handles are ignored.
        unsafe {
            for p in self.pipelines {
                ctx.device.destroy_pipeline(p, None);
            }
            ctx.device
                .destroy_pipeline_layout(self.pipeline_layout, None);
            ctx.device.destroy_descriptor_pool(self.pool, None);
            ctx.device
                .destroy_descriptor_set_layout(self.set_layout, None);
        }
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
                [a, b, s.order, s.groups]
            }))
        {
            ctx.destroy_buffer(b);
        }
    }
}

impl SlotInputs {
    /// Frame slot `slot`'s parameter blocks, order and groups for up to `n` instances.
    fn new(ctx: &Context, slot: u32, n: u64) -> Result<Self, VkError> {
        let uniform = vk::BufferUsageFlags::UNIFORM_BUFFER;
        let storage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let params_size = std::mem::size_of::<CullParams>() as u64;
        let specs = [
            (format!("cull params[{slot}].early"), params_size, uniform),
            (format!("cull params[{slot}].late"), params_size, uniform),
            (format!("cull order[{slot}]"), n * 4, storage),
            // At most one group per instance.
            (format!("cull groups[{slot}]"), n * 16, storage),
        ];
        let mut made = Vec::with_capacity(specs.len());
        for (name, size, usage) in specs {
            match ctx.create_buffer(&name, size, usage, MemoryUse::Streaming) {
                Ok(b) => made.push(b),
                Err(e) => {
                    destroy_buffers(ctx, made);
                    return Err(e);
                }
            }
        }
        match <[Buffer; 4]>::try_from(made) {
            Ok([early, late, order, groups]) => Ok(SlotInputs {
                params: [early, late],
                order,
                groups,
                group_count: [0; 4],
                group_total: 0,
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
}

impl GpuLayout {
    /// The layout of `draws` over `instance_count` instances.
    pub fn of(draws: &DrawList, instance_count: usize) -> Self {
        let mut layout = GpuLayout::default();
        layout.fill(draws, instance_count);
        layout
    }

    /// Refills the layout for `draws`.
    pub fn fill(&mut self, draws: &DrawList, instance_count: usize) {
        let stride = instance_count.max(1) as u32;
        self.order.clear();
        self.order.resize(instance_count, u32::MAX);
        self.groups.clear();
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
