//! GPU culling against the exact oracle (lavapipe, validation on): for the conservative
//! techniques (frustum, two-phase HiZ, software occlusion) no visible instance is ever culled and the image equals
//! the unculled one on every frame; single-phase HiZ's and reprojection's false negatives after
//! fast motion are measured, not hidden, and held to bounds on walks (and to none on a still
//! camera).

use tilegraph_e2e::gpu_with;
use tilegraph_passes::cull::{CullBounds, Culling, DrawCount, GpuLists, IndirectDraw};
use tilegraph_passes::cullcheck::{cull_check, cull_check_options, CheckExtras, CullCheck};
use tilegraph_passes::{RenderOptions, SceneRenderer, Technique};
use tilegraph_scene::{CameraPath, PathKey, Scene};
use tilegraph_vk::{Feature, FeatureRequest};

const SIZE: (u32, u32) = (160, 90);

/// A short, hard test path from a scene's own path: its first frames, then every 23rd frame
/// (jumps the shader sees as very fast motion, without a cut flag), and both sides of each cut.
fn test_path(scene: &Scene, frames: usize) -> CameraPath {
    let keys = scene.camera_path().keys();
    let mut picks: Vec<usize> = (0..4.min(keys.len())).collect();
    for (i, k) in keys.iter().enumerate() {
        if k.cut && i > 0 {
            picks.extend([i - 1, i, (i + 1).min(keys.len() - 1)]);
        }
    }
    picks.extend((4..keys.len()).step_by(23));
    picks.sort_unstable();
    picks.dedup();
    picks.truncate(frames);
    let selected: Vec<PathKey> = picks
        .iter()
        .map(|&i| PathKey {
            camera: keys[i].camera,
            cut: keys[i].cut && i > 0,
        })
        .collect();
    CameraPath::new(format!("{} test path", scene.name()), selected).unwrap()
}

fn check(scene: &Scene, culling: Culling, frames: usize) -> CullCheck {
    let features = FeatureRequest::default().require([
        Feature::GeometryShader,
        Feature::DrawIndirectCount,
        Feature::MultiDrawIndirect,
    ]);
    let g = gpu_with(None, features).unwrap();
    let path = test_path(scene, frames);
    cull_check(
        &g,
        scene,
        culling,
        &path,
        SIZE,
        None,
        tilegraph_cull::NpotMode::EdgeAware,
    )
    .unwrap()
}

fn summary(r: &CullCheck) -> String {
    let t = &r.totals;
    format!(
        "{:<11} {:<9} frames {:>2}  visible {:>5}  drawn {:>6}  FN {:>3} ({} frames)  FP rate {:.3}  images equal {}/{}",
        r.technique, r.scene, t.frames, t.visible, t.drawn, t.false_negatives, t.frames_with_false_negatives, t.false_positive_rate, t.frames_image_equal, t.frames
    )
}

#[test]
fn conservative_techniques_never_cull_a_visible_instance() {
    let mut lines = Vec::new();
    let mut specs: Vec<String> = ["city:1500", "forest:800", "interior:800"]
        .map(String::from)
        .to_vec();
    match tilegraph_e2e::test_data("scenes/FlightHelmet/FlightHelmet.gltf") {
        Some(p) => specs.push(p.display().to_string()),
        None => eprintln!(
            "skipping FlightHelmet: {} not found",
            tilegraph_e2e::test_data_dir().display()
        ),
    }
    for spec in &specs {
        let scene = tilegraph_scene::load(spec).unwrap();
        let mut drawn = Vec::new();
        for culling in [
            Culling::Frustum,
            Culling::HizTwoPhase,
            Culling::SoftwareOcclusion,
        ] {
            let r = check(&scene, culling, 12);
            lines.push(summary(&r));
            drawn.push(r.totals.drawn);
            for f in &r.frames {
                assert_eq!(
                    f.false_negatives, 0,
                    "{spec} {}: frame {} culled visible instances {:?}",
                    r.technique, f.frame, f.false_negative_ids
                );
                assert!(f.image_equal, "{spec} {}: frame {} differs from the unculled image in {} pixels ({} owned by drawn instances)", r.technique, f.frame, f.image_diff_pixels, f.image_diff_pixels_owner_drawn);
                assert!(f.visible > 0, "{spec}: frame {} sees nothing", f.frame);
            }
            assert!(r.totals.drawn >= r.totals.visible);
        }
        // Software occlusion hides something in the scenes where buildings and walls occlude.
        if spec.starts_with("city") || spec.starts_with("interior") {
            assert!(
                drawn[2] < drawn[0],
                "{spec}: software occlusion drew {} of frustum's {}",
                drawn[2],
                drawn[0]
            );
        }
    }
    println!("{}", lines.join("\n"));
}

