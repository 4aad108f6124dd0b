//! Several views in one frame on lavapipe (validation on): a main camera with three shadow
//! cascades, a second camera into its own target and an orthographic map view, declared on
//! one graph and submitted together — and each view's image equals rendering that view alone,
//! frame after frame, whatever its technique, culling and shadows (so a view's history, its
//! pyramid and last frame's visibility, is its own).

use glam::{DVec3, Vec3};
use tilegraph_cull::shadow::CasterCulling;
use tilegraph_e2e::gpu_with;
use tilegraph_passes::cull::Culling;
use tilegraph_passes::shadow::ShadowOptions;
use tilegraph_passes::{RenderOptions, SceneRenderer, Technique};
use tilegraph_scene::{Camera, CameraFrame, CameraPath, DepthConvention, Projection, Scene};
use tilegraph_vk::readback::RgbaImage;

fn shadows(cascades: u32, culling: CasterCulling) -> ShadowOptions {
    ShadowOptions {
        cascades,
        resolution: 256,
        culling,
        ..ShadowOptions::default()
    }
}

/// The main view: forward with pre-passes, three cascades, two-phase HiZ.
fn main_options() -> RenderOptions {
    RenderOptions {
        technique: Technique::Forward,
        width: 160,
        height: 90,
        depth_prepass: Some(true),
        culling: Culling::HizTwoPhase,
        shadows: shadows(3, CasterCulling::ReceiversHiz),
        ..Default::default()
    }
}

/// A second camera: the visibility buffer, single-phase HiZ (it reuses its own last frame),
/// two cascades of its own.
fn second_options() -> RenderOptions {
    RenderOptions {
        technique: Technique::Visbuf,
        width: 96,
        height: 64,
        culling: Culling::Hiz,
        shadows: shadows(2, CasterCulling::Receivers),
        clear_color: [0.1, 0.2, 0.3, 1.0],
        ..Default::default()
    }
}

/// A map: orthographic, from above, frustum culling, no shadows.
fn map_options() -> RenderOptions {
    RenderOptions {
        technique: Technique::Forward,
        width: 64,
        height: 64,
        culling: Culling::Frustum,
        ..Default::default()
    }
}

fn map_camera(scene: &Scene, around: DVec3) -> Camera {
    let b = scene.bounds();
    let height = b.max.y - b.min.y;
    Camera {
        eye: DVec3::new(around.x, b.max.y + 10.0, around.z),
        target: DVec3::new(around.x, b.min.y, around.z),
        up: Vec3::Z,
        projection: Projection::Orthographic {
            half_height: 40.0,
            near: 1.0,
            far: (height + 20.0) as f32,
            depth: DepthConvention::Reverse,
        },
    }
}

/// Frame `i` of `path` seen by a camera on it, `offset` keys ahead (wrapping: a cut).
fn path_frame(path: &CameraPath, i: usize, offset: usize, aspect: f32) -> CameraFrame {
    let k = (i + offset) % path.len();
    let key = path.keys()[k];
    let previous = (i > 0 && k > 0 && !key.cut).then(|| path.keys()[k - 1].camera);
    CameraFrame::new(i, key.camera, previous.as_ref(), aspect)
}

fn aspect(o: &RenderOptions) -> f32 {
    o.width as f32 / o.height as f32
}

/// The frames of one view rendered alone.
fn alone(scene: &Scene, options: RenderOptions, frames: &[CameraFrame]) -> Vec<RgbaImage> {
    let g = gpu_with(Some("lavapipe"), options.device_features()).unwrap();
    let mut r = SceneRenderer::new(&g, scene, options).unwrap();
    let images = frames
        .iter()
        .map(|f| {
            r.render_frame(&g, scene, f).unwrap();
            r.read_image(&g).unwrap()
        })
        .collect();
    r.destroy(&g);
    images
}

fn assert_same(what: &str, frame: usize, together: &RgbaImage, alone: &RgbaImage) {
    let differing = together
        .pixels
        .chunks_exact(4)
        .zip(alone.pixels.chunks_exact(4))
        .filter(|(a, b)| a != b)
        .count();
    assert_eq!(
        (together.width, together.height),
        (alone.width, alone.height)
    );
    assert_eq!(
        differing, 0,
        "{what}, frame {frame}: {differing} pixels differ from the view rendered alone"
    );
}

