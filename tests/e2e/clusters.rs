//! Cluster culling against the exact oracle (lavapipe, validation on): `frustum-clusters` and
//! `hiz-2phase-clusters` never cull a visible instance and leave every frame's image equal to
//! the unculled one on the shipped scenes, FlightHelmet and one Godot room; back-facing cones
//! remove clusters of closed meshes (and leave mirrored and double-sided ones alone); the
//! fixed draw count (a profile without `drawIndirectCount`) draws the same; deferred texturing
//! and the visibility buffer (whose ids count a cluster run's triangles from the run's first)
//! stay exact under cluster culling, their G-buffer or ids drawn in both phases.

use tilegraph_e2e::gpu_with;
use tilegraph_passes::cull::{ClusterEarly, Culling, DrawCount};
use tilegraph_passes::cullcheck::{cull_check_options, CheckExtras, CullCheck};
use tilegraph_passes::{RenderError, RenderOptions, SceneRenderer, Technique};
use tilegraph_scene::{CameraPath, PathKey, Scene};

const SIZE: (u32, u32) = (160, 90);

/// The first frames of the scene's path, then every 29th (fast motion without a cut flag).
fn path(scene: &Scene, frames: usize) -> CameraPath {
    let keys = scene.camera_path().keys();
    let mut picks: Vec<usize> = (0..3.min(keys.len())).collect();
    picks.extend((3..keys.len()).step_by(29));
    picks.truncate(frames);
    let selected: Vec<PathKey> = picks
        .iter()
        .map(|&i| PathKey {
            camera: keys[i].camera,
            cut: false,
        })
        .collect();
    CameraPath::new(format!("{} cluster path", scene.name()), selected).unwrap()
}

fn check(profile: Option<&str>, scene: &Scene, culling: Culling, frames: usize) -> CullCheck {
    check_along(profile, scene, culling, &path(scene, frames), SIZE)
}

fn check_along(
    profile: Option<&str>,
    scene: &Scene,
    culling: Culling,
    path: &CameraPath,
    size: (u32, u32),
) -> CullCheck {
    let options = RenderOptions {
        width: size.0,
        height: size.1,
        culling,
        ..Default::default()
    };
    check_with(profile, scene, options, path)
}

fn check_with(
    profile: Option<&str>,
    scene: &Scene,
    options: RenderOptions,
    path: &CameraPath,
) -> CullCheck {
    let g = gpu_with(profile, tilegraph_e2e::culling_features()).unwrap();
    cull_check_options(&g, scene, options, path, None, CheckExtras::default()).unwrap()
}

/// FN 0 at instance and at cluster level (the oracle sees below the instance: a cluster
/// technique's frames must carry its comparison), images equal.
fn assert_exact(what: &str, r: &CullCheck) {
    for f in &r.frames {
        assert_eq!(
            f.false_negatives, 0,
            "{what} {}: frame {} culled visible instances {:?}",
            r.technique, f.frame, f.false_negative_ids
        );
        if r.technique.ends_with("-clusters") {
            let c = f.clusters.unwrap_or_else(|| {
                panic!(
                    "{what} {}: frame {} has no cluster comparison",
                    r.technique, f.frame
                )
            });
            assert_eq!(
                c.false_negatives, 0,
                "{what} {}: frame {} culled {} visible clusters",
                r.technique, f.frame, c.false_negatives
            );
            assert!(c.visible > 0 && c.drawn >= c.visible - c.false_negatives);
        }
        assert!(
            f.image_equal,
            "{what} {}: frame {} differs from the unculled image in {} pixels ({} owned by drawn instances)",
            r.technique, f.frame, f.image_diff_pixels, f.image_diff_pixels_owner_drawn
        );
    }
}

/// `specs`, then FlightHelmet and the Godot room where the test data has them (a skip said
/// where not).
fn with_helmet_and_room(specs: &[&str]) -> Vec<String> {
    let mut specs: Vec<String> = specs.iter().map(|s| s.to_string()).collect();
    for data in [
        "scenes/FlightHelmet/FlightHelmet.gltf",
        "bench/GodotRooms/room.gltf",
    ] {
        match tilegraph_e2e::test_data(data) {
            Some(p) => specs.push(p.display().to_string()),
            None => eprintln!(
                "skipping {data}: {} not found",
                tilegraph_e2e::test_data_dir().display()
            ),
        }
    }
    specs
}

fn with_clusters(spec: &str) -> Scene {
    let mut scene = tilegraph_scene::load(spec).unwrap();
    let (data, _) = tilegraph_scene::clusters::build(&scene).unwrap();
    scene.attach_clusters(data).unwrap();
    scene
}

