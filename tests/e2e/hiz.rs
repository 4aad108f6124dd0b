//! The GPU HiZ pyramid equals the CPU reference (tilegraph-cull) exactly.
//!
//! No graph here: each case fills a depth image with known depths by a buffer -> image copy
//! (exact for D32_SFLOAT and D16_UNORM alike: no rasterizer arithmetic), builds the pyramid with
//! `HizBuilder::record`, reads the whole buffer back and compares every texel of every level
//! with `HizPyramid::build` on the same depths, bit for bit. Validation and synchronization
//! validation are on (the `Gpu` guard fails a test on any message).

use std::mem::{offset_of, size_of};

use tilegraph_cull::{dequantize_d16, DepthFormat, Extent2d, ExtentExt, HizPyramid};
use tilegraph_e2e::gpu;
use tilegraph_passes::hiz::{
    DepthConvention, HizBuilder, HizLayout, HizLevelsPush, HizPush, HizStep, NpotMode, ReduceRule,
    SampledDepth, HIZ_COPY_SPV, HIZ_REDUCE_LEVELS_SPV, HIZ_REDUCE_SPV, LEVELS_WORKGROUP_SIZE,
    MAX_PYRAMID_BYTES, WORKGROUP_SIZE,
};
use tilegraph_profile::MemoryUse;
use tilegraph_vk::ash::vk;
use tilegraph_vk::executor::BufferHandle;
use tilegraph_vk::readback::read_buffer;
use tilegraph_vk::{Context, Image, VkError};

const D32: DepthFormat = DepthFormat::D32Float;
const MODES: [NpotMode; 2] = [NpotMode::EdgeAware, NpotMode::PadToPow2];
const CONVENTIONS: [DepthConvention; 2] = [DepthConvention::Standard, DepthConvention::Reverse];
const READ_LAYOUT: vk::ImageLayout = vk::ImageLayout::DEPTH_STENCIL_READ_ONLY_OPTIMAL;

/// The brief's sizes plus a few powers of two and small odd ones.
const SIZES: [(u32, u32); 13] = [
    (1, 1),
    (2, 1),
    (1, 2),
    (2, 2),
    (3, 3),
    (5, 7),
    (27, 13),
    (64, 64),
    (160, 90),
    (97, 61),
    (4096, 1),
    (1, 300),
    (1920, 1080),
];

/// splitmix64: deterministic, no dependency.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1) on a 2^-24 grid: every value is 0 or a normal f32.
    fn unit(&mut self) -> f32 {
        (self.next() >> 40) as f32 / (1u32 << 24) as f32
    }
}

/// Depths as the image stores them.
enum Depth {
    D32(Vec<f32>),
    D16(Vec<u16>),
}

impl Depth {
    fn vk_format(&self) -> vk::Format {
        match self {
            Depth::D32(_) => vk::Format::D32_SFLOAT,
            Depth::D16(_) => vk::Format::D16_UNORM,
        }
    }

    fn format(&self) -> DepthFormat {
        match self {
            Depth::D32(_) => DepthFormat::D32Float,
            Depth::D16(_) => DepthFormat::D16Unorm,
        }
    }

    fn name(&self) -> &'static str {
        match self {
            Depth::D32(_) => "D32",
            Depth::D16(_) => "D16",
        }
    }

    /// The floats a shader should read: the value itself, or `code / 65535` (the spec's
    /// UNORM -> float conversion, which `DepthFormat::D16Unorm.store` also produces).
    fn floats(&self) -> Vec<f32> {
        match self {
            Depth::D32(v) => v.clone(),
            Depth::D16(v) => v.iter().map(|&c| dequantize_d16(c)).collect(),
        }
    }

    fn bytes(&self) -> Vec<u8> {
        match self {
            Depth::D32(v) => v.iter().flat_map(|d| d.to_le_bytes()).collect(),
            Depth::D16(v) => v.iter().flat_map(|d| d.to_le_bytes()).collect(),
        }
    }

    /// Random depths: mostly uniform in [0, 1), with exact 0.0 and 1.0 mixed in so the extremes
    /// of both conventions appear in every pyramid.
    fn random(format: DepthFormat, n: usize, seed: u64) -> Depth {
        let mut rng = Rng(seed);
        match format {
            DepthFormat::D32Float => Depth::D32(
                (0..n)
                    .map(|_| match rng.next() % 64 {
                        0 => 0.0,
                        1 => 1.0,
                        _ => rng.unit(),
                    })
                    .collect(),
            ),
            DepthFormat::D16Unorm => Depth::D16(
                (0..n)
                    .map(|_| match rng.next() % 64 {
                        0 => 0,
                        1 => u16::MAX,
                        _ => (rng.next() >> 48) as u16,
                    })
                    .collect(),
            ),
        }
    }
}