#[test]
fn occlusion_culling_draws_less_than_frustum_culling_in_the_city() {
    let scene = tilegraph_scene::load("city:1500").unwrap();
    let frustum = check(&scene, Culling::Frustum, 8);
    let two_phase = check(&scene, Culling::HizTwoPhase, 8);
    let single = check(&scene, Culling::Hiz, 8);
    println!(
        "{}\n{}\n{}",
        summary(&frustum),
        summary(&two_phase),
        summary(&single)
    );
    // From the third frame on, two-phase culling has history: it draws a fraction of what the
    // frustum keeps (street level: most of the city is behind the first buildings).
    let late = |r: &CullCheck| r.frames.iter().skip(2).map(|f| f.drawn).sum::<usize>();
    assert!(
        late(&two_phase) * 2 < late(&frustum),
        "two-phase {} vs frustum {}",
        late(&two_phase),
        late(&frustum)
    );
    // Single-phase HiZ is as selective, at the price of false negatives after jumps; whatever
    // they are, they are counted per frame. None on the first frame (no history) nor after a
    // camera cut (the previous pyramid shows another view: that frame is frustum-culled only).
    assert!(single.frames.iter().any(|f| f.cut), "the path has a cut");
    for f in single.frames.iter().filter(|f| f.cut || f.frame == 0) {
        assert_eq!(f.false_negatives, 0, "frame {} (cut {})", f.frame, f.cut);
    }
    assert!(late(&single) * 2 < late(&frustum));
}

/// Depth reprojection (not conservative, measured): last frame's depth moved into this frame's
/// view culls about as much as single-phase HiZ; its misses are counted per frame, and a frame
/// without a miss draws the unculled image. The first frame (no depth yet) and the frame after
/// a cut are frustum-culled only.
#[test]
fn reprojected_depth_culls_and_its_misses_are_counted() {
    let scene = tilegraph_scene::load("city:1500").unwrap();
    let frustum = check(&scene, Culling::Frustum, 8);
    let reproject = check(&scene, Culling::Reproject, 8);
    println!("{}\n{}", summary(&frustum), summary(&reproject));
    let late = |r: &CullCheck| r.frames.iter().skip(2).map(|f| f.drawn).sum::<usize>();
    assert!(
        late(&reproject) * 2 < late(&frustum),
        "reproject {} vs frustum {}",
        late(&reproject),
        late(&frustum)
    );
    for f in &reproject.frames {
        if f.cut || f.frame == 0 {
            assert_eq!(f.false_negatives, 0, "frame {} (cut {})", f.frame, f.cut);
        }
        if f.false_negatives == 0 {
            assert!(
                f.image_equal,
                "frame {}: no miss, yet the image differs",
                f.frame
            );
        }
    }
    let fn_total: usize = reproject.frames.iter().map(|f| f.false_negatives).sum();
    assert_eq!(fn_total, reproject.totals.false_negatives);
}