#[test]
fn three_views_in_one_graph_each_equal_to_rendering_it_alone() {
    let scene = tilegraph_scene::load("city:300").unwrap();
    let path = scene.camera_path().clone();
    let n = 6.min(path.len());
    let (main, second, map) = (main_options(), second_options(), map_options());
    let main_frames: Vec<_> = (0..n)
        .map(|i| path_frame(&path, i, 0, aspect(&main)))
        .collect();
    let second_frames: Vec<_> = (0..n)
        .map(|i| path_frame(&path, i, path.len() / 2, aspect(&second)))
        .collect();
    let map_frames: Vec<_> = main_frames
        .iter()
        .map(|f| CameraFrame::new(f.index, map_camera(&scene, f.camera.eye), None, 1.0))
        .collect();

    let mut features = main.device_features();
    features.required.extend(second.device_features().required);
    features.optional.extend(second.device_features().optional);
    let g = gpu_with(Some("lavapipe"), features).unwrap();
    let mut r = SceneRenderer::new(&g, &scene, main.clone()).unwrap();
    let v2 = r
        .add_view(&g, &scene, second.clone(), &second_frames[0].camera)
        .unwrap();
    let v3 = r
        .add_view(&g, &scene, map.clone(), &map_frames[0].camera)
        .unwrap();
    assert_eq!(r.view_count(), 3);
    let mut together = Vec::new();
    for i in 0..n {
        r.set_view_frame(v2, &second_frames[i]).unwrap();
        r.set_view_frame(v3, &map_frames[i]).unwrap();
        let report = r.render_frame(&g, &scene, &main_frames[i]).unwrap();
        if i == 0 {
            // One graph: every view's passes, the further views' named by their view, each
            // view's shadow maps in it.
            let names: Vec<&str> = report.plan.passes.iter().map(|p| p.name.as_str()).collect();
            for view in ["view1/", "view2/"] {
                assert!(names.iter().any(|p| p.starts_with(view)), "{names:?}");
            }
            assert!(names.iter().any(|p| p.starts_with("shadow")), "{names:?}");
            assert!(
                names.iter().any(|p| p.starts_with("view1/shadow")),
                "{names:?}"
            );
            assert!(
                !names.iter().any(|p| p.starts_with("view2/shadow")),
                "{names:?}"
            );
        }
        together.push((
            r.read_image(&g).unwrap(),
            r.read_view_image(&g, v2).unwrap(),
            r.read_view_image(&g, v3).unwrap(),
        ));
    }
    r.destroy(&g);
    if let Some(dir) = std::env::var_os("VIEWS_DUMP") {
        let dir = std::path::PathBuf::from(dir);
        for (name, img) in [
            ("main", &together[2].0),
            ("second", &together[2].1),
            ("map", &together[2].2),
        ] {
            tilegraph_e2e::golden::write_png(&dir.join(format!("{name}.png")), img).unwrap();
        }
    }

    let main_alone = alone(&scene, main, &main_frames);
    let second_alone = alone(&scene, second, &second_frames);
    let map_alone = alone(&scene, map, &map_frames);
    for (i, (m, s, p)) in together.iter().enumerate() {
        assert_same("main view", i, m, &main_alone[i]);
        assert_same("second camera", i, s, &second_alone[i]);
        assert_same("map", i, p, &map_alone[i]);
    }
    // The views see something: the test would pass vacuously on blank images.
    let colours = |img: &RgbaImage| {
        let mut c: Vec<&[u8]> = img.pixels.chunks_exact(4).collect();
        c.sort_unstable();
        c.dedup();
        c.len()
    };
    // (The map, orthographic from above, sees flat roofs and streets: few colours.)
    for (what, img, least) in [
        ("second view", &together[0].1, 16),
        ("map", &together[0].2, 2),
    ] {
        assert!(colours(img) > least, "{what}: {} colours", colours(img));
    }
}

#[test]
fn unknown_views_are_refused() {
    let scene = tilegraph_scene::load("city:50").unwrap();
    let g = gpu_with(Some("lavapipe"), Default::default()).unwrap();
    let mut r = SceneRenderer::new(&g, &scene, map_options()).unwrap();
    let camera = scene.camera_path().keys()[0].camera;
    let v = r.add_view(&g, &scene, map_options(), &camera).unwrap();
    assert!(r.set_view_camera(v, &camera, false).is_ok());
    let mut bad = camera;
    bad.eye = DVec3::splat(f64::NAN);
    assert!(r.set_view_camera(v, &bad, true).is_err());
    let mut other = SceneRenderer::new(&g, &scene, map_options()).unwrap();
    // A view of another renderer, past this one's views.
    let w = other.add_view(&g, &scene, map_options(), &camera).unwrap();
    let w2 = other.add_view(&g, &scene, map_options(), &camera).unwrap();
    assert_eq!(w.index(), 1);
    assert!(r.set_view_camera(w2, &camera, false).is_err());
    assert!(r.read_view_image(&g, w2).is_err());
    other.destroy(&g);
    r.destroy(&g);
}