/// A depth image holding known depths, in `READ_LAYOUT`, with a DEPTH-aspect view.
struct DepthImage {
    image: Image,
    view: vk::ImageView,
}

impl DepthImage {
    fn upload(ctx: &Context, (w, h): (u32, u32), depth: &Depth) -> Result<Self, VkError> {
        let info = vk::ImageCreateInfo::default()
            .image_type(vk::ImageType::TYPE_2D)
            .format(depth.vk_format())
            .extent(vk::Extent3D {
                width: w,
                height: h,
                depth: 1,
            })
            .mip_levels(1)
            .array_layers(1)
            .samples(vk::SampleCountFlags::TYPE_1)
            .tiling(vk::ImageTiling::OPTIMAL)
            .usage(
                vk::ImageUsageFlags::DEPTH_STENCIL_ATTACHMENT
                    | vk::ImageUsageFlags::SAMPLED
                    | vk::ImageUsageFlags::TRANSFER_DST
                    | vk::ImageUsageFlags::TRANSFER_SRC,
            )
            .initial_layout(vk::ImageLayout::UNDEFINED);
        let image = ctx.create_image("hiz test depth", &info, MemoryUse::GpuOnly)?;
        let range = vk::ImageSubresourceRange {
            aspect_mask: vk::ImageAspectFlags::DEPTH,
            base_mip_level: 0,
            level_count: 1,
            base_array_layer: 0,
            layer_count: 1,
        };
        let view_info = vk::ImageViewCreateInfo::default()
            .image(image.raw)
            .view_type(vk::ImageViewType::TYPE_2D)
            .format(depth.vk_format())
            .subresource_range(range);
        // SAFETY: live image of this device; the view matches its format and only mip.
        let view = match unsafe { ctx.device.create_image_view(&view_info, None) } {
            Ok(v) => v,
            Err(r) => {
                ctx.destroy_image(image);
                return Err(VkError::call("vkCreateImageView", r));
            }
        };
        let this = DepthImage { image, view };
        match this.fill(ctx, range, depth) {
            Ok(()) => Ok(this),
            Err(e) => {
                this.destroy(ctx);
                Err(e)
            }
        }
    }

    fn fill(
        &self,
        ctx: &Context,
        range: vk::ImageSubresourceRange,
        depth: &Depth,
    ) -> Result<(), VkError> {
        let bytes = depth.bytes();
        let mut staging = ctx.create_buffer(
            "hiz test depth staging",
            bytes.len() as u64,
            vk::BufferUsageFlags::TRANSFER_SRC,
            MemoryUse::Staging,
        )?;
        let result = match staging.mapped_mut() {
            Some(m) => {
                m[..bytes.len()].copy_from_slice(&bytes);
                ctx.submit_and_wait(|cb| {
                    let to_dst = [vk::ImageMemoryBarrier2::default()
                        .src_stage_mask(vk::PipelineStageFlags2::NONE)
                        .dst_stage_mask(vk::PipelineStageFlags2::COPY)
                        .dst_access_mask(vk::AccessFlags2::TRANSFER_WRITE)
                        .old_layout(vk::ImageLayout::UNDEFINED)
                        .new_layout(vk::ImageLayout::TRANSFER_DST_OPTIMAL)
                        .image(self.image.raw)
                        .subresource_range(range)];
                    ctx.cmd_pipeline_barrier2(
                        cb,
                        &vk::DependencyInfo::default().image_memory_barriers(&to_dst),
                    )?;
                    let region = vk::BufferImageCopy::default()
                        .image_subresource(vk::ImageSubresourceLayers {
                            aspect_mask: vk::ImageAspectFlags::DEPTH,
                            mip_level: 0,
                            base_array_layer: 0,
                            layer_count: 1,
                        })
                        .image_extent(vk::Extent3D {
                            width: self.image.extent.width,
                            height: self.image.extent.height,
                            depth: 1,
                        });
                    // SAFETY: the image is in TRANSFER_DST_OPTIMAL; the staging buffer holds
                    // exactly width * height texels of the format; D32 values are in [0, 1].
                    unsafe {
                        ctx.device.cmd_copy_buffer_to_image(
                            cb,
                            staging.raw,
                            self.image.raw,
                            vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                            &[region],
                        )
                    };
                    let to_read = [vk::ImageMemoryBarrier2::default()
                        .src_stage_mask(vk::PipelineStageFlags2::COPY)
                        .src_access_mask(vk::AccessFlags2::TRANSFER_WRITE)
                        .dst_stage_mask(vk::PipelineStageFlags2::COMPUTE_SHADER)
                        .dst_access_mask(vk::AccessFlags2::SHADER_SAMPLED_READ)
                        .old_layout(vk::ImageLayout::TRANSFER_DST_OPTIMAL)
                        .new_layout(READ_LAYOUT)
                        .image(self.image.raw)
                        .subresource_range(range)];
                    ctx.cmd_pipeline_barrier2(
                        cb,
                        &vk::DependencyInfo::default().image_memory_barriers(&to_read),
                    )
                })
            }
            None => Err(VkError::Invalid {
                what: "hiz test staging".into(),
                reason: "staging memory is not host-visible".into(),
            }),
        };
        ctx.destroy_buffer(staging);
        result
    }

