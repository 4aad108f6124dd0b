//! Cascaded shadow maps of the scene's directional light (`Lighting::direction`): fitted on the
//! CPU each frame (`tilegraph_cull::shadow`, a handful of matrices and planes in the frame's
//! uniforms), casters culled on the GPU per cascade, drawn into one depth atlas, sampled with
//! PCF by every shading (forward, pre-pass, visibility buffer).
//!
//! A frame with shadows declares three passes before its geometry:
//! - `shadow-counts` (transfer): zeroes the casters' draw counts (GPU count only);
//! - `shadow-cull` (compute, `shadow_cull.comp`): one thread per instance slot tests each
//!   cascade's caster planes ([`CasterCulling`]) and writes a draw per surviving caster into
//!   its cascade's list of its class (opaque, alpha-tested);
//! - `shadow-cascades` (raster, [`PassClass::Shadow`]): the atlas cleared, each cascade drawn
//!   into its square of it from its lists — one render pass, one depth attachment stored.
//!
//! The shading passes sample the atlas ([`SceneTargets::shadow`]), so the graph orders them
//! after it and puts the barrier between. The atlas is imported (it lives as long as the
//! renderer, bound in set 0 once) and left where the shading samples it.

use ash::vk;
use glam::Mat4;
use tilegraph_cull::shadow::{
    caster_planes, fit_cascades, lookup_reach, lowest_receiver, CascadeSettings, Cascades,
    ShadowCamera, MAX_CASCADES, MAX_CASTER_PLANES,
};
use tilegraph_cull::DepthFormat;
use tilegraph_graph::{
    AccessFlags, BufferId, ClearDepthStencil, ImageDesc, ImageId, Import, InitialContent,
    PassClass, PipelineStages, ResourceState,
};
use tilegraph_profile::{MemoryUse, Profile};
use tilegraph_scene::{Camera, Scene};
use tilegraph_vk::ash;
use tilegraph_vk::executor::{External, Externals, PassContext};
use tilegraph_vk::pipeline::{
    allocate_set, create_compute_pipeline, create_described_pipeline, create_pipeline_layout,
    create_set_layout, write_buffer_set, Blend, DepthState, GraphicsDesc, Stage, VertexLayout,
};
use tilegraph_vk::{Buffer, Context, Feature, VkError};

pub use tilegraph_cull::shadow::CasterCulling;

use crate::cull::{CullState, DrawCount};
use crate::frame::{scene_set, FrameGraph, PassState, Payload, SceneResources};
use crate::gpu_scene::shadow_atlas::{AtlasDesc, ShadowAtlas, SAMPLED};
use crate::gpu_scene::FrameUniforms;
use crate::pipelines::{render_pass_of, PipelineKey};
use crate::spv;

/// A renderer's shadows (knobs `shadow_cascades`, `shadow_resolution`, `shadow_format`,
/// `shadow_culling`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ShadowOptions {
    /// 0: no shadows; 1 to 4 cascades.
    pub cascades: u32,
    /// Texels on a side of each cascade.
    pub resolution: u32,
    /// The atlas's format; `None`: the profile's knob, else D16 on tilers (seed 001: a bin's
    /// size is tile memory over the bytes per pixel, depth included) and D32 elsewhere.
    pub format: Option<DepthFormat>,
    pub culling: CasterCulling,
    /// How far from the eye receivers get shadows, metres; 0: the scene's extent.
    pub distance: f32,
    /// Texels either side of a lookup its filter weighs (knob `shadow_pcf`, 0 to 2).
    pub pcf: u32,
}

impl Default for ShadowOptions {
    fn default() -> Self {
        ShadowOptions {
            cascades: 0,
            resolution: 1024,
            format: None,
            culling: CasterCulling::Receivers,
            distance: 0.0,
            pcf: 1,
        }
    }
}

impl ShadowOptions {
    pub fn enabled(&self) -> bool {
        self.cascades > 0
    }

    /// The atlas these options make on `profile`.
    pub fn atlas(&self, profile: &Profile) -> AtlasDesc {
        let knob = profile
            .knobs
            .get("shadow_format")
            .and_then(|v| v.as_name())
            .and_then(parse_format);
        let default = if profile.is_tiler() {
            DepthFormat::D16Unorm
        } else {
            DepthFormat::D32Float
        };
        AtlasDesc {
            cascades: self.cascades.min(MAX_CASCADES as u32),
            resolution: self.resolution.clamp(64, 4096),
            format: self.format.or(knob).unwrap_or(default),
        }
    }

