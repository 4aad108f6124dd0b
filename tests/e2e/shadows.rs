//! Cascaded shadow maps on lavapipe (validation on): the city and the interior with three
//! cascades under forward, forward with pre-passes and the visibility buffer match their golden
//! images; shadows only take light away (no pixel brighter than the unshadowed frame) and take
//! a good part of it; and caster culling by cascade and by receivers is exact — every frame of
//! the city's path, a light turning over the city, and walks at eye height through the city and
//! the interior equals the frame that draws every caster — while drawing fewer casters.

use glam::Vec3;
use tilegraph_cull::shadow::CasterCulling;
use tilegraph_e2e::gpu_with;
use tilegraph_passes::shadow::ShadowOptions;
use tilegraph_passes::{RenderOptions, SceneRenderer, Technique};
use tilegraph_scene::{CameraFrame, CameraPath, Motion, MotionParams, PathKey, Scene};
use tilegraph_vk::readback::RgbaImage;

const W: u32 = 160;
const H: u32 = 90;

fn shadows(culling: CasterCulling) -> ShadowOptions {
    ShadowOptions {
        cascades: 3,
        resolution: 256,
        culling,
        ..ShadowOptions::default()
    }
}

fn options(technique: Technique, prepass: bool, shadows: ShadowOptions) -> RenderOptions {
    RenderOptions {
        technique,
        width: W,
        height: H,
        depth_prepass: Some(prepass),
        alpha_prepass: Some(prepass),
        shadows,
        ..Default::default()
    }
}

/// One rendered frame: the image and the casters drawn per cascade.
struct Shot {
    image: RgbaImage,
    casters: Option<[u32; 4]>,
}

/// Renders `frames` of `path` (light along `light(frame)`) with `options` on one renderer.
fn render_path(
    scene: &Scene,
    options: RenderOptions,
    path: &CameraPath,
    frames: &[usize],
    light: impl Fn(usize) -> Option<Vec3>,
) -> Vec<Shot> {
    render_moving(scene, options, path, frames, light, None)
}

/// [`render_path`] with the scene moving (`motion`: movers slide and swing, instances spawn
/// and despawn; `tilegraph_scene::Motion`), brought to each frame before it renders.
fn render_moving(
    scene: &Scene,
    options: RenderOptions,
    path: &CameraPath,
    frames: &[usize],
    light: impl Fn(usize) -> Option<Vec3>,
    motion: Option<MotionParams>,
) -> Vec<Shot> {
    let mut scene = scene.clone();
    let mut motion = motion.map(|m| Motion::new(&scene, path, m));
    let scene = &mut scene;
    let g = gpu_with(Some("lavapipe"), options.device_features()).unwrap();
    let mut r = SceneRenderer::new(&g, scene, options).unwrap();
    let aspect = W as f32 / H as f32;
    let mut out = Vec::new();
    let mut previous = None;
    for &i in frames {
        let key = path.keys()[i];
        let before = if key.cut { None } else { previous.as_ref() };
        let frame = CameraFrame::new(i, key.camera, before, aspect);
        if let Some(l) = light(i) {
            r.set_light_direction(l);
        }
        if let Some(m) = &mut motion {
            m.apply(scene, i).unwrap();
        }
        r.render_frame(&g, scene, &frame).unwrap();
        let casters = r.read_shadow_casters(&g).unwrap();
        out.push(Shot {
            image: r.read_image(&g).unwrap(),
            casters,
        });
        previous = Some(key.camera);
    }
    r.destroy(&g);
    out
}

fn first_frames(path: &CameraPath, n: usize) -> Vec<usize> {
    (0..n.min(path.len())).collect()
}

fn city() -> Scene {
    tilegraph_scene::load("city:300").unwrap()
}

fn interior() -> Scene {
    tilegraph_scene::load("interior").unwrap()
}

/// (pixels darker than `unshadowed`, pixels brighter by more than a level).
fn darkening(shadowed: &RgbaImage, unshadowed: &RgbaImage) -> (usize, usize) {
    shadowed
        .pixels
        .chunks_exact(4)
        .zip(unshadowed.pixels.chunks_exact(4))
        .fold((0, 0), |(dark, bright), (s, u)| {
            let darker = (0..3).any(|c| s[c] < u[c]);
            let brighter = (0..3).any(|c| s[c] > u[c].saturating_add(1));
            (dark + usize::from(darker), bright + usize::from(brighter))
        })
}