    fn destroy(self, ctx: &Context) {
        // SAFETY: every submission using the view has completed (submit_and_wait).
        unsafe { ctx.device.destroy_image_view(self.view, None) };
        ctx.destroy_image(self.image);
    }
}

fn floats(bytes: &[u8]) -> Vec<f32> {
    bytes
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect()
}

/// Builds the pyramid of `depth` on the GPU and returns the whole buffer.
fn gpu_build(
    ctx: &Context,
    builder: &mut HizBuilder,
    depth: &DepthImage,
    layout: &HizLayout,
) -> Result<Vec<f32>, VkError> {
    let pyramid = ctx.create_buffer(
        "hiz pyramid",
        layout.size_bytes(),
        vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::TRANSFER_SRC,
        MemoryUse::GpuOnly,
    )?;
    let handle = BufferHandle {
        raw: pyramid.raw,
        size: pyramid.size,
    };
    let result = ctx
        .submit_and_wait(|cb| {
            builder.record(ctx, cb, 0, sampled(depth.view, READ_LAYOUT), handle, layout)
        })
        .and_then(|_| read_buffer(ctx, handle))
        .map(|b| floats(&b));
    ctx.destroy_buffer(pyramid);
    result
}

/// Every stored level of the GPU pyramid equals the CPU level of the same index in the chain bit
/// for bit (from the layout's base level on); extents and scales agree.
fn assert_same(layout: &HizLayout, gpu: &[f32], cpu: &HizPyramid, what: &str) {
    let base = layout.base_level as usize;
    assert_eq!(
        layout.levels.len() + base,
        cpu.levels().len(),
        "{what}: level count"
    );
    assert_eq!(
        gpu.len() as u64,
        layout.total_texels,
        "{what}: buffer length"
    );
    for (k, (info, level)) in layout.levels.iter().zip(&cpu.levels()[base..]).enumerate() {
        assert_eq!(info.level as usize, base + k, "{what}: level index");
        let e = level.extent();
        assert_eq!(
            (info.width, info.height),
            (e.width_px, e.height_px),
            "{what}: level {k} extent"
        );
        assert_eq!(
            (info.scale_x, info.scale_y),
            level.scale(),
            "{what}: level {k} scale"
        );
        let Some(texels) = layout.level_texels(gpu, k) else {
            panic!("{what}: level {k} is outside the buffer");
        };
        let mismatch = texels
            .iter()
            .zip(level.texels())
            .position(|(g, c)| g.to_bits() != c.to_bits());
        if let Some(i) = mismatch {
            panic!(
                "{what}: level {k} ({}x{}) texel ({}, {}): GPU {:e} ({:#010x}), CPU {:e} ({:#010x})",
                info.width,
                info.height,
                i as u32 % info.width,
                i as u32 / info.width,
                texels[i],
                texels[i].to_bits(),
                level.texels()[i],
                level.texels()[i].to_bits()
            );
        }
    }
}

fn extent((w, h): (u32, u32)) -> Extent2d {
    Extent2d::try_new(w, h).unwrap()
}