    /// The cascades' fitting.
    pub fn settings(&self) -> CascadeSettings {
        CascadeSettings {
            count: self.cascades.clamp(1, MAX_CASCADES as u32),
            resolution: self.resolution.clamp(64, 4096),
            distance: f64::from(self.distance),
            pcf_radius: self.pcf.min(2),
            ..CascadeSettings::default()
        }
    }
}

/// `d16` / `d32`.
pub fn parse_format(name: &str) -> Option<DepthFormat> {
    match name {
        "d16" => Some(DepthFormat::D16Unorm),
        "d32" => Some(DepthFormat::D32Float),
        _ => None,
    }
}

/// Fits this frame's cascades to `camera` over `scene` and writes them, with their caster
/// planes, into `uniforms`; the cascades (none without shadows or for a degenerate view).
pub fn write_shadow_uniforms(
    uniforms: &mut FrameUniforms,
    camera: &Camera,
    aspect: f32,
    scene: &Scene,
    to_light: glam::Vec3,
    options: &ShadowOptions,
    atlas: AtlasDesc,
) -> Cascades {
    let forward = (camera.target - camera.eye).normalize_or_zero();
    uniforms.view_forward = forward.as_vec3().extend(0.0).to_array();
    if atlas.cascades == 0 {
        return Cascades::default();
    }
    let view = ShadowCamera {
        eye: camera.eye,
        forward,
        up: camera.up.as_dvec3(),
        projection: camera.projection,
        aspect: f64::from(aspect),
    };
    let bounds = scene.bounds();
    let settings = options.settings();
    let cascades = fit_cascades(
        &view,
        to_light.as_dvec3(),
        (bounds.min, bounds.max),
        &settings,
    );
    let eye = camera.eye;
    let translate = glam::DMat4::from_translation(eye);
    let (cols, rows) = atlas.grid();
    for (i, c) in cascades.as_slice().iter().enumerate() {
        let relative: Mat4 = (c.clip_from_world * translate).as_mat4();
        uniforms.shadow_clip[i] = relative.to_cols_array_2d();
        uniforms.shadow_far[i] = c.far as f32;
        uniforms.shadow_texel[i] = c.texel as f32;
        let planes = caster_planes(&cascades, i, &settings, options.culling).relative_to(eye);
        for (k, p) in planes.as_slice().iter().enumerate() {
            uniforms.caster_planes[i * MAX_CASTER_PLANES + k] = p.as_vec4().to_array();
        }
        uniforms.caster_counts[i] = planes.count as u32;
        if let Some(basis) = cascades.basis {
            let reach = lookup_reach(c, &settings);
            let floor = lowest_receiver(&cascades, i) - reach - basis.l.dot(eye);
            uniforms.caster_floor[i] = floor as f32;
            uniforms.caster_reach[i] = reach as f32;
        }
    }
    let res = settings.resolution as f32;
    uniforms.shadow_params = [settings.normal_offset_texels as f32, res, 1.0 / res, 0.0];
    uniforms.shadow_info = [cascades.count as u32, cols, rows, settings.pcf_radius];
    cascades
}

/// The cascades [`write_shadow_uniforms`] fits for a frame, without the uniforms (tools: the
/// caster oracle, `cullcheck::casters`).
pub fn frame_cascades(
    camera: &Camera,
    aspect: f32,
    scene: &Scene,
    to_light: glam::Vec3,
    options: &ShadowOptions,
    atlas: AtlasDesc,
) -> Cascades {
    let mut uniforms = bytemuck::Zeroable::zeroed();
    write_shadow_uniforms(
        &mut uniforms,
        camera,
        aspect,
        scene,
        to_light,
        options,
        atlas,
    )
}

/// The slope-scaled depth bias of the casters (units of the depth slope): with the normal
/// offset of the lookup, what keeps a lit surface from shadowing itself.
const SLOPE_BIAS: f32 = 2.0;

