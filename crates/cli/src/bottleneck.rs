//! `tilegraph bottleneck SCENE`: seed 002's recipe for finding the limiting stage, automated.
//! Starting from the end of the pipeline, the frame is timed as it is and then with one stage's
//! work taken away at a time — the fragment shader made trivial (a fixed colour), the
//! resolution made tiny, the vertex shader made trivial (nothing rasterized), a quarter of
//! each mesh's triangles, a quarter of the instances — and its CPU time per frame is taken;
//! the stage whose removal saves most of the frame, in the recipe's order, is named, with the
//! measured savings and what to try for it.

use std::time::Instant;

use serde::Serialize;
use tilegraph_passes::cull::Culling;
use tilegraph_passes::{GpuTiming, RenderOptions, SceneRenderer, StageProbe};
use tilegraph_profile::knobs::KnobSettings;
use tilegraph_scene::{CameraPath, Scene};
use tilegraph_vk::queries::FRAME_TIMING;
use tilegraph_vk::{Context, FeatureRequest};

use crate::run::RunArgs;
use crate::CliError;

/// A probe counts when it saves at least this share of the frame.
pub const SIGNIFICANT: f64 = 0.15;
/// Fewer instances point at the draws (rather than the triangles) when they save this many
/// times what fewer triangles save.
const DRAWS_OVER_TRIANGLES: f64 = 1.5;
/// The CPU limits the frame when its time per frame exceeds the GPU's by this factor.
const CPU_OVER_GPU: f64 = 1.2;
/// The tiny resolution's side (seed 002: "something like 50x50"), at most a quarter of the
/// frame's.
const TINY: u32 = 50;
/// The share of triangles and of instances the thinned probes keep: 1 in 4.
const THIN: u32 = 4;

pub struct BottleneckArgs<'a> {
    pub run: &'a RunArgs,
    pub knobs: &'a KnobSettings,
    pub scene: &'a Scene,
    /// ALU iterations of the heavy material (`render --heavy`).
    pub heavy: u32,
}

/// The stage that limits the frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Stage {
    /// Fragment shading: a fixed colour saves the frame.
    Fragment,
    /// Per-pixel work besides shading — depth and colour writes, fill, bandwidth: a tiny
    /// resolution saves it.
    MemoryWrite,
    /// Per-object cost: a quarter of the instances saves far more than a quarter of their
    /// triangles.
    Draws,
    /// The number of vertices and triangles.
    Geometry,
    /// Vertex shading and primitive setup (a trivial vertex shader saves it, fewer triangles
    /// do not).
    Vertex,
    /// The CPU: recording and submitting takes longer than the GPU's frame.
    Cpu,
    /// None of the probes saves the frame: its fixed costs (passes, clears, barriers, culling
    /// dispatches).
    Fixed,
}

impl Stage {
    fn name(self) -> &'static str {
        match self {
            Stage::Fragment => "fragment shading",
            Stage::MemoryWrite => "memory writes (pixel fill)",
            Stage::Draws => "draws (per-object cost)",
            Stage::Geometry => "geometry (vertex and triangle count)",
            Stage::Vertex => "vertex shading",
            Stage::Cpu => "CPU (recording and submission)",
            Stage::Fixed => "fixed per-frame cost",
        }
    }

    /// What to try for it: tilegraph's knobs, cullings and shadings first.
    fn advice(self) -> &'static str {
        match self {
            Stage::Fragment => {
                "shade each pixel once: `--shading prepass` (EQUAL after a depth pre-pass) or \
                 `visbuf`; cull what is hidden before shading (`--culling hiz-2phase`); `tilegraph \
                 lint` names pipeline state that defeats early-Z, FPK, HSR or LRZ; a lighter material"
            }
            Stage::MemoryWrite => {
                "write fewer bytes per pixel: `--set depth_format=d16`, attachments kept in tile \
                 memory (`tilegraph graph` shows each attachment's traffic), a lower resolution"
            }
            Stage::Draws => {
                "fewer objects: merge small meshes so that instancing draws them together, \
                 cull whole instances cheaply (`--culling frustum` or `hiz-2phase`), and for \
                 cluster techniques a larger `cluster_gap`"
            }
            Stage::Geometry => {
                "fewer triangles: cluster culling (`--culling hiz-2phase-clusters` or \
                 `frustum-clusters`), an occlusion culling for hidden instances, coarser meshes \
                 far away"
            }
            Stage::Vertex => {
                "a lighter vertex shader; `--shading forward` without a pre-pass runs the vertex \
                 work once instead of twice"
            }
            Stage::Cpu => {
                "the render thread: GPU culling rather than `software-occlusion`, fewer views, \
                 scene edits batched per frame"
            }
            Stage::Fixed => {
                "the frame's fixed work: fewer passes, clears and barriers (`tilegraph graph`), \
                 the culling's own dispatches (`cull-check` reports their ms)"
            }
        }
    }
}

