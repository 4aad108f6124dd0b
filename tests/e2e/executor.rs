//! Executing compiled plans on lavapipe, validation (with synchronization validation) on.

use std::sync::Arc;
use tilegraph_e2e::frames::{
    aliasing_frame, classic_mobile_frame, destroy_target, externals, target, visbuf_frame, Frame,
    Kit, Payload,
};
use tilegraph_e2e::gpu;
use tilegraph_graph::Residency;
use tilegraph_vk::ash::vk;

use tilegraph_graph::CompiledGraph;
use tilegraph_vk::executor::{Executor, Externals, FrameStats};
use tilegraph_vk::queries::{GpuTiming, FRAME_TIMING};
use tilegraph_vk::readback::read_image;

const W: u32 = 160;
const H: u32 = 90;

fn px(bytes: &[u8], x: u32, y: u32) -> [u8; 4] {
    let i = ((y * W + x) * 4) as usize;
    [bytes[i], bytes[i + 1], bytes[i + 2], bytes[i + 3]]
}

fn close(a: [u8; 4], b: [u8; 4]) -> bool {
    a.iter().zip(b).all(|(x, y)| x.abs_diff(y) <= 2)
}

/// Executes one frame of `plan`, each pass recorded by its compiled payload.
fn execute(
    exec: &mut Executor,
    g: &tilegraph_vk::Context,
    plan: &Arc<tilegraph_graph::Plan>,
    ext: &Externals,
    compiled: &mut CompiledGraph<Payload>,
) -> FrameStats {
    exec.execute(g, plan, ext, &mut |id, pc| match compiled.payload_mut(id) {
        Some(p) => p(pc),
        None => Ok(()),
    })
    .unwrap()
}

struct Outcome {
    pixels: Vec<u8>,
    render_passes: u32,
    subpasses: u32,
    allocations_after_first: Vec<u64>,
    timings_ok: bool,
    aliasing_used: bool,
}

fn run(
    profile: &str,
    make: fn(&std::rc::Rc<std::cell::RefCell<Kit>>, u32, u32) -> Frame,
    frames: usize,
) -> (Outcome, tilegraph_graph::Plan) {
    let g = gpu(Some(profile)).unwrap();
    let kit = Kit::new(&g).unwrap();
    let frame = make(&kit, W, H);
    let target_id = frame.target;
    let mut compiled = frame.graph.compile(g.profile()).unwrap();
    let plan = Arc::new(compiled.plan.clone());
    let (image, handle) = target(&g, W, H).unwrap();
    let ext = externals(target_id, &handle);
    let mut exec = Executor::new(&g).unwrap();
    let mut allocations = Vec::new();
    let mut stats = None;
    for _ in 0..frames {
        let s = execute(&mut exec, &g, &plan, &ext, &mut compiled);
        allocations.push(s.allocations);
        stats = Some(s);
    }
    exec.finish(&g).unwrap();
    let pixels = read_image(&g, &handle, vk::ImageLayout::TRANSFER_SRC_OPTIMAL, 0).unwrap();
    let stats_supported = g.has_feature(tilegraph_vk::Feature::PipelineStatisticsQuery);
    let timings_ok = exec.latest_timings().is_some_and(|t| {
        (!stats_supported
            || t.passes
                .iter()
                .all(|p| p.vertex_invocations.is_some() && p.fragment_invocations.is_some()))
            && t.passes.len() == plan.passes.len()
            && t.passes
                .iter()
                .all(|p| p.end_ticks >= p.begin_ticks && p.begin_ticks > 0)
            && t.passes
                .windows(2)
                .all(|w| w[1].begin_ticks >= w[0].begin_ticks)
    });
    let stats = stats.unwrap();
    exec.destroy(&g);
    kit.borrow_mut().destroy(&g);
    destroy_target(&g, image, handle);
    (
        Outcome {
            pixels,
            render_passes: stats.render_passes,
            subpasses: stats.subpasses,
            allocations_after_first: allocations[1..].to_vec(),
            timings_ok,
            aliasing_used: stats.aliasing_used,
        },
        Arc::unwrap_or_clone(plan),
    )
}

