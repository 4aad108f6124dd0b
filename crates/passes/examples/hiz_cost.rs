//! The HiZ build against its bandwidth limit (docs/BENCHMARKS.md, "HiZ pyramid build"): on the
//! default device, the GPU time of each dispatch of the build (timestamps, median of RUNS
//! submissions) for a D32 reverse-Z depth of each size and both NPOT modes, fused (4 levels
//! per dispatch) and not, and at the coarser base levels of knob `hiz_resolution` (half,
//! quarter; EdgeAware, fused), the bytes each
//! dispatch reads and writes, and the device's buffer-copy bandwidth; the ratio is the build's
//! time over the time its bytes take at copy bandwidth. Validation follows
//! `TILEGRAPH_VALIDATION` (off in release builds).
//!
//! `cargo run --release -p tilegraph-passes --example hiz_cost -- [RUNS] [WxH ...]`

use tilegraph_passes::hiz::{
    DepthConvention, DepthFormat, HizBuilder, HizLayout, HizStep, NpotMode, SampledDepth,
};
use tilegraph_passes::targets::{create_image_2d, destroy_target};
use tilegraph_profile::MemoryUse;
use tilegraph_vk::ash::vk;
use tilegraph_vk::executor::{BufferHandle, ImageHandle};
use tilegraph_vk::{Context, ContextOptions, Image, VkError};

const READ_LAYOUT: vk::ImageLayout = vk::ImageLayout::DEPTH_STENCIL_READ_ONLY_OPTIMAL;
const COPY_BYTES: u64 = 256 << 20;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let runs: usize = args.next().map_or(Ok(20), |a| a.parse())?;
    let mut sizes = Vec::new();
    for a in args {
        let (w, h) = a.split_once('x').ok_or("sizes are WxH")?;
        sizes.push((w.parse::<u32>()?, h.parse::<u32>()?));
    }
    if sizes.is_empty() {
        sizes = vec![(1920, 1080), (3840, 2160)];
    }
    let ctx = Context::new(ContextOptions::from_env())?;
    let pool = timestamp_pool(&ctx, 32)?;
    let result = run(&ctx, pool, runs, &sizes);
    // SAFETY: every submission using the pool has completed (submit_and_wait).
    unsafe { ctx.device.destroy_query_pool(pool, None) };
    result?;
    ctx.destroy_checked()?;
    Ok(())
}

fn run(
    ctx: &Context,
    pool: vk::QueryPool,
    runs: usize,
    sizes: &[(u32, u32)],
) -> Result<(), Box<dyn std::error::Error>> {
    let copy_gbps = copy_bandwidth_gbps(ctx, pool, runs)?;
    println!(
        "{} ({}), median of {runs}; buffer copy {copy_gbps:.0} GB/s (bytes read + written)",
        ctx.physical.identity.device_name,
        ctx.profile().name
    );
    println!("| extent | mode | dispatch | MB moved | gpu_ms | GB/s |");
    println!("|---|---|---|---|---|---|");
    let mut builder = HizBuilder::new(ctx, 1)?;
    let mut totals = Vec::new();
    for &size in sizes {
        let depth = DepthImage::cleared(ctx, size)?;
        for (mode, per, base) in [
            // (NPOT mode, levels per dispatch, base level)
            (NpotMode::EdgeAware, 4, 0usize),
            (NpotMode::EdgeAware, 1, 0),
            (NpotMode::PadToPow2, 4, 0),
            (NpotMode::PadToPow2, 1, 0),
            (NpotMode::EdgeAware, 4, 1),
            (NpotMode::EdgeAware, 4, 2),
        ] {
            let layout =
                HizLayout::new(size, mode, DepthConvention::Reverse, DepthFormat::D32Float)?
                    .with_base_level(base as u32)
                    .with_levels_per_dispatch(per);
            let variant = match base {
                0 => format!("{mode:?}, {per} per dispatch"),
                b => format!("{mode:?}, {per} per dispatch, from level {b}"),
            };
            let measured = time_steps(ctx, &mut builder, pool, &depth, &layout, runs);
            let steps = match measured {
                Ok(s) => s,
                Err(e) => {
                    depth.destroy(ctx);
                    builder.destroy(ctx);
                    return Err(e.into());
                }
            };
            for (i, ms) in steps.iter().enumerate() {
                let bytes = layout.step_bytes(i).unwrap_or(0);
                let what = match layout.step(i) {
                    Some(Ok(HizStep::Single { level: 0, .. })) => {
                        format!("from depth (level {base})")
                    }
                    Some(Ok(HizStep::Single { level, .. })) => format!("level {}", level + base),
                    Some(Ok(HizStep::Fused { first, push })) => format!(
                        "levels {}-{}",
                        first + base,
                        first + base + push.levels as usize - 1
                    ),
                    _ => "?".to_string(),
                };
                println!(
                    "| {}x{} | {variant} | {what} | {:.2} | {ms:.4} | {:.0} |",
                    size.0,
                    size.1,
                    bytes as f64 / 1e6,
                    bytes as f64 / (ms * 1e6)
                );
            }
            let total: f64 = steps.iter().sum();
            let floor = layout.traffic_bytes() as f64 / (copy_gbps * 1e6);
            totals.push(format!(
                "{}x{} {variant}: {} dispatches, {:.1} MB ({:.1} MB pyramid), {total:.4} ms; at copy bandwidth {floor:.4} ms; ratio {:.2}",
                size.0,
                size.1,
                steps.len(),
                layout.traffic_bytes() as f64 / 1e6,
                layout.size_bytes() as f64 / 1e6,
                total / floor
            ));
        }
        depth.destroy(ctx);
    }
    builder.destroy(ctx);
    for t in totals {
        println!("{t}");
    }
    Ok(())
}