/// Extremes on the GPU path: a world 10^6 m from the origin (camera-relative transforms), odd
/// and tiny viewports (non-power-of-two pyramids down to 1x1) — no visible instance culled, and
/// every frame equals the unculled one.
#[test]
fn extremes_keep_two_phase_culling_conservative() {
    let features = FeatureRequest::default().require([
        Feature::GeometryShader,
        Feature::DrawIndirectCount,
        Feature::MultiDrawIndirect,
    ]);
    let mut scene = tilegraph_scene::load("city:800").unwrap();
    let near_origin = {
        let g = gpu_with(None, features.clone()).unwrap();
        cull_check(
            &g,
            &scene,
            Culling::HizTwoPhase,
            &test_path(&scene, 6),
            SIZE,
            None,
            tilegraph_cull::NpotMode::EdgeAware,
        )
        .unwrap()
    };
    scene.translate(glam::DVec3::new(1.0e6, 0.0, -1.0e6));
    let mut lines = vec![summary(&near_origin)];
    for (size, mode) in [
        (SIZE, tilegraph_cull::NpotMode::EdgeAware),
        ((27, 13), tilegraph_cull::NpotMode::EdgeAware),
        ((27, 13), tilegraph_cull::NpotMode::PadToPow2),
        ((1, 1), tilegraph_cull::NpotMode::EdgeAware),
        ((3, 3), tilegraph_cull::NpotMode::PadToPow2),
    ] {
        let g = gpu_with(None, features.clone()).unwrap();
        let r = cull_check(
            &g,
            &scene,
            Culling::HizTwoPhase,
            &test_path(&scene, 6),
            size,
            None,
            mode,
        )
        .unwrap();
        lines.push(format!(
            "at 1e6 m, {}x{} {mode:?}: {}",
            size.0,
            size.1,
            summary(&r)
        ));
        for f in &r.frames {
            assert_eq!(
                f.false_negatives, 0,
                "{size:?} {mode:?}: frame {} culled {:?}",
                f.frame, f.false_negative_ids
            );
            assert!(
                f.image_equal,
                "{size:?} {mode:?}: frame {} differs from the unculled image in {} pixels ({} owned by drawn instances)",
                f.frame, f.image_diff_pixels, f.image_diff_pixels_owner_drawn
            );
        }
        if size == SIZE {
            // Far from the origin the view is the same: the same instances are visible.
            for (a, b) in r.frames.iter().zip(&near_origin.frames) {
                assert!(
                    a.visible.abs_diff(b.visible) <= 1,
                    "frame {}: {} visible at 1e6 m vs {} at the origin",
                    a.frame,
                    a.visible,
                    b.visible
                );
            }
        }
    }
    println!("{}", lines.join("\n"));
}

