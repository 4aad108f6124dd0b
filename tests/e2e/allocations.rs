//! Heap allocations of the engine's frame, counted by a global allocator: after the first
//! frame (declaration, plan, resources — and room for the plan's GPU times) recording a frame
//! and reading its statistics allocate nothing; a frame that re-declares (the engine changed
//! how it hands its target over) is counted and reported, and the frames after it allocate
//! nothing again. The game moves a tenth of the city every frame, in the count: changes to the
//! scene allocate nothing either. Under two-phase culling the frame also renders a second
//! camera with shadows of its own (a further view, moved every frame): nothing either.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicU64, Ordering};

use tilegraph_e2e::engine::Engine;
use tilegraph_e2e::frames;
use tilegraph_graph::{AccessFlags, Layout as ImageLayout, PipelineStages, ResourceState};
use tilegraph_passes::cull::Culling;
use tilegraph_passes::{EngineTarget, RenderOptions, SceneRenderer, Technique};
use tilegraph_vk::ash::vk;
use tilegraph_vk::executor::EngineFrame;

/// The system allocator, counting allocations (and reallocations) on every thread.
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

fn allocations() -> u64 {
    ALLOCATIONS.load(Ordering::Relaxed)
}

#[test]
fn recording_and_stats_allocate_nothing_after_the_first_frames() {
    let mut scene = tilegraph_scene::load("city:2000").unwrap();
    // The game's movers and the batch it hands over (its own buffers, kept between frames).
    let movers: Vec<_> = (0..scene.instances().len() as u32)
        .step_by(10)
        .filter_map(|i| {
            let id = tilegraph_scene::InstanceId(i);
            Some((
                scene.instance_handle(id)?,
                scene.instances()[i as usize].transform,
            ))
        })
        .collect();
    assert!(movers.len() >= 150, "{} movers", movers.len());
    let mut batch = Vec::with_capacity(movers.len());
    for culling in [Culling::Frustum, Culling::HizTwoPhase] {
        let options = RenderOptions {
            technique: Technique::Prepass,
            culling,
            width: 96,
            height: 54,
            ..Default::default()
        };
        let mut engine = Engine::start();
        let ctx = engine.adopt(&options.device_features(), None).unwrap();
        let slots = 2;
        let mut r = SceneRenderer::for_engine(&ctx, &scene, options.clone(), slots).unwrap();
        let path: Vec<_> = scene.camera_path().frames(16.0 / 9.0).take(24).collect();
        // A second camera further along the path, with two cascades, into its own target.
        let view = (culling == Culling::HizTwoPhase).then(|| {
            let view_options = RenderOptions {
                culling: Culling::Frustum,
                width: 48,
                height: 32,
                shadows: tilegraph_passes::shadow::ShadowOptions {
                    cascades: 2,
                    resolution: 128,
                    ..Default::default()
                },
                ..options.clone()
            };
            r.add_view(&ctx, &scene, view_options, &path[12].camera)
                .unwrap()
        });
        let (image, handle) = frames::target(&ctx, options.width, options.height).unwrap();
        let pool_info = vk::CommandPoolCreateInfo::default()
            .queue_family_index(ctx.queue_family)
            .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER);
        // SAFETY: valid device.
        let pool = unsafe { ctx.device.create_command_pool(&pool_info, None) }.unwrap();
        let alloc = vk::CommandBufferAllocateInfo::default()
            .command_pool(pool)
            .level(vk::CommandBufferLevel::PRIMARY)
            .command_buffer_count(slots as u32);
        // SAFETY: live pool.
        let cbs = unsafe { ctx.device.allocate_command_buffers(&alloc) }.unwrap();
        // SAFETY: valid device.
        let fences: Vec<vk::Fence> = (0..slots)
            .map(|_| {
                unsafe {
                    ctx.device
                        .create_fence(&vk::FenceCreateInfo::default(), None)
                }
                .unwrap()
            })
            .collect();
        let kept = ResourceState::image(
            ImageLayout::TransferSrc,
            PipelineStages::COPY,
            AccessFlags::TRANSFER_READ,
        );
        // From frame 12 the engine hands its target over as the last frame left it (its
        // content kept) instead of discarded: a different declaration.
        const REDECLARE: usize = 12;
        let mut declared = Vec::new();
        let mut per_frame = Vec::new();
        let mut submitted = vec![false; slots];
        let mut gpu_ms = 0.0;
        for (i, frame) in path.iter().enumerate() {
            let slot = i % slots;
            let cb = cbs[slot];
            // The engine's side, outside the count: wait, reset, begin.
            // SAFETY: the fence was submitted with the slot's last frame.
            unsafe {
                if submitted[slot] {
                    ctx.device
                        .wait_for_fences(&[fences[slot]], true, u64::MAX)
                        .unwrap();
                    ctx.device.reset_fences(&[fences[slot]]).unwrap();
                }
                ctx.device
                    .reset_command_buffer(cb, vk::CommandBufferResetFlags::empty())
                    .unwrap();
                ctx.device
                    .begin_command_buffer(cb, &vk::CommandBufferBeginInfo::default())
                    .unwrap();
            }
            let target = EngineTarget {
                image: &handle,
                initial: if i < REDECLARE {
                    ResourceState::UNDEFINED
                } else {
                    kept
                },
                final_state: kept,
            };
            let engine_frame = EngineFrame {
                command_buffer: cb,
                slot,
            };
            let before = allocations();
            batch.clear();
            batch.extend(movers.iter().map(|(h, t)| {
                let mut t = *t;
                t.translation.x += (i % 6) as f64 * 0.5;
                (*h, t)
            }));
            scene.set_transforms(&batch).unwrap();
            if let Some(v) = view {
                let camera = path[(i + 12) % path.len()].camera;
                r.set_view_camera(v, &camera, false).unwrap();
            }
            let report = r
                .record(&ctx, &scene, frame, engine_frame, &target)
                .unwrap();
            // Statistics: the report, and the newest GPU times from the query ring.
            let drawn = report.draws;
            let was_declared = report.declared;
            if let Some(t) = r.executor().latest_timings() {
                gpu_ms = t.passes.iter().map(|p| p.gpu_ms).sum::<f64>();
            }
            drop(report);
            per_frame.push(allocations() - before);
            declared.push(was_declared);
            assert!(drawn > 0);
            let cbs = [cb];
            let submit = vk::SubmitInfo::default().command_buffers(&cbs);
            // SAFETY: recorded buffer, unsignalled fence.
            unsafe {
                ctx.device.end_command_buffer(cb).unwrap();
                ctx.device
                    .queue_submit(ctx.queue, &[submit], fences[slot])
                    .unwrap();
            }
            submitted[slot] = true;
        }
        assert!(gpu_ms > 0.0, "no GPU times arrived");
        println!(
            "{}: heap allocations per frame {per_frame:?}: frame 0 declares ({}), frame \
             {REDECLARE} re-declares ({})",
            culling.name(),
            per_frame[0],
            per_frame[REDECLARE],
        );
        // The further view's target is the renderer's: its first frame imports it undefined,
        // the second as the first left it — a declaration of its own.
        let expected: &[usize] = match view {
            Some(_) => &[0, 1, REDECLARE],
            None => &[0, REDECLARE],
        };
        let declaring: Vec<usize> = (0..declared.len()).filter(|&i| declared[i]).collect();
        assert_eq!(declaring, expected, "frames that declared");
        assert!(
            per_frame[0] > 0 && per_frame[REDECLARE] > 0,
            "{per_frame:?}"
        );
        let steady = per_frame
            .iter()
            .enumerate()
            .filter(|(i, _)| !expected.contains(i));
        for (i, n) in steady {
            assert_eq!(
                *n,
                0,
                "{}: frame {i} allocates: {per_frame:?}",
                culling.name()
            );
        }
        // SAFETY: idle device (waited below first).
        unsafe {
            ctx.device.device_wait_idle().unwrap();
            for f in fences {
                ctx.device.destroy_fence(f, None);
            }
            ctx.device.destroy_command_pool(pool, None);
        }
        r.destroy(&ctx);
        frames::destroy_target(&ctx, image, handle);
        ctx.destroy_checked().unwrap();
        let messages = engine.destroy();
        assert!(messages.is_empty(), "validation: {messages:#?}");
    }
}
