//! Levels of detail by screen error (knob `lod_error_px`), on lavapipe with validation on: the
//! levels cut triangles, their image error is measured against the full-detail frame (and
//! stays small at a pixel), culling stays exact relative to the frame the levels make (every
//! technique, with or without a pre-pass, with a fixed draw count, draws the same image), and
//! what cannot draw them says so.

use tilegraph_e2e::gpu_with;
use tilegraph_passes::cull::Culling;
use tilegraph_passes::cullcheck::{cull_check_options, CheckExtras, CullCheck};
use tilegraph_passes::{RenderError, RenderOptions, SceneRenderer, Technique};
use tilegraph_scene::{CameraPath, Scene};

const SIZE: (u32, u32) = (160, 90);

fn options(culling: Culling, lod_error_px: f32) -> RenderOptions {
    RenderOptions {
        width: SIZE.0,
        height: SIZE.1,
        culling,
        lod_error_px,
        ..Default::default()
    }
}

/// The first `n` frames of the scene's path.
fn path(scene: &Scene, n: usize) -> CameraPath {
    let keys: Vec<_> = scene.camera_path().keys().iter().take(n).copied().collect();
    CameraPath::new(format!("{} lod path", scene.name()), keys).unwrap()
}

fn check(profile: Option<&str>, scene: &Scene, options: RenderOptions, frames: usize) -> CullCheck {
    let g = gpu_with(profile, tilegraph_e2e::culling_features()).unwrap();
    cull_check_options(
        &g,
        scene,
        options,
        &path(scene, frames),
        None,
        CheckExtras::default(),
    )
    .unwrap()
}

/// The spheres (1,280 triangles each, some stretched, some mirrored), then FlightHelmet where
/// the test data has it; clusters and levels attached.
fn scenes() -> Vec<Scene> {
    let mut scenes = vec![tilegraph_e2e::closed_spheres(3, 4, true)];
    match tilegraph_e2e::test_data("scenes/FlightHelmet/FlightHelmet.gltf") {
        Some(p) => {
            let mut s = tilegraph_scene::load(&p.display().to_string()).unwrap();
            let (data, _) = tilegraph_scene::clusters::build(&s).unwrap();
            s.attach_clusters(data).unwrap();
            scenes.push(s);
        }
        None => eprintln!(
            "skipping FlightHelmet: {} not found",
            tilegraph_e2e::test_data_dir().display()
        ),
    }
    scenes
}

/// Coarser error bounds draw fewer triangles for more image error (against the full-detail
/// frame; at these small sizes most pixels are edges, and the error counts shading too: the
/// levels bound the surface's distance, not its normals). At 0 px nothing changes.
#[test]
fn levels_cut_triangles_for_a_measured_image_error() {
    for scene in scenes() {
        let name = scene.name().to_string();
        assert!(
            scene.clusters().is_some_and(|c| c.has_lods()),
            "{name}: no mesh simplified"
        );
        let runs: Vec<(f32, CullCheck)> = [0.0, 1.0, 4.0]
            .into_iter()
            .map(|px| {
                (
                    px,
                    check(None, &scene, options(Culling::HizTwoPhase, px), 6),
                )
            })
            .collect();
        let triangles: Vec<u64> = runs.iter().map(|r| r.1.totals.triangles_drawn).collect();
        eprintln!(
            "{name}: triangles {triangles:?}, psnr {:?}, largest difference {:?}, depth {:?}",
            runs.iter()
                .map(|r| r.1.totals.image_error.psnr_db)
                .collect::<Vec<_>>(),
            runs.iter()
                .map(|r| r.1.totals.image_error.max_channel_diff)
                .collect::<Vec<_>>(),
            runs.iter()
                .map(|r| r.1.totals.image_error.max_depth_rel_diff)
                .collect::<Vec<_>>()
        );
        // Full detail: the culled frame equals the reference.
        let exact = &runs[0].1;
        assert_eq!(
            exact.totals.frames_image_equal, exact.totals.frames,
            "{name}"
        );
        assert_eq!(exact.totals.image_error.psnr_db, None, "{name}");
        assert!(
            triangles[1] <= triangles[0] && triangles[2] < triangles[0],
            "{name}: {triangles:?}"
        );
        assert!(triangles[2] <= triangles[1], "{name}: {triangles:?}");
        // The depth is compared in every check: the same at full detail; where levels are
        // drawn the largest difference sits on a silhouette, one surface in front of another
        // (13-17 % on these at 160x90).
        assert_eq!(
            exact.totals.image_error.max_depth_rel_diff,
            Some(0.0),
            "{name}"
        );
        for (px, r) in &runs[1..] {
            let d = r.totals.image_error.max_depth_rel_diff;
            assert!(
                d.is_some_and(|d| d.is_finite() && d > 0.0),
                "{name} {px} px: {d:?}"
            );
        }
        let (one, four) = (&runs[1].1.totals.image_error, &runs[2].1.totals.image_error);
        assert!(one.psnr_db.is_none_or(|p| p > 20.0), "{name}: {one:?}");
        assert!(one.mse <= four.mse, "{name}: {one:?} {four:?}");
        for (px, r) in &runs {
            for f in &r.frames {
                // The error is the frame's, per frame too.
                assert_eq!(
                    f.image_error.psnr_db.is_none(),
                    f.image_equal,
                    "{name} {px} px frame {}",
                    f.frame
                );
            }
        }
    }
}

