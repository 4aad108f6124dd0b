//! Async compute: a frame whose depth pyramid is built on a second queue while the shadow map
//! is drawn on the first, compiled with async compute off, on with exclusive sharing and on
//! with concurrent sharing.

mod common;

use common::*;
use tilegraph_graph::*;
use tilegraph_profile::{Profile, QueueSharing};

struct AsyncFrame {
    graph: GraphBuilder<&'static str>,
    depth: ImageId,
    pyramid: ImageId,
}

/// Depth pre-pass; the HiZ build (async-capable) samples its depth into a pyramid; the shadow
/// map, which needs neither; culling reads the pyramid into a draw list; the colour pass draws
/// the list with the shadow map over the pre-pass's depth into the swapchain image.
fn async_frame() -> AsyncFrame {
    frame_of(true)
}

/// [`async_frame`], with the shadow map, or without it and with the culling async-capable too.
fn frame_of(shadow_map: bool) -> AsyncFrame {
    let mut g = GraphBuilder::new();
    let depth = g.create_image("depth", ImageDesc::new(EXTENT, Format::D32_SFLOAT));
    let pyramid = g.create_image(
        "hiz",
        ImageDesc::new(Extent2d::new(1024, 512), Format::R32_SFLOAT).with_mip_levels(11),
    );
    let shadow = g.create_image(
        "shadow_map",
        ImageDesc::new(Extent2d::new(2048, 2048), Format::D32_SFLOAT),
    );
    let draws = g.create_buffer("draw_list", 1 << 20);
    let swapchain = g.import_image(
        "swapchain",
        ImageDesc::new(EXTENT, Format::B8G8R8A8_SRGB),
        Import::SWAPCHAIN,
    );
    g.export(swapchain);
    g.raster_pass("depth_prepass", PassClass::DepthPrepass, "depth_prepass")
        .depth_stencil_clear(depth, ClearDepthStencil::REVERSE_Z);
    g.compute_pass("hiz_build", PassClass::Compute, "hiz_build")
        .sampled(depth)
        .storage_write(pyramid)
        .async_compute();
    if shadow_map {
        g.raster_pass("shadow", PassClass::DepthPrepass, "shadow")
            .depth_stencil_clear(shadow, ClearDepthStencil::REVERSE_Z);
    }
    let mut cull = g.compute_pass("cull", PassClass::Compute, "cull");
    cull.sampled(pyramid).storage_write(draws);
    if !shadow_map {
        cull.async_compute();
    }
    let mut opaque = g.raster_pass("opaque", PassClass::Opaque, "opaque");
    opaque.indirect(draws);
    if shadow_map {
        opaque.sampled(shadow);
    }
    opaque
        .depth_stencil_read_only(depth)
        .color(swapchain)
        .coverage(Coverage::Full);
    AsyncFrame {
        graph: g,
        depth,
        pyramid,
    }
}

fn with_async(sharing: QueueSharing) -> Profile {
    let mut p = profile("desktop-nvidia");
    p.queues.async_compute = true;
    p.queues.sharing = sharing;
    p
}

fn submission_of(plan: &Plan, pass: &str) -> usize {
    let step = plan.pass_by_name(pass).unwrap().step.index();
    plan.submissions
        .iter()
        .position(|s| s.steps().contains(&step))
        .unwrap()
}

#[test]
fn with_async_compute_off_everything_is_one_graphics_submission() {
    let mut off = profile("desktop-nvidia");
    off.queues.async_compute = false;
    let plan = async_frame().graph.compile(&off).unwrap().plan;
    assert_eq!(plan.submissions.len(), 1);
    assert_eq!(plan.submissions[0].steps(), 0..plan.steps.len());
    assert!(plan.submissions[0].waits.is_empty());
    assert!(plan.passes.iter().all(|p| p.queue == Queue::Graphics));
    assert!(plan.pass_by_name("hiz_build").unwrap().async_capable);
    let queue = plan
        .explain()
        .into_iter()
        .find(|r| r.topic == Topic::Queue)
        .unwrap();
    assert_eq!(
        (queue.subject.as_str(), queue.decision.as_str()),
        ("hiz_build", "graphics")
    );
    assert!(queue.why.contains("off"), "{}", queue.why);
}

