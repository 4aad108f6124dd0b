//! Embedding from Rust: an engine's own instance and device (made with plain ash, its own
//! messenger, validation and synchronization validation on) adopted by tilegraph. The frame
//! equals the one tilegraph renders on a device it creates, bit for bit; tilegraph never
//! destroys what it adopted, and destroys everything it made on it (the engine's teardown of
//! the device reports no object left alive).

use tilegraph_e2e::engine::Engine;
use tilegraph_e2e::gpu_with;
use tilegraph_passes::cull::Culling;
use tilegraph_passes::{RenderError, RenderOptions, SceneRenderer, Technique, WantedBy};
use tilegraph_scene::Scene;
use tilegraph_vk::readback::RgbaImage;
use tilegraph_vk::{Context, Feature, FeatureRequest};

fn city() -> Scene {
    tilegraph_scene::load("city:300").unwrap()
}

fn options() -> RenderOptions {
    RenderOptions {
        technique: Technique::Prepass,
        culling: Culling::HizTwoPhase,
        width: 160,
        height: 90,
        ..Default::default()
    }
}

/// Two frames of the city's first two cameras (the second frame culls against the first).
fn render(ctx: &Context, scene: &Scene) -> RgbaImage {
    let mut r = SceneRenderer::new(ctx, scene, options()).unwrap();
    for frame in 0..2 {
        let camera = scene.camera_path().camera(frame).unwrap();
        r.render(ctx, scene, &camera).unwrap();
    }
    let image = r.read_image(ctx).unwrap();
    r.destroy(ctx);
    image
}

#[test]
fn an_adopted_device_renders_the_same_frame_and_is_left_to_the_engine() {
    let scene = city();
    let reference = {
        let g = gpu_with(Some("mali-valhall"), options().device_features()).unwrap();
        render(&g, &scene)
    };

    let mut engine = Engine::start();
    let ctx = engine
        .adopt(&options().device_features(), Some("mali-valhall"))
        .unwrap();
    assert!(!ctx.owns_device());
    assert!(!ctx.instance().owned());
    assert_eq!(ctx.profile().name, "mali-valhall");
    let image = render(&ctx, &scene);
    ctx.wait_idle().unwrap();
    ctx.destroy_checked().unwrap();
    assert!(
        image.pixels == reference.pixels,
        "the adopted device's frame differs from tilegraph's own"
    );
    // The device is still the engine's: it can still use it after tilegraph is gone.
    let device = engine.device.as_ref().unwrap();
    // SAFETY: a live device of the engine's.
    unsafe { device.device_wait_idle() }.unwrap();
    let messages = engine.destroy();
    assert!(messages.is_empty(), "validation: {messages:#?}");
}

/// The profile is chosen from the adopted device's identity when none is forced.
#[test]
fn an_adopted_device_gets_the_profile_of_its_identity() {
    let mut engine = Engine::start();
    let ctx = engine.adopt(&FeatureRequest::executor(), None).unwrap();
    let own = gpu_with(None, FeatureRequest::default()).unwrap();
    assert_eq!(ctx.profile().name, own.profile().name);
    assert_eq!(
        ctx.physical.identity.device_name,
        own.physical.identity.device_name
    );
    drop(own);
    ctx.destroy_checked().unwrap();
    let messages = engine.destroy();
    assert!(messages.is_empty(), "validation: {messages:#?}");
}

/// A device created without what the options need fails when the renderer is made, with the
/// feature and what wants it — not as a validation error later.
#[test]
fn a_missing_feature_on_an_adopted_device_names_the_feature_and_its_user() {
    let scene = city();
    let mut engine = Engine::start();
    // The engine enabled only what the executor needs: no indirect-count draws.
    let ctx = engine.adopt(&FeatureRequest::executor(), None).unwrap();
    let err = SceneRenderer::new(&ctx, &scene, options())
        .err()
        .expect("the renderer must refuse the device");
    match &err {
        RenderError::MissingFeature {
            feature, wanted_by, ..
        } => {
            assert_eq!(*feature, Feature::DrawIndirectCount);
            assert_eq!(*wanted_by, WantedBy::Culling(Culling::HizTwoPhase));
        }
        other => panic!("unexpected error: {other}"),
    }
    let text = err.to_string();
    assert!(
        text.contains("culling hiz-2phase") && text.contains("DrawIndirectCount"),
        "{text}"
    );
    ctx.destroy_checked().unwrap();
    let messages = engine.destroy();
    assert!(messages.is_empty(), "validation: {messages:#?}");
}

/// The engine's messenger really sees objects left alive at its device's teardown: the check
/// the tests above rely on.
#[test]
fn the_engines_teardown_reports_an_object_left_alive() {
    let mut engine = Engine::start();
    let ctx = engine.adopt(&FeatureRequest::executor(), None).unwrap();
    ctx.destroy_checked().unwrap();
    let device = engine.device.as_ref().unwrap();
    let info = tilegraph_vk::ash::vk::BufferCreateInfo::default()
        .size(256)
        .usage(tilegraph_vk::ash::vk::BufferUsageFlags::UNIFORM_BUFFER);
    // SAFETY: a valid buffer, deliberately never destroyed.
    let _leaked = unsafe { device.create_buffer(&info, None) }.unwrap();
    let messages = engine.destroy();
    assert!(
        messages.iter().any(|m| m.contains("vkDestroyDevice")),
        "the leak was not reported: {messages:#?}"
    );
}
