//! What a renderer creates on the GPU before its first frame: the scene uploaded, the
//! pipelines' layouts, and the states of its techniques.

use tilegraph_scene::{DepthConvention, Scene};
use tilegraph_vk::{Context, VkError};

use crate::cull::{CullState, Culling, Occluder};
use crate::frame::SceneResources;
use crate::gpu_scene::{Capacity, GpuScene};
use crate::hiz::{HizState, ReprojectState};
use crate::occlusion::{OqState, RasterOcclusion};
use crate::options::{RenderError, RenderOptions};
use crate::pipelines::Pipelines;
use crate::setup::Technique;
use crate::shadow::ShadowState;
use crate::visbuf::classify::ClassifyState;
use crate::visbuf::ResolveSets;
use tilegraph_cull::shadow::CasterCulling;

/// The GPU side of a renderer: the scene uploaded with room for `capacity`, the pipelines'
/// layouts, and per view (`views`, the main view first) the states of its techniques.
/// Whatever was created is destroyed again when a later step fails.
pub(super) fn create_resources(
    ctx: &Context,
    scene: &Scene,
    views: &[&RenderOptions],
    frames_in_flight: usize,
    capacity: Capacity,
) -> Result<SceneResources, RenderError> {
    let Some(main) = views.first() else {
        return Err(RenderError::Vk(VkError::Invalid {
            what: "scene renderer".into(),
            reason: "no view".into(),
        }));
    };
    let mut textures = ctx.profile().textures;
    if let Some(b) = main.texture_binding {
        textures.binding = b;
    }
    let atlases: Vec<_> = views
        .iter()
        .map(|o| o.shadows.atlas(ctx.profile()))
        .collect();
    let capacity = capacity.with_views(views.len());
    let gpu = GpuScene::new(ctx, scene, frames_in_flight, capacity, textures, &atlases)?;
    let pipelines = match Pipelines::new(
        ctx,
        gpu.set_layout,
        (main.count_fragments, main.probe),
        (gpu.textures.binding, gpu.textures.slot_count()),
    ) {
        Ok(p) => p,
        Err(e) => {
            gpu.destroy(ctx);
            return Err(e.into());
        }
    };
    let mut res = SceneResources::new(gpu, pipelines);
    for (view, options) in views.iter().enumerate() {
        res.enter_view(view);
        if let Err(e) = add_states(ctx, scene, options, frames_in_flight, capacity, &mut res) {
            res.destroy(ctx);
            return Err(e.into());
        }
    }
    res.enter_view(0);
    Ok(res)
}

/// The states of `options`' techniques.
fn add_states(
    ctx: &Context,
    scene: &Scene,
    options: &RenderOptions,
    frames_in_flight: usize,
    capacity: Capacity,
    res: &mut SceneResources,
) -> Result<(), VkError> {
    let culling = options.culling;
    let instances = capacity.instances;
    let set_layout = res.scene.set_layout;

    if culling.uses_pyramid() {
        let depth = scene
            .camera_path()
            .camera(0)
            .map_or(DepthConvention::Reverse, |c| {
                c.projection.depth_convention()
            });
        let size = (options.width, options.height);
        // Reprojection moves last frame's full-resolution depth: the pyramid's level 0.
        let base_level = if culling == Culling::Reproject {
            0
        } else {
            options.hiz_base_level
        };
        let hiz = HizState::new(
            ctx,
            size,
            options.hiz_mode,
            depth,
            options.depth_format,
            base_level,
            frames_in_flight,
        )?;
        if culling == Culling::Reproject {
            match ReprojectState::new(ctx, &hiz, frames_in_flight) {
                Ok(r) => {
                    res.states.insert(r);
                }
                Err(e) => {
                    res.states.insert(hiz);
                    return Err(e);
                }
            }
        }
        res.states.insert(hiz);
    }
    if culling.uses_gpu_lists() {
        let hiz = res.states.get::<HizState>();
        // Reprojection's culling reads the reprojected pyramid (with the same level table).
        let occluder = match (hiz, res.states.get::<ReprojectState>()) {
            (Some(h), Some(r)) => Some(Occluder {
                pyramid: r.pyramid.raw,
                levels: h.levels.raw,
            }),
            (h, _) => h.map(Occluder::of),
        };
        let orders: Vec<_> = (0..frames_in_flight.max(1))
            .filter_map(|slot| res.scene.order(slot))
            .collect();
        let mut c = CullState::new(
            ctx,
            culling,
            scene,
            crate::cull::CullInputs {
                scene_set_layout: set_layout,
                orders: &orders,
                occluder,
                bounds: options.cull_bounds,
                cluster_early: options.cluster_early,
                cluster_gap: options.cluster_gap,
                capacity,
                triangle_culling: options.triangle_culling,
                lod: crate::cull::LodSettings {
                    error_px: options.lod_error_px,
                    hysteresis: options.lod_hysteresis,
                },
            },
        )?;
        if c.clusters.as_ref().is_some_and(|s| s.triangles.is_some()) {
            res.scene
                .reserve_index_tail(crate::cull::triangles::tail_indices(scene));
        }
        c.set_recheck_interval(options.occlusion_recheck);
        let draw_ids = c.draw_ids.raw;
        let runs = c.clusters.as_ref().map(|s| s.run_triangles.raw);
        res.states.insert(c);
        res.scene.add_culled_sets(ctx, draw_ids, runs)?;
        if culling == Culling::RasterOcclusion {
            let visibility = res.states.get::<CullState>().map(|c| &c.visibility);
            if let Some(visibility) = visibility {
                let scale = options.raster_occlusion_scale;
                let raster = RasterOcclusion::new(
                    ctx,
                    set_layout,
                    visibility,
                    instances,
                    scale,
                    frames_in_flight,
                )?;
                res.states.insert(raster);
            }
        }
    }
    if culling.uses_queries() {
        let conditional = culling.conditional();
        let mut oq = OqState::new(
            ctx,
            scene,
            options.oq_group,
            conditional,
            set_layout,
            frames_in_flight,
        )?;
        oq.set_recheck_interval(options.occlusion_recheck);
        res.states.insert(oq);
    }
    if options.shadows.enabled() {
        let view = res.view();
        let atlas = res
            .scene
            .atlas(view)
            .map(|a| a.desc)
            .ok_or_else(|| VkError::Invalid {
                what: "shadows".into(),
                reason: format!("no shadow atlas for view {view}"),
            })?;
        // `receivers-hiz` reads the camera's pyramid through the GPU culling's sets.
        let cull_sets = match (options.shadows.culling, res.states.get::<CullState>()) {
            (CasterCulling::ReceiversHiz, Some(c)) => Some(c.phase_set_layout()),
            _ => None,
        };
        let shadows = ShadowState::new(ctx, set_layout, cull_sets, atlas, instances)?;
        res.states.insert(shadows);
    }
    if options.technique.screen_space() {
        res.states.insert(ResolveSets::new(ctx, frames_in_flight)?);
    }
    if options.technique == Technique::Visbuf {
        // Also where the resolve is not classified: its set layout is what an engine's
        // resolve layout is made with (`SceneRenderer::resolve_set_layout`); the compute
        // pipeline is made on first use.
        res.states
            .insert(ClassifyState::new(ctx, set_layout, frames_in_flight)?);
    }
    Ok(())
}