/// The casters' lists and the pipelines that fill and draw them.
pub struct ShadowState {
    pub atlas: AtlasDesc,
    commands: Buffer,
    counts: Buffer,
    casters: Buffer,
    /// Draw slots per list (one list per cascade and class).
    capacity: u32,
    draw_count: DrawCount,
    /// Instance slots this frame (threads of the culling dispatch).
    instances: u32,
    set_layout: vk::DescriptorSetLayout,
    pool: vk::DescriptorPool,
    set: vk::DescriptorSet,
    cull_layout: vk::PipelineLayout,
    cull_pipeline: vk::Pipeline,
    /// `receivers-hiz`: the culling that also reads the camera's pyramid through the GPU
    /// culling's late-phase set (set 1; the lists move to set 2).
    hiz_layout: vk::PipelineLayout,
    hiz_pipeline: vk::Pipeline,
    draw_layout: vk::PipelineLayout,
    depth_clamp: bool,
}

impl PassState for ShadowState {
    fn destroy(self: Box<Self>, ctx: &Context) {
        (*self).destroy_all(ctx);
    }
}

impl ShadowState {
    /// The lists for `capacity` instance slots and the atlas `atlas`, over the scene's set 0
    /// layout; with `cull_set_layout` (the GPU culling's phase sets), the `receivers-hiz`
    /// culling too.
    pub fn new(
        ctx: &Context,
        scene_set_layout: vk::DescriptorSetLayout,
        cull_set_layout: Option<vk::DescriptorSetLayout>,
        atlas: AtlasDesc,
        capacity: u32,
    ) -> Result<Self, VkError> {
        let lists = u64::from(atlas.cascades.max(1)) * 2;
        let slots = lists * u64::from(capacity.max(1));
        let storage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let indirect = vk::BufferUsageFlags::INDIRECT_BUFFER;
        let gpu = MemoryUse::GpuOnly;
        let commands = ctx.create_buffer("shadow commands", slots * 20, storage | indirect, gpu)?;
        // Host-visible: tools read the casters drawn after the frame.
        let counts_usage = storage | indirect | vk::BufferUsageFlags::TRANSFER_DST;
        let counts = match ctx.create_buffer(
            "shadow counts",
            lists * 4,
            counts_usage,
            MemoryUse::Readback,
        ) {
            Ok(b) => b,
            Err(e) => {
                ctx.destroy_buffer(commands);
                return Err(e);
            }
        };
        // Tools copy the caster ids out after the frame (`read_caster_ids`).
        let casters_usage = storage | vk::BufferUsageFlags::TRANSFER_SRC;
        let casters = match ctx.create_buffer("shadow casters", slots * 4, casters_usage, gpu) {
            Ok(b) => b,
            Err(e) => {
                ctx.destroy_buffer(commands);
                ctx.destroy_buffer(counts);
                return Err(e);
            }
        };
        let mut s = ShadowState {
            atlas,
            commands,
            counts,
            casters,
            capacity: capacity.max(1),
            draw_count: DrawCount::for_device(ctx),
            instances: 0,
            set_layout: vk::DescriptorSetLayout::null(),
            pool: vk::DescriptorPool::null(),
            set: vk::DescriptorSet::null(),
            cull_layout: vk::PipelineLayout::null(),
            cull_pipeline: vk::Pipeline::null(),
            hiz_layout: vk::PipelineLayout::null(),
            hiz_pipeline: vk::Pipeline::null(),
            draw_layout: vk::PipelineLayout::null(),
            depth_clamp: ctx.has_feature(Feature::DepthClamp),
        };
        match s.init(ctx, scene_set_layout, cull_set_layout) {
            Ok(()) => Ok(s),
            Err(e) => {
                s.destroy_all(ctx);
                Err(e)
            }
        }
    }

