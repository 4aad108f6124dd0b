//! An engine's own material drawing tilegraph's culled lists (lavapipe, validation on): shaders
//! of its own through `shaders/include/tilegraph_instance.glsl` (test_engine.vert/.frag), a
//! pipeline layout with tilegraph's scene set as set 0 and a set of its own bound by its bind
//! callback. The city through `none` and `hiz-2phase` gives equal images frame by frame, with the
//! engine's depth pre-pass shaders and without (tilegraph's pre-pass, then the engine's colour
//! testing EQUAL against it), and the engine's shading really is what is drawn; the cluster
//! techniques draw it group by group, images equal to the unculled frame's.

use std::rc::Rc;

use tilegraph_e2e::gpu_with;
use tilegraph_passes::materials::{
    EngineMaterial, EngineResolve, MaterialPass, MaterialShaders, ShaderCode,
};
use tilegraph_passes::{RenderOptions, SceneRenderer};
use tilegraph_profile::MemoryUse;
use tilegraph_scene::{MaterialClass, MaterialId, Scene};
use tilegraph_vk::ash::vk;
use tilegraph_vk::pipeline::{allocate_set, create_pipeline_layout, create_set_layout};
use tilegraph_vk::readback::RgbaImage;
use tilegraph_vk::{Buffer, Context};

const VS: &[u8] = include_bytes!("../../shaders/spv/test_engine.vert.spv");
const FS: &[u8] = include_bytes!("../../shaders/spv/test_engine.frag.spv");
const RS: &[u8] = include_bytes!("../../shaders/spv/test_engine_resolve.frag.spv");

/// What the engine owns for its material: its set's layout, pool, set and uniform buffer, and
/// the pipeline layouts (raster: the scene set, then its set; resolve, with a visibility
/// buffer: the scene set, tilegraph's resolve set, then its set).
struct EngineSide {
    set_layout: vk::DescriptorSetLayout,
    layout: vk::PipelineLayout,
    resolve_layout: Option<vk::PipelineLayout>,
    pool: vk::DescriptorPool,
    set: vk::DescriptorSet,
    tint: Buffer,
}

impl EngineSide {
    fn new(ctx: &Context, r: &SceneRenderer) -> EngineSide {
        let scene_set_layout = r.scene_set_layout();
        let set_layout = create_set_layout(
            ctx,
            &[(
                0,
                vk::DescriptorType::UNIFORM_BUFFER,
                vk::ShaderStageFlags::FRAGMENT,
            )],
        )
        .unwrap();
        let layout = create_pipeline_layout(ctx, &[scene_set_layout, set_layout], None).unwrap();
        let resolve_layout = r.resolve_set_layout().map(|resolve_set| {
            create_pipeline_layout(ctx, &[scene_set_layout, resolve_set, set_layout], None).unwrap()
        });
        let sizes = [vk::DescriptorPoolSize {
            ty: vk::DescriptorType::UNIFORM_BUFFER,
            descriptor_count: 1,
        }];
        let info = vk::DescriptorPoolCreateInfo::default()
            .max_sets(1)
            .pool_sizes(&sizes);
        // SAFETY: valid create info.
        let pool = unsafe { ctx.device.create_descriptor_pool(&info, None) }.unwrap();
        let set = allocate_set(ctx, pool, set_layout).unwrap();
        let mut tint = ctx
            .create_buffer(
                "engine tint",
                16,
                vk::BufferUsageFlags::UNIFORM_BUFFER,
                MemoryUse::Streaming,
            )
            .unwrap();
        let rgba: [f32; 4] = [1.0, 0.85, 0.7, 1.0];
        ctx.write_mapped(&mut tint, 0, bytemuck_bytes(&rgba))
            .unwrap();
        tilegraph_vk::pipeline::write_buffer_set(
            ctx,
            set,
            &[(0, vk::DescriptorType::UNIFORM_BUFFER, tint.raw)],
        );
        EngineSide {
            set_layout,
            layout,
            resolve_layout,
            pool,
            set,
            tint,
        }
    }

