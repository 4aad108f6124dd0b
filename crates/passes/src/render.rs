//! Rendering a scene: the frame setup's passes declared on a graph, compiled for the profile,
//! executed by `tilegraph-vk`.
//!
//! Pass by pass (seed 003 for the pre-pass recipe, seed 001 for the order):
//! - `depth-prepass`: positions only, no fragment shader, depth writes on;
//! - `depth-prepass-alpha`: alpha-tested geometry with its discard, depth writes on;
//! - `opaque` / `alpha-tested`: colour; after a pre-pass depth compares EQUAL with writes off;
//! - `visbuf-write` + `visbuf-resolve`: ids, then shading per pixel (input attachment on tilers);
//! - `transparent`: blended back to front, depth tested, not written.
//!
//! The graph merges them into subpasses of one render pass where the profile says so, so depth
//! (and ids) never leave tile memory.

use std::cell::RefCell;
use std::collections::HashMap;
use std::rc::Rc;
use std::sync::Arc;

use ash::vk;
use tilegraph_cull::NpotMode;
use tilegraph_graph::BufferId;
use tilegraph_graph::{
    AccessFlags, ClearColor, ClearDepthStencil, Coverage, Extent2d, Format, GraphBuilder,
    GraphError, ImageDesc, ImageId, Import, InitialContent, Layout, PassClass, PipelineStages,
    Plan, ResourceState,
};
use tilegraph_profile::{MemoryUse, Profile};
use tilegraph_scene::{Camera, CameraFrame, DepthConvention, Scene};
use tilegraph_vk::ash;
use tilegraph_vk::executor::{Executor, External, Externals, FrameStats, ImageHandle, PassContext};
use tilegraph_vk::first_frame::RgbaImage;
use tilegraph_vk::pipeline::{
    allocate_set, create_graphics_pipeline, create_pipeline_layout, create_set_layout, Blend,
    DepthState, GraphicsDesc, RenderTarget, Stage, VertexLayout,
};
use tilegraph_vk::queries::PassMedian;
use tilegraph_vk::{Context, Image, VkError};

use crate::cull::{gpu_planes, list_index, CullParams, CullState, Culling, Phase};
use crate::draws::{self, Draw, DrawList};
use crate::gpu_scene::{visbuf_instance_bits, FrameUniforms, GpuScene, Lighting};
use crate::pipelines::{render_pass_of, PipelineCache};
use crate::setup::{decide, FrameSetup, PassKind, SceneContent, Technique};

/// Errors of rendering a scene: each names what failed.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    #[error(transparent)]
    Vk(#[from] VkError),
    #[error("compiling the frame graph: {0}")]
    Graph(#[from] GraphError),
    #[error("visibility buffer: {instances} instances and meshes of up to {max_triangles} triangles do not fit a 32-bit id")]
    VisbufIdOverflow {
        instances: usize,
        max_triangles: u32,
    },
    #[error("technique {technique} needs device feature {feature}, which {device:?} does not have (or it was not requested)")]
    MissingFeature {
        technique: &'static str,
        feature: tilegraph_vk::Feature,
        device: String,
    },
    #[error("culling {culling} needs {extension}, which {device:?} does not have (or it was not requested)")]
    MissingExtension {
        culling: &'static str,
        extension: &'static str,
        device: String,
    },
    #[error("culling {culling} does not support the {technique} technique (it needs a depth pre-pass before colour)")]
    UnsupportedCulling {
        culling: &'static str,
        technique: &'static str,
    },
    #[error("invalid render size {width}x{height}")]
    Size { width: u32, height: u32 },
}

/// How to render.
#[derive(Debug, Clone, PartialEq)]
pub struct RenderOptions {
    pub technique: Technique,
    pub width: u32,
    pub height: u32,
    pub lighting: Lighting,
    pub clear_color: [f32; 4],
    /// Count the fragments each colour pass shades (an atomic per fragment; needs
    /// `fragmentStoresAndAtomics`). For measurement runs, not for shipping frames.
    pub count_fragments: bool,
    /// Overrides the profile's opaque draw order (measurements: `BackToFront` is the worst
    /// case for early depth rejection).
    pub opaque_order: Option<tilegraph_profile::SortOrder>,
    /// GPU culling before drawing (opaque and alpha-tested instances; blended ones are frustum
    /// culled on the CPU and sorted back to front).
    pub culling: Culling,
    /// How the HiZ pyramid handles non-power-of-two sizes (seed 000's two fixes).
    pub hiz_mode: NpotMode,
    /// Keep the visibility buffer's ids after the frame (the oracle reads them back):
    /// the id attachment becomes an imported image, so it is stored.
    pub capture_ids: bool,
    /// Occlusion queries: instances per query (groups of nearby instances share one box).
    pub oq_group: usize,
    /// Raster occlusion: 1 tests boxes at full resolution; 2 or 4 test screen rectangles
    /// against a conservative (farthest-depth) 1/2 or 1/4 resolution depth.
    pub raster_occlusion_scale: u32,
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            technique: Technique::Forward,
            width: 320,
            height: 180,
            lighting: Lighting::default(),
            clear_color: [0.55, 0.65, 0.78, 1.0],
            count_fragments: false,
            opaque_order: None,
            culling: Culling::None,
            hiz_mode: NpotMode::EdgeAware,
            capture_ids: false,
            oq_group: 1,
            raster_occlusion_scale: 1,
        }
    }
}

/// What one frame did.
#[derive(Debug, Clone)]
pub struct FrameReport {
    pub setup: FrameSetup,
    pub plan: Arc<Plan>,
    pub stats: FrameStats,
    pub draws: usize,
    pub triangles: u64,
}

mod spv {
    pub const DEPTH_VS: &[u8] = include_bytes!("../../../shaders/spv/depth.vert.spv");
    pub const DEPTH_ALPHA_VS: &[u8] = include_bytes!("../../../shaders/spv/depth_alpha.vert.spv");
    pub const DEPTH_ALPHA_FS: &[u8] = include_bytes!("../../../shaders/spv/depth_alpha.frag.spv");
    pub const FORWARD_VS: &[u8] = include_bytes!("../../../shaders/spv/forward.vert.spv");
    pub const FORWARD_FS: &[u8] = include_bytes!("../../../shaders/spv/forward.frag.spv");
    pub const FORWARD_EARLY_FS: &[u8] =
        include_bytes!("../../../shaders/spv/forward_early.frag.spv");
    pub const FORWARD_COUNT_FS: &[u8] =
        include_bytes!("../../../shaders/spv/forward_count.frag.spv");
    pub const FORWARD_COUNT_LATE_FS: &[u8] =
        include_bytes!("../../../shaders/spv/forward_count_late.frag.spv");
    pub const VISBUF_VS: &[u8] = include_bytes!("../../../shaders/spv/visbuf.vert.spv");
    pub const VISBUF_FS: &[u8] = include_bytes!("../../../shaders/spv/visbuf.frag.spv");
    pub const FULLSCREEN_VS: &[u8] = include_bytes!("../../../shaders/spv/fullscreen.vert.spv");
    pub const RESOLVE_INPUT_FS: &[u8] =
        include_bytes!("../../../shaders/spv/visbuf_resolve_input.frag.spv");
    pub const RESOLVE_SAMPLED_FS: &[u8] =
        include_bytes!("../../../shaders/spv/visbuf_resolve_sampled.frag.spv");
}

/// Pipeline variants of the scene passes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
enum Variant {
    DepthOpaque,
    DepthAlpha,
    /// Forward colour; `class` 0 opaque, 1 alpha-tested, 2 blended; `equal` after a pre-pass.
    Forward {
        class: u32,
        equal: bool,
    },
    Visbuf {
        alpha: bool,
    },
    ResolveInput,
    ResolveSampled,
}

const POSITION: (u32, vk::Format, u32) = (0, vk::Format::R32G32B32_SFLOAT, 0);
const NORMAL: (u32, vk::Format, u32) = (1, vk::Format::R32G32B32_SFLOAT, 12);
const UV: (u32, vk::Format, u32) = (2, vk::Format::R32G32_SFLOAT, 24);
const VERTEX_STRIDE: u32 = 32;

/// Shared by every payload of a frame: pipelines per (render pass, subpass, variant), the
/// per-frame-slot descriptor sets, and this frame's draw list.
struct Shared {
    scene_layout: vk::PipelineLayout,
    input_set_layout: vk::DescriptorSetLayout,
    sampled_set_layout: vk::DescriptorSetLayout,
    input_layout: vk::PipelineLayout,
    sampled_layout: vk::PipelineLayout,
    pool: vk::DescriptorPool,
    sampler: vk::Sampler,
    /// By (render pass, subpass, variant, double-sided, reverse-Z): the depth compare is baked
    /// in, and a camera may change the convention.
    pipelines: PipelineCache<(Variant, bool, bool)>,
    /// Pipelines of render passes with serials below this are destroyed.
    pruned_below: u64,
    resolve_sets: HashMap<(usize, bool), vk::DescriptorSet>,
    scene_sets: Vec<vk::DescriptorSet>,
    vertex_buffer: vk::Buffer,
    index_buffer: vk::Buffer,
    draws: DrawList,
    depth: DepthConvention,
    count_fragments: bool,
    cull: Option<CullState>,
    culled_sets: Vec<vk::DescriptorSet>,
    oq: Option<crate::occlusion::OqState>,
    raster: Option<crate::occlusion::RasterOcclusion>,
}