/// The knobs of what culling builds: the pyramid at half and quarter resolution (its finest
/// level reduced straight from the depth) and sphere bounds (tangent rects in the shader) stay
/// conservative — FN 0 and images equal — on the test scenes, and at the extremes (10^6 m
/// from the origin, odd and 1x1 viewports, both NPOT modes).
#[test]
fn pyramid_resolution_and_sphere_bounds_stay_conservative() {
    let features = FeatureRequest::default().require([
        Feature::GeometryShader,
        Feature::DrawIndirectCount,
        Feature::MultiDrawIndirect,
    ]);
    let run = |scene: &Scene,
               culling: Culling,
               base: u32,
               bounds: CullBounds,
               size: (u32, u32),
               mode: tilegraph_cull::NpotMode,
               frames: usize| {
        let g = gpu_with(None, features.clone()).unwrap();
        let options = RenderOptions {
            width: size.0,
            height: size.1,
            culling,
            hiz_mode: mode,
            hiz_base_level: base,
            cull_bounds: bounds,
            ..Default::default()
        };
        let path = test_path(scene, frames);
        let r =
            cull_check_options(&g, scene, options, &path, None, CheckExtras::default()).unwrap();
        let what = format!(
            "{} {} base level {base} {} {}x{} {mode:?}",
            r.scene,
            r.technique,
            bounds.name(),
            size.0,
            size.1
        );
        for f in &r.frames {
            assert_eq!(
                f.false_negatives, 0,
                "{what}: frame {} culled {:?}",
                f.frame, f.false_negative_ids
            );
            assert!(
                f.image_equal,
                "{what}: frame {} differs from the unculled image in {} pixels ({} owned by drawn instances)",
                f.frame, f.image_diff_pixels, f.image_diff_pixels_owner_drawn
            );
        }
        (r.totals.drawn, format!("{what}: {}", summary(&r)))
    };
    let edge = tilegraph_cull::NpotMode::EdgeAware;
    let mut lines = Vec::new();
    let mut frustum_drawn = Vec::new();
    for spec in ["city:1500", "forest:800"] {
        let scene = tilegraph_scene::load(spec).unwrap();
        for bounds in [CullBounds::Aabb, CullBounds::Sphere] {
            let (drawn, line) = run(&scene, Culling::Frustum, 0, bounds, SIZE, edge, 8);
            frustum_drawn.push(drawn);
            lines.push(line);
        }
        for (culling, base, bounds) in [
            (Culling::HizTwoPhase, 0, CullBounds::Sphere),
            (Culling::HizTwoPhase, 1, CullBounds::Aabb),
            (Culling::HizTwoPhase, 2, CullBounds::Sphere),
        ] {
            lines.push(run(&scene, culling, base, bounds, SIZE, edge, 8).1);
        }
    }
    // The city's buildings are axis-aligned boxes: their spheres are looser, and the knob shows.
    assert!(
        frustum_drawn[1] > frustum_drawn[0],
        "city frustum: sphere drew {}, box {}",
        frustum_drawn[1],
        frustum_drawn[0]
    );
    let mut far = tilegraph_scene::load("city:800").unwrap();
    far.translate(glam::DVec3::new(1.0e6, 0.0, -1.0e6));
    for (size, mode, base) in [
        ((27, 13), edge, 1),
        ((27, 13), tilegraph_cull::NpotMode::PadToPow2, 2),
        ((1, 1), edge, 2),
        ((3, 3), tilegraph_cull::NpotMode::PadToPow2, 1),
    ] {
        lines.push(
            run(
                &far,
                Culling::HizTwoPhase,
                base,
                CullBounds::Sphere,
                size,
                mode,
                6,
            )
            .1,
        );
    }
    println!("{}", lines.join("\n"));
}

/// A path whose frames change the depth convention (allowed per frame in camera-path JSON):
/// the pyramid must be reduced in the convention of the depth it is built from, and
/// single-phase HiZ must not test one frame's boxes against a pyramid of the other convention.
#[test]
fn frames_that_switch_depth_convention_stay_conservative() {
    use tilegraph_scene::{DepthConvention, Projection};
    let features = FeatureRequest::default().require([
        Feature::GeometryShader,
        Feature::DrawIndirectCount,
        Feature::MultiDrawIndirect,
    ]);
    let scene = tilegraph_scene::load("city:800").unwrap();
    let base = test_path(&scene, 12);
    let keys: Vec<PathKey> = base
        .keys()
        .iter()
        .enumerate()
        .map(|(i, k)| {
            let mut camera = k.camera;
            if i % 2 == 1 {
                if let Projection::Perspective {
                    fov_y_rad, near, ..
                } = camera.projection
                {
                    camera.projection = Projection::Perspective {
                        fov_y_rad,
                        near,
                        far: Some(5000.0),
                        depth: DepthConvention::Standard,
                    };
                }
            }
            PathKey { camera, cut: k.cut }
        })
        .collect();
    let path = CameraPath::new("switching depth", keys).unwrap();
    let mut lines = Vec::new();
    for culling in [Culling::HizTwoPhase, Culling::Hiz] {
        let g = gpu_with(None, features.clone()).unwrap();
        let r = cull_check(
            &g,
            &scene,
            culling,
            &path,
            SIZE,
            None,
            tilegraph_cull::NpotMode::EdgeAware,
        )
        .unwrap();
        lines.push(summary(&r));
        for f in &r.frames {
            // Single-phase HiZ may miss what motion uncovers; never what a convention change
            // would: the frames here alternate conventions, so every frame after the first is
            // tested against nothing (two-phase: against its own depth).
            assert_eq!(
                f.false_negatives, 0,
                "{culling:?}: frame {} culled {:?}",
                f.frame, f.false_negative_ids
            );
        }
    }
    println!("{}", lines.join("\n"));
}

