//! The ideal frame: the oracle's visible set drawn with no culling work, every technique's
//! ceiling.

use tilegraph_scene::Scene;
use tilegraph_vk::queries::{GpuTiming, FRAME_TIMING};
use tilegraph_vk::Context;

use super::compared_instances;
use super::world::{Timing, World};
use crate::cull::Culling;
use crate::options::{RenderError, RenderOptions};
use crate::renderer::SceneRenderer;

/// What the oracle saw in one frame.
#[derive(Debug)]
pub(super) struct FrameVisible {
    /// The compared instances owning a pixel.
    pub instances: Vec<u32>,
    /// For a cluster technique, their clusters owning a pixel (sorted
    /// [`crate::draws::cluster_key`]s).
    pub clusters: Option<Vec<u64>>,
}

/// The ideal frame's median GPU milliseconds: `options` without culling, on a copy of `scene`
/// in which each frame hides every compared instance the oracle did not see (blended and hidden
/// instances as they are) and, where the oracle saw clusters, draws only those of the others,
/// timed whole, frames back to back after one untimed pass along the path (and the warm-up).
/// Only its time is read: with the visibility buffer its cluster runs are CPU draws, whose ids
/// count from each mesh's first triangle rather than the run's (the resolve shades other
/// triangles of the same instances: the same work, not the same image).
pub(super) fn ideal_frame(
    ctx: &Context,
    scene: &Scene,
    options: RenderOptions,
    timing: &Timing<'_>,
    visible: &[FrameVisible],
) -> Result<Option<f64>, RenderError> {
    let mut scene = scene.clone();
    let compared = compared_instances(&scene);
    let original: Vec<_> = scene.instances().iter().map(|i| i.flags).collect();
    let mut renderer = SceneRenderer::new(
        ctx,
        &scene,
        // At full detail: levels of detail are chosen by GPU culling, which this frame has
        // none of (a technique with them can beat its ceiling).
        RenderOptions {
            culling: Culling::None,
            gpu_timing: GpuTiming::Frame,
            lod_error_px: 0.0,
            ..options
        },
    )?;
    let mut shown = vec![true; compared.len()];
    let mut run = |renderer: &mut SceneRenderer, scene: &mut Scene| {
        let mut want = vec![false; compared.len()];
        for (index, seen) in visible.iter().enumerate() {
            let Some(frame) = timing.path.frame(index, timing.aspect) else {
                break;
            };
            want.iter_mut().for_each(|w| *w = false);
            for &i in &seen.instances {
                if let Some(w) = want.get_mut(i as usize) {
                    *w = true;
                }
            }
            for i in 0..compared.len() {
                if !compared[i] || want[i] == shown[i] {
                    continue;
                }
                let Some(h) = scene.instance_handle(tilegraph_scene::InstanceId(i as u32)) else {
                    continue;
                };
                let bits = original[i].bits()
                    | if want[i] {
                        0
                    } else {
                        tilegraph_scene::InstanceFlags::HIDDEN.bits()
                    };
                let flags = tilegraph_scene::InstanceFlags::from_bits(bits)
                    .unwrap_or(tilegraph_scene::InstanceFlags::HIDDEN);
                scene.set_flags(h, flags)?;
                shown[i] = want[i];
            }
            renderer.keep_only_clusters(seen.clusters.as_deref());
            renderer.render_frame(ctx, scene, &frame)?;
        }
        renderer.finish(ctx)
    };
    let mut still = World::Still(&scene);
    let warmed = timing.warm_up(ctx, &mut still, &mut renderer);
    let result = warmed
        .and_then(|()| run(&mut renderer, &mut scene))
        .and_then(|()| {
            renderer.clear_timings();
            run(&mut renderer, &mut scene)
        })
        .map(|()| {
            renderer
                .medians()
                .into_iter()
                .find(|m| m.name == FRAME_TIMING)
                .map(|m| m.median_gpu_ms)
        });
    renderer.destroy(ctx);
    result
}
