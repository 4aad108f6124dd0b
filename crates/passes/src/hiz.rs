//! GPU hierarchical-Z pyramid build (see docs/CULLING.md for the algorithm it must match):
//! [`add_hiz_build`] declares it on a frame's graph, [`HizBuilder`] records it.
//!
//! The pyramid is one storage buffer of `f32` holding every level packed (level 0 first, each
//! row-major with row 0 at the top); [`HizLayout`] says where each level lives. It is a buffer
//! and not a mip-mapped image because `NpotMode::PadToPow2`'s level 1 (27x13 -> 16x8) is not a
//! Vulkan mip size of the depth buffer, and because plain loads and stores make the result
//! bit-identical to the CPU reference `tilegraph_cull::HizPyramid::build` by construction.
//!
//! [`HizBuilder::record`] records one compute dispatch per level: level 0 copies the depth image
//! (`texelFetch`, no sampler; D16 values are re-derived as the correctly rounded `k / 65535`,
//! which the UNORM conversion does not promise), every further level reduces the one before it
//! with pure min/max (max for `DepthConvention::Standard`, min for `Reverse`), reading the source
//! range the mode's rule picks ([`ReduceRule`]). A buffer barrier separates consecutive levels.

use bytemuck::{Pod, Zeroable};
use tilegraph_cull::{level_extents, Extent2d, ExtentExt};
use tilegraph_graph::{BufferId, ImageId, PassClass};
use tilegraph_profile::MemoryUse;
use tilegraph_vk::ash::vk;
use tilegraph_vk::executor::BufferHandle;
use tilegraph_vk::pipeline::{
    create_compute_pipeline, create_pipeline_layout, create_set_layout, Stage,
};
use tilegraph_vk::{Buffer, Context, VkError};

use crate::frame::{FrameGraph, PassState, Payload};
use crate::gpu_scene::upload;

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
    g.compute_pass("hiz-build", PassClass::Compute, build)
        .sampled(depth)
        .storage_read_write(pyramid);
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
    /// The pyramid of a D32 depth buffer of `extent_px`, built with `mode`.
    pub fn new(
        ctx: &Context,
        extent_px: (u32, u32),
        mode: NpotMode,
        depth: DepthConvention,
        frames_in_flight: usize,
    ) -> Result<Self, VkError> {
        let layout = HizLayout::new(extent_px, mode, depth, DepthFormat::D32Float)?;
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
    /// Level 0's size.
    pub extent_px: (u32, u32),
    /// The convention of the depth it was last built from.
    pub built_from: Option<DepthConvention>,
}

