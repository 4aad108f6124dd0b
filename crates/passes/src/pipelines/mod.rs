//! Every graphics pipeline the shipped passes draw with, in one cache.
//!
//! A pipeline is created against one render pass and subpass, on first use, and stays valid with
//! any compatible one. The executor destroys its render passes when the plan changes, and a
//! driver may give the same handle value to a new, incompatible render pass: the cache is keyed
//! on the render pass's serial ([`RenderPassRef::serial`]), which is never reused, and
//! [`Pipelines::prune`] drops what was created for render passes that no longer exist.
//!
//! The scene's pipelines ([`Variant`]: depth pre-pass, forward colour, visibility-buffer ids and
//! resolve) and the occlusion proxies' ([`Proxy`]) are described here, since several passes share
//! them; a pass with a pipeline of its own describes it and caches it through
//! [`Pipelines::get_or_create`].

use std::collections::HashMap;
use std::rc::Rc;
use std::sync::Arc;

use tilegraph_graph::PassId;
use tilegraph_profile::lint::DrawState;
use tilegraph_profile::TextureBinding;
use tilegraph_scene::DepthConvention;
use tilegraph_vk::ash::vk;
use tilegraph_vk::executor::{PassContext, RenderPassRef};
use tilegraph_vk::pipeline::{
    create_described_pipeline, create_pipeline_layout, create_set_layout, Blend, DepthState,
    DescribedPipeline, GraphicsDesc, RenderTarget, Stage,
};
use tilegraph_vk::{Context, VkError};

pub use crate::depth_test::ColourDepth;
use crate::draws::DrawClass;
use crate::materials::{EngineMaterial, MaterialPass};
use crate::probe::StageProbe;
use crate::spv;

mod variants;
use variants::scene_pipeline;

/// How far occlusion proxies are pulled toward the eye, in units of the depth format (a D32
/// float's ulp at the box's largest depth, 1/65535 for D16): a few, against interpolation and
/// rounding differences between a box and the surface it encloses.
pub const PROXY_DEPTH_BIAS: i32 = 4;

/// `fullscreen.vert`: one triangle covering the render area, no vertex input.
pub const FULLSCREEN_VS: &[u8] = spv::FULLSCREEN_VS;

/// The scene's pipelines.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Variant {
    /// Depth pre-pass of opaque geometry: positions only, no fragment shader.
    DepthOpaque,
    /// Depth pre-pass of alpha-tested geometry, with its discard.
    DepthAlpha,
    /// Forward colour of a material class, testing (and writing) depth as `depth` says.
    Forward {
        class: DrawClass,
        depth: ColourDepth,
    },
    /// Visibility-buffer ids of opaque or alpha-tested geometry.
    Visbuf { alpha: bool },
    /// The resolve reading the ids as an input attachment (tilers) ...
    ResolveInput,
    /// ... or sampling them.
    ResolveSampled,
    /// Deferred texturing's G-buffer of opaque or alpha-tested geometry.
    Gbuffer { alpha: bool },
    /// Deferred texturing's resolve, reading the G-buffer and depth as input attachments
    /// (`input`, tilers) or sampling them.
    GbufferResolve { input: bool },
}

/// The engine-material raster pass kind a variant belongs to; `None` for the visibility
/// buffer's passes — its id pass is tilegraph's, and an engine's resolve shader runs per
/// material after classification (`visbuf::classify`), not through a variant — and for
/// deferred texturing's, whose G-buffer layout is tilegraph's.
pub fn material_pass(variant: Variant) -> Option<MaterialPass> {
    match variant {
        Variant::DepthOpaque | Variant::DepthAlpha => Some(MaterialPass::Depth),
        Variant::Forward { .. } => Some(MaterialPass::Color),
        Variant::Visbuf { .. }
        | Variant::ResolveInput
        | Variant::ResolveSampled
        | Variant::Gbuffer { .. }
        | Variant::GbufferResolve { .. } => None,
    }
}

/// The occlusion proxies: a bounding box drawn against the frame's depth.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Proxy {
    /// One box per occlusion query (`oq_box.vert`, push constants).
    QueryBox,
    /// Every instance's box, flagging visible instances (`raster_occlusion.*`); the vertex
    /// shader's `scale` widens it for a depth of 1/scale resolution.
    RasterBox { scale: u32 },
}