#[test]
fn classic_mobile_frame_renders_under_every_profile() {
    for profile in [
        "lavapipe",
        "mali-valhall",
        "adreno-7xx",
        "powervr-b",
        "desktop-nvidia",
    ] {
        let (o, plan) = run(profile, classic_mobile_frame, 4);
        if std::env::var_os("SHOW_PLAN").is_some() {
            eprintln!(
                "{profile}: {} render pass(es), {} subpasses\n{plan}",
                o.render_passes, o.subpasses
            );
        }
        // Left: red (near quad) inverted; right: green (far quad) inverted; centre: the blue
        // glass blended over red at 50% then inverted.
        assert!(
            close(px(&o.pixels, 10, 45), [0, 255, 255, 255]),
            "{profile} left {:?}",
            px(&o.pixels, 10, 45)
        );
        assert!(
            close(px(&o.pixels, 150, 45), [255, 0, 255, 255]),
            "{profile} right {:?}",
            px(&o.pixels, 150, 45)
        );
        assert!(
            close(px(&o.pixels, 75, 45), [127, 255, 127, 255]),
            "{profile} centre {:?}",
            px(&o.pixels, 75, 45)
        );
        assert!(
            o.allocations_after_first.iter().all(|a| *a == 0),
            "{profile}: steady-state allocations {:?}",
            o.allocations_after_first
        );
        assert!(
            o.timings_ok,
            "{profile}: timestamps missing, zero or not monotone"
        );
        if plan.passes.len() == 4 && profile != "lavapipe" && profile != "desktop-nvidia" {
            // Tilers: one render pass, four subpasses; depth and scene colour never leave the tile.
            assert_eq!((o.render_passes, o.subpasses), (1, 4), "{profile}\n{plan}");
            for name in ["depth", "scene-color"] {
                assert_eq!(
                    plan.resource_by_name(name).unwrap().residency,
                    Residency::Transient,
                    "{profile} {name}"
                );
            }
        }
    }
}

/// Each timing mode records the queries it names and no others (validation checks that every
/// query read was written), and a change of mode starts a new history.
#[test]
fn each_timing_mode_measures_what_it_names() {
    let g = gpu(Some("lavapipe")).unwrap();
    let kit = Kit::new(&g).unwrap();
    let frame = classic_mobile_frame(&kit, W, H);
    let target_id = frame.target;
    let mut compiled = frame.graph.compile(g.profile()).unwrap();
    let plan = Arc::new(compiled.plan.clone());
    let (image, handle) = target(&g, W, H).unwrap();
    let ext = externals(target_id, &handle);
    let mut exec = Executor::new(&g).unwrap();
    let stats_supported = g.has_feature(tilegraph_vk::Feature::PipelineStatisticsQuery);
    let passes = plan.passes.len();
    for timing in [
        GpuTiming::Frame,
        GpuTiming::Passes,
        GpuTiming::Off,
        GpuTiming::PassStatistics,
        GpuTiming::Frame,
    ] {
        exec.set_timing(&g, timing).unwrap();
        assert_eq!(exec.timing(), timing);
        assert!(exec.medians().is_empty(), "{timing}: history kept");
        for _ in 0..3 {
            execute(&mut exec, &g, &plan, &ext, &mut compiled);
        }
        exec.finish(&g).unwrap();
        let latest = exec.latest_timings();
        let names: Vec<String> = exec.medians().into_iter().map(|m| m.name).collect();
        match timing {
            GpuTiming::Off => {
                assert!(latest.is_none(), "off: {latest:?}");
                assert!(names.is_empty(), "off: {names:?}");
            }
            GpuTiming::Frame => {
                let t = latest.unwrap();
                assert_eq!(t.passes.len(), 1, "{t:?}");
                let f = &t.passes[0];
                assert_eq!(f.name, FRAME_TIMING);
                assert!(f.end_ticks > f.begin_ticks && f.gpu_ms > 0.0, "{f:?}");
                assert!(f.vertex_invocations.is_none());
                assert_eq!(names, [FRAME_TIMING]);
            }
            GpuTiming::Passes | GpuTiming::PassStatistics => {
                let t = latest.unwrap();
                assert_eq!(t.passes.len(), passes, "{timing}: {t:?}");
                let counted = timing == GpuTiming::PassStatistics && stats_supported;
                assert!(
                    t.passes
                        .iter()
                        .all(|p| p.vertex_invocations.is_some() == counted
                            && p.fragment_invocations.is_some() == counted),
                    "{timing}: {t:?}"
                );
                assert_eq!(names.len(), passes, "{timing}: {names:?}");
            }
        }
    }
    exec.destroy(&g);
    kit.borrow_mut().destroy(&g);
    destroy_target(&g, image, handle);
}