/// The frame as it is and under each probe: median GPU ms of the whole frame, and the median
/// CPU ms of a frame (recording and submission, and any wait for a free frame in flight).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Measured {
    /// The frame under the probes' culling ([`probe_culling`]), which the probes save from.
    pub frame_gpu_ms: f64,
    pub cpu_ms: f64,
    pub trivial_fragment_ms: f64,
    pub tiny_resolution_ms: f64,
    pub trivial_vertex_ms: f64,
    pub quarter_triangles_ms: f64,
    pub quarter_instances_ms: f64,
}

impl Measured {
    /// The share of the frame a probe taking `ms` saves (negative where it is slower).
    fn saving(&self, ms: f64) -> f64 {
        if self.frame_gpu_ms > 0.0 {
            1.0 - ms / self.frame_gpu_ms
        } else {
            0.0
        }
    }
}

/// The stage that limits the frame, and why. The probes overlap — a tiny frame also skips the
/// shading, a quarter of the triangles also a quarter of their pixels, a quarter of the
/// instances also their triangles — so each stage's share is estimated from the probe that
/// isolates it best: shading S = what a fixed colour saves, pixels P = what a tiny frame saves,
/// per triangle T and per instance I = what a quarter of them saves, scaled to all of them.
/// In order: the CPU if a frame takes it [`CPU_OVER_GPU`] times the GPU's; fragment shading if
/// S is [`SIGNIFICANT`] and at least half of P; draws if I is significant and
/// [`DRAWS_OVER_TRIANGLES`] times T; geometry if T is significant and clearly more than P
/// (small triangles: a tiny frame skips their raster setup too, but fewer of them save more);
/// memory writes if P is significant; vertex shading if the trivial vertex shader saves a
/// significant share; else the frame's fixed costs.
pub fn classify(m: &Measured) -> (Stage, String) {
    let base = m.frame_gpu_ms;
    let pct = |ms: f64| format!("{:.0} %", 100.0 * m.saving(ms));
    let share = |x: f64| if base > 0.0 { x / base } else { 0.0 };
    let (s, p, v) = (
        share(base - m.trivial_fragment_ms),
        share(base - m.tiny_resolution_ms),
        share(base - m.trivial_vertex_ms),
    );
    let scale = f64::from(THIN) / f64::from(THIN - 1);
    let t = (share(base - m.quarter_triangles_ms) * scale).min(1.0);
    let i = (share(base - m.quarter_instances_ms) * scale).min(1.0);
    if m.cpu_ms > CPU_OVER_GPU * base {
        return (
            Stage::Cpu,
            format!(
                "a frame takes {:.3} ms of CPU (recording and submission) against {:.3} ms of GPU",
                m.cpu_ms, base
            ),
        );
    }
    if s >= SIGNIFICANT && s >= 0.5 * p {
        return (
            Stage::Fragment,
            format!(
                "a fixed-colour fragment shader saves {}",
                pct(m.trivial_fragment_ms)
            ),
        );
    }
    if i >= SIGNIFICANT && i >= DRAWS_OVER_TRIANGLES * t {
        return (
            Stage::Draws,
            format!(
                "a quarter of the instances saves {}, a quarter of each mesh's triangles {}",
                pct(m.quarter_instances_ms),
                pct(m.quarter_triangles_ms)
            ),
        );
    }
    if t >= SIGNIFICANT && t > 1.25 * p {
        return (
            Stage::Geometry,
            format!(
                "a quarter of each mesh's triangles saves {} (a tiny frame {})",
                pct(m.quarter_triangles_ms),
                pct(m.tiny_resolution_ms)
            ),
        );
    }
    if p >= SIGNIFICANT {
        return (
            Stage::MemoryWrite,
            format!(
                "a tiny frame ({TINY}x{TINY} at most) saves {} where a fixed-colour fragment shader saves {}",
                pct(m.tiny_resolution_ms),
                pct(m.trivial_fragment_ms)
            ),
        );
    }
    if v >= SIGNIFICANT {
        return (
            Stage::Vertex,
            format!(
                "a trivial vertex shader saves {} where fewer triangles save {}",
                pct(m.trivial_vertex_ms),
                pct(m.quarter_triangles_ms)
            ),
        );
    }
    (
        Stage::Fixed,
        format!(
            "no probe saves {:.0} % of the {:.3} ms frame, and the CPU keeps up ({:.3} ms)",
            100.0 * SIGNIFICANT,
            base,
            m.cpu_ms
        ),
    )
}