    fn init(
        &mut self,
        ctx: &Context,
        scene_set_layout: vk::DescriptorSetLayout,
        cull_set_layout: Option<vk::DescriptorSetLayout>,
    ) -> Result<(), VkError> {
        let ssbo = vk::DescriptorType::STORAGE_BUFFER;
        let c = vk::ShaderStageFlags::COMPUTE;
        let cv = c | vk::ShaderStageFlags::VERTEX;
        self.set_layout = create_set_layout(ctx, &[(0, ssbo, c), (1, ssbo, c), (2, ssbo, cv)])?;
        let sizes = [vk::DescriptorPoolSize {
            ty: ssbo,
            descriptor_count: 3,
        }];
        let info = vk::DescriptorPoolCreateInfo::default()
            .max_sets(1)
            .pool_sizes(&sizes);
        // SAFETY: valid create info.
        self.pool = unsafe { ctx.device.create_descriptor_pool(&info, None) }
            .map_err(|r| VkError::call("vkCreateDescriptorPool", r))?;
        self.set = allocate_set(ctx, self.pool, self.set_layout)?;
        write_buffer_set(
            ctx,
            self.set,
            &[
                (0, ssbo, self.commands.raw),
                (1, ssbo, self.counts.raw),
                (2, ssbo, self.casters.raw),
            ],
        );
        let sets = [scene_set_layout, self.set_layout];
        let push = |stage, size| vk::PushConstantRange {
            stage_flags: stage,
            offset: 0,
            size,
        };
        self.cull_layout = create_pipeline_layout(ctx, &sets, Some(push(c, 12)))?;
        self.draw_layout =
            create_pipeline_layout(ctx, &sets, Some(push(vk::ShaderStageFlags::VERTEX, 4)))?;
        self.cull_pipeline = create_compute_pipeline(
            ctx,
            &Stage {
                name: "shadow_cull.comp",
                spirv: spv::SHADOW_CULL_CS,
                specialization: &[],
            },
            self.cull_layout,
        )?;
        if let Some(cull) = cull_set_layout {
            let sets = [scene_set_layout, cull, self.set_layout];
            self.hiz_layout = create_pipeline_layout(ctx, &sets, Some(push(c, 12)))?;
            self.hiz_pipeline = create_compute_pipeline(
                ctx,
                &Stage {
                    name: "shadow_cull_hiz.comp",
                    spirv: spv::SHADOW_CULL_HIZ_CS,
                    specialization: &[],
                },
                self.hiz_layout,
            )?;
        }
        Ok(())
    }

    fn destroy_all(self, ctx: &Context) {
        // SAFETY: the GPU is idle (caller's guarantee); null handles are ignored.
        unsafe {
            ctx.device.destroy_pipeline(self.cull_pipeline, None);
            ctx.device.destroy_pipeline_layout(self.cull_layout, None);
            ctx.device.destroy_pipeline(self.hiz_pipeline, None);
            ctx.device.destroy_pipeline_layout(self.hiz_layout, None);
            ctx.device.destroy_pipeline_layout(self.draw_layout, None);
            ctx.device.destroy_descriptor_pool(self.pool, None);
            ctx.device
                .destroy_descriptor_set_layout(self.set_layout, None);
        }
        for b in [self.commands, self.counts, self.casters] {
            ctx.destroy_buffer(b);
        }
    }

    /// The instance slots this frame's culling covers.
    pub fn set_instances(&mut self, instances: u32) {
        self.instances = instances.min(self.capacity);
    }

    /// Casters drawn into each cascade by the last completed frame (opaque plus alpha-tested;
    /// GPU count only, read after the frames in flight are done).
    pub fn casters_drawn(&self) -> Option<[u32; MAX_CASCADES]> {
        let counts = self.list_counts()?;
        let mut out = [0; MAX_CASCADES];
        for (c, pair) in counts.chunks_exact(2).enumerate().take(MAX_CASCADES) {
            out[c] = pair[0] + pair[1];
        }
        Some(out)
    }

    /// The casters (instance ids, sorted) the last completed frame drew into each cascade:
    /// opaque and alpha-tested lists together. GPU count only; copies the lists out (waits
    /// for the GPU: tools).
    pub fn read_caster_ids(&self, ctx: &Context) -> Result<Option<Vec<Vec<u32>>>, VkError> {
        let Some(counts) = self.list_counts() else {
            return Ok(None);
        };
        let bytes = tilegraph_vk::readback::read_buffer(ctx, CullState::handle(&self.casters))?;
        let word = |k: usize| {
            bytes
                .get(k * 4..k * 4 + 4)
                .map_or(u32::MAX, |w| u32::from_le_bytes([w[0], w[1], w[2], w[3]]))
        };
        let capacity = self.capacity as usize;
        let cascades = self.atlas.cascades as usize;
        let mut out = vec![Vec::new(); cascades];
        for (list, &count) in counts.iter().enumerate().take(cascades * 2) {
            let ids = &mut out[list / 2];
            let start = list * capacity;
            ids.extend((start..start + (count as usize).min(capacity)).map(word));
        }
        for ids in &mut out {
            ids.sort_unstable();
            ids.dedup();
        }
        Ok(Some(out))
    }

