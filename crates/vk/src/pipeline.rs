//! Graphics and compute pipeline creation from a small description, so passes state what they
//! want (depth test, blend, cull, target) instead of filling Vulkan structs by hand.

use ash::vk;

use tilegraph_profile::lint::{ColorWrites, DepthCompare, DrawState, StencilUse};

use crate::error::{VkError, VkResultExt};
use crate::shader::create_shader_module;
use crate::shader_facts::fragment_facts;
use crate::Context;

/// Where a graphics pipeline renders.
#[derive(Debug, Clone, Copy)]
pub enum RenderTarget<'a> {
    /// Dynamic rendering with these formats.
    Dynamic {
        color: &'a [vk::Format],
        depth: vk::Format,
    },
    /// A subpass of a render pass (the tiler path).
    Subpass {
        render_pass: vk::RenderPass,
        subpass: u32,
        color_count: u32,
    },
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Blend {
    /// Colour written as is.
    Opaque,
    /// Straight alpha blending (src alpha, 1 - src alpha).
    Alpha,
    /// No colour written at all (depth-only or side-effect-only pipelines).
    NoColorWrites,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DepthState {
    pub test: bool,
    pub write: bool,
    pub compare: vk::CompareOp,
    /// Constant depth bias in the depth format's own units (a float format's ulp at the
    /// primitive's largest depth, 1/65535 for D16; spec "Depth Bias"), applied after clipping;
    /// 0 leaves it off.
    pub bias: i32,
    /// Depth bias per unit of the primitive's depth slope (shadow maps: the steeper a caster's
    /// surface seen from the light, the more it is pushed back); 0 leaves it off.
    pub slope_bias: f32,
    /// Clamp depth to the viewport's range instead of clipping at the near and far planes
    /// (`depthClamp`; shadow maps: casters nearer the light than the near plane still write).
    pub clamp: bool,
}

impl DepthState {
    pub const OFF: DepthState = DepthState {
        test: false,
        write: false,
        compare: vk::CompareOp::ALWAYS,
        bias: 0,
        slope_bias: 0.0,
        clamp: false,
    };
}

/// The vertex layout of the scene's shared vertex buffer (`tilegraph_scene::Vertex`, 32 bytes):
/// location 0 position, 1 normal, 2 uv; `attributes` picks which locations the shader reads.
#[derive(Debug, Clone, Copy)]
pub struct VertexLayout<'a> {
    pub stride: u32,
    /// (location, format, offset)
    pub attributes: &'a [(u32, vk::Format, u32)],
}

/// One shader stage: SPIR-V bytes and optional u32 specialization constants (id, value).
#[derive(Debug, Clone, Copy)]
pub struct Stage<'a> {
    pub name: &'a str,
    pub spirv: &'a [u8],
    pub specialization: &'a [(u32, u32)],
}

#[derive(Debug, Clone, Copy)]
pub struct GraphicsDesc<'a> {
    pub name: &'a str,
    pub vertex: Stage<'a>,
    pub fragment: Option<Stage<'a>>,
    pub vertex_layout: Option<VertexLayout<'a>>,
    pub layout: vk::PipelineLayout,
    pub target: RenderTarget<'a>,
    pub depth: DepthState,
    pub blend: Blend,
    pub cull: vk::CullModeFlags,
    pub samples: vk::SampleCountFlags,
}

struct SpecData {
    entries: Vec<vk::SpecializationMapEntry>,
    data: Vec<u8>,
}

fn spec(consts: &[(u32, u32)]) -> SpecData {
    let entries = consts
        .iter()
        .enumerate()
        .map(|(i, (id, _))| vk::SpecializationMapEntry {
            constant_id: *id,
            offset: (i * 4) as u32,
            size: 4,
        })
        .collect();
    let data = consts.iter().flat_map(|(_, v)| v.to_le_bytes()).collect();
    SpecData { entries, data }
}