#[test]
fn three_cascades_match_their_golden_images_and_only_take_light_away() {
    let bless = std::env::var_os("TILEGRAPH_BLESS").is_some();
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("golden");
    let mut failures = Vec::new();
    for (name, scene) in [("city", city()), ("interior", interior())] {
        let path = scene.camera_path().clone();
        let frame = [0];
        let lit = |_| None;
        let off = ShadowOptions::default();
        let on = shadows(CasterCulling::Receivers);
        let mut images = Vec::new();
        for (shading, technique, prepass) in [
            ("forward", Technique::Forward, false),
            ("prepass", Technique::Forward, true),
            ("visbuf", Technique::Visbuf, false),
            ("deferred-texturing", Technique::DeferredTexturing, false),
        ] {
            let unshadowed = options(technique, prepass, off);
            let unshadowed = render_path(&scene, unshadowed, &path, &frame, lit);
            let shot = render_path(&scene, options(technique, prepass, on), &path, &frame, lit);
            let image = &shot[0].image;
            let (dark, bright) = darkening(image, &unshadowed[0].image);
            println!(
                "{name} {shading}: {dark} of {} pixels in shadow, {bright} brighter",
                W * H
            );
            assert_eq!(
                bright, 0,
                "{name} {shading}: a shadow made a pixel brighter"
            );
            assert!(
                dark >= (W * H / 20) as usize,
                "{name} {shading}: only {dark} pixels in shadow"
            );
            let golden = dir.join(format!("shadows-{name}-{shading}.png"));
            if bless {
                tilegraph_e2e::golden::write_png(&golden, image).unwrap();
            } else if let Err(e) = tilegraph_e2e::golden::compare(&golden, image, 2) {
                failures.push(format!("{name} {shading}: {e}"));
            }
            images.push((unshadowed[0].image.clone(), shot[0].image.clone()));
        }
        // The pre-pass changes no lookup: where it draws what forward draws, shadows and all.
        if images[0].0 == images[1].0 {
            assert!(
                images[0].1 == images[1].1,
                "{name}: pre-pass frame differs from forward"
            );
        } else {
            println!("{name}: the pre-pass frame differs from forward without shadows too");
        }
    }
    assert!(
        failures.is_empty(),
        "golden mismatches (TILEGRAPH_BLESS=1 regenerates):\n{}",
        failures.join("\n")
    );
}

/// Renders `frames` under every caster culling (`base`: the shading and the GPU culling);
/// asserts the images equal the unculled ones and the casters drawn shrink from none to
/// cascade to receivers to receivers-hiz, per cascade and frame; the casters summed over the
/// frames in [`CasterCulling::ALL`]'s order.
fn culled_equals_unculled(
    what: &str,
    scene: &Scene,
    base: &RenderOptions,
    path: &CameraPath,
    frames: &[usize],
    light: impl Fn(usize) -> Option<Vec3> + Copy,
) -> [u64; 4] {
    moving_culled_equals_unculled(what, scene, base, (path, frames), light, None)
}

/// [`culled_equals_unculled`] with the scene moving.
fn moving_culled_equals_unculled(
    what: &str,
    scene: &Scene,
    base: &RenderOptions,
    (path, frames): (&CameraPath, &[usize]),
    light: impl Fn(usize) -> Option<Vec3> + Copy,
    motion: Option<MotionParams>,
) -> [u64; 4] {
    let run = |c| {
        let o = RenderOptions {
            shadows: shadows(c),
            ..base.clone()
        };
        render_moving(scene, o, path, frames, light, motion)
    };
    let runs: Vec<Vec<Shot>> = CasterCulling::ALL.into_iter().map(run).collect();
    let mut totals = [0u64; 4];
    for (k, culling) in CasterCulling::ALL.into_iter().enumerate() {
        for (i, (a, b)) in runs[k].iter().zip(&runs[0]).enumerate() {
            assert!(
                a.image == b.image,
                "{what}, {} culling, frame {i}: the image differs from drawing every caster",
                culling.name()
            );
            let Some(ca) = a.casters else {
                continue; // a fixed draw count keeps no counts
            };
            if k > 0 {
                let looser = runs[k - 1][i].casters.unwrap_or([u32::MAX; 4]);
                for c in 0..3 {
                    assert!(ca[c] <= looser[c], "{what} frame {i} cascade {c}: {ca:?}");
                }
            }
            totals[k] += ca.iter().map(|&n| u64::from(n)).sum::<u64>();
        }
    }
    println!(
        "{what}: casters drawn over {} frames: none {}, cascade {}, receivers {}, receivers-hiz {}",
        frames.len(),
        totals[0],
        totals[1],
        totals[2],
        totals[3]
    );
    totals
}

