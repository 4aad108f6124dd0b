//! `tilegraph render` and the demo frame: a scene drawn with the profile's passes (and the
//! knobs' culling), the per-pass GPU time table (medians over frames, from timestamps), and a PNG.

use std::path::Path;

use serde::Serialize;
use tilegraph_passes::knobs::Resolved;
use tilegraph_passes::{FrameReport, GpuTiming, RenderOptions, SceneRenderer};
use tilegraph_scene::Scene;
use tilegraph_vk::queries::{FrameTimings, PassMedian, FRAME_TIMING};
use tilegraph_vk::{Context, FeatureRequest};

use tilegraph_profile::knobs::KnobSettings;

use crate::run::RunArgs;
use crate::timeline::{overlap, Overlap, PassSpan, Timeline};
use crate::{image_io, CliError};

pub struct RenderArgs<'a> {
    pub run: &'a RunArgs,
    /// The knobs the run sets (`RunArgs::knob_settings`).
    pub knobs: &'a KnobSettings,
    pub scene: &'a Scene,
    pub heavy: u32,
    pub camera_frame: usize,
    pub out: &'a Path,
}

/// `render --json`: what was drawn, how, and what it cost.
#[derive(Serialize)]
struct RenderJson<'a> {
    scene: &'a str,
    instances: usize,
    device: &'a str,
    profile: &'a str,
    profile_matched_by: String,
    culling: &'static str,
    shading: &'static str,
    #[serde(flatten)]
    knobs: &'a Resolved,
    auto_trial: Option<&'a str>,
    size: [u32; 2],
    frames: u32,
    passes: Vec<PassJson<'a>>,
    render_passes: usize,
    barriers: usize,
    traffic_bytes: u64,
    naive_traffic_bytes: u64,
    draws: usize,
    triangles: u64,
    /// Shadow casters the last frame drew per cascade (with shadows and a GPU draw count).
    shadow_casters: Option<[u32; 4]>,
    lint_findings: usize,
    gpu_ms: Vec<TimingJson>,
    /// Each pass's queue and median start and end in the frame (per-pass timing).
    timeline: &'a [PassSpan],
    /// The async compute queue's time against the graphics queue's passes.
    async_overlap: Option<Overlap>,
    /// Median of the whole frame (timed with two timestamps, no per-pass queries).
    frame_gpu_ms: f64,
    /// The passes' medians summed: the frame without what lies between its passes.
    passes_gpu_ms: f64,
    out: String,
}

#[derive(Serialize)]
struct PassJson<'a> {
    pass: &'static str,
    included: bool,
    reason: &'a str,
}

#[derive(Serialize)]
struct TimingJson {
    pass: String,
    median_gpu_ms: f64,
}

/// The scene a render draws: as loaded, or moving one frame further at every frame
/// (`SPEC@moving`, [`crate::run::split_motion`]).
struct World<'a> {
    still: &'a tilegraph_scene::Scene,
    moving: Option<(tilegraph_scene::Scene, tilegraph_scene::Motion)>,
    frame: usize,
}

impl World<'_> {
    /// The scene of the next frame.
    fn next(&mut self) -> Result<&tilegraph_scene::Scene, CliError> {
        let Some((scene, motion)) = &mut self.moving else {
            return Ok(self.still);
        };
        motion.apply(scene, self.frame)?;
        self.frame += 1;
        Ok(scene)
    }
}

pub fn run(args: &RenderArgs<'_>) -> Result<(), CliError> {
    image_io::check_png_path(args.out)?;
    let run = args.run;
    let (w, h) = run.size.unwrap_or((320, 180));
    let frames = run.frames.unwrap_or(16);
    crate::run::on_context(run.context_options(FeatureRequest::executor()), |ctx| {
        render_with(ctx, args, (w, h), frames)
    })
}