#[test]
fn visbuf_frame_keeps_ids_on_chip_and_resolves_them() {
    for profile in ["mali-valhall", "adreno-7xx", "lavapipe"] {
        let (o, plan) = run(profile, visbuf_frame, 3);
        // id 7 -> (7/255, 0, 1); id 9 -> (9/255, 0, 1).
        assert!(
            close(px(&o.pixels, 10, 45), [7, 0, 255, 255]),
            "{profile} left {:?}",
            px(&o.pixels, 10, 45)
        );
        assert!(
            close(px(&o.pixels, 150, 45), [9, 0, 255, 255]),
            "{profile} right {:?}",
            px(&o.pixels, 150, 45)
        );
        assert!(o.allocations_after_first.iter().all(|a| *a == 0));
        if profile != "lavapipe" {
            assert_eq!((o.render_passes, o.subpasses), (1, 2), "{profile}\n{plan}");
            assert_eq!(
                plan.resource_by_name("visbuf-id").unwrap().residency,
                Residency::Transient
            );
        }
    }
}

#[test]
fn aliased_images_in_sequence_render_correctly() {
    for profile in ["lavapipe", "mali-valhall"] {
        let (o, plan) = run(profile, aliasing_frame, 3);
        assert!(
            plan.aliasing.saved_bytes() > 0,
            "{profile}: the plan did not alias a and b\n{plan}"
        );
        let (a, b) = (
            plan.resource_by_name("a").unwrap(),
            plan.resource_by_name("b").unwrap(),
        );
        let (sa, sb) = (a.memory.unwrap(), b.memory.unwrap());
        assert!(
            sa.overlaps(&sb),
            "{profile}: a and b do not share memory\n{plan}"
        );
        assert!(
            o.aliasing_used,
            "{profile}: real memory requirements forced dedicated memory"
        );
        assert!(
            close(px(&o.pixels, 10, 45), [255, 0, 0, 255]),
            "{profile} left {:?}",
            px(&o.pixels, 10, 45)
        );
        assert!(
            close(px(&o.pixels, 150, 45), [0, 0, 255, 255]),
            "{profile} right {:?}",
            px(&o.pixels, 150, 45)
        );
        assert!(o.allocations_after_first.iter().all(|a| *a == 0));
    }
}

