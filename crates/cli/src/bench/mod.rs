//! `tilegraph bench`: a matrix of settings (scenes × profiles × sizes × camera paths × shading ×
//! culling × knob values), each run against the exact oracle (`cull-check`), written to a
//! directory as it goes: `results.json` (every run), `report.md`, `report.html` (one
//! self-contained file: tables, plots, the worst frames' images, which are also kept in
//! `frames/`), and SVG plots (a Pareto plot per scene and size, GPU time per pass). An
//! interrupted bench resumes: finished runs are kept and not run again.

pub mod doc;
mod html;
pub(crate) mod matrix;
mod pareto;
mod plot;
#[cfg(test)]
mod readable;
mod report;
pub(crate) mod results;

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use indicatif::{ProgressBar, ProgressStyle};
use tilegraph_passes::cull::Culling;
use tilegraph_passes::cullcheck::{cull_check_options, FailedFrame, OnFailure};
use tilegraph_passes::RenderOptions;
use tilegraph_profile::knobs::{KnobSettings, KnobValue};
use tilegraph_scene::{CameraPath, Scene};
use tilegraph_vk::readback::RgbaImage;
use tilegraph_vk::{Context, ContextOptions};

pub use matrix::{Matrix, Setting};
pub use results::{Results, RunRecord, WorstFrame};

use crate::CliError;

#[derive(clap::Args, Debug, Clone, Default)]
pub struct BenchArgs {
    /// A TOML file with the matrix (the same keys as the options: scenes, culling, shading,
    /// profiles, sizes, camera_paths, frames, and [set] knob = [values]); options given on the
    /// command line replace its entries.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Scenes (comma-separated specs: city, forest:800, path/to/level.gltf).
    #[arg(long, value_delimiter = ',')]
    pub scenes: Vec<String>,
    /// Culling techniques (default: every one; `profile`: the profile's choice).
    #[arg(long, value_delimiter = ',')]
    pub culling: Vec<String>,
    /// Shading techniques (default: forward; `profile`: the profile's choice).
    #[arg(long, value_delimiter = ',')]
    pub shading: Vec<String>,
    /// Profiles to force, one after the other (default: the device's own).
    #[arg(long, value_delimiter = ',')]
    pub profiles: Vec<String>,
    /// Frame sizes, WxH (default: 320x180).
    #[arg(long, value_delimiter = ',')]
    pub sizes: Vec<String>,
    /// Camera paths: `own` (the scene's), `walk[:SEED]` (at eye height through the scene) or a
    /// JSON file (default: own).
    #[arg(long, value_delimiter = ',')]
    pub camera_paths: Vec<String>,
    /// One axis per knob: `--set oq_group=1,16` (repeatable).
    #[arg(long = "set", value_name = "KNOB=V1,V2")]
    pub set: Vec<String>,
    /// Frames per camera path (default: 24).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    pub frames: Option<u32>,
    /// Where results.json, report.md and the plots go.
    #[arg(long)]
    pub out: PathBuf,
}

