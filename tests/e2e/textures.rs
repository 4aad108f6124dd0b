//! Textured materials on lavapipe (validation on): the gallery (tests/src/textured.rs) under
//! forward, forward with depth pre-passes, the visibility buffer and deferred texturing matches
//! its golden images; the pre-pass frame equals the forward frame exactly (alpha-tested
//! discards agree); the visibility buffer's resolve, with analytic UV derivatives, and deferred
//! texturing's, with the G-buffer's packed UV, derivatives and normal, stay within the stated
//! tolerance of forward; deferred texturing's resolve as a tiler's subpass (input attachments)
//! renders what the sampled resolve renders; textures bound as layers of one image (the
//! fallback) render what the indexed binding renders, within the resampling's error.

use tilegraph_e2e::gpu_with;
use tilegraph_e2e::textured::textured_gallery;
use tilegraph_passes::{RenderOptions, SceneRenderer, Technique};
use tilegraph_profile::TextureBinding;
use tilegraph_scene::Scene;
use tilegraph_vk::readback::RgbaImage;
use tilegraph_vk::Feature;

const W: u32 = 160;
const H: u32 = 90;

/// One frame (camera 0) and the texture binding the renderer got.
fn image_of(profile: &str, scene: &Scene, options: RenderOptions) -> (RgbaImage, TextureBinding) {
    image_at(profile, scene, options, 0)
}

/// The frame from camera `frame` of the scene's path.
fn image_at(
    profile: &str,
    scene: &Scene,
    options: RenderOptions,
    frame: usize,
) -> (RgbaImage, TextureBinding) {
    let g = gpu_with(Some(profile), options.device_features()).unwrap();
    let mut r = SceneRenderer::new(&g, scene, options).unwrap();
    let cam = scene.camera_path().camera(frame).unwrap();
    r.render(&g, scene, &cam).unwrap();
    let image = r.read_image(&g).unwrap();
    let binding = r.texture_binding();
    r.destroy(&g);
    (image, binding)
}

/// What the indexed binding falls back to on this device: indexed where it has both texture
/// array indexing features (NVIDIA, Mesa 23+), layers where not (lavapipe of Mesa 22.3, the CI's).
fn indexed_here() -> TextureBinding {
    let g = gpu_with(Some("lavapipe"), RenderOptions::default().device_features()).unwrap();
    let can = g.has_feature(Feature::SampledImageArrayDynamicIndexing)
        && g.has_feature(Feature::SampledImageArrayNonUniformIndexing);
    if can {
        TextureBinding::Indexed
    } else {
        TextureBinding::Layers
    }
}

fn options(technique: Technique, prepass: bool) -> RenderOptions {
    RenderOptions {
        technique,
        width: W,
        height: H,
        depth_prepass: Some(prepass),
        alpha_prepass: Some(prepass),
        ..Default::default()
    }
}

/// (pixels differing in some channel, the largest channel difference).
fn difference(a: &RgbaImage, b: &RgbaImage) -> (usize, u8) {
    a.pixels
        .chunks_exact(4)
        .zip(b.pixels.chunks_exact(4))
        .map(|(p, q)| {
            p.iter()
                .zip(q)
                .map(|(x, y)| x.abs_diff(*y))
                .max()
                .unwrap_or(0)
        })
        .fold((0, 0), |(n, m), d| (n + usize::from(d > 0), m.max(d)))
}

/// The largest channel difference deferred texturing may show against forward.
const DEFERRED_LARGEST: u8 = 2;

