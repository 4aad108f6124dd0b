//! Measuring a culling technique against the exact oracle, frame by frame.
//!
//! For every frame of a camera path three renderers run on the same device: the **oracle**
//! (visibility buffer of every instance, no culling, ids read back: V = the instances that own at
//! least one pixel), the **reference** (forward, no culling) and the **technique** (forward with
//! the culling under test; D = what its GPU lists drew, or for occlusion queries the mask of
//! query results its CPU draw lists used). Then FN = V \ D (visible but culled:
//! holes, popping), FP = D \ V (hidden but drawn: wasted work), and whether the technique's image
//! equals the reference bit for bit. Blended instances are outside the comparison: no technique
//! culls them on the GPU (they are frustum-culled on the CPU and sorted), and the visibility buffer
//! does not hold them.

use tilegraph_scene::{CameraPath, MotionParams, Scene};
use tilegraph_vk::queries::{GpuTiming, FRAME_TIMING};
use tilegraph_vk::readback::RgbaImage;
use tilegraph_vk::Context;

use crate::cull::Culling;
use crate::knobs::AutoTrial;
use crate::options::{RenderError, RenderOptions};
use crate::renderer::SceneRenderer;
use crate::setup::Technique;
use crate::shadow::{CasterCulling, ShadowOptions};

pub mod casters;
mod clusters;
mod ideal;
mod image;
mod report;
mod stray;
mod world;

use ideal::{ideal_frame, FrameVisible};
use world::{run_trial, Timing, World};

pub use casters::CasterCheck;
pub use clusters::{cluster_check, ClusterCheck};
pub use image::ImageError;
use image::{diff_image, summed};
pub use report::{CullCheck, FrameCheck, PassTime, Totals};

/// A frame the check found wrong (false negatives or an image unlike the reference), for
/// [`CheckExtras::on_failure`].
pub struct FailedFrame<'a> {
    pub check: &'a FrameCheck,
    /// The technique's image and the unculled reference.
    pub technique: &'a RgbaImage,
    pub reference: &'a RgbaImage,
    /// The reference dimmed to grey, pixels that differ in red, and the pixels of visible
    /// instances the technique culled (false negatives) in magenta.
    pub diff: RgbaImage,
}

/// A callback for each failed frame ([`CheckExtras::on_failure`]).
pub type OnFailure<'a> = &'a mut dyn FnMut(&FailedFrame<'_>) -> Result<(), String>;

/// What a check does besides counting.
#[derive(Default)]
pub struct CheckExtras<'a> {
    /// `culling = auto`: the trial to run before the check ([`AutoTrial`]).
    pub auto: Option<AutoTrial>,
    /// Called for every frame with false negatives or an unequal image (`cull-check
    /// --save-frames`); an error stops the check.
    pub on_failure: Option<OnFailure<'a>>,
    /// Called after each checked frame with (frames done, frames in all): a progress bar.
    pub on_frame: Option<&'a mut dyn FnMut(usize, usize)>,
    /// The scene moves along the path ([`Motion`](tilegraph_scene::Motion)): every renderer sees the scene each frame
    /// brings, the oracle included, in the checked and in the timed passes alike.
    pub motion: Option<MotionParams>,
    /// How long to render the path (from its start, again and again) before the timed pass:
    /// a GPU whose clocks dropped during the checked pass's readbacks brings them back to
    /// what the workload holds them at, so settings timed one after the other compare alike.
    /// Zero (the default) times at once.
    pub timing_warmup: std::time::Duration,
}

/// Technique knobs of a check.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CheckOptions {
    pub hiz_mode: tilegraph_cull::NpotMode,
    /// Occlusion queries: instances per query.
    pub oq_group: usize,
    /// Raster occlusion: 1, or 2 / 4 for a conservative low-resolution depth.
    pub raster_occlusion_scale: u32,
}

/// Runs `culling` along `path` (every frame, or the first `max_frames`).
pub fn cull_check(
    ctx: &Context,
    scene: &Scene,
    culling: Culling,
    path: &CameraPath,
    size: (u32, u32),
    max_frames: Option<usize>,
    hiz_mode: tilegraph_cull::NpotMode,
) -> Result<CullCheck, RenderError> {
    let options = CheckOptions {
        hiz_mode,
        oq_group: RenderOptions::default().oq_group,
        raster_occlusion_scale: 1,
    };
    cull_check_with(ctx, scene, culling, path, size, max_frames, &options)
}