/// Uploads `depth`, then for every mode, convention and base level (knob `hiz_resolution`:
/// full, half, quarter) builds on the GPU and compares with the CPU reference built from what
/// the image holds.
fn check_all_modes(
    ctx: &Context,
    builder: &mut HizBuilder,
    size: (u32, u32),
    depth: &Depth,
    label: &str,
) {
    let image = DepthImage::upload(ctx, size, depth).unwrap();
    let expected_level0 = depth.format().store_buffer(&depth.floats());
    for (mode, conv, per, base) in MODES
        .into_iter()
        .flat_map(|m| CONVENTIONS.map(|c| (m, c)))
        .flat_map(|(m, c)| [(m, c, 4), (m, c, 1)])
        .flat_map(|(m, c, per)| [0, 1, 2].map(|base| (m, c, per, base)))
    {
        let what = format!(
            "{label} {}x{} {} {mode:?} {conv:?} {per} levels per dispatch, base level {base}",
            size.0,
            size.1,
            depth.name()
        );
        let layout = HizLayout::new(size, mode, conv, depth.format())
            .unwrap()
            .with_base_level(base)
            .with_levels_per_dispatch(per);
        let gpu = gpu_build(ctx, builder, &image, &layout).unwrap();
        // Level 0 is exactly what the image holds, as the spec's conversion gives it.
        let level0 = layout.level_texels(&gpu, 0).unwrap();
        if let Some(i) = (layout.base_level == 0)
            .then_some(level0)
            .into_iter()
            .flat_map(|l| l.iter().zip(&expected_level0))
            .position(|(g, e)| g.to_bits() != e.to_bits())
        {
            panic!(
                "{what}: level 0 texel {i}: GPU read {:e}, the format stores {:e}",
                level0[i], expected_level0[i]
            );
        }
        let cpu =
            HizPyramid::build(&expected_level0, extent(size), conv, depth.format(), mode).unwrap();
        assert_same(&layout, &gpu, &cpu, &what);
    }
    image.destroy(ctx);
}

#[test]
fn gpu_pyramid_equals_cpu_reference_d32() {
    let g = gpu(None).unwrap();
    let mut builder = HizBuilder::new(&g, 1).unwrap();
    for (i, &size) in SIZES.iter().enumerate() {
        let n = size.0 as usize * size.1 as usize;
        let depth = Depth::random(DepthFormat::D32Float, n, 0xD32 + i as u64);
        check_all_modes(&g, &mut builder, size, &depth, "random");
    }
    builder.destroy(&g);
}

#[test]
fn gpu_pyramid_equals_cpu_reference_d16() {
    let g = gpu(None).unwrap();
    let mut builder = HizBuilder::new(&g, 1).unwrap();
    for (i, &size) in SIZES.iter().enumerate() {
        let n = size.0 as usize * size.1 as usize;
        let depth = Depth::random(DepthFormat::D16Unorm, n, 0xD16 + i as u64);
        check_all_modes(&g, &mut builder, size, &depth, "random");
    }
    builder.destroy(&g);
}

/// Every size from 1x1 to 64x64, both modes and conventions: the fused dispatches' tiles meet
/// every case there is (leftover rows and columns at each fused level, one axis reaching 1
/// before the other, a single workgroup holding a whole level). One 64x64 image: a layout of
/// w x h builds from its top-left corner. The base level (full, half, quarter) rotates with the
/// size, so each base meets a third of the sizes (every parity of both axes).
#[test]
fn gpu_pyramid_equals_cpu_reference_at_every_size_to_64() {
    let g = gpu(None).unwrap();
    let mut builder = HizBuilder::new(&g, 1).unwrap();
    let depth = Depth::random(D32, 64 * 64, 0x64);
    let image = DepthImage::upload(&g, (64, 64), &depth).unwrap();
    let all = depth.floats();
    let mut fused = 0;
    for w in 1..=64u32 {
        for h in 1..=64u32 {
            let corner: Vec<f32> = (0..h as usize)
                .flat_map(|y| all[y * 64..y * 64 + w as usize].iter().copied())
                .collect();
            for mode in MODES {
                for conv in CONVENTIONS {
                    let base = (w + 2 * h) % 3;
                    let layout = HizLayout::new((w, h), mode, conv, D32)
                        .unwrap()
                        .with_base_level(base);
                    fused += (0..)
                        .map_while(|i| layout.step(i))
                        .filter(|s| matches!(s, Ok(HizStep::Fused { .. })))
                        .count();
                    let gpu = gpu_build(&g, &mut builder, &image, &layout).unwrap();
                    let cpu = HizPyramid::build(&corner, extent((w, h)), conv, D32, mode).unwrap();
                    let what = format!("{w}x{h} {mode:?} {conv:?} base level {base}");
                    assert_same(&layout, &gpu, &cpu, &what);
                }
            }
        }
    }
    assert!(fused > 4096, "the sizes use fused dispatches ({fused})");
    image.destroy(&g);
    builder.destroy(&g);
}