    fn destroy(self, ctx: &Context) {
        // SAFETY: the GPU is idle; the renderer that used them is destroyed.
        unsafe {
            ctx.device.destroy_descriptor_pool(self.pool, None);
            ctx.device.destroy_pipeline_layout(self.layout, None);
            if let Some(l) = self.resolve_layout {
                ctx.device.destroy_pipeline_layout(l, None);
            }
            ctx.device
                .destroy_descriptor_set_layout(self.set_layout, None);
        }
        ctx.destroy_buffer(self.tint);
    }
}

fn bytemuck_bytes(v: &[f32; 4]) -> &[u8] {
    // SAFETY: f32s are plain bytes; the slice covers exactly the array.
    unsafe { std::slice::from_raw_parts(v.as_ptr().cast::<u8>(), 16) }
}

fn code(name: &str, spirv: &[u8]) -> ShaderCode {
    ShaderCode {
        name: name.into(),
        spirv: spirv.to_vec(),
    }
}

/// The engine's material: colour always, depth pre-pass shaders when `depth`, its resolve when
/// the renderer has a visibility buffer.
fn material(side: &EngineSide, depth: bool) -> EngineMaterial {
    let (layout, set, resolve_layout) = (side.layout, side.set, side.resolve_layout);
    let binds = Rc::new(std::cell::Cell::new(0u32));
    let counter = Rc::clone(&binds);
    EngineMaterial {
        name: "toon".into(),
        layout,
        depth: depth.then(|| MaterialShaders {
            vertex: code("test_engine.vert", VS),
            fragment: None,
        }),
        color: Some(MaterialShaders {
            vertex: code("test_engine.vert", VS),
            fragment: Some(code("test_engine.frag", FS)),
        }),
        resolve: resolve_layout.map(|layout| EngineResolve {
            fragment: code("test_engine_resolve.frag", RS),
            layout,
        }),
        bind: Box::new(move |ctx, cb, pass| {
            counter.set(counter.get() + 1);
            // In a resolve the engine's set is set 2 (set 1 is tilegraph's).
            let (layout, index) = match (pass, resolve_layout) {
                (MaterialPass::Resolve, Some(l)) => (l, 2),
                _ => (layout, 1),
            };
            // SAFETY: recording; the set and layout live until the renderer is destroyed.
            unsafe {
                ctx.device.cmd_bind_descriptor_sets(
                    cb,
                    vk::PipelineBindPoint::GRAPHICS,
                    layout,
                    index,
                    &[set],
                    &[],
                )
            };
        }),
    }
}

/// The city with its opaque materials drawn by engine material 0.
fn city_with_engine_materials() -> Scene {
    city_with_engine_material_every(1)
}

/// The city with every `step`-th of its opaque materials drawn by engine material 0 (2: each
/// list alternates between the engine's pipeline and tilegraph's).
fn city_with_engine_material_every(step: usize) -> Scene {
    let mut scene = tilegraph_scene::load("city:400").unwrap();
    let opaque: Vec<MaterialId> = scene
        .materials()
        .iter()
        .enumerate()
        .filter(|(_, m)| m.class == MaterialClass::Opaque)
        .map(|(i, _)| MaterialId(i as u32))
        .collect();
    assert!(opaque.len() >= step, "{} opaque materials", opaque.len());
    for id in opaque.into_iter().step_by(step) {
        scene.set_engine_material(id, Some(0)).unwrap();
    }
    scene
}

/// [`city_with_engine_material_every`] 2, its clusters attached.
fn clustered_city_with_engine_materials() -> Scene {
    let mut scene = city_with_engine_material_every(2);
    let (data, _) = tilegraph_scene::clusters::build(&scene).unwrap();
    scene.attach_clusters(data).unwrap();
    scene
}