/// [`cull_check`] with the technique knobs of [`CheckOptions`].
pub fn cull_check_with(
    ctx: &Context,
    scene: &Scene,
    culling: Culling,
    path: &CameraPath,
    size: (u32, u32),
    max_frames: Option<usize>,
    options: &CheckOptions,
) -> Result<CullCheck, RenderError> {
    let tested = RenderOptions {
        width: size.0,
        height: size.1,
        hiz_mode: options.hiz_mode,
        oq_group: options.oq_group,
        raster_occlusion_scale: options.raster_occlusion_scale,
        culling,
        ..Default::default()
    };
    cull_check_options(ctx, scene, tested, path, max_frames, CheckExtras::default())
}

/// The check of `tested` (any shading, culling and knobs) along `path`: the reference is the
/// same options without culling, the oracle the visibility buffer of everything.
///
/// `auto` (`culling = auto`): the trial ([`AutoTrial`]) runs first, as an engine runs it — a
/// renderer of its own, frames back to back along the path, after the timing warm-up — and the
/// check and the timing pass then run what it kept in a renderer made like any other check's.
/// (Timed between the oracle's and the reference's frames, the candidates measured those
/// frames' effects too: on lavapipe a candidate's trial time differed from its own timed run by
/// up to 20 %.)
pub fn cull_check_options(
    ctx: &Context,
    scene: &Scene,
    tested: RenderOptions,
    path: &CameraPath,
    max_frames: Option<usize>,
    extras: CheckExtras<'_>,
) -> Result<CullCheck, RenderError> {
    let CheckExtras {
        auto,
        mut on_failure,
        mut on_frame,
        motion,
        timing_warmup,
    } = extras;
    let mut world = World::new(scene, path, motion);
    let scene = world.scene();
    let size = (tested.width, tested.height);
    // The oracle and the reference draw every mesh at full detail: levels of detail are
    // measured as image error against them.
    let oracle = SceneRenderer::new(
        ctx,
        scene,
        RenderOptions {
            technique: Technique::Visbuf,
            capture_ids: true,
            // Its depth tells stray pixels from the triangles' own (`stray.rs`).
            capture_depth: true,
            culling: Culling::None,
            lod_error_px: 0.0,
            opaque_order: None,
            alpha_prepass: None,
            depth_prepass: None,
            shadows: ShadowOptions::default(),
            ..tested.clone()
        },
    )?;
    // Every caster into every cascade: the technique's caster culling is checked with its
    // instance culling.
    // The reference's and the technique's depth are kept and compared: where the images
    // differ, the same depth on both sides is a tie (and with levels of detail, how far the
    // surfaces moved).
    let reference = RenderOptions {
        culling: Culling::None,
        lod_error_px: 0.0,
        capture_depth: true,
        shadows: ShadowOptions {
            culling: CasterCulling::None,
            ..tested.shadows
        },
        ..tested.clone()
    };
    let reference = match SceneRenderer::new(ctx, scene, reference) {
        Ok(r) => r,
        Err(e) => {
            oracle.destroy(ctx);
            return Err(e);
        }
    };
    let count = max_frames.map_or(path.len(), |m| m.min(path.len()));
    let aspect = size.0 as f32 / size.1 as f32;
    let (tested, auto_review) = match auto {
        Some(trial) => {
            let timing = Timing {
                path,
                count,
                aspect,
                warmup: timing_warmup,
            };
            match run_trial(ctx, &timing, &mut world, tested, trial) {
                Ok((kept, why)) => (kept, Some(why)),
                Err(e) => {
                    oracle.destroy(ctx);
                    reference.destroy(ctx);
                    return Err(e);
                }
            }
        }
        None => (tested, None),
    };
    let culling = tested.culling;
    let tested = RenderOptions {
        capture_depth: true,
        ..tested
    };
    let tested = match SceneRenderer::new(ctx, world.scene(), tested) {
        Ok(r) => r,
        Err(e) => {
            oracle.destroy(ctx);
            reference.destroy(ctx);
            return Err(e);
        }
    };
    let mut renderers = Renderers {
        oracle,
        reference,
        tested,
    };
    let run = Run {
        culling,
        path,
        size,
        max_frames,
        auto_review,
        timing_warmup,
    };
    let result = run.check(
        ctx,
        &mut world,
        &mut renderers,
        &mut on_failure,
        &mut on_frame,
    );
    let Renderers {
        oracle,
        reference,
        tested,
    } = renderers;
    let tested_options = tested.options().clone();
    oracle.destroy(ctx);
    reference.destroy(ctx);
    tested.destroy(ctx);
    let (mut check, visible) = result?;
    // The ideal frame, in a renderer made after the others are gone (as the tested one was):
    // a still scene only (a moving one would be copied whole every frame).
    if let World::Still(scene) = world {
        let timing = Timing {
            path,
            count: visible.len(),
            aspect,
            warmup: timing_warmup,
        };
        let ideal = ideal_frame(ctx, scene, tested_options, &timing, &visible)?;
        check.totals.ideal_frame_gpu_ms = ideal;
        check.totals.efficiency = ideal
            .filter(|_| check.totals.frame_gpu_ms > 0.0)
            .map(|i| i / check.totals.frame_gpu_ms);
    }
    Ok(check)
}

