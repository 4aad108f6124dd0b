//! The visibility buffer's per-material resolves (lavapipe, validation on): one full-screen pass
//! per material discarding the others' pixels, and material classification (per-material tile
//! lists, indirect tile quads) give the über-resolve's image bit for bit, frame by frame, on the
//! city with its opaque geometry spread over many materials — at every classification tile size,
//! on an immediate-mode profile (ids sampled) and a tiler's (the per-material passes read the
//! ids as an input attachment; classification stores them).

use tilegraph_e2e::gpu_with;
use tilegraph_passes::cull::Culling;
use tilegraph_passes::{RenderOptions, SceneRenderer, Technique, VisbufResolve};
use tilegraph_scene::Scene;
use tilegraph_vk::readback::RgbaImage;

/// Frames of the city's path (every 50th of its first 200, its cut included) resolved by
/// `resolve` under `profile`.
fn frames(
    scene: &Scene,
    profile: &str,
    resolve: VisbufResolve,
    tile: u32,
    culling: Culling,
) -> Vec<RgbaImage> {
    let options = RenderOptions {
        technique: Technique::Visbuf,
        width: 160,
        height: 90,
        culling,
        visbuf_resolve: Some(resolve),
        classify_tile: Some(tile),
        ..Default::default()
    };
    let g = gpu_with(Some(profile), options.device_features()).unwrap();
    let mut r = SceneRenderer::new(&g, scene, options).unwrap();
    let mut images = Vec::new();
    for i in (0..200).step_by(50) {
        let cam = scene.camera_path().camera(i).unwrap();
        r.render(&g, scene, &cam).unwrap();
        images.push(r.read_image(&g).unwrap());
    }
    r.destroy(&g);
    images
}

fn assert_same(a: &[RgbaImage], b: &[RgbaImage], what: &str) {
    assert_eq!(a.len(), b.len());
    for (k, (x, y)) in a.iter().zip(b).enumerate() {
        let differing = x
            .pixels
            .chunks_exact(4)
            .zip(y.pixels.chunks_exact(4))
            .filter(|(p, q)| p != q)
            .count();
        assert_eq!(
            differing, 0,
            "frame {k}: {what} differs from the über-resolve in {differing} pixels"
        );
    }
}

/// 40 materials spread over the city's opaque instances: more than one 32-bit word of a tile's
/// material mask.
fn city() -> Scene {
    let scene = tilegraph_scene::load("city:400")
        .unwrap()
        .with_spread_materials(40)
        .unwrap();
    assert!(scene.materials().len() > 40);
    scene
}

#[test]
fn per_material_and_classified_resolves_equal_the_uber_resolve() {
    let scene = city();
    let uber = frames(&scene, "lavapipe", VisbufResolve::Uber, 16, Culling::None);
    // Many materials on screen: the test means something.
    let colours: std::collections::BTreeSet<[u8; 4]> = uber[0]
        .pixels
        .chunks_exact(4)
        .map(|p| [p[0], p[1], p[2], p[3]])
        .collect();
    assert!(colours.len() > 30, "{} colours in frame 0", colours.len());
    let per = frames(
        &scene,
        "lavapipe",
        VisbufResolve::PerMaterial,
        16,
        Culling::None,
    );
    assert_same(&uber, &per, "per-material");
    for tile in [8, 16, 32] {
        let classified = frames(
            &scene,
            "lavapipe",
            VisbufResolve::Classified,
            tile,
            Culling::None,
        );
        assert_same(&uber, &classified, &format!("classified ({tile} px tiles)"));
    }
    // Through two-phase culling (its two id passes) too.
    let uber_culled = frames(
        &scene,
        "lavapipe",
        VisbufResolve::Uber,
        16,
        Culling::HizTwoPhase,
    );
    assert_same(&uber, &uber_culled, "uber after hiz-2phase");
    let culled = frames(
        &scene,
        "lavapipe",
        VisbufResolve::Classified,
        16,
        Culling::HizTwoPhase,
    );
    assert_same(&uber, &culled, "classified after hiz-2phase");
}

#[test]
fn on_a_tiler_the_resolves_agree_too() {
    let scene = city();
    let uber = frames(
        &scene,
        "mali-valhall",
        VisbufResolve::Uber,
        16,
        Culling::None,
    );
    let per = frames(
        &scene,
        "mali-valhall",
        VisbufResolve::PerMaterial,
        16,
        Culling::None,
    );
    assert_same(&uber, &per, "per-material (input attachment)");
    let classified = frames(
        &scene,
        "mali-valhall",
        VisbufResolve::Classified,
        16,
        Culling::None,
    );
    assert_same(&uber, &classified, "classified (ids stored)");
}