/// Creates a graphics pipeline (dynamic viewport and scissor, triangle lists, CCW front faces:
/// the projection's y flip keeps glTF's counter-clockwise fronts counter-clockwise on screen).
pub fn create_graphics_pipeline(
    ctx: &Context,
    desc: &GraphicsDesc<'_>,
) -> Result<vk::Pipeline, VkError> {
    let mut modules = Vec::new();
    let result = (|| {
        let vs = create_shader_module(ctx, desc.vertex.name, desc.vertex.spirv)?;
        modules.push(vs);
        let vs_spec = spec(desc.vertex.specialization);
        let vs_info = vk::SpecializationInfo::default()
            .map_entries(&vs_spec.entries)
            .data(&vs_spec.data);
        let mut stages = vec![vk::PipelineShaderStageCreateInfo::default()
            .stage(vk::ShaderStageFlags::VERTEX)
            .module(vs)
            .name(c"main")
            .specialization_info(&vs_info)];
        let fs_spec = desc.fragment.map(|f| spec(f.specialization));
        let fs_info = fs_spec.as_ref().map(|s| {
            vk::SpecializationInfo::default()
                .map_entries(&s.entries)
                .data(&s.data)
        });
        if let (Some(f), Some(info)) = (desc.fragment, fs_info.as_ref()) {
            let fs = create_shader_module(ctx, f.name, f.spirv)?;
            modules.push(fs);
            stages.push(
                vk::PipelineShaderStageCreateInfo::default()
                    .stage(vk::ShaderStageFlags::FRAGMENT)
                    .module(fs)
                    .name(c"main")
                    .specialization_info(info),
            );
        }
        let bindings: Vec<vk::VertexInputBindingDescription> = desc
            .vertex_layout
            .iter()
            .map(|l| vk::VertexInputBindingDescription {
                binding: 0,
                stride: l.stride,
                input_rate: vk::VertexInputRate::VERTEX,
            })
            .collect();
        let attributes: Vec<vk::VertexInputAttributeDescription> = desc
            .vertex_layout
            .iter()
            .flat_map(|l| l.attributes.iter())
            .map(
                |&(location, format, offset)| vk::VertexInputAttributeDescription {
                    location,
                    binding: 0,
                    format,
                    offset,
                },
            )
            .collect();
        let vertex_input = vk::PipelineVertexInputStateCreateInfo::default()
            .vertex_binding_descriptions(&bindings)
            .vertex_attribute_descriptions(&attributes);
        let assembly = vk::PipelineInputAssemblyStateCreateInfo::default()
            .topology(vk::PrimitiveTopology::TRIANGLE_LIST);
        let viewport_state = vk::PipelineViewportStateCreateInfo::default()
            .viewport_count(1)
            .scissor_count(1);
        let raster = vk::PipelineRasterizationStateCreateInfo::default()
            .polygon_mode(vk::PolygonMode::FILL)
            .cull_mode(desc.cull)
            .front_face(vk::FrontFace::COUNTER_CLOCKWISE)
            .depth_clamp_enable(desc.depth.clamp)
            .depth_bias_enable(desc.depth.bias != 0 || desc.depth.slope_bias != 0.0)
            .depth_bias_constant_factor(desc.depth.bias as f32)
            .depth_bias_slope_factor(desc.depth.slope_bias)
            .line_width(1.0);
        let multisample =
            vk::PipelineMultisampleStateCreateInfo::default().rasterization_samples(desc.samples);
        let depth = vk::PipelineDepthStencilStateCreateInfo::default()
            .depth_test_enable(desc.depth.test)
            .depth_write_enable(desc.depth.write)
            .depth_compare_op(desc.depth.compare);
        let color_count = match desc.target {
            RenderTarget::Dynamic { color, .. } => color.len() as u32,
            RenderTarget::Subpass { color_count, .. } => color_count,
        };
        let attachment = match desc.blend {
            Blend::Opaque => vk::PipelineColorBlendAttachmentState::default()
                .color_write_mask(vk::ColorComponentFlags::RGBA),
            Blend::NoColorWrites => vk::PipelineColorBlendAttachmentState::default(),
            Blend::Alpha => vk::PipelineColorBlendAttachmentState::default()
                .blend_enable(true)
                .src_color_blend_factor(vk::BlendFactor::SRC_ALPHA)
                .dst_color_blend_factor(vk::BlendFactor::ONE_MINUS_SRC_ALPHA)
                .color_blend_op(vk::BlendOp::ADD)
                .src_alpha_blend_factor(vk::BlendFactor::ONE)
                .dst_alpha_blend_factor(vk::BlendFactor::ONE_MINUS_SRC_ALPHA)
                .alpha_blend_op(vk::BlendOp::ADD)
                .color_write_mask(vk::ColorComponentFlags::RGBA),
        };
        let attachments = vec![attachment; color_count as usize];
        let blend = vk::PipelineColorBlendStateCreateInfo::default().attachments(&attachments);
        let dynamic = [vk::DynamicState::VIEWPORT, vk::DynamicState::SCISSOR];
        let dynamic_state = vk::PipelineDynamicStateCreateInfo::default().dynamic_states(&dynamic);
        let mut info = vk::GraphicsPipelineCreateInfo::default()
            .stages(&stages)
            .vertex_input_state(&vertex_input)
            .input_assembly_state(&assembly)
            .viewport_state(&viewport_state)
            .rasterization_state(&raster)
            .multisample_state(&multisample)
            .depth_stencil_state(&depth)
            .color_blend_state(&blend)
            .dynamic_state(&dynamic_state)
            .layout(desc.layout);
        let color_formats: Vec<vk::Format>;
        let mut rendering;
        match desc.target {
            RenderTarget::Dynamic { color, depth } => {
                color_formats = color.to_vec();
                rendering = vk::PipelineRenderingCreateInfo::default()
                    .color_attachment_formats(&color_formats)
                    .depth_attachment_format(depth);
                info = info.push_next(&mut rendering);
            }
            RenderTarget::Subpass {
                render_pass,
                subpass,
                ..
            } => {
                info = info.render_pass(render_pass).subpass(subpass);
            }
        }
        ctx.injected_fault_at(
            crate::FaultSite::PipelineCreation,
            "vkCreateGraphicsPipelines (injected fault)",
        )?;
        // SAFETY: every referenced state struct outlives the call.
        let pipelines = unsafe {
            ctx.device
                .create_graphics_pipelines(vk::PipelineCache::null(), &[info], None)
        }
        .map_err(|(_, r)| VkError::call("vkCreateGraphicsPipelines", r))?;
        let p = pipelines.first().copied().ok_or_else(|| VkError::Invalid {
            what: desc.name.to_string(),
            reason: "no pipeline returned".into(),
        })?;
        ctx.set_name(p, desc.name);
        Ok(p)
    })();
    for m in modules {
        // SAFETY: modules are only needed during pipeline creation.
        unsafe { ctx.device.destroy_shader_module(m, None) };
    }
    result
}