/// The three renderers of a check, on one device.
struct Renderers {
    /// Visibility buffer, no culling, ids captured.
    oracle: SceneRenderer,
    /// Forward, no culling.
    reference: SceneRenderer,
    /// Forward, with the culling under test.
    tested: SceneRenderer,
}

/// What a check runs.
struct Run<'a> {
    culling: Culling,
    path: &'a CameraPath,
    size: (u32, u32),
    max_frames: Option<usize>,
    /// What `auto`'s trial timed and kept (`None`: the culling was given).
    auto_review: Option<String>,
    timing_warmup: std::time::Duration,
}

impl Run<'_> {
    fn check(
        &self,
        ctx: &Context,
        world: &mut World<'_>,
        r: &mut Renderers,
        on_failure: &mut Option<OnFailure<'_>>,
        on_frame: &mut Option<&mut dyn FnMut(usize, usize)>,
    ) -> Result<(CullCheck, Vec<FrameVisible>), RenderError> {
        let Run {
            culling,
            path,
            size,
            max_frames,
            ..
        } = *self;
        let auto_switch = self.auto_review.clone();
        let Renderers {
            oracle,
            reference,
            tested,
        } = r;
        let aspect = size.0 as f32 / size.1 as f32;
        let count = max_frames.map_or(path.len(), |m| m.min(path.len()));
        let mut frames = Vec::with_capacity(count);
        // Per frame, the compared instances the oracle saw (for the ideal frame).
        let mut visible_sets = Vec::with_capacity(count);
        let mut cpu_ms = Vec::with_capacity(count);
        let mut compared = 0;
        // Degenerate triangles, for telling stray pixels in the technique's frame.
        let degenerate = world.scene().degenerate_triangle_ids();
        for index in 0..count {
            let Some(frame) = path.frame(index, aspect) else {
                break;
            };
            let scene = world.at(index)?;
            // What the comparison covers: the drawn opaque and alpha-tested instances.
            let n = scene.instances().len();
            let compare = compared_instances(scene);
            compared = compare.iter().filter(|c| **c).count();
            let tri = |i: usize| {
                scene
                    .instances()
                    .get(i)
                    .and_then(|inst| scene.mesh(inst.mesh))
                    .map_or(0, |m| u64::from(m.triangle_count()))
            };
            oracle.render_frame(ctx, scene, &frame)?;
            let owners = oracle
                .read_pixel_owners(ctx)?
                .ok_or(RenderError::MissingReadback {
                    what: "the oracle's visibility buffer",
                })?;
            let ids = &owners.instances;
            let oracle_depth = oracle.read_depth(ctx)?;
            let stray = match (&owners.triangles, &oracle_depth) {
                (Some(triangles), Some(depth)) => Some(stray::OracleFrame {
                    scene,
                    matrices: &frame.current,
                    instances: ids,
                    triangles,
                    depth,
                    size,
                    degenerate: &degenerate,
                }),
                _ => None,
            };
            let mut visible = vec![false; n];
            for &id in ids {
                if let Some(v) = visible.get_mut(id as usize) {
                    *v = true;
                }
            }
            let seen: Vec<u32> = (0..n as u32)
                .filter(|&i| visible[i as usize] && compare[i as usize])
                .collect();
            reference.render_frame(ctx, scene, &frame)?;
            let want = reference.read_image(ctx)?;
            let casters_all = reference.read_shadow_casters(ctx)?;
            tested.render_frame(ctx, scene, &frame)?;
            let got = tested.read_image(ctx)?;
            let casters = tested.read_shadow_casters(ctx)?;
            let caster_check = match (tested.read_shadow_caster_ids(ctx)?, &owners.triangles) {
                (Some(drawn), Some(triangles)) => {
                    let differing: Vec<bool> = got
                        .pixels
                        .chunks_exact(4)
                        .zip(want.pixels.chunks_exact(4))
                        .map(|(a, b)| a != b)
                        .collect();
                    let oracle_frame = casters::OracleFrame {
                        frame: &frame,
                        size,
                        instances: ids,
                        triangles,
                        differing: &differing,
                    };
                    let options = tested.options();
                    let cascades = crate::shadow::frame_cascades(
                        &frame.camera,
                        aspect,
                        scene,
                        options.lighting.direction,
                        &options.shadows,
                        options.shadows.atlas(ctx.profile()),
                    );
                    let needs = casters::needed_casters(
                        scene,
                        &oracle_frame,
                        &cascades,
                        &options.shadows.settings(),
                        &casters::casters(scene),
                    );
                    Some(casters::check(&needs, &drawn))
                }
                _ => None,
            };
            let below = if tested.options().culling.clusters() {
                let triangles = owners.triangles.as_deref();
                Some(clusters::of_technique(
                    ctx,
                    tested,
                    scene,
                    (ids, triangles),
                    &compare,
                    stray.as_ref(),
                )?)
            } else {
                None
            };
            let (cluster_triangles, clusters, seen_clusters) = match below {
                Some(b) => (Some(b.triangles), b.check, b.visible),
                None => (None, None, None),
            };
            visible_sets.push(FrameVisible {
                instances: seen,
                clusters: seen_clusters,
            });
            let mut drawn = vec![false; n];
            match tested.drawn_instances(ctx)? {
                Some(list) => {
                    for id in list {
                        if let Some(d) = drawn.get_mut(id as usize) {
                            *d = true;
                        }
                    }
                }
                None => drawn.iter_mut().for_each(|d| *d = true),
            }
            // Culled instances seen only through stray pixels are not visible.
            let stray_only = stray.as_ref().map_or_else(Vec::new, |s| {
                let culled: Vec<u64> = (0..n)
                    .filter(|&i| compare[i] && visible[i] && !drawn[i])
                    .map(|i| i as u64)
                    .collect();
                let key_of = |p: usize| {
                    ids.get(p)
                        .filter(|&&i| i != u32::MAX)
                        .map(|&i| u64::from(i))
                };
                s.only_stray(&culled, key_of)
            });
            for &i in &stray_only {
                if let Some(v) = visible.get_mut(i as usize) {
                    *v = false;
                }
            }
            let depths = match (tested.read_depth(ctx)?, reference.read_depth(ctx)?) {
                (Some(a), Some(b)) => Some((a, b)),
                _ => None,
            };
            let diff = image::PixelDiff::between(
                &got,
                &want,
                ids,
                &drawn,
                depths.as_ref(),
                stray.as_ref(),
            );
            let mut check = FrameCheck {
                frame: index,
                cut: frame.cut,
                visible: 0,
                drawn: 0,
                false_negatives: 0,
                false_positives: 0,
                image_equal: got == want,
                image_diff_pixels: diff.pixels,
                image_diff_pixels_owner_drawn: diff.owner_drawn,
                image_diff_pixels_depth_tie: diff.depth_tie,
                image_diff_pixels_stray: diff.stray,
                image_diff_pixels_unexplained: diff.unexplained,
                image_error: match &depths {
                    Some((a, b)) => {
                        ImageError::between(&got, &want).with_depth(a, b, &frame.current)
                    }
                    None => ImageError::between(&got, &want),
                },
                triangles_drawn: 0,
                false_negative_ids: Vec::new(),
                stray_only: stray_only.len(),
                clusters,
                shadow_casters: casters.map(|c| c.iter().sum()),
                shadow_casters_all: casters_all.map(|c| c.iter().sum()),
                casters: caster_check,
            };
            for i in (0..n).filter(|&i| compare[i]) {
                check.visible += usize::from(visible[i]);
                if drawn[i] {
                    check.drawn += 1;
                    check.triangles_drawn += tri(i);
                }
                match (visible[i], drawn[i]) {
                    (true, false) => {
                        check.false_negatives += 1;
                        if check.false_negative_ids.len() < 8 {
                            check.false_negative_ids.push(i as u32);
                        }
                    }
                    (false, true) => check.false_positives += 1,
                    _ => {}
                }
            }
            if let Some(t) = cluster_triangles {
                check.triangles_drawn = t;
            }
            // Levels of detail: the triangles of the levels the commands drew.
            if tested.options().lod_error_px > 0.0 {
                if let Some(lists) = tested.gpu_lists(ctx)? {
                    check.triangles_drawn = lists.colour_triangles();
                }
            }
            if let Some(save) = on_failure.as_mut() {
                let cluster_fn = check.clusters.is_some_and(|c| c.false_negatives > 0);
                let caster_fn = check.casters.is_some_and(|c| c.false_negatives > 0);
                if check.false_negatives > 0 || cluster_fn || caster_fn || !check.image_equal {
                    let failed = FailedFrame {
                        check: &check,
                        technique: &got,
                        reference: &want,
                        diff: diff_image(&got, &want, ids, &visible, &drawn),
                    };
                    save(&failed).map_err(RenderError::Save)?;
                }
            }
            frames.push(check);
            if let Some(progress) = on_frame.as_mut() {
                progress(frames.len(), count);
            }
        }
        // Times come from two more passes along the path, frames back to back: the checked
        // pass waits for three readbacks between frames, long enough for a GPU to lower its
        // clocks, and its timings measured that (up to 2.8x on an H200 at 1080p). The first
        // times each pass, the second only the whole frame: what is outside the passes (render
        // pass clears, loads and stores, barriers) counts in a frame, and timing each pass
        // costs time of its own (docs/ACCURACY.md, "What a frame time is"). The timed frames
        // keep no depth: storing it is the comparison's cost, not the technique's.
        tested.stop_keeping_depth(ctx)?;
        Timing {
            path,
            count: frames.len(),
            aspect,
            warmup: self.timing_warmup,
        }
        .warm_up(ctx, world, tested)?;
        let checked_with = tested.options().gpu_timing;
        let mut software_ms = Vec::new();
        let mut timed = |timing: GpuTiming, cpu_ms: &mut Vec<f64>| {
            tested.finish(ctx)?;
            tested.set_gpu_timing(ctx, timing)?;
            tested.clear_timings();
            for index in 0..frames.len() {
                let Some(frame) = path.frame(index, aspect) else {
                    break;
                };
                let scene = world.at(index)?;
                let started = std::time::Instant::now();
                let report = tested.render_frame(ctx, scene, &frame)?;
                cpu_ms.push(started.elapsed().as_secs_f64() * 1e3);
                if let (Some(s), GpuTiming::Frame) = (report.software, timing) {
                    software_ms.push(s.cpu_ms);
                }
            }
            tested.finish(ctx)?;
            Ok::<_, RenderError>(tested.medians())
        };
        let medians = timed(GpuTiming::Passes, &mut Vec::new())?;
        let frame = timed(GpuTiming::Frame, &mut cpu_ms)?
            .into_iter()
            .find(|m| m.name == FRAME_TIMING);
        tested.set_gpu_timing(ctx, checked_with)?;
        let is_cull = |name: &str| {
            [
                "cull",
                "cluster",
                "hiz",
                "reproject",
                "occlusion",
                "oq-",
                "raster-occlusion",
            ]
            .iter()
            .any(|p| name.starts_with(p))
        };
        let totals = Totals {
            frames: frames.len(),
            instances: compared,
            visible: frames.iter().map(|f| f.visible).sum(),
            drawn: frames.iter().map(|f| f.drawn).sum(),
            false_negatives: frames.iter().map(|f| f.false_negatives).sum(),
            false_positives: frames.iter().map(|f| f.false_positives).sum(),
            false_positive_rate: {
                let drawn: usize = frames.iter().map(|f| f.drawn).sum();
                let fp: usize = frames.iter().map(|f| f.false_positives).sum();
                if drawn == 0 {
                    0.0
                } else {
                    fp as f64 / drawn as f64
                }
            },
            frames_with_false_negatives: frames.iter().filter(|f| f.false_negatives > 0).count(),
            cluster_false_negatives: frames
                .iter()
                .filter_map(|f| f.clusters)
                .map(|c| c.false_negatives)
                .sum(),
            frames_with_cluster_false_negatives: frames
                .iter()
                .filter(|f| f.clusters.is_some_and(|c| c.false_negatives > 0))
                .count(),
            cluster_false_positives: frames
                .iter()
                .filter_map(|f| f.clusters)
                .map(|c| c.false_positives)
                .sum(),
            stray_only: frames.iter().map(|f| f.stray_only).sum(),
            cluster_stray_only: frames
                .iter()
                .filter_map(|f| f.clusters)
                .map(|c| c.stray_only)
                .sum(),
            frames_image_equal: frames.iter().filter(|f| f.image_equal).count(),
            image_diff_pixels: frames.iter().map(|f| f.image_diff_pixels).sum(),
            image_diff_pixels_depth_tie: frames.iter().map(|f| f.image_diff_pixels_depth_tie).sum(),
            image_diff_pixels_stray: frames.iter().map(|f| f.image_diff_pixels_stray).sum(),
            image_diff_pixels_unexplained: frames
                .iter()
                .map(|f| f.image_diff_pixels_unexplained)
                .sum(),
            image_error: ImageError::over(frames.iter().map(|f| &f.image_error)),
            triangles_drawn: frames.iter().map(|f| f.triangles_drawn).sum(),
            // Folded from +0.0: an empty f64 sum is -0.0, which prints as "-0.0 ms".
            cull_gpu_ms: medians
                .iter()
                .filter(|m| is_cull(&m.name))
                .fold(0.0, |a, m| a + m.median_gpu_ms),
            frame_gpu_ms: frame.as_ref().map_or(0.0, |m| m.median_gpu_ms),
            frame_gpu_ms_p95: frame.as_ref().map_or(0.0, |m| m.p95_gpu_ms),
            shadow_casters: summed(frames.iter().map(|f| f.shadow_casters)),
            shadow_casters_all: summed(frames.iter().map(|f| f.shadow_casters_all)),
            shadow_gpu_ms: medians
                .iter()
                .filter(|m| m.name.starts_with("shadow"))
                .fold(0.0, |a, m| a + m.median_gpu_ms),
            shadow_casters_needed: summed_casters(&frames, |c| c.needed),
            shadow_caster_false_positives: summed_casters(&frames, |c| c.false_positives),
            shadow_caster_false_negatives: summed_casters(&frames, |c| c.false_negatives),
            ideal_frame_gpu_ms: None,
            efficiency: None,
            passes_gpu_ms: medians.iter().fold(0.0, |a, m| a + m.median_gpu_ms),
            cpu_ms: tilegraph_vk::queries::median(&cpu_ms).unwrap_or(0.0),
            software_cpu_ms: tilegraph_vk::queries::median(&software_ms),
            passes: medians
                .iter()
                .map(|m| PassTime {
                    name: m.name.clone(),
                    gpu_ms: m.median_gpu_ms,
                    p95_gpu_ms: m.p95_gpu_ms,
                })
                .collect(),
        };
        Ok((
            CullCheck {
                technique: culling.name().to_string(),
                auto_review: auto_switch,
                scene: world.scene().name().to_string(),
                profile: ctx.profile().name.clone(),
                size: [size.0, size.1],
                frames,
                totals,
            },
            visible_sets,
        ))
    }
}

/// `field` of the frames' caster checks summed (`None` when no frame has one).
fn summed_casters(frames: &[FrameCheck], field: impl Fn(&CasterCheck) -> usize) -> Option<u64> {
    frames
        .iter()
        .filter_map(|f| f.casters.as_ref())
        .map(|c| field(c) as u64)
        .reduce(|a, b| a + b)
}

/// Per instance slot, whether the comparison covers it: drawn (not hidden, not a free slot),
/// opaque or alpha-tested (blended instances are sorted on the CPU by every technique, and the
/// visibility buffer does not hold them).
fn compared_instances(scene: &Scene) -> Vec<bool> {
    scene
        .instances()
        .iter()
        .map(|i| {
            i.flags.is_drawn()
                && !scene
                    .instance_material(i)
                    .is_some_and(|m| matches!(m.class, tilegraph_scene::MaterialClass::Blended))
        })
        .collect()
}
