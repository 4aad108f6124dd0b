//! Embedding from Rust: an engine's own instance and device (made with plain ash, its own
//! messenger, validation and synchronization validation on) adopted by tilegraph. The frame
//! equals the one tilegraph renders on a device it creates, bit for bit; tilegraph never
//! destroys what it adopted, and destroys everything it made on it (the engine's teardown of
//! the device reports no object left alive).

use std::sync::Arc;

use tilegraph_e2e::engine::Engine;
use tilegraph_e2e::{frames, gpu_with};
use tilegraph_graph::{AccessFlags, Layout, PipelineStages, ResourceState};
use tilegraph_passes::cull::Culling;
use tilegraph_passes::{
    EngineTarget, RenderError, RenderOptions, SceneRenderer, Technique, WantedBy,
};
use tilegraph_scene::Scene;
use tilegraph_vk::ash::vk;
use tilegraph_vk::executor::EngineFrame;
use tilegraph_vk::readback::RgbaImage;
use tilegraph_vk::{Context, Feature, FeatureRequest};

fn city() -> Scene {
    tilegraph_scene::load("city:300").unwrap()
}

fn options() -> RenderOptions {
    RenderOptions {
        technique: Technique::Prepass,
        culling: Culling::HizTwoPhase,
        width: 160,
        height: 90,
        ..Default::default()
    }
}

const FRAMES: usize = 4;

fn aspect() -> f32 {
    let o = options();
    o.width as f32 / o.height as f32
}

/// The city's first frames (each culls against the ones before), submitted by tilegraph.
fn render(ctx: &Context, scene: &Scene) -> RgbaImage {
    let mut r = SceneRenderer::new(ctx, scene, options()).unwrap();
    for frame in scene.camera_path().frames(aspect()).take(FRAMES) {
        r.render_frame(ctx, scene, &frame).unwrap();
    }
    let image = r.read_image(ctx).unwrap();
    r.destroy(ctx);
    image
}

#[test]
fn an_adopted_device_renders_the_same_frame_and_is_left_to_the_engine() {
    let scene = city();
    let reference = {
        let g = gpu_with(Some("mali-valhall"), options().device_features()).unwrap();
        render(&g, &scene)
    };

    let mut engine = Engine::start();
    let ctx = engine
        .adopt(&options().device_features(), Some("mali-valhall"))
        .unwrap();
    assert!(!ctx.owns_device());
    assert!(!ctx.instance().owned());
    assert_eq!(ctx.profile().name, "mali-valhall");
    let image = render(&ctx, &scene);
    ctx.wait_idle().unwrap();
    ctx.destroy_checked().unwrap();
    assert!(
        image.pixels == reference.pixels,
        "the adopted device's frame differs from tilegraph's own"
    );
    // The device is still the engine's: it can still use it after tilegraph is gone.
    let device = engine.device.as_ref().unwrap();
    // SAFETY: a live device of the engine's.
    unsafe { device.device_wait_idle() }.unwrap();
    let messages = engine.destroy();
    assert!(messages.is_empty(), "validation: {messages:#?}");
}

/// The profile is chosen from the adopted device's identity when none is forced.
#[test]
fn an_adopted_device_gets_the_profile_of_its_identity() {
    let mut engine = Engine::start();
    let ctx = engine.adopt(&FeatureRequest::executor(), None).unwrap();
    let own = gpu_with(None, FeatureRequest::default()).unwrap();
    assert_eq!(ctx.profile().name, own.profile().name);
    assert_eq!(
        ctx.physical.identity.device_name,
        own.physical.identity.device_name
    );
    drop(own);
    ctx.destroy_checked().unwrap();
    let messages = engine.destroy();
    assert!(messages.is_empty(), "validation: {messages:#?}");
}