/// What a cached pipeline bakes in besides its render pass and subpass.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PipelineKey {
    /// The depth compare is baked in, and a camera may change the convention.
    Scene {
        variant: Variant,
        double_sided: bool,
        reverse_z: bool,
        /// The engine material whose shaders it runs (`None`: tilegraph's).
        engine: Option<u32>,
    },
    Proxy {
        proxy: Proxy,
        reverse_z: bool,
    },
    /// A pass's own pipeline, named by the pass.
    Named(&'static str),
    /// The visibility buffer's resolve of one material (`visbuf::classify`): over the screen
    /// (`tile` 0; the ids an input attachment or sampled) or over its tiles of `tile` pixels.
    /// With `engine`, engine material `engine`'s resolve shader.
    Resolve {
        material: u32,
        input: bool,
        tile: u32,
        engine: Option<u32>,
    },
}

const POSITION: (u32, vk::Format, u32) = (0, vk::Format::R32G32B32_SFLOAT, 0);
const NORMAL: (u32, vk::Format, u32) = (1, vk::Format::R32G32B32_SFLOAT, 12);
const UV: (u32, vk::Format, u32) = (2, vk::Format::R32G32_SFLOAT, 24);
const VERTEX_STRIDE: u32 = 32;

/// One pipeline bound while tracing ([`Pipelines::start_trace`]): the draws after it, up to
/// the next bind, record with its state.
#[derive(Debug, Clone)]
pub struct TracedBind {
    pub pass: PassId,
    pub pass_name: String,
    pub state: Arc<DrawState>,
}

/// The graphics pipelines and the pipeline layouts of the scene's variants.
pub struct Pipelines {
    cache: HashMap<(u64, u32, PipelineKey), (vk::Pipeline, Arc<DrawState>)>,
    /// Every pipeline handed out for a bind, in recording order, while a lint traces a frame.
    trace: Option<Vec<TracedBind>>,
    /// Pipelines of render passes with serials below this are destroyed.
    pruned_below: u64,
    /// Count fragments in the colour passes (`forward_count*.frag`), and the bottleneck
    /// finder's trivial shaders.
    shaders: (bool, StageProbe),
    /// How the scene's textures are bound (which build of each fragment shader), and the
    /// descriptors of the binding: `TEXTURE_SLOTS` (specialization 1) of the indexed builds.
    textures: (TextureBinding, u32),
    /// The engine's materials (`SceneRenderer::add_material`), by id (shared with the
    /// pipeline descriptions that read their shaders).
    materials: Vec<Rc<EngineMaterial>>,
    /// Set 0: the scene (`GpuScene::set_layout`, owned by the scene).
    pub scene_layout: vk::PipelineLayout,
    /// Set 1 of the resolves: the ids or the G-buffer (binding 0) and the depth (binding 1,
    /// deferred texturing's) as input attachments, or sampled.
    pub input_set_layout: vk::DescriptorSetLayout,
    pub sampled_set_layout: vk::DescriptorSetLayout,
    pub input_layout: vk::PipelineLayout,
    pub sampled_layout: vk::PipelineLayout,
}

impl Pipelines {
    /// The layouts of the scene's variants over `scene_set_layout` (set 0).
    pub fn new(
        ctx: &Context,
        scene_set_layout: vk::DescriptorSetLayout,
        shaders: (bool, StageProbe),
        textures: (TextureBinding, u32),
    ) -> Result<Self, VkError> {
        let mut p = Pipelines {
            cache: HashMap::new(),
            trace: None,
            pruned_below: 0,
            shaders,
            textures,
            materials: Vec::new(),
            scene_layout: vk::PipelineLayout::null(),
            input_set_layout: vk::DescriptorSetLayout::null(),
            sampled_set_layout: vk::DescriptorSetLayout::null(),
            input_layout: vk::PipelineLayout::null(),
            sampled_layout: vk::PipelineLayout::null(),
        };
        match p.create_layouts(ctx, scene_set_layout) {
            Ok(()) => Ok(p),
            Err(e) => {
                p.destroy(ctx);
                Err(e)
            }
        }
    }