/// What rendering `scene`'s first frame under `options` gives, engine material 0 registered
/// (its colour shaders only).
fn first_frame(scene: &Scene, options: RenderOptions) -> Result<(), tilegraph_passes::RenderError> {
    let g = gpu_with(Some("lavapipe"), options.device_features()).unwrap();
    let mut r = SceneRenderer::new(&g, scene, options).unwrap();
    let side = EngineSide::new(&g, &r);
    r.add_material(material(&side, false));
    let cam = scene.camera_path().camera(0).unwrap();
    let result = r.render(&g, scene, &cam).map(|_| ());
    r.destroy(&g);
    side.destroy(&g);
    result
}

/// Frames of the city's path (every 40th of its first 200) under `culling`, with the engine's
/// material registered (`engine`) or not.
fn frames(
    scene: &Scene,
    culling: tilegraph_passes::cull::Culling,
    engine: Option<bool>,
) -> Vec<RgbaImage> {
    let options = RenderOptions {
        width: 160,
        height: 90,
        culling,
        ..Default::default()
    };
    frames_with(scene, options, engine)
}

/// As [`frames`], under `options`.
fn frames_with(scene: &Scene, options: RenderOptions, engine: Option<bool>) -> Vec<RgbaImage> {
    frames_on("lavapipe", scene, options, engine)
}

/// As [`frames_with`], with profile `profile` forced.
fn frames_on(
    profile: &str,
    scene: &Scene,
    options: RenderOptions,
    engine: Option<bool>,
) -> Vec<RgbaImage> {
    frames_and_triangles(profile, scene, options, engine).0
}

/// As [`frames_on`], with the triangles each frame's colour lists drew (read back from the
/// GPU lists; empty without GPU culling).
fn frames_and_triangles(
    profile: &str,
    scene: &Scene,
    options: RenderOptions,
    engine: Option<bool>,
) -> (Vec<RgbaImage>, Vec<u64>) {
    let g = gpu_with(Some(profile), options.device_features()).unwrap();
    let mut r = SceneRenderer::new(&g, scene, options).unwrap();
    let side = EngineSide::new(&g, &r);
    if let Some(depth) = engine {
        assert_eq!(r.add_material(material(&side, depth)), 0);
    }
    let (mut images, mut triangles) = (Vec::new(), Vec::new());
    for i in (0..200).step_by(40) {
        let cam = scene.camera_path().camera(i).unwrap();
        r.render(&g, scene, &cam).unwrap();
        images.push(r.read_image(&g).unwrap());
        if let Some(lists) = r.gpu_lists(&g).unwrap() {
            triangles.push(lists.colour_triangles());
        }
    }
    r.destroy(&g);
    side.destroy(&g);
    (images, triangles)
}

#[test]
fn an_engine_material_draws_the_culled_city_as_it_draws_the_unculled_one() {
    use tilegraph_passes::cull::Culling;
    let scene = city_with_engine_materials();
    let tilegraph_only = frames(&scene, Culling::None, None);
    for depth in [false, true] {
        let none = frames(&scene, Culling::None, Some(depth));
        let two_phase = frames(&scene, Culling::HizTwoPhase, Some(depth));
        for (k, (a, b)) in none.iter().zip(&two_phase).enumerate() {
            assert!(
                a == b,
                "frame {k} (engine depth shaders: {depth}): hiz-2phase differs from none"
            );
        }
        let changed = none
            .iter()
            .zip(&tilegraph_only)
            .map(|(a, b)| {
                a.pixels
                    .chunks_exact(4)
                    .zip(b.pixels.chunks_exact(4))
                    .filter(|(p, q)| p != q)
                    .count()
            })
            .sum::<usize>();
        println!("engine depth shaders {depth}: {changed} pixels of 5 frames differ from tilegraph's shading");
        assert!(
            changed > 5 * 160 * 90 / 4,
            "the engine's shading is not what was drawn ({changed} pixels differ from tilegraph's)"
        );
    }
}