#[test]
fn cluster_culling_never_culls_a_visible_pixel() {
    let specs = with_helmet_and_room(&["city:1500", "forest:800", "interior:800"]);
    let mut lines = Vec::new();
    for spec in &specs {
        let scene = with_clusters(spec);
        let mut triangles = Vec::new();
        for culling in [
            Culling::Frustum,
            Culling::FrustumClusters,
            Culling::HizTwoPhase,
            Culling::HizTwoPhaseClusters,
        ] {
            let r = check(None, &scene, culling, 8);
            assert_exact(spec, &r);
            lines.push(format!(
                "{spec:<60} {:<20} drawn {:>5} triangles {:>9}",
                r.technique, r.totals.drawn, r.totals.triangles_drawn
            ));
            triangles.push(r.totals.triangles_drawn);
        }
        // A cluster is culled only inside an instance the instance stage kept: frustum
        // clusters draw a subset of frustum culling's triangles.
        assert!(triangles[1] <= triangles[0], "{spec}: {triangles:?}");
        if spec.ends_with("room.gltf") {
            // The room's walls are one mesh whose box always passes; its clusters do not (the
            // pyramid removes them; at 160x90 the snapping keeps most back-facing ones).
            assert!(
                triangles[3] * 4 < triangles[2] * 3,
                "{spec}: hiz-2phase-clusters {} vs hiz-2phase {}",
                triangles[3],
                triangles[2]
            );
        }
    }
    println!("{}", lines.join("\n"));
}

/// Deferred texturing and the visibility buffer under both cluster techniques: FN 0 and every
/// image equal to its unculled frame, with the resolve sampled (lavapipe) and as a tiler's
/// subpass (mali-valhall). The visibility buffer's ids name a cluster run's triangles by the
/// run's first triangle in its mesh plus the primitive id: were that first triangle taken as
/// the mesh's, `frustum-clusters` (every draw a run) would resolve another triangle's surface
/// in every frame of FlightHelmet, `hiz-2phase-clusters` in its first.
#[test]
fn screen_space_shading_keeps_cluster_culling_exact() {
    let mut specs = vec!["city:1500".to_string()];
    match tilegraph_e2e::test_data("scenes/FlightHelmet/FlightHelmet.gltf") {
        Some(p) => specs.push(p.display().to_string()),
        None => eprintln!(
            "skipping FlightHelmet: {} not found",
            tilegraph_e2e::test_data_dir().display()
        ),
    }
    for spec in &specs {
        let scene = with_clusters(spec);
        for (technique, profile, culling) in [
            (Technique::DeferredTexturing, None, Culling::HizTwoPhase),
            (Technique::DeferredTexturing, None, Culling::FrustumClusters),
            (
                Technique::DeferredTexturing,
                None,
                Culling::HizTwoPhaseClusters,
            ),
            (
                Technique::DeferredTexturing,
                Some("mali-valhall"),
                Culling::HizTwoPhaseClusters,
            ),
            (Technique::Visbuf, None, Culling::FrustumClusters),
            (Technique::Visbuf, None, Culling::HizTwoPhaseClusters),
            (
                Technique::Visbuf,
                Some("mali-valhall"),
                Culling::HizTwoPhaseClusters,
            ),
        ] {
            let options = RenderOptions {
                width: SIZE.0,
                height: SIZE.1,
                culling,
                technique,
                ..Default::default()
            };
            let r = check_with(profile, &scene, options, &path(&scene, 6));
            assert_exact(&format!("{spec} {} {profile:?}", technique.name()), &r);
        }
    }
}

/// `levels` (scene spec, walk seed) and the Godot room with walk seed 5 where the test data
/// has it (skipped, saying so, where it does not).
fn with_godot_room(levels: &[(&str, u64)]) -> Vec<(String, u64)> {
    let mut specs: Vec<(String, u64)> = levels.iter().map(|(s, k)| (s.to_string(), *k)).collect();
    match tilegraph_e2e::test_data("bench/GodotRooms/room.gltf") {
        Some(p) => specs.push((p.display().to_string(), 5)),
        None => eprintln!(
            "skipping the Godot room: {} not found",
            tilegraph_e2e::test_data_dir().display()
        ),
    }
    specs
}