/// The culling the probes run under: the configured one where it does not read the frame's
/// depth or the scene's instance numbering, else frustum culling (of clusters for a cluster
/// technique). A trivial vertex shader leaves the depth empty, a tiny frame coarse and the
/// thinned scenes full of holes: occlusion culling would cull differently under each probe
/// (HiZ culls nothing behind an empty depth), and the probes would time another frame.
pub fn probe_culling(c: Culling) -> Culling {
    match c {
        Culling::None | Culling::Frustum | Culling::FrustumClusters => c,
        c if c.clusters() => Culling::FrustumClusters,
        _ => Culling::Frustum,
    }
}

/// `bottleneck --json`.
#[derive(Serialize)]
struct Report<'a> {
    scene: &'a str,
    device: &'a str,
    profile: &'a str,
    culling: &'static str,
    /// The culling the probes ran under, and the frame under the configured one where they
    /// differ.
    probe_culling: &'static str,
    configured_frame_gpu_ms: f64,
    shading: &'static str,
    size: [u32; 2],
    frames: u32,
    measured: Measured,
    stage: Stage,
    reason: &'a str,
    advice: &'static str,
}

pub fn run(args: &BottleneckArgs<'_>) -> Result<(), CliError> {
    let run = args.run;
    crate::run::on_context(run.context_options(FeatureRequest::executor()), |ctx| {
        let (w, h) = run.size.unwrap_or((320, 180));
        let frames = run.frames.unwrap_or(24);
        let mut options = RenderOptions {
            width: w,
            height: h,
            ..Default::default()
        };
        RunArgs::resolve(ctx, args.scene, args.knobs, &mut options)?;
        if options.technique.screen_space() {
            return Err(CliError::Usage(format!(
                "bottleneck: its probes make the forward colour and vertex shaders trivial, and \
                 {} shading resolves in shaders of its own: run it with --shading forward \
                 or prepass",
                options.technique.name()
            )));
        }
        options.lighting.heavy_iterations = args.heavy;
        let configured = options.clone();
        options.culling = probe_culling(options.culling);
        let path = run.camera_path(args.scene)?;
        let time =
            |scene: &Scene, options: RenderOptions| time_frames(ctx, scene, options, &path, frames);
        let probe = |p: StageProbe| RenderOptions {
            probe: p,
            ..options.clone()
        };
        let tiny = ((w / 4).clamp(1, TINY), (h / 4).clamp(1, TINY));
        let (frame_gpu_ms, cpu_ms) = time(args.scene, options.clone())?;
        let configured_frame_gpu_ms = if configured.culling == options.culling {
            frame_gpu_ms
        } else {
            time(args.scene, configured.clone())?.0
        };
        // The thinned scenes, with clusters of their own where the scene has them.
        let thinned = |triangles: u32, instances: u32| -> Result<Scene, CliError> {
            let mut s = args.scene.thinned(triangles, instances)?;
            if args.scene.clusters().is_some() {
                let name = s.name().to_string();
                crate::run::attach_clusters(&mut s, &name, false)?;
            }
            Ok(s)
        };
        let fewer_triangles = thinned(THIN, 1)?;
        let fewer_instances = thinned(1, THIN)?;
        let m = Measured {
            frame_gpu_ms,
            cpu_ms,
            trivial_fragment_ms: time(
                args.scene,
                probe(StageProbe {
                    trivial_fragment: true,
                    ..Default::default()
                }),
            )?
            .0,
            tiny_resolution_ms: time(
                args.scene,
                RenderOptions {
                    width: tiny.0,
                    height: tiny.1,
                    ..options.clone()
                },
            )?
            .0,
            trivial_vertex_ms: time(
                args.scene,
                probe(StageProbe {
                    trivial_vertex: true,
                    ..Default::default()
                }),
            )?
            .0,
            quarter_triangles_ms: time(&fewer_triangles, options.clone())?.0,
            quarter_instances_ms: time(&fewer_instances, options.clone())?.0,
        };
        let (stage, reason) = classify(&m);
        let report = Report {
            scene: args.scene.name(),
            device: &ctx.physical.identity.device_name,
            profile: &ctx.profile().name,
            culling: configured.culling.name(),
            probe_culling: options.culling.name(),
            configured_frame_gpu_ms,
            shading: options.technique.name(),
            size: [w, h],
            frames,
            measured: m,
            stage,
            reason: &reason,
            advice: stage.advice(),
        };
        print(run.json, &report)
    })
}