impl HizState {
    pub fn info(&self) -> PyramidInfo {
        PyramidInfo {
            levels: self.layout.levels.len() as u32,
            extent_px: self.layout.extent_px(),
            built_from: self.built_from,
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

/// `Levels` of `cull.comp`: per level (offset, width, height, 0) and the pixel -> texel scale.
pub fn level_table(layout: &HizLayout) -> Vec<[u32; 4]> {
    let mut out = Vec::with_capacity(2 * layout.levels.len());
    let (w0, h0) = layout
        .levels
        .first()
        .map_or((1, 1), |l| (l.width, l.height));
    let (p_w, p_h) = layout.levels.get(1).map_or((1, 1), |l| (l.width, l.height));
    for (k, l) in layout.levels.iter().enumerate() {
        out.push([l.offset_texels as u32, l.width, l.height, 0]);
        let scale = match (layout.mode, k) {
            (_, 0) => [1, 1, 1, 1],
            (NpotMode::PadToPow2, k) => {
                let f = 1u32 << (k - 1);
                [p_w, w0 * f, p_h, h0 * f]
            }
            (_, k) => [1, 1 << k, 1, 1 << k],
        };
        out.push(scale);
    }
    out
}

/// SPIR-V of the level-0 copy (`shaders/hiz_copy.comp`).
pub const HIZ_COPY_SPV: &[u8] = include_bytes!("../../../shaders/spv/hiz_copy.comp.spv");
/// SPIR-V of the reduction (`shaders/hiz_reduce.comp`).
pub const HIZ_REDUCE_SPV: &[u8] = include_bytes!("../../../shaders/spv/hiz_reduce.comp.spv");

/// `local_size_x` and `local_size_y` of both shaders: one thread per destination texel.
pub const WORKGROUP_SIZE: u32 = 8;

/// Largest pyramid accepted, in bytes: the minimum `maxStorageBufferRange` every Vulkan device
/// guarantees (2^27). The whole pyramid is one storage-buffer descriptor, so a larger one could
/// exceed the device's limit (tilegraph-vk does not report the real limit yet). 4096x4096
/// (89 MB) fits; 8192x8192 does not.
pub const MAX_PYRAMID_BYTES: u64 = 1 << 27;

/// Descriptor bindings of set 0 (both shaders; the reduction only uses the pyramid).
const BINDING_DEPTH: u32 = 0;
const BINDING_PYRAMID: u32 = 1;

/// How a level's texel picks its source range, per axis (`shaders/common/hiz.glsl`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ReduceRule {
    /// Level 0: a copy of the depth image (D16: snapped to the exact `k / 65535`).
    Copy,
    /// `2t ..= (t == dst - 1 ? src - 1 : 2t + 1)`: EdgeAware, every level >= 1.
    EdgeAware,
    /// `2t ..= min(2t + 1, src - 1)`: PadToPow2, levels >= 2.
    Halve,
    /// `(t * src) / dst ..= ((t + 1) * src + dst - 1) / dst - 1`: PadToPow2, level 1.
    PadFirst,
}

impl ReduceRule {
    /// The value of `HizPush::rule`: `HIZ_RULE_*` in GLSL, or `HIZ_COPY_*` (the depth format)
    /// for the copy.
    fn gpu_code(self, format: DepthFormat) -> u32 {
        match self {
            ReduceRule::Copy => match format {
                DepthFormat::D32Float => 0,
                DepthFormat::D16Unorm => 1,
            },
            ReduceRule::EdgeAware => 0,
            ReduceRule::Halve => 1,
            ReduceRule::PadFirst => 2,
        }
    }
}

/// Push constants of both shaders; mirrors `HizPush` in `shaders/common/hiz.glsl` (32 bytes;
/// tests/e2e/hiz.rs checks the offsets against the SPIR-V).
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct HizPush {
    /// First texel of the source level in the pyramid buffer (reduction only).
    pub src_offset: u32,
    /// First texel of the level this dispatch writes.
    pub dst_offset: u32,
    /// Source level (reduction) or depth image (copy) size.
    pub src_extent: [u32; 2],
    /// Size of the level this dispatch writes.
    pub dst_extent: [u32; 2],
    /// `HIZ_RULE_*` (reduction) or `HIZ_COPY_*` (copy: 0 D32, 1 D16).
    pub rule: u32,
    /// 0: Standard (max), 1: Reverse (min).
    pub convention: u32,
}

/// Where one level lives in the pyramid buffer, and how level-0 pixels map to its texels.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct HizLevelInfo {
    /// First texel (f32 element) of the level in the buffer.
    pub offset_texels: u64,
    pub width: u32,
    pub height: u32,
    /// Level-0 pixel `p` maps to texel `min(p * texels / pixels, extent - 1)` per axis, as
    /// `tilegraph_cull::HizLevel::scale` (integer arithmetic; fits `uint` for any accepted extent).
    pub scale_x: AxisScale,
    pub scale_y: AxisScale,
    /// Which source texels each texel of this level reads.
    pub rule: ReduceRule,
}

impl HizLevelInfo {
    pub fn texel_count(&self) -> u64 {
        u64::from(self.width) * u64::from(self.height)
    }
}

/// The packed layout of a pyramid for one depth extent, mode, convention and depth format: plain
/// data, no Vulkan handles. Computed from `tilegraph_cull::level_extents`, so it always has the
/// CPU reference's levels.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct HizLayout {
    pub mode: NpotMode,
    pub convention: DepthConvention,
    /// The format of the depth image level 0 is read from. It must be right: a D32 depth read
    /// as D16 would be snapped to the nearest code, which is not conservative.
    pub format: DepthFormat,
    /// Level 0 (the depth buffer's extent) first; the last level is 1x1.
    pub levels: Vec<HizLevelInfo>,
    pub total_texels: u64,
}