/// Renders the scene's first frames with `options` on `profile`'s device; returns the images.
fn images(
    profile: Option<&str>,
    scene: &Scene,
    options: RenderOptions,
    frames: usize,
) -> Vec<Vec<u8>> {
    let g = gpu_with(profile, tilegraph_e2e::culling_features()).unwrap();
    let mut r = SceneRenderer::new(&g, scene, options).unwrap();
    let mut out = Vec::new();
    for k in 0..frames {
        let cam = scene.camera_path().camera(k).unwrap();
        r.render(&g, scene, &cam).unwrap();
        out.push(r.read_image(&g).unwrap().pixels);
    }
    r.destroy(&g);
    out
}

/// The levels are a function of the instance and the camera alone: frustum, hiz and
/// hiz-2phase culling, a depth pre-pass (whose depth the colour pass tests EQUAL) and a fixed
/// draw count (mali-valhall's profile: one command per group and level, culled ones empty)
/// draw the same image as frustum culling, and so does deferred texturing under both: culling
/// stays exact under levels of detail.
#[test]
fn every_culling_draws_the_same_levels() {
    let scene = tilegraph_e2e::closed_spheres(3, 4, true);
    let px = 2.0;
    let forward = images(None, &scene, options(Culling::Frustum, px), 4);
    let full = images(None, &scene, options(Culling::Frustum, 0.0), 4);
    assert_ne!(
        forward, full,
        "2 px changed nothing: the levels were not drawn"
    );
    let deferred = |culling| RenderOptions {
        technique: Technique::DeferredTexturing,
        ..options(culling, px)
    };
    let deferred_frustum = images(None, &scene, deferred(Culling::Frustum), 4);
    let variants = [
        (&forward, None, options(Culling::HizTwoPhase, px)),
        (&forward, None, options(Culling::Hiz, px)),
        (
            &forward,
            None,
            RenderOptions {
                depth_prepass: Some(true),
                technique: Technique::Prepass,
                ..options(Culling::HizTwoPhase, px)
            },
        ),
        (
            &forward,
            Some("mali-valhall"),
            options(Culling::HizTwoPhase, px),
        ),
        (&deferred_frustum, None, deferred(Culling::HizTwoPhase)),
    ];
    for (want, profile, o) in variants {
        let what = format!("{profile:?} {} {}", o.culling.name(), o.technique.name());
        let got = images(profile, &scene, o, 4);
        for (k, (a, b)) in got.iter().zip(want).enumerate() {
            let differing = a
                .chunks_exact(4)
                .zip(b.chunks_exact(4))
                .filter(|(x, y)| x != y)
                .count();
            assert_eq!(differing, 0, "{what}: frame {k}");
        }
    }
}

/// What cannot draw levels of detail is a typed error saying why: culling that does not choose
/// them, the visibility buffer, a scene without them.
#[test]
fn levels_of_detail_say_what_they_need() {
    let g = gpu_with(None, tilegraph_e2e::culling_features()).unwrap();
    let scene = tilegraph_e2e::closed_spheres(1, 2, false);
    let refused = |scene: &Scene, o: RenderOptions| match SceneRenderer::new(&g, scene, o) {
        Err(RenderError::Lod { reason, .. }) => reason,
        Err(e) => panic!("another error: {e}"),
        Ok(r) => {
            r.destroy(&g);
            panic!("accepted")
        }
    };
    assert!(refused(&scene, options(Culling::None, 1.0)).contains("GPU instance culling"));
    assert!(refused(&scene, options(Culling::HizTwoPhaseClusters, 1.0))
        .contains("GPU instance culling"));
    let visbuf = RenderOptions {
        technique: Technique::Visbuf,
        ..options(Culling::Frustum, 1.0)
    };
    assert!(refused(&scene, visbuf).contains("visibility buffer"));
    assert!(refused(&scene, options(Culling::Frustum, f32::NAN)).contains("positive"));
    let plain = tilegraph_scene::load("city:200").unwrap();
    assert!(refused(&plain, options(Culling::Frustum, 1.0)).contains("clusters"));
}