/// Cluster culling under engine materials: each draw group's runs of clusters are drawn with its
/// own pipeline (the frame places each group's commands where the CPU knows them). The engine
/// draws every other opaque material of the city, so each list alternates between its pipeline
/// and tilegraph's; with the clusters attached, both cluster techniques give the unculled
/// frame's image, through the GPU's draw count (lavapipe) and through a fixed one (adreno-6xx),
/// forward with the engine's depth shaders and without (and with `cluster_early = clusters`,
/// `cluster_gap = 3`), through the visibility buffer with the engine's resolve, on a tiler's
/// profile (mali-valhall) with two cascades of shadows whose casters the pyramid culls, and with
/// per-triangle culling after the clusters.
#[test]
fn an_engine_material_draws_the_clusters_culling_kept() {
    use tilegraph_passes::cull::Culling;
    use tilegraph_passes::{Technique, VisbufResolve};
    let scene = clustered_city_with_engine_materials();
    fn forward(culling: Culling) -> RenderOptions {
        RenderOptions {
            width: 160,
            height: 90,
            culling,
            ..Default::default()
        }
    }
    fn visbuf(culling: Culling) -> RenderOptions {
        RenderOptions {
            technique: Technique::Visbuf,
            visbuf_resolve: Some(VisbufResolve::Classified),
            ..forward(culling)
        }
    }
    type Options = fn(Culling) -> RenderOptions;
    // The early phase culling clusters too, gaps of up to 3 culled clusters drawn through.
    fn other_settings(culling: Culling) -> RenderOptions {
        RenderOptions {
            cluster_early: tilegraph_passes::cull::ClusterEarly::Clusters,
            cluster_gap: 3,
            ..forward(culling)
        }
    }
    // Two cascades of shadows, their casters culled against this frame's pyramid.
    fn shadowed(culling: Culling) -> RenderOptions {
        RenderOptions {
            technique: Technique::Prepass,
            shadows: tilegraph_passes::shadow::ShadowOptions {
                cascades: 2,
                resolution: 256,
                culling: tilegraph_passes::shadow::CasterCulling::ReceiversHiz,
                ..Default::default()
            },
            ..forward(culling)
        }
    }
    let cases: [(&str, Options, bool); 6] = [
        ("lavapipe", forward, false),
        ("lavapipe", forward, true),
        ("adreno-6xx", forward, false),
        ("lavapipe", visbuf, false),
        ("lavapipe", other_settings, true),
        ("mali-valhall", shadowed, true),
    ];
    for (profile, options, depth) in cases {
        let none = frames_on(profile, &scene, options(Culling::None), Some(depth));
        let tilegraph = frames_on(profile, &scene, options(Culling::None), None);
        let engine_shaded = differing(&none, &tilegraph);
        assert!(
            engine_shaded > 5 * 160 * 90 / 8,
            "{profile}: only {engine_shaded} pixels are the engine's"
        );
        for culling in [Culling::FrustumClusters, Culling::HizTwoPhaseClusters] {
            let culled = frames_on(profile, &scene, options(culling), Some(depth));
            let differ = differing(&none, &culled);
            println!(
                "{profile} {} engine depth {depth}: {differ} pixels differ from none, {engine_shaded} are the engine's",
                culling.name()
            );
            assert_eq!(
                differ,
                0,
                "{profile}, {}, engine depth shaders {depth}: the culled frames differ",
                culling.name()
            );
        }
    }

    // Per-triangle culling after the clusters: it finds each command of a list drawn group by
    // group through the groups' runs, and rewrites it in place.
    fn triangles(culling: Culling) -> RenderOptions {
        RenderOptions {
            triangle_culling: true,
            ..forward(culling)
        }
    }
    // The lists read back: the engine's frames (drawn group by group from fixed places) draw
    // the same triangles as tilegraph's own (packed), per-triangle culling fewer still.
    let none = frames_on("lavapipe", &scene, forward(Culling::None), Some(true));
    for culling in [Culling::FrustumClusters, Culling::HizTwoPhaseClusters] {
        let run = |o, engine| frames_and_triangles("lavapipe", &scene, o, engine);
        let (images, by_cluster) = run(forward(culling), Some(true));
        let (_, packed) = run(forward(culling), None);
        let (culled, by_triangle) = run(triangles(culling), Some(true));
        let (_, packed_triangles) = run(triangles(culling), None);
        let name = culling.name();
        println!(
            "{name}: triangles {by_cluster:?} (tilegraph's {packed:?}), per triangle {by_triangle:?} ({packed_triangles:?})"
        );
        assert_eq!(differing(&none, &images), 0, "{name}");
        assert_eq!(differing(&none, &culled), 0, "{name} with triangle culling");
        assert_eq!(
            by_cluster, packed,
            "{name}: fixed places drew other clusters"
        );
        assert_eq!(by_triangle, packed_triangles, "{name}: other triangles");
        assert!(
            by_triangle.iter().zip(&by_cluster).all(|(t, c)| t < c),
            "{name}: per-triangle culling kept every triangle"
        );
    }
}
/// The same under a moving scene: instances move (a quarter of them turning mirrored and back),
/// spawn and despawn every frame, so the draw groups, their lengths and the cluster layout
/// change under the fixed places; 16 frames under `hiz-2phase-clusters` equal the unculled
/// ones, every one of them shaded by the engine. The first mirrored instance gives its mesh a
/// turned copy, whose clusters make the renderer's buffers anew: that once dropped the engine's
/// materials (tilegraph's shading drew them from then on).
#[test]
fn an_engine_material_draws_the_clusters_of_a_moving_scene() {
    use tilegraph_passes::cull::Culling;
    use tilegraph_scene::{Motion, MotionParams};
    let scene = clustered_city_with_engine_materials();
    let run = |culling, engine: bool| {
        let mut scene = scene.clone();
        let path = scene.camera_path().clone();
        let params = MotionParams {
            movers: 0.2,
            spawns: 12,
            seed: 3,
            mirrors: 0.25,
        };
        let mut motion = Motion::new(&scene, &path, params);
        let options = RenderOptions {
            width: 160,
            height: 90,
            culling,
            ..Default::default()
        };
        let g = gpu_with(Some("lavapipe"), options.device_features()).unwrap();
        let mut r = SceneRenderer::new(&g, &scene, options).unwrap();
        let side = EngineSide::new(&g, &r);
        if engine {
            r.add_material(material(&side, true));
        }
        let mut images = Vec::new();
        for i in 0..16 {
            motion.apply(&mut scene, i).unwrap();
            let cam = path.camera(i * 4).unwrap();
            r.render(&g, &scene, &cam).unwrap();
            images.push(r.read_image(&g).unwrap());
        }
        r.destroy(&g);
        side.destroy(&g);
        images
    };
    let none = run(Culling::None, true);
    let tilegraph = run(Culling::None, false);
    let clusters = run(Culling::HizTwoPhaseClusters, true);
    for (k, ((a, b), t)) in none.iter().zip(&clusters).zip(&tilegraph).enumerate() {
        assert!(a == b, "frame {k}: hiz-2phase-clusters differs from none");
        let engine_shaded = differing(std::slice::from_ref(a), std::slice::from_ref(t));
        assert!(
            engine_shaded > 160 * 90 / 8,
            "frame {k}: only {engine_shaded} pixels are the engine's"
        );
    }
}