impl HizLayout {
    /// The layout for a depth buffer of `extent_px` (width, height) in `format`. Rejects a zero or
    /// oversized extent (`tilegraph_cull::MAX_EXTENT_PX`), `NpotMode::NaiveBuggy` (a reference
    /// for the bug only: the GPU never builds it), and pyramids above [`MAX_PYRAMID_BYTES`].
    pub fn new(
        extent_px: (u32, u32),
        mode: NpotMode,
        convention: DepthConvention,
        format: DepthFormat,
    ) -> Result<Self, VkError> {
        let invalid = |reason: String| VkError::Invalid {
            what: format!("hiz layout {}x{} {mode:?}", extent_px.0, extent_px.1),
            reason,
        };
        if mode == NpotMode::NaiveBuggy {
            return Err(invalid(
                "NaiveBuggy drops the last row/column at odd sizes; the GPU build implements \
                 EdgeAware and PadToPow2 only"
                    .into(),
            ));
        }
        let extent = Extent2d::named("depth extent", extent_px.0, extent_px.1)
            .map_err(|e| invalid(e.to_string()))?;
        let extents = level_extents(extent, mode);
        let (w, h) = (extent.width_px, extent.height_px);
        let (pw, ph) = extents.get(1).map_or((w, h), |e| (e.width_px, e.height_px));
        let mut levels = Vec::with_capacity(extents.len());
        let mut offset = 0u64;
        for (k, e) in extents.iter().enumerate() {
            let k = k as u32;
            let info = HizLevelInfo {
                offset_texels: offset,
                width: e.width_px,
                height: e.height_px,
                scale_x: axis_scale(mode, k, w, pw),
                scale_y: axis_scale(mode, k, h, ph),
                rule: match (mode, k) {
                    (_, 0) => ReduceRule::Copy,
                    (NpotMode::PadToPow2, 1) => ReduceRule::PadFirst,
                    (NpotMode::PadToPow2, _) => ReduceRule::Halve,
                    _ => ReduceRule::EdgeAware,
                },
            };
            offset += info.texel_count();
            levels.push(info);
        }
        let layout = HizLayout {
            mode,
            convention,
            format,
            levels,
            total_texels: offset,
        };
        if layout.size_bytes() > MAX_PYRAMID_BYTES {
            return Err(invalid(format!(
                "the pyramid needs {} bytes, more than the {MAX_PYRAMID_BYTES} bytes every \
                 device can bind as one storage buffer",
                layout.size_bytes()
            )));
        }
        Ok(layout)
    }

    /// Level 0's extent: the depth buffer's.
    pub fn extent_px(&self) -> (u32, u32) {
        self.levels.first().map_or((0, 0), |l| (l.width, l.height))
    }

    /// Bytes the pyramid buffer needs (at least).
    pub fn size_bytes(&self) -> u64 {
        self.total_texels * 4
    }

    /// The texels of `level` within a pyramid read back whole (`None` past the last level or
    /// when `pyramid` is too short).
    pub fn level_texels<'a>(&self, pyramid: &'a [f32], level: usize) -> Option<&'a [f32]> {
        let l = self.levels.get(level)?;
        let start = usize::try_from(l.offset_texels).ok()?;
        let len = usize::try_from(l.texel_count()).ok()?;
        pyramid.get(start..start.checked_add(len)?)
    }

    /// The push constants of every dispatch, level 0 (the copy) first.
    pub fn push_constants(&self) -> Result<Vec<HizPush>, VkError> {
        (0..self.levels.len())
            .map(|k| self.push_for_level(k))
            .collect()
    }

    fn push_for_level(&self, k: usize) -> Result<HizPush, VkError> {
        let dst = self.levels.get(k).ok_or_else(|| VkError::Invalid {
            what: "hiz layout".into(),
            reason: format!("no level {k}"),
        })?;
        // Level 0 "reads" the depth image, which has its own extent.
        let src = k
            .checked_sub(1)
            .and_then(|s| self.levels.get(s))
            .unwrap_or(dst);
        let offset = |texels: u64| {
            u32::try_from(texels).map_err(|_| VkError::Invalid {
                what: "hiz layout".into(),
                reason: format!("texel offset {texels} does not fit a shader uint"),
            })
        };
        Ok(HizPush {
            src_offset: offset(src.offset_texels)?,
            dst_offset: offset(dst.offset_texels)?,
            src_extent: [src.width, src.height],
            dst_extent: [dst.width, dst.height],
            rule: dst.rule.gpu_code(self.format),
            convention: match self.convention {
                DepthConvention::Standard => 0,
                DepthConvention::Reverse => 1,
            },
        })
    }
}

