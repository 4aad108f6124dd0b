//! GPU hierarchical-Z pyramid build (see docs/CULLING.md for the algorithm it must match):
//! [`add_hiz_build`] declares it on a frame's graph, [`HizBuilder`] records it.
//!
//! The pyramid is one storage buffer of `f32` holding every stored level packed (the base first, each
//! row-major with row 0 at the top); [`HizLayout`] says where each level lives. It is a buffer
//! and not a mip-mapped image because `NpotMode::PadToPow2`'s level 1 (27x13 -> 16x8) is not a
//! Vulkan mip size of the depth buffer, and because plain loads and stores make the result
//! bit-identical to the CPU reference `tilegraph_cull::HizPyramid::build` by construction.
//!
//! [`HizBuilder::record`] records the base level from the depth image (`texelFetch`, no
//! sampler; D16 values are re-derived as the correctly rounded `k / 65535`, which the UNORM
//! conversion does not promise): level 0 as a copy, or level 1 or 2 (knob `hiz_resolution`,
//! [`HizLayout::with_base_level`]) as the farthest depth of each texel's footprint; every
//! further level reduces the one before it with pure
//! min/max (max for `DepthConvention::Standard`, min for `Reverse`), reading the source range
//! the mode's rule picks ([`ReduceRule`]), up to [`FUSED_LEVELS`] levels per dispatch through
//! shared memory (`hiz_reduce_levels.comp`; PadToPow2's level 1 has a dispatch of its own). A
//! buffer barrier separates consecutive dispatches.

mod builder;
mod layout;
mod reproject;

pub use builder::{
    HizBuilder, SampledDepth, HIZ_COPY_SPV, HIZ_REDUCE_LEVELS_SPV, HIZ_REDUCE_SPV,
    LEVELS_WORKGROUP_SIZE, WORKGROUP_SIZE,
};
pub use layout::{
    HizLayout, HizLevelInfo, HizLevelsPush, HizPush, HizStep, ReduceRule, FUSED_LEVELS,
    LEVELS_COARSE_TILE, MAX_PYRAMID_BYTES,
};

use tilegraph_graph::{BufferId, ImageId, PassClass};
use tilegraph_profile::MemoryUse;
use tilegraph_vk::ash::vk;
use tilegraph_vk::{Buffer, Context, VkError};

use crate::frame::{FrameGraph, PassState, Payload};
use crate::gpu_scene::upload;

pub use reproject::{
    add_reprojection, import_reprojection, ReprojectPush, ReprojectState, Reprojected,
};
pub use tilegraph_cull::{AxisScale, DepthConvention, DepthFormat, NpotMode};

/// The pyramid a build wrote: read by culling passes after it (this frame's late phase, or the
/// next frame's single-phase test).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct HizPyramid {
    pub buffer: BufferId,
}

/// Declares the pyramid build: `depth` sampled, every level of `pyramid` (the [`HizState`]'s
/// buffer, imported into the frame) written. The frame's depth convention picks the reduction
/// (the farther depth of each footprint): a camera path may change it from one frame to the
/// next.
pub fn add_hiz_build(g: &mut FrameGraph, depth: ImageId, pyramid: BufferId) -> HizPyramid {
    let build: Payload = Box::new(move |pc, res| {
        let view = pc.image(depth)?.view;
        let buffer = pc.buffer(pyramid)?;
        let convention = res.frame.depth;
        let hiz = res.states.require_mut::<HizState>(pc.pass_name)?;
        // The stored layout follows the frame, for whoever reads the pyramid back.
        hiz.layout.convention = convention;
        // The graph samples depth formats in DEPTH_STENCIL_READ_ONLY_OPTIMAL.
        let source = SampledDepth {
            view,
            layout: vk::ImageLayout::DEPTH_STENCIL_READ_ONLY_OPTIMAL,
        };
        hiz.builder
            .record(pc.ctx, pc.cb, pc.frame_slot, source, buffer, &hiz.layout)?;
        hiz.built_from = Some(convention);
        Ok(())
    });
    // Only compute work on what it declares: it may run on an async compute queue.
    g.compute_pass("hiz-build", PassClass::Compute, build)
        .sampled(depth)
        .storage_read_write(pyramid)
        .async_compute();
    HizPyramid { buffer: pyramid }
}