/// Pixels of `a` and `b` that differ, over all frames.
fn differing(a: &[RgbaImage], b: &[RgbaImage]) -> usize {
    a.iter()
        .zip(b)
        .map(|(x, y)| {
            x.pixels
                .chunks_exact(4)
                .zip(y.pixels.chunks_exact(4))
                .filter(|(p, q)| p != q)
                .count()
        })
        .sum()
}

/// The engine's resolve shader (`test_engine_resolve.frag`, through
/// `shaders/include/tilegraph_visbuf.glsl`) shades its materials' pixels of the classified
/// visibility buffer: the culled city equals the unculled one, the toon is the engine's (its
/// forward colour shader's within the pixels where interpolation moves a band or stripe edge),
/// and without classification the renderer says what is missing.
#[test]
fn an_engine_resolve_shades_the_classified_visibility_buffer() {
    use tilegraph_passes::cull::Culling;
    use tilegraph_passes::{Technique, VisbufResolve};
    let scene = city_with_engine_materials();
    let visbuf = |culling| RenderOptions {
        width: 160,
        height: 90,
        culling,
        technique: Technique::Visbuf,
        visbuf_resolve: Some(VisbufResolve::Classified),
        ..Default::default()
    };
    let none = frames_with(&scene, visbuf(Culling::None), Some(false));
    let two_phase = frames_with(&scene, visbuf(Culling::HizTwoPhase), Some(false));
    for (k, (a, b)) in none.iter().zip(&two_phase).enumerate() {
        assert!(a == b, "frame {k}: hiz-2phase differs from none");
    }
    let tilegraph = frames_with(&scene, visbuf(Culling::None), None);
    let forward = frames(&scene, Culling::None, Some(false));
    let total = 5 * 160 * 90;
    let engine_shaded = differing(&none, &tilegraph);
    let off_forward = differing(&none, &forward);
    println!(
        "engine resolve: {engine_shaded} of {total} pixels differ from tilegraph's resolve, {off_forward} from the engine's forward shading"
    );
    assert!(
        engine_shaded > total / 2,
        "{engine_shaded} pixels are the engine's"
    );
    assert!(
        off_forward < total / 500,
        "{off_forward} pixels differ from forward"
    );

    // The über-resolve cannot run the engine's shader: a typed error, not tilegraph's shading.
    let options = RenderOptions {
        visbuf_resolve: Some(VisbufResolve::Uber),
        ..visbuf(Culling::None)
    };
    match first_frame(&scene, options) {
        Err(tilegraph_passes::RenderError::EngineResolveNeedsClassification { .. }) => {}
        other => panic!("expected EngineResolveNeedsClassification, got {other:?}"),
    }
}