/// The per-axis pixel -> texel scale of level `k` (docs/CULLING.md, "Level-0 pixel -> texel
/// mapping"); `pow2_px` is level 1's size (PadToPow2's `P`). Checked against the CPU
/// reference's `HizLevel::scale` by tests/e2e/hiz.rs.
fn axis_scale(mode: NpotMode, k: u32, level0_px: u32, pow2_px: u32) -> AxisScale {
    match (mode, k) {
        (_, 0) => AxisScale {
            texels: 1,
            pixels: 1,
        },
        (NpotMode::PadToPow2, k) => AxisScale {
            texels: pow2_px,
            pixels: level0_px << (k - 1),
        },
        (NpotMode::EdgeAware | NpotMode::NaiveBuggy, k) => AxisScale {
            texels: 1,
            pixels: 1 << k,
        },
    }
}

/// Layouts a sampled depth image may be in while the build reads it.
const READABLE_DEPTH_LAYOUTS: [vk::ImageLayout; 5] = [
    vk::ImageLayout::DEPTH_STENCIL_READ_ONLY_OPTIMAL,
    vk::ImageLayout::DEPTH_READ_ONLY_OPTIMAL,
    vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL,
    vk::ImageLayout::READ_ONLY_OPTIMAL,
    vk::ImageLayout::GENERAL,
];

/// The depth a build reads: a DEPTH-aspect, single-mip view, sampled in `layout`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SampledDepth {
    pub view: vk::ImageView,
    pub layout: vk::ImageLayout,
}

/// The pipelines and per-frame-slot descriptor sets of the build.
pub struct HizBuilder {
    set_layout: vk::DescriptorSetLayout,
    pipeline_layout: vk::PipelineLayout,
    copy: vk::Pipeline,
    reduce: vk::Pipeline,
    pool: vk::DescriptorPool,
    /// One set per frame-in-flight slot, rewritten by every `record` for that slot.
    sets: Vec<vk::DescriptorSet>,
}

impl HizBuilder {
    /// Creates both pipelines and `frames_in_flight` descriptor sets.
    pub fn new(ctx: &Context, frames_in_flight: usize) -> Result<Self, VkError> {
        if frames_in_flight == 0 {
            return Err(VkError::Invalid {
                what: "hiz builder".into(),
                reason: "frames_in_flight is zero".into(),
            });
        }
        let n = u32::try_from(frames_in_flight).map_err(|_| VkError::Invalid {
            what: "hiz builder".into(),
            reason: format!("frames_in_flight {frames_in_flight} is too large"),
        })?;
        // Start from null handles and fill in; on error, `destroy` skips what is still null
        // (destroying VK_NULL_HANDLE is a no-op in Vulkan).
        let mut b = HizBuilder {
            set_layout: vk::DescriptorSetLayout::null(),
            pipeline_layout: vk::PipelineLayout::null(),
            copy: vk::Pipeline::null(),
            reduce: vk::Pipeline::null(),
            pool: vk::DescriptorPool::null(),
            sets: Vec::new(),
        };
        match b.create(ctx, n) {
            Ok(()) => Ok(b),
            Err(e) => {
                b.destroy(ctx);
                Err(e)
            }
        }
    }

