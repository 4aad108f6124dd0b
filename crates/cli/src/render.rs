//! `tilegraph render` and the demo frame: a scene drawn with the profile's passes, the per-pass
//! GPU time table (medians over frames, from timestamps), and a PNG.

use std::path::Path;

use tilegraph_passes::{FrameReport, RenderOptions, SceneRenderer, Technique};
use tilegraph_scene::Scene;
use tilegraph_vk::{Context, ContextOptions};

use crate::{image_io, CliError};

pub struct RenderArgs<'a> {
    pub scene: &'a Scene,
    pub technique: Technique,
    pub profile: Option<&'a str>,
    pub size: (u32, u32),
    pub frames: u32,
    pub heavy: u32,
    pub camera_frame: usize,
    pub out: &'a Path,
}

pub fn run(args: &RenderArgs<'_>) -> Result<(), CliError> {
    let mut options = ContextOptions::from_env();
    if let Some(p) = args.profile {
        options.profile = Some(p.to_string());
    }
    let mut ropts = RenderOptions {
        technique: args.technique,
        width: args.size.0,
        height: args.size.1,
        ..Default::default()
    };
    ropts.lighting.heavy_iterations = args.heavy;
    options.features = ropts.device_features();
    let ctx = Context::new(options)?;
    let scene = args.scene;
    let camera = scene
        .camera_path()
        .camera(args.camera_frame)
        .ok_or_else(|| {
            CliError::Usage(format!(
                "camera frame {} is outside the scene's path of {} frames",
                args.camera_frame,
                scene.camera_path().len()
            ))
        })?;
    let mut renderer = SceneRenderer::new(&ctx, scene, ropts)?;
    let result = (|| {
        let mut last: Option<FrameReport> = None;
        let mut lint = None;
        renderer.lint_next_frame();
        for _ in 0..args.frames.max(1) {
            let report = renderer.render(&ctx, scene, &camera)?;
            lint = lint.or_else(|| report.lint.clone());
            last = Some(report);
        }
        let image = renderer.read_image(&ctx)?;
        Ok::<_, CliError>((last, lint, image))
    })();
    let (report, lint, image) = match result {
        Ok(v) => v,
        Err(e) => {
            renderer.destroy(&ctx);
            return Err(e);
        }
    };
    // Written and printed before the renderer is destroyed (the timings live in it); destroyed
    // whatever writing or printing did (a full disk, a closed pipe).
    let printed = (|| -> Result<(), CliError> {
        image_io::write_png(args.out, &image)?;
        outln!(
            "scene {:?}: {} instances; device {:?}; profile {} ({}); technique {}; {}x{}",
            scene.name(),
            scene.instances().len(),
            ctx.physical.identity.device_name,
            ctx.profile().name,
            ctx.selection.matched_by,
            args.technique.name(),
            args.size.0,
            args.size.1
        )?;
        if let Some(r) = &report {
            outln!("\npasses chosen by the frame setup:")?;
            for d in &r.setup.decisions {
                outln!(
                    "  {:<20} {:<8} {}",
                    d.pass.name(),
                    if d.included { "included" } else { "left out" },
                    d.reason
                )?;
            }
            outln!(
                "\nplan: {} render pass(es), {} barriers; traffic {} (naive {}); {} draws, {} triangles",
                r.plan.render_passes().count(),
                r.plan.barrier_count(),
                bytes(r.plan.traffic.planned.total_bytes()),
                bytes(r.plan.traffic.naive.total_bytes()),
                r.draws,
                r.triangles
            )?;
        }
        if let Some(l) = &lint {
            outln!("{}", l.summary())?;
        }
        print_timings(&renderer, args.frames)?;
        outln!("wrote {}", args.out.display())?;
        Ok(())
    })();
    renderer.destroy(&ctx);
    // Validation through the teardown: objects left alive are reported there.
    ctx.destroy_checked()?;
    printed
}

/// The per-pass GPU time table: medians over the frames rendered, with the last frame's
/// shader invocation counts where the device has pipeline statistics.
pub fn print_timings(renderer: &SceneRenderer, frames: u32) -> Result<(), CliError> {
    let medians = renderer.medians();
    let latest = renderer.executor().latest_timings();
    outln!(
        "\nGPU time per pass (median of {} frames, timestamps):",
        renderer
            .executor()
            .history()
            .frames()
            .min(u64::from(frames))
    )?;
    outln!(
        "  {:<22} {:>10} {:>14} {:>14}",
        "pass",
        "gpu ms",
        "vertex inv.",
        "fragment inv."
    )?;
    let mut total = 0.0;
    for m in &medians {
        let stats = latest.and_then(|t| t.passes.iter().find(|p| p.name == m.name));
        let fmt = |v: Option<u64>| v.map_or("-".to_string(), |x| x.to_string());
        outln!(
            "  {:<22} {:>10.3} {:>14} {:>14}",
            m.name,
            m.median_gpu_ms,
            fmt(stats.and_then(|s| s.vertex_invocations)),
            fmt(stats.and_then(|s| s.fragment_invocations))
        )?;
        total += m.median_gpu_ms;
    }
    outln!("  {:<22} {:>10.3}", "total", total)
}

fn bytes(b: u64) -> String {
    if b >= 1 << 20 {
        format!("{:.1} MiB", b as f64 / f64::from(1u32 << 20))
    } else {
        format!("{:.1} KiB", b as f64 / 1024.0)
    }
}
