//! A scene that moves while it is culled (lavapipe, validation on): movers slide out from
//! behind buildings and back, thin upright ones swing like doors, instances spawn in front of
//! the camera and despawn (tilegraph_scene::Motion). Every conservative technique — frustum,
//! two-phase HiZ, raster occlusion, same-frame queries, and the cluster techniques — culls no
//! visible instance and draws the unculled image bit for bit on every frame: with the camera
//! still (every newly visible instance was revealed by motion: the frame an object leaves an
//! occluder is the case two-phase culling exists for), and along a hard path of jumps and cuts;
//! deferred texturing, whose G-buffer both phases draw, likewise.

use tilegraph_e2e::{culling_features, gpu_with};
use tilegraph_passes::cull::Culling;
use tilegraph_passes::cullcheck::{cull_check_options, CheckExtras, CullCheck};
use tilegraph_passes::{RenderOptions, SceneRenderer, Technique};
use tilegraph_scene::{CameraPath, Motion, MotionParams, PathKey, Scene};

const SIZE: (u32, u32) = (160, 90);

const CONSERVATIVE: [Culling; 4] = [
    Culling::Frustum,
    Culling::HizTwoPhase,
    Culling::RasterOcclusion,
    Culling::OqConditional,
];

/// `frames` frames of one of the scene's path cameras, held still.
fn still(scene: &Scene, key: usize, frames: usize) -> CameraPath {
    let camera = scene.camera_path().keys()[key].camera;
    let keys = (0..frames)
        .map(|i| PathKey {
            camera,
            cut: i == 0,
        })
        .collect();
    CameraPath::new("still camera", keys).unwrap()
}

/// The scene's path: its first frames one after another, then every 17th frame (jumps), with
/// its cuts.
fn walk(scene: &Scene, frames: usize) -> CameraPath {
    let keys = scene.camera_path().keys();
    let mut picks: Vec<usize> = (0..6.min(keys.len())).collect();
    picks.extend((6..keys.len()).step_by(17));
    picks.truncate(frames);
    let selected = picks
        .iter()
        .map(|&i| PathKey {
            camera: keys[i].camera,
            cut: keys[i].cut && i > 0,
        })
        .collect();
    CameraPath::new("walk with jumps", selected).unwrap()
}

/// A third of the small instances move, a quarter of those turning mirrored for half their
/// period (each mesh's copy of reversed winding made on the first turn: with clusters
/// attached, new cluster tables).
fn motion() -> MotionParams {
    MotionParams {
        movers: 0.3,
        spawns: 6,
        seed: 7,
        mirrors: 0.25,
    }
}

fn check(g: &tilegraph_e2e::Gpu, scene: &Scene, path: &CameraPath, culling: Culling) -> CullCheck {
    check_shaded(g, scene, path, (Technique::Prepass, culling))
}

fn check_shaded(
    g: &tilegraph_e2e::Gpu,
    scene: &Scene,
    path: &CameraPath,
    (technique, culling): (Technique, Culling),
) -> CullCheck {
    check_options(g, scene, path, options(technique, culling))
}

/// The suite's render options: `technique`, `culling`, [`SIZE`].
fn options(technique: Technique, culling: Culling) -> RenderOptions {
    RenderOptions {
        technique,
        culling,
        width: SIZE.0,
        height: SIZE.1,
        ..Default::default()
    }
}

fn check_options(
    g: &tilegraph_e2e::Gpu,
    scene: &Scene,
    path: &CameraPath,
    options: RenderOptions,
) -> CullCheck {
    check_moving(g, scene, path, options, motion())
}

fn check_moving(
    g: &tilegraph_e2e::Gpu,
    scene: &Scene,
    path: &CameraPath,
    options: RenderOptions,
    motion: MotionParams,
) -> CullCheck {
    let extras = CheckExtras {
        motion: Some(motion),
        ..Default::default()
    };
    cull_check_options(g, scene, options, path, None, extras).unwrap()
}