/// A plan that asks for something the device was not created with gets a typed error before
/// anything is created: here a conditional-rendering predicate without
/// VK_EXT_conditional_rendering enabled.
#[test]
fn a_predicate_without_conditional_rendering_is_a_typed_error() {
    use tilegraph_graph::{ClearColor, Coverage, GraphBuilder, PassClass};
    let g = gpu(Some("lavapipe")).unwrap();
    assert!(g.conditional_rendering().is_none());
    let (image, handle) = target(&g, W, H).unwrap();
    let mut graph: GraphBuilder<()> = GraphBuilder::new();
    let out = graph.import_image(
        "target",
        tilegraph_graph::ImageDesc::new(
            tilegraph_graph::Extent2d::new(W, H),
            tilegraph_graph::Format::R8G8B8A8_UNORM,
        ),
        tilegraph_graph::Import::SWAPCHAIN,
    );
    graph.export(out);
    let conditions = graph.create_buffer("conditions", 256);
    graph
        .transfer_pass("fill", PassClass::Transfer, ())
        .transfer_dst(conditions)
        .coverage(Coverage::Full);
    graph
        .raster_pass("draw", PassClass::Opaque, ())
        .predicate(conditions)
        .color_clear(out, ClearColor::BLACK);
    let plan = Arc::new(graph.compile(g.profile()).unwrap().plan);
    let ext = externals(out, &handle);
    let mut exec = Executor::new(&g).unwrap();
    let err = exec
        .execute(&g, &plan, &ext, &mut |_, _| Ok(()))
        .expect_err("a predicate needs VK_EXT_conditional_rendering");
    assert!(
        err.to_string().contains("VK_EXT_conditional_rendering"),
        "{err}"
    );
    exec.destroy(&g);
    destroy_target(&g, image, handle);
}

/// A pass that fails after a flush (the query render pass on Adreno, seed 001): the frame is
/// given up without ending its command buffer inside the render pass, the half already
/// submitted is waited for before the slot is reused, and the next frames run. Flushes reuse
/// their command buffers frame after frame.
#[test]
fn a_frame_that_fails_after_a_flush_is_given_up_cleanly() {
    use tilegraph_graph::{
        ClearColor, ClearDepthStencil, Extent2d, Format, GraphBuilder, ImageDesc, Import,
        PassClass, Retention, Step,
    };
    let g = gpu(Some("adreno-7xx")).unwrap();
    let (image, handle) = target(&g, W, H).unwrap();
    let extent = Extent2d::new(W, H);
    // Payload: whether the pass is the query pass.
    let mut graph: GraphBuilder<bool> = GraphBuilder::new();
    let out = graph.import_image(
        "target",
        ImageDesc::new(extent, Format::R8G8B8A8_UNORM),
        Import::SWAPCHAIN,
    );
    graph.export(out);
    let depth = graph.create_image("depth", ImageDesc::new(extent, Format::D32_SFLOAT));
    graph
        .raster_pass("opaque", PassClass::Opaque, false)
        .color_clear(out, ClearColor::BLACK)
        .depth_stencil_clear(depth, ClearDepthStencil::REVERSE_Z);
    graph
        .raster_pass("queries", PassClass::OcclusionQuery, true)
        .depth_stencil_read_only(depth)
        .retention(Retention::Always);
    let compiled = graph.compile(g.profile()).unwrap();
    let plan = Arc::new(compiled.plan.clone());
    assert!(
        plan.steps.iter().any(|s| matches!(s, Step::Flush(_))),
        "adreno-7xx flushes before the query render pass:\n{plan}"
    );
    let ext = externals(out, &handle);
    let mut exec = Executor::new(&g).unwrap();
    for frame in 0..6 {
        let fail = frame == 2;
        let result = exec.execute(&g, &plan, &ext, &mut |id, _| {
            if fail && compiled.payload(id) == Some(&true) {
                Err(tilegraph_vk::VkError::Invalid {
                    what: "test".into(),
                    reason: "the query pass fails".into(),
                })
            } else {
                Ok(())
            }
        });
        assert_eq!(result.is_err(), fail, "frame {frame}: {result:?}");
    }
    exec.finish(&g).unwrap();
    // One command buffer per slot, and one more per slot for the half after the flush.
    assert_eq!(exec.command_buffer_count(), 2 * exec.frames_in_flight());
    exec.destroy(&g);
    destroy_target(&g, image, handle);
}