/// A graphics pipeline and what the state lint knows of it.
#[derive(Debug, Clone)]
pub struct DescribedPipeline {
    pub pipeline: vk::Pipeline,
    pub state: DrawState,
}

/// Creates a graphics pipeline together with its [`DrawState`], both from `desc`: what the
/// lint checks is what was created.
pub fn create_described_pipeline(
    ctx: &Context,
    desc: &GraphicsDesc<'_>,
) -> Result<DescribedPipeline, VkError> {
    let state = draw_state(desc)?;
    let pipeline = create_graphics_pipeline(ctx, desc)?;
    Ok(DescribedPipeline { pipeline, state })
}

/// The state lint's view of a pipeline: its fixed-function state, and the facts of its
/// fragment shader under its specialization. Named by the fragment shader (the vertex shader
/// for a depth-only pipeline) and its specialization constants.
pub fn draw_state(desc: &GraphicsDesc<'_>) -> Result<DrawState, VkError> {
    let facts = match desc.fragment {
        Some(f) => fragment_facts(f.name, f.spirv, f.specialization)?,
        None => Default::default(),
    };
    let stage = desc.fragment.unwrap_or(desc.vertex);
    let mut pipeline = stage.name.to_string();
    for (id, value) in stage.specialization {
        pipeline.push_str(&format!(" [{id}={value}]"));
    }
    let color_count = match desc.target {
        RenderTarget::Dynamic { color, .. } => color.len() as u32,
        RenderTarget::Subpass { color_count, .. } => color_count,
    };
    let writes_color = color_count > 0 && desc.blend != Blend::NoColorWrites;
    Ok(DrawState {
        pipeline,
        depth_test: desc.depth.test,
        // Vulkan writes no depth when the test is off.
        depth_write: desc.depth.test && desc.depth.write,
        depth_compare: compare(desc.depth.compare),
        blend: desc.blend == Blend::Alpha && writes_color,
        color_writes: if writes_color {
            ColorWrites::All
        } else {
            ColorWrites::None
        },
        // Every attachment gets the same blend state (`create_graphics_pipeline`).
        attachments_differ: false,
        discard: facts.discard,
        alpha_to_coverage: false,
        shader_depth_write: facts.depth_write,
        storage_writes: facts.storage_writes,
        early_fragment_tests: facts.early_fragment_tests,
        stencil: StencilUse::Off,
        secondary_command_buffer: false,
    })
}