    /// The draws in each list (cascade * 2 + class) of the last completed frame (GPU count).
    fn list_counts(&self) -> Option<Vec<u32>> {
        if !matches!(self.draw_count, DrawCount::Gpu) {
            return None;
        }
        let bytes = self.counts.mapped()?;
        let lists = self.atlas.cascades as usize * 2;
        Some(
            (0..lists)
                .map(|k| {
                    bytes
                        .get(k * 4..k * 4 + 4)
                        .map_or(0, |w| u32::from_le_bytes([w[0], w[1], w[2], w[3]]))
                })
                .collect(),
        )
    }

    /// Whether `receivers-hiz` can run here (the GPU culling's sets were there to build on).
    pub fn has_hiz(&self) -> bool {
        self.hiz_pipeline != vk::Pipeline::null()
    }

    /// Records the culling; with `cull_set` (the GPU culling's late-phase set of this slot)
    /// against the camera's pyramid too.
    fn record_cull(
        &self,
        pc: &PassContext<'_>,
        set0: vk::DescriptorSet,
        cull_set: Option<vk::DescriptorSet>,
    ) {
        if self.instances == 0 {
            return;
        }
        let fixed = u32::from(!matches!(self.draw_count, DrawCount::Gpu));
        let push = [self.instances, self.capacity, fixed];
        let (pipeline, layout) = match cull_set {
            Some(_) => (self.hiz_pipeline, self.hiz_layout),
            None => (self.cull_pipeline, self.cull_layout),
        };
        let with_pyramid = cull_set.map(|c| [set0, c, self.set]);
        let plain = [set0, self.set];
        let sets: &[vk::DescriptorSet] = match &with_pyramid {
            Some(s) => s,
            None => &plain,
        };
        let d = &pc.ctx.device;
        // SAFETY: recording outside a render pass; pipeline, layout and sets are live.
        unsafe {
            d.cmd_bind_pipeline(pc.cb, vk::PipelineBindPoint::COMPUTE, pipeline);
            d.cmd_bind_descriptor_sets(pc.cb, vk::PipelineBindPoint::COMPUTE, layout, 0, sets, &[]);
            d.cmd_push_constants(
                pc.cb,
                layout,
                vk::ShaderStageFlags::COMPUTE,
                0,
                bytemuck::cast_slice(&push),
            );
            d.cmd_dispatch(pc.cb, self.instances.div_ceil(64), 1, 1);
        }
    }

    /// Draws list `list` (cascade * 2 + class).
    fn record_list(&self, pc: &PassContext<'_>, list: u32) {
        let offset = u64::from(list) * u64::from(self.capacity) * 20;
        let d = &pc.ctx.device;
        // SAFETY (all three): inside the render pass with a pipeline, vertex/index buffers and
        // sets bound; list `list` holds `capacity` commands of 20 bytes from `offset`, the
        // first `instances` (fixed) or the counted ones (GPU) written by the culling this frame.
        match self.draw_count {
            DrawCount::Gpu => unsafe {
                d.cmd_draw_indexed_indirect_count(
                    pc.cb,
                    self.commands.raw,
                    offset,
                    self.counts.raw,
                    u64::from(list) * 4,
                    self.capacity,
                    20,
                );
            },
            DrawCount::Fixed { multi_draw: true } => unsafe {
                d.cmd_draw_indexed_indirect(pc.cb, self.commands.raw, offset, self.instances, 20);
            },
            DrawCount::Fixed { multi_draw: false } => {
                for k in 0..u64::from(self.instances) {
                    unsafe {
                        d.cmd_draw_indexed_indirect(
                            pc.cb,
                            self.commands.raw,
                            offset + 20 * k,
                            1,
                            20,
                        )
                    };
                }
            }
        }
    }
}

/// The shadow resources of one frame's graph.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ShadowIds {
    pub atlas: ImageId,
    commands: BufferId,
    counts: BufferId,
    casters: BufferId,
    gpu_count: bool,
}