/// A buffer the graph owns and writes before anything else in the frame has no barrier in the
/// plan; from the second frame on the executor makes that first write wait for the earlier
/// frames still in flight (queue submissions are not ordered by themselves). lavapipe runs
/// submissions one after another, so this checks that the added barrier is valid usage (clean
/// under validation), not the race itself.
#[test]
fn an_owned_buffer_written_first_waits_for_earlier_frames() {
    use tilegraph_graph::{Coverage, GraphBuilder, PassClass};
    let g = gpu(Some("lavapipe")).unwrap();
    let mut graph: GraphBuilder<()> = GraphBuilder::new();
    let result = graph.create_buffer("result", 1024);
    let copy = graph.create_buffer("copy", 1024);
    graph.export(result);
    graph.export(copy);
    let fill = graph
        .transfer_pass("fill", PassClass::Transfer, ())
        .transfer_dst(result)
        .coverage(Coverage::Full)
        .id();
    // Also reads it (TRANSFER_SRC usage, so it can be read back).
    graph
        .transfer_pass("copy", PassClass::Transfer, ())
        .transfer_src(result)
        .transfer_dst(copy)
        .coverage(Coverage::Full);
    let plan = Arc::new(graph.compile(g.profile()).unwrap().plan);
    assert!(
        matches!(
            plan.steps.first(),
            Some(tilegraph_graph::Step::Transfer { .. })
        ),
        "the plan has no barrier before the first write:\n{plan}"
    );
    let mut exec = Executor::new(&g).unwrap();
    for frame in 0..4u32 {
        exec.execute(&g, &plan, &Externals::new(), &mut |id, pc| {
            let (src, dst) = (pc.buffer(result)?, pc.buffer(copy)?);
            // SAFETY: recording command buffer, live buffers of the plan.
            unsafe {
                if id == fill {
                    let value = 0x0101_0101 * frame;
                    pc.ctx
                        .device
                        .cmd_fill_buffer(pc.cb, src.raw, 0, vk::WHOLE_SIZE, value);
                } else {
                    let region = vk::BufferCopy::default().size(1024);
                    pc.ctx
                        .device
                        .cmd_copy_buffer(pc.cb, src.raw, dst.raw, &[region]);
                }
            }
            Ok(())
        })
        .unwrap();
    }
    exec.finish(&g).unwrap();
    let buffer = exec
        .resources()
        .and_then(|r| r.buffer(result.into()))
        .unwrap();
    let bytes = tilegraph_vk::readback::read_buffer(&g, buffer).unwrap();
    assert!(
        bytes[..1024].iter().all(|&b| b == 3),
        "the last frame's fill"
    );
    exec.destroy(&g);
}

/// The caller's image must be what the plan declared: a different format (or a smaller image)
/// is a typed error before any framebuffer is made from it.
#[test]
fn an_external_image_unlike_its_declaration_is_a_typed_error() {
    use tilegraph_graph::{
        ClearColor, Extent2d, Format, GraphBuilder, ImageDesc, Import, PassClass,
    };
    let g = gpu(Some("lavapipe")).unwrap();
    let (image, handle) = target(&g, W, H).unwrap();
    let mut graph: GraphBuilder<()> = GraphBuilder::new();
    // The test target is RGBA8 UNORM; declared as BGRA8 sRGB here.
    let out = graph.import_image(
        "target",
        ImageDesc::new(Extent2d::new(W, H), Format::B8G8R8A8_SRGB),
        Import::SWAPCHAIN,
    );
    graph.export(out);
    graph
        .raster_pass("clear", PassClass::Opaque, ())
        .color_clear(out, ClearColor::BLACK);
    let plan = Arc::new(graph.compile(g.profile()).unwrap().plan);
    let mut exec = Executor::new(&g).unwrap();
    let err = exec
        .execute(&g, &plan, &externals(out, &handle), &mut |_, _| Ok(()))
        .expect_err("a format mismatch");
    assert!(err.to_string().contains("target"), "{err}");
    assert!(err.to_string().contains("B8G8R8A8_SRGB"), "{err}");
    exec.destroy(&g);
    destroy_target(&g, image, handle);
}