/// Graph handles of the culling buffers in this frame's graph.
#[derive(Debug, Clone, Copy)]
struct CullBuffers {
    commands: BufferId,
    counts: BufferId,
    draw_ids: BufferId,
    visibility: BufferId,
    pyramid: Option<BufferId>,
}

/// What has been declared so far in a frame (first uses clear).
struct Declared {
    target: ImageId,
    depth: ImageId,
    ids: Option<ImageId>,
    depth_clear: ClearDepthStencil,
    color_clear: ClearColor,
    color_cleared: bool,
    depth_cleared: bool,
    /// By material class (opaque, alpha-tested): whether a depth pre-pass wrote its depth, so
    /// its colour pass tests EQUAL without writing ([`FrameSetup::prepassed`]).
    prepassed: [bool; 2],
    gpu: Option<CullBuffers>,
    /// Conditional occlusion queries: the results buffer the colour passes are predicated on,
    /// once the query pass is declared.
    conditions: Option<BufferId>,
    /// Raster occlusion: flags and culling declared (before the first colour pass).
    flags_declared: bool,
}

impl Shared {
    /// Destroys the pipelines made for render passes older than `floor` (once per floor).
    fn prune_pipelines(&mut self, ctx: &Context, floor: u64) {
        if floor <= self.pruned_below {
            return;
        }
        self.pruned_below = floor;
        self.pipelines.prune(ctx, floor);
        if let Some(o) = self.oq.as_mut() {
            o.prune_pipelines(ctx, floor);
        }
        if let Some(r) = self.raster.as_mut() {
            r.prune_pipelines(ctx, floor);
        }
    }

    fn pipeline_count(&self) -> usize {
        self.pipelines.len()
            + self.oq.as_ref().map_or(0, |o| o.pipeline_count())
            + self.raster.as_ref().map_or(0, |r| r.pipeline_count())
    }

    fn compare(&self) -> vk::CompareOp {
        match self.depth {
            DepthConvention::Reverse => vk::CompareOp::GREATER,
            DepthConvention::Standard => vk::CompareOp::LESS,
        }
    }

    fn pipeline(
        &mut self,
        pc: &PassContext<'_>,
        variant: Variant,
        double_sided: bool,
        color_count: u32,
    ) -> Result<vk::Pipeline, VkError> {
        let rp = render_pass_of(pc, "scene passes")?;
        let key = (
            variant,
            double_sided,
            self.depth == DepthConvention::Reverse,
        );
        if let Some(p) = self.pipelines.get(rp, key) {
            return Ok(p);
        }
        let write = DepthState {
            test: true,
            write: true,
            compare: self.compare(),
        };
        let stage = |name, spirv| Stage {
            name,
            spirv,
            specialization: &[],
        };
        let pos_only = [POSITION];
        let pos_uv = [POSITION, UV];
        let all = [POSITION, NORMAL, UV];
        let class_spec: [(u32, u32); 1];
        let (vs, fs, attrs, depth, blend, layout): VariantState = match variant {
            Variant::DepthOpaque => (
                stage("depth.vert", spv::DEPTH_VS),
                None,
                &pos_only,
                write,
                Blend::NoColorWrites,
                self.scene_layout,
            ),
            Variant::DepthAlpha => (
                stage("depth_alpha.vert", spv::DEPTH_ALPHA_VS),
                Some(stage("depth_alpha.frag", spv::DEPTH_ALPHA_FS)),
                &pos_uv,
                write,
                Blend::NoColorWrites,
                self.scene_layout,
            ),
            Variant::Forward { class, equal } => {
                class_spec = [(0, class)];
                let depth = match (class, equal) {
                    (2, _) => DepthState {
                        test: true,
                        write: false,
                        compare: self.compare(),
                    },
                    (_, true) => DepthState {
                        test: true,
                        write: false,
                        compare: vk::CompareOp::EQUAL,
                    },
                    _ => write,
                };
                let blend = if class == 2 {
                    Blend::Alpha
                } else {
                    Blend::Opaque
                };
                // Early fragment tests unless a discard decides what depth is written (alpha
                // tested without a pre-pass): seed 003, discard disables early-Z.
                let (fs_name, fs) = match (class == 1 && !equal, self.count_fragments) {
                    (true, true) => ("forward_count_late.frag", spv::FORWARD_COUNT_LATE_FS),
                    (true, false) => ("forward.frag", spv::FORWARD_FS),
                    (false, true) => ("forward_count.frag", spv::FORWARD_COUNT_FS),
                    (false, false) => ("forward_early.frag", spv::FORWARD_EARLY_FS),
                };
                (
                    stage("forward.vert", spv::FORWARD_VS),
                    Some(Stage {
                        name: fs_name,
                        spirv: fs,
                        specialization: &class_spec,
                    }),
                    &all,
                    depth,
                    blend,
                    self.scene_layout,
                )
            }
            Variant::Visbuf { alpha } => {
                class_spec = [(0, u32::from(alpha))];
                (
                    stage("visbuf.vert", spv::VISBUF_VS),
                    Some(Stage {
                        name: "visbuf.frag",
                        spirv: spv::VISBUF_FS,
                        specialization: &class_spec,
                    }),
                    &pos_uv,
                    write,
                    Blend::Opaque,
                    self.scene_layout,
                )
            }
            Variant::ResolveInput => (
                stage("fullscreen.vert", spv::FULLSCREEN_VS),
                Some(stage("visbuf_resolve_input.frag", spv::RESOLVE_INPUT_FS)),
                &[],
                DepthState::OFF,
                Blend::Opaque,
                self.input_layout,
            ),
            Variant::ResolveSampled => (
                stage("fullscreen.vert", spv::FULLSCREEN_VS),
                Some(stage(
                    "visbuf_resolve_sampled.frag",
                    spv::RESOLVE_SAMPLED_FS,
                )),
                &[],
                DepthState::OFF,
                Blend::Opaque,
                self.sampled_layout,
            ),
        };
        let vertex_layout = (!attrs.is_empty()).then_some(VertexLayout {
            stride: VERTEX_STRIDE,
            attributes: attrs,
        });
        let fullscreen = matches!(variant, Variant::ResolveInput | Variant::ResolveSampled);
        let p = create_graphics_pipeline(
            pc.ctx,
            &GraphicsDesc {
                name: pc.pass_name,
                vertex: vs,
                fragment: fs,
                vertex_layout,
                layout,
                target: RenderTarget::Subpass {
                    render_pass: rp.handle,
                    subpass: rp.subpass,
                    color_count,
                },
                depth,
                blend,
                cull: if double_sided || fullscreen {
                    vk::CullModeFlags::NONE
                } else {
                    vk::CullModeFlags::BACK
                },
                samples: vk::SampleCountFlags::TYPE_1,
            },
        )?;
        self.pipelines.insert(rp, key, p);
        Ok(p)
    }

    /// Set 0 of a frame slot (the plain one), or an error naming who asked.
    fn scene_set(&self, slot: usize, what: &str) -> Result<vk::DescriptorSet, VkError> {
        self.scene_sets
            .get(slot)
            .copied()
            .ok_or_else(|| VkError::Invalid {
                what: what.to_string(),
                reason: format!("no scene set for frame slot {slot}"),
            })
    }

    /// Binds the scene's vertex and index buffers and set 0 (the culled variant reads the culling
    /// shader's draw list), and sets the viewport.
    fn bind_geometry(&self, pc: &PassContext<'_>, culled: bool) -> Result<(), VkError> {
        let sets = if culled {
            &self.culled_sets
        } else {
            &self.scene_sets
        };
        let set = *sets.get(pc.frame_slot).ok_or_else(|| VkError::Invalid {
            what: "scene".into(),
            reason: format!(
                "no {}descriptor set for frame slot {}",
                if culled { "culled " } else { "" },
                pc.frame_slot
            ),
        })?;
        pc.set_full_viewport();
        let d = &pc.ctx.device;
        // SAFETY: recording inside a subpass; buffers and set are live.
        unsafe {
            d.cmd_bind_vertex_buffers(pc.cb, 0, &[self.vertex_buffer], &[0]);
            d.cmd_bind_index_buffer(pc.cb, self.index_buffer, 0, vk::IndexType::UINT32);
            d.cmd_bind_descriptor_sets(
                pc.cb,
                vk::PipelineBindPoint::GRAPHICS,
                self.scene_layout,
                0,
                &[set],
                &[],
            );
        }
        Ok(())
    }