/// A device created without what the options need fails when the renderer is made, with the
/// feature and what wants it — not as a validation error later.
#[test]
fn a_missing_feature_on_an_adopted_device_names_the_feature_and_its_user() {
    let scene = city();
    let mut engine = Engine::start();
    // The engine enabled only what the executor needs: no host query reset.
    let ctx = engine.adopt(&FeatureRequest::executor(), None).unwrap();
    let queries = RenderOptions {
        culling: Culling::Oq,
        ..options()
    };
    let err = SceneRenderer::new(&ctx, &scene, queries)
        .err()
        .expect("the renderer must refuse the device");
    match &err {
        RenderError::MissingFeature {
            feature, wanted_by, ..
        } => {
            assert_eq!(*feature, Feature::HostQueryReset);
            assert_eq!(*wanted_by, WantedBy::Culling(Culling::Oq));
        }
        other => panic!("unexpected error: {other}"),
    }
    let text = err.to_string();
    assert!(
        text.contains("culling oq") && text.contains("HostQueryReset"),
        "{text}"
    );
    ctx.destroy_checked().unwrap();
    let messages = engine.destroy();
    assert!(messages.is_empty(), "validation: {messages:#?}");
}

/// The engine's messenger really sees objects left alive at its device's teardown: the check
/// the tests above rely on.
#[test]
fn the_engines_teardown_reports_an_object_left_alive() {
    let mut engine = Engine::start();
    let ctx = engine.adopt(&FeatureRequest::executor(), None).unwrap();
    ctx.destroy_checked().unwrap();
    let device = engine.device.as_ref().unwrap();
    let info = tilegraph_vk::ash::vk::BufferCreateInfo::default()
        .size(256)
        .usage(tilegraph_vk::ash::vk::BufferUsageFlags::UNIFORM_BUFFER);
    // SAFETY: a valid buffer, deliberately never destroyed.
    let _leaked = unsafe { device.create_buffer(&info, None) }.unwrap();
    let messages = engine.destroy();
    assert!(
        messages.iter().any(|m| m.contains("vkDestroyDevice")),
        "the leak was not reported: {messages:#?}"
    );
}

/// The engine's per-slot command buffers and fences.
struct EngineFrames {
    pool: vk::CommandPool,
    cbs: Vec<vk::CommandBuffer>,
    fences: Vec<vk::Fence>,
    submitted: Vec<bool>,
}

impl EngineFrames {
    fn new(ctx: &Context, slots: usize) -> EngineFrames {
        let d = &ctx.device;
        let info = vk::CommandPoolCreateInfo::default()
            .queue_family_index(ctx.queue_family)
            .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER);
        // SAFETY: valid device and family.
        let pool = unsafe { d.create_command_pool(&info, None) }.unwrap();
        let alloc = vk::CommandBufferAllocateInfo::default()
            .command_pool(pool)
            .level(vk::CommandBufferLevel::PRIMARY)
            .command_buffer_count(slots as u32);
        // SAFETY: live pool.
        let cbs = unsafe { d.allocate_command_buffers(&alloc) }.unwrap();
        let fences = (0..slots)
            // SAFETY: valid device.
            .map(|_| unsafe { d.create_fence(&vk::FenceCreateInfo::default(), None) }.unwrap())
            .collect();
        EngineFrames {
            pool,
            cbs,
            fences,
            submitted: vec![false; slots],
        }
    }

    /// Waits for the slot's last frame, and begins its command buffer.
    fn begin(&mut self, ctx: &Context, slot: usize) -> vk::CommandBuffer {
        let d = &ctx.device;
        // SAFETY: the fence was submitted with the slot's last frame; the buffer is then idle.
        unsafe {
            if std::mem::take(&mut self.submitted[slot]) {
                d.wait_for_fences(&[self.fences[slot]], true, u64::MAX)
                    .unwrap();
                d.reset_fences(&[self.fences[slot]]).unwrap();
            }
            let cb = self.cbs[slot];
            d.reset_command_buffer(cb, vk::CommandBufferResetFlags::empty())
                .unwrap();
            d.begin_command_buffer(cb, &vk::CommandBufferBeginInfo::default())
                .unwrap();
            cb
        }
    }

    fn submit(&mut self, ctx: &Context, slot: usize) {
        let cbs = [self.cbs[slot]];
        let submit = vk::SubmitInfo::default().command_buffers(&cbs);
        // SAFETY: a recorded buffer; the slot's fence is unsignalled.
        unsafe {
            ctx.device.end_command_buffer(cbs[0]).unwrap();
            ctx.device
                .queue_submit(ctx.queue, &[submit], self.fences[slot])
                .unwrap();
        }
        self.submitted[slot] = true;
    }

    fn destroy(self, ctx: &Context) {
        // SAFETY: the device is idle.
        unsafe {
            ctx.device.device_wait_idle().unwrap();
            for f in self.fences {
                ctx.device.destroy_fence(f, None);
            }
            ctx.device.destroy_command_pool(self.pool, None);
        }
    }
}