/// Every D16 code once (256x256). Level 0 must hold exactly `k / 65535` correctly rounded (what
/// `DepthFormat::D16Unorm.store` gives) whatever the implementation's UNORM -> float conversion
/// does; the raw conversion is measured too (a layout claiming D32 copies it unchanged) and only
/// has to be close enough for the copy shader to recover the code.
#[test]
fn d16_level0_is_the_exact_dequantized_code() {
    let g = gpu(None).unwrap();
    let mut builder = HizBuilder::new(&g, 1).unwrap();
    let size = (256u32, 256u32);
    let codes: Vec<u16> = (0..=u16::MAX).collect();
    let depth = Depth::D16(codes.clone());
    let image = DepthImage::upload(&g, size, &depth).unwrap();
    let exact = depth.floats();
    for conv in CONVENTIONS {
        let layout =
            HizLayout::new(size, NpotMode::EdgeAware, conv, DepthFormat::D16Unorm).unwrap();
        let gpu_texels = gpu_build(&g, &mut builder, &image, &layout).unwrap();
        let cpu = HizPyramid::build(
            &exact,
            extent(size),
            conv,
            DepthFormat::D16Unorm,
            NpotMode::EdgeAware,
        )
        .unwrap();
        assert_same(
            &layout,
            &gpu_texels,
            &cpu,
            &format!("all D16 codes {conv:?}"),
        );
    }
    let raw_layout =
        HizLayout::new(size, NpotMode::EdgeAware, DepthConvention::Reverse, D32).unwrap();
    let raw = gpu_build(&g, &mut builder, &image, &raw_layout).unwrap();
    let raw = raw_layout.level_texels(&raw, 0).unwrap();
    let mut off = 0usize;
    let mut max_ulps = 0i64;
    for ((&k, &r), &e) in codes.iter().zip(raw).zip(&exact) {
        let ulps = (i64::from(r.to_bits()) - i64::from(e.to_bits())).abs();
        off += usize::from(ulps != 0);
        max_ulps = max_ulps.max(ulps);
        assert_eq!(
            (f64::from(r) * 65535.0).round(),
            f64::from(k),
            "code {k}: the raw read {r:e} is not within half a code"
        );
    }
    println!(
        "{}: raw D16 texelFetch differs from the correctly rounded k/65535 for {off} of 65536 \
         codes (at most {max_ulps} ulp); the copy shader snaps them",
        g.physical.identity.device_name
    );
    image.destroy(&g);
    builder.destroy(&g);
}

/// Only extreme values, so min/max constantly chooses between 0, 1, the smallest normal, the
/// f32 just below 1 and the one just above 0.5, and ties (equal values) are everywhere.
#[test]
fn edge_values_survive_exactly() {
    let g = gpu(None).unwrap();
    let mut builder = HizBuilder::new(&g, 1).unwrap();
    let values = [
        0.0f32,
        1.0,
        f32::MIN_POSITIVE,
        1.0 - f32::EPSILON / 2.0,
        0.5,
        f32::from_bits(0.5f32.to_bits() + 1),
        f32::EPSILON,
    ];
    let codes = [0u16, 1, 2, 32767, 32768, 65534, 65535];
    for (i, size) in [(27u32, 13u32), (3, 3), (33, 17), (1, 300)]
        .into_iter()
        .enumerate()
    {
        let n = size.0 as usize * size.1 as usize;
        let mut rng = Rng(0xED6E + i as u64);
        let d32 = Depth::D32(
            (0..n)
                .map(|_| values[(rng.next() % values.len() as u64) as usize])
                .collect(),
        );
        check_all_modes(&g, &mut builder, size, &d32, "edge values");
        let d16 = Depth::D16(
            (0..n)
                .map(|_| codes[(rng.next() % codes.len() as u64) as usize])
                .collect(),
        );
        check_all_modes(&g, &mut builder, size, &d16, "edge codes");
        // Constant buffers: every level is that value.
        for v in [0.0f32, 1.0] {
            check_all_modes(&g, &mut builder, size, &Depth::D32(vec![v; n]), "constant");
        }
    }
    builder.destroy(&g);
}