    fn create_layouts(
        &mut self,
        ctx: &Context,
        scene_set_layout: vk::DescriptorSetLayout,
    ) -> Result<(), VkError> {
        let all = vk::ShaderStageFlags::VERTEX | vk::ShaderStageFlags::FRAGMENT;
        self.scene_layout = create_pipeline_layout(ctx, &[scene_set_layout], None)?;
        // Binding 0: the visibility buffer's ids or deferred texturing's G-buffer; 1: the
        // depth (deferred texturing's resolve only).
        let fragment = vk::ShaderStageFlags::FRAGMENT;
        let input = vk::DescriptorType::INPUT_ATTACHMENT;
        self.input_set_layout =
            create_set_layout(ctx, &[(0, input, fragment), (1, input, fragment)])?;
        let sampled = vk::DescriptorType::COMBINED_IMAGE_SAMPLER;
        self.sampled_set_layout = create_set_layout(ctx, &[(0, sampled, all), (1, sampled, all)])?;
        self.input_layout =
            create_pipeline_layout(ctx, &[scene_set_layout, self.input_set_layout], None)?;
        self.sampled_layout =
            create_pipeline_layout(ctx, &[scene_set_layout, self.sampled_set_layout], None)?;
        Ok(())
    }

    /// The pipeline cached for the subpass `pc` records into under `key`, or the one
    /// `describe` describes, created now. Every call is a bind: the caller binds what it gets
    /// and draws with it (recorded while tracing).
    pub fn get_or_create(
        &mut self,
        pc: &PassContext<'_>,
        key: PipelineKey,
        describe: impl FnOnce(RenderTarget<'static>) -> Result<DescribedPipeline, VkError>,
    ) -> Result<vk::Pipeline, VkError> {
        let rp = render_pass_of(pc)?;
        let at = (rp.serial, rp.subpass, key);
        let (pipeline, state) = match self.cache.get(&at) {
            Some((p, state)) => (*p, state),
            None => {
                let d = describe(RenderTarget::Subpass {
                    render_pass: rp.handle,
                    subpass: rp.subpass,
                    color_count: 0,
                })?;
                let entry = self
                    .cache
                    .entry(at)
                    .or_insert((d.pipeline, Arc::new(d.state)));
                (entry.0, &entry.1)
            }
        };
        if let Some(trace) = &mut self.trace {
            trace.push(TracedBind {
                pass: pc.pass,
                pass_name: pc.pass_name.to_string(),
                state: Arc::clone(state),
            });
        }
        Ok(pipeline)
    }

    /// Records every bind from now on (the state lint's view of a frame), until
    /// [`Self::take_trace`]. Off by default: a steady frame allocates nothing.
    pub fn start_trace(&mut self) {
        self.trace = Some(Vec::new());
    }

    /// The binds recorded since [`Self::start_trace`], in recording order; tracing stops.
    pub fn take_trace(&mut self) -> Option<Vec<TracedBind>> {
        self.trace.take()
    }

    /// The resolve's fragment shader in the build the scene's textures need: reading the ids
    /// as an input attachment or sampling them.
    pub fn resolve_fragment(&self, input: bool) -> (&'static str, &'static [u8]) {
        let layers = self.textures.0 == TextureBinding::Layers;
        match (input, layers) {
            (true, false) => ("visbuf_resolve_input.frag", spv::RESOLVE_INPUT_FS),
            (true, true) => ("visbuf_resolve_input.frag", spv::RESOLVE_INPUT_LAYERS_FS),
            (false, false) => ("visbuf_resolve_sampled.frag", spv::RESOLVE_SAMPLED_FS),
            (false, true) => (
                "visbuf_resolve_sampled.frag",
                spv::RESOLVE_SAMPLED_LAYERS_FS,
            ),
        }
    }

    /// The alpha-tested depth pass's fragment shader (`depth_alpha.frag`) in the build the
    /// scene's textures need.
    pub fn depth_alpha_fragment(&self) -> (&'static str, &'static [u8]) {
        if self.textures.0 == TextureBinding::Layers {
            ("depth_alpha.frag", spv::DEPTH_ALPHA_LAYERS_FS)
        } else {
            ("depth_alpha.frag", spv::DEPTH_ALPHA_FS)
        }
    }

    /// `TEXTURE_SLOTS` (specialization 1 of the fragment shaders).
    pub fn texture_slots(&self) -> u32 {
        self.textures.1
    }

    /// Registers an engine material; its id.
    pub fn add_material(&mut self, material: EngineMaterial) -> u32 {
        self.materials.push(Rc::new(material));
        (self.materials.len() - 1) as u32
    }

    /// Hands the engine's materials, with their ids, to `fresh` (the renderer's pipelines made
    /// anew for new buffers: the engine registered them once, for the renderer's life).
    pub fn hand_materials_to(&mut self, fresh: &mut Pipelines) {
        fresh.materials = std::mem::take(&mut self.materials);
    }

    /// Engine materials registered.
    pub fn material_count(&self) -> usize {
        self.materials.len()
    }

    /// The engine material that draws `variant` for scene material `engine` (its
    /// `engine_material`): `None` when it has none, or no shaders for that pass kind.
    pub fn engine_for(&self, engine: Option<u32>, variant: Variant) -> Option<u32> {
        let pass = material_pass(variant)?;
        engine.filter(|&k| {
            self.materials
                .get(k as usize)
                .is_some_and(|m| m.shaders(pass).is_some())
        })
    }

    /// The pipeline layout set 0 is bound with for `engine`'s pipelines (tilegraph's own for
    /// `None`).
    pub fn layout_for(&self, engine: Option<u32>) -> vk::PipelineLayout {
        engine
            .and_then(|k| self.materials.get(k as usize))
            .map_or(self.scene_layout, |m| m.layout)
    }

    /// Engine material `engine`.
    pub fn engine_material(&self, engine: u32) -> Option<&Rc<EngineMaterial>> {
        self.materials.get(engine as usize)
    }

    /// Lets engine material `engine` bind its own sets for `variant`'s pass.
    pub fn bind_material(
        &self,
        ctx: &Context,
        cb: vk::CommandBuffer,
        engine: u32,
        variant: Variant,
    ) {
        if let (Some(m), Some(pass)) = (self.materials.get(engine as usize), material_pass(variant))
        {
            (m.bind)(ctx, cb, pass);
        }
    }

    /// A scene pipeline for the subpass `pc` records into: `color_count` colour attachments,
    /// depth compared in `depth`'s direction; running engine material `engine`'s shaders
    /// (from [`Self::engine_for`]) or tilegraph's.
    pub fn scene(
        &mut self,
        pc: &PassContext<'_>,
        (variant, engine): (Variant, Option<u32>),
        double_sided: bool,
        color_count: u32,
        depth: DepthConvention,
    ) -> Result<vk::Pipeline, VkError> {
        let key = PipelineKey::Scene {
            variant,
            double_sided,
            reverse_z: depth == DepthConvention::Reverse,
            engine,
        };
        let layouts = (self.scene_layout, self.input_layout, self.sampled_layout);
        let shaders = self.shaders;
        let textures = self.textures;
        let material = engine.and_then(|k| self.materials.get(k as usize).cloned());
        self.get_or_create(pc, key, |target| {
            let target = with_colors(target, color_count);
            let material_shaders = material.as_deref().and_then(|m| {
                material_pass(variant)
                    .and_then(|p| m.shaders(p))
                    .map(|s| (s, m.layout))
            });
            scene_pipeline(
                pc,
                target,
                layouts,
                (variant, double_sided, depth),
                shaders,
                textures,
                material_shaders,
            )
        })
    }

    /// An occlusion proxy's pipeline (`layout`: the proxy's own) for the subpass `pc` records
    /// into: depth tested against the frame's depth, nothing written, front faces only. The box
    /// encloses its object, so where the object is in front of the depth the box is too, or
    /// level with it: hence OR_EQUAL; and seen from outside, a box's front face is nearer than
    /// its back face at every pixel, so the back faces add fragments and no answer. A box the
    /// camera is in or that reaches the near plane (or its guard band, [`NEAR_GUARD`](crate::occlusion::queries::NEAR_GUARD)) is not
    /// drawn: queries skip it and draw its instances, raster occlusion's culling counts it
    /// visible.
    ///
    /// The box's depth is biased toward the eye by [`PROXY_DEPTH_BIAS`] units of the depth
    /// format: where a box face and the surface it encloses round to the same depth (depths
    /// crowded near 1.0 by a tiny near plane and standard depth, where the pixel of padding the
    /// box gets is less than an ulp), an interpolation error of an ulp must not put the box
    /// behind its own surface.
    pub fn proxy(
        &mut self,
        pc: &PassContext<'_>,
        proxy: Proxy,
        layout: vk::PipelineLayout,
        depth: DepthConvention,
    ) -> Result<vk::Pipeline, VkError> {
        let reverse = depth == DepthConvention::Reverse;
        let key = PipelineKey::Proxy {
            proxy,
            reverse_z: reverse,
        };
        self.get_or_create(pc, key, |target| {
            let scale;
            let (vertex, fragment) = match proxy {
                Proxy::QueryBox => (stage("oq_box.vert", spv::OQ_BOX_VS), None),
                Proxy::RasterBox { scale: s } => {
                    scale = [(0, s)];
                    (
                        Stage {
                            name: "raster_occlusion.vert",
                            spirv: spv::RASTER_VS,
                            specialization: &scale,
                        },
                        Some(stage("raster_occlusion.frag", spv::RASTER_FS)),
                    )
                }
            };
            create_described_pipeline(
                pc.ctx,
                &GraphicsDesc {
                    name: pc.pass_name,
                    vertex,
                    fragment,
                    vertex_layout: None,
                    layout,
                    target,
                    depth: DepthState {
                        test: true,
                        write: false,
                        compare: if reverse {
                            vk::CompareOp::GREATER_OR_EQUAL
                        } else {
                            vk::CompareOp::LESS_OR_EQUAL
                        },
                        bias: if reverse {
                            PROXY_DEPTH_BIAS
                        } else {
                            -PROXY_DEPTH_BIAS
                        },
                        slope_bias: 0.0,
                        clamp: false,
                    },
                    blend: Blend::NoColorWrites,
                    // The box triangles wind counter-clockwise seen from outside, as glTF's do.
                    cull: vk::CullModeFlags::BACK,
                    samples: vk::SampleCountFlags::TYPE_1,
                },
            )
        })
    }

    /// Destroys the pipelines made for render passes older than `floor`
    /// ([`Executor::render_pass_serial_floor`](tilegraph_vk::executor::Executor::render_pass_serial_floor)),
    /// once per floor: those render passes are gone and no frame in flight uses their pipelines.
    pub fn prune(&mut self, ctx: &Context, floor: u64) {
        if floor <= self.pruned_below {
            return;
        }
        self.pruned_below = floor;
        self.cache.retain(|&(serial, _, _), (p, _)| {
            let keep = serial >= floor;
            if !keep {
                // SAFETY: no frame in flight uses it (the executor waited before rebuilding).
                unsafe { ctx.device.destroy_pipeline(*p, None) };
            }
            keep
        });
    }

    /// Graphics pipelines cached now.
    pub fn len(&self) -> usize {
        self.cache.len()
    }

    pub fn is_empty(&self) -> bool {
        self.cache.is_empty()
    }

    /// Destroys every pipeline and layout; the GPU must be idle.
    pub fn destroy(self, ctx: &Context) {
        // SAFETY: the GPU is idle (caller's guarantee); null handles are ignored.
        unsafe {
            for (_, (p, _)) in self.cache {
                ctx.device.destroy_pipeline(p, None);
            }
            ctx.device.destroy_pipeline_layout(self.scene_layout, None);
            ctx.device.destroy_pipeline_layout(self.input_layout, None);
            ctx.device
                .destroy_pipeline_layout(self.sampled_layout, None);
            ctx.device
                .destroy_descriptor_set_layout(self.input_set_layout, None);
            ctx.device
                .destroy_descriptor_set_layout(self.sampled_set_layout, None);
        }
    }
}

/// The render pass `pc` records into; an error naming the pass when there is none (a compute or
/// transfer pass).
pub fn render_pass_of(pc: &PassContext<'_>) -> Result<RenderPassRef, VkError> {
    pc.render_pass.ok_or_else(|| VkError::Invalid {
        what: pc.pass_name.into(),
        reason: "graphics pipelines record inside a render pass".into(),
    })
}

fn stage(name: &'static str, spirv: &'static [u8]) -> Stage<'static> {
    Stage {
        name,
        spirv,
        specialization: &[],
    }
}

pub(crate) fn with_colors(
    target: RenderTarget<'static>,
    color_count: u32,
) -> RenderTarget<'static> {
    match target {
        RenderTarget::Subpass {
            render_pass,
            subpass,
            ..
        } => RenderTarget::Subpass {
            render_pass,
            subpass,
            color_count,
        },
        other => other,
    }
}