fn assert_exact(what: &str, r: &CullCheck) {
    for f in &r.frames {
        assert_eq!(
            f.false_negatives, 0,
            "{what} {}: frame {} culled visible instances {:?}",
            r.technique, f.frame, f.false_negative_ids
        );
        assert!(
            f.image_equal,
            "{what} {}: frame {} differs from the unculled image in {} pixels ({} owned by drawn instances)",
            r.technique, f.frame, f.image_diff_pixels, f.image_diff_pixels_owner_drawn
        );
    }
    let t = &r.totals;
    println!(
        "{what:<28} {:<16} frames {:>2}  visible {:>5}  drawn {:>5}  FN {}  images equal {}/{}",
        r.technique,
        t.frames,
        t.visible,
        t.drawn,
        t.false_negatives,
        t.frames_image_equal,
        t.frames
    );
}

/// Per frame of `path`, the instances that own a pixel (the visibility buffer of everything),
/// with the scene moving; and the instances that move.
fn visible_sets(
    g: &tilegraph_e2e::Gpu,
    scene: &Scene,
    path: &CameraPath,
) -> (Vec<Vec<u32>>, Vec<u32>) {
    let mut world = scene.clone();
    let mut motion = Motion::new(scene, path, motion());
    let mut movers: Vec<u32> = motion.mover_ids().map(|i| i.0).collect();
    movers.sort_unstable();
    let options = RenderOptions {
        technique: Technique::Visbuf,
        capture_ids: true,
        width: SIZE.0,
        height: SIZE.1,
        ..Default::default()
    };
    let mut oracle = SceneRenderer::new(g, &world, options).unwrap();
    let mut sets = Vec::new();
    for (i, frame) in path.frames(SIZE.0 as f32 / SIZE.1 as f32).enumerate() {
        motion.apply(&mut world, i).unwrap();
        oracle.render_frame(g, &world, &frame).unwrap();
        let mut ids = oracle.read_instance_ids(g).unwrap().unwrap();
        ids.sort_unstable();
        ids.dedup();
        ids.retain(|&i| i != u32::MAX);
        sets.push(ids);
    }
    oracle.destroy(g);
    (sets, movers)
}

#[test]
fn objects_leaving_occluders_are_drawn_the_frame_they_appear() {
    let g = gpu_with(None, culling_features()).unwrap();
    let scene = tilegraph_scene::load("city:1500").unwrap();
    // Street level, the camera still: whatever comes into view, motion brought.
    let path = still(&scene, 0, 32);
    let (sets, movers) = visible_sets(&g, &scene, &path);
    let appeared: usize = sets
        .windows(2)
        .map(|w| {
            w[1].iter()
                .filter(|i| w[0].binary_search(i).is_err() && movers.binary_search(i).is_ok())
                .count()
        })
        .sum();
    assert!(
        appeared >= 8,
        "only {appeared} moving instances came into view: the motion shows too little"
    );
    println!("{appeared} moving instances came into view of a still camera over 32 frames");
    for culling in CONSERVATIVE {
        assert_exact("city, still camera", &check(&g, &scene, &path, culling));
    }
    // Deferred texturing draws its G-buffer in both phases: what moved into view in the late
    // phase is in it.
    let shaded = (Technique::DeferredTexturing, Culling::HizTwoPhase);
    let r = check_shaded(&g, &scene, &path, shaded);
    assert_exact("city, still camera", &r);
}

#[test]
fn conservative_techniques_stay_exact_along_a_walk_while_the_scene_moves() {
    let g = gpu_with(None, culling_features()).unwrap();
    for spec in ["city:1500", "interior:800", "maze:800"] {
        let scene = tilegraph_scene::load(spec).unwrap();
        let path = walk(&scene, 16);
        for culling in CONSERVATIVE {
            assert_exact(&format!("{spec}, walk"), &check(&g, &scene, &path, culling));
        }
    }
}