    /// Binds the scene and records `draws` with `variant` (two pipelines: single- and
    /// double-sided).
    fn record_draws(
        &mut self,
        pc: &PassContext<'_>,
        variant: Variant,
        draws: &[Draw],
        color_count: u32,
    ) -> Result<(), VkError> {
        if draws.is_empty() {
            return Ok(());
        }
        self.bind_geometry(pc, false)?;
        if matches!(variant, Variant::Forward { class: 0 | 1, .. }) {
            if let Some(conditions) = self.oq.as_ref().and_then(|o| o.conditions.as_ref()) {
                let raw = conditions.raw;
                return self.record_conditional(pc, variant, draws, color_count, raw);
            }
        }
        let d = &pc.ctx.device;
        // Blended draws keep their back-to-front order, switching pipelines where the
        // sidedness changes. Opaque and alpha-tested ones are grouped by pipeline (their order
        // only helps early-Z).
        let in_order = matches!(variant, Variant::Forward { class: 2, .. });
        let groups: &[Option<bool>] = if in_order {
            &[None]
        } else {
            &[Some(false), Some(true)]
        };
        for &group in groups {
            let mut bound: Option<bool> = None;
            for draw in draws
                .iter()
                .filter(|d| group.is_none_or(|sided| d.double_sided == sided))
            {
                if bound != Some(draw.double_sided) {
                    let p = self.pipeline(pc, variant, draw.double_sided, color_count)?;
                    // SAFETY: as above.
                    unsafe { d.cmd_bind_pipeline(pc.cb, vk::PipelineBindPoint::GRAPHICS, p) };
                    bound = Some(draw.double_sided);
                }
                // SAFETY: the draw's ranges lie inside the scene's buffers (built from the scene).
                unsafe {
                    d.cmd_draw_indexed(
                        pc.cb,
                        draw.index_count,
                        draw.instance_count,
                        draw.first_index,
                        draw.vertex_offset,
                        draw.first_instance,
                    )
                };
            }
        }
        Ok(())
    }

    /// Records `draws` one instance at a time, each predicated on its occlusion query's result
    /// (instances the frame did not query are drawn unconditionally). Same order as the
    /// instanced draws, so the image equals the unculled one.
    fn record_conditional(
        &mut self,
        pc: &PassContext<'_>,
        variant: Variant,
        draws: &[Draw],
        color_count: u32,
        conditions: vk::Buffer,
    ) -> Result<(), VkError> {
        let cond = pc
            .ctx
            .conditional_rendering()
            .ok_or_else(|| VkError::Invalid {
                what: pc.pass_name.into(),
                reason: "VK_EXT_conditional_rendering is not enabled".into(),
            })?;
        let d = &pc.ctx.device;
        for sided in [false, true] {
            let mut bound = false;
            for draw in draws.iter().filter(|d| d.double_sided == sided) {
                if !bound {
                    let p = self.pipeline(pc, variant, sided, color_count)?;
                    // SAFETY: inside the subpass; the pipeline is live.
                    unsafe { d.cmd_bind_pipeline(pc.cb, vk::PipelineBindPoint::GRAPHICS, p) };
                    bound = true;
                }
                for k in draw.first_instance..draw.first_instance + draw.instance_count {
                    let offset = self
                        .draws
                        .instances
                        .get(k as usize)
                        .and_then(|&id| self.oq.as_ref()?.condition_offset(id));
                    if let Some(offset) = offset {
                        let begin = vk::ConditionalRenderingBeginInfoEXT::default()
                            .buffer(conditions)
                            .offset(offset);
                        // SAFETY: the buffer has CONDITIONAL_RENDERING usage, the offset is a
                        // multiple of 4 inside it; the copy pass wrote it and made it visible
                        // to the conditional-rendering stage.
                        unsafe { (cond.fp().cmd_begin_conditional_rendering_ext)(pc.cb, &begin) };
                    }
                    // SAFETY: the draw's ranges lie inside the scene's buffers.
                    unsafe {
                        d.cmd_draw_indexed(
                            pc.cb,
                            draw.index_count,
                            1,
                            draw.first_index,
                            draw.vertex_offset,
                            k,
                        )
                    };
                    if offset.is_some() {
                        // SAFETY: ends the conditional block begun above, in the same subpass.
                        unsafe { (cond.fp().cmd_end_conditional_rendering_ext)(pc.cb) };
                    }
                }
            }
        }
        Ok(())
    }

    /// Records the culling shader's lists of one material class and phase (single- and
    /// double-sided, each with its pipeline) as indirect draws with a GPU count.
    fn record_indirect(
        &mut self,
        pc: &PassContext<'_>,
        variant: Variant,
        class: u32,
        phase: u32,
        color_count: u32,
    ) -> Result<(), VkError> {
        self.bind_geometry(pc, true)?;
        let d = &pc.ctx.device;
        for sided in [false, true] {
            let p = self.pipeline(pc, variant, sided, color_count)?;
            // SAFETY: as above.
            unsafe { d.cmd_bind_pipeline(pc.cb, vk::PipelineBindPoint::GRAPHICS, p) };
            if let Some(cull) = self.cull.as_ref() {
                cull.record_draws(pc.ctx, pc.cb, list_index(class, sided, phase));
            }
        }
        Ok(())
    }

    fn record_resolve(
        &mut self,
        pc: &PassContext<'_>,
        ids: ImageId,
        input: bool,
    ) -> Result<(), VkError> {
        let variant = if input {
            Variant::ResolveInput
        } else {
            Variant::ResolveSampled
        };
        let pipeline = self.pipeline(pc, variant, false, 1)?;
        let scene_set = *self
            .scene_sets
            .get(pc.frame_slot)
            .ok_or_else(|| VkError::Invalid {
                what: "scene".into(),
                reason: "no descriptor set for this frame slot".into(),
            })?;
        let key = (pc.frame_slot, input);
        let set = match self.resolve_sets.get(&key) {
            Some(s) => *s,
            None => {
                // The pool holds a set per slot and variant.
                let layout = if input {
                    self.input_set_layout
                } else {
                    self.sampled_set_layout
                };
                let s = allocate_set(pc.ctx, self.pool, layout)?;
                self.resolve_sets.insert(key, s);
                s
            }
        };
        let view = pc.image(ids)?.view;
        let info = [vk::DescriptorImageInfo {
            sampler: self.sampler,
            image_view: view,
            image_layout: vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL,
        }];
        let ty = if input {
            vk::DescriptorType::INPUT_ATTACHMENT
        } else {
            vk::DescriptorType::COMBINED_IMAGE_SAMPLER
        };
        let write = vk::WriteDescriptorSet::default()
            .dst_set(set)
            .dst_binding(0)
            .descriptor_type(ty)
            .image_info(&info);
        let layout = if input {
            self.input_layout
        } else {
            self.sampled_layout
        };
        pc.set_full_viewport();
        let d = &pc.ctx.device;
        // SAFETY: the slot's previous frame completed (executor guarantee), so the set is idle;
        // recording inside the resolve subpass.
        unsafe {
            d.update_descriptor_sets(&[write], &[]);
            d.cmd_bind_pipeline(pc.cb, vk::PipelineBindPoint::GRAPHICS, pipeline);
            d.cmd_bind_descriptor_sets(
                pc.cb,
                vk::PipelineBindPoint::GRAPHICS,
                layout,
                0,
                &[scene_set, set],
                &[],
            );
            d.cmd_draw(pc.cb, 3, 1, 0, 0);
        }
        Ok(())
    }
}

type Payload = Box<dyn FnMut(&mut PassContext<'_>) -> Result<(), VkError>>;
/// Picks one class of draws out of the frame's draw list.
type SelectDraws = fn(&DrawList) -> &[Draw];
/// (vertex stage, fragment stage, vertex attributes, depth state, blend, layout) of a variant.
type VariantState<'a> = (
    Stage<'a>,
    Option<Stage<'a>>,
    &'a [(u32, vk::Format, u32)],
    DepthState,
    Blend,
    vk::PipelineLayout,
);

/// Device features a technique needs (request them when creating the context).
pub fn required_features(technique: Technique) -> tilegraph_vk::FeatureRequest {
    let r = tilegraph_vk::FeatureRequest::default();
    match technique {
        Technique::Visbuf => r.require([tilegraph_vk::Feature::GeometryShader]),
        Technique::Forward | Technique::Prepass => r,
    }
}

/// Renders one scene frame after frame.
pub struct SceneRenderer {
    options: RenderOptions,
    gpu: GpuScene,
    executor: Executor,
    shared: Rc<RefCell<Shared>>,
    target: Image,
    target_handle: ImageHandle,
    content: SceneContent,
    instance_bits: Option<u32>,
    frames: u64,
    last_slot: usize,
    /// The captured id image (with `capture_ids`).
    ids_target: Option<(Image, ImageHandle)>,
    /// Per instance: whether its material is blended.
    blended: Vec<bool>,
    /// Occlusion queries: the opaque and alpha-tested instances the last frame drew.
    last_drawn: Option<Vec<u32>>,
    /// The camera of the last frame rendered.
    last_camera: Option<tilegraph_scene::Camera>,
}