fn print(json: bool, r: &Report<'_>) -> Result<(), CliError> {
    if json {
        let text = serde_json::to_string_pretty(r).map_err(|e| CliError::Usage(e.to_string()))?;
        return outln!("{text}");
    }
    let m = &r.measured;
    outln!(
        "{} on {} ({}), {} {} at {}x{}, {} frames (medians):",
        r.scene,
        r.device,
        r.profile,
        r.shading,
        r.culling,
        r.size[0],
        r.size[1],
        r.frames
    )?;
    if r.probe_culling != r.culling {
        outln!(
            "  the frame with {}: {:.3} ms; the probes run with {} (they change the depth that {} reads)",
            r.culling,
            r.configured_frame_gpu_ms,
            r.probe_culling,
            r.culling
        )?;
    }
    outln!("  {:<44} {:>9} {:>8}", "probe", "GPU ms", "saves")?;
    for (what, ms) in [
        ("the frame (the probes' culling)", m.frame_gpu_ms),
        ("fragment shader: a fixed colour", m.trivial_fragment_ms),
        ("resolution: tiny (50x50 at most)", m.tiny_resolution_ms),
        (
            "vertex shader: trivial, nothing rasterized",
            m.trivial_vertex_ms,
        ),
        ("a quarter of each mesh's triangles", m.quarter_triangles_ms),
        ("a quarter of the instances", m.quarter_instances_ms),
    ] {
        outln!("  {what:<44} {ms:>9.3} {:>7.0} %", 100.0 * m.saving(ms))?;
    }
    outln!("  CPU per frame: {:.3} ms", m.cpu_ms)?;
    outln!("bottleneck: {} — {}", r.stage.name(), r.reason)?;
    outln!("try: {}", r.advice)
}

/// Median whole-frame GPU ms and CPU ms per frame of `frames` frames along `path` (after the
/// warm-up every timed run has).
pub(crate) fn time_frames(
    ctx: &Context,
    scene: &Scene,
    options: RenderOptions,
    path: &CameraPath,
    frames: u32,
) -> Result<(f64, f64), CliError> {
    let mut renderer = SceneRenderer::new(ctx, scene, options)?;
    let result = (|| {
        renderer.set_gpu_timing(ctx, GpuTiming::Frame)?;
        let camera = |i: usize| path.camera(i % path.len().max(1));
        let warm = Instant::now();
        let mut i = 0;
        while warm.elapsed() < crate::run::TIMING_WARMUP || i < 2 {
            if let Some(c) = camera(i) {
                renderer.render(ctx, scene, &c)?;
            }
            i += 1;
        }
        renderer.finish(ctx)?;
        renderer.clear_timings();
        let mut cpu = Vec::with_capacity(frames as usize);
        for i in 0..frames as usize {
            let Some(c) = camera(i) else { break };
            let started = Instant::now();
            renderer.render(ctx, scene, &c)?;
            cpu.push(started.elapsed().as_secs_f64() * 1e3);
        }
        renderer.finish(ctx)?;
        let gpu = renderer
            .medians()
            .iter()
            .find(|m| m.name == FRAME_TIMING)
            .map_or(0.0, |m| m.median_gpu_ms);
        Ok::<_, CliError>((gpu, tilegraph_vk::queries::median(&cpu).unwrap_or(0.0)))
    })();
    renderer.destroy(ctx);
    result
}