/// Imports the atlas and the casters' lists into the frame's graph.
pub fn import_shadows(
    g: &mut FrameGraph,
    externals: &mut Externals,
    res_atlas: &ShadowAtlas,
    state: &ShadowState,
) -> ShadowIds {
    let desc = state.atlas;
    let (w, h) = desc.extent();
    let format = match desc.format {
        DepthFormat::D16Unorm => tilegraph_graph::Format::D16_UNORM,
        DepthFormat::D32Float => tilegraph_graph::Format::D32_SFLOAT,
    };
    let atlas = g.import_image(
        "shadow-atlas",
        ImageDesc::new(tilegraph_graph::Extent2d::new(w, h), format),
        Import {
            initial: SAMPLED,
            content: InitialContent::Discard,
            final_state: SAMPLED,
        },
    );
    g.export(atlas);
    externals.insert(atlas, External::Image(res_atlas.handle().clone()));
    // Whatever touched them last frame, this frame waits for.
    let any = ResourceState::buffer(
        PipelineStages::EVERY_GRAPH_STAGE,
        AccessFlags::MEMORY_READ.union(AccessFlags::MEMORY_WRITE),
    );
    let discard = Import {
        initial: any,
        content: InitialContent::Discard,
        final_state: any,
    };
    let mut buffer = |name: &str, b: &Buffer| {
        let id = g.import_buffer(name, b.size, discard);
        externals.insert(id, External::Buffer(CullState::handle(b)));
        id
    };
    let ids = ShadowIds {
        atlas,
        commands: buffer("shadow-commands", &state.commands),
        counts: buffer("shadow-counts", &state.counts),
        casters: buffer("shadow-casters", &state.casters),
        gpu_count: matches!(state.draw_count, DrawCount::Gpu),
    };
    // Tools read the counts after the frame (written where the GPU counts).
    if ids.gpu_count {
        g.export(ids.counts);
    }
    ids
}

/// Declares the casters' culling: the counts zeroed (GPU count), then `shadow_cull.comp` —
/// or, given this frame's camera pyramid (`receivers-hiz`), `shadow_cull_hiz.comp`.
pub fn add_shadow_culling(g: &mut FrameGraph, ids: ShadowIds, pyramid: Option<BufferId>) {
    if ids.gpu_count {
        let counts = ids.counts;
        let clear: Payload = Box::new(move |pc, res| {
            let state = res.states.require::<ShadowState>(pc.pass_name)?;
            // SAFETY: recording outside a render pass; the buffer is live, its size a
            // multiple of 4.
            unsafe {
                pc.ctx
                    .device
                    .cmd_fill_buffer(pc.cb, state.counts.raw, 0, vk::WHOLE_SIZE, 0)
            };
            Ok(())
        });
        g.transfer_pass("shadow-counts", PassClass::Compute, clear)
            .transfer_dst(counts)
            .async_compute();
    }
    let with_pyramid = pyramid.is_some();
    let cull: Payload = Box::new(move |pc, res| {
        let set0 = scene_set(pc, res)?;
        let cull_set = if with_pyramid {
            let late = res
                .states
                .require::<CullState>(pc.pass_name)?
                .phase_set(pc.frame_slot, 1);
            Some(late.ok_or_else(|| VkError::Invalid {
                what: pc.pass_name.into(),
                reason: format!("no culling set for frame slot {}", pc.frame_slot),
            })?)
        } else {
            None
        };
        let state = res.states.require::<ShadowState>(pc.pass_name)?;
        state.record_cull(pc, set0, cull_set);
        Ok(())
    });
    // It reads the scene and writes only its lists: it may run on the async compute queue.
    let mut p = g.compute_pass("shadow-cull", PassClass::Compute, cull);
    p.async_compute()
        .storage_write(ids.commands)
        .storage_write(ids.casters);
    if ids.gpu_count {
        p.storage_read_write(ids.counts);
    }
    if let Some(pyramid) = pyramid {
        p.storage_read(pyramid);
    }
}

/// Declares the cascades' depth: the atlas cleared, every cascade drawn into its square from
/// its lists.
pub fn add_shadow_maps(g: &mut FrameGraph, ids: ShadowIds) {
    let record: Payload = Box::new(record_cascades);
    let mut p = g.raster_pass("shadow-cascades", PassClass::Shadow, record);
    // Standard depth: 0 at the light, cleared to the far end.
    p.depth_stencil_clear(
        ids.atlas,
        ClearDepthStencil {
            depth: 1.0,
            stencil: 0,
        },
    );
    p.indirect(ids.commands).storage_read(ids.casters);
    if ids.gpu_count {
        p.indirect(ids.counts);
    }
}

