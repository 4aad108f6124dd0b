//! `engine_record`: the CPU an engine's render thread pays per frame for tilegraph — the
//! game's changes to the scene (none, 10 % of the instances moved, or 1,000 instances added
//! and 1,000 removed), then `SceneRenderer::record` (the scene's CPU work: what changed
//! uploaded, CPU lists, culling inputs; then the executor's recording) and `latest_timings` —
//! with GPU-driven culling, on procedural cities of 10k, 100k and 1M instances by default, the
//! camera moving along the city's path. The engine's own work (fence wait, command buffer
//! begin/end, submit) is outside the timing. Reports the recording thread's CPU time (what the
//! render thread pays; on lavapipe the "GPU" runs on the same cores, so wall time there
//! measures the contention, not tilegraph) and the wall time, as medians and 90th percentiles,
//! and the heap allocations of the measured frames (0 expected).
//!
//! `cargo bench -p tilegraph-passes --bench engine_record -- [SCENES] [FRAMES]`, SCENES a
//! comma-separated list (docs/BENCHMARKS.md, "Recording into the engine's command buffer").
//! `TILEGRAPH_TRACE_ALLOCATIONS=N` prints the backtraces of the first N allocations of the
//! measured frames (each scenario).

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use glam::{DVec3, Mat3};
use tilegraph_graph::ResourceState;
use tilegraph_passes::cull::Culling;
use tilegraph_passes::{EngineTarget, RenderOptions, SceneRenderer, Technique};
use tilegraph_scene::{InstanceFlags, InstanceHandle, InstanceId, MeshHandle, Scene, Transform};
use tilegraph_vk::ash::vk;
use tilegraph_vk::executor::{EngineFrame, ImageHandle};
use tilegraph_vk::{Context, ContextOptions, Validation};

struct Counting;
static ALLOCATIONS: AtomicU64 = AtomicU64::new(0);
/// Backtraces still to print of allocations in measured frames (`TILEGRAPH_TRACE_ALLOCATIONS=N`):
/// where a steady frame allocates, on whatever device the bench runs.
static TRACE: AtomicU64 = AtomicU64::new(0);

thread_local! {
    static TRACING: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// Prints where this allocation comes from, once per traced allocation (not for the
/// backtrace's own allocations).
fn trace() {
    if TRACE.load(Ordering::Relaxed) == 0 || TRACING.with(|t| t.replace(true)) {
        return;
    }
    if TRACE.fetch_sub(1, Ordering::Relaxed) > 0 {
        eprintln!(
            "allocation in a measured frame:\n{}",
            std::backtrace::Backtrace::force_capture()
        );
    }
    TRACING.with(|t| t.set(false));
}

// SAFETY: forwards to the system allocator.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        trace();
        // SAFETY: the caller's layout.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: allocated by `alloc` with this layout.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        trace();
        // SAFETY: as above.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

const WIDTH: u32 = 320;
const HEIGHT: u32 = 180;
const SLOTS: usize = 2;
/// Frames before the measured ones: the first uploads, and every buffer the changes grow
/// (grid cells the movers reach, the journal) at its steady size.
const WARMUP: usize = 16;

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

/// What the game changes before each frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Changes {
    /// Nothing: a still scene, the camera moving.
    None,
    /// `n` instances moved (one batch).
    Moves(usize),
    /// `n` instances added and the `n` added the frame before removed.
    Churn(usize),
}

impl Changes {
    fn label(self) -> String {
        match self {
            Changes::None => "static".into(),
            Changes::Moves(n) => format!("{n} moved"),
            Changes::Churn(n) => format!("{n} added + {n} removed"),
        }
    }
}

/// The game: its handles and the buffers it changes the scene with (kept: its own frames
/// allocate nothing either).
struct Game {
    movers: Vec<(InstanceHandle, Transform)>,
    batch: Vec<(InstanceHandle, Transform)>,
    spawned: Vec<InstanceHandle>,
    spawn_mesh: Option<MeshHandle>,
}

impl Game {
    fn new(scene: &Scene, changes: Changes) -> Self {
        let n = scene.instances().len();
        let movers = match changes {
            Changes::Moves(m) => (0..m.min(n))
                .filter_map(|k| {
                    let id = InstanceId((k * n / m.max(1)) as u32);
                    let h = scene.instance_handle(id)?;
                    Some((h, scene.instances()[id.index()].transform))
                })
                .collect(),
            _ => Vec::new(),
        };
        let spawn_mesh = (0..scene.meshes().len() as u32)
            .filter_map(|m| scene.mesh_handle(tilegraph_scene::MeshId(m)))
            .nth(3);
        Game {
            batch: Vec::with_capacity(movers.len()),
            movers,
            spawned: Vec::new(),
            spawn_mesh,
        }
    }

