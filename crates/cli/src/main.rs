//! `tilegraph`: the command-line face of the library. Thin: parsing, printing, files.

/// `println!` that reports failure instead of panicking: `outln!(...)?`. A closed pipe
/// (`tilegraph devices | head -1`) ends the command quietly, as other Unix tools do.
macro_rules! outln {
    () => {
        $crate::write_line(format_args!(""))
    };
    ($($arg:tt)*) => {
        $crate::write_line(format_args!($($arg)*))
    };
}

mod cullcheck;
mod devices;
mod image_io;
mod lint;
mod render;

use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};
use tilegraph_passes::cull::Culling;
use tilegraph_passes::Technique;

#[derive(Parser)]
#[command(
    name = "tilegraph",
    version,
    about = "Render graphs for tile-based GPUs, validated on lavapipe"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// List every Vulkan device, its identity, the profile chosen and why, and the memory type
    /// chosen for each use.
    Devices {
        /// One JSON array instead of a table.
        #[arg(long)]
        json: bool,
    },
    /// The demo: device discovery, then the embedded city drawn with the profile's passes,
    /// its per-pass GPU time table, and the frame as PNG.
    Demo {
        /// Where to write the frame.
        #[arg(long, default_value = "target/demo/frame.png")]
        out: PathBuf,
        /// Frame size, WxH.
        #[arg(long, default_value = "320x180", value_parser = parse_size)]
        size: (u32, u32),
        /// Frames to render (timings are medians over them).
        #[arg(long, default_value_t = 16)]
        frames: u32,
    },
    /// Render a scene with a technique and profile; print the passes chosen and the per-pass
    /// GPU time table; write the image.
    Render {
        /// A .gltf/.glb path, or city|forest|field|interior[:size[:seed]], or `default`.
        scene: String,
        #[arg(long, default_value = "forward", value_parser = parse_technique)]
        technique: Technique,
        /// Force a profile (as TILEGRAPH_PROFILE does).
        #[arg(long)]
        profile: Option<String>,
        #[arg(long, default_value = "320x180", value_parser = parse_size)]
        size: (u32, u32),
        #[arg(long, default_value = "frame.png")]
        out: PathBuf,
        /// Frames to render (timings are medians over them).
        #[arg(long, default_value_t = 16)]
        frames: u32,
        /// ALU iterations of the heavy material (0 = plain Lambert).
        #[arg(long, default_value_t = 0)]
        heavy: u32,
        /// Which frame of the scene's camera path to look from.
        #[arg(long, default_value_t = 0)]
        camera_frame: usize,
    },
    /// Render every frame of a camera path with a culling technique and with the exact oracle;
    /// report visible, drawn, false negatives and positives, and image equality per frame.
    CullCheck {
        /// A .gltf/.glb path, or city|forest|field|interior[:size[:seed]], or `default`.
        scene: String,
        /// none | frustum | hiz | hiz-2phase | oq | oq-conditional | raster-occlusion
        #[arg(long, value_parser = parse_culling)]
        technique: Culling,
        /// Camera path JSON (docs/SCENES.md); the scene's own test path when absent.
        #[arg(long)]
        camera_path: Option<PathBuf>,
        #[arg(long, default_value = "320x180", value_parser = parse_size)]
        size: (u32, u32),
        /// Force a profile (as TILEGRAPH_PROFILE does).
        #[arg(long)]
        profile: Option<String>,
        /// Only the first N frames of the path.
        #[arg(long)]
        frames: Option<usize>,
        /// HiZ pyramid for non-power-of-two sizes: edge-aware | pad-to-pow2.
        #[arg(long, default_value = "edge-aware", value_parser = parse_npot)]
        hiz_npot: tilegraph_cull::NpotMode,
        /// Occlusion queries: one query per group of N nearby instances (union box).
        #[arg(long, default_value_t = 1)]
        oq_group: usize,
        /// Raster occlusion against a conservative 1/N-resolution depth (1, 2 or 4).
        #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=4))]
        raster_occlusion_scale: u32,
        #[arg(long)]
        json: bool,
    },
    /// Record one frame of a scene under a profile and check every pipeline it binds against
    /// the profile's state rules (what defeats LRZ, FPK, HSR, early-Z), with their sources.
    Lint {
        /// A .gltf/.glb path, or city|forest|field|interior[:size[:seed]], or `default`.
        scene: String,
        /// none | frustum | hiz | hiz-2phase | oq | oq-conditional | raster-occlusion
        #[arg(long, default_value = "none", value_parser = parse_culling)]
        culling: Culling,
        /// forward | prepass | visbuf
        #[arg(long, default_value = "forward", value_parser = parse_technique)]
        shading: Technique,
        /// Force a profile (as TILEGRAPH_PROFILE does).
        #[arg(long)]
        profile: Option<String>,
        #[arg(long, default_value = "160x90", value_parser = parse_size)]
        size: (u32, u32),
        /// `{"findings": [...], "render_passes": [...]}` instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Instance, mesh and triangle counts, bounds and material classes of a scene.
    SceneInfo {
        /// A .gltf/.glb path, or city|forest|field|interior[:size[:seed]], or `default`.
        scene: String,
        /// One JSON object instead of a table.
        #[arg(long)]
        json: bool,
    },
}

