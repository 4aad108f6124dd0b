//! Faults injected where a frame can fail (lavapipe, validation on): its start, its
//! submission, the wait for a frame slot's fence, a pipeline's creation, a memory allocation
//! (`Context::inject_fault_at`). The frame that meets the fault returns a typed error naming the
//! call, nothing of it runs, and the renderer carries on: every later frame renders, and the last
//! frame's image equals a run without the fault, bit for bit — through two-phase culling, whose
//! visibility and pyramid outlive frames.

use tilegraph_e2e::gpu_with;
use tilegraph_passes::cull::Culling;
use tilegraph_passes::{RenderError, RenderOptions, SceneRenderer, Technique};
use tilegraph_scene::Scene;
use tilegraph_vk::ash::vk;
use tilegraph_vk::readback::RgbaImage;
use tilegraph_vk::{FaultSite, VkError};

const FRAMES: usize = 6;

/// `FRAMES` frames of the city's path (every 7th camera) with `technique` and two-phase
/// culling; with `fault`, injected before frame `at`. Each frame's outcome (the error's text),
/// and the last image.
fn run(
    scene: &Scene,
    technique: Technique,
    fault: Option<(usize, FaultSite, vk::Result)>,
) -> (Vec<Option<String>>, RgbaImage) {
    let options = RenderOptions {
        technique,
        culling: Culling::HizTwoPhase,
        width: 160,
        height: 90,
        ..Default::default()
    };
    let g = gpu_with(Some("lavapipe"), options.device_features()).unwrap();
    let mut r = SceneRenderer::new(&g, scene, options).unwrap();
    let mut outcomes = Vec::new();
    for i in 0..FRAMES {
        if let Some((at, site, result)) = fault {
            if at == i {
                g.inject_fault_at(site, result);
            }
        }
        let cam = scene.camera_path().camera(i * 7).unwrap();
        outcomes.push(r.render(&g, scene, &cam).err().map(|e| {
            // A failure is a typed Vulkan error naming the call, out of memory here.
            assert!(
                matches!(&e, RenderError::Vk(v) if v.is_out_of_memory()),
                "frame {i}: {e:?}"
            );
            e.to_string()
        }));
    }
    let image = r.read_image(&g).unwrap();
    r.destroy(&g);
    (outcomes, image)
}

#[test]
fn a_frame_that_meets_a_fault_fails_alone_and_the_next_frames_render_as_without_it() {
    let scene = tilegraph_scene::load("city:400").unwrap();
    let oom = vk::Result::ERROR_OUT_OF_DEVICE_MEMORY;
    for technique in [Technique::Prepass, Technique::Visbuf] {
        let (clean, reference) = run(&scene, technique, None);
        assert!(clean.iter().all(Option::is_none), "{clean:?}");
        // Where each site is reached: pipelines and graph resources are made by the first
        // frame; fences are waited for once both slots have a frame in flight.
        for (at, site, call) in [
            (2, FaultSite::FrameStart, "recording the frame"),
            (3, FaultSite::Submit, "vkQueueSubmit"),
            (3, FaultSite::FenceWait, "vkWaitForFences"),
            (0, FaultSite::PipelineCreation, "vkCreateGraphicsPipelines"),
            (0, FaultSite::Allocation, "vkAllocateMemory"),
        ] {
            let (outcomes, image) = run(&scene, technique, Some((at, site, oom)));
            for (i, o) in outcomes.iter().enumerate() {
                match o {
                    Some(e) => {
                        assert_eq!(i, at, "{technique:?} {site:?}: frame {i} failed: {e}");
                        assert!(e.contains(call), "{technique:?} {site:?}: {e}");
                    }
                    None => assert_ne!(i, at, "{technique:?} {site:?}: the fault was not met"),
                }
            }
            let differing = image
                .pixels
                .chunks_exact(4)
                .zip(reference.pixels.chunks_exact(4))
                .filter(|(a, b)| a != b)
                .count();
            assert_eq!(
                differing, 0,
                "{technique:?} {site:?}: the last frame differs from a run without the fault"
            );
        }
    }
    // The error type says what the engine should do.
    let lost = VkError::call("vkQueueSubmit", vk::Result::ERROR_DEVICE_LOST);
    assert!(!lost.is_out_of_memory());
}