impl SceneRenderer {
    pub fn new(ctx: &Context, scene: &Scene, options: RenderOptions) -> Result<Self, RenderError> {
        let (w, h) = (options.width, options.height);
        if w == 0
            || h == 0
            || w > ctx.physical.limits.max_image_dimension_2d
            || h > ctx.physical.limits.max_image_dimension_2d
        {
            return Err(RenderError::Size {
                width: w,
                height: h,
            });
        }
        let max_tris = scene
            .meshes()
            .iter()
            .map(|m| m.triangle_count())
            .max()
            .unwrap_or(0);
        let instance_bits = visbuf_instance_bits(scene.instances().len(), max_tris);
        if options.technique == Technique::Visbuf && instance_bits.is_none() {
            return Err(RenderError::VisbufIdOverflow {
                instances: scene.instances().len(),
                max_triangles: max_tris,
            });
        }
        let mut needed = required_features(options.technique);
        if options.culling.uses_gpu_lists() {
            needed.required.extend(CullState::required_features());
        }
        if options.culling == Culling::RasterOcclusion {
            needed
                .required
                .insert(tilegraph_vk::Feature::FragmentStoresAndAtomics);
        }
        if options.culling.uses_queries() {
            needed
                .required
                .extend(crate::occlusion::OqState::required_features());
        }
        if options.count_fragments {
            needed
                .required
                .insert(tilegraph_vk::Feature::FragmentStoresAndAtomics);
        }
        if options.technique == Technique::Visbuf
            && matches!(
                options.culling,
                Culling::OqConditional | Culling::RasterOcclusion
            )
        {
            // Both test boxes against a depth pre-pass before colour; the visibility buffer
            // has no pre-pass to test against.
            return Err(RenderError::UnsupportedCulling {
                culling: options.culling.name(),
                technique: options.technique.name(),
            });
        }
        if options.culling.conditional()
            && !ctx.has_feature(tilegraph_vk::Feature::ConditionalRendering)
        {
            return Err(RenderError::MissingExtension {
                culling: options.culling.name(),
                extension: "VK_EXT_conditional_rendering",
                device: ctx.physical.identity.device_name.clone(),
            });
        }
        for f in needed.required {
            if !ctx.has_feature(f) {
                return Err(RenderError::MissingFeature {
                    technique: options.technique.name(),
                    feature: f,
                    device: ctx.physical.identity.device_name.clone(),
                });
            }
        }
        let executor = Executor::new(ctx)?;
        let gpu = GpuScene::new(ctx, scene, executor.frames_in_flight())?;
        let all = vk::ShaderStageFlags::VERTEX | vk::ShaderStageFlags::FRAGMENT;
        let scene_layout = create_pipeline_layout(ctx, &[gpu.set_layout], None)?;
        let input_set_layout = create_set_layout(
            ctx,
            &[(
                0,
                vk::DescriptorType::INPUT_ATTACHMENT,
                vk::ShaderStageFlags::FRAGMENT,
            )],
        )?;
        let sampled_set_layout =
            create_set_layout(ctx, &[(0, vk::DescriptorType::COMBINED_IMAGE_SAMPLER, all)])?;
        let input_layout = create_pipeline_layout(ctx, &[gpu.set_layout, input_set_layout], None)?;
        let sampled_layout =
            create_pipeline_layout(ctx, &[gpu.set_layout, sampled_set_layout], None)?;
        let n = executor.frames_in_flight() as u32;
        let sizes = [
            vk::DescriptorPoolSize {
                ty: vk::DescriptorType::INPUT_ATTACHMENT,
                descriptor_count: n,
            },
            vk::DescriptorPoolSize {
                ty: vk::DescriptorType::COMBINED_IMAGE_SAMPLER,
                descriptor_count: n,
            },
        ];
        let pool_info = vk::DescriptorPoolCreateInfo::default()
            .max_sets(2 * n)
            .pool_sizes(&sizes);
        // SAFETY: valid create info.
        let pool = unsafe { ctx.device.create_descriptor_pool(&pool_info, None) }
            .map_err(|r| VkError::call("vkCreateDescriptorPool", r))?;
        let sampler_info = vk::SamplerCreateInfo::default()
            .mag_filter(vk::Filter::NEAREST)
            .min_filter(vk::Filter::NEAREST)
            .mipmap_mode(vk::SamplerMipmapMode::NEAREST)
            .address_mode_u(vk::SamplerAddressMode::CLAMP_TO_EDGE)
            .address_mode_v(vk::SamplerAddressMode::CLAMP_TO_EDGE)
            .max_lod(0.0);
        // SAFETY: valid create info.
        let sampler = unsafe { ctx.device.create_sampler(&sampler_info, None) }
            .map_err(|r| VkError::call("vkCreateSampler", r))?;
        let scene_sets = (0..executor.frames_in_flight())
            .filter_map(|s| gpu.set(s))
            .collect();
        let depth = scene
            .camera_path()
            .camera(0)
            .map_or(DepthConvention::Reverse, |c| {
                c.projection.depth_convention()
            });
        let shared = Rc::new(RefCell::new(Shared {
            scene_layout,
            input_set_layout,
            sampled_set_layout,
            input_layout,
            sampled_layout,
            pool,
            sampler,
            pipelines: PipelineCache::default(),
            pruned_below: 0,
            resolve_sets: HashMap::new(),
            scene_sets,
            vertex_buffer: gpu.vertices.raw,
            index_buffer: gpu.indices.raw,
            draws: DrawList::default(),
            depth,
            count_fragments: options.count_fragments,
            cull: None,
            culled_sets: Vec::new(),
            oq: None,
            raster: None,
        }));
        let mut gpu = gpu;
        let blended: Vec<bool> = scene
            .instances()
            .iter()
            .map(|i| {
                scene
                    .instance_material(i)
                    .is_some_and(|m| m.class == tilegraph_scene::MaterialClass::Blended)
            })
            .collect();
        if options.culling.uses_queries() {
            let oq = crate::occlusion::OqState::new(
                ctx,
                scene,
                options.oq_group,
                options.culling.conditional(),
                &blended,
                gpu.set_layout,
                executor.frames_in_flight(),
            )?;
            shared.borrow_mut().oq = Some(oq);
        }
        if options.culling.uses_gpu_lists() {
            let cull = CullState::new(
                ctx,
                options.culling,
                scene.instances().len() as u32,
                (w, h),
                depth,
                options.hiz_mode,
                gpu.set_layout,
                executor.frames_in_flight(),
            )?;
            gpu.add_culled_sets(ctx, cull.draw_ids.raw)?;
            let mut s = shared.borrow_mut();
            if options.culling == Culling::RasterOcclusion {
                s.raster = Some(crate::occlusion::RasterOcclusion::new(
                    ctx,
                    gpu.set_layout,
                    &cull.visibility,
                    scene.instances().len() as u32,
                    options.raster_occlusion_scale,
                    executor.frames_in_flight(),
                )?);
            }
            s.culled_sets = (0..executor.frames_in_flight())
                .filter_map(|i| gpu.culled_set(i))
                .collect();
            s.cull = Some(cull);
        }
        let (target, target_handle) = create_target(ctx, w, h, vk::Format::R8G8B8A8_UNORM)?;
        let ids_target = match options.capture_ids && options.technique == Technique::Visbuf {
            true => Some(create_target(ctx, w, h, vk::Format::R32_UINT)?),
            false => None,
        };
        Ok(SceneRenderer {
            options,
            gpu,
            executor,
            shared,
            target,
            target_handle,
            content: SceneContent::of(scene),
            instance_bits,
            frames: 0,
            last_slot: 0,
            ids_target,
            blended,
            last_drawn: None,
            last_camera: None,
        })
    }

    pub fn options(&self) -> &RenderOptions {
        &self.options
    }

    /// Sets the heavy-material ALU iterations for the next frames.
    pub fn set_heavy_iterations(&mut self, iterations: u32) {
        self.options.lighting.heavy_iterations = iterations;
    }

    /// Which passes this renderer's frames have on `profile`.
    pub fn setup(&self, profile: &Profile) -> FrameSetup {
        decide(self.content, profile, self.options.technique).with_culling(self.options.culling)
    }

    /// Renders one frame from a lone `camera`: a still camera when it is the last frame's
    /// camera, else a cut (no previous frame to reproject).
    pub fn render(
        &mut self,
        ctx: &Context,
        scene: &Scene,
        camera: &Camera,
    ) -> Result<FrameReport, RenderError> {
        let m = camera.matrices(self.options.width as f32 / self.options.height as f32);
        let frame = CameraFrame {
            index: 0,
            camera: *camera,
            cut: self.last_camera != Some(*camera),
            current: m,
            previous: m,
            reproject: m.view_projection,
        };
        self.render_frame(ctx, scene, &frame)
    }