    fn create(&mut self, ctx: &Context, n: u32) -> Result<(), VkError> {
        let compute = vk::ShaderStageFlags::COMPUTE;
        self.set_layout = create_set_layout(
            ctx,
            &[
                (BINDING_DEPTH, vk::DescriptorType::SAMPLED_IMAGE, compute),
                (BINDING_PYRAMID, vk::DescriptorType::STORAGE_BUFFER, compute),
            ],
        )?;
        self.pipeline_layout = create_pipeline_layout(
            ctx,
            &[self.set_layout],
            Some(vk::PushConstantRange {
                stage_flags: compute,
                offset: 0,
                size: std::mem::size_of::<HizPush>() as u32,
            }),
        )?;
        self.copy = create_compute_pipeline(
            ctx,
            &Stage {
                name: "hiz_copy",
                spirv: HIZ_COPY_SPV,
                specialization: &[],
            },
            self.pipeline_layout,
        )?;
        self.reduce = create_compute_pipeline(
            ctx,
            &Stage {
                name: "hiz_reduce",
                spirv: HIZ_REDUCE_SPV,
                specialization: &[],
            },
            self.pipeline_layout,
        )?;
        let sizes = [
            vk::DescriptorPoolSize {
                ty: vk::DescriptorType::SAMPLED_IMAGE,
                descriptor_count: n,
            },
            vk::DescriptorPoolSize {
                ty: vk::DescriptorType::STORAGE_BUFFER,
                descriptor_count: n,
            },
        ];
        let pool_info = vk::DescriptorPoolCreateInfo::default()
            .max_sets(n)
            .pool_sizes(&sizes);
        // SAFETY: valid create info on a live device.
        self.pool = unsafe { ctx.device.create_descriptor_pool(&pool_info, None) }
            .map_err(|r| VkError::call("vkCreateDescriptorPool", r))?;
        ctx.set_name(self.pool, "hiz descriptors");
        let layouts = vec![self.set_layout; n as usize];
        let alloc = vk::DescriptorSetAllocateInfo::default()
            .descriptor_pool(self.pool)
            .set_layouts(&layouts);
        // SAFETY: the pool was sized for exactly `n` sets of this layout.
        self.sets = unsafe { ctx.device.allocate_descriptor_sets(&alloc) }
            .map_err(|r| VkError::call("vkAllocateDescriptorSets", r))?;
        Ok(())
    }

    /// Number of frame slots (descriptor sets).
    pub fn frame_slots(&self) -> usize {
        self.sets.len()
    }