/// Runs the matrix, resuming from `out/results.json` where it exists.
pub fn run(args: &BenchArgs) -> Result<(), CliError> {
    let matrix = Matrix::from_args(args)?;
    std::fs::create_dir_all(&args.out).map_err(|e| CliError::Write {
        path: args.out.clone(),
        reason: e.to_string(),
    })?;
    let results_path = args.out.join("results.json");
    let mut results = Results::load_or_new(&results_path)?;
    let scenes = load_scenes(&matrix)?;
    let settings = matrix.expand(|spec| scenes.get(spec))?;
    let todo: Vec<&Setting> = settings
        .iter()
        .filter(|s| !results.is_done(&s.key()))
        .collect();
    let kept = settings.len() - todo.len();
    if kept > 0 {
        eprintln!(
            "tilegraph bench: {kept} of {} runs already in {}; running the other {}",
            settings.len(),
            results_path.display(),
            todo.len()
        );
    }
    let bar = ProgressBar::new(todo.len() as u64);
    bar.set_style(
        ProgressStyle::with_template("{bar:30} {pos}/{len} {elapsed_precise} eta {eta} {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    // One device context per profile, in the order the matrix names them.
    let mut profiles: Vec<Option<&str>> = Vec::new();
    for s in &todo {
        if !profiles.contains(&s.profile.as_deref()) {
            profiles.push(s.profile.as_deref());
        }
    }
    for profile in profiles {
        let mut options = ContextOptions::from_env();
        if let Some(p) = profile {
            options.force_profile(p, "bench --profiles");
        }
        options.features = crate::cullcheck::oracle_features();
        let options = crate::run::with_every_culling_feature(options);
        let mut paths: HashMap<String, CameraPath> = HashMap::new();
        crate::run::on_context(options, |ctx| {
            for s in todo.iter().filter(|s| s.profile.as_deref() == profile) {
                bar.set_message(s.key());
                let scene = scenes
                    .get(&s.scene)
                    .ok_or_else(|| CliError::Usage(format!("scene {} was not loaded", s.scene)))?;
                results.insert(run_or_record_failure(
                    ctx,
                    scene,
                    s,
                    matrix.frames,
                    &mut paths,
                    Some(&args.out),
                )?);
                results.save(&results_path)?;
                bar.inc(1);
            }
            Ok(())
        })?;
    }
    bar.finish_and_clear();
    let written = write_outputs(&args.out, &results, &settings)?;
    let failed = settings
        .iter()
        .filter(|s| results.get(&s.key()).is_some_and(|r| r.error.is_some()))
        .count();
    outln!(
        "bench: {} runs ({} new, {} failed) in {}: {}",
        settings.len(),
        todo.len(),
        failed,
        args.out.display(),
        written
            .iter()
            .map(|p| p
                .file_name()
                .map_or(String::new(), |n| n.to_string_lossy().into_owned()))
            .collect::<Vec<_>>()
            .join(", ")
    )?;
    Ok(())
}

pub(crate) fn load_scenes(matrix: &Matrix) -> Result<HashMap<String, Scene>, CliError> {
    let mut scenes = HashMap::new();
    // Clusters change the index order: every technique of the sweep draws the same one. `auto`
    // tries cluster culling on scenes of big instances: they get their clusters too.
    // Levels of detail come with the clusters.
    let lod = matrix
        .axes
        .iter()
        .any(|(k, values)| k == "lod_error_px" && values.iter().any(|v| v.to_string() != "0"));
    let clusters = if lod {
        crate::run::Clusters::WithLevels
    } else if matrix
        .culling
        .iter()
        .any(|c| Culling::parse(c).is_some_and(Culling::clusters))
    {
        crate::run::Clusters::Yes
    } else if matrix.culling.iter().any(|c| Culling::parse(c).is_none()) {
        crate::run::Clusters::ForAuto
    } else {
        crate::run::Clusters::No
    };
    for spec in &matrix.scenes {
        if !scenes.contains_key(spec) {
            scenes.insert(spec.clone(), crate::run::load_scene(spec, clusters)?);
        }
    }
    Ok(scenes)
}

/// [`run_one`], a setting the device cannot run (a missing feature, a knob it cannot use)
/// recorded as failed so that the sweep goes on; a lost device ends it.
pub(crate) fn run_or_record_failure(
    ctx: &Context,
    scene: &Scene,
    s: &Setting,
    frames: u32,
    paths: &mut HashMap<String, CameraPath>,
    worst_to: Option<&Path>,
) -> Result<RunRecord, CliError> {
    match run_one(ctx, scene, s, frames, paths, worst_to) {
        Ok(r) => Ok(r),
        Err(CliError::Render(e)) if !e.is_device_lost() => {
            Ok(RunRecord::failed(s, ctx, e.to_string()))
        }
        Err(CliError::KnobUse(e)) => Ok(RunRecord::failed(s, ctx, e.to_string())),
        Err(e) => Err(e),
    }
}

/// One setting against the oracle; with `worst_to`, the images of its worst frame (if any
/// differs) are written under `worst_to/frames/`.
pub(crate) fn run_one(
    ctx: &Context,
    scene: &Scene,
    s: &Setting,
    frames: u32,
    paths: &mut HashMap<String, CameraPath>,
    worst_to: Option<&Path>,
) -> Result<RunRecord, CliError> {
    let path = match paths.get(&s.camera_path_key()) {
        Some(p) => p.clone(),
        None => {
            let p = match s.camera_path.as_deref() {
                None => scene.camera_path().clone(),
                Some(spec) => crate::run::named_camera_path(spec, scene)?,
            };
            paths.insert(s.camera_path_key(), p.clone());
            p
        }
    };
    let mut knobs = KnobSettings::default();
    if s.culling != matrix::PROFILE_CHOICE {
        knobs.set("culling", KnobValue::Name(s.culling.clone()))?;
    }
    if s.shading != matrix::PROFILE_CHOICE {
        knobs.set("shading", KnobValue::Name(s.shading.clone()))?;
    }
    for (k, v) in &s.knobs {
        knobs.set(k, v.clone())?;
    }
    let mut options = RenderOptions {
        width: s.size[0],
        height: s.size[1],
        ..Default::default()
    };
    let resolved = crate::run::RunArgs::resolve(ctx, scene, &knobs, &mut options)?;
    let started = Instant::now();
    // The worst frame's images: the most pixels unlike the unculled image, then the most FN.
    let mut worst: Option<(usize, usize, usize, [RgbaImage; 3])> = None;
    let mut keep_worst = |f: &FailedFrame<'_>| -> Result<(), String> {
        let score = (f.check.image_diff_pixels, f.check.false_negatives);
        if worst.as_ref().is_none_or(|w| (w.1, w.2) < score) {
            worst = Some((
                f.check.frame,
                score.0,
                score.1,
                [f.technique.clone(), f.reference.clone(), f.diff.clone()],
            ));
        }
        Ok(())
    };
    let check = cull_check_options(
        ctx,
        scene,
        options,
        &path,
        Some(frames as usize),
        tilegraph_passes::cullcheck::CheckExtras {
            auto: resolved.auto_trial(crate::run::auto_inputs(ctx, scene, None)),
            motion: crate::run::split_motion(&s.scene)?.1,
            timing_warmup: crate::run::TIMING_WARMUP,
            on_failure: worst_to.map(|_| &mut keep_worst as OnFailure<'_>),
            ..Default::default()
        },
    )?;
    let mut record =
        RunRecord::from_check(s, ctx, &resolved, check, started.elapsed().as_secs_f64());
    if let (Some(out), Some((frame, differing_pixels, false_negatives, images))) = (worst_to, worst)
    {
        let stem = format!("frames/{:016x}", fnv1a(s.key().as_bytes()));
        let [technique, reference, diff] = images;
        let save = |what: &str, image: &RgbaImage| -> Result<String, CliError> {
            let name = format!("{stem}-{what}.png");
            crate::image_io::write_png(&out.join(&name), image)?;
            Ok(name)
        };
        record.worst_frame = Some(WorstFrame {
            frame,
            differing_pixels,
            false_negatives,
            technique: save("technique", &technique)?,
            reference: save("reference", &reference)?,
            diff: save("diff", &diff)?,
        });
    }
    Ok(record)
}

/// A stable 64-bit hash of a setting's key: its worst frame's file names.
fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
    })
}

/// report.md and the plots, from every run the matrix names (old and new).
pub(crate) fn write_outputs(
    out: &Path,
    results: &Results,
    settings: &[Setting],
) -> Result<Vec<PathBuf>, CliError> {
    let runs: Vec<&RunRecord> = settings
        .iter()
        .filter_map(|s| results.get(&s.key()))
        .collect();
    let labels = matrix::Labels::new(settings);
    let mut written = Vec::new();
    for group in report::groups(&runs) {
        written.push(pareto::write(out, &group, &labels)?);
        written.push(plot::passes(out, &group, &labels)?);
        if group.has_shadows() {
            written.push(plot::casters(out, &group, &labels)?);
        }
        if group.has_lod() {
            written.push(plot::lod(out, &group, &labels)?);
        }
    }
    let report_path = out.join("report.md");
    results::write_atomically(&report_path, report::markdown(&runs, &labels).as_bytes())?;
    written.insert(0, html::write(out, &runs, &labels)?);
    written.insert(0, report_path);
    written.insert(0, out.join("results.json"));
    Ok(written)
}
