//! Each scene variant's shaders and fixed-function state ([`scene_pipeline`]).

use tilegraph_profile::TextureBinding;
use tilegraph_scene::DepthConvention;
use tilegraph_vk::ash::vk;
use tilegraph_vk::executor::PassContext;
use tilegraph_vk::pipeline::{
    create_described_pipeline, Blend, DepthState, GraphicsDesc, RenderTarget, Stage, VertexLayout,
};
use tilegraph_vk::VkError;

use super::{stage, ColourDepth, DescribedPipeline, Variant, NORMAL, POSITION, UV, VERTEX_STRIDE};
use crate::depth_test::{nearer, nearer_or_equal};
use crate::draws::DrawClass;
use crate::materials::MaterialShaders;
use crate::probe::StageProbe;
use crate::spv;

/// (vertex stage, fragment stage, vertex attributes, depth state, blend, layout) of a variant.
type VariantState<'a> = (
    Stage<'a>,
    Option<Stage<'a>>,
    &'a [(u32, vk::Format, u32)],
    DepthState,
    Blend,
    vk::PipelineLayout,
);

/// Describes and creates one scene variant's pipeline.
pub(super) fn scene_pipeline(
    pc: &PassContext<'_>,
    target: RenderTarget<'_>,
    (scene_layout, input_layout, sampled_layout): (
        vk::PipelineLayout,
        vk::PipelineLayout,
        vk::PipelineLayout,
    ),
    (variant, double_sided, depth): (Variant, bool, DepthConvention),
    (count_fragments, probe): (bool, StageProbe),
    (texture_binding, texture_slots): (TextureBinding, u32),
    engine: Option<(&MaterialShaders, vk::PipelineLayout)>,
) -> Result<DescribedPipeline, VkError> {
    // Specialization 1 of every fragment shader: TEXTURE_SLOTS (textures.glsl, ignored by the
    // layers builds); 0 is the variant's own where it has one.
    let slots_spec = [(1, texture_slots)];
    let layers = texture_binding == TextureBinding::Layers;
    let pick = |indexed: &'static [u8], with_layers: &'static [u8]| {
        if layers {
            with_layers
        } else {
            indexed
        }
    };
    let write = DepthState {
        test: true,
        write: true,
        compare: nearer(depth),
        bias: 0,
        slope_bias: 0.0,
        clamp: false,
    };
    let pos_only = [POSITION];
    let pos_uv = [POSITION, UV];
    let all = [POSITION, NORMAL, UV];
    let class_spec: [(u32, u32); 2];
    let forward_spec: [(u32, u32); 3];
    let vertex_spec = [(0, u32::from(probe.trivial_vertex))];
    let (vs, fs, attrs, depth_state, blend, layout): VariantState<'_> = match variant {
        Variant::DepthOpaque => (
            Stage {
                name: "depth.vert",
                spirv: spv::DEPTH_VS,
                specialization: &vertex_spec,
            },
            None,
            &pos_only,
            write,
            Blend::NoColorWrites,
            scene_layout,
        ),
        Variant::DepthAlpha => (
            stage("depth_alpha.vert", spv::DEPTH_ALPHA_VS),
            Some(Stage {
                name: "depth_alpha.frag",
                spirv: pick(spv::DEPTH_ALPHA_FS, spv::DEPTH_ALPHA_LAYERS_FS),
                specialization: &slots_spec,
            }),
            &pos_uv,
            write,
            Blend::NoColorWrites,
            scene_layout,
        ),
        Variant::Forward {
            class,
            depth: colour_depth,
        } => {
            forward_spec = [
                (0, class.index()),
                (1, texture_slots),
                (2, u32::from(probe.trivial_fragment)),
            ];
            let depth_state = match (class, colour_depth) {
                (DrawClass::Blended, _) => DepthState {
                    test: true,
                    write: false,
                    compare: nearer(depth),
                    bias: 0,
                    slope_bias: 0.0,
                    clamp: false,
                },
                (_, ColourDepth::Equal) => DepthState {
                    test: true,
                    write: false,
                    compare: vk::CompareOp::EQUAL,
                    bias: 0,
                    slope_bias: 0.0,
                    clamp: false,
                },
                (_, ColourDepth::WriteOrEqual) => DepthState {
                    test: true,
                    write: true,
                    compare: nearer_or_equal(depth),
                    bias: 0,
                    slope_bias: 0.0,
                    clamp: false,
                },
                (_, ColourDepth::Write) => write,
            };
            let depth_state = if probe.no_depth_test {
                DepthState::OFF
            } else {
                depth_state
            };
            let blend = if class == DrawClass::Blended {
                Blend::Alpha
            } else {
                Blend::Opaque
            };
            // Early fragment tests unless a discard decides what depth is written (alpha
            // tested without a pre-pass): seed 003, discard disables early-Z.
            let late = class == DrawClass::AlphaTested && colour_depth != ColourDepth::Equal;
            let (fs_name, fs) = match (late, count_fragments) {
                _ if probe.late_depth => (
                    "forward_late_depth.frag",
                    pick(
                        spv::FORWARD_LATE_DEPTH_FS,
                        spv::FORWARD_LATE_DEPTH_LAYERS_FS,
                    ),
                ),
                (true, true) => (
                    "forward_count_late.frag",
                    pick(
                        spv::FORWARD_COUNT_LATE_FS,
                        spv::FORWARD_COUNT_LATE_LAYERS_FS,
                    ),
                ),
                (true, false) => (
                    "forward.frag",
                    pick(spv::FORWARD_FS, spv::FORWARD_LAYERS_FS),
                ),
                (false, true) => (
                    "forward_count.frag",
                    pick(spv::FORWARD_COUNT_FS, spv::FORWARD_COUNT_LAYERS_FS),
                ),
                (false, false) => (
                    "forward_early.frag",
                    pick(spv::FORWARD_EARLY_FS, spv::FORWARD_EARLY_LAYERS_FS),
                ),
            };
            (
                Stage {
                    name: "forward.vert",
                    spirv: spv::FORWARD_VS,
                    specialization: &vertex_spec,
                },
                Some(Stage {
                    name: fs_name,
                    spirv: fs,
                    specialization: &forward_spec,
                }),
                &all,
                depth_state,
                blend,
                scene_layout,
            )
        }
        Variant::Visbuf { alpha } => {
            class_spec = [(0, u32::from(alpha)), (1, texture_slots)];
            (
                stage("visbuf.vert", spv::VISBUF_VS),
                Some(Stage {
                    name: "visbuf.frag",
                    spirv: pick(spv::VISBUF_FS, spv::VISBUF_LAYERS_FS),
                    specialization: &class_spec,
                }),
                &pos_uv,
                write,
                Blend::Opaque,
                scene_layout,
            )
        }
        Variant::Gbuffer { alpha } => {
            class_spec = [(0, u32::from(alpha)), (1, texture_slots)];
            (
                stage("gbuffer.vert", spv::GBUFFER_VS),
                Some(Stage {
                    name: "gbuffer.frag",
                    spirv: pick(spv::GBUFFER_FS, spv::GBUFFER_LAYERS_FS),
                    specialization: &class_spec,
                }),
                &all,
                write,
                Blend::Opaque,
                scene_layout,
            )
        }
        Variant::GbufferResolve { input } => {
            let (name, spirv, layout) = match input {
                true => (
                    "gbuffer_resolve_input.frag",
                    pick(spv::GBUFFER_INPUT_FS, spv::GBUFFER_INPUT_LAYERS_FS),
                    input_layout,
                ),
                false => (
                    "gbuffer_resolve_sampled.frag",
                    pick(spv::GBUFFER_SAMPLED_FS, spv::GBUFFER_SAMPLED_LAYERS_FS),
                    sampled_layout,
                ),
            };
            (
                stage("fullscreen.vert", spv::FULLSCREEN_VS),
                Some(Stage {
                    name,
                    spirv,
                    specialization: &slots_spec,
                }),
                &[],
                DepthState::OFF,
                Blend::Opaque,
                layout,
            )
        }
        Variant::ResolveInput => (
            stage("fullscreen.vert", spv::FULLSCREEN_VS),
            Some(Stage {
                name: "visbuf_resolve_input.frag",
                spirv: pick(spv::RESOLVE_INPUT_FS, spv::RESOLVE_INPUT_LAYERS_FS),
                specialization: &slots_spec,
            }),
            &[],
            DepthState::OFF,
            Blend::Opaque,
            input_layout,
        ),
        Variant::ResolveSampled => (
            stage("fullscreen.vert", spv::FULLSCREEN_VS),
            Some(Stage {
                name: "visbuf_resolve_sampled.frag",
                spirv: pick(spv::RESOLVE_SAMPLED_FS, spv::RESOLVE_SAMPLED_LAYERS_FS),
                specialization: &slots_spec,
            }),
            &[],
            DepthState::OFF,
            Blend::Opaque,
            sampled_layout,
        ),
    };
    // An engine material runs its shaders, with its layout, in this variant's fixed-function
    // state; its vertex shader gets every attribute.
    let (vs, fs, attrs, layout) = match engine {
        None => (vs, fs, attrs, layout),
        Some((shaders, engine_layout)) => {
            if shaders.fragment.is_none()
                && (variant == Variant::DepthAlpha || matches!(variant, Variant::Forward { .. }))
            {
                return Err(VkError::Invalid {
                    what: format!("engine material shaders {:?}", shaders.vertex.name),
                    reason: "a colour or alpha-tested depth pass needs a fragment shader".into(),
                });
            }
            (
                Stage {
                    name: &shaders.vertex.name,
                    spirv: &shaders.vertex.spirv,
                    specialization: &[],
                },
                shaders.fragment.as_ref().map(|f| Stage {
                    name: &f.name,
                    spirv: &f.spirv,
                    specialization: &[],
                }),
                &all[..],
                engine_layout,
            )
        }
    };
    let vertex_layout = (!attrs.is_empty()).then_some(VertexLayout {
        stride: VERTEX_STRIDE,
        attributes: attrs,
    });
    let fullscreen = matches!(
        variant,
        Variant::ResolveInput | Variant::ResolveSampled | Variant::GbufferResolve { .. }
    );
    create_described_pipeline(
        pc.ctx,
        &GraphicsDesc {
            name: pc.pass_name,
            vertex: vs,
            fragment: fs,
            vertex_layout,
            layout,
            target,
            depth: depth_state,
            blend,
            cull: if double_sided || fullscreen {
                vk::CullModeFlags::NONE
            } else {
                vk::CullModeFlags::BACK
            },
            samples: vk::SampleCountFlags::TYPE_1,
        },
    )
}