fn record_cascades(pc: &mut PassContext<'_>, res: &mut SceneResources) -> Result<(), VkError> {
    let set0 = scene_set(pc, res)?;
    let SceneResources {
        scene,
        pipelines,
        states,
        ..
    } = res;
    let state = states.require::<ShadowState>(pc.pass_name)?;
    let alpha_fs = pipelines.depth_alpha_fragment();
    let slots = [(1, pipelines.texture_slots())];
    let d = &pc.ctx.device;
    // SAFETY: recording inside the pass's subpass; buffers and sets are live.
    unsafe {
        d.cmd_bind_vertex_buffers(pc.cb, 0, &[scene.vertices.raw], &[0]);
        d.cmd_bind_index_buffer(pc.cb, scene.indices.raw, 0, vk::IndexType::UINT32);
        d.cmd_bind_descriptor_sets(
            pc.cb,
            vk::PipelineBindPoint::GRAPHICS,
            state.draw_layout,
            0,
            &[set0, state.set],
            &[],
        );
    }
    let res_side = state.atlas.resolution;
    for alpha in [false, true] {
        let key = PipelineKey::Named(if alpha {
            "shadow-alpha"
        } else {
            "shadow-opaque"
        });
        let pipeline = pipelines.get_or_create(pc, key, |target| {
            let (vertex, fragment, attributes): (_, _, &[(u32, vk::Format, u32)]) = if alpha {
                (
                    stage("shadow_alpha.vert", spv::SHADOW_ALPHA_VS, &[]),
                    Some(stage(alpha_fs.0, alpha_fs.1, &slots)),
                    &[POSITION, UV],
                )
            } else {
                (stage("shadow.vert", spv::SHADOW_VS, &[]), None, &[POSITION])
            };
            create_described_pipeline(
                pc.ctx,
                &GraphicsDesc {
                    name: pc.pass_name,
                    vertex,
                    fragment,
                    vertex_layout: Some(VertexLayout {
                        stride: 32,
                        attributes,
                    }),
                    layout: state.draw_layout,
                    target,
                    depth: DepthState {
                        test: true,
                        write: true,
                        compare: vk::CompareOp::LESS_OR_EQUAL,
                        bias: 1,
                        slope_bias: SLOPE_BIAS,
                        clamp: state.depth_clamp,
                    },
                    blend: Blend::NoColorWrites,
                    // Both faces: open meshes and single-sided walls still cast.
                    cull: vk::CullModeFlags::NONE,
                    samples: vk::SampleCountFlags::TYPE_1,
                },
            )
        })?;
        let _ = render_pass_of(pc)?;
        // SAFETY: inside the render pass; the pipeline is live.
        unsafe { d.cmd_bind_pipeline(pc.cb, vk::PipelineBindPoint::GRAPHICS, pipeline) };
        for c in 0..state.atlas.cascades {
            let (x, y) = state.atlas.offset(c);
            let viewport = vk::Viewport {
                x: x as f32,
                y: y as f32,
                width: res_side as f32,
                height: res_side as f32,
                min_depth: 0.0,
                max_depth: 1.0,
            };
            let scissor = vk::Rect2D {
                offset: vk::Offset2D {
                    x: x as i32,
                    y: y as i32,
                },
                extent: vk::Extent2D {
                    width: res_side,
                    height: res_side,
                },
            };
            // SAFETY: dynamic viewport and scissor inside the atlas; push range of the layout.
            unsafe {
                d.cmd_set_viewport(pc.cb, 0, &[viewport]);
                d.cmd_set_scissor(pc.cb, 0, &[scissor]);
                d.cmd_push_constants(
                    pc.cb,
                    state.draw_layout,
                    vk::ShaderStageFlags::VERTEX,
                    0,
                    &c.to_le_bytes(),
                );
            }
            state.record_list(pc, c * 2 + u32::from(alpha));
        }
    }
    Ok(())
}

const POSITION: (u32, vk::Format, u32) = (0, vk::Format::R32G32B32_SFLOAT, 0);
const UV: (u32, vk::Format, u32) = (2, vk::Format::R32G32_SFLOAT, 24);

fn stage<'a>(name: &'a str, spirv: &'a [u8], specialization: &'a [(u32, u32)]) -> Stage<'a> {
    Stage {
        name,
        spirv,
        specialization,
    }
}
