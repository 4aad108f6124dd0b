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

mod bench;
mod bottleneck;
mod cullcheck;
mod devices;
mod experiments;
mod graph;
mod image_io;
mod knobs;
mod lint;
mod markup;
mod pvs;
mod render;
mod run;
mod timeline;
mod tune;
mod validate;

use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

use crate::run::RunArgs;

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
        #[arg(long, default_value_t = 16, value_parser = clap::value_parser!(u32).range(1..))]
        frames: u32,
    },
    /// Render a scene under a profile with its culling and shading; print the knobs, the passes
    /// chosen and the per-pass GPU time table; write the image.
    Render {
        #[command(flatten)]
        run: RunArgs,
        /// Where to write the frame (PNG).
        #[arg(long, default_value = "frame.png")]
        out: PathBuf,
        /// ALU iterations of the heavy material (0 = plain Lambert).
        #[arg(long, default_value_t = 0)]
        heavy: u32,
        /// Which frame of the camera path to look from.
        #[arg(long, default_value_t = 0)]
        camera_frame: usize,
    },
    /// Render every frame of a camera path with a culling technique and with the exact oracle;
    /// report visible, drawn, false negatives and positives, and image equality per frame.
    CullCheck {
        #[command(flatten)]
        run: RunArgs,
        /// For each frame with false negatives or an image unlike the reference, write
        /// `frame-NNNN-technique.png`, `-reference.png` and `-diff.png` (differing pixels red,
        /// the pixels of culled visible instances magenta) here.
        #[arg(long)]
        save_frames: Option<PathBuf>,
    },
    /// Record one frame of a scene under a profile and check every pipeline it binds against
    /// the profile's state rules (what defeats LRZ, FPK, HSR, early-Z), with their sources.
    Lint {
        #[command(flatten)]
        run: RunArgs,
    },
    /// Sweep a matrix of scenes, profiles, sizes, camera paths, shading, culling and knob values
    /// against the exact oracle; write results.json, report.md and SVG plots (Pareto fronts,
    /// GPU time per pass) to --out, resuming where an earlier run stopped.
    Bench(bench::BenchArgs),
    /// Rewrite a marked section of a doc (docs/ACCURACY.md, docs/BENCHMARKS.md) with the tables
    /// of bench results, naming the machine, driver and build that measured them.
    BenchDoc(bench::doc::DocArgs),
    /// Sweep the knobs the profile exposes for one scene on this device, pick the fastest
    /// setting that meets the accuracy constraint, check it on a path it did not see, and write
    /// the profile with the pick as its knobs (load it with TILEGRAPH_PROFILE_DIR).
    Tune(tune::TuneArgs),
    /// Find the stage that limits the frame (seed 002's recipe): time it as it is, then with
    /// a fixed-colour fragment shader, at 50x50, with a trivial vertex shader, with a quarter
    /// of each mesh's triangles and with a quarter of the instances; name the stage whose
    /// removal saves the frame, with the savings and what to try.
    Bottleneck {
        #[command(flatten)]
        run: RunArgs,
        /// ALU iterations of the heavy material (0 = plain Lambert).
        #[arg(long, default_value_t = 0)]
        heavy: u32,
    },
    /// Seed 000's geometry-culling tests on this device: its scene, techniques, workloads and
    /// sizes, each frame over early Z front to back's, beside the seed's published figures for
    /// one of its GPUs; results.json, report.md and SVG plots in --out.
    Experiments(experiments::ExperimentsArgs),
    /// The compiled plan of one frame of a scene (steps, or DOT with --dot) and the reason for
    /// every merge, load and store op, barrier and attachment's traffic.
    Graph {
        #[command(flatten)]
        run: RunArgs,
        /// The plan as Graphviz DOT instead.
        #[arg(long)]
        dot: bool,
    },
    /// The knobs (choices that trade speed for accuracy or memory): domain, default, the
    /// profile's value, and whether a scene can use each.
    Knobs {
        /// Show this profile's values (no device needed).
        #[arg(long)]
        profile: Option<String>,
        /// Show which knobs this scene is offered.
        #[arg(long)]
        scene: Option<String>,
        #[arg(long)]
        json: bool,
    },
    /// Check a game's scenes in its CI: for each scene, forced profile, shading and culling,
    /// the validation layers, the profile's state lint, culling exactness against the oracle
    /// and images against goldens kept in DIR (`--bless` writes them); JUnit XML, a JSON
    /// summary and a Markdown report; the exit status says pass or fail (docs/VALIDATING.md).
    Validate(validate::ValidateArgs),
    /// Bake a precomputed visible set: for each cell of a grid over the region cameras visit
    /// (the camera path's eyes, grown by half a cell), the instances the exact oracle's id
    /// render sees from sampled viewpoints (six 90° faces each); `--culling pvs --pvs FILE`
    /// draws it. Prints the bake time and the file's size.
    Pvs(pvs::PvsArgs),
    /// Instance, mesh and triangle counts, bounds and material classes of a scene.
    SceneInfo {
        /// A .gltf/.glb path, or city|forest|field|interior|maze[:size[:seed]], or `default`.
        scene: String,
        /// One JSON object instead of a table.
        #[arg(long)]
        json: bool,
        /// Also build the scene's clusters (meshoptimizer) and report their count, build time
        /// and memory.
        #[arg(long)]
        clusters: bool,
        /// Write the clusters to FILE (prebuilt data for builds without meshoptimizer, such as
        /// Android's); implies --clusters.
        #[arg(long, value_name = "FILE")]
        write_clusters: Option<std::path::PathBuf>,
        /// Leave the levels of detail out of the clusters reported and written (an engine that
        /// never sets `lod_error_px` saves their indices, about as many as the scene's, in the
        /// file and on the GPU).
        #[arg(long)]
        without_levels: bool,
    },
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
    #[error(transparent)]
    Knob(#[from] tilegraph_profile::knobs::KnobError),
    #[error(transparent)]
    KnobUse(#[from] tilegraph_passes::knobs::KnobUseError),
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
            run,
            out,
            heavy,
            camera_frame,
        } => run
            .knob_settings(run::TechniqueMeant::Shading)
            .and_then(|knobs| {
                let clusters = run::wants_clusters(&knobs);
                Ok((knobs, run::load_scene(&run.scene, clusters)?))
            })
            .and_then(|(knobs, s)| {
                render::run(&render::RenderArgs {
                    run: &run,
                    knobs: &knobs,
                    scene: &s,
                    heavy,
                    camera_frame,
                    out: &out,
                })
            }),
        Command::SceneInfo {
            scene,
            json,
            clusters,
            write_clusters,
            without_levels,
        } => scene_info(
            &scene,
            json,
            clusters || without_levels,
            write_clusters.as_deref(),
            without_levels,
        ),
        Command::Lint { run } => lint::run(&run),
        Command::CullCheck { run, save_frames } => cullcheck::run(&run, save_frames.as_deref()),
        Command::Bench(args) => bench::run(&args),
        Command::Graph { run, dot } => graph::run(&run, dot),
        Command::Bottleneck { run, heavy } => run
            .knob_settings(run::TechniqueMeant::Shading)
            .and_then(|knobs| {
                let clusters = run::wants_clusters(&knobs);
                Ok((knobs, run::load_scene(&run.scene, clusters)?))
            })
            .and_then(|(knobs, scene)| {
                bottleneck::run(&bottleneck::BottleneckArgs {
                    run: &run,
                    knobs: &knobs,
                    scene: &scene,
                    heavy,
                })
            }),
        Command::BenchDoc(args) => bench::doc::run(&args),
        Command::Tune(args) => tune::run(&args),
        Command::Experiments(args) => experiments::run(&args),
        Command::Validate(args) => validate::run(&args),
        Command::Pvs(args) => pvs::run(&args),
        Command::Knobs {
            profile,
            scene,
            json,
        } => knobs::run(profile.as_deref(), scene.as_deref(), json),
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
    let run = RunArgs {
        scene: "default".into(),
        profile: None,
        culling: None,
        shading: None,
        set: Vec::new(),
        size: Some(size),
        camera_path: None,
        frames: Some(frames),
        json: false,
        texture_binding: None,
        pvs: None,
        async_compute: None,
        technique: None,
        oq_group: None,
        raster_occlusion_scale: None,
        hiz_npot: None,
    };
    render::run(&render::RenderArgs {
        run: &run,
        knobs: &tilegraph_profile::knobs::KnobSettings::default(),
        scene: &scene,
        heavy: 0,
        camera_frame: 0,
        out,
    })
}