    /// Renders one frame of a camera path (its previous matrices feed single-phase HiZ).
    pub fn render_frame(
        &mut self,
        ctx: &Context,
        scene: &Scene,
        frame: &CameraFrame,
    ) -> Result<FrameReport, RenderError> {
        let (w, h) = (self.options.width, self.options.height);
        self.last_camera = Some(frame.camera);
        let m = frame.current;
        let profile = ctx.profile().clone();
        let setup = self.setup(&profile);
        let culling = self.options.culling;
        // With GPU culling on, the CPU lists serve only blended geometry: frustum-cull it here.
        // Techniques whose CPU lists draw opaque geometry (queries, and the pre-pass that raster
        // occlusion tests against) frustum-cull all of it here; the others only blended.
        let cpu_frustum_all = culling.uses_queries() || culling == Culling::RasterOcclusion;
        let blended_mask = match culling {
            Culling::None => None,
            _ => Some(
                crate::cull::cpu_frustum_mask(scene, &m)?
                    .into_iter()
                    .zip(&self.blended)
                    .map(|(v, b)| v || (!b && !cpu_frustum_all))
                    .collect::<Vec<bool>>(),
            ),
        };
        let slot = self.executor.acquire_slot(ctx)?;
        // Occlusion queries: the newest complete frame's results select what this frame draws
        // (read now, never waited for: the acquired slot's frame has completed).
        let blended_mask = match self.shared.borrow_mut().oq.as_mut() {
            Some(oq) if culling.conditional() => {
                // Same-frame results on the GPU; reading the slot only recycles its pool.
                oq.collect(ctx, slot)?;
                oq.prepare(
                    slot,
                    &m,
                    self.options.height as f32,
                    blended_mask.as_deref(),
                );
                blended_mask
            }
            Some(oq) => {
                oq.collect(ctx, slot)?;
                let mask = oq.mask();
                // Every instance in the frustum is queried, drawn or not: a hidden one must be
                // able to come back.
                oq.prepare(
                    slot,
                    &m,
                    self.options.height as f32,
                    blended_mask.as_deref(),
                );
                let combined: Vec<bool> = blended_mask
                    .unwrap_or_else(|| vec![true; mask.len()])
                    .into_iter()
                    .zip(mask)
                    .map(|(a, b)| a && b)
                    .collect();
                self.last_drawn = Some(
                    (0..combined.len())
                        .filter(|&i| combined[i] && !self.blended.get(i).copied().unwrap_or(false))
                        .map(|i| i as u32)
                        .collect(),
                );
                Some(combined)
            }
            None => blended_mask,
        };
        let order = self
            .options
            .opaque_order
            .unwrap_or(profile.passes.opaque_sort);
        let draws = draws::build(scene, m.eye, order, blended_mask.as_deref());
        let uniforms = FrameUniforms::new(
            m.view_projection,
            m.depth,
            (w, h),
            &self.options.lighting,
            self.instance_bits.unwrap_or(32),
        );
        self.gpu
            .write_frame(ctx, slot, scene, m.eye, &uniforms, &draws)?;
        self.last_slot = slot;
        if let Some(cull) = self.shared.borrow_mut().cull.as_mut() {
            cull.write_order(
                ctx,
                slot,
                &crate::cull::gpu_order(&draws, scene.instances().len()),
            )?;
            let planes = gpu_planes(m.view_projection, m.depth)?;
            let levels = cull
                .hiz_layout
                .as_ref()
                .map_or(0, |l| l.levels.len() as u32);
            let (pw, ph) = cull
                .hiz_layout
                .as_ref()
                .and_then(|l| l.levels.first())
                .map_or((w, h), |l| (l.width, l.height));
            let reverse = u32::from(m.depth == DepthConvention::Reverse);
            let n = cull.instance_count;
            let mk = |phase: Phase, view_proj: glam::Mat4, levels: u32| CullParams {
                planes,
                hiz_view_proj: view_proj.to_cols_array_2d(),
                info: [n, phase as u32, levels, reverse],
                screen: [pw, ph, n.max(1), 0],
            };
            let first = match culling {
                // After a camera cut the previous pyramid shows another view: testing against
                // it would cull at random. That frame is frustum-culled only.
                Culling::Hiz => mk(
                    Phase::HizPrevious,
                    frame.reproject,
                    if cull.pyramid_convention == Some(m.depth) && !frame.cut {
                        levels
                    } else {
                        0
                    },
                ),
                // Raster occlusion: the early phase reads this frame's flags.
                Culling::HizTwoPhase | Culling::RasterOcclusion => {
                    mk(Phase::Early, m.view_projection, 0)
                }
                _ => mk(Phase::Frustum, m.view_projection, 0),
            };
            cull.write_params(ctx, slot, 0, &first)?;
            cull.write_params(ctx, slot, 1, &mk(Phase::Late, m.view_projection, levels))?;
        }
        let cpu_draws = draws.opaque.len() + draws.alpha_tested.len() + draws.blended.len();
        let triangles = draws.triangles();
        {
            let mut s = self.shared.borrow_mut();
            s.draws = draws;
            s.depth = m.depth;
        }
        let (graph, target_id) = self.declare(&setup, &profile, m.depth, self.frames == 0);
        let (plan, payloads) = graph.compile(&profile)?.into_parts();
        let plan = Arc::new(plan);
        let mut payloads: HashMap<_, _> = payloads.into_iter().collect();
        let externals = self.externals(target_id, &plan);
        let stats =
            self.executor.execute(
                ctx,
                &plan,
                &externals,
                &mut |id, pc| match payloads.get_mut(&id) {
                    Some(p) => p(pc),
                    None => Ok(()),
                },
            )?;
        // After a rebuild, the pipelines of the destroyed render passes go (at the first frame
        // that succeeds after it: the floor only rises).
        self.shared
            .borrow_mut()
            .prune_pipelines(ctx, self.executor.render_pass_serial_floor());
        self.frames += 1;
        Ok(FrameReport {
            setup,
            plan,
            stats,
            draws: cpu_draws,
            triangles,
        })
    }

    /// Physical resources of the imported ones: the target and the culling buffers.
    fn externals(&self, target: ImageId, plan: &Plan) -> Externals {
        let mut ext = Externals::from_iter([(target, External::Image(self.target_handle.clone()))]);
        if let (Some((_, h)), Some(r)) = (&self.ids_target, plan.resource_by_name("visbuf-id")) {
            ext.insert(r.id, External::Image(h.clone()));
        }
        if let Some(b) = self
            .shared
            .borrow()
            .oq
            .as_ref()
            .and_then(|o| o.conditions.as_ref())
        {
            if let Some(r) = plan.resource_by_name("oq-conditions") {
                ext.insert(r.id, External::Buffer(CullState::handle(b)));
            }
        }
        if let Some(cull) = self.shared.borrow().cull.as_ref() {
            let named = [
                ("cull-commands", Some(&cull.commands)),
                ("cull-counts", Some(&cull.counts)),
                ("cull-draw-ids", Some(&cull.draw_ids)),
                ("visibility", Some(&cull.visibility)),
                ("hiz-pyramid", cull.pyramid.as_ref()),
            ];
            for (name, buffer) in named {
                if let (Some(r), Some(b)) = (plan.resource_by_name(name), buffer) {
                    ext.insert(r.id, External::Buffer(CullState::handle(b)));
                }
            }
        }
        ext
    }

    /// The instance owning each pixel of the last frame (`u32::MAX` for background), from the
    /// captured visibility buffer (`capture_ids`); waits for the GPU.
    pub fn read_instance_ids(&mut self, ctx: &Context) -> Result<Option<Vec<u32>>, RenderError> {
        self.executor.finish(ctx)?;
        let Some((_, h)) = &self.ids_target else {
            return Ok(None);
        };
        let bytes =
            tilegraph_vk::readback::read_image(ctx, h, vk::ImageLayout::TRANSFER_SRC_OPTIMAL, 0)?;
        let tri_bits = 32 - self.instance_bits.unwrap_or(32);
        Ok(Some(
            bytes
                .chunks_exact(4)
                .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
                .map(|id| {
                    if id == u32::MAX {
                        u32::MAX
                    } else if tri_bits >= 32 {
                        0
                    } else {
                        id >> tri_bits
                    }
                })
                .collect(),
        ))
    }

    /// The instances the last frame drew through GPU culling (waits), or `None` without culling.
    pub fn drawn_instances(&mut self, ctx: &Context) -> Result<Option<Vec<u32>>, RenderError> {
        self.executor.finish(ctx)?;
        if let Some(d) = &self.last_drawn {
            return Ok(Some(d.clone()));
        }
        if let Some(oq) = self.shared.borrow().oq.as_ref() {
            if oq.conditions.is_some() {
                return Ok(Some(oq.conditional_drawn(ctx)?));
            }
        }
        match self.shared.borrow().cull.as_ref() {
            Some(c) => Ok(Some(c.drawn_instances(ctx)?)),
            None => Ok(None),
        }
    }