/// Two-phase HiZ with a pre-pass (or the visibility buffer): the frames where
/// `receivers-hiz` has this frame's pyramid before the colour.
fn two_phase(technique: Technique) -> RenderOptions {
    RenderOptions {
        culling: tilegraph_passes::cull::Culling::HizTwoPhase,
        ..options(technique, true, ShadowOptions::default())
    }
}

#[test]
fn caster_culling_is_exact_along_the_city_path_and_under_a_turning_light() {
    let scene = city();
    let path = scene.camera_path().clone();
    let frames = first_frames(&path, 5);
    let base = two_phase(Technique::Forward);
    let [none, cascade, receivers, hiz] =
        culled_equals_unculled("city path", &scene, &base, &path, &frames, |_| None);
    assert!(
        hiz < receivers && receivers < cascade && cascade < none,
        "{hiz} {receivers} {cascade} {none}"
    );
    // The light turns 40 degrees a frame round the vertical, 35 degrees up, over a still camera.
    let still = CameraPath::new("still", vec![path.keys()[2]; 9]).unwrap();
    let turning = |i: usize| {
        let (a, e) = ((40.0 * i as f32).to_radians(), 35f32.to_radians());
        Some(Vec3::new(a.cos() * e.cos(), e.sin(), a.sin() * e.cos()))
    };
    let frames: Vec<usize> = (0..9).collect();
    let base = two_phase(Technique::Visbuf);
    culled_equals_unculled("turning light", &scene, &base, &still, &frames, turning);
}

#[test]
fn caster_culling_is_exact_on_walks_through_the_city_and_the_interior() {
    for (name, scene) in [("city", city()), ("interior", interior())] {
        let walk = CameraPath::eye_height_walk(&scene.bounds(), 48, 38);
        // Walking frames, a yaw sweep, both sides of the cut at 24.
        let frames = [0, 1, 2, 9, 17, 23, 24, 25, 40];
        let base = two_phase(Technique::Forward);
        culled_equals_unculled(name, &scene, &base, &walk, &frames, |_| None);
    }
}

/// Movers slide out from behind buildings and back under a still camera, instances spawn and
/// despawn (the frames two-phase culling exists for): every caster culling, `receivers-hiz`
/// against the pyramid of this frame's early depth included, still draws the image of every
/// caster.
#[test]
fn caster_culling_is_exact_while_the_scene_moves() {
    let scene = tilegraph_scene::load("city:1500").unwrap();
    let camera = scene.camera_path().keys()[0].camera;
    let keys = (0..10)
        .map(|i| PathKey {
            camera,
            cut: i == 0,
        })
        .collect();
    let still = CameraPath::new("still camera", keys).unwrap();
    let frames: Vec<usize> = (0..10).collect();
    let motion = MotionParams {
        movers: 0.3,
        spawns: 6,
        seed: 7,
        mirrors: 0.25,
    };
    for technique in [
        Technique::Forward,
        Technique::Visbuf,
        Technique::DeferredTexturing,
    ] {
        let base = two_phase(technique);
        let what = format!("moving city, {technique:?}");
        let run = (&still, frames.as_slice());
        moving_culled_equals_unculled(&what, &scene, &base, run, |_| None, Some(motion));
    }
}

/// The filter's width (knob `shadow_pcf`) changes the image and not the exactness: with one
/// bilinear compare and with the 5x5 texels, receiver culling still draws every caster's image.
#[test]
fn every_filter_width_keeps_caster_culling_exact() {
    let scene = city();
    let path = scene.camera_path().clone();
    let frames = first_frames(&path, 3);
    let base = two_phase(Technique::Forward);
    let mut images = Vec::new();
    for pcf in [0, 1, 2] {
        let run = |culling| {
            let o = RenderOptions {
                shadows: ShadowOptions {
                    pcf,
                    ..shadows(culling)
                },
                ..base.clone()
            };
            render_path(&scene, o, &path, &frames, |_| None)
        };
        let (all, culled) = (run(CasterCulling::None), run(CasterCulling::ReceiversHiz));
        for (i, (a, b)) in culled.iter().zip(&all).enumerate() {
            assert!(
                a.image == b.image,
                "pcf {pcf}, frame {i}: culled casters show"
            );
        }
        images.push(all.into_iter().next().map(|s| s.image));
    }
    assert!(
        images[0] != images[1] && images[1] != images[2],
        "the filter changed nothing"
    );
}