/// After the caller destroys and recreates its images (a new swapchain), the executor forgets
/// the framebuffers made with the old views and builds new ones on the next frame.
#[test]
fn framebuffers_of_external_views_are_forgotten_on_request() {
    let g = gpu(Some("lavapipe")).unwrap();
    let kit = Kit::new(&g).unwrap();
    let frame = classic_mobile_frame(&kit, W, H);
    let target_id = frame.target;
    let mut compiled = frame.graph.compile(g.profile()).unwrap();
    let plan = Arc::new(compiled.plan.clone());
    let mut exec = Executor::new(&g).unwrap();
    let mut run_frame = |exec: &mut Executor, handle: &tilegraph_vk::executor::ImageHandle| {
        execute(
            exec,
            &g,
            &plan,
            &externals(target_id, handle),
            &mut compiled,
        );
    };
    let (image, handle) = target(&g, W, H).unwrap();
    run_frame(&mut exec, &handle);
    let cached = exec.framebuffer_count();
    assert!(cached > 0);
    exec.forget_external_views(&g).unwrap();
    assert!(
        exec.framebuffer_count() < cached,
        "the target's framebuffer is gone"
    );
    destroy_target(&g, image, handle);
    let (image, handle) = target(&g, W, H).unwrap();
    run_frame(&mut exec, &handle);
    assert_eq!(exec.framebuffer_count(), cached);
    exec.finish(&g).unwrap();
    exec.destroy(&g);
    kit.borrow_mut().destroy(&g);
    destroy_target(&g, image, handle);
}

/// Every barrier, timestamp and subpass dependency the executor records is a synchronization2
/// structure: on a context created without the feature it refuses to start (typed error).
#[test]
fn the_executor_needs_synchronization2() {
    let mut options = tilegraph_e2e::options(Some("lavapipe"), Default::default());
    options.features = tilegraph_vk::FeatureRequest::default();
    let g = tilegraph_e2e::Gpu::new(tilegraph_e2e::context(options).unwrap());
    assert!(!g.has_feature(tilegraph_vk::Feature::Synchronization2));
    let err = Executor::new(&g)
        .err()
        .expect("no executor without synchronization2");
    assert!(err.to_string().contains("Synchronization2"), "{err}");
}

/// An image the device cannot create (here storage on an sRGB format) is a typed error naming
/// it before anything is created: creating it anyway would be invalid usage.
#[test]
fn an_image_the_device_cannot_create_is_a_typed_error() {
    use tilegraph_graph::{Coverage, Extent2d, Format, GraphBuilder, ImageDesc, PassClass};
    let g = gpu(Some("lavapipe")).unwrap();
    let mut graph: GraphBuilder<()> = GraphBuilder::new();
    let lut = graph.create_image(
        "lut",
        ImageDesc::new(Extent2d::new(16, 16), Format::R8G8B8A8_SRGB),
    );
    graph.export(lut);
    graph
        .compute_pass("bake", PassClass::Compute, ())
        .storage_write(lut)
        .coverage(Coverage::Full);
    let plan = Arc::new(graph.compile(g.profile()).unwrap().plan);
    let mut exec = Executor::new(&g).unwrap();

    // A plan that works, then the one that cannot be built, then the working one again: the
    // failed rebuild must not leave the executor without resources for it.
    let mut ok_graph: GraphBuilder<()> = GraphBuilder::new();
    let buffer = ok_graph.create_buffer("counts", 256);
    ok_graph.export(buffer);
    ok_graph
        .compute_pass("count", PassClass::Compute, ())
        .storage_write(buffer)
        .coverage(Coverage::Full);
    let ok_plan = Arc::new(ok_graph.compile(g.profile()).unwrap().plan);
    let run =
        |exec: &mut Executor, plan| exec.execute(&g, plan, &Externals::new(), &mut |_, _| Ok(()));
    run(&mut exec, &ok_plan).unwrap();
    let err = run(&mut exec, &plan).expect_err("no sRGB storage images");
    assert!(err.to_string().contains("\"lut\""), "{err}");
    let again = run(&mut exec, &ok_plan);
    assert!(
        again.is_ok(),
        "the working plan after a failed one: {again:?}"
    );
    exec.finish(&g).unwrap();
    exec.destroy(&g);
}

