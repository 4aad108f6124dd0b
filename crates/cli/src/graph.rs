//! `tilegraph graph`: the compiled plan of one frame of a scene — its steps (`Plan`'s
//! `Display`) or its DOT — and the reason for every merge, load and store op, barrier and
//! attachment's traffic (`Plan::explain`).

use std::sync::Arc;

use tilegraph_graph::Plan;
use tilegraph_passes::{RenderOptions, SceneRenderer};
use tilegraph_vk::{Context, FeatureRequest};

use crate::run::{RunArgs, TechniqueMeant};
use crate::CliError;

pub fn run(a: &RunArgs, dot: bool) -> Result<(), CliError> {
    let knobs = a.knob_settings(TechniqueMeant::Shading)?;
    let scene = crate::run::load_scene(&a.scene, crate::run::wants_clusters(&knobs))?;
    let (w, h) = a.size.unwrap_or((320, 180));
    crate::run::on_context(a.context_options(FeatureRequest::executor()), |ctx| {
        let mut o = RenderOptions {
            width: w,
            height: h,
            ..Default::default()
        };
        let resolved = RunArgs::resolve(ctx, &scene, &knobs, &mut o)?;
        let plan = plan_of(ctx, &scene, o.clone(), a)?;
        print(a, dot, &plan, &o, &resolved)
    })
}

/// The plan of the first frame of the camera path.
fn plan_of(
    ctx: &Context,
    scene: &tilegraph_scene::Scene,
    options: RenderOptions,
    a: &RunArgs,
) -> Result<Arc<Plan>, CliError> {
    let path = a.camera_path(scene)?;
    let camera = path
        .camera(0)
        .ok_or_else(|| CliError::Usage("the camera path has no frames".into()))?;
    let mut renderer = SceneRenderer::new(ctx, scene, options)?;
    let report = renderer.render(ctx, scene, &camera);
    let finished = renderer.finish(ctx);
    renderer.destroy(ctx);
    let report = report?;
    finished?;
    Ok(report.plan)
}

fn print(
    a: &RunArgs,
    dot: bool,
    plan: &Plan,
    o: &RenderOptions,
    resolved: &tilegraph_passes::knobs::Resolved,
) -> Result<(), CliError> {
    if dot {
        outln!("{}", plan.to_dot())?;
        return Ok(());
    }
    let reasons = plan.explain();
    if a.json {
        let value = serde_json::json!({
            "profile": plan.profile,
            "culling": o.culling.name(),
            "shading": o.technique.name(),
            "knobs": resolved,
            "render_passes": plan.render_passes().count(),
            "barriers": plan.barrier_count(),
            "traffic_bytes": plan.traffic.planned.total_bytes(),
            "naive_traffic_bytes": plan.traffic.naive.total_bytes(),
            "plan": plan.to_string(),
            "reasons": reasons.iter().map(|r| serde_json::json!({
                "step": r.step.map(|s| s.0),
                "topic": r.topic.name(),
                "subject": r.subject,
                "decision": r.decision,
                "why": r.why,
            })).collect::<Vec<_>>(),
        });
        outln!("{}", serde_json::to_string_pretty(&value)?)?;
        return Ok(());
    }
    outln!(
        "plan of {:?} under {} (culling {}, shading {}, {}x{})\n",
        a.scene,
        plan.profile,
        o.culling.name(),
        o.technique.name(),
        o.width,
        o.height
    )?;
    outln!("{plan}")?;
    outln!("why:")?;
    for r in &reasons {
        outln!("  {r}")?;
    }
    Ok(())
}