/// The naive 2x2 reduction drops the last column (and row) of odd sizes; the GPU must not.
/// At 27x13 a far last column (Standard 1.0 / Reverse 0.0) behind near depths everywhere else is
/// invisible to NaiveBuggy's level 1 and present at every level of the GPU's.
#[test]
fn gpu_is_not_the_naive_reduction_on_27x13() {
    let g = gpu(None).unwrap();
    let mut builder = HizBuilder::new(&g, 1).unwrap();
    let size = (27u32, 13u32);
    for conv in CONVENTIONS {
        let (near, far) = match conv {
            DepthConvention::Standard => (0.25f32, 1.0f32),
            DepthConvention::Reverse => (0.75, 0.0),
        };
        for far_row in [false, true] {
            let depth: Vec<f32> = (0..27 * 13)
                .map(|i| {
                    let (x, y) = (i % 27, i / 27);
                    if (!far_row && x == 26) || (far_row && y == 12) {
                        far
                    } else {
                        near
                    }
                })
                .collect();
            let what = format!(
                "27x13 {conv:?} far {}",
                if far_row { "row" } else { "column" }
            );
            let image = DepthImage::upload(&g, size, &Depth::D32(depth.clone())).unwrap();
            let layout =
                HizLayout::new(size, NpotMode::EdgeAware, conv, DepthFormat::D32Float).unwrap();
            let gpu_texels = gpu_build(&g, &mut builder, &image, &layout).unwrap();
            image.destroy(&g);
            let naive = HizPyramid::build(
                &depth,
                extent(size),
                conv,
                DepthFormat::D32Float,
                NpotMode::NaiveBuggy,
            )
            .unwrap();
            // The naive pyramid has the same extents (the Vulkan chain) but loses the far edge.
            assert!(
                naive.levels()[1].texels().iter().all(|&d| d == near),
                "{what}: the naive reference should show the bug"
            );
            let level1 = layout.level_texels(&gpu_texels, 1).unwrap();
            assert_ne!(level1, naive.levels()[1].texels(), "{what}");
            for k in 0..layout.levels.len() {
                assert!(
                    layout.level_texels(&gpu_texels, k).unwrap().contains(&far),
                    "{what}: GPU level {k} lost the far edge"
                );
            }
            let cpu = HizPyramid::build(
                &depth,
                extent(size),
                conv,
                DepthFormat::D32Float,
                NpotMode::EdgeAware,
            )
            .unwrap();
            assert_same(&layout, &gpu_texels, &cpu, &what);
        }
    }
    builder.destroy(&g);
}