fn parse_culling(s: &str) -> Result<Culling, String> {
    Culling::parse(s).ok_or_else(|| {
        format!(
            "unknown culling technique {s:?} (none, frustum, hiz, hiz-2phase, oq, oq-conditional, raster-occlusion)"
        )
    })
}

fn parse_npot(s: &str) -> Result<tilegraph_cull::NpotMode, String> {
    match s {
        "edge-aware" => Ok(tilegraph_cull::NpotMode::EdgeAware),
        "pad-to-pow2" => Ok(tilegraph_cull::NpotMode::PadToPow2),
        _ => Err(format!("unknown HiZ mode {s:?} (edge-aware, pad-to-pow2)")),
    }
}

fn parse_technique(s: &str) -> Result<Technique, String> {
    Technique::parse(s).ok_or_else(|| format!("unknown technique {s:?} (forward, prepass, visbuf)"))
}

/// Errors of the CLI: each names what failed.
#[derive(Debug, thiserror::Error)]
pub enum CliError {
    #[error(transparent)]
    Vk(#[from] tilegraph_vk::VkError),
    #[error(transparent)]
    Profile(#[from] tilegraph_profile::ProfileError),
    #[error("writing {path}: {reason}")]
    Write { path: PathBuf, reason: String },
    #[error("JSON: {0}")]
    Json(#[from] serde_json::Error),
    #[error(transparent)]
    Scene(#[from] tilegraph_scene::SceneError),
    #[error(transparent)]
    Render(#[from] tilegraph_passes::RenderError),
    #[error("{0}")]
    Usage(String),
    /// Whoever read standard output stopped reading (`| head`): not a failure.
    #[error("standard output closed")]
    OutputClosed,
}

/// One line to standard output.
pub fn write_line(line: std::fmt::Arguments<'_>) -> Result<(), CliError> {
    let mut out = std::io::stdout().lock();
    out.write_fmt(line)
        .and_then(|()| out.write_all(b"\n"))
        .map_err(|e| match e.kind() {
            std::io::ErrorKind::BrokenPipe => CliError::OutputClosed,
            _ => CliError::Write {
                path: PathBuf::from("<stdout>"),
                reason: e.to_string(),
            },
        })
}

pub fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("expected WxH, got {s:?}"))?;
    let w: u32 = w.trim().parse().map_err(|e| format!("width {w:?}: {e}"))?;
    let h: u32 = h.trim().parse().map_err(|e| format!("height {h:?}: {e}"))?;
    if w == 0 || h == 0 || w > 16384 || h > 16384 {
        return Err(format!("size {w}x{h} is outside 1..=16384"));
    }
    Ok((w, h))
}

fn main() -> ExitCode {
    env_logger::Builder::from_env(env_logger::Env::default().default_filter_or("warn")).init();
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Devices { json } => devices::run(json),
        Command::Demo { out, size, frames } => demo(&out, size, frames),
        Command::Render {
            scene,
            technique,
            profile,
            size,
            out,
            frames,
            heavy,
            camera_frame,
        } => tilegraph_scene::load(&scene)
            .map_err(CliError::from)
            .and_then(|s| {
                render::run(&render::RenderArgs {
                    scene: &s,
                    technique,
                    profile: profile.as_deref(),
                    size,
                    frames,
                    heavy,
                    camera_frame,
                    out: &out,
                })
            }),
        Command::SceneInfo { scene, json } => scene_info(&scene, json),
        Command::Lint {
            scene,
            culling,
            shading,
            profile,
            size,
            json,
        } => tilegraph_scene::load(&scene)
            .map_err(CliError::from)
            .and_then(|s| {
                lint::run(&lint::Args {
                    scene: &s,
                    culling,
                    shading,
                    profile: profile.as_deref(),
                    size,
                    json,
                })
            }),
        Command::CullCheck {
            scene,
            technique,
            camera_path,
            size,
            profile,
            frames,
            hiz_npot,
            oq_group,
            raster_occlusion_scale,
            json,
        } => cullcheck::run(&cullcheck::Args {
            scene: &scene,
            culling: technique,
            camera_path: camera_path.as_deref(),
            size,
            profile: profile.as_deref(),
            frames,
            hiz_npot,
            oq_group,
            raster_occlusion_scale,
            json,
        }),
    };
    match result {
        Ok(()) | Err(CliError::OutputClosed) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("tilegraph: {e}");
            ExitCode::FAILURE
        }
    }
}

fn demo(out: &std::path::Path, size: (u32, u32), frames: u32) -> Result<(), CliError> {
    devices::run(false)?;
    outln!()?;
    let scene = tilegraph_scene::default_scene()?;
    render::run(&render::RenderArgs {
        scene: &scene,
        technique: Technique::Forward,
        profile: None,
        size,
        frames,
        heavy: 0,
        camera_frame: 0,
        out,
    })
}

fn scene_info(spec: &str, json: bool) -> Result<(), CliError> {
    let scene = tilegraph_scene::load(spec)?;
    let info = scene.info();
    if json {
        outln!("{}", serde_json::to_string(&info)?)?;
    } else {
        outln!("{info}")?;
    }
    Ok(())
}