#[test]
fn the_pyramid_is_built_on_the_compute_queue_beside_the_shadow_map() {
    let frame = async_frame();
    let plan = frame
        .graph
        .compile(&with_async(QueueSharing::Exclusive))
        .unwrap()
        .plan;
    let hiz = plan.pass_by_name("hiz_build").unwrap();
    assert_eq!(hiz.queue, Queue::AsyncCompute, "{plan}");
    for p in plan.passes.iter().filter(|p| p.name != "hiz_build") {
        assert_eq!(p.queue, Queue::Graphics, "{}", p.name);
    }
    let (prepass, build, shadow, cull) = (
        submission_of(&plan, "depth_prepass"),
        submission_of(&plan, "hiz_build"),
        submission_of(&plan, "shadow"),
        submission_of(&plan, "cull"),
    );
    let subs = &plan.submissions;
    // The build waits for the depth (and takes it over from the graphics family).
    let waits_on = |k: usize, on: usize| subs[k].waits.iter().any(|w| w.submission.index() == on);
    assert!(waits_on(build, prepass), "{plan}");
    assert!(subs[build].waits.iter().flat_map(|w| &w.reasons).any(|r| {
        *r == WaitReason::Resource {
            resource: frame.depth.0,
            hazard: Hazard::LayoutTransition,
            transfer: true,
        }
    }));
    // The shadow map does not wait for it: that is the overlap.
    assert!(
        subs[shadow]
            .waits
            .iter()
            .all(|w| subs[w.submission.index()].queue == Queue::Graphics),
        "{plan}"
    );
    // Culling reads the pyramid after the build, taking it back.
    assert!(waits_on(cull, build), "{plan}");
    let released = |k: usize, r: ResourceId| {
        subs[k]
            .releases
            .images
            .iter()
            .any(|b| b.resource == r && b.queue_transfer.is_some())
    };
    assert!(released(prepass, frame.depth.0), "{plan}");
    assert!(released(build, frame.pyramid.0), "{plan}");
    // Frame start and join.
    assert_eq!(subs[0].queue, Queue::Graphics);
    assert_eq!(subs[0].steps(), 0..0);
    assert!(subs[build].waits.iter().any(|w| w.submission.0 == 0));
    assert_eq!(subs.last().unwrap().queue, Queue::Graphics);
    // The async queue's resources have memory of their own.
    assert!(plan.resources[frame.pyramid.0.index()].async_queue);
    assert!(matches!(
        plan.resources[frame.pyramid.0.index()]
            .alias_lifetime()
            .memory,
        MemoryNeed::Dedicated(_)
    ));
    // `tilegraph graph` explains the assignment and every wait.
    let reasons = plan.explain();
    assert!(reasons.iter().any(|r| r.topic == Topic::Queue
        && r.subject == "hiz_build"
        && r.decision == "async-compute"));
    let waits = reasons.iter().filter(|r| r.topic == Topic::Wait).count();
    let listed: usize = subs
        .iter()
        .flat_map(|s| &s.waits)
        .map(|w| w.reasons.len())
        .sum();
    assert_eq!(waits, listed);
    assert!(reasons
        .iter()
        .any(|r| r.topic == Topic::Wait && r.why.contains("hiz") && r.why.contains("family")));
    insta::assert_snapshot!("async_frame_desktop_nvidia_exclusive", plan.to_string());
}

#[test]
fn concurrent_sharing_transfers_nothing() {
    let plan = async_frame()
        .graph
        .compile(&with_async(QueueSharing::Concurrent))
        .unwrap()
        .plan;
    assert!(plan.submissions.len() > 2, "{plan}");
    assert!(plan.submissions.iter().all(|s| s.releases.is_empty()));
    for step in &plan.steps {
        if let Step::Barriers(b) = step {
            assert!(b.images.iter().all(|x| x.queue_transfer.is_none()));
            assert!(b.buffers.iter().all(|x| x.queue_transfer.is_none()));
        }
    }
    let reasons = plan
        .submissions
        .iter()
        .flat_map(|s| &s.waits)
        .flat_map(|w| &w.reasons);
    assert!(reasons
        .clone()
        .all(|r| !matches!(r, WaitReason::Resource { transfer: true, .. })));
    assert!(reasons.clone().any(|r| *r == WaitReason::FrameStart));
}

#[test]
fn re_placing_memory_keeps_the_submissions() {
    let mut plan = async_frame()
        .graph
        .compile(&with_async(QueueSharing::Exclusive))
        .unwrap()
        .plan;
    let before = plan.submissions.clone();
    let requirements = plan.estimated_requirements();
    plan.reassign_aliases(&requirements).unwrap();
    assert_eq!(plan.submissions, before);
}

/// Without the shadow map nothing raster runs beside the build (the colour pass waits on the
/// culling that waits on it, the pre-pass comes before): it stays on the graphics queue, and the
/// frame is one submission, async compute on or not.
#[test]
fn a_pass_no_raster_work_runs_beside_stays_on_the_graphics_queue() {
    let plan = frame_of(false)
        .graph
        .compile(&with_async(QueueSharing::Concurrent))
        .unwrap()
        .plan;
    assert!(
        plan.passes.iter().all(|p| p.queue == Queue::Graphics),
        "{plan}"
    );
    assert_eq!(plan.submissions.len(), 1, "{plan}");
    let why = plan
        .explain()
        .into_iter()
        .find(|r| r.topic == Topic::Queue && r.subject == "cull")
        .map(|r| r.why)
        .unwrap_or_default();
    assert!(why.contains("every raster pass"), "{why}");
}