fn render_with(
    ctx: &Context,
    args: &RenderArgs<'_>,
    (w, h): (u32, u32),
    frames: u32,
) -> Result<(), CliError> {
    let run = args.run;
    let scene = args.scene;
    let mut ropts = RenderOptions {
        width: w,
        height: h,
        ..Default::default()
    };
    ropts.pvs = run.load_pvs()?;
    let resolved = RunArgs::resolve(ctx, scene, args.knobs, &mut ropts)?;
    ropts.lighting.heavy_iterations = args.heavy;
    ropts.texture_binding = run.texture_binding;
    let path = run.camera_path(scene)?;
    let camera = path.camera(args.camera_frame).ok_or_else(|| {
        CliError::Usage(format!(
            "camera frame {} is outside the camera path of {} frames",
            args.camera_frame,
            path.len()
        ))
    })?;
    let mut world = World {
        still: scene,
        moving: crate::run::split_motion(&run.scene)?
            .1
            .map(|p| (scene.clone(), tilegraph_scene::Motion::new(scene, &path, p))),
        frame: 0,
    };
    let mut renderer = SceneRenderer::new(ctx, scene, ropts.clone())?;
    let mut trial_reason = None;
    // `auto`: time every candidate on this device first, keep the fastest.
    let inputs = crate::run::auto_inputs(ctx, scene, ropts.pvs.as_deref());
    if let Some(mut trial) = resolved.auto_trial(inputs) {
        while trial_reason.is_none() {
            let drawn = world
                .next()
                .and_then(|s| Ok(renderer.render(ctx, s, &camera)?));
            if let Err(e) = drawn {
                renderer.destroy(ctx);
                return Err(e);
            }
            // On an error the trial has destroyed the renderer.
            let (next, why) = trial.after_render(ctx, scene, renderer, &mut ropts)?;
            renderer = next;
            trial_reason = why;
        }
    }
    let result = (|| {
        renderer.finish(ctx)?;
        renderer.clear_timings();
        let mut last: Option<FrameReport> = None;
        let mut lint = None;
        let mut timeline = Timeline::default();
        let period_ns = f64::from(ctx.physical.limits.timestamp_period_ns);
        renderer.lint_next_frame();
        for _ in 0..frames {
            let report = renderer.render(ctx, world.next()?, &camera)?;
            timeline.gather(renderer.executor().latest_timings(), period_ns);
            lint = lint.or_else(|| report.lint.clone());
            last = Some(report);
        }
        renderer.finish(ctx)?;
        timeline.gather(renderer.executor().latest_timings(), period_ns);
        let image = renderer.read_image(ctx)?;
        let casters = renderer.read_shadow_casters(ctx)?;
        // The same frames again with two timestamps each and no per-pass queries: the frame
        // time, with what lies between the passes (clears, stores, barriers).
        let passes = Timed {
            spans: timeline.spans(last.as_ref().map(|r| r.plan.as_ref())),
            medians: renderer.medians(),
            latest: renderer.executor().latest_timings().cloned(),
            frames: renderer
                .executor()
                .history()
                .frames()
                .min(u64::from(frames)),
            frame_ms: None,
        };
        renderer.set_gpu_timing(ctx, GpuTiming::Frame)?;
        for _ in 0..frames {
            renderer.render(ctx, world.next()?, &camera)?;
        }
        renderer.finish(ctx)?;
        let timed = Timed {
            frame_ms: renderer
                .medians()
                .iter()
                .find(|m| m.name == FRAME_TIMING)
                .map(|m| m.median_gpu_ms),
            ..passes
        };
        Ok::<_, CliError>((last, lint, image, timed, casters))
    })();
    let (report, lint, image, timed, casters) = match result {
        Ok(v) => v,
        Err(e) => {
            renderer.destroy(ctx);
            return Err(e);
        }
    };
    // Written and printed before the renderer is destroyed (the timings live in it); destroyed
    // whatever writing or printing did (a full disk, a closed pipe).
    let printed = (|| -> Result<(), CliError> {
        image_io::write_png(args.out, &image)?;
        if run.json {
            let medians = &timed.medians;
            let json = RenderJson {
                scene: scene.name(),
                instances: scene.instances().len(),
                device: &ctx.physical.identity.device_name,
                profile: &ctx.profile().name,
                profile_matched_by: ctx.selection.matched_by.to_string(),
                culling: ropts.culling.name(),
                shading: ropts.technique.name(),
                knobs: &resolved,
                auto_trial: trial_reason.as_deref(),
                size: [w, h],
                frames,
                passes: report
                    .iter()
                    .flat_map(|r| r.setup.decisions.iter())
                    .map(|d| PassJson {
                        pass: d.pass.name(),
                        included: d.included,
                        reason: &d.reason,
                    })
                    .collect(),
                render_passes: report
                    .as_ref()
                    .map_or(0, |r| r.plan.render_passes().count()),
                barriers: report.as_ref().map_or(0, |r| r.plan.barrier_count()),
                traffic_bytes: report
                    .as_ref()
                    .map_or(0, |r| r.plan.traffic.planned.total_bytes()),
                naive_traffic_bytes: report
                    .as_ref()
                    .map_or(0, |r| r.plan.traffic.naive.total_bytes()),
                draws: report.as_ref().map_or(0, |r| r.draws),
                triangles: report.as_ref().map_or(0, |r| r.triangles),
                shadow_casters: casters,
                lint_findings: lint.as_ref().map_or(0, |l| l.findings.len()),
                frame_gpu_ms: timed.frame_ms.unwrap_or(0.0),
                passes_gpu_ms: medians.iter().map(|m| m.median_gpu_ms).sum(),
                timeline: &timed.spans,
                async_overlap: overlap(&timed.spans),
                gpu_ms: medians
                    .iter()
                    .map(|m| TimingJson {
                        pass: m.name.to_string(),
                        median_gpu_ms: m.median_gpu_ms,
                    })
                    .collect(),
                out: args.out.display().to_string(),
            };
            outln!("{}", serde_json::to_string(&json)?)?;
            return Ok(());
        }
        outln!(
            "scene {:?}: {} instances; device {:?}; profile {} ({}); culling {}; shading {}; {}x{}",
            scene.name(),
            scene.instances().len(),
            ctx.physical.identity.device_name,
            ctx.profile().name,
            ctx.selection.matched_by,
            ropts.culling.name(),
            ropts.technique.name(),
            w,
            h
        )?;
        outln!("\nknobs:")?;
        for line in resolved.describe() {
            outln!("  {line}")?;
        }
        if let Some(why) = &trial_reason {
            outln!("  then {why}")?;
        }
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
        if let Some(c) = casters {
            let cascades = ropts.shadows.cascades as usize;
            outln!(
                "shadow casters drawn per cascade ({}): {:?}",
                ropts.shadows.culling.name(),
                &c[..cascades.min(4)]
            )?;
        }
        if let Some(l) = &lint {
            outln!("{}", l.summary())?;
        }
        print_timings(ctx, &timed)?;
        outln!("wrote {}", args.out.display())?;
        Ok(())
    })();
    renderer.destroy(ctx);
    printed
}