/// A scene naming an engine material the renderer does not have is a typed error.
#[test]
fn an_unregistered_engine_material_is_a_typed_error() {
    let scene = city_with_engine_materials();
    let options = RenderOptions {
        width: 64,
        height: 36,
        ..Default::default()
    };
    let g = gpu_with(Some("lavapipe"), options.device_features()).unwrap();
    let mut r = SceneRenderer::new(&g, &scene, options).unwrap();
    let side = EngineSide::new(&g, &r);
    // One registered (id 0), so the table is built; the scene also names id 3.
    r.add_material(material(&side, false));
    let mut scene = scene;
    scene.set_engine_material(MaterialId(0), Some(3)).unwrap();
    let cam = scene.camera_path().camera(0).unwrap();
    match r.render(&g, &scene, &cam) {
        Err(tilegraph_passes::RenderError::UnknownEngineMaterial {
            engine: 3,
            registered: 1,
            ..
        }) => {}
        other => panic!("expected UnknownEngineMaterial, got {other:?}"),
    }
    r.destroy(&g);
    side.destroy(&g);
}

/// With levels of detail an engine material's run of draw groups is seven commands a group
/// (one per level): its draws of closed spheres (their opaque material the engine's) under
/// `hiz-2phase` equal those under `frustum` frame by frame, and differ from full detail.
#[test]
fn an_engine_material_draws_the_levels_culling_chose() {
    use tilegraph_passes::cull::Culling;
    let mut scene = tilegraph_e2e::closed_spheres(3, 4, false);
    let opaque: Vec<MaterialId> = (scene.materials().iter().enumerate())
        .filter(|(_, m)| m.class == MaterialClass::Opaque)
        .map(|(i, _)| MaterialId(i as u32))
        .collect();
    for id in opaque {
        scene.set_engine_material(id, Some(0)).unwrap();
    }
    let run = |culling, lod_error_px| {
        let options = RenderOptions {
            width: 160,
            height: 90,
            culling,
            lod_error_px,
            ..Default::default()
        };
        let g = gpu_with(Some("lavapipe"), options.device_features()).unwrap();
        let mut r = SceneRenderer::new(&g, &scene, options).unwrap();
        let side = EngineSide::new(&g, &r);
        assert_eq!(r.add_material(material(&side, false)), 0);
        let mut images = Vec::new();
        for i in 0..scene.camera_path().len().min(4) {
            let cam = scene.camera_path().camera(i).unwrap();
            r.render(&g, &scene, &cam).unwrap();
            images.push(r.read_image(&g).unwrap());
        }
        r.destroy(&g);
        side.destroy(&g);
        images
    };
    let frustum = run(Culling::Frustum, 2.0);
    let two_phase = run(Culling::HizTwoPhase, 2.0);
    assert_eq!(differing(&frustum, &two_phase), 0);
    assert!(
        differing(&frustum, &run(Culling::Frustum, 0.0)) > 0,
        "no level was drawn"
    );
}

