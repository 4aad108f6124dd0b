//! An engine's frame: the shipped passes' `add_*` functions and a pass of the engine's own on
//! one graph (lavapipe, validation on). The engine's post-process reads the scene colour at the
//! same pixel, so on a tiler profile it joins the scene's render pass as a subpass and the
//! scene colour never leaves tile memory; the image is the shipped renderer's, inverted, bit
//! for bit. A frame declared again unchanged reuses its plan.

use std::sync::Arc;

use tilegraph_e2e::frames::{post_invert, Kit};
use tilegraph_e2e::gpu_with;
use tilegraph_graph::{
    AccessFlags, Coverage, Extent2d, Format, ImageDesc, Import, InitialContent, Layout, PassClass,
    PipelineStages, Residency, ResourceState,
};
use tilegraph_passes::draws::DrawClass;
use tilegraph_passes::forward::{add_forward, add_transparent};
use tilegraph_passes::pipelines::ColourDepth;
use tilegraph_passes::prepass::add_depth_prepass;
use tilegraph_passes::{
    DrawSource, FrameGraph, Payload, RenderOptions, SceneRenderer, SceneTargets, Technique,
};
use tilegraph_scene::DepthConvention;
use tilegraph_vk::executor::{External, Externals, ImageHandle};

const W: u32 = 160;
const H: u32 = 90;

/// The engine's frame: depth pre-pass, opaque and blended colour into a scene colour it
/// creates, then its own post-process into its target (the renderer's, for the readback).
fn engine_frame(
    kit: &std::rc::Rc<std::cell::RefCell<Kit>>,
    target: &ImageHandle,
    first: bool,
    clear: [f32; 4],
) -> (FrameGraph, Externals) {
    let extent = Extent2d::new(W, H);
    let mut g = FrameGraph::new();
    let kept = ResourceState::image(
        Layout::TransferSrc,
        PipelineStages::COPY,
        AccessFlags::TRANSFER_READ,
    );
    let out = g.import_image(
        "engine-target",
        ImageDesc::new(extent, Format::R8G8B8A8_UNORM),
        Import {
            initial: if first {
                ResourceState::UNDEFINED
            } else {
                kept
            },
            content: InitialContent::Discard,
            final_state: kept,
        },
    );
    let externals = Externals::from_iter([(out, External::Image(target.clone()))]);
    let color = g.create_image(
        "scene-color",
        ImageDesc::new(extent, Format::R8G8B8A8_UNORM),
    );
    let depth = g.create_image("depth", ImageDesc::new(extent, Format::D32_SFLOAT));
    let mut t = SceneTargets::new(color, depth, extent, clear, DepthConvention::Reverse);
    add_depth_prepass(
        &mut g,
        &mut t,
        DrawClass::Opaque,
        DrawSource::Cpu,
        "depth-prepass",
    );
    add_forward(
        &mut g,
        &mut t,
        DrawClass::Opaque,
        ColourDepth::Equal,
        DrawSource::Cpu,
        None,
        "opaque",
    );
    add_transparent(&mut g, &mut t);
    // The engine's own pass: it keeps its state itself and ignores the scene's.
    let mut post = post_invert(kit, color);
    let record: Payload = Box::new(move |pc, _| post(pc));
    g.raster_pass("post", PassClass::Post, record)
        .input(color)
        .color(out)
        .coverage(Coverage::Full);
    g.export(out);
    (g, externals)
}

#[test]
fn an_engine_frame_composes_the_shipped_passes_with_its_own() {
    let scene = tilegraph_scene::load("city:400").unwrap();
    let camera = scene.camera_path().camera(0).unwrap();
    for profile in ["adreno-7xx", "mali-valhall", "desktop-nvidia"] {
        let g = gpu_with(Some(profile), Default::default()).unwrap();
        let options = RenderOptions {
            technique: Technique::Prepass,
            width: W,
            height: H,
            ..Default::default()
        };
        // The shipped renderer's own frame (pre-pass, opaque, transparent) is the reference.
        let mut reference = SceneRenderer::new(&g, &scene, options.clone()).unwrap();
        reference.render(&g, &scene, &camera).unwrap();
        let want = reference.read_image(&g).unwrap();
        reference.destroy(&g);

        let mut r = SceneRenderer::new(&g, &scene, options.clone()).unwrap();
        let kit = Kit::new(&g).unwrap();
        let frame = scene.camera_path().frame(0, W as f32 / H as f32).unwrap();
        let mut plans = Vec::new();
        for i in 0..3 {
            r.prepare_frame(&g, &scene, &frame).unwrap();
            let (graph, externals) =
                engine_frame(&kit, r.target().unwrap(), i == 0, options.clear_color);
            let report = r.execute_graph(&g, graph, &externals).unwrap();
            let got = r.read_image(&g).unwrap();
            for (p, (a, b)) in got
                .pixels
                .chunks_exact(4)
                .zip(want.pixels.chunks_exact(4))
                .enumerate()
            {
                let inverted = [255 - b[0], 255 - b[1], 255 - b[2], 255];
                assert_eq!(a, inverted, "{profile}, frame {i}, pixel {p}");
            }
            plans.push(report.plan);
        }
        // The first frame imports the target UNDEFINED; the next two declare the same graph,
        // and the third reuses the second's plan.
        assert!(!Arc::ptr_eq(&plans[0], &plans[1]), "{profile}");
        assert!(Arc::ptr_eq(&plans[1], &plans[2]), "{profile}");
        let plan = &plans[2];
        let post = plan.passes.iter().find(|p| p.name == "post").unwrap();
        let color = plan.resource_by_name("scene-color").unwrap();
        if g.profile().is_tiler() {
            // One render pass: the post-process is its fourth subpass, and the scene colour
            // lives and dies in tile memory.
            assert_eq!(plan.render_passes().count(), 1, "{profile}\n{plan}");
            assert_eq!(post.subpass.map(|s| s.0), Some(3), "{profile}\n{plan}");
            assert_eq!(color.residency, Residency::Transient, "{profile}\n{plan}");
        }
        r.destroy(&g);
        kit.borrow_mut().destroy(&g);
    }
}