    fn declare(
        &self,
        setup: &FrameSetup,
        profile: &Profile,
        depth_convention: DepthConvention,
        first_frame: bool,
    ) -> (GraphBuilder<Payload>, ImageId) {
        let (w, h) = (self.options.width, self.options.height);
        let extent = Extent2d::new(w, h);
        let culling = self.options.culling;
        let mut g: GraphBuilder<Payload> = GraphBuilder::new();
        // The target survives frames: after the first it is in TRANSFER_SRC from the last
        // frame's release, read by the readback copy.
        let leftover = ResourceState::image(
            Layout::TransferSrc,
            PipelineStages::COPY,
            AccessFlags::TRANSFER_READ,
        );
        let target = g.import_image(
            "color",
            ImageDesc::new(extent, Format::R8G8B8A8_UNORM),
            Import {
                initial: if first_frame {
                    ResourceState::UNDEFINED
                } else {
                    leftover
                },
                content: InitialContent::Discard,
                final_state: leftover,
            },
        );
        let depth = g.create_image("depth", ImageDesc::new(extent, Format::D32_SFLOAT));
        let ids = self.ids_target.as_ref().map(|_| {
            let ids = g.import_image(
                "visbuf-id",
                ImageDesc::new(extent, Format::R32_UINT),
                Import {
                    initial: if first_frame {
                        ResourceState::UNDEFINED
                    } else {
                        leftover
                    },
                    content: InitialContent::Discard,
                    final_state: leftover,
                },
            );
            g.export(ids);
            ids
        });
        let mut f = Declared {
            target,
            depth,
            ids,
            depth_clear: ClearDepthStencil {
                depth: depth_convention_far(depth_convention),
                stencil: 0,
            },
            color_clear: ClearColor::Float(self.options.clear_color),
            color_cleared: false,
            depth_cleared: false,
            prepassed: [setup.prepassed(0), setup.prepassed(1)],
            gpu: None,
            conditions: None,
            flags_declared: false,
        };
        let shared = &self.shared;
        let two_phase = culling == Culling::HizTwoPhase;
        if let Some(cull) = shared.borrow().cull.as_ref() {
            f.gpu = Some(self.declare_culling_buffers(&mut g, cull));
        }
        if let (Some(b), false) = (f.gpu, culling == Culling::RasterOcclusion) {
            self.declare_cull_dispatch(&mut g, b, two_phase, culling);
        }
        // Two-phase with a pre-pass: depth of the early lists, pyramid, late culling, depth of
        // the late lists, then colour once over the union (the early lists, which the late
        // dispatch completes) in the unculled order. The visibility buffer draws ids in both
        // phases instead.
        let split_depth = two_phase && setup.has_prepass();
        let phases: &[u32] = if two_phase { &[0, 1] } else { &[0] };
        for &phase in phases {
            if phase == 1 {
                // No depth written by the early phase (nothing opaque or alpha-tested): no
                // occluders, no pyramid, and no late lists to fill.
                if let (Some(b), true) = (f.gpu, f.depth_cleared) {
                    self.declare_hiz_build(&mut g, f.depth, b);
                    let mut c = g.compute_pass("cull-late", PassClass::Compute, self.dispatch(1));
                    c.storage_read_write(b.counts)
                        .storage_read_write(b.commands)
                        .storage_write(b.draw_ids)
                        .storage_read_write(b.visibility);
                    if let Some(p) = b.pyramid {
                        c.storage_read(p);
                    }
                }
            }
            let suffix = match (two_phase, phase) {
                (false, _) => "",
                (true, 0) => "-early",
                (true, _) => "-late",
            };
            for pass in setup.included() {
                let depth_only = matches!(
                    pass,
                    PassKind::DepthPrepassOpaque | PassKind::DepthPrepassAlpha
                );
                if split_depth && !depth_only {
                    continue; // colour after both depth phases
                }
                if culling.conditional() && !depth_only && f.conditions.is_none() && f.depth_cleared
                {
                    // Boxes against the pre-pass depth, then colour predicated on them.
                    self.declare_queries(&mut g, &mut f);
                }
                if culling == Culling::RasterOcclusion && !depth_only && !f.flags_declared {
                    match (f.gpu, f.depth_cleared) {
                        (Some(b), true) => self.declare_raster_occlusion(&mut g, &f, b),
                        // No pre-pass depth (nothing opaque): no boxes to test; the lists
                        // still get written.
                        (Some(b), false) => {
                            self.declare_cull_dispatch(&mut g, b, false, Culling::RasterOcclusion)
                        }
                        (None, _) => {}
                    }
                    f.flags_declared = true;
                }
                self.declare_geometry(&mut g, &mut f, pass, phase, suffix, profile);
            }
        }
        if split_depth {
            for pass in setup
                .included()
                .filter(|p| matches!(p, PassKind::Opaque | PassKind::AlphaTested))
            {
                self.declare_geometry(&mut g, &mut f, pass, 0, "", profile);
            }
        }
        if setup.includes(PassKind::VisbufResolve) {
            if let Some(ids) = f.ids {
                let input = profile.is_tiler();
                let shared_r = shared.clone();
                let resolve: Payload = Box::new(move |pc: &mut PassContext<'_>| {
                    shared_r.borrow_mut().record_resolve(pc, ids, input)
                });
                let mut r =
                    g.raster_pass(PassKind::VisbufResolve.name(), PassClass::Opaque, resolve);
                if input {
                    r.input(ids);
                } else {
                    r.sampled(ids);
                }
                color_use(&mut r, target, &mut f.color_cleared, f.color_clear);
            }
        }
        if setup.includes(PassKind::Transparent) {
            let mut p = g.raster_pass(
                PassKind::Transparent.name(),
                PassClass::Transparent,
                self.cpu_draws(
                    Variant::Forward {
                        class: 2,
                        equal: false,
                    },
                    |d| &d.blended,
                    1,
                ),
            );
            color_use(&mut p, target, &mut f.color_cleared, f.color_clear);
            depth_use(&mut p, depth, &mut f.depth_cleared, f.depth_clear, true);
        }
        if let (Culling::Hiz, Some(b)) = (culling, f.gpu) {
            // Next frame's occluders: this frame's depth.
            self.declare_hiz_build(&mut g, f.depth, b);
        }
        if culling.uses_queries() && !culling.conditional() && f.depth_cleared {
            // After all opaque work (the graph's class order); results are read next frame.
            self.declare_queries(&mut g, &mut f);
        }
        if !f.color_cleared {
            // Nothing drew (an empty view of an empty scene): still produce a cleared image.
            let mut p = g.raster_pass(
                "clear",
                PassClass::Opaque,
                Box::new(|_: &mut PassContext<'_>| Ok(())) as Payload,
            );
            p.color_clear(target, f.color_clear)
                .coverage(Coverage::Full);
        }
        g.export(target);
        (g, target)
    }

    /// Imports the persistent culling buffers into this frame's graph.
    fn declare_culling_buffers(
        &self,
        g: &mut GraphBuilder<Payload>,
        cull: &CullState,
    ) -> CullBuffers {
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
        let commands = g.import_buffer("cull-commands", cull.commands.size, discard);
        let counts = g.import_buffer("cull-counts", cull.counts.size, discard);
        let draw_ids = g.import_buffer("cull-draw-ids", cull.draw_ids.size, discard);
        let visibility = g.import_buffer("visibility", cull.visibility.size, keep);
        let pyramid = cull
            .pyramid
            .as_ref()
            .map(|p| g.import_buffer("hiz-pyramid", p.size, keep));
        // What the next frame reads survives this one.
        g.export(visibility);
        if let Some(p) = pyramid {
            g.export(p);
        }
        // Tools read the drawn set back after the frame.
        g.export(counts);
        g.export(draw_ids);
        CullBuffers {
            commands,
            counts,
            draw_ids,
            visibility,
            pyramid,
        }
    }