#[test]
fn cluster_techniques_stay_exact_while_the_scene_moves() {
    let g = gpu_with(None, culling_features()).unwrap();
    let scene = tilegraph_e2e::closed_spheres(6, 6, true);
    let path = walk(&scene, 10);
    for culling in [Culling::FrustumClusters, Culling::HizTwoPhaseClusters] {
        assert_exact("closed spheres, walk", &check(&g, &scene, &path, culling));
    }
    let shaded = (Technique::DeferredTexturing, Culling::HizTwoPhaseClusters);
    let r = check_shaded(&g, &scene, &path, shaded);
    assert_exact("closed spheres, walk", &r);
    // No sphere mirrored at build: every mover's first turn makes its mesh's copy (clusters
    // and cones turned) while the renderer runs, which then takes new cluster tables.
    let plain = tilegraph_e2e::closed_spheres(4, 4, false);
    let turning = MotionParams {
        mirrors: 1.0,
        ..motion()
    };
    for culling in [Culling::FrustumClusters, Culling::HizTwoPhaseClusters] {
        let options = options(Technique::Prepass, culling);
        let r = check_moving(&g, &plain, &walk(&plain, 10), options, turning);
        assert_exact("closed spheres turning mirrored", &r);
    }
    let mut turned = plain.clone();
    Motion::new(&plain, &walk(&plain, 10), turning)
        .apply(&mut turned, 0)
        .unwrap();
    assert!(
        turned.meshes().len() > plain.meshes().len(),
        "no copy was made: nothing turned"
    );
    // Per-triangle culling packs into the index buffer's tail while the scene moves.
    for culling in [Culling::FrustumClusters, Culling::HizTwoPhaseClusters] {
        let options = RenderOptions {
            triangle_culling: true,
            ..options(Technique::Prepass, culling)
        };
        let r = check_options(&g, &scene, &path, options);
        assert_exact("closed spheres, walk, triangle culling", &r);
    }
}

/// Instances coming and going leave cluster culling's history where it was: the cluster
/// bases follow in the same buffers (before, every spawn made the renderer's buffers anew,
/// waiting for the frames in flight and forgetting what was visible, and the next frame's
/// late phase drew whatever the empty early depth could not hide). So `hiz-2phase-clusters`,
/// whose early phase is `hiz-2phase`'s, draws no more triangles than `hiz-2phase` in any frame
/// of a walk at eye height while instances spawn and despawn, and stays exact. Its spawns
/// append slots, take freed ones in place and lay every slot out anew twice (the cluster
/// layout's debug log, `RUST_LOG=tilegraph_passes::cull::cluster_layout=debug`, names them).
#[test]
fn spawns_leave_the_cluster_history_as_it_was() {
    let g = gpu_with(None, culling_features()).unwrap();
    let mut scene = tilegraph_scene::load("forest:2000").unwrap();
    let (data, _) = tilegraph_scene::clusters::build(&scene).unwrap();
    scene.attach_clusters(data).unwrap();
    let walk = CameraPath::eye_height_walk(&scene.bounds(), 240, 16);
    let path = CameraPath::new("walk 16", walk.keys()[..24].to_vec()).unwrap();
    let run = |culling| {
        let options = RenderOptions {
            technique: Technique::Prepass,
            culling,
            width: 192,
            height: 108,
            ..Default::default()
        };
        let extras = CheckExtras {
            motion: Some(MotionParams {
                movers: 0.1,
                spawns: 12,
                seed: 1,
                mirrors: 0.0,
            }),
            ..Default::default()
        };
        cull_check_options(&g, &scene, options, &path, None, extras).unwrap()
    };
    let instances = run(Culling::HizTwoPhase);
    let clusters = run(Culling::HizTwoPhaseClusters);
    assert_exact("forest, walk with spawns", &instances);
    assert_exact("forest, walk with spawns", &clusters);
    tilegraph_e2e::assert_no_more_triangles("forest, walk with spawns", &instances, &clusters);
    for c in &clusters.frames {
        if let Some(cl) = &c.clusters {
            assert_eq!(
                cl.false_negatives, 0,
                "frame {}: visible clusters culled",
                c.frame
            );
        }
    }
    assert!(
        clusters.totals.triangles_drawn < instances.totals.triangles_drawn,
        "the clusters culled nothing more: {} against {} triangles",
        clusters.totals.triangles_drawn,
        instances.totals.triangles_drawn
    );
}