/// A scene that outgrows the renderer's buffers mid-path (new buffers for every view, their
/// states made again) and moves every frame: the main view and a second camera still equal
/// rendering each alone through the same changes.
#[test]
fn views_follow_a_scene_that_grows_and_moves() {
    use tilegraph_scene::{InstanceFlags, MeshId};
    let base = tilegraph_scene::load("city:300").unwrap();
    let path = base.camera_path().clone();
    let n = 6.min(path.len());
    let main = RenderOptions {
        culling: Culling::HizTwoPhase,
        shadows: shadows(2, CasterCulling::Receivers),
        ..main_options()
    };
    let second = RenderOptions {
        culling: Culling::Hiz,
        ..second_options()
    };
    let main_frames: Vec<_> = (0..n)
        .map(|i| path_frame(&path, i, 0, aspect(&main)))
        .collect();
    let second_frames: Vec<_> = (0..n)
        .map(|i| path_frame(&path, i, 3, aspect(&second)))
        .collect();
    // Frame i's scene: from frame 2, twice the instance slots (copies of the first mesh along
    // the street the path looks down), every copy slid by i.
    let scene_at = |scene: &mut Scene, i: usize, spawned: &mut Vec<_>| {
        let slots = base.instances().len();
        if i == 2 {
            let mesh = scene.mesh_handle(MeshId(0)).unwrap();
            let at = base.instances()[0].transform;
            for k in 0..2 * slots {
                let mut t = at;
                t.translation.x += (k % 40) as f64 * 3.0;
                t.translation.z += (k / 40) as f64 * 3.0;
                spawned.push(
                    scene
                        .add_instance(mesh, t, InstanceFlags::default())
                        .unwrap(),
                );
            }
        }
        let moved: Vec<_> = spawned
            .iter()
            .map(|&h| {
                let mut t = scene.instance(h).unwrap().transform;
                t.translation.y += 0.25;
                (h, t)
            })
            .collect();
        scene.set_transforms(&moved).unwrap();
    };

    let mut features = main.device_features();
    features.required.extend(second.device_features().required);
    features.optional.extend(second.device_features().optional);
    let g = gpu_with(Some("lavapipe"), features).unwrap();
    let mut scene = base.clone();
    let mut spawned = Vec::new();
    let mut r = SceneRenderer::new(&g, &scene, main.clone()).unwrap();
    let v = r
        .add_view(&g, &scene, second.clone(), &second_frames[0].camera)
        .unwrap();
    let mut together = Vec::new();
    for i in 0..n {
        scene_at(&mut scene, i, &mut spawned);
        r.set_view_frame(v, &second_frames[i]).unwrap();
        r.render_frame(&g, &scene, &main_frames[i]).unwrap();
        together.push((r.read_image(&g).unwrap(), r.read_view_image(&g, v).unwrap()));
    }
    assert!(scene.instances().len() >= 3 * base.instances().len());
    r.destroy(&g);

    for (which, options, frames) in [(0, &main, &main_frames), (1, &second, &second_frames)] {
        let mut scene = base.clone();
        let mut spawned = Vec::new();
        let mut alone = SceneRenderer::new(&g, &scene, options.clone()).unwrap();
        for (i, f) in frames.iter().enumerate() {
            scene_at(&mut scene, i, &mut spawned);
            alone.render_frame(&g, &scene, f).unwrap();
            let image = alone.read_image(&g).unwrap();
            let got = if which == 0 {
                &together[i].0
            } else {
                &together[i].1
            };
            assert_same(
                if which == 0 {
                    "main view"
                } else {
                    "second camera"
                },
                i,
                got,
                &image,
            );
        }
        alone.destroy(&g);
    }
}

/// Two views that both cull per triangle pack into regions of their own of the index buffer's
/// tail: in one graph, each equals the view rendered alone.
#[test]
fn two_views_culling_per_triangle_each_equal_to_rendering_it_alone() {
    let mut scene = tilegraph_scene::load("city:300").unwrap();
    let (clusters, _) = tilegraph_scene::clusters::build(&scene).unwrap();
    scene.attach_clusters(clusters).unwrap();
    let path = scene.camera_path().clone();
    let n = 4.min(path.len());
    let triangles = |o: RenderOptions, culling| RenderOptions {
        culling,
        triangle_culling: true,
        shadows: ShadowOptions::default(),
        ..o
    };
    let main = triangles(main_options(), Culling::HizTwoPhaseClusters);
    let second = RenderOptions {
        // The visibility buffer has no cluster path.
        technique: Technique::Forward,
        ..triangles(second_options(), Culling::FrustumClusters)
    };
    let main_frames: Vec<_> = (0..n)
        .map(|i| path_frame(&path, i, 0, aspect(&main)))
        .collect();
    let second_frames: Vec<_> = (0..n)
        .map(|i| path_frame(&path, i, path.len() / 2, aspect(&second)))
        .collect();
    let g = gpu_with(Some("lavapipe"), tilegraph_e2e::culling_features()).unwrap();
    let mut r = SceneRenderer::new(&g, &scene, main.clone()).unwrap();
    let v2 = r
        .add_view(&g, &scene, second.clone(), &second_frames[0].camera)
        .unwrap();
    let mut together = Vec::new();
    for i in 0..n {
        r.set_view_frame(v2, &second_frames[i]).unwrap();
        r.render_frame(&g, &scene, &main_frames[i]).unwrap();
        together.push((
            r.read_image(&g).unwrap(),
            r.read_view_image(&g, v2).unwrap(),
        ));
    }
    r.destroy(&g);
    let main_alone = alone(&scene, main, &main_frames);
    let second_alone = alone(&scene, second, &second_frames);
    for (i, (m, s)) in together.iter().enumerate() {
        assert_same("main view, triangle culling", i, m, &main_alone[i]);
        assert_same("second camera, triangle culling", i, s, &second_alone[i]);
    }
}