/// A scene with nothing but blended geometry (a glTF of glass panes): nothing writes depth
/// before the pyramid, so two-phase culling has no occluders. The frame must still render
/// (it failed with a read of the never-written depth), every culling technique alike.
#[test]
fn culling_a_scene_of_only_blended_geometry_renders() {
    use tilegraph_passes::{RenderOptions, SceneRenderer, Technique};
    use tilegraph_scene::{Material, MaterialClass, SceneBuilder, Transform, Vertex};
    let mut b = SceneBuilder::new("glass");
    let glass = b.add_material(Material {
        base_color: [0.2, 0.5, 1.0, 0.5],
        class: MaterialClass::Blended,
        double_sided: true,
        base_color_texture: None,
        engine_material: None,
    });
    let v = |x: f32, y: f32| Vertex {
        position: [x, y, 0.0],
        normal: [0.0, 0.0, 1.0],
        uv: [0.0; 2],
    };
    let pane = b
        .add_mesh(
            &[v(-1.0, -1.0), v(1.0, -1.0), v(1.0, 1.0), v(-1.0, 1.0)],
            &[0, 1, 2, 0, 2, 3],
            glass,
        )
        .unwrap();
    for z in [-3.0, -5.0] {
        b.add_instance(
            Transform::from_translation(glam::DVec3::new(0.0, 0.0, z)),
            pane,
        )
        .unwrap();
    }
    let scene = b.build(None).unwrap();
    let features = FeatureRequest::default().require([
        Feature::GeometryShader,
        Feature::DrawIndirectCount,
        Feature::MultiDrawIndirect,
        Feature::FragmentStoresAndAtomics,
    ]);
    for culling in [
        Culling::Frustum,
        Culling::Hiz,
        Culling::HizTwoPhase,
        Culling::RasterOcclusion,
    ] {
        for technique in [Technique::Forward, Technique::Prepass] {
            let g = gpu_with(
                None,
                RenderOptions {
                    technique,
                    ..Default::default()
                }
                .device_features()
                .require(features.required.iter().copied()),
            )
            .unwrap();
            let mut r = SceneRenderer::new(
                &g,
                &scene,
                RenderOptions {
                    technique,
                    width: SIZE.0,
                    height: SIZE.1,
                    culling,
                    ..Default::default()
                },
            )
            .unwrap();
            let cam = scene.camera_path().camera(0).unwrap();
            for _ in 0..2 {
                if let Err(e) = r.render(&g, &scene, &cam) {
                    panic!("{culling:?} {technique:?}: {e}");
                }
            }
            r.finish(&g).unwrap();
            r.destroy(&g);
        }
    }
}

/// The lists of one two-phase HiZ frame sequence on a device forced to `profile`.
fn lists_along_path(profile: Option<&str>, scene: &Scene, path: &CameraPath) -> Vec<GpuLists> {
    let features = FeatureRequest::default().require([
        Feature::GeometryShader,
        Feature::DrawIndirectCount,
        Feature::MultiDrawIndirect,
    ]);
    let g = gpu_with(profile, features).unwrap();
    let options = RenderOptions {
        technique: Technique::Prepass,
        culling: Culling::HizTwoPhase,
        width: SIZE.0,
        height: SIZE.1,
        ..Default::default()
    };
    let mut r = SceneRenderer::new(&g, scene, options).unwrap();
    let aspect = SIZE.0 as f32 / SIZE.1 as f32;
    let mut out = Vec::new();
    for index in 0..path.len() {
        let frame = path.frame(index, aspect).unwrap();
        r.render_frame(&g, scene, &frame).unwrap();
        out.push(r.gpu_lists(&g).unwrap().unwrap());
    }
    r.destroy(&g);
    out
}