/// Median GPU milliseconds of each dispatch of the build, over `runs` submissions.
fn time_steps(
    ctx: &Context,
    builder: &mut HizBuilder,
    pool: vk::QueryPool,
    depth: &DepthImage,
    layout: &HizLayout,
    runs: usize,
) -> Result<Vec<f64>, VkError> {
    let steps = (0..).map_while(|i| layout.step(i)).count();
    let pyramid = ctx.create_buffer(
        "hiz pyramid",
        layout.size_bytes(),
        vk::BufferUsageFlags::STORAGE_BUFFER,
        MemoryUse::GpuOnly,
    )?;
    let handle = BufferHandle {
        raw: pyramid.raw,
        size: pyramid.size,
    };
    let sampled = SampledDepth {
        view: depth.view,
        layout: READ_LAYOUT,
    };
    let mut samples = vec![Vec::with_capacity(runs); steps];
    let result = (|| {
        for run in 0..=runs {
            ctx.submit_and_wait(|cb| {
                // SAFETY: recording outside a render pass; the pool holds 32 queries.
                unsafe {
                    ctx.device
                        .cmd_reset_query_pool(cb, pool, 0, steps as u32 + 1)
                };
                // The previous run wrote the same buffer (an earlier, finished submission).
                let waw = [vk::MemoryBarrier2::default()
                    .src_stage_mask(vk::PipelineStageFlags2::COMPUTE_SHADER)
                    .src_access_mask(vk::AccessFlags2::SHADER_STORAGE_WRITE)
                    .dst_stage_mask(vk::PipelineStageFlags2::COMPUTE_SHADER)
                    .dst_access_mask(
                        vk::AccessFlags2::SHADER_STORAGE_READ
                            | vk::AccessFlags2::SHADER_STORAGE_WRITE,
                    )];
                ctx.cmd_pipeline_barrier2(
                    cb,
                    &vk::DependencyInfo::default().memory_barriers(&waw),
                )?;
                builder.time_dispatches(Some((pool, 0)));
                let recorded = builder.record(ctx, cb, 0, sampled, handle, layout);
                builder.time_dispatches(None);
                recorded
            })?;
            let stamps = read_stamps(ctx, pool, steps + 1)?;
            if run > 0 {
                for (k, s) in samples.iter_mut().enumerate() {
                    s.push(stamps[k + 1] - stamps[k]);
                }
            }
        }
        Ok(samples.iter_mut().map(|s| median(s)).collect())
    })();
    ctx.destroy_buffer(pyramid);
    result
}

/// GB/s of `vkCmdCopyBuffer` between two device buffers, bytes read plus bytes written.
fn copy_bandwidth_gbps(ctx: &Context, pool: vk::QueryPool, runs: usize) -> Result<f64, VkError> {
    let usage = vk::BufferUsageFlags::TRANSFER_SRC | vk::BufferUsageFlags::TRANSFER_DST;
    let src = ctx.create_buffer("copy src", COPY_BYTES, usage, MemoryUse::GpuOnly)?;
    let dst = match ctx.create_buffer("copy dst", COPY_BYTES, usage, MemoryUse::GpuOnly) {
        Ok(b) => b,
        Err(e) => {
            ctx.destroy_buffer(src);
            return Err(e);
        }
    };
    let mut ms = Vec::with_capacity(runs);
    let result = (|| {
        for run in 0..=runs {
            ctx.submit_and_wait(|cb| {
                let waw = [vk::MemoryBarrier2::default()
                    .src_stage_mask(vk::PipelineStageFlags2::COPY)
                    .src_access_mask(vk::AccessFlags2::TRANSFER_WRITE)
                    .dst_stage_mask(vk::PipelineStageFlags2::COPY)
                    .dst_access_mask(vk::AccessFlags2::TRANSFER_WRITE)];
                // SAFETY: recording outside a render pass; both buffers hold COPY_BYTES.
                unsafe { ctx.device.cmd_reset_query_pool(cb, pool, 0, 2) };
                ctx.cmd_pipeline_barrier2(
                    cb,
                    &vk::DependencyInfo::default().memory_barriers(&waw),
                )?;
                ctx.cmd_write_timestamp2(cb, vk::PipelineStageFlags2::BOTTOM_OF_PIPE, pool, 0)?;
                let region = [vk::BufferCopy {
                    src_offset: 0,
                    dst_offset: 0,
                    size: COPY_BYTES,
                }];
                // SAFETY: as above.
                unsafe { ctx.device.cmd_copy_buffer(cb, src.raw, dst.raw, &region) };
                ctx.cmd_write_timestamp2(cb, vk::PipelineStageFlags2::BOTTOM_OF_PIPE, pool, 1)
            })?;
            let stamps = read_stamps(ctx, pool, 2)?;
            if run > 0 {
                ms.push(stamps[1] - stamps[0]);
            }
        }
        Ok(2.0 * COPY_BYTES as f64 / (median(&mut ms) * 1e6))
    })();
    ctx.destroy_buffer(src);
    ctx.destroy_buffer(dst);
    result
}