/// Levels exported as one mesh per material (`@one-mesh`: one instance covers the level, its
/// clusters lie far from the mesh's origin, thin and distant pieces of surface share a mesh
/// with everything else), on walks at eye height with yaw sweeps and hard cuts: both cluster
/// techniques keep every frame's image equal to the unculled one, and draw no more triangles
/// in any frame than the instance culling they refine.
/// The Godot room (its objects instances, its walls one mesh) walks the same way.
#[test]
fn one_mesh_levels_on_eye_height_walks_stay_exact() {
    let specs = with_godot_room(&[
        ("interior:700@one-mesh", 7),
        ("city:900@one-mesh", 3),
        ("maze:700@one-mesh", 5),
    ]);
    for (spec, seed) in &specs {
        let (spec, seed) = (spec.as_str(), *seed);
        let scene = with_clusters(spec);
        if spec.ends_with("@one-mesh") {
            assert!(scene.instances().len() <= scene.materials().len());
        }
        let path = CameraPath::eye_height_walk(&scene.bounds(), 14, seed);
        for (instance, clusters) in [
            (Culling::Frustum, Culling::FrustumClusters),
            (Culling::HizTwoPhase, Culling::HizTwoPhaseClusters),
        ] {
            let whole = check_along(None, &scene, instance, &path, SIZE);
            let r = check_along(None, &scene, clusters, &path, SIZE);
            assert_exact(spec, &r);
            tilegraph_e2e::assert_no_more_triangles(spec, &whole, &r);
            println!(
                "{spec:<24} {:<20} {:>9} triangles; {:<12} {:>9}",
                r.technique,
                r.totals.triangles_drawn,
                whole.technique,
                whole.totals.triangles_drawn
            );
            assert!(
                r.totals.triangles_drawn < whole.totals.triangles_drawn,
                "{spec}: {} culled no cluster along the walk",
                r.technique
            );
        }
    }
}

/// Degenerate triangles of the maze that lavapipe, at 333x77, rasterizes at a depth they
/// never reach. On walk 233673 a collinear triangle 15-22 m away owns a pixel at depth 1.0 —
/// the near plane, where its corners lie at 0.0006 — in the unculled frame (19), and
/// `hiz-2phase-clusters` rightly culls its cluster, whose box lies behind a wall. On walk
/// 491291 `frustum-clusters`, drawing the level in runs of clusters, shows such a fleck at 1.0
/// in front of a wall (frame 10) that the whole draw of the unculled frame does not. The oracle
/// judges both stray: no false negative, and every differing pixel a stray one. (On the H200
/// neither frame draws a stray fragment, and both are exact outright.)
#[test]
fn degenerate_triangles_stray_pixels_are_no_culling_errors() {
    let g = gpu_with(None, tilegraph_e2e::culling_features()).unwrap();
    for (seed, culling, frames) in [
        (233673, Culling::HizTwoPhaseClusters, 20),
        (491291, Culling::FrustumClusters, 11),
    ] {
        let size = if seed == 233673 { 1500 } else { 500 };
        let scene = with_clusters(&format!("maze:{size}:{seed}@one-mesh"));
        let path = CameraPath::eye_height_walk(&scene.bounds(), 240, seed);
        let options = RenderOptions {
            width: 333,
            height: 77,
            culling,
            ..Default::default()
        };
        let extras = CheckExtras::default();
        let r = cull_check_options(&g, &scene, options, &path, Some(frames), extras).unwrap();
        for f in &r.frames {
            let c = f
                .clusters
                .expect("a cluster technique's frame has a cluster comparison");
            assert_eq!(c.false_negatives, 0, "walk {seed} frame {}: {c:?}", f.frame);
            assert_eq!(f.false_negatives, 0, "walk {seed} frame {}", f.frame);
            assert_eq!(
                f.image_diff_pixels, f.image_diff_pixels_stray,
                "walk {seed} frame {}: every differing pixel is a stray one",
                f.frame
            );
        }
        let t = &r.totals;
        println!(
            "maze walk {seed} at 333x77, {}: clusters FN {}, stray-only {}; images equal {}/{}, {} stray pixels differ",
            r.technique, t.cluster_false_negatives, t.cluster_stray_only, t.frames_image_equal, t.frames, t.image_diff_pixels_stray
        );
    }
}