/// What the device's figures cannot say: on a CPU rasterizer (lavapipe) pipeline statistics
/// count fragments before the depth test, and timestamps between passes of one render pass
/// land where the rasterizer happens to flush (its tiles are rasterized outside them).
pub fn device_caveat(ctx: &tilegraph_vk::Context) -> Option<&'static str> {
    (ctx.physical.identity.device_type == tilegraph_profile::DeviceType::Cpu).then_some(
        "note: a CPU rasterizer: fragment counts are before the depth test, and per-pass times inside one render pass are where it flushed (most rasterization falls outside them); compare frames timed whole",
    )
}

fn mib(bytes: u64) -> f64 {
    bytes as f64 / (1024.0 * 1024.0)
}

fn scene_info(
    spec: &str,
    json: bool,
    clusters: bool,
    write_clusters: Option<&std::path::Path>,
    without_levels: bool,
) -> Result<(), CliError> {
    let scene = run::load_scene(spec, false)?;
    let info = scene.info();
    let clusters = if clusters || write_clusters.is_some() {
        let (mut data, stats) = tilegraph_scene::clusters::build(&scene)?;
        if without_levels {
            data = data.without_lods();
        }
        if let Some(path) = write_clusters {
            data.write(path)?;
        }
        Some(ClusterInfo::new(&data, stats))
    } else {
        None
    };
    // What a renderer of it holds on the GPU (two frames in flight, GPU culling's lists).
    let memory =
        tilegraph_passes::scene_memory(&scene, tilegraph_vk::frames::DEFAULT_FRAMES_IN_FLIGHT, 0);
    if json {
        let mut v = serde_json::to_value(&info)?;
        if let Some(o) = v.as_object_mut() {
            if let Some(c) = &clusters {
                o.insert("clusters".into(), serde_json::to_value(c)?);
            }
            let mut m = serde_json::to_value(memory)?;
            if let Some(m) = m.as_object_mut() {
                m.insert("total_bytes".into(), memory.total_bytes().into());
                m.insert(
                    "bytes_per_instance".into(),
                    memory.bytes_per_instance().into(),
                );
            }
            o.insert("gpu_memory".into(), m);
        }
        outln!("{v}")?;
    } else {
        outln!("{info}")?;
        outln!(
            "GPU memory         {:.1} MiB: geometry {:.1} MiB, textures {:.1} MiB, {} frame slots of {:.1} MiB, culling lists {:.1} MiB; {:.0} B per instance slot ({} slots)",
            mib(memory.total_bytes()),
            mib(memory.geometry_bytes),
            mib(memory.texture_bytes),
            memory.frames_in_flight,
            mib(memory.slot_bytes),
            mib(memory.culling_bytes),
            memory.bytes_per_instance(),
            memory.instance_slots
        )?;
        if let Some(c) = clusters {
            outln!(
                "clusters           {} ({:.1} triangles each, {:.1} % with a back-facing cone), built in {:.1} ms, {:.2} MiB",
                c.clusters,
                c.triangles_per_cluster,
                100.0 * c.cone_fraction,
                c.build_ms,
                c.bytes as f64 / (1024.0 * 1024.0)
            )?;
            outln!(
                "levels of detail   {} ({} indices, {:.2} MiB)",
                c.levels,
                c.level_indices,
                (c.level_indices * 4) as f64 / (1024.0 * 1024.0)
            )?;
        }
    }
    Ok(())
}