fn compare(op: vk::CompareOp) -> DepthCompare {
    match op {
        vk::CompareOp::NEVER => DepthCompare::Never,
        vk::CompareOp::LESS => DepthCompare::Less,
        vk::CompareOp::EQUAL => DepthCompare::Equal,
        vk::CompareOp::LESS_OR_EQUAL => DepthCompare::LessOrEqual,
        vk::CompareOp::GREATER => DepthCompare::Greater,
        vk::CompareOp::NOT_EQUAL => DepthCompare::NotEqual,
        vk::CompareOp::GREATER_OR_EQUAL => DepthCompare::GreaterOrEqual,
        _ => DepthCompare::Always,
    }
}

/// A nearest-filtering, clamp-to-edge sampler for single-level images read texel by texel
/// (depth, ids). The same mode on every axis and no LOD clamp, as Arm's best practices ask.
pub fn create_nearest_sampler(ctx: &Context) -> Result<vk::Sampler, VkError> {
    let info = vk::SamplerCreateInfo::default()
        .mag_filter(vk::Filter::NEAREST)
        .min_filter(vk::Filter::NEAREST)
        .mipmap_mode(vk::SamplerMipmapMode::NEAREST)
        .address_mode_u(vk::SamplerAddressMode::CLAMP_TO_EDGE)
        .address_mode_v(vk::SamplerAddressMode::CLAMP_TO_EDGE)
        .address_mode_w(vk::SamplerAddressMode::CLAMP_TO_EDGE)
        .max_lod(vk::LOD_CLAMP_NONE);
    // SAFETY: valid create info.
    unsafe { ctx.device.create_sampler(&info, None) }.vk("vkCreateSampler")
}

/// Creates a compute pipeline.
pub fn create_compute_pipeline(
    ctx: &Context,
    stage: &Stage<'_>,
    layout: vk::PipelineLayout,
) -> Result<vk::Pipeline, VkError> {
    let module = create_shader_module(ctx, stage.name, stage.spirv)?;
    let s = spec(stage.specialization);
    let spec_info = vk::SpecializationInfo::default()
        .map_entries(&s.entries)
        .data(&s.data);
    let info = vk::ComputePipelineCreateInfo::default()
        .stage(
            vk::PipelineShaderStageCreateInfo::default()
                .stage(vk::ShaderStageFlags::COMPUTE)
                .module(module)
                .name(c"main")
                .specialization_info(&spec_info),
        )
        .layout(layout);
    // SAFETY: module and layout are live.
    let r = unsafe {
        ctx.device
            .create_compute_pipelines(vk::PipelineCache::null(), &[info], None)
    };
    // SAFETY: only needed during creation.
    unsafe { ctx.device.destroy_shader_module(module, None) };
    let p = r
        .map_err(|(_, r)| VkError::call("vkCreateComputePipelines", r))?
        .first()
        .copied()
        .ok_or_else(|| VkError::Invalid {
            what: stage.name.to_string(),
            reason: "no pipeline returned".into(),
        })?;
    ctx.set_name(p, stage.name);
    Ok(p)
}