    /// The occlusion-query pass (reading depth only; its results leave the graph through the
    /// query pool, hence kept without an export) and, for conditional rendering, the copy of
    /// its results into the predicate buffer.
    fn declare_queries(&self, g: &mut GraphBuilder<Payload>, f: &mut Declared) {
        let shared_q = self.shared.clone();
        let queries: Payload = Box::new(move |pc: &mut PassContext<'_>| {
            let mut s = shared_q.borrow_mut();
            let depth = s.depth;
            let set = s.scene_set(pc.frame_slot, "occlusion queries")?;
            match s.oq.as_mut() {
                Some(oq) => oq.record(pc, set, depth),
                None => Ok(()),
            }
        });
        let query_pass = g
            .raster_pass("occlusion-queries", PassClass::OcclusionQuery, queries)
            .depth_stencil_read_only(f.depth)
            .retention(tilegraph_graph::Retention::Always)
            .id();
        let size = match self
            .shared
            .borrow()
            .oq
            .as_ref()
            .and_then(|o| o.conditions.as_ref())
        {
            Some(b) => b.size,
            None => return,
        };
        let any = ResourceState::buffer(
            PipelineStages::ALL_COMMANDS,
            AccessFlags::MEMORY_READ.union(AccessFlags::MEMORY_WRITE),
        );
        let conditions = g.import_buffer(
            "oq-conditions",
            size,
            Import {
                initial: any,
                content: InitialContent::Discard,
                final_state: any,
            },
        );
        // Tools read the drawn set back after the frame.
        g.export(conditions);
        let shared_c = self.shared.clone();
        let copy: Payload =
            Box::new(
                move |pc: &mut PassContext<'_>| match shared_c.borrow().oq.as_ref() {
                    Some(oq) => oq.record_copy(pc),
                    None => Ok(()),
                },
            );
        g.transfer_pass("oq-copy-results", PassClass::Transfer, copy)
            .transfer_dst(conditions)
            .after(query_pass);
        f.conditions = Some(conditions);
    }

    /// The culling dispatch of the early (or only) phase: reset the counts, cull.
    fn declare_cull_dispatch(
        &self,
        g: &mut GraphBuilder<Payload>,
        b: CullBuffers,
        two_phase: bool,
        culling: Culling,
    ) {
        g.transfer_pass("cull-reset", PassClass::Compute, zero_fill(b.counts))
            .transfer_dst(b.counts);
        let mut c = g.compute_pass(
            if two_phase { "cull-early" } else { "cull" },
            PassClass::Compute,
            self.dispatch(0),
        );
        c.storage_read_write(b.counts)
            .storage_write(b.commands)
            .storage_write(b.draw_ids);
        if two_phase {
            c.storage_read(b.visibility);
        }
        if culling == Culling::RasterOcclusion {
            // cull.comp's visibility binding is writable (the late phase writes it), so
            // synchronization validation counts the dispatch as a writer.
            c.storage_read_write(b.visibility);
        }
        if let (Culling::Hiz, Some(p)) = (culling, b.pyramid) {
            c.storage_read(p);
        }
    }

    /// Raster occlusion: clear the flags, rasterize every box against the pre-pass depth
    /// (flags written by surviving fragments), then cull into the indirect lists from them.
    fn declare_raster_occlusion(
        &self,
        g: &mut GraphBuilder<Payload>,
        f: &Declared,
        b: CullBuffers,
    ) {
        g.transfer_pass(
            "raster-occlusion-clear",
            PassClass::Compute,
            zero_fill(b.visibility),
        )
        .transfer_dst(b.visibility);
        let shared = self.shared.clone();
        let boxes: Payload = Box::new(move |pc: &mut PassContext<'_>| {
            let mut s = shared.borrow_mut();
            let depth = s.depth;
            let set = s.scene_set(pc.frame_slot, "raster occlusion")?;
            match s.raster.as_mut() {
                Some(r) => r.record(pc, set, depth),
                None => Ok(()),
            }
        });
        let scale = self.shared.borrow().raster.as_ref().map_or(1, |r| r.scale);
        let full = (self.options.width, self.options.height);
        let tested_depth = if scale > 1 {
            let low = (full.0.div_ceil(scale).max(1), full.1.div_ceil(scale).max(1));
            let low_depth = g.create_image(
                "occlusion-depth",
                ImageDesc::new(Extent2d::new(low.0, low.1), Format::D32_SFLOAT),
            );
            let shared = self.shared.clone();
            let depth = f.depth;
            let downsample: Payload = Box::new(move |pc: &mut PassContext<'_>| {
                let view = pc.image(depth)?.view;
                let mut s = shared.borrow_mut();
                let convention = s.depth;
                match s.raster.as_mut() {
                    Some(r) => r.record_downsample(pc, view, full, convention),
                    None => Ok(()),
                }
            });
            g.raster_pass(
                "raster-occlusion-depth",
                PassClass::OcclusionQuery,
                downsample,
            )
            .sampled(f.depth)
            .depth_stencil_clear(low_depth, f.depth_clear);
            low_depth
        } else {
            f.depth
        };
        g.raster_pass("raster-occlusion", PassClass::OcclusionQuery, boxes)
            .depth_stencil_read_only(tested_depth)
            .storage_write(b.visibility);
        self.declare_cull_dispatch(g, b, false, Culling::RasterOcclusion);
    }

    fn declare_hiz_build(&self, g: &mut GraphBuilder<Payload>, depth: ImageId, b: CullBuffers) {
        let Some(pyramid) = b.pyramid else { return };
        let shared = self.shared.clone();
        let build: Payload = Box::new(move |pc: &mut PassContext<'_>| {
            let view = pc.image(depth)?.view;
            let buffer = pc.buffer(pyramid)?;
            let mut s = shared.borrow_mut();
            // The frame's convention decides the reduction (the farther depth of each
            // footprint): a camera path may change it from one frame to the next.
            let depth_convention = s.depth;
            let cull = s.cull.as_mut().ok_or_else(|| VkError::Invalid {
                what: "hiz-build".into(),
                reason: "no culling state".into(),
            })?;
            let mut layout = cull.hiz_layout.clone().ok_or_else(|| VkError::Invalid {
                what: "hiz-build".into(),
                reason: "no pyramid layout".into(),
            })?;
            layout.convention = crate::cull::cull_convention(depth_convention);
            // The stored layout follows too, for whoever reads the pyramid back.
            if let Some(stored) = cull.hiz_layout.as_mut() {
                stored.convention = layout.convention;
            }
            let builder = cull.hiz.as_mut().ok_or_else(|| VkError::Invalid {
                what: "hiz-build".into(),
                reason: "no pyramid builder".into(),
            })?;
            // The graph samples depth formats in DEPTH_STENCIL_READ_ONLY_OPTIMAL.
            builder.record(
                pc.ctx,
                pc.cb,
                pc.frame_slot,
                view,
                vk::ImageLayout::DEPTH_STENCIL_READ_ONLY_OPTIMAL,
                buffer,
                &layout,
            )?;
            cull.pyramid_convention = Some(depth_convention);
            Ok(())
        });
        g.compute_pass("hiz-build", PassClass::Compute, build)
            .sampled(depth)
            .storage_read_write(pyramid);
    }

    fn dispatch(&self, which: usize) -> Payload {
        let shared = self.shared.clone();
        Box::new(move |pc: &mut PassContext<'_>| {
            let s = shared.borrow();
            let scene_set = *s
                .scene_sets
                .get(pc.frame_slot)
                .ok_or_else(|| VkError::Invalid {
                    what: "cull".into(),
                    reason: "no scene set".into(),
                })?;
            match s.cull.as_ref() {
                Some(c) => c.record_dispatch(pc.ctx, pc.cb, scene_set, pc.frame_slot, which),
                None => Ok(()),
            }
        })
    }

    fn cpu_draws(&self, variant: Variant, which: SelectDraws, colors: u32) -> Payload {
        let shared = self.shared.clone();
        Box::new(move |pc: &mut PassContext<'_>| {
            let mut s = shared.borrow_mut();
            let draws: Vec<Draw> = which(&s.draws).to_vec();
            s.record_draws(pc, variant, &draws, colors)
        })
    }

    /// Draws of one material class: the CPU list, or the culling shader's indirect lists.
    fn class_draws(
        &self,
        variant: Variant,
        class: u32,
        phase: u32,
        colors: u32,
        gpu: bool,
    ) -> Payload {
        if !gpu {
            return self.cpu_draws(
                variant,
                if class == 0 {
                    |d: &DrawList| &d.opaque[..]
                } else {
                    |d: &DrawList| &d.alpha_tested[..]
                },
                colors,
            );
        }
        let shared = self.shared.clone();
        Box::new(move |pc: &mut PassContext<'_>| {
            shared
                .borrow_mut()
                .record_indirect(pc, variant, class, phase, colors)
        })
    }

    fn declare_geometry(
        &self,
        g: &mut GraphBuilder<Payload>,
        f: &mut Declared,
        pass: PassKind,
        phase: u32,
        suffix: &str,
        _profile: &Profile,
    ) {
        // Raster occlusion tests boxes against the depth of everything: the pre-pass is not
        // culled (its CPU lists), only colour is.
        let gpu = match (self.options.culling, pass) {
            (
                Culling::RasterOcclusion,
                PassKind::DepthPrepassOpaque | PassKind::DepthPrepassAlpha,
            ) => None,
            _ => f.gpu,
        };
        let name = format!("{}{suffix}", pass.name());
        let uses_lists = |p: &mut tilegraph_graph::RasterPassBuilder<'_, Payload>| {
            if let Some(b) = gpu {
                p.indirect(b.commands)
                    .indirect(b.counts)
                    .storage_read(b.draw_ids);
            }
        };
        match pass {
            PassKind::DepthPrepassOpaque | PassKind::DepthPrepassAlpha => {
                let (variant, class) = if pass == PassKind::DepthPrepassOpaque {
                    (Variant::DepthOpaque, 0)
                } else {
                    (Variant::DepthAlpha, 1)
                };
                let mut p = g.raster_pass(
                    name,
                    PassClass::DepthPrepass,
                    self.class_draws(variant, class, phase, 0, gpu.is_some()),
                );
                depth_use(&mut p, f.depth, &mut f.depth_cleared, f.depth_clear, false);
                uses_lists(&mut p);
            }
            PassKind::Opaque | PassKind::AlphaTested => {
                let (class, pclass) = if pass == PassKind::Opaque {
                    (0, PassClass::Opaque)
                } else {
                    (1, PassClass::AlphaTested)
                };
                let prepassed = f.prepassed[class as usize];
                let variant = Variant::Forward {
                    class,
                    equal: prepassed,
                };
                let mut p = g.raster_pass(
                    name,
                    pclass,
                    self.class_draws(variant, class, phase, 1, gpu.is_some()),
                );
                color_use(&mut p, f.target, &mut f.color_cleared, f.color_clear);
                depth_use(
                    &mut p,
                    f.depth,
                    &mut f.depth_cleared,
                    f.depth_clear,
                    prepassed,
                );
                uses_lists(&mut p);
                if let Some(c) = f.conditions {
                    // Read by vkCmdBeginConditionalRenderingEXT: the graph puts the barrier
                    // from the results copy to the conditional-rendering stage before this pass.
                    p.predicate(c);
                }
            }
            PassKind::VisbufWrite => {
                let extent = Extent2d::new(self.options.width, self.options.height);
                let ids = *f.ids.get_or_insert_with(|| {
                    g.create_image("visbuf-id", ImageDesc::new(extent, Format::R32_UINT))
                });
                let opaque =
                    self.class_draws(Variant::Visbuf { alpha: false }, 0, phase, 1, gpu.is_some());
                let alpha =
                    self.class_draws(Variant::Visbuf { alpha: true }, 1, phase, 1, gpu.is_some());
                let mut both = [opaque, alpha];
                let write: Payload = Box::new(move |pc: &mut PassContext<'_>| {
                    for p in &mut both {
                        p(pc)?;
                    }
                    Ok(())
                });
                let mut p = g.raster_pass(name, PassClass::Opaque, write);
                if phase == 0 {
                    p.color_clear(ids, ClearColor::Uint([u32::MAX; 4]));
                } else {
                    p.color(ids);
                }
                depth_use(&mut p, f.depth, &mut f.depth_cleared, f.depth_clear, false);
                uses_lists(&mut p);
            }
            PassKind::VisbufResolve | PassKind::Transparent => {} // after the geometry phases
        }
    }

    /// Waits for the frames in flight, collecting their GPU timings.
    pub fn finish(&mut self, ctx: &Context) -> Result<(), RenderError> {
        Ok(self.executor.finish(ctx)?)
    }

    /// Median GPU time per pass over the frames rendered so far (call [`Self::finish`] first).
    pub fn medians(&self) -> Vec<PassMedian> {
        self.executor.medians()
    }

    /// Fragments shaded by the opaque, alpha-tested and blended colour passes of the last frame
    /// (with `count_fragments`; waits for the GPU).
    pub fn fragment_counts(&mut self, ctx: &Context) -> Result<[u32; 3], RenderError> {
        self.executor.finish(ctx)?;
        Ok(self.gpu.fragment_counts(ctx, self.last_slot)?)
    }

    /// Graphics pipelines cached now (those of render passes the executor destroyed are
    /// dropped after the frame that rebuilt them).
    pub fn cached_pipelines(&self) -> usize {
        self.shared.borrow().pipeline_count()
    }

    pub fn executor(&self) -> &Executor {
        &self.executor
    }

    /// Reads the last frame's image (waits for the GPU).
    pub fn read_image(&mut self, ctx: &Context) -> Result<RgbaImage, RenderError> {
        self.executor.finish(ctx)?;
        let pixels = tilegraph_vk::readback::read_image(
            ctx,
            &self.target_handle,
            vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
            0,
        )?;
        Ok(RgbaImage {
            width: self.options.width,
            height: self.options.height,
            pixels,
        })
    }

    pub fn destroy(self, ctx: &Context) {
        let SceneRenderer {
            gpu,
            executor,
            shared,
            target,
            target_handle,
            ids_target,
            ..
        } = self;
        executor.destroy(ctx);
        if let Ok(mut s) = Rc::try_unwrap(shared).map(RefCell::into_inner) {
            if let Some(c) = s.cull.take() {
                c.destroy(ctx);
            }
            if let Some(o) = s.oq.take() {
                o.destroy(ctx);
            }
            if let Some(r) = s.raster.take() {
                r.destroy(ctx);
            }
            // SAFETY: the executor waited for every frame; nothing uses these any more.
            s.pipelines.destroy(ctx);
            unsafe {
                ctx.device.destroy_sampler(s.sampler, None);
                ctx.device.destroy_descriptor_pool(s.pool, None);
                ctx.device.destroy_pipeline_layout(s.scene_layout, None);
                ctx.device.destroy_pipeline_layout(s.input_layout, None);
                ctx.device.destroy_pipeline_layout(s.sampled_layout, None);
                ctx.device
                    .destroy_descriptor_set_layout(s.input_set_layout, None);
                ctx.device
                    .destroy_descriptor_set_layout(s.sampled_set_layout, None);
            }
        }
        gpu.destroy(ctx);
        // SAFETY: GPU idle.
        unsafe { ctx.device.destroy_image_view(target_handle.view, None) };
        ctx.destroy_image(target);
        if let Some((image, handle)) = ids_target {
            // SAFETY: GPU idle.
            unsafe { ctx.device.destroy_image_view(handle.view, None) };
            ctx.destroy_image(image);
        }
    }
}

