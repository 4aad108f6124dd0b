//! `tilegraph lint`: one frame of a scene recorded under a profile, every pipeline it binds
//! checked against the profile's state rules (LRZ, FPK, HSR, early-Z), each finding with its
//! source.

use tilegraph_passes::cull::Culling;
use tilegraph_passes::lint::FrameLint;
use tilegraph_passes::{RenderOptions, SceneRenderer, Technique};
use tilegraph_scene::Scene;
use tilegraph_vk::{Context, ContextOptions};

use crate::CliError;

pub struct Args<'a> {
    pub scene: &'a Scene,
    pub culling: Culling,
    pub shading: Technique,
    pub profile: Option<&'a str>,
    pub size: (u32, u32),
    pub json: bool,
}

pub fn run(args: &Args<'_>) -> Result<(), CliError> {
    let mut options = ContextOptions::from_env();
    if let Some(p) = args.profile {
        options.profile = Some(p.to_string());
    }
    let ropts = RenderOptions {
        technique: args.shading,
        culling: args.culling,
        width: args.size.0,
        height: args.size.1,
        ..Default::default()
    };
    options.features = ropts.device_features();
    let ctx = Context::new(options)?;
    let result = lint_scene(&ctx, args.scene, ropts);
    let printed = result.and_then(|lint| print(args, &ctx, &lint));
    ctx.destroy_checked()?;
    printed
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

fn print(args: &Args<'_>, ctx: &Context, lint: &FrameLint) -> Result<(), CliError> {
    if args.json {
        let value = serde_json::json!({
            "scene": args.scene.name(),
            "profile": lint.profile,
            "device": ctx.physical.identity.device_name,
            "culling": args.culling.name(),
            "shading": args.shading.name(),
            "render_passes": lint.render_passes,
            "findings": lint.findings,
        });
        outln!("{}", serde_json::to_string_pretty(&value)?)?;
        return Ok(());
    }
    outln!(
        "lint of {:?} under {} (culling {}, shading {}, {}x{}), recorded on {:?}",
        args.scene.name(),
        lint.profile,
        args.culling.name(),
        args.shading.name(),
        args.size.0,
        args.size.1,
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
    for f in &lint.findings {
        outln!("{f}")?;
    }
    outln!("{}", lint.summary())
}
