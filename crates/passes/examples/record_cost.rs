//! The CPU cost of recording an unchanged frame, for callgrind (docs/BENCHMARKS.md,
//! "Recording an unchanged frame"): renders `city:2000` at 320x180 on the default device with
//! GPU frustum culling, `WARMUP` frames and then `FRAMES` more from the same camera, validation
//! off. Run under `valgrind --tool=callgrind --toggle-collect=...` to count the instructions of
//! the frames' recording.
//!
//! `cargo run --release -p tilegraph-passes --example record_cost -- [FRAMES] [SCENE]`

use tilegraph_passes::cull::Culling;
use tilegraph_passes::{RenderOptions, SceneRenderer};
use tilegraph_vk::{Context, ContextOptions, Validation};

const WARMUP: usize = 8;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let frames: usize = args.next().map_or(Ok(32), |a| a.parse())?;
    let scene_name = args.next().unwrap_or_else(|| "city:2000".into());
    let scene = tilegraph_scene::load(&scene_name)?;
    let mut options = ContextOptions::from_env();
    options.validation = Validation::Off;
    let render = RenderOptions {
        culling: Culling::Frustum,
        ..RenderOptions::default()
    };
    options.features = render.device_features();
    let ctx = Context::new(options)?;
    let mut renderer = SceneRenderer::new(&ctx, &scene, render)?;
    let camera = scene
        .camera_path()
        .camera(0)
        .ok_or("the scene has no camera")?;
    for _ in 0..WARMUP + frames {
        renderer.render(&ctx, &scene, &camera)?;
    }
    renderer.finish(&ctx)?;
    println!(
        "{} frames of {scene_name} on {} ({})",
        WARMUP + frames,
        ctx.physical.identity.device_name,
        ctx.profile().name
    );
    renderer.destroy(&ctx);
    ctx.destroy_checked()?;
    Ok(())
}