/// A transfer payload that zeroes a whole buffer (the graph put it in TRANSFER_DST).
fn zero_fill(buffer: BufferId) -> Payload {
    Box::new(move |pc: &mut PassContext<'_>| {
        let b = pc.buffer(buffer)?;
        // SAFETY: recording outside a render pass; the buffer is live and a transfer destination.
        unsafe {
            pc.ctx
                .device
                .cmd_fill_buffer(pc.cb, b.raw, 0, vk::WHOLE_SIZE, 0)
        };
        Ok(())
    })
}

fn depth_convention_far(c: DepthConvention) -> f32 {
    match c {
        DepthConvention::Reverse => 0.0,
        DepthConvention::Standard => 1.0,
    }
}

fn color_use(
    p: &mut tilegraph_graph::RasterPassBuilder<'_, Payload>,
    target: ImageId,
    cleared: &mut bool,
    clear: ClearColor,
) {
    if *cleared {
        p.color(target);
    } else {
        p.color_clear(target, clear);
        *cleared = true;
    }
}

fn depth_use(
    p: &mut tilegraph_graph::RasterPassBuilder<'_, Payload>,
    depth: ImageId,
    cleared: &mut bool,
    clear: ClearDepthStencil,
    read_only: bool,
) {
    if !*cleared {
        p.depth_stencil_clear(depth, clear);
        *cleared = true;
    } else if read_only {
        p.depth_stencil_read_only(depth);
    } else {
        p.depth_stencil(depth);
    }
}

fn create_target(
    ctx: &Context,
    w: u32,
    h: u32,
    format: vk::Format,
) -> Result<(Image, ImageHandle), VkError> {
    let extra = if format == vk::Format::R32_UINT {
        vk::ImageUsageFlags::INPUT_ATTACHMENT | vk::ImageUsageFlags::SAMPLED
    } else {
        vk::ImageUsageFlags::empty()
    };
    let info = vk::ImageCreateInfo::default()
        .image_type(vk::ImageType::TYPE_2D)
        .format(format)
        .extent(vk::Extent3D {
            width: w,
            height: h,
            depth: 1,
        })
        .mip_levels(1)
        .array_layers(1)
        .samples(vk::SampleCountFlags::TYPE_1)
        .tiling(vk::ImageTiling::OPTIMAL)
        .usage(vk::ImageUsageFlags::COLOR_ATTACHMENT | vk::ImageUsageFlags::TRANSFER_SRC | extra)
        .initial_layout(vk::ImageLayout::UNDEFINED);
    let image = ctx.create_image("render target", &info, MemoryUse::GpuOnly)?;
    let view_info = vk::ImageViewCreateInfo::default()
        .image(image.raw)
        .view_type(vk::ImageViewType::TYPE_2D)
        .format(format)
        .subresource_range(vk::ImageSubresourceRange {
            aspect_mask: vk::ImageAspectFlags::COLOR,
            base_mip_level: 0,
            level_count: 1,
            base_array_layer: 0,
            layer_count: 1,
        });
    // SAFETY: live image with bound memory.
    let view = match unsafe { ctx.device.create_image_view(&view_info, None) } {
        Ok(v) => v,
        Err(r) => {
            ctx.destroy_image(image);
            return Err(VkError::call("vkCreateImageView", r));
        }
    };
    let handle = ImageHandle {
        raw: image.raw,
        view,
        full_view: view,
        mip_views: Vec::new(),
        format,
        extent: vk::Extent2D {
            width: w,
            height: h,
        },
        mip_levels: 1,
        aspect: vk::ImageAspectFlags::COLOR,
    };
    Ok((image, handle))
}