#[test]
fn layouts_reject_bad_input_and_match_the_reference_chain() {
    for bad in [(0, 5), (5, 0), (16385, 1)] {
        assert!(matches!(
            HizLayout::new(bad, NpotMode::EdgeAware, DepthConvention::Reverse, D32),
            Err(VkError::Invalid { .. })
        ));
    }
    assert!(matches!(
        HizLayout::new(
            (27, 13),
            NpotMode::NaiveBuggy,
            DepthConvention::Reverse,
            D32
        ),
        Err(VkError::Invalid { .. })
    ));
    // 8192x8192 needs ~358 MB: more than every device guarantees for one storage buffer.
    assert!(HizLayout::new(
        (8192, 8192),
        NpotMode::EdgeAware,
        DepthConvention::Reverse,
        D32
    )
    .is_err());
    let big = HizLayout::new(
        (4096, 4096),
        NpotMode::EdgeAware,
        DepthConvention::Reverse,
        D32,
    )
    .unwrap();
    assert!(big.size_bytes() <= MAX_PYRAMID_BYTES);

    let l = HizLayout::new(
        (27, 13),
        NpotMode::PadToPow2,
        DepthConvention::Standard,
        D32,
    )
    .unwrap();
    let sizes: Vec<(u32, u32)> = l.levels.iter().map(|l| (l.width, l.height)).collect();
    assert_eq!(sizes, [(27, 13), (16, 8), (8, 4), (4, 2), (2, 1), (1, 1)]);
    let offsets: Vec<u64> = l.levels.iter().map(|l| l.offset_texels).collect();
    assert_eq!(offsets, [0, 351, 479, 511, 519, 521]);
    assert_eq!(l.total_texels, 522);
    assert_eq!(l.size_bytes(), 522 * 4);
    let push = l.push_constants().unwrap();
    assert_eq!(push.len(), 6);
    assert_eq!(
        push[1],
        HizPush {
            src_offset: 0,
            dst_offset: 351,
            src_extent: [27, 13],
            dst_extent: [16, 8],
            rule: 2,
            convention: 0,
            base_level: 1,
            npot: 1,
            pow2_extent: [16, 8],
        }
    );
    assert_eq!((push[2].rule, push[2].src_offset), (1, 351));
    let e = HizLayout::new((27, 13), NpotMode::EdgeAware, DepthConvention::Reverse, D32).unwrap();
    let sizes: Vec<(u32, u32)> = e.levels.iter().map(|l| (l.width, l.height)).collect();
    assert_eq!(sizes, [(27, 13), (13, 6), (6, 3), (3, 1), (1, 1)]);
    assert!(e.push_constants().unwrap()[1..]
        .iter()
        .all(|p| p.rule == 0 && p.convention == 1));
    let one = HizLayout::new((1, 1), NpotMode::PadToPow2, DepthConvention::Reverse, D32).unwrap();
    assert_eq!(one.levels.len(), 1);
    assert_eq!(one.level_texels(&[0.5], 0), Some(&[0.5f32][..]));
    assert_eq!(one.level_texels(&[0.5], 1), None);
    assert_eq!(one.level_texels(&[], 0), None);
    // A coarser base level (knob hiz_resolution): the finer levels are gone, offsets packed from
    // 0, the base built from the depth image (27x13 pixels), the level table's scales those of
    // the whole chain; a base past the chain's end is its 1x1 level.
    let half = e.clone().with_base_level(1);
    let sizes: Vec<(u32, u32)> = half.levels.iter().map(|l| (l.width, l.height)).collect();
    assert_eq!(sizes, [(13, 6), (6, 3), (3, 1), (1, 1)]);
    let offsets: Vec<u64> = half.levels.iter().map(|l| l.offset_texels).collect();
    assert_eq!(offsets, [0, 78, 96, 99]);
    assert_eq!((half.total_texels, half.extent_px()), (100, (27, 13)));
    let push = half.push_constants().unwrap();
    assert_eq!(
        (push[0].src_extent, push[0].dst_extent, push[0].base_level),
        ([27, 13], [13, 6], 1)
    );
    assert_eq!(half.levels[1].scale_x, e.levels[2].scale_x);
    // Reads the depth once (4 bytes a pixel), writes 78 texels, then the fused rest.
    assert_eq!(half.step_bytes(0), Some(27 * 13 * 4 + 78 * 4));
    let padded = l.clone().with_base_level(2);
    assert_eq!(padded.levels[0].rule, ReduceRule::FromDepth);
    assert_eq!(padded.push_constants().unwrap()[0].pow2_extent, [16, 8]);
    assert!(padded.levels[1..]
        .iter()
        .all(|l| l.rule == ReduceRule::Halve));
    let top = e.clone().with_base_level(9);
    assert_eq!(
        (top.levels.len(), top.base_level, top.total_texels),
        (1, 4, 1)
    );
}

#[test]
fn record_rejects_bad_input_without_recording() {
    let g = gpu(None).unwrap();
    assert!(matches!(
        HizBuilder::new(&g, 0),
        Err(VkError::Invalid { .. })
    ));
    let mut builder = HizBuilder::new(&g, 2).unwrap();
    assert_eq!(builder.frame_slots(), 2);
    let size = (27, 13);
    let image = DepthImage::upload(&g, size, &Depth::D32(vec![0.5; 27 * 13])).unwrap();
    let layout = HizLayout::new(size, NpotMode::EdgeAware, DepthConvention::Reverse, D32).unwrap();
    let small = g
        .create_buffer(
            "hiz too small",
            layout.size_bytes() - 4,
            vk::BufferUsageFlags::STORAGE_BUFFER,
            MemoryUse::GpuOnly,
        )
        .unwrap();
    let small_handle = BufferHandle {
        raw: small.raw,
        size: small.size,
    };
    let errors = g
        .submit_and_wait(|cb| {
            Ok([
                builder.record(
                    &g,
                    cb,
                    2,
                    sampled(image.view, READ_LAYOUT),
                    small_handle,
                    &layout,
                ),
                builder.record(
                    &g,
                    cb,
                    0,
                    sampled(image.view, READ_LAYOUT),
                    small_handle,
                    &layout,
                ),
                builder.record(
                    &g,
                    cb,
                    0,
                    sampled(image.view, vk::ImageLayout::TRANSFER_DST_OPTIMAL),
                    small_handle,
                    &layout,
                ),
            ])
        })
        .unwrap();
    for (i, e) in errors.iter().enumerate() {
        assert!(matches!(e, Err(VkError::Invalid { .. })), "case {i}: {e:?}");
    }
    g.destroy_buffer(small);
    image.destroy(&g);
    builder.destroy(&g);
}

// --- the Rust mirror of the GLSL push constants agrees with the SPIR-V ---