/// The cluster knobs' other settings trade work, never exactness: `cluster_early = "clusters"`
/// (the early phase draws only the clusters not found occluded last frame: the triangle bound
/// given up for less early work) with `cluster_gap = 8` (long gaps drawn through), and the
/// default early phase with `cluster_gap = 0` (exactly the surviving clusters): on a one-mesh
/// level's walk and the Godot room's, FN 0 at cluster level and every image equal.
#[test]
fn other_cluster_settings_stay_exact() {
    let specs = with_godot_room(&[("interior:700@one-mesh", 7)]);
    for (spec, seed) in &specs {
        let scene = with_clusters(spec);
        let path = CameraPath::eye_height_walk(&scene.bounds(), 14, *seed);
        let options = |early, gap| RenderOptions {
            width: SIZE.0,
            height: SIZE.1,
            culling: Culling::HizTwoPhaseClusters,
            cluster_early: early,
            cluster_gap: gap,
            ..Default::default()
        };
        let whole = check_with(None, &scene, options(ClusterEarly::Instances, 0), &path);
        let r = check_with(None, &scene, options(ClusterEarly::Clusters, 8), &path);
        assert_exact(spec, &r);
        assert_exact(spec, &whole);
        println!(
            "{spec:<24} colour triangles: clusters, gap 8 {:>9}; instances, gap 0 {:>9}",
            r.totals.triangles_drawn, whole.totals.triangles_drawn
        );
    }
}

/// Closed spheres seen from a few metres at 320x180: the clusters on the far side of each
/// sphere face away and their cones remove them (a cluster of ~120 triangles spans ~70 degrees
/// of normals, so the camera must lie in a cone of ~55 degrees around its axis, less the room
/// left for the rasterizer's snapping: about a fifth of a sphere's clusters). Mirrored spheres
/// (negative scale), non-uniformly scaled and double-sided ones are not cone-tested: were they,
/// their visible front would vanish and the image check would fail. From far away, where a
/// sphere's triangles are a fraction of a pixel and snapping can turn them, no cone rejects.
/// (`cluster_gap = 0`: the cones' own effect, no gap drawn through.)
#[test]
fn back_facing_cones_remove_clusters_of_closed_meshes() {
    let near = |scene: &Scene| {
        let projection = scene.camera_path().keys()[0].camera.projection;
        let keys = (0..6)
            .map(|i| PathKey {
                camera: tilegraph_scene::Camera {
                    eye: glam::DVec3::new(-3.0 + 1.2 * f64::from(i), 2.5, 6.0),
                    target: glam::DVec3::new(0.0, 0.0, -1.0),
                    up: glam::Vec3::Y,
                    projection,
                },
                cut: false,
            })
            .collect();
        CameraPath::new("near the spheres", keys).unwrap()
    };
    for exempt in [false, true] {
        let scene = tilegraph_e2e::closed_spheres(3, 4, exempt);
        let path = near(&scene);
        // Exactly the surviving clusters: a bridged gap would draw back-facing ones again.
        let options = RenderOptions {
            width: 320,
            height: 180,
            culling: Culling::FrustumClusters,
            cluster_gap: 0,
            ..Default::default()
        };
        let r = check_with(None, &scene, options, &path);
        assert_exact("closed spheres", &r);
        let instance = check_along(None, &scene, Culling::Frustum, &path, (320, 180));
        let (clusters, whole) = (r.totals.triangles_drawn, instance.totals.triangles_drawn);
        println!(
            "closed spheres (exempt ones: {exempt}): frustum {whole} triangles, frustum-clusters {clusters}"
        );
        let most = if exempt { 0.95 } else { 0.9 };
        assert!(
            (clusters as f64) < most * whole as f64,
            "cones removed too little: {clusters} of {whole} triangles drawn"
        );
    }
    // The scene's own path keeps its distance: the spheres are a pixel or two across at
    // 160x90, and the cones keep every cluster.
    let scene = tilegraph_e2e::closed_spheres(3, 4, false);
    let far = check(None, &scene, Culling::FrustumClusters, 6);
    assert_exact("closed spheres, far", &far);
    let whole = check(None, &scene, Culling::Frustum, 6);
    assert_eq!(far.totals.triangles_drawn, whole.totals.triangles_drawn);
}

/// Without `drawIndirectCount` (mali-valhall's profile, forced on lavapipe) every list draws its
/// whole capacity, the commands past the frame's count cleared: the same image, no visible
/// instance culled.
#[test]
fn cluster_lists_hold_with_a_fixed_draw_count() {
    let scene = tilegraph_e2e::closed_spheres(2, 3, true);
    for culling in [Culling::FrustumClusters, Culling::HizTwoPhaseClusters] {
        let r = check(Some("mali-valhall"), &scene, culling, 5);
        assert_exact("mali-valhall", &r);
    }
    let g = gpu_with(Some("mali-valhall"), tilegraph_e2e::culling_features()).unwrap();
    let options = RenderOptions {
        width: SIZE.0,
        height: SIZE.1,
        technique: Technique::Prepass,
        culling: Culling::HizTwoPhaseClusters,
        ..Default::default()
    };
    let mut r = SceneRenderer::new(&g, &scene, options).unwrap();
    let cam = scene.camera_path().camera(0).unwrap();
    r.render(&g, &scene, &cam).unwrap();
    let lists = r.gpu_lists(&g).unwrap().unwrap();
    assert!(matches!(lists.draw_count, DrawCount::Fixed { .. }));
    assert!(lists.colour_triangles() > 0);
    r.destroy(&g);
}

