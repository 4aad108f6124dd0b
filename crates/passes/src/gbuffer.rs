//! Deferred texturing (seed 000): a G-buffer pass writes, per pixel, what shading needs from
//! the surface and nothing it can fetch later — the material, the normal, the UV and its
//! screen derivatives, 128 bits in one `RGBA32_UINT` attachment (`shaders/common/gbuffer.glsl`)
//! beside the depth — and a full-screen resolve samples each pixel's textures once and shades
//! it. Unlike the visibility buffer the resolve fetches no vertices (the G-buffer pass
//! interpolated them), and unlike forward the textures are read for visible pixels only. On a
//! tiler the resolve is a subpass of the G-buffer's render pass reading the G-buffer and the
//! depth as input attachments: 128 + 32 bits a pixel, within what tile memory holds, so the
//! G-buffer is transient and never written to memory; on immediate GPUs it samples them.

use tilegraph_graph::{ClearColor, Format, ImageDesc, ImageId, PassId};
use tilegraph_vk::ash::vk;
use tilegraph_vk::executor::PassContext;
use tilegraph_vk::VkError;

use crate::frame::{DrawSource, FrameGraph, Payload, SceneResources};
use crate::pipelines::Variant;
use crate::targets::SceneTargets;
use crate::visbuf::{add_screen_resolve, add_screen_write, ResolveSets};

/// The G-buffer's format: 128 bits a pixel (material and normal, UV, two UV derivatives).
pub const GBUFFER_FORMAT: Format = Format::R32G32B32A32_UINT;

/// Material ids the G-buffer holds (12 bits holding the material + 1; 0 marks the background).
pub const GBUFFER_MATERIALS: u32 = 0xFFF;

/// Declares a G-buffer pass named `name` of phase `phase` (0 clears the G-buffer; two-phase
/// culling's second phase adds to it), drawing opaque then alpha-tested geometry from
/// `source`. Returns the G-buffer, created by the first G-buffer pass.
pub fn add_gbuffer_write(
    g: &mut FrameGraph,
    targets: &mut SceneTargets,
    phase: u32,
    source: DrawSource,
    name: &str,
) -> ImageId {
    let extent = targets.extent;
    let gbuffer = *targets
        .gbuffer
        .get_or_insert_with(|| g.create_image("gbuffer", ImageDesc::new(extent, GBUFFER_FORMAT)));
    // Zero, the background: materials are stored + 1 so that the clear is all zeros, the value
    // fast clears most commonly take (on the H200 it measured the same as all ones).
    let clear = ClearColor::Uint([0; 4]);
    let variant = |alpha| Variant::Gbuffer { alpha };
    add_screen_write(g, targets, (gbuffer, clear), (phase, source, name), variant);
    gbuffer
}

/// Declares the resolve: shades every covered pixel of the colour target from `gbuffer` and
/// the depth, read as input attachments (`input`: tilers, where the resolve merges into the
/// G-buffer's render pass) or sampled.
pub fn add_gbuffer_resolve(
    g: &mut FrameGraph,
    targets: &mut SceneTargets,
    gbuffer: ImageId,
    input: bool,
) -> PassId {
    let depth = targets.depth;
    let record: Payload = Box::new(move |pc, res| record_resolve(pc, res, [gbuffer, depth], input));
    // G-buffer at input_attachment_index 0, depth at 1.
    let images = [gbuffer, depth];
    add_screen_resolve(g, targets, "gbuffer-resolve", (&images, input), record)
}

/// One full-screen triangle of the resolve.
fn record_resolve(
    pc: &mut PassContext<'_>,
    res: &mut SceneResources,
    [gbuffer, depth]: [ImageId; 2],
    input: bool,
) -> Result<(), VkError> {
    let variant = Variant::GbufferResolve { input };
    let pipeline = res
        .pipelines
        .scene(pc, (variant, None), false, 1, res.frame.depth)?;
    pc.set_full_viewport();
    let images = [
        (gbuffer, vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL),
        (depth, vk::ImageLayout::DEPTH_STENCIL_READ_ONLY_OPTIMAL),
    ];
    ResolveSets::bind(pc, res, input, &images)?;
    let d = &pc.ctx.device;
    // SAFETY: recording inside the resolve's subpass, its sets bound.
    unsafe {
        d.cmd_bind_pipeline(pc.cb, vk::PipelineBindPoint::GRAPHICS, pipeline);
        d.cmd_draw(pc.cb, 3, 1, 0, 0);
    }
    Ok(())
}