/// The first `n` timestamps of `pool`, in milliseconds.
fn read_stamps(ctx: &Context, pool: vk::QueryPool, n: usize) -> Result<Vec<f64>, VkError> {
    let mut ticks = vec![0u64; n];
    // SAFETY: the submission that wrote the queries has completed.
    unsafe {
        ctx.device.get_query_pool_results(
            pool,
            0,
            &mut ticks,
            vk::QueryResultFlags::TYPE_64 | vk::QueryResultFlags::WAIT,
        )
    }
    .map_err(|r| VkError::call("vkGetQueryPoolResults", r))?;
    let period_ns = f64::from(ctx.physical.limits.timestamp_period_ns);
    Ok(ticks.iter().map(|&t| t as f64 * period_ns / 1e6).collect())
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

fn timestamp_pool(ctx: &Context, count: u32) -> Result<vk::QueryPool, VkError> {
    let info = vk::QueryPoolCreateInfo::default()
        .query_type(vk::QueryType::TIMESTAMP)
        .query_count(count);
    // SAFETY: valid create info on a live device.
    unsafe { ctx.device.create_query_pool(&info, None) }
        .map_err(|r| VkError::call("vkCreateQueryPool", r))
}

/// A D32 depth image cleared to 0.5, in `READ_LAYOUT`, with a DEPTH-aspect view (the build's
/// time does not depend on the values).
struct DepthImage {
    target: (Image, ImageHandle),
    view: vk::ImageView,
}

impl DepthImage {
    fn cleared(ctx: &Context, size: (u32, u32)) -> Result<Self, VkError> {
        let usage = vk::ImageUsageFlags::DEPTH_STENCIL_ATTACHMENT
            | vk::ImageUsageFlags::SAMPLED
            | vk::ImageUsageFlags::TRANSFER_DST;
        let target = create_image_2d(
            ctx,
            "hiz cost depth",
            size,
            vk::Format::D32_SFLOAT,
            usage,
            vk::ImageAspectFlags::DEPTH,
        )?;
        let range = vk::ImageSubresourceRange {
            aspect_mask: vk::ImageAspectFlags::DEPTH,
            base_mip_level: 0,
            level_count: 1,
            base_array_layer: 0,
            layer_count: 1,
        };
        let raw = target.1.raw;
        let this = DepthImage {
            view: target.1.view,
            target,
        };
        let cleared = ctx.submit_and_wait(|cb| {
            let to = |old,
                      new,
                      src: (vk::PipelineStageFlags2, vk::AccessFlags2),
                      dst: (vk::PipelineStageFlags2, vk::AccessFlags2)| {
                vk::ImageMemoryBarrier2::default()
                    .src_stage_mask(src.0)
                    .src_access_mask(src.1)
                    .dst_stage_mask(dst.0)
                    .dst_access_mask(dst.1)
                    .old_layout(old)
                    .new_layout(new)
                    .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
                    .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
                    .image(raw)
                    .subresource_range(range)
            };
            let copy = (
                vk::PipelineStageFlags2::CLEAR,
                vk::AccessFlags2::TRANSFER_WRITE,
            );
            let first = [to(
                vk::ImageLayout::UNDEFINED,
                vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                (vk::PipelineStageFlags2::NONE, vk::AccessFlags2::NONE),
                copy,
            )];
            ctx.cmd_pipeline_barrier2(
                cb,
                &vk::DependencyInfo::default().image_memory_barriers(&first),
            )?;
            let value = vk::ClearDepthStencilValue {
                depth: 0.5,
                stencil: 0,
            };
            // SAFETY: the image is in TRANSFER_DST_OPTIMAL with TRANSFER_DST usage.
            unsafe {
                ctx.device.cmd_clear_depth_stencil_image(
                    cb,
                    raw,
                    vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                    &value,
                    &[range],
                )
            };
            let read = [to(
                vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                READ_LAYOUT,
                copy,
                (
                    vk::PipelineStageFlags2::COMPUTE_SHADER,
                    vk::AccessFlags2::SHADER_SAMPLED_READ,
                ),
            )];
            ctx.cmd_pipeline_barrier2(
                cb,
                &vk::DependencyInfo::default().image_memory_barriers(&read),
            )
        });
        match cleared {
            Ok(()) => Ok(this),
            Err(e) => {
                this.destroy(ctx);
                Err(e)
            }
        }
    }

    fn destroy(self, ctx: &Context) {
        // Every submission using it was waited for.
        destroy_target(ctx, self.target);
    }
}