const OP_EXECUTION_MODE: u32 = 16;
const OP_TYPE_STRUCT: u32 = 30;
const OP_TYPE_POINTER: u32 = 32;
const OP_MEMBER_DECORATE: u32 = 72;
const DECORATION_OFFSET: u32 = 35;
const EXECUTION_MODE_LOCAL_SIZE: u32 = 17;
const STORAGE_CLASS_PUSH_CONSTANT: u32 = 9;

/// Member offsets of the push-constant block and the LocalSize of a compute module.
fn push_block_and_local_size(spv: &[u8]) -> (Vec<u32>, [u32; 3]) {
    let words: Vec<u32> = spv
        .chunks_exact(4)
        .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    assert_eq!(words[0], 0x0723_0203, "not SPIR-V");
    let mut offsets: Vec<(u32, u32, u32)> = Vec::new(); // (struct, member, offset)
    let mut structs = Vec::new();
    let mut push_pointees = Vec::new();
    let mut local = [0; 3];
    let mut i = 5;
    while i < words.len() {
        let count = ((words[i] >> 16) as usize).max(1);
        let ins = &words[i..i + count];
        match words[i] & 0xFFFF {
            OP_EXECUTION_MODE if ins[2] == EXECUTION_MODE_LOCAL_SIZE => {
                local = [ins[3], ins[4], ins[5]]
            }
            OP_MEMBER_DECORATE if ins[3] == DECORATION_OFFSET => {
                offsets.push((ins[1], ins[2], ins[4]))
            }
            OP_TYPE_STRUCT => structs.push(ins[1]),
            OP_TYPE_POINTER if ins[2] == STORAGE_CLASS_PUSH_CONSTANT => push_pointees.push(ins[3]),
            _ => {}
        }
        i += count;
    }
    // Pointers into the block's members are PushConstant pointers too; the block is the struct.
    let blocks: Vec<u32> = push_pointees
        .into_iter()
        .filter(|p| structs.contains(p))
        .collect();
    let [block] = blocks[..] else {
        panic!("expected one push-constant block, found {blocks:?}");
    };
    let mut members: Vec<(u32, u32)> = offsets
        .into_iter()
        .filter(|(s, _, _)| *s == block)
        .map(|(_, m, o)| (m, o))
        .collect();
    members.sort();
    (members.into_iter().map(|(_, o)| o).collect(), local)
}

#[test]
fn push_constants_and_workgroup_match_the_shaders() {
    let rust = vec![
        offset_of!(HizPush, src_offset) as u32,
        offset_of!(HizPush, dst_offset) as u32,
        offset_of!(HizPush, src_extent) as u32,
        offset_of!(HizPush, dst_extent) as u32,
        offset_of!(HizPush, rule) as u32,
        offset_of!(HizPush, convention) as u32,
        offset_of!(HizPush, base_level) as u32,
        offset_of!(HizPush, npot) as u32,
        offset_of!(HizPush, pow2_extent) as u32,
    ];
    assert_eq!(size_of::<HizPush>(), 48);
    for (name, spv) in [("hiz_copy", HIZ_COPY_SPV), ("hiz_reduce", HIZ_REDUCE_SPV)] {
        let (offsets, local) = push_block_and_local_size(spv);
        assert_eq!(offsets, rust, "{name}: push-constant offsets");
        assert_eq!(
            local,
            [WORKGROUP_SIZE, WORKGROUP_SIZE, 1],
            "{name}: local size"
        );
    }
    let levels = vec![
        offset_of!(HizLevelsPush, src_offset) as u32,
        offset_of!(HizLevelsPush, levels) as u32,
        offset_of!(HizLevelsPush, src_extent) as u32,
        offset_of!(HizLevelsPush, rule) as u32,
        offset_of!(HizLevelsPush, convention) as u32,
        offset_of!(HizLevelsPush, groups) as u32,
        offset_of!(HizLevelsPush, dst_offset) as u32,
        offset_of!(HizLevelsPush, dst_extent) as u32,
    ];
    assert_eq!(size_of::<HizLevelsPush>(), 80);
    let (offsets, local) = push_block_and_local_size(HIZ_REDUCE_LEVELS_SPV);
    assert_eq!(offsets, levels, "hiz_reduce_levels: push-constant offsets");
    assert_eq!(
        local,
        [LEVELS_WORKGROUP_SIZE, LEVELS_WORKGROUP_SIZE, 1],
        "hiz_reduce_levels: local size"
    );
}

/// The depth a build reads.
fn sampled(view: vk::ImageView, layout: vk::ImageLayout) -> SampledDepth {
    SampledDepth { view, layout }
}