/// A million instances build, load, cull and render on lavapipe (small): two-phase HiZ draws
/// the unculled image while a thousand instances move every frame, and culls most of the city.
#[test]
fn a_million_instances_move_cull_and_render() {
    let g = gpu_with(None, culling_features()).unwrap();
    let mut scene = tilegraph_scene::load("city:1M").unwrap();
    assert_eq!(scene.instances().len(), 1_000_000);
    let path = walk(&scene, 3);
    let n = scene.instances().len();
    let movers: Vec<_> = (0..1000)
        .filter_map(|k| {
            let id = tilegraph_scene::InstanceId((k * n / 1000) as u32);
            Some((
                scene.instance_handle(id)?,
                scene.instances()[id.index()].transform,
            ))
        })
        .collect();
    let options = |culling| RenderOptions {
        technique: Technique::Prepass,
        culling,
        width: 96,
        height: 54,
        ..Default::default()
    };
    let mut culled = SceneRenderer::new(&g, &scene, options(Culling::HizTwoPhase)).unwrap();
    let mut unculled = SceneRenderer::new(&g, &scene, options(Culling::None)).unwrap();
    let mut last = None;
    for (i, frame) in path.frames(96.0 / 54.0).enumerate() {
        let moves: Vec<_> = movers
            .iter()
            .map(|(h, t)| {
                let mut t = *t;
                t.translation.y += i as f64 * 0.5;
                (*h, t)
            })
            .collect();
        scene.set_transforms(&moves).unwrap();
        last = Some(culled.render_frame(&g, &scene, &frame).unwrap());
        unculled.render_frame(&g, &scene, &frame).unwrap();
        assert!(
            culled.read_image(&g).unwrap() == unculled.read_image(&g).unwrap(),
            "frame {i}: the culled image differs"
        );
    }
    culled.finish(&g).unwrap();
    let drawn = culled.drawn_instances(&g).unwrap().unwrap().len();
    println!("1M city, 96x54: two-phase HiZ drew {drawn} instances; {last:?}");
    assert!(drawn > 0 && drawn < n / 10, "drew {drawn} of {n}");
    culled.destroy(&g);
    unculled.destroy(&g);
}

/// `scene-info`'s GPU memory is what a renderer allocates for the scene's buffers.
#[test]
fn the_memory_estimate_is_what_a_renderer_allocates() {
    let g = gpu_with(None, culling_features()).unwrap();
    let scene = tilegraph_scene::load("city:2k").unwrap();
    let options = RenderOptions {
        culling: Culling::HizTwoPhase,
        width: 64,
        height: 36,
        ..Default::default()
    };
    let r = SceneRenderer::new(&g, &scene, options).unwrap();
    let estimate =
        tilegraph_passes::scene_memory(&scene, tilegraph_vk::frames::DEFAULT_FRAMES_IN_FLIGHT, 0);
    assert_eq!(r.scene_memory(), estimate);
    assert!(estimate.bytes_per_instance() > 96.0, "{estimate:?}");
    r.destroy(&g);
}

/// `scene` built again: each mesh's vertices through `vertex`, each triangle's corners through
/// `triangle`, each instance's linear part through `linear`.
fn rebuilt(
    scene: &Scene,
    vertex: impl Fn(tilegraph_scene::Vertex) -> tilegraph_scene::Vertex,
    triangle: impl Fn([u32; 3]) -> [u32; 3],
    linear: impl Fn(glam::Mat3) -> glam::Mat3,
) -> Scene {
    use tilegraph_scene::{SceneBuilder, Transform};
    let mut b = SceneBuilder::new(format!("{} rebuilt", scene.name()));
    for m in scene.materials() {
        assert!(m.base_color_texture.is_none(), "an untextured scene");
        b.add_material(*m);
    }
    let meshes: Vec<_> = scene
        .meshes()
        .iter()
        .map(|m| {
            let first = m.vertex_offset as usize;
            let vertices: Vec<_> = scene.vertices()[first..first + m.vertex_count as usize]
                .iter()
                .map(|v| vertex(*v))
                .collect();
            let range = m.first_index as usize..(m.first_index + m.index_count) as usize;
            let indices: Vec<u32> = scene.indices()[range]
                .chunks_exact(3)
                .flat_map(|t| triangle([t[0], t[1], t[2]]))
                .collect();
            b.add_mesh(&vertices, &indices, m.material).unwrap()
        })
        .collect();
    for inst in scene.instances() {
        let t = Transform::new(linear(inst.transform.linear), inst.transform.translation);
        b.add_instance(t, meshes[inst.mesh.index()]).unwrap();
    }
    b.build(Some(scene.camera_path().clone())).unwrap()
}