/// A descriptor-set layout from (binding, type, stages) triples, one descriptor each.
pub fn create_set_layout(
    ctx: &Context,
    bindings: &[(u32, vk::DescriptorType, vk::ShaderStageFlags)],
) -> Result<vk::DescriptorSetLayout, VkError> {
    let counted: Vec<_> = bindings.iter().map(|&(b, t, s)| (b, t, s, 1)).collect();
    create_set_layout_counted(ctx, &counted)
}

/// A descriptor-set layout from (binding, type, stages, descriptor count).
pub fn create_set_layout_counted(
    ctx: &Context,
    bindings: &[(u32, vk::DescriptorType, vk::ShaderStageFlags, u32)],
) -> Result<vk::DescriptorSetLayout, VkError> {
    let b: Vec<vk::DescriptorSetLayoutBinding> = bindings
        .iter()
        .map(|&(binding, ty, stages, count)| {
            vk::DescriptorSetLayoutBinding::default()
                .binding(binding)
                .descriptor_type(ty)
                .descriptor_count(count)
                .stage_flags(stages)
        })
        .collect();
    let info = vk::DescriptorSetLayoutCreateInfo::default().bindings(&b);
    // SAFETY: valid create info.
    unsafe { ctx.device.create_descriptor_set_layout(&info, None) }
        .vk("vkCreateDescriptorSetLayout")
}

/// A pipeline layout from set layouts and an optional push-constant range.
pub fn create_pipeline_layout(
    ctx: &Context,
    sets: &[vk::DescriptorSetLayout],
    push: Option<vk::PushConstantRange>,
) -> Result<vk::PipelineLayout, VkError> {
    let ranges: Vec<vk::PushConstantRange> = push.into_iter().collect();
    let info = vk::PipelineLayoutCreateInfo::default()
        .set_layouts(sets)
        .push_constant_ranges(&ranges);
    // SAFETY: valid create info.
    unsafe { ctx.device.create_pipeline_layout(&info, None) }.vk("vkCreatePipelineLayout")
}

/// Allocates one set of `layout` from `pool`.
pub fn allocate_set(
    ctx: &Context,
    pool: vk::DescriptorPool,
    layout: vk::DescriptorSetLayout,
) -> Result<vk::DescriptorSet, VkError> {
    let layouts = [layout];
    let info = vk::DescriptorSetAllocateInfo::default()
        .descriptor_pool(pool)
        .set_layouts(&layouts);
    // SAFETY: live pool and layout; an exhausted pool is reported as an error.
    let sets =
        unsafe { ctx.device.allocate_descriptor_sets(&info) }.vk("vkAllocateDescriptorSets")?;
    sets.first().copied().ok_or_else(|| VkError::Invalid {
        what: "descriptor set".into(),
        reason: "none allocated".into(),
    })
}

/// Points each (binding, type, buffer) of `set` at the whole buffer. The caller guarantees the
/// set is not in use by the GPU.
pub fn write_buffer_set(
    ctx: &Context,
    set: vk::DescriptorSet,
    bindings: &[(u32, vk::DescriptorType, vk::Buffer)],
) {
    let infos: Vec<[vk::DescriptorBufferInfo; 1]> = bindings
        .iter()
        .map(|(_, _, b)| {
            [vk::DescriptorBufferInfo {
                buffer: *b,
                offset: 0,
                range: vk::WHOLE_SIZE,
            }]
        })
        .collect();
    let writes: Vec<vk::WriteDescriptorSet> = bindings
        .iter()
        .zip(&infos)
        .map(|((binding, ty, _), info)| {
            vk::WriteDescriptorSet::default()
                .dst_set(set)
                .dst_binding(*binding)
                .descriptor_type(*ty)
                .buffer_info(info)
        })
        .collect();
    // SAFETY: every buffer is live and the set idle (caller's guarantee).
    unsafe { ctx.device.update_descriptor_sets(&writes, &[]) };
}

