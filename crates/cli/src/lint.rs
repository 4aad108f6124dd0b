//! `tilegraph lint`: one frame of a scene recorded under a profile, every pipeline it binds
//! checked against the profile's state rules (LRZ, FPK, HSR, early-Z), each finding with its
//! source.

use tilegraph_passes::lint::FrameLint;
use tilegraph_passes::{RenderOptions, SceneRenderer};
use tilegraph_scene::Scene;
use tilegraph_vk::{Context, FeatureRequest};

use crate::run::{RunArgs, TechniqueMeant};
use crate::CliError;

pub fn run(args: &RunArgs) -> Result<(), CliError> {
    let knobs = args.knob_settings(TechniqueMeant::Shading)?;
    let scene = crate::run::load_scene(&args.scene, crate::run::wants_clusters(&knobs))?;
    let (w, h) = args.size.unwrap_or((160, 90));
    crate::run::on_context(args.context_options(FeatureRequest::executor()), |ctx| {
        let mut ropts = RenderOptions {
            width: w,
            height: h,
            ..Default::default()
        };
        RunArgs::resolve(ctx, &scene, &knobs, &mut ropts)?;
        let lint = lint_scene(ctx, &scene, ropts.clone())?;
        print(args, &scene, &ropts, ctx, &lint)
    })
}

/// The lint of the first frame of the scene's camera path.
fn lint_scene(ctx: &Context, scene: &Scene, options: RenderOptions) -> Result<FrameLint, CliError> {
    let camera = scene
        .camera_path()
        .camera(0)
        .ok_or_else(|| CliError::Usage(format!("scene {:?} has no camera path", scene.name())))?;
    let mut renderer = SceneRenderer::new(ctx, scene, options)?;
    renderer.lint_next_frame();
    let report = renderer.render(ctx, scene, &camera);
    let finished = renderer.finish(ctx);
    renderer.destroy(ctx);
    let report = report?;
    finished?;
    Ok(report.lint.map(|l| (*l).clone()).unwrap_or_default())
}

fn print(
    args: &RunArgs,
    scene: &Scene,
    o: &RenderOptions,
    ctx: &Context,
    lint: &FrameLint,
) -> Result<(), CliError> {
    if args.json {
        let value = serde_json::json!({
            "scene": scene.name(),
            "profile": lint.profile,
            "device": ctx.physical.identity.device_name,
            "culling": o.culling.name(),
            "shading": o.technique.name(),
            "render_passes": lint.render_passes,
            "findings": lint.findings,
            "accepted_findings": lint.accepted_count(),
            "open_findings": lint.findings.len() - lint.accepted_count(),
        });
        outln!("{}", serde_json::to_string_pretty(&value)?)?;
        return Ok(());
    }
    outln!(
        "lint of {:?} under {} (culling {}, shading {}, {}x{}), recorded on {:?}",
        scene.name(),
        lint.profile,
        o.culling.name(),
        o.technique.name(),
        o.width,
        o.height,
        ctx.physical.identity.device_name
    )?;
    for rp in &lint.render_passes {
        outln!("render pass {}:", rp.index)?;
        for (i, d) in rp.draws.iter().enumerate() {
            let s = &d.state;
            outln!(
                "  {i:>3} {:<22} {:<34} depth {}{} {:?}{}{}{}",
                d.pass,
                s.pipeline,
                if s.depth_test { "test" } else { "-" },
                if s.depth_write { "+write" } else { "" },
                s.depth_compare,
                if s.blend { ", blend" } else { "" },
                if s.discard { ", discard" } else { "" },
                if s.storage_writes {
                    ", storage writes"
                } else {
                    ""
                },
            )?;
        }
    }
    outln!()?;
    if lint.findings.is_empty() {
        outln!("no findings")?;
    }
    // Findings to act on first; the accepted ones after, each with why the state is intended.
    for f in lint.findings.iter().filter(|f| f.accepted.is_none()) {
        outln!("{f}")?;
    }
    for f in &lint.findings {
        if let Some(reason) = &f.accepted {
            outln!("accepted: {f}\n    why: {reason}")?;
        }
    }
    outln!("{}", lint.summary())
}
