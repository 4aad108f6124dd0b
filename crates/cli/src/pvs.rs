//! `tilegraph pvs`: bakes a precomputed visible set and writes it as JSON.

use std::path::PathBuf;

use tilegraph_passes::pvs::{bake, path_region, BakeSpec};

use crate::run::{load_scene, on_context, Clusters};
use crate::CliError;

#[derive(clap::Args, Debug, Clone)]
pub struct PvsArgs {
    /// A .gltf/.glb path, or city|forest|field|interior|maze[:size[:seed]], or `default`.
    pub scene: String,
    /// A cell's side in metres.
    #[arg(long, default_value_t = 8.0)]
    pub cell: f64,
    /// Viewpoints sampled per cell (each renders six faces).
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u32).range(1..))]
    pub samples: u32,
    /// Each face's side in pixels.
    #[arg(long, default_value_t = 128, value_parser = clap::value_parser!(u32).range(1..=4096))]
    pub face_px: u32,
    /// The region: the eyes of this camera path (`walk[:SEED]` or a JSON file), grown by half a
    /// cell; the scene's own path when absent.
    #[arg(long)]
    pub camera_path: Option<PathBuf>,
    /// Cover the scene's whole extent across (x and z) at the path's heights, so that any
    /// camera at those heights is inside (an eye-height walk anywhere in the level).
    #[arg(long)]
    pub whole_level: bool,
    /// The viewpoints' random sequence.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Force a profile by name.
    #[arg(long)]
    pub profile: Option<String>,
    /// Where to write the set (JSON).
    #[arg(long)]
    pub out: PathBuf,
}

pub fn run(a: &PvsArgs) -> Result<(), CliError> {
    if !(a.cell.is_finite() && a.cell > 0.0) {
        return Err(CliError::Usage(format!(
            "--cell {}: a positive length",
            a.cell
        )));
    }
    let scene = load_scene(&a.scene, Clusters::No)?;
    let path = match &a.camera_path {
        Some(p) => crate::run::named_camera_path(&p.to_string_lossy(), &scene)?,
        None => scene.camera_path().clone(),
    };
    let mut region = path_region(&path, a.cell);
    if a.whole_level {
        let b = scene.bounds();
        region.min.x = b.min.x;
        region.min.z = b.min.z;
        region.max.x = b.max.x;
        region.max.z = b.max.z;
    }
    let spec = BakeSpec {
        region,
        cell: a.cell,
        samples: a.samples,
        face_px: a.face_px,
        seed: a.seed,
    };
    let mut options = tilegraph_vk::ContextOptions::from_env();
    if let Some(p) = &a.profile {
        options.force_profile(p, "--profile");
    }
    options.features = tilegraph_passes::RenderOptions {
        technique: tilegraph_passes::Technique::Visbuf,
        ..Default::default()
    }
    .device_features();
    let pvs = on_context(options, |ctx| {
        let bar = indicatif::ProgressBar::new(0);
        let pvs = bake(ctx, &scene, &spec, |done, all| {
            bar.set_length(all as u64);
            bar.set_position(done as u64);
        });
        bar.finish_and_clear();
        Ok(pvs?)
    })?;
    let text = serde_json::to_string(&pvs)?;
    std::fs::write(&a.out, &text).map_err(|e| CliError::Write {
        path: a.out.clone(),
        reason: e.to_string(),
    })?;
    let cells = pvs.cells.len().max(1);
    outln!(
        "{}: {} cells of {:.1}x{:.1}x{:.1} m ({}x{}x{}), {} viewpoints x 6 faces of {} px each; {:.1} s; {} bytes; {:.1} of {} instances per cell on average",
        a.out.display(),
        pvs.cells.len(),
        pvs.cell[0],
        pvs.cell[1],
        pvs.cell[2],
        pvs.dims[0],
        pvs.dims[1],
        pvs.dims[2],
        pvs.samples,
        pvs.face_px,
        pvs.bake_seconds,
        text.len(),
        pvs.stored_ids() as f64 / cells as f64,
        pvs.instances
    )?;
    Ok(())
}