/// A depth-stencil image that a shader samples gets a depth-only view for it (a sampled view
/// must show one aspect); attachments keep the view with both.
#[test]
fn a_sampled_depth_stencil_image_has_a_depth_only_view() {
    use tilegraph_graph::{
        ClearDepthStencil, Coverage, Extent2d, Format, GraphBuilder, ImageDesc, PassClass,
    };
    let g = gpu(Some("lavapipe")).unwrap();
    let mut graph: GraphBuilder<()> = GraphBuilder::new();
    let depth = graph.create_image(
        "depth",
        ImageDesc::new(Extent2d::new(W, H), Format::D24_UNORM_S8_UINT),
    );
    let ao = graph.create_buffer("ao", 1024);
    graph.export(ao);
    graph
        .raster_pass("prepass", PassClass::DepthPrepass, ())
        .depth_stencil_clear(depth, ClearDepthStencil::REVERSE_Z);
    graph
        .compute_pass("ao", PassClass::Compute, ())
        .sampled(depth)
        .storage_write(ao)
        .coverage(Coverage::Full);
    let plan = Arc::new(graph.compile(g.profile()).unwrap().plan);
    let mut exec = Executor::new(&g).unwrap();
    exec.execute(&g, &plan, &Externals::new(), &mut |_, _| Ok(()))
        .unwrap();
    exec.finish(&g).unwrap();
    let h = exec
        .resources()
        .and_then(|r| r.image(depth.into()))
        .unwrap()
        .clone();
    assert_ne!(h.full_view, h.view);
    assert_eq!(
        h.aspect,
        vk::ImageAspectFlags::DEPTH | vk::ImageAspectFlags::STENCIL
    );
    exec.destroy(&g);
}

/// The executor rebuilds its render passes when the plan changes, and a driver may give a new,
/// incompatible render pass the handle value of one it destroyed: a pipeline cache keyed on the
/// handle would hand out a pipeline made for another render pass. Two plans in turn on one
/// executor and one pipeline cache (keyed on serials): every frame valid under validation, and
/// every rebuild's render passes carry serials never seen before, above the executor's floor.
#[test]
fn render_passes_rebuilt_for_another_plan_get_new_serials() {
    let g = gpu(Some("lavapipe")).unwrap();
    let kit = Kit::new(&g).unwrap();
    let (image, handle) = target(&g, W, H).unwrap();
    let mut exec = Executor::new(&g).unwrap();
    let mut seen: Vec<(u64, vk::RenderPass)> = Vec::new();
    for i in 0..4 {
        let frame = if i % 2 == 0 {
            classic_mobile_frame(&kit, W, H)
        } else {
            visbuf_frame(&kit, W, H)
        };
        let target_id = frame.target;
        let mut compiled = frame.graph.compile(g.profile()).unwrap();
        let plan = Arc::new(compiled.plan.clone());
        let mut used = Vec::new();
        let stats = exec
            .execute(&g, &plan, &externals(target_id, &handle), &mut |id, pc| {
                if let Some(rp) = pc.render_pass {
                    used.push((rp.serial, rp.handle));
                }
                match compiled.payload_mut(id) {
                    Some(p) => p(pc),
                    None => Ok(()),
                }
            })
            .unwrap();
        assert!(stats.rebuilt, "frame {i}: another plan");
        assert!(!used.is_empty());
        for &(serial, _) in &used {
            assert!(serial >= exec.render_pass_serial_floor(), "frame {i}");
            assert!(
                seen.iter().all(|&(s, _)| s != serial),
                "frame {i}: serial {serial} seen before"
            );
        }
        let reused = used
            .iter()
            .filter(|(_, h)| seen.iter().any(|(_, old)| old == h))
            .count();
        println!(
            "frame {i}: {reused} of {} render pass uses got a reused handle",
            used.len()
        );
        seen.extend(used);
    }
    exec.finish(&g).unwrap();
    exec.destroy(&g);
    kit.borrow_mut().destroy(&g);
    destroy_target(&g, image, handle);
}