/// The engine clears its target itself, then hands it over in the state the clear left it in.
fn engine_clear(ctx: &Context, cb: vk::CommandBuffer, image: vk::Image, old: vk::ImageLayout) {
    let range = vk::ImageSubresourceRange {
        aspect_mask: vk::ImageAspectFlags::COLOR,
        base_mip_level: 0,
        level_count: 1,
        base_array_layer: 0,
        layer_count: 1,
    };
    let to_dst = [vk::ImageMemoryBarrier2::default()
        .src_stage_mask(vk::PipelineStageFlags2::COPY)
        .dst_stage_mask(vk::PipelineStageFlags2::CLEAR)
        .dst_access_mask(vk::AccessFlags2::TRANSFER_WRITE)
        .old_layout(old)
        .new_layout(vk::ImageLayout::TRANSFER_DST_OPTIMAL)
        .image(image)
        .subresource_range(range)];
    // SAFETY: recording, outside a render pass.
    unsafe {
        ctx.device.cmd_pipeline_barrier2(
            cb,
            &vk::DependencyInfo::default().image_memory_barriers(&to_dst),
        );
        ctx.device.cmd_clear_color_image(
            cb,
            image,
            vk::ImageLayout::TRANSFER_DST_OPTIMAL,
            &vk::ClearColorValue {
                float32: [1.0, 0.0, 0.0, 1.0],
            },
            &[range],
        );
    }
}

/// The engine records tilegraph's frames into its own command buffers (two slots, two target
/// images like a swapchain's), submits them itself, and gets the same image, bit for bit, as
/// tilegraph's own submission. Its target arrives in the layout the engine's clear left it in
/// and leaves in the one the engine asked for; an unchanged frame reuses its plan; GPU times
/// arrive from the query ring without waiting.
#[test]
fn the_engine_records_tilegraphs_frame_into_its_own_command_buffer() {
    let scene = city();
    let reference = {
        let g = gpu_with(Some("mali-valhall"), options().device_features()).unwrap();
        render(&g, &scene)
    };
    let mut engine = Engine::start();
    let ctx = engine
        .adopt(&options().device_features(), Some("mali-valhall"))
        .unwrap();
    let slots = 2;
    let mut r = SceneRenderer::for_engine(&ctx, &scene, options(), slots).unwrap();
    let o = options();
    let targets = [
        frames::target(&ctx, o.width, o.height).unwrap(),
        frames::target(&ctx, o.width, o.height).unwrap(),
    ];
    let mut engine_frames = EngineFrames::new(&ctx, slots);
    let cleared = ResourceState::image(
        Layout::TransferDst,
        PipelineStages::CLEAR,
        AccessFlags::TRANSFER_WRITE,
    );
    let for_copy = ResourceState::image(
        Layout::TransferSrc,
        PipelineStages::COPY,
        AccessFlags::TRANSFER_READ,
    );
    let mut plans = Vec::new();
    let mut timed = 0;
    for (i, frame) in scene
        .camera_path()
        .frames(aspect())
        .take(FRAMES)
        .enumerate()
    {
        let slot = i % slots;
        let cb = engine_frames.begin(&ctx, slot);
        let (_, handle) = &targets[i % 2];
        let old = if i < 2 {
            vk::ImageLayout::UNDEFINED
        } else {
            vk::ImageLayout::TRANSFER_SRC_OPTIMAL
        };
        engine_clear(&ctx, cb, handle.raw, old);
        let target = EngineTarget {
            image: handle,
            initial: cleared,
            final_state: for_copy,
        };
        let engine_frame = EngineFrame {
            command_buffer: cb,
            slot,
        };
        let report = r
            .record(&ctx, &scene, &frame, engine_frame, &target)
            .unwrap();
        assert_eq!(report.stats.flushes, 0);
        plans.push(report.plan);
        engine_frames.submit(&ctx, slot);
        timed += usize::from(r.executor().latest_timings().is_some());
    }
    // Frame 0 declares (first frame), frame 1 declares again (no longer the first); from
    // then on the same plan.
    assert!(
        Arc::ptr_eq(&plans[1], &plans[3]),
        "the unchanged frame re-declared"
    );
    assert!(timed > 0, "no GPU times arrived from the query ring");
    engine_frames.destroy(&ctx);
    let last = &targets[(FRAMES - 1) % 2].1;
    let pixels =
        tilegraph_vk::readback::read_image(&ctx, last, vk::ImageLayout::TRANSFER_SRC_OPTIMAL, 0)
            .unwrap();
    assert!(
        pixels == reference.pixels,
        "the engine-recorded frame differs from tilegraph's own"
    );
    r.destroy(&ctx);
    for (image, handle) in targets {
        frames::destroy_target(&ctx, image, handle);
    }
    ctx.destroy_checked().unwrap();
    let messages = engine.destroy();
    assert!(messages.is_empty(), "validation: {messages:#?}");
}

