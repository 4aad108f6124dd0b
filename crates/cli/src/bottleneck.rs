//! `tilegraph bottleneck SCENE`: seed 002's recipe for finding the limiting stage, automated.
//! Starting from the end of the pipeline, the frame is timed as it is and then with one stage's
//! work taken away at a time — the fragment shader made trivial (a fixed colour), the
//! resolution made tiny, the vertex shader made trivial (nothing rasterized), a quarter of
//! each mesh's triangles, a quarter of the instances — and its CPU time per frame is taken;
//! the stage whose removal saves most of the frame, in the recipe's order, is named, with the
//! measured savings and what to try for it.

use std::time::Instant;

use serde::Serialize;
use tilegraph_passes::{GpuTiming, RenderOptions, SceneRenderer, StageProbe, Technique};
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

/// The stage that limits the frame, and why, from the recipe's end of the pipeline backwards:
/// the first probe that saves at least [`SIGNIFICANT`] of the frame names it; with none, the
/// CPU if it takes longer than the GPU, else the frame's fixed costs.
pub fn classify(m: &Measured) -> (Stage, String) {
    let pct = |ms: f64| format!("{:.0} %", 100.0 * m.saving(ms));
    let (f, r, v) = (
        m.saving(m.trivial_fragment_ms),
        m.saving(m.tiny_resolution_ms),
        m.saving(m.trivial_vertex_ms),
    );
    let (tris, insts) = (
        m.saving(m.quarter_triangles_ms),
        m.saving(m.quarter_instances_ms),
    );
    if f >= SIGNIFICANT {
        return (
            Stage::Fragment,
            format!(
                "a fixed-colour fragment shader saves {}",
                pct(m.trivial_fragment_ms)
            ),
        );
    }
    if r >= SIGNIFICANT {
        return (
            Stage::MemoryWrite,
            format!(
                "a tiny frame ({TINY}x{TINY} at most) saves {} where a trivial fragment shader saves {}",
                pct(m.tiny_resolution_ms),
                pct(m.trivial_fragment_ms)
            ),
        );
    }
    if insts >= SIGNIFICANT && insts >= DRAWS_OVER_TRIANGLES * tris.max(0.0) {
        return (
            Stage::Draws,
            format!(
                "a quarter of the instances saves {}, a quarter of each mesh's triangles {}",
                pct(m.quarter_instances_ms),
                pct(m.quarter_triangles_ms)
            ),
        );
    }
    if tris >= SIGNIFICANT {
        return (
            Stage::Geometry,
            format!(
                "a quarter of each mesh's triangles saves {}",
                pct(m.quarter_triangles_ms)
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
    if m.cpu_ms > CPU_OVER_GPU * m.frame_gpu_ms {
        return (
            Stage::Cpu,
            format!(
                "no probe saves {:.0} % of the GPU's {:.3} ms, and a frame takes {:.3} ms of CPU",
                100.0 * SIGNIFICANT,
                m.frame_gpu_ms,
                m.cpu_ms
            ),
        );
    }
    (
        Stage::Fixed,
        format!(
            "no probe saves {:.0} % of the {:.3} ms frame, and the CPU keeps up ({:.3} ms)",
            100.0 * SIGNIFICANT,
            m.frame_gpu_ms,
            m.cpu_ms
        ),
    )
}

/// `bottleneck --json`.
#[derive(Serialize)]
struct Report<'a> {
    scene: &'a str,
    device: &'a str,
    profile: &'a str,
    culling: &'static str,
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
        if options.technique == Technique::Visbuf {
            return Err(CliError::Usage(
                "bottleneck: its probes make the forward colour and vertex shaders trivial, and                  visbuf shading resolves in shaders of its own: run it with --shading forward                  or prepass"
                    .into(),
            ));
        }
        options.lighting.heavy_iterations = args.heavy;
        let path = run.camera_path(args.scene)?;
        let time =
            |scene: &Scene, options: RenderOptions| time_frames(ctx, scene, options, &path, frames);
        let probe = |p: StageProbe| RenderOptions {
            probe: p,
            ..options.clone()
        };
        let tiny = ((w / 4).clamp(1, TINY), (h / 4).clamp(1, TINY));
        let (frame_gpu_ms, cpu_ms) = time(args.scene, options.clone())?;
        let fewer_triangles = args.scene.thinned(THIN, 1)?;
        let fewer_instances = args.scene.thinned(1, THIN)?;
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
            culling: options.culling.name(),
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
    outln!("  {:<44} {:>9} {:>8}", "probe", "GPU ms", "saves")?;
    for (what, ms) in [
        ("the frame as it is", m.frame_gpu_ms),
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
fn time_frames(
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

    fn measured(f: f64, r: f64, v: f64, t: f64, i: f64, cpu: f64) -> Measured {
        Measured {
            frame_gpu_ms: 10.0,
            cpu_ms: cpu,
            trivial_fragment_ms: f,
            tiny_resolution_ms: r,
            trivial_vertex_ms: v,
            quarter_triangles_ms: t,
            quarter_instances_ms: i,
        }
    }

    #[test]
    fn the_recipe_names_the_first_stage_that_saves_the_frame() {
        // A heavy material: shading is most of it (and a tiny frame saves it too).
        let heavy = measured(2.0, 1.0, 1.5, 7.0, 3.0, 0.5);
        assert_eq!(classify(&heavy).0, Stage::Fragment);
        // Fill: the shader is cheap, the pixels are not.
        let fill = measured(9.5, 3.0, 4.0, 9.0, 7.0, 0.5);
        assert_eq!(classify(&fill).0, Stage::MemoryWrite);
        // Dense meshes: fewer triangles save in proportion, fewer instances no more.
        let dense = measured(9.8, 9.5, 2.0, 3.5, 3.0, 0.5);
        assert_eq!(classify(&dense).0, Stage::Geometry);
        // Many small draws: fewer instances save, their few triangles do not.
        let draws = measured(9.9, 9.8, 8.0, 9.5, 3.0, 0.5);
        assert_eq!(classify(&draws).0, Stage::Draws);
        // A heavy vertex shader: the trivial one saves, fewer triangles less than 15 %.
        let vertex = measured(9.9, 9.8, 6.0, 9.0, 9.0, 0.5);
        assert_eq!(classify(&vertex).0, Stage::Vertex);
        // Nothing on the GPU helps, the CPU takes longer: CPU; keeps up: fixed costs.
        let cpu = measured(9.9, 9.8, 9.7, 9.6, 9.5, 20.0);
        assert_eq!(classify(&cpu).0, Stage::Cpu);
        let fixed = measured(9.9, 9.8, 9.7, 9.6, 9.5, 1.0);
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
}