/// A cluster technique on a scene without clusters, and with the visibility buffer, are typed
/// errors naming what is missing.
#[test]
fn cluster_techniques_say_what_they_need() {
    let g = gpu_with(None, tilegraph_e2e::culling_features()).unwrap();
    let plain = tilegraph_scene::load("city:50").unwrap();
    let options = RenderOptions {
        width: 32,
        height: 32,
        culling: Culling::HizTwoPhaseClusters,
        ..Default::default()
    };
    match SceneRenderer::new(&g, &plain, options.clone()) {
        Err(RenderError::NoClusters { culling, scene }) => {
            assert_eq!(culling, "hiz-2phase-clusters");
            assert!(scene.contains("city"), "{scene}");
        }
        Err(e) => panic!("expected NoClusters, got {e}"),
        Ok(r) => {
            r.destroy(&g);
            panic!("rendered clusters the scene does not have");
        }
    }
    // Per-triangle culling packs the kept triangles anew: the visibility buffer's ids could
    // not name them.
    let clustered = with_clusters("city:50");
    let visbuf = RenderOptions {
        technique: Technique::Visbuf,
        triangle_culling: true,
        ..options
    };
    match SceneRenderer::new(&g, &clustered, visbuf) {
        Err(RenderError::UnsupportedCulling { reason, .. }) => {
            assert!(reason.contains("triangle_culling"), "{reason}")
        }
        Err(e) => panic!("expected UnsupportedCulling, got {e}"),
        Ok(r) => {
            r.destroy(&g);
            panic!("visbuf with per-triangle culling");
        }
    }
}

/// Per-triangle culling (knob `triangle_culling`) after both cluster techniques: on the city,
/// the interior, FlightHelmet and the Godot room along their paths, and on a one-mesh level's
/// eye-height walk with yaw sweeps and cuts, FN 0 and every frame's image equal to the
/// unculled one; no frame draws more triangles than the same technique without it, and each
/// run draws fewer. (The cluster comparison does not apply: a packed command's range names no
/// cluster; the images carry exactness.)
#[test]
fn triangle_culling_keeps_images_equal_and_draws_fewer_triangles() {
    let mut runs: Vec<(String, CameraPath)> = Vec::new();
    for spec in with_helmet_and_room(&["city:1500", "interior:800"]) {
        let scene = tilegraph_scene::load(&spec).unwrap();
        let p = path(&scene, 6);
        runs.push((spec, p));
    }
    let walk_spec = "interior:700@one-mesh";
    let walk_scene = tilegraph_scene::load(walk_spec).unwrap();
    runs.push((
        walk_spec.into(),
        CameraPath::eye_height_walk(&walk_scene.bounds(), 10, 7),
    ));
    for (spec, path) in &runs {
        let scene = with_clusters(spec);
        for culling in [Culling::FrustumClusters, Culling::HizTwoPhaseClusters] {
            let options = |triangles| RenderOptions {
                width: SIZE.0,
                height: SIZE.1,
                culling,
                triangle_culling: triangles,
                ..Default::default()
            };
            let clusters = check_with(None, &scene, options(false), path);
            let r = check_with(None, &scene, options(true), path);
            for (a, b) in clusters.frames.iter().zip(&r.frames) {
                assert_eq!(b.false_negatives, 0, "{spec} {culling:?} frame {}", b.frame);
                assert!(
                    b.image_equal,
                    "{spec} {culling:?} + triangles: frame {} differs in {} pixels",
                    b.frame, b.image_diff_pixels
                );
                assert!(
                    b.triangles_drawn <= a.triangles_drawn,
                    "{spec} {culling:?} frame {}: {} triangles with triangle culling, {} without",
                    b.frame,
                    b.triangles_drawn,
                    a.triangles_drawn
                );
            }
            println!(
                "{spec:<60} {:<20} triangles {:>9} -> {:>9}",
                r.technique, clusters.totals.triangles_drawn, r.totals.triangles_drawn
            );
            assert!(
                r.totals.triangles_drawn < clusters.totals.triangles_drawn,
                "{spec} {culling:?}: per-triangle culling removed no triangle"
            );
        }
    }
}