/// Two views of one renderer, each culling clusters (`hiz-2phase-clusters` and
/// `frustum-clusters`, another size and camera), both draw the engine's materials from fixed
/// places: each view's image equals that view rendered alone and unculled.
#[test]
fn every_view_draws_engine_materials_with_cluster_culling() {
    use tilegraph_passes::cull::Culling;
    let scene = clustered_city_with_engine_materials();
    let path = scene.camera_path().clone();
    let camera = |k: usize| path.camera(k).unwrap();
    let options = |culling, width| RenderOptions {
        width,
        height: 90,
        culling,
        ..Default::default()
    };
    let main = options(Culling::HizTwoPhaseClusters, 160);
    let second = options(Culling::FrustumClusters, 120);
    let g = gpu_with(Some("lavapipe"), tilegraph_e2e::culling_features()).unwrap();
    let mut r = SceneRenderer::new(&g, &scene, main.clone()).unwrap();
    let side = EngineSide::new(&g, &r);
    r.add_material(material(&side, true));
    let v2 = r
        .add_view(&g, &scene, second.clone(), &camera(100))
        .unwrap();
    let (mut mains, mut seconds) = (Vec::new(), Vec::new());
    for i in 0..6 {
        r.set_view_camera(v2, &camera(100 + 10 * i), false).unwrap();
        r.render(&g, &scene, &camera(10 * i)).unwrap();
        mains.push(r.read_image(&g).unwrap());
        seconds.push(r.read_view_image(&g, v2).unwrap());
    }
    r.destroy(&g);
    side.destroy(&g);
    let alone = |o: RenderOptions, from: usize| {
        let unculled = RenderOptions {
            culling: Culling::None,
            ..o
        };
        let mut r = SceneRenderer::new(&g, &scene, unculled).unwrap();
        let side = EngineSide::new(&g, &r);
        r.add_material(material(&side, true));
        let images: Vec<_> = (0..6)
            .map(|i| {
                r.render(&g, &scene, &camera(from + 10 * i)).unwrap();
                r.read_image(&g).unwrap()
            })
            .collect();
        r.destroy(&g);
        side.destroy(&g);
        images
    };
    assert_eq!(differing(&mains, &alone(main, 0)), 0, "main view");
    assert_eq!(differing(&seconds, &alone(second, 100)), 0, "second view");
}