/// The pyramid a renderer keeps across frames: its buffer, the level table the culling shader
/// reads, the build's pipelines, and the convention of the depth it was last built from.
pub struct HizState {
    pub layout: HizLayout,
    pub pyramid: Buffer,
    /// `Levels` of `cull.comp` ([`level_table`]).
    pub levels: Buffer,
    builder: HizBuilder,
    /// The depth convention of the depth the pyramid was last built from (`None`: never
    /// built). Single-phase HiZ tests a frame against the previous frame's pyramid only when
    /// the conventions agree: a pyramid of the other convention holds the wrong extreme of each
    /// footprint, and its reprojection maps depth the other way.
    pub built_from: Option<DepthConvention>,
}

impl HizState {
    /// The pyramid of a `format` depth buffer of `extent_px`, built with `mode`, its finest
    /// stored level `base_level` (0 full resolution, 1 half, 2 quarter: knob `hiz_resolution`).
    pub fn new(
        ctx: &Context,
        extent_px: (u32, u32),
        mode: NpotMode,
        depth: DepthConvention,
        format: DepthFormat,
        base_level: u32,
        frames_in_flight: usize,
    ) -> Result<Self, VkError> {
        let per_dispatch = ctx.profile().passes.hiz_levels_per_dispatch as usize;
        let layout = HizLayout::new(extent_px, mode, depth, format)?
            .with_base_level(base_level)
            .with_levels_per_dispatch(per_dispatch);
        let storage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let pyramid = ctx.create_buffer(
            "hiz pyramid",
            layout.size_bytes(),
            storage | vk::BufferUsageFlags::TRANSFER_SRC,
            MemoryUse::GpuOnly,
        )?;
        let table = level_table(&layout);
        let levels = match upload(ctx, "hiz levels", bytemuck::cast_slice(&table), storage) {
            Ok(l) => l,
            Err(e) => {
                ctx.destroy_buffer(pyramid);
                return Err(e);
            }
        };
        match HizBuilder::new(ctx, frames_in_flight) {
            Ok(builder) => Ok(HizState {
                layout,
                pyramid,
                levels,
                builder,
                built_from: None,
            }),
            Err(e) => {
                ctx.destroy_buffer(pyramid);
                ctx.destroy_buffer(levels);
                Err(e)
            }
        }
    }
}

/// What the culling shader's parameters say of the pyramid.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PyramidInfo {
    pub levels: u32,
    /// The depth buffer's size (pixels the level table maps from).
    pub extent_px: (u32, u32),
    /// The convention of the depth it was last built from.
    pub built_from: Option<DepthConvention>,
    /// The depth's format: a D16 pyramid holds codes.
    pub format: DepthFormat,
}

impl HizState {
    pub fn info(&self) -> PyramidInfo {
        PyramidInfo {
            levels: self.layout.levels.len() as u32,
            extent_px: self.layout.extent_px(),
            built_from: self.built_from,
            format: self.layout.format,
        }
    }
}

impl PassState for HizState {
    fn destroy(self: Box<Self>, ctx: &Context) {
        self.builder.destroy(ctx);
        ctx.destroy_buffer(self.pyramid);
        ctx.destroy_buffer(self.levels);
    }
}

/// `Levels` of `cull.comp`: per stored level (offset, width, height, 0) and the depth-pixel ->
/// texel scale.
pub fn level_table(layout: &HizLayout) -> Vec<[u32; 4]> {
    layout
        .levels
        .iter()
        .flat_map(|l| {
            [
                [l.offset_texels as u32, l.width, l.height, 0],
                [
                    l.scale_x.texels,
                    l.scale_x.pixels,
                    l.scale_y.texels,
                    l.scale_y.pixels,
                ],
            ]
        })
        .collect()
}