/// Ordered compaction: each list's commands cover survivors only (with the GPU draw count) and
/// draw them in the unculled order; a profile without `drawIndirectCount` (forced on lavapipe)
/// draws one command per group, culled groups empty, and the same instances in the same order.
#[test]
fn compacted_lists_keep_the_unculled_order_with_either_draw_count() {
    let scene = tilegraph_scene::load("city:1500").unwrap();
    let path = test_path(&scene, 6);
    let counted = lists_along_path(None, &scene, &path);
    let fixed = lists_along_path(Some("mali-valhall"), &scene, &path);
    let mut empty_groups = 0;
    for (frame, (c, f)) in counted.iter().zip(&fixed).enumerate() {
        assert_eq!(c.draw_count, DrawCount::Gpu);
        assert!(matches!(f.draw_count, DrawCount::Fixed { .. }));
        for (list, (cl, fl)) in c.lists.iter().zip(&f.lists).enumerate() {
            assert!(
                cl.iter().all(|d| !d.instances.is_empty()),
                "frame {frame} list {list}: the draw count covers an empty command"
            );
            assert!(fl.len() >= cl.len());
            empty_groups += fl.iter().filter(|d| d.instances.is_empty()).count();
            let ids = |l: &[IndirectDraw]| -> Vec<u32> {
                l.iter().flat_map(|d| d.instances.iter().copied()).collect()
            };
            assert_eq!(ids(cl), ids(fl), "frame {frame} list {list}");
            // The unculled order: entries strictly increase along each command (a bucket's
            // survivors in entry order; the commands follow the frame's bucket order), and
            // every entry is the list's.
            let list_phase0 = (list % 4) as u32;
            for d in cl {
                let entries: Vec<u32> = d.instances.iter().map(|&i| c.order[i as usize]).collect();
                assert!(
                    entries.windows(2).all(|w| w[0] < w[1]),
                    "frame {frame} list {list}: survivors out of the unculled order"
                );
                assert!(entries.iter().all(|e| *e / c.stride == list_phase0));
            }
        }
    }
    assert!(
        empty_groups > 0,
        "occlusion culls whole groups on the street path"
    );
}

/// Per-frame stats without a stall: a frame's report carries what the newest completed frame
/// drew and culled on the GPU, read from a per-slot copy of the draw counts. With a still camera
/// every frame draws the same set, so the lagged counts equal the last frame's read back.
#[test]
fn frame_reports_carry_the_gpu_culling_counts_without_waiting() {
    let scene = tilegraph_scene::load("city:1500").unwrap();
    let features =
        FeatureRequest::default().want([Feature::DrawIndirectCount, Feature::MultiDrawIndirect]);
    for (profile, culling) in [
        (None, Culling::Frustum),
        (None, Culling::HizTwoPhase),
        (Some("mali-valhall"), Culling::HizTwoPhase),
    ] {
        let g = gpu_with(profile, features.clone()).unwrap();
        let options = RenderOptions {
            technique: Technique::Prepass,
            culling,
            width: SIZE.0,
            height: SIZE.1,
            ..Default::default()
        };
        let mut r = SceneRenderer::new(&g, &scene, options).unwrap();
        let camera = scene.camera_path().camera(0).unwrap();
        let mut reports = Vec::new();
        for _ in 0..6 {
            reports.push(r.render(&g, &scene, &camera).unwrap());
        }
        // The first frame has nothing completed to report.
        assert_eq!(reports[0].gpu_culling, None);
        let last = reports
            .last()
            .unwrap()
            .gpu_culling
            .expect("counts of a completed frame");
        assert!(last.frame >= 3 && last.frame < 6, "frame {}", last.frame);
        let drawn = r.drawn_instances(&g).unwrap().unwrap();
        let lists = r.gpu_lists(&g).unwrap().unwrap();
        let commands: usize = lists.lists[..4].iter().map(Vec::len).sum();
        assert_eq!(last.instances as usize, drawn.len(), "{culling:?}");
        assert_eq!(last.commands as usize, commands, "{culling:?}");
        let gpu_instances = lists.order.iter().filter(|&&o| o != u32::MAX).count();
        assert_eq!((last.instances + last.culled) as usize, gpu_instances);
        assert!(last.culled > 0, "{culling:?} culls part of the city");
        r.destroy(&g);
    }
}