#[test]
fn textured_gallery_matches_its_golden_images() {
    let scene = textured_gallery().load();
    assert_eq!(scene.textures().len(), 4);
    let bless = std::env::var_os("TILEGRAPH_BLESS").is_some();
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("golden");
    let (forward, binding) = image_of("lavapipe", &scene, options(Technique::Forward, false));
    assert_eq!(binding, indexed_here());
    let (prepass, _) = image_of("lavapipe", &scene, options(Technique::Forward, true));
    let (visbuf, _) = image_of("lavapipe", &scene, options(Technique::Visbuf, false));
    let dtex = options(Technique::DeferredTexturing, false);
    let (deferred, _) = image_of("lavapipe", &scene, dtex.clone());
    // mali-valhall merges the resolve into the G-buffer's render pass, reading G-buffer and
    // depth as input attachments: the same arithmetic on the same values.
    let (subpass, _) = image_of("mali-valhall", &scene, dtex);
    assert!(
        subpass == deferred,
        "deferred texturing: the subpass resolve differs from the sampled one"
    );
    let mut failures = Vec::new();
    for (name, img) in [
        ("forward", &forward),
        ("prepass", &prepass),
        ("visbuf", &visbuf),
        ("deferred-texturing", &deferred),
    ] {
        let path = dir.join(format!("textured-gallery-{name}.png"));
        if bless {
            tilegraph_e2e::golden::write_png(&path, img).unwrap();
        } else if let Err(e) = tilegraph_e2e::golden::compare(&path, img, 2) {
            failures.push(format!("{name}: {e}"));
        }
    }
    assert!(
        failures.is_empty(),
        "golden mismatches (TILEGRAPH_BLESS=1 regenerates):\n{}",
        failures.join("\n")
    );
    // The pre-pass and the colour pass discard the same alpha-tested texels: equal images.
    assert!(
        forward == prepass,
        "the pre-pass frame differs from forward"
    );
    // The resolve's analytic quad derivatives equal the rasterizer's fine ones up to rounding
    // (ray barycentrics against interpolated UVs): a level of 255 here and there, on both views
    // (ACCURACY.md, "Textures in the visibility buffer").
    for frame in 0..scene.camera_path().len() {
        let (forward, _) = image_at(
            "lavapipe",
            &scene,
            options(Technique::Forward, false),
            frame,
        );
        let (visbuf, _) = image_at("lavapipe", &scene, options(Technique::Visbuf, false), frame);
        let (pixels, largest) = difference(&forward, &visbuf);
        println!(
            "frame {frame}: visbuf vs forward: {pixels} of {} pixels differ, by at most {largest}",
            W * H
        );
        assert!(
            pixels <= (W * H / 10) as usize && largest <= 2,
            "frame {frame}: visbuf vs forward: {pixels} pixels differ, by up to {largest}"
        );
        // Deferred texturing samples with the G-buffer pass's own hardware derivatives (as
        // halves), a UV of 16 bits over two periods and a normal of 10 bits a component
        // (ACCURACY.md, "Deferred texturing").
        let dtex = options(Technique::DeferredTexturing, false);
        let (deferred, _) = image_at("lavapipe", &scene, dtex, frame);
        let (pixels, largest) = difference(&forward, &deferred);
        println!(
            "frame {frame}: deferred texturing vs forward: {pixels} of {} pixels differ, by at most {largest}",
            W * H
        );
        assert!(
            pixels <= (W * H / 10) as usize && largest <= DEFERRED_LARGEST,
            "frame {frame}: deferred texturing vs forward: {pixels} pixels differ, by up to {largest}"
        );
    }
}

/// Textures as layers of one image (the fallback; forced here): the gallery's four sizes
/// resampled to the largest (64x64) and one repeating sampler for all, so the frame differs
/// from the indexed one by that resampling and the gradient's clamped edge. Where the device
/// cannot index textures (lavapipe of Mesa 22.3) both frames are the fallback's and equal.
#[test]
fn textures_as_layers_render_what_indexed_textures_render() {
    let scene = textured_gallery().load();
    let here = indexed_here();
    for technique in [
        Technique::Forward,
        Technique::Visbuf,
        Technique::DeferredTexturing,
    ] {
        let (indexed, a) = image_of("lavapipe", &scene, options(technique, false));
        let forced = RenderOptions {
            texture_binding: Some(TextureBinding::Layers),
            ..options(technique, false)
        };
        let (layers, b) = image_of("lavapipe", &scene, forced);
        assert_eq!((a, b), (here, TextureBinding::Layers));
        if here == TextureBinding::Layers {
            assert!(
                indexed == layers,
                "{technique:?}: the same binding, different frames"
            );
        }
        let (pixels, largest) = difference(&indexed, &layers);
        println!("{technique:?}: layers vs indexed: {pixels} pixels differ, by at most {largest}");
        assert!(
            pixels <= (W * H / 10) as usize && largest <= 60,
            "{technique:?}: layers vs indexed: {pixels} pixels differ, by up to {largest}"
        );
    }
}