#[cfg(test)]
mod tests {
    use tilegraph_profile::lint::{lint, LintDraw, LintRenderPass};
    use tilegraph_profile::{PipelineState, ProfileSet};

    use super::*;

    const DEPTH_ALPHA_VS: &[u8] = include_bytes!("../../../shaders/spv/depth_alpha.vert.spv");
    const DEPTH_ALPHA_FS: &[u8] = include_bytes!("../../../shaders/spv/depth_alpha.frag.spv");

    /// A deliberately bad pipeline — the alpha test's discard, blended, writing depth — and
    /// the opaque draw recorded after it: the state the lint sees comes from the description
    /// and the shader, and each vendor's rules fire on it.
    #[test]
    fn a_bad_pipeline_described_is_what_the_lint_flags() {
        let desc = |blend, fragment| GraphicsDesc {
            name: "bad",
            vertex: Stage {
                name: "depth_alpha.vert",
                spirv: DEPTH_ALPHA_VS,
                specialization: &[],
            },
            fragment,
            vertex_layout: None,
            layout: vk::PipelineLayout::null(),
            target: RenderTarget::Subpass {
                render_pass: vk::RenderPass::null(),
                subpass: 0,
                color_count: 1,
            },
            depth: DepthState {
                test: true,
                write: true,
                compare: vk::CompareOp::GREATER,
                bias: 0,
                slope_bias: 0.0,
                clamp: false,
            },
            blend,
            cull: vk::CullModeFlags::BACK,
            samples: vk::SampleCountFlags::TYPE_1,
        };
        let fs = Stage {
            name: "depth_alpha.frag",
            spirv: DEPTH_ALPHA_FS,
            specialization: &[],
        };
        let bad = draw_state(&desc(Blend::Alpha, Some(fs))).unwrap();
        assert!(bad.discard && bad.blend && bad.depth_write && !bad.early_fragment_tests);
        assert_eq!(bad.pipeline, "depth_alpha.frag");
        let opaque = draw_state(&desc(Blend::Opaque, None)).unwrap();
        assert!(opaque.occluder());
        let rp = LintRenderPass {
            index: 0,
            draws: [bad, opaque]
                .into_iter()
                .map(|state| LintDraw {
                    pass: "engine-bad".into(),
                    state,
                })
                .collect(),
        };
        let set = ProfileSet::embedded().unwrap();
        for (profile, expect) in [
            (
                "adreno-7xx",
                &[
                    PipelineState::DiscardWithDepthWrite,
                    PipelineState::BlendWithDepthWrite,
                    PipelineState::OccluderAfterBlend,
                ][..],
            ),
            (
                "mali-valhall",
                &[
                    PipelineState::DiscardWithDepthWrite,
                    PipelineState::BlendWithDepthWrite,
                    PipelineState::OccluderAfterBlend,
                ],
            ),
            (
                "powervr-b",
                &[
                    PipelineState::DiscardWithDepthWrite,
                    PipelineState::BlendWithDepthWrite,
                    PipelineState::OccluderAfterDiscard,
                    PipelineState::OccluderAfterBlend,
                ],
            ),
            ("lavapipe", &[PipelineState::DiscardWithDepthWrite]),
        ] {
            let findings = lint(set.get(profile).unwrap(), std::slice::from_ref(&rp));
            let mut rules: Vec<&str> = findings.iter().map(|f| f.rule.name()).collect();
            rules.sort_unstable();
            rules.dedup();
            let mut expect: Vec<&str> = expect.iter().map(|r| r.name()).collect();
            expect.sort_unstable();
            assert_eq!(rules, expect, "{profile}: {findings:#?}");
        }
    }
}