/// The techniques that may miss — single-phase HiZ and depth reprojection, which test against
/// last frame's depth, and occlusion queries, whose answers are a frame late — are bounded, not
/// only measured: along walks at eye height with yaw
/// sweeps and hard cuts (city and interior) their false-negative rate stays under bounds set
/// from measured rates with headroom ([`fn_bounds`]), no frame misses more
/// than a share of what it sees, the first frame and the frames after cuts miss nothing; and on
/// a still camera they converge: from the second frame on nothing is missed and every image
/// equals the unculled one.
#[test]
fn techniques_that_may_miss_are_bounded_and_converge() {
    let features = tilegraph_e2e::culling_features();
    let mut lines = Vec::new();
    for spec in ["city:1500", "interior:800"] {
        let scene = tilegraph_scene::load(spec).unwrap();
        let walk = CameraPath::eye_height_walk(&scene.bounds(), 24, 5);
        let keys = scene.camera_path().keys();
        let still = CameraPath::new(
            format!("{spec} still"),
            vec![
                PathKey {
                    camera: keys[keys.len() / 3].camera,
                    cut: false,
                };
                4
            ],
        )
        .unwrap();
        for culling in [Culling::Hiz, Culling::Reproject, Culling::Oq] {
            let g = gpu_with(None, features.clone()).unwrap();
            let edge = tilegraph_cull::NpotMode::EdgeAware;
            let r = cull_check(&g, &scene, culling, &walk, SIZE, None, edge).unwrap();
            let t = &r.totals;
            let rate = t.false_negatives as f64 / t.visible.max(1) as f64;
            let worst = r
                .frames
                .iter()
                .map(|f| f.false_negatives as f64 / f.visible.max(1) as f64)
                .fold(0.0, f64::max);
            lines.push(format!(
                "{spec} walk {}: FN rate {rate:.4} ({} of {} visible), worst frame {worst:.3}",
                culling.name(),
                t.false_negatives,
                t.visible
            ));
            let (rate_bound, frame_bound) = fn_bounds(spec, culling);
            assert!(
                rate <= rate_bound,
                "{} (bound {rate_bound})",
                lines.last().unwrap()
            );
            assert!(
                worst <= frame_bound,
                "{} (bound {frame_bound})",
                lines.last().unwrap()
            );
            for f in r.frames.iter().filter(|f| f.cut || f.frame == 0) {
                assert_eq!(
                    f.false_negatives, 0,
                    "{spec} {culling:?}: frame {}",
                    f.frame
                );
            }
            let s = cull_check(&g, &scene, culling, &still, SIZE, None, edge).unwrap();
            for f in s.frames.iter().skip(1) {
                assert_eq!(
                    f.false_negatives, 0,
                    "{spec} {culling:?} still camera: frame {} culled {:?}",
                    f.frame, f.false_negative_ids
                );
                assert!(
                    f.image_equal,
                    "{spec} {culling:?} still camera: frame {} differs in {} pixels",
                    f.frame, f.image_diff_pixels
                );
            }
        }
    }
    println!("{}", lines.join("\n"));
}

/// Bounds of [`techniques_that_may_miss_are_bounded_and_converge`]: over the walk, the share of
/// visible instances missed, and the largest share one frame misses — about twice what lavapipe
/// measured at `5deef50` (city: 1 of 712 visible missed by each, worst frames 0.032, 0.027 and
/// 0.032 for `oq`; interior: `hiz` 13 of 101, worst frame 0.625 of a frame that sees 8;
/// `reproject` and `oq` none). The
/// frames are deterministic on lavapipe: a change in what is missed shows here first.
fn fn_bounds(spec: &str, culling: Culling) -> (f64, f64) {
    match (spec.starts_with("city"), culling) {
        (true, _) => (0.005, 0.08),
        (false, Culling::Hiz) => (0.25, 0.8),
        (false, _) => (0.03, 0.25),
    }
}