/// A render pass that loads an attachment another step wrote and only reads it still writes it
/// with its store op where that is DONT_CARE or STORE: write after write, so the barrier before
/// the render pass names the store's write in its destination access, not only the load and
/// the input-attachment read (the property tests' access-mask model asks for it; the layers
/// accept either here, because the layout transition in that barrier makes the write
/// available). With STORE_OP_NONE the render pass writes nothing, and the barrier names no
/// write. Run with synchronization validation on two profiles.
#[test]
fn a_loaded_attachment_the_render_pass_only_reads_is_synchronized_with_its_store() {
    use tilegraph_e2e::frames::target_import;
    use tilegraph_graph::{
        ClearColor, Coverage, Extent2d, Format, GraphBuilder, ImageDesc, PassClass, StoreOp,
    };
    // powervr-b, without store_op_none, keeps nothing of `x` (DONT_CARE) unless it is exported
    // (STORE); lavapipe keeps it with NONE, exported or not.
    for (profile, export, store) in [
        ("powervr-b", false, StoreOp::DontCare),
        ("powervr-b", true, StoreOp::Store),
        ("lavapipe", false, StoreOp::None),
    ] {
        let g = gpu(Some(profile)).unwrap();
        let (image, handle) = target(&g, W, H).unwrap();
        let mut graph: GraphBuilder<()> = GraphBuilder::new();
        let desc = ImageDesc::new(Extent2d::new(W, H), Format::R8G8B8A8_UNORM);
        let out = graph.import_image("target", desc, target_import());
        graph.export(out);
        let x = graph.create_image("x", desc);
        if export {
            graph.export(x);
        }
        let fill = graph
            .transfer_pass("fill", PassClass::Transfer, ())
            .transfer_dst(x)
            .coverage(Coverage::Full)
            .id();
        graph
            .raster_pass("read", PassClass::Post, ())
            .input(x)
            .color_clear(out, ClearColor::BLACK);
        let plan = Arc::new(graph.compile(g.profile()).unwrap().plan);
        let before_render_pass = plan.steps.iter().find_map(|s| match s {
            tilegraph_graph::Step::Barriers(b) => b.images.iter().find(|i| {
                i.resource == x.into() && i.new_layout == tilegraph_graph::Layout::ShaderReadOnly
            }),
            _ => None,
        });
        let stored = plan
            .render_passes()
            .flat_map(|(_, rp)| &rp.attachments)
            .find(|a| a.resource == x.into())
            .map(|a| a.store_op);
        assert_eq!(stored, Some(store), "{profile}\n{plan}");
        assert_eq!(
            before_render_pass.map(|b| b
                .dst_access
                .contains(tilegraph_graph::AccessFlags::COLOR_ATTACHMENT_WRITE)),
            Some(store != StoreOp::None),
            "{profile}: the barrier before the render pass and the store disagree\n{plan}"
        );
        let mut exec = Executor::new(&g).unwrap();
        exec.execute(&g, &plan, &externals(out, &handle), &mut |id, pc| {
            if id == fill {
                let range = vk::ImageSubresourceRange::default()
                    .aspect_mask(vk::ImageAspectFlags::COLOR)
                    .level_count(1)
                    .layer_count(1);
                let color = vk::ClearColorValue {
                    float32: [1.0, 0.0, 0.0, 1.0],
                };
                // SAFETY: recording command buffer; `x` is in TRANSFER_DST_OPTIMAL for this pass.
                unsafe {
                    pc.ctx.device.cmd_clear_color_image(
                        pc.cb,
                        pc.image(x)?.raw,
                        vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                        &color,
                        &[range],
                    );
                }
            }
            Ok(())
        })
        .unwrap();
        exec.finish(&g).unwrap();
        exec.destroy(&g);
        destroy_target(&g, image, handle);
        // Dropping `g` fails the test on any validation message.
    }
}
