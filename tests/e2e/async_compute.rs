//! Async compute on lavapipe (validation and synchronization validation on): frames whose
//! culling, HiZ build and shadow-caster culling run on the async compute queue draw the images
//! they draw on one queue, with exclusive sharing (ownership transfers) and concurrent sharing:
//! single-phase HiZ, two-phase HiZ with cascaded shadows (the cascades drawn while the async
//! queue builds the pyramid and culls the late phase), and two-phase HiZ with clusters.
//!
//! Lavapipe has one queue family of one queue, so the two-queue plans are submitted to that
//! queue in plan order (`ContextOptions::async_on_one_queue`): every part, its timeline waits
//! and signals and its barriers run and are validated, in an order the waits respect. What
//! lavapipe cannot show: work of the two queues overlapping, and ownership transfers between two
//! families (with one family the release halves are dropped and the acquire halves are plain
//! barriers, as the executor records them on any device whose async queue shares the family).

use tilegraph_e2e::{options, Gpu};
use tilegraph_graph::Queue;
use tilegraph_passes::cull::Culling;
use tilegraph_passes::shadow::ShadowOptions;
use tilegraph_passes::{RenderOptions, SceneRenderer, Technique};
use tilegraph_profile::{QueuePolicy, QueueSharing};
use tilegraph_scene::Scene;
use tilegraph_vk::readback::RgbaImage;
use tilegraph_vk::{Feature, FeatureRequest};

const SIZE: (u32, u32) = (160, 90);
const FRAMES: usize = 5;

/// The scene's first frames under `culling` (with `cascades` shadow cascades) with the given
/// queue policy (`None`: one queue); each frame's image, and whether the plans ran the HiZ
/// build, the culling and the shadow casters' culling on the async queue.
fn frames(
    scene: &Scene,
    (culling, cascades): (Culling, u32),
    queues: Option<QueuePolicy>,
) -> (Vec<RgbaImage>, bool) {
    let features = FeatureRequest::default().require([
        Feature::GeometryShader,
        Feature::DrawIndirectCount,
        Feature::MultiDrawIndirect,
    ]);
    let mut o = options(Some("lavapipe"), features);
    o.queues = queues;
    o.async_on_one_queue = true;
    tilegraph_e2e::init_logging();
    let g = Gpu::new(tilegraph_e2e::context(o).unwrap());
    assert_eq!(
        g.async_queue.is_some(),
        queues.is_some_and(|q| q.async_compute)
    );
    let options = RenderOptions {
        technique: Technique::Prepass,
        culling,
        width: SIZE.0,
        height: SIZE.1,
        shadows: ShadowOptions {
            cascades,
            resolution: 256,
            ..ShadowOptions::default()
        },
        ..Default::default()
    };
    let mut r = SceneRenderer::new(&g, scene, options).unwrap();
    let aspect = SIZE.0 as f32 / SIZE.1 as f32;
    let mut images = Vec::new();
    let mut on_async = true;
    for index in 0..FRAMES.min(scene.camera_path().len()) {
        let frame = scene.camera_path().frame(index, aspect).unwrap();
        let report = r.render_frame(&g, scene, &frame).unwrap();
        // Single-phase: the colour pass waits on the culling, which stays on the graphics
        // queue; the build (for the next frame) runs beside the colour pass. Two-phase with
        // shadows: the culling and the build run beside the cascades.
        let mut async_passes = vec!["hiz-build"];
        if culling != Culling::Hiz {
            async_passes.push("cull-late");
        }
        if cascades > 0 {
            async_passes.push("shadow-cull");
        }
        for name in async_passes {
            let pass = report.plan.pass_by_name(name);
            assert!(pass.is_some(), "{culling:?}: no pass {name}");
            on_async &= pass.is_some_and(|p| p.queue == Queue::AsyncCompute);
        }
        if culling == Culling::Hiz {
            let cull = report.plan.pass_by_name("cull");
            assert!(
                cull.is_some_and(|p| p.queue == Queue::Graphics),
                "{culling:?}"
            );
        }
        on_async &= report.plan.submissions.len() > 2;
        images.push(r.read_image(&g).unwrap());
    }
    r.finish(&g).unwrap();
    r.destroy(&g);
    (images, on_async)
}

#[test]
fn culling_on_the_async_queue_draws_the_same_frames() {
    let mut scene = tilegraph_scene::load("city:300").unwrap();
    let (clusters, _) = tilegraph_scene::clusters::build(&scene).unwrap();
    scene.attach_clusters(clusters).unwrap();
    let cases = [
        (Culling::Hiz, 0),
        (Culling::HizTwoPhase, 3),
        (Culling::HizTwoPhaseClusters, 2),
    ];
    for case in cases {
        let culling = case.0;
        let (one_queue, on_async) = frames(&scene, case, None);
        assert!(
            !on_async,
            "{culling:?}: async compute off, yet the culling is on the async queue"
        );
        for sharing in [QueueSharing::Exclusive, QueueSharing::Concurrent] {
            let policy = QueuePolicy {
                async_compute: true,
                sharing,
            };
            let (two_queues, on_async) = frames(&scene, case, Some(policy));
            // Single-phase with exclusive sharing: the build and the colour pass both read the
            // depth, which belongs to one family at a time, so nothing runs beside the build
            // and it stays on the graphics queue.
            let expected = culling != Culling::Hiz || sharing == QueueSharing::Concurrent;
            assert_eq!(
                on_async, expected,
                "{culling:?} {sharing:?}: the culling's queues"
            );
            for (i, (a, b)) in one_queue.iter().zip(&two_queues).enumerate() {
                assert!(a == b, "{culling:?} {sharing:?}: frame {i} differs");
            }
        }
    }
}