    /// The game's changes of frame `frame`; spawns go around `spawn_at` (a level's spawn
    /// area: the same place frame after frame).
    fn change(
        &mut self,
        scene: &mut Scene,
        changes: Changes,
        frame: usize,
        spawn_at: DVec3,
    ) -> Result<(), Box<dyn std::error::Error>> {
        match changes {
            Changes::None => {}
            Changes::Moves(_) => {
                self.batch.clear();
                let dx = (frame % 8) as f64 * 0.25;
                self.batch.extend(self.movers.iter().map(|(h, t)| {
                    let mut t = *t;
                    t.translation.x += dx;
                    (*h, t)
                }));
                scene.set_transforms(&self.batch)?;
            }
            Changes::Churn(n) => {
                for h in self.spawned.drain(..) {
                    scene.remove_instance(h)?;
                }
                let Some(mesh) = self.spawn_mesh else {
                    return Ok(());
                };
                for k in 0..n {
                    let at =
                        spawn_at + DVec3::new((k % 40) as f64 * 2.0, 0.0, (k / 40) as f64 * 2.0);
                    let t = Transform::new(Mat3::IDENTITY, at);
                    self.spawned
                        .push(scene.add_instance(mesh, t, InstanceFlags::default())?);
                }
            }
        }
        Ok(())
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // `cargo bench` passes `--bench`; the rest are ours.
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .collect();
    let specs: Vec<String> = args
        .first()
        .map_or("city:10k,city:100k,city:1M", String::as_str)
        .split(',')
        .map(String::from)
        .collect();
    let frames: usize = args.get(1).map_or(Ok(40), |a| a.parse())?;
    let traced: u64 = std::env::var("TILEGRAPH_TRACE_ALLOCATIONS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(0);
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
        "engine_record: {WIDTH}x{HEIGHT}, {} ({}), {frames} frames after {WARMUP}; per frame: \
         the game's changes + record + stats, thread CPU and wall (median, p90), heap allocations",
        ctx.physical.identity.device_name,
        ctx.profile().name
    );
    let mut side = engine_side(&ctx)?;
    for spec in &specs {
        let base = tilegraph_scene::load(spec)?;
        let n = base.instances().len();
        let mut scenarios = vec![Changes::None];
        if n >= 20_000 {
            scenarios.extend([Changes::Moves(n / 10), Changes::Churn(1_000)]);
        }
        let path: Vec<_> = base
            .camera_path()
            .frames(WIDTH as f32 / HEIGHT as f32)
            .collect();
        for &changes in &scenarios {
            for culling in all {
                let mut scene = base.clone();
                let mut game = Game::new(&scene, changes);
                let render = RenderOptions {
                    technique: Technique::Prepass,
                    culling,
                    width: WIDTH,
                    height: HEIGHT,
                    // Room for what the game spawns: no rebuild in the measured frames.
                    instance_capacity: (n + 2_000) as u32,
                    ..Default::default()
                };
                let mut r = SceneRenderer::for_engine(&ctx, &scene, render, SLOTS)?;
                let mut times = Vec::with_capacity(frames);
                let mut cpu_times = Vec::with_capacity(frames);
                let mut change_times = Vec::with_capacity(frames);
                let mut allocations = 0;
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
                    if i == WARMUP {
                        TRACE.store(traced, Ordering::Relaxed);
                    }
                    let before = ALLOCATIONS.load(Ordering::Relaxed);
                    let start = Instant::now();
                    let cpu_start = thread_cpu();
                    game.change(&mut scene, changes, i, path[0].camera.eye)?;
                    let changed = thread_cpu();
                    let report = r.record(&ctx, &scene, frame, engine, &target)?;
                    let timed = r.executor().latest_timings().map(|t| t.frame);
                    let cpu = thread_cpu().saturating_sub(cpu_start);
                    let elapsed = start.elapsed();
                    let allocated = ALLOCATIONS.load(Ordering::Relaxed) - before;
                    drop((report, timed));
                    if i + 1 == WARMUP + frames {
                        TRACE.store(0, Ordering::Relaxed);
                    }
                    if i >= WARMUP {
                        times.push(elapsed);
                        cpu_times.push(cpu);
                        change_times.push(changed.saturating_sub(cpu_start));
                        allocations += allocated;
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
                for v in [&mut times, &mut cpu_times, &mut change_times] {
                    v.sort_unstable();
                }
                let ms = |d: Duration| d.as_secs_f64() * 1e3;
                println!(
                    "  {spec:<10} {:>9} instances  {:<22} {:<11} CPU: median {:.3} ms (changes {:.3}), p90 {:.3} ms; wall: median {:.3} ms, p90 {:.3} ms; allocations in {frames} frames: {allocations}",
                    n,
                    changes.label(),
                    culling.name(),
                    ms(percentile(&cpu_times, 0.5)),
                    ms(percentile(&change_times, 0.5)),
                    ms(percentile(&cpu_times, 0.9)),
                    ms(percentile(&times, 0.5)),
                    ms(percentile(&times, 0.9)),
                );
                ctx.wait_idle()?;
                side.submitted.iter_mut().for_each(|s| *s = false);
                // SAFETY: the device is idle: the fences' frames are done.
                unsafe { ctx.device.reset_fences(&side.fences)? };
                r.destroy(&ctx);
            }
        }
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