    /// Records the whole build: level 0 from `depth` (a view of an image whose extent is
    /// `layout`'s level 0 and whose format is `layout.format`), then every level. `pyramid` must hold at least `layout.size_bytes()`.
    ///
    /// The caller has already made the depth image readable by compute shaders in
    /// `depth.layout` and made earlier accesses to `pyramid` safe (a graph pass declaring it
    /// StorageReadWrite gets both barriers); this function inserts the barriers *between*
    /// levels only. After it, the pyramid was written by COMPUTE_SHADER / SHADER_STORAGE_WRITE.
    /// The previous use of `frame_slot`'s descriptor set must have completed (the executor's
    /// frames-in-flight guarantee); two builds in one command buffer need two slots.
    pub fn record(
        &mut self,
        ctx: &Context,
        cb: vk::CommandBuffer,
        frame_slot: usize,
        depth: SampledDepth,
        pyramid: BufferHandle,
        layout: &HizLayout,
    ) -> Result<(), VkError> {
        let SampledDepth {
            view: depth_view,
            layout: depth_layout,
        } = depth;
        let invalid = |reason: String| VkError::Invalid {
            what: "hiz build".into(),
            reason,
        };
        let set = *self.sets.get(frame_slot).ok_or_else(|| {
            invalid(format!(
                "frame slot {frame_slot} out of range ({} slots)",
                self.sets.len()
            ))
        })?;
        if !READABLE_DEPTH_LAYOUTS.contains(&depth_layout) {
            return Err(invalid(format!(
                "depth layout {depth_layout:?} is not one a sampled image can be read in"
            )));
        }
        if depth_view == vk::ImageView::null() || pyramid.raw == vk::Buffer::null() {
            return Err(invalid("null depth view or pyramid buffer".into()));
        }
        if pyramid.size < layout.size_bytes() {
            return Err(invalid(format!(
                "pyramid buffer holds {} bytes, the layout needs {}",
                pyramid.size,
                layout.size_bytes()
            )));
        }
        // Checked up front so a bad layout fails before anything is recorded (computed again
        // per dispatch below: no list is kept, nothing allocated per frame).
        let levels = layout.levels.len();
        for k in 0..levels {
            layout.push_for_level(k)?;
        }

        let image_info = [vk::DescriptorImageInfo {
            sampler: vk::Sampler::null(),
            image_view: depth_view,
            image_layout: depth_layout,
        }];
        let buffer_info = [vk::DescriptorBufferInfo {
            buffer: pyramid.raw,
            offset: 0,
            range: layout.size_bytes(),
        }];
        let writes = [
            vk::WriteDescriptorSet::default()
                .dst_set(set)
                .dst_binding(BINDING_DEPTH)
                .descriptor_type(vk::DescriptorType::SAMPLED_IMAGE)
                .image_info(&image_info),
            vk::WriteDescriptorSet::default()
                .dst_set(set)
                .dst_binding(BINDING_PYRAMID)
                .descriptor_type(vk::DescriptorType::STORAGE_BUFFER)
                .buffer_info(&buffer_info),
        ];
        let d = &ctx.device;
        // SAFETY: the set is not in use by pending work (the caller's frame-slot guarantee); the
        // view and buffer are live; the range fits the buffer (checked above) and is below the
        // guaranteed maxStorageBufferRange (HizLayout::new).
        unsafe { d.update_descriptor_sets(&writes, &[]) };
        // SAFETY: `cb` is recording outside a render pass (the caller's contract for a compute
        // pass); the set matches the pipeline layout.
        unsafe {
            d.cmd_bind_descriptor_sets(
                cb,
                vk::PipelineBindPoint::COMPUTE,
                self.pipeline_layout,
                0,
                &[set],
                &[],
            );
        }
        // Between levels: level k's writes become visible to level k+1's reads. The destination
        // also names SHADER_STORAGE_WRITE because the whole buffer is one descriptor: the
        // synchronization validator sees every dispatch as reading and writing all of it.
        let between = [vk::BufferMemoryBarrier2::default()
            .src_stage_mask(vk::PipelineStageFlags2::COMPUTE_SHADER)
            .src_access_mask(vk::AccessFlags2::SHADER_STORAGE_WRITE)
            .dst_stage_mask(vk::PipelineStageFlags2::COMPUTE_SHADER)
            .dst_access_mask(
                vk::AccessFlags2::SHADER_STORAGE_READ | vk::AccessFlags2::SHADER_STORAGE_WRITE,
            )
            .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
            .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
            .buffer(pyramid.raw)
            .offset(0)
            .size(layout.size_bytes())];
        for k in 0..levels {
            let push = &layout.push_for_level(k)?;
            if k > 0 {
                ctx.cmd_pipeline_barrier2(
                    cb,
                    &vk::DependencyInfo::default().buffer_memory_barriers(&between),
                )?;
            }
            let pipeline = if k == 0 { self.copy } else { self.reduce };
            // SAFETY: recording; the pipeline uses `pipeline_layout`, whose push range is exactly
            // one HizPush; the dispatch covers dst_extent (the shaders bound-check the rest).
            unsafe {
                if k <= 1 {
                    d.cmd_bind_pipeline(cb, vk::PipelineBindPoint::COMPUTE, pipeline);
                }
                d.cmd_push_constants(
                    cb,
                    self.pipeline_layout,
                    vk::ShaderStageFlags::COMPUTE,
                    0,
                    bytemuck::bytes_of(push),
                );
                d.cmd_dispatch(
                    cb,
                    push.dst_extent[0].div_ceil(WORKGROUP_SIZE),
                    push.dst_extent[1].div_ceil(WORKGROUP_SIZE),
                    1,
                );
            }
        }
        Ok(())
    }

    /// Destroys the pipelines, layouts and descriptor pool. The GPU must be done with them.
    pub fn destroy(self, ctx: &Context) {
        // SAFETY: the caller guarantees no pending work uses these objects; null handles (a
        // partially created builder) are ignored by vkDestroy*. Freeing the pool frees the sets.
        unsafe {
            ctx.device.destroy_pipeline(self.copy, None);
            ctx.device.destroy_pipeline(self.reduce, None);
            ctx.device.destroy_descriptor_pool(self.pool, None);
            ctx.device
                .destroy_pipeline_layout(self.pipeline_layout, None);
            ctx.device
                .destroy_descriptor_set_layout(self.set_layout, None);
        }
    }
}
