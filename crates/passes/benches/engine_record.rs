//! `engine_record`: the CPU an engine pays per frame to have tilegraph record a scene into its
//! command buffer and to read the frame's statistics — `SceneRenderer::record` (the scene's
//! CPU work: draw lists, camera-relative instances, culling inputs; then the executor's
//! recording) plus `latest_timings` — with GPU-driven culling, on `city:100k` by default.
//! The engine's own work (fence wait, command buffer begin/end, submit) is outside the timing.
//! Reports the recording thread's CPU time (what the engine's render thread pays; on
//! lavapipe the "GPU" runs on the same cores, so wall time there measures the contention, not
//! tilegraph) and the wall time, as medians and 90th percentiles over the measured frames, and
//! the heap allocations of those frames (0 expected).
//!
//! `cargo bench -p tilegraph-passes --bench engine_record -- [SCENE] [FRAMES]`
//! (docs/BENCHMARKS.md, "Recording into the engine's command buffer").

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use tilegraph_graph::ResourceState;
use tilegraph_passes::cull::Culling;
use tilegraph_passes::{EngineTarget, RenderOptions, SceneRenderer, Technique};
use tilegraph_vk::ash::vk;
use tilegraph_vk::executor::{EngineFrame, ImageHandle};
use tilegraph_vk::{Context, ContextOptions, Validation};

struct Counting;
static ALLOCATIONS: AtomicU64 = AtomicU64::new(0);

// SAFETY: forwards to the system allocator.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        // SAFETY: the caller's layout.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: allocated by `alloc` with this layout.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        // SAFETY: as above.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

const WIDTH: u32 = 320;
const HEIGHT: u32 = 180;
const SLOTS: usize = 2;
const WARMUP: usize = 8;

/// The engine's side: command buffers, fences, a colour target.
struct EngineSide {
    pool: vk::CommandPool,
    cbs: Vec<vk::CommandBuffer>,
    fences: Vec<vk::Fence>,
    submitted: Vec<bool>,
    target: (tilegraph_vk::Image, ImageHandle),
}

fn engine_side(ctx: &Context) -> Result<EngineSide, Box<dyn std::error::Error>> {
    let d = &ctx.device;
    let info = vk::CommandPoolCreateInfo::default()
        .queue_family_index(ctx.queue_family)
        .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER);
    // SAFETY: valid device.
    let pool = unsafe { d.create_command_pool(&info, None) }?;
    let alloc = vk::CommandBufferAllocateInfo::default()
        .command_pool(pool)
        .level(vk::CommandBufferLevel::PRIMARY)
        .command_buffer_count(SLOTS as u32);
    // SAFETY: live pool.
    let cbs = unsafe { d.allocate_command_buffers(&alloc) }?;
    let mut fences = Vec::new();
    for _ in 0..SLOTS {
        // SAFETY: valid device.
        fences.push(unsafe { d.create_fence(&vk::FenceCreateInfo::default(), None) }?);
    }
    let target =
        tilegraph_passes::targets::create_target(ctx, (WIDTH, HEIGHT), vk::Format::R8G8B8A8_UNORM)?;
    Ok(EngineSide {
        pool,
        cbs,
        fences,
        submitted: vec![false; SLOTS],
        target,
    })
}

/// CPU time of the calling thread.
fn thread_cpu() -> Duration {
    let mut t = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: a valid timespec to fill; CLOCK_THREAD_CPUTIME_ID exists on Linux and Android.
    unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut t) };
    Duration::new(t.tv_sec as u64, t.tv_nsec as u32)
}