/// The caster oracle's positive control: a caster the frame needs, taken out of the shadows
/// (its `CASTS_SHADOWS` cleared, as a culling that missed it would draw), changes the image,
/// and the oracle attributes the differing pixels to it: a caster false negative. With every
/// caster drawn the same oracle reports none, and every caster it needs was drawn.
#[test]
fn the_caster_oracle_names_a_needed_caster_left_out() {
    use tilegraph_passes::cullcheck::casters::{self, OracleFrame};
    use tilegraph_scene::{InstanceFlags, InstanceId};

    let scene = city();
    let options = options(Technique::Forward, false, shadows(CasterCulling::None));
    let mut features = options.device_features();
    features
        .required
        .extend(tilegraph_e2e::culling_features().required);
    let g = gpu_with(Some("lavapipe"), features).unwrap();
    let frame = scene
        .camera_path()
        .frames(W as f32 / H as f32)
        .next()
        .unwrap();
    let mut oracle = SceneRenderer::new(
        &g,
        &scene,
        RenderOptions {
            technique: Technique::Visbuf,
            capture_ids: true,
            shadows: ShadowOptions::default(),
            ..options.clone()
        },
    )
    .unwrap();
    oracle.render_frame(&g, &scene, &frame).unwrap();
    let owners = oracle.read_pixel_owners(&g).unwrap().unwrap();
    oracle.destroy(&g);
    let triangles = owners.triangles.clone().unwrap();
    let all_casters = casters::casters(&scene);
    let cascades = tilegraph_passes::shadow::frame_cascades(
        &frame.camera,
        W as f32 / H as f32,
        &scene,
        options.lighting.direction,
        &options.shadows,
        options.shadows.atlas(g.profile()),
    );
    let render = |scene: &Scene| {
        let mut r = SceneRenderer::new(&g, scene, options.clone()).unwrap();
        r.render_frame(&g, scene, &frame).unwrap();
        let image = r.read_image(&g).unwrap();
        let drawn = r.read_shadow_caster_ids(&g).unwrap().unwrap();
        r.destroy(&g);
        (image, drawn)
    };
    let needs_with = |differing: &[bool]| {
        let oracle_frame = OracleFrame {
            frame: &frame,
            size: (W, H),
            instances: &owners.instances,
            triangles: &triangles,
            differing,
        };
        casters::needed_casters(
            &scene,
            &oracle_frame,
            &cascades,
            &options.shadows.settings(),
            &all_casters,
        )
    };
    let (reference, drawn_all) = render(&scene);
    let none_differ = vec![false; (W * H) as usize];
    let needs = needs_with(&none_differ);
    let whole = casters::check(&needs, &drawn_all);
    assert!(whole.needed > 0, "{whole:?}");
    assert_eq!(
        (whole.false_negatives, whole.needed_culled),
        (0, 0),
        "{whole:?}"
    );
    // The nearest cascade's needed casters, one at a time, until one's shadow shows.
    let candidates: Vec<u32> = (0..scene.instances().len() as u32)
        .filter(|&i| needs.needed[0][i as usize])
        .take(12)
        .collect();
    for x in candidates {
        let mut without = scene.clone();
        let h = without.instance_handle(InstanceId(x)).unwrap();
        without.set_flags(h, InstanceFlags::NONE).unwrap();
        let (image, drawn) = render(&without);
        let differing: Vec<bool> = image
            .pixels
            .chunks_exact(4)
            .zip(reference.pixels.chunks_exact(4))
            .map(|(a, b)| a != b)
            .collect();
        if !differing.contains(&true) {
            continue;
        }
        let check = casters::check(&needs_with(&differing), &drawn);
        println!("caster {x} left out: {check:?}");
        assert!(check.false_negatives >= 1, "{check:?}");
        assert!(drawn.iter().all(|c| c.binary_search(&x).is_err()));
        return;
    }
    panic!("no needed caster of the nearest cascade changed the image when left out");
}