/// What `scene-info --clusters` adds.
#[derive(serde::Serialize)]
struct ClusterInfo {
    clusters: u64,
    triangles_per_cluster: f64,
    /// Clusters whose normal cone can reject them (cutoff below 1).
    cone_fraction: f64,
    build_ms: f64,
    /// Cluster records and mesh ranges (the index buffer is reordered, not grown).
    bytes: u64,
    /// Levels of detail over every mesh, and the indices they add to the scene's.
    levels: u64,
    level_indices: u64,
}

impl ClusterInfo {
    fn new(
        data: &tilegraph_scene::clusters::ClusterData,
        stats: tilegraph_scene::clusters::BuildStats,
    ) -> Self {
        let n = data.clusters.len().max(1) as f64;
        let triangles: u64 = data
            .clusters
            .iter()
            .map(|c| u64::from(c.index_count / 3))
            .sum();
        let coned = data.clusters.iter().filter(|c| c.cone_cutoff < 1.0).count();
        ClusterInfo {
            clusters: stats.clusters,
            triangles_per_cluster: triangles as f64 / n,
            cone_fraction: coned as f64 / n,
            build_ms: stats.milliseconds,
            bytes: (data.clusters.len()
                * std::mem::size_of::<tilegraph_scene::clusters::GpuCluster>()
                + data.mesh_clusters.len() * 8) as u64,
            levels: data.lods.iter().filter(|l| l.index_count > 0).count() as u64,
            level_indices: data.lods.iter().map(|l| u64::from(l.index_count)).sum(),
        }
    }
}