/// Frames 1-3 of the scene's path (frame 0 drawn before `turn` changes the scene).
fn frames_drawn(
    g: &tilegraph_e2e::Gpu,
    scene: &Scene,
    culling: Culling,
    turn: impl FnOnce(&mut Scene),
) -> Vec<Vec<u8>> {
    let mut scene = scene.clone();
    let options = options(Technique::Prepass, culling);
    let mut r = SceneRenderer::new(g, &scene, options).unwrap();
    let mut images = Vec::new();
    let mut turn = Some(turn);
    for (i, frame) in scene
        .camera_path()
        .clone()
        .frames(SIZE.0 as f32 / SIZE.1 as f32)
        .take(4)
        .enumerate()
    {
        if i == 1 {
            if let Some(t) = turn.take() {
                t(&mut scene);
            }
        }
        r.render_frame(g, &scene, &frame).unwrap();
        if i > 0 {
            images.push(r.read_image(g).unwrap().pixels);
        }
    }
    r.destroy(g);
    images
}

/// A mirroring instance (negative determinant) draws what its mesh mirrored by hand draws
/// (positions and normals negated along x, every triangle turned, the instance's own
/// transform): the same image bit for bit, whether the scene was built so or every instance
/// turned mirroring between two frames of a running renderer (the meshes' copies made then).
/// Drawn as given, without the turn, the same geometry shows its inside: another image.
#[test]
fn a_mirroring_instance_draws_its_mesh_mirrored() {
    use glam::{Mat3, Vec3};
    use tilegraph_scene::{Transform, Vertex};
    let g = gpu_with(None, culling_features()).unwrap();
    let scene = tilegraph_scene::load("city:300").unwrap();
    let flip = Mat3::from_diagonal(Vec3::new(-1.0, 1.0, 1.0));
    let mirrored = |v: Vertex| Vertex {
        position: [-v.position[0], v.position[1], v.position[2]],
        normal: [-v.normal[0], v.normal[1], v.normal[2]],
        uv: v.uv,
    };
    let by_hand = rebuilt(&scene, mirrored, |[a, b, c]| [a, c, b], |l| l);
    let built = rebuilt(&scene, |v| v, |t| t, |l| l * flip);
    let inside_out = rebuilt(&scene, mirrored, |t| t, |l| l);
    let keep = |_: &mut Scene| {};
    let expected = frames_drawn(&g, &by_hand, Culling::None, keep);
    for culling in [Culling::None, Culling::HizTwoPhase] {
        assert_eq!(
            frames_drawn(&g, &built, culling, keep),
            expected,
            "{culling:?}"
        );
        let turned = frames_drawn(&g, &scene, culling, |s| {
            let moves: Vec<_> = (0..s.instances().len() as u32)
                .filter_map(|i| s.instance_handle(tilegraph_scene::InstanceId(i)))
                .map(|h| {
                    let t = s.instance(h).unwrap().transform;
                    (h, Transform::new(t.linear * flip, t.translation))
                })
                .collect();
            s.set_transforms(&moves).unwrap();
        });
        assert_eq!(turned, expected, "{culling:?}, turned while drawn");
    }
    assert_ne!(frames_drawn(&g, &inside_out, Culling::None, keep), expected);
}