/// What `render` timed: each pass over its frames, then the whole frame over as many again.
struct Timed {
    medians: Vec<PassMedian>,
    spans: Vec<PassSpan>,
    latest: Option<FrameTimings>,
    /// Frames the pass medians cover.
    frames: u64,
    frame_ms: Option<f64>,
}

/// The per-pass GPU time table: medians over the frames rendered (each pass's queue, time, and
/// start and end since the frame's first timestamp), with the last frame's shader invocation
/// counts where the device has pipeline statistics; then the async compute queue's overlap with
/// the graphics queue, and the whole frame.
fn print_timings(ctx: &Context, timed: &Timed) -> Result<(), CliError> {
    outln!(
        "\nGPU time per pass (median of {} frames, timestamps):",
        timed.frames
    )?;
    outln!(
        "  {:<22} {:<14} {:>8} {:>8} {:>8} {:>14} {:>14}",
        "pass",
        "queue",
        "gpu ms",
        "start",
        "end",
        "vertex inv.",
        "fragment inv."
    )?;
    let mut total = 0.0;
    for m in &timed.medians {
        let stats = timed
            .latest
            .as_ref()
            .and_then(|t| t.passes.iter().find(|p| p.name == m.name));
        let span = timed.spans.iter().find(|s| s.pass == m.name);
        let fmt = |v: Option<u64>| v.map_or("-".to_string(), |x| x.to_string());
        let at = |v: Option<f64>| v.map_or("-".to_string(), |x| format!("{x:.3}"));
        outln!(
            "  {:<22} {:<14} {:>8.3} {:>8} {:>8} {:>14} {:>14}",
            m.name,
            span.map_or("-", |s| s.queue),
            m.median_gpu_ms,
            at(span.map(|s| s.start_ms)),
            at(span.map(|s| s.end_ms)),
            fmt(stats.and_then(|s| s.vertex_invocations)),
            fmt(stats.and_then(|s| s.fragment_invocations))
        )?;
        total += m.median_gpu_ms;
    }
    outln!("  {:<22} {:<14} {:>8.3}", "passes", "", total)?;
    if let Some(o) = overlap(&timed.spans) {
        outln!(
            "  async compute queue busy {:.3} ms: {:.3} beside graphics passes, {:.3} between \
             them (the graphics queue's barriers, clears, load/store ops, or its waits)",
            o.busy_ms,
            o.beside_passes_ms,
            o.between_passes_ms
        )?;
    }
    if let Some(ms) = timed.frame_ms {
        outln!(
            "  {:<22} {:<14} {:>8.3}   (timed whole, no per-pass queries: clears, stores, barriers included)",
            "frame",
            "",
            ms
        )?;
    }
    if let Some(caveat) = crate::device_caveat(ctx) {
        outln!("  {caveat}")?;
    }
    Ok(())
}

fn bytes(b: u64) -> String {
    if b >= 1 << 20 {
        format!("{:.1} MiB", b as f64 / f64::from(1u32 << 20))
    } else {
        format!("{:.1} KiB", b as f64 / 1024.0)
    }
}