fn percentile(sorted: &[Duration], p: f64) -> Duration {
    let i = ((sorted.len() as f64 - 1.0) * p).round() as usize;
    sorted.get(i).copied().unwrap_or_default()
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // `cargo bench` passes `--bench`; the rest are ours.
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .collect();
    let spec = args.first().map_or("city:100k", String::as_str);
    let frames: usize = args.get(1).map_or(Ok(120), |a| a.parse())?;
    let scene = tilegraph_scene::load(spec)?;
    let mut options = ContextOptions::from_env();
    options.validation = Validation::Off;
    let all = [Culling::Frustum, Culling::HizTwoPhase];
    for culling in all {
        options.features.required.extend(
            RenderOptions {
                culling,
                ..Default::default()
            }
            .device_features()
            .required,
        );
    }
    let ctx = Context::new(options)?;
    println!(
        "engine_record: {spec} ({} instances), {WIDTH}x{HEIGHT}, {} ({}), {frames} frames after {WARMUP}",
        scene.instances().len(),
        ctx.physical.identity.device_name,
        ctx.profile().name
    );
    let mut side = engine_side(&ctx)?;
    let path: Vec<_> = scene
        .camera_path()
        .frames(WIDTH as f32 / HEIGHT as f32)
        .collect();
    for culling in all {
        let render = RenderOptions {
            technique: Technique::Prepass,
            culling,
            width: WIDTH,
            height: HEIGHT,
            ..Default::default()
        };
        let mut r = SceneRenderer::for_engine(&ctx, &scene, render, SLOTS)?;
        let mut times = Vec::with_capacity(frames);
        let mut cpu_times = Vec::with_capacity(frames);
        let mut allocations = 0;
        let mut gpu_ms = 0.0;
        for i in 0..WARMUP + frames {
            let slot = i % SLOTS;
            let cb = side.cbs[slot];
            // SAFETY: the fence was submitted with the slot's last frame.
            unsafe {
                if side.submitted[slot] {
                    ctx.device
                        .wait_for_fences(&[side.fences[slot]], true, u64::MAX)?;
                    ctx.device.reset_fences(&[side.fences[slot]])?;
                }
                ctx.device
                    .reset_command_buffer(cb, vk::CommandBufferResetFlags::empty())?;
                ctx.device
                    .begin_command_buffer(cb, &vk::CommandBufferBeginInfo::default())?;
            }
            let target = EngineTarget {
                image: &side.target.1,
                initial: ResourceState::UNDEFINED,
                final_state: ResourceState::image(
                    tilegraph_graph::Layout::TransferSrc,
                    tilegraph_graph::PipelineStages::COPY,
                    tilegraph_graph::AccessFlags::TRANSFER_READ,
                ),
            };
            let frame = &path[i % path.len()];
            let engine = EngineFrame {
                command_buffer: cb,
                slot,
            };
            let before = ALLOCATIONS.load(Ordering::Relaxed);
            let start = Instant::now();
            let cpu_start = thread_cpu();
            let report = r.record(&ctx, &scene, frame, engine, &target)?;
            let timed = r
                .executor()
                .latest_timings()
                .map(|t| t.passes.iter().map(|p| p.gpu_ms).sum::<f64>());
            let cpu = thread_cpu().saturating_sub(cpu_start);
            let elapsed = start.elapsed();
            let allocated = ALLOCATIONS.load(Ordering::Relaxed) - before;
            drop(report);
            if i >= WARMUP {
                times.push(elapsed);
                cpu_times.push(cpu);
                allocations += allocated;
                gpu_ms = timed.unwrap_or(gpu_ms);
            }
            let cbs = [cb];
            let submit = vk::SubmitInfo::default().command_buffers(&cbs);
            // SAFETY: recorded buffer, unsignalled fence.
            unsafe {
                ctx.device.end_command_buffer(cb)?;
                ctx.device
                    .queue_submit(ctx.queue, &[submit], side.fences[slot])?;
            }
            side.submitted[slot] = true;
        }
        times.sort_unstable();
        cpu_times.sort_unstable();
        let ms = |d: Duration| d.as_secs_f64() * 1e3;
        println!(
            "  {:<11} record + stats, thread CPU: median {:.3} ms, p90 {:.3} ms; wall: median {:.3} ms, p90 {:.3} ms; heap allocations over {frames} frames: {allocations}; newest GPU frame, passes summed, {gpu_ms:.2} ms",
            culling.name(),
            ms(percentile(&cpu_times, 0.5)),
            ms(percentile(&cpu_times, 0.9)),
            ms(percentile(&times, 0.5)),
            ms(percentile(&times, 0.9)),
        );
        ctx.wait_idle()?;
        r.destroy(&ctx);
    }
    ctx.wait_idle()?;
    // SAFETY: idle device.
    unsafe {
        for f in &side.fences {
            ctx.device.destroy_fence(*f, None);
        }
        ctx.device.destroy_command_pool(side.pool, None);
    }
    tilegraph_passes::targets::destroy_target(&ctx, side.target);
    ctx.destroy_checked()?;
    Ok(())
}