#[cfg(test)]
mod tests {
    use super::*;

    /// (frame, cpu, fixed colour, tiny, trivial vertex, quarter triangles, quarter instances).
    fn measured(ms: [f64; 7]) -> Measured {
        Measured {
            frame_gpu_ms: ms[0],
            cpu_ms: ms[1],
            trivial_fragment_ms: ms[2],
            tiny_resolution_ms: ms[3],
            trivial_vertex_ms: ms[4],
            quarter_triangles_ms: ms[5],
            quarter_instances_ms: ms[6],
        }
    }

    #[test]
    fn the_h100_cases_are_named_as_constructed() {
        // H100 80GB HBM3, 580.159.04, 1080p, 48 frames (docs/TUNING.md, "Finding the
        // bottleneck"): a heavy material, dense meshes, a million small draws, the city as
        // shipped, the Godot rooms unculled.
        let cases = [
            (
                [69.386, 69.440, 0.789, 0.323, 0.422, 27.742, 58.530],
                Stage::Fragment,
            ),
            (
                [22.802, 22.772, 19.971, 14.471, 8.631, 6.020, 5.928],
                Stage::Geometry,
            ),
            (
                [84.239, 318.857, 79.257, 79.156, 79.205, 78.236, 38.498],
                Stage::Cpu,
            ),
            (
                [0.815, 0.839, 0.790, 0.112, 0.422, 0.580, 0.710],
                Stage::MemoryWrite,
            ),
            (
                [120.810, 120.822, 106.392, 120.475, 41.488, 30.411, 30.415],
                Stage::Geometry,
            ),
        ];
        for (ms, want) in cases {
            let (got, why) = classify(&measured(ms));
            assert_eq!(got, want, "{ms:?}: {why}");
        }
    }

    #[test]
    fn each_stage_is_reachable() {
        // Per-object GPU cost: fewer instances save, fewer of their triangles little.
        let draws = measured([10.0, 1.0, 9.8, 9.7, 9.0, 9.6, 4.0]);
        assert_eq!(classify(&draws).0, Stage::Draws);
        // A heavy vertex shader over few triangles.
        let vertex = measured([10.0, 1.0, 9.9, 9.5, 6.0, 9.2, 9.2]);
        assert_eq!(classify(&vertex).0, Stage::Vertex);
        // Big triangles, fill-bound: fewer triangles save their pixels, no more than a tiny
        // frame does.
        let fill = measured([10.0, 1.0, 9.5, 2.0, 2.0, 3.0, 3.0]);
        assert_eq!(classify(&fill).0, Stage::MemoryWrite);
        let fixed = measured([10.0, 1.0, 9.9, 9.8, 9.7, 9.6, 9.5]);
        let (stage, why) = classify(&fixed);
        assert_eq!(stage, Stage::Fixed);
        assert!(why.contains("10.000 ms"), "{why}");
        // A GPU frame of nothing divides by nothing: the CPU limits it.
        let zero = Measured {
            frame_gpu_ms: 0.0,
            ..fixed
        };
        assert_eq!(classify(&zero).0, Stage::Cpu);
    }

    #[test]
    fn occlusion_cullings_give_way_to_frustum_culling_under_the_probes() {
        assert_eq!(probe_culling(Culling::HizTwoPhase), Culling::Frustum);
        assert_eq!(probe_culling(Culling::Oq), Culling::Frustum);
        assert_eq!(probe_culling(Culling::Pvs), Culling::Frustum);
        assert_eq!(
            probe_culling(Culling::HizTwoPhaseClusters),
            Culling::FrustumClusters
        );
        assert_eq!(probe_culling(Culling::None), Culling::None);
        assert_eq!(
            probe_culling(Culling::FrustumClusters),
            Culling::FrustumClusters
        );
    }
}