/// The Adreno profile flushes before its occlusion-query render pass; with the engine
/// submitting, that flush is counted for the engine to make, not made.
#[test]
fn a_flush_the_engine_owns_is_counted_not_made() {
    let scene = city();
    let options = RenderOptions {
        culling: Culling::Oq,
        ..options()
    };
    let mut engine = Engine::start();
    let ctx = engine
        .adopt(&options.device_features(), Some("adreno-7xx"))
        .unwrap();
    let mut r = SceneRenderer::for_engine(&ctx, &scene, options.clone(), 1).unwrap();
    let (image, handle) = frames::target(&ctx, options.width, options.height).unwrap();
    let mut engine_frames = EngineFrames::new(&ctx, 1);
    let mut left = 0;
    for frame in scene.camera_path().frames(aspect()).take(2) {
        let cb = engine_frames.begin(&ctx, 0);
        let target = EngineTarget {
            image: &handle,
            initial: ResourceState::UNDEFINED,
            final_state: ResourceState::image(
                Layout::TransferSrc,
                PipelineStages::COPY,
                AccessFlags::TRANSFER_READ,
            ),
        };
        let f = EngineFrame {
            command_buffer: cb,
            slot: 0,
        };
        let report = r.record(&ctx, &scene, &frame, f, &target).unwrap();
        left += report.stats.flushes_left_to_engine;
        assert_eq!(report.stats.flushes, 0);
        engine_frames.submit(&ctx, 0);
    }
    assert!(left > 0, "the adreno profile's flush was not reported");
    // The owned-submission call is refused with the reason.
    let err = r.render(&ctx, &scene, &scene.camera_path().camera(0).unwrap());
    assert!(matches!(err, Err(RenderError::EngineSubmits)));
    engine_frames.destroy(&ctx);
    r.destroy(&ctx);
    frames::destroy_target(&ctx, image, handle);
    ctx.destroy_checked().unwrap();
    let messages = engine.destroy();
    assert!(messages.is_empty(), "validation: {messages:#?}");
}

/// Out-of-memory injected through the context's memory budget: the frame that needs memory
/// fails with a typed error, nothing is left half-made, and once memory is available the next
/// frame renders the same image as an undisturbed renderer.
#[test]
fn out_of_memory_fails_the_frame_cleanly_and_the_next_one_succeeds() {
    let scene = city();
    let g = gpu_with(Some("mali-valhall"), options().device_features()).unwrap();
    let reference = render(&g, &scene);
    let mut r = SceneRenderer::new(&g, &scene, options()).unwrap();
    let frames: Vec<_> = scene.camera_path().frames(aspect()).take(FRAMES).collect();
    // The renderer holds its scene; the first frame still needs its attachments.
    g.set_memory_budget(Some(g.allocated_bytes()));
    let err = r.render_frame(&g, &scene, &frames[0]).unwrap_err();
    assert!(err.is_out_of_memory(), "{err}");
    assert!(err.to_string().contains("out of device memory"), "{err}");
    let held = g.allocated_bytes();
    // Failing again holds no more memory.
    let err = r.render_frame(&g, &scene, &frames[0]).unwrap_err();
    assert!(err.is_out_of_memory(), "{err}");
    assert_eq!(g.allocated_bytes(), held);
    g.set_memory_budget(None);
    for frame in &frames {
        r.render_frame(&g, &scene, frame).unwrap();
    }
    let image = r.read_image(&g).unwrap();
    assert!(
        image.pixels == reference.pixels,
        "the frame after the failure differs"
    );
    r.destroy(&g);
}