/// A draw group longer than one compaction chunk (1,296 spheres of one mesh, the chunk is
/// 1,024 entries): every instance the frustum keeps is drawn exactly once, by a command whose
/// index range is one of its mesh's levels, several levels in use; the same instances as at
/// full detail; two-phase culling draws the same image as frustum culling.
#[test]
fn long_groups_pack_each_level_once() {
    let scene = tilegraph_e2e::closed_spheres(36, 36, false);
    let g = gpu_with(None, tilegraph_e2e::culling_features()).unwrap();
    // From a corner at eye height across the grid: near spheres fine, far ones coarse.
    let cam = tilegraph_scene::Camera::looking_at(
        glam::DVec3::new(-46.0, 1.5, -46.0),
        glam::DVec3::new(0.0, 0.0, 0.0),
    );
    let drawn = |px: f32| {
        let mut r = SceneRenderer::new(&g, &scene, options(Culling::Frustum, px)).unwrap();
        r.render(&g, &scene, &cam).unwrap();
        let lists = r.gpu_lists(&g).unwrap().unwrap();
        let image = r.read_image(&g).unwrap().pixels;
        r.destroy(&g);
        (lists, image)
    };
    let (full, _) = drawn(0.0);
    let (lod, lod_image) = drawn(1.0);
    let ids = |lists: &tilegraph_passes::cull::GpuLists| {
        let mut ids: Vec<u32> = lists.lists[..4]
            .iter()
            .flatten()
            .flat_map(|d| d.instances.iter().copied())
            .collect();
        ids.sort_unstable();
        ids
    };
    let (full_ids, lod_ids) = (ids(&full), ids(&lod));
    assert!(
        full_ids.len() > 1024,
        "{} drawn: the group fits one chunk",
        full_ids.len()
    );
    let mut unique = lod_ids.clone();
    unique.dedup();
    assert_eq!(unique.len(), lod_ids.len(), "an instance drawn twice");
    assert_eq!(lod_ids, full_ids, "levels changed what the frustum keeps");
    let clusters = scene.clusters().unwrap();
    let mut ranges_used = std::collections::BTreeSet::new();
    for d in lod.lists[..4].iter().flatten() {
        for &id in &d.instances {
            let m = scene.instances()[id as usize].mesh;
            let mesh = scene.mesh(m).unwrap();
            let own = (mesh.first_index, mesh.index_count);
            let levels: Vec<(u32, u32)> = clusters
                .lods_of(m.0)
                .iter()
                .map(|l| (l.first_index, l.index_count))
                .collect();
            let range = (d.first_index, d.index_count);
            assert!(
                range == own || levels.contains(&range),
                "instance {id}: range {range:?}"
            );
        }
        ranges_used.insert((d.first_index, d.index_count));
    }
    assert!(ranges_used.len() > 2, "levels used: {ranges_used:?}");
    let mut r = SceneRenderer::new(&g, &scene, options(Culling::HizTwoPhase, 1.0)).unwrap();
    r.render(&g, &scene, &cam).unwrap();
    assert!(
        r.read_image(&g).unwrap().pixels == lod_image,
        "two-phase drew another image"
    );
    r.destroy(&g);
}

/// An instance near a level's threshold does not flip levels from frame to frame: the camera
/// dollies back and forth by 3 % over a grid of spheres (all in view), with a cut at frame 5.
/// Without the band (`lod_hysteresis = 0`) the levels follow every step; with the default 0.2
/// the spheres keep the finer levels they had (never a coarser one than the bound allows) until
/// the cut, which forgets them; frustum and two-phase culling alike.
#[test]
fn levels_do_not_flip_near_a_threshold() {
    use tilegraph_scene::{Camera, PathKey};
    let mut scene = tilegraph_e2e::closed_spheres(12, 12, false);
    let (data, _) = tilegraph_scene::clusters::build(&scene).unwrap();
    scene.attach_clusters(data).unwrap();
    let direction = glam::DVec3::new(0.0, 0.8, 0.6).normalize();
    let keys = (0..8)
        .map(|i| PathKey {
            camera: Camera::looking_at(
                direction * if i % 2 == 0 { 40.0 } else { 41.2 },
                glam::DVec3::ZERO,
            ),
            cut: i == 0 || i == 5,
        })
        .collect();
    let path = CameraPath::new("dolly", keys).unwrap();
    let g = gpu_with(None, tilegraph_e2e::culling_features()).unwrap();
    for culling in [Culling::Frustum, Culling::HizTwoPhase] {
        let triangles = |band: f32| {
            let o = RenderOptions {
                width: 320,
                height: 180,
                culling,
                lod_error_px: 2.0,
                lod_hysteresis: band,
                ..Default::default()
            };
            let r = cull_check_options(&g, &scene, o, &path, None, CheckExtras::default());
            let r = r.unwrap();
            assert_eq!(r.totals.false_negatives, 0, "{}", culling.name());
            r.frames
                .iter()
                .map(|f| f.triangles_drawn)
                .collect::<Vec<_>>()
        };
        let (plain, banded) = (triangles(0.0), triangles(0.2));
        eprintln!("{}: band 0 {plain:?}, band 0.2 {banded:?}", culling.name());
        let (near, far) = (plain[0], plain[1]);
        // Without the band the levels follow the dolly: a coarser level one step out.
        assert!(far < near, "{}: {plain:?}", culling.name());
        assert!(
            plain
                .iter()
                .enumerate()
                .all(|(i, &t)| t == if i % 2 == 0 { near } else { far }),
            "{}: {plain:?}",
            culling.name()
        );
        // With it the near levels stay, but for the cut frame (5), which chooses afresh.
        let want: Vec<u64> = (0..8).map(|i| if i == 5 { far } else { near }).collect();
        assert_eq!(banded, want, "{}", culling.name());
    }
}
