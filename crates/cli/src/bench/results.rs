//! results.json: every run of a bench, written after each run (to a temporary file, then renamed,
//! so an interrupted bench never leaves a half-written file that looks complete).

use std::path::Path;

use serde::{Deserialize, Serialize};
use tilegraph_passes::cullcheck::CullCheck;
use tilegraph_passes::knobs::Resolved;
use tilegraph_vk::Context;

use super::Setting;
use crate::CliError;

/// Format version of results.json; a file of another version is not resumed from.
pub const RESULTS_VERSION: u32 = 2;

#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct Results {
    pub version: u32,
    pub runs: Vec<RunRecord>,
}

/// Where a run ran.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DeviceRecord {
    /// The tilegraph that measured: version and commit (`0.1.0 7021862`).
    #[serde(default)]
    pub build: String,
    pub name: String,
    pub driver: String,
    pub driver_version: String,
    pub api: String,
    pub profile: String,
    pub profile_matched_by: String,
}

/// One frame of a run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FrameRecord {
    pub frame: usize,
    pub visible: usize,
    pub drawn: usize,
    pub false_negatives: usize,
    pub false_positives: usize,
    pub triangles_drawn: u64,
    pub image_equal: bool,
    /// PSNR of the frame's image against the full-detail, unculled one (absent where equal,
    /// and in results written before it).
    #[serde(default)]
    pub image_psnr_db: Option<f64>,
    /// With shadows: the casters drawn into the cascades, summed (absent without shadows and
    /// in results written before them).
    #[serde(default)]
    pub shadow_casters: Option<u32>,
    /// With shadows: the casters the oracle needed, drawn casters none needed, needed ones
    /// culled where the image differed (absent in results written before them).
    #[serde(default)]
    pub shadow_casters_needed: Option<u32>,
    #[serde(default)]
    pub shadow_caster_false_positives: Option<u32>,
    #[serde(default)]
    pub shadow_caster_false_negatives: Option<u32>,
}

/// One pass's GPU time over a run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PassRecord {
    pub name: String,
    pub median_gpu_ms: f64,
    pub p95_gpu_ms: f64,
}

/// A run's totals.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TotalsRecord {
    pub frames: usize,
    pub visible: usize,
    pub drawn: usize,
    /// Visible instances culled, plus visible clusters culled (cluster techniques: a cluster
    /// missed is as wrong as an instance missed).
    pub false_negatives: usize,
    /// Of those, clusters (0 for instance techniques and in results written before the cluster
    /// oracle).
    #[serde(default)]
    pub cluster_false_negatives: usize,
    pub false_positives: usize,
    /// FN / visible over the path.
    pub fn_rate: f64,
    /// FP / drawn over the path.
    pub fp_rate: f64,
    pub frames_with_false_negatives: usize,
    pub frames_image_equal: usize,
    /// Pixels that differed from the unculled images over the path, and of those the ones
    /// holding the same depth (ties of depth precision; 0 in results written before them).
    #[serde(default)]
    pub image_diff_pixels: usize,
    #[serde(default)]
    pub image_diff_pixels_depth_tie: usize,
    /// The images against the full-detail, unculled ones over the path: root mean squared
    /// difference per channel (8-bit levels; 0 for an exact technique), PSNR (absent where
    /// every frame was equal) and the largest difference (levels of detail trade these for
    /// triangles; absent in results written before them).
    #[serde(default)]
    pub image_rmse: f64,
    #[serde(default)]
    pub image_psnr_db: Option<f64>,
    #[serde(default)]
    pub image_max_channel_diff: u8,
    /// Levels of detail: the largest relative difference of view distance at a pixel both the
    /// setting and the full-detail frame cover (absent without levels).
    #[serde(default)]
    pub image_max_depth_rel_diff: Option<f64>,
    pub triangles_drawn: u64,
    /// Median of the whole frame (two timestamps around it, no per-pass queries).
    pub frame_gpu_ms: f64,
    /// 95th percentile of the same frames.
    pub frame_gpu_ms_p95: f64,
    /// The ideal frame: the oracle's visible instances (clusters, for a cluster technique) drawn
    /// with no culling work, timed whole (absent for moving scenes and in results written
    /// before it).
    #[serde(default)]
    pub ideal_frame_gpu_ms: Option<f64>,
    /// Sum of the passes' medians (timed each, in a pass of their own along the path): the
    /// frame without what lies between its passes. (Format 1 had no such field, and its
    /// `frame_gpu_ms` was this sum.)
    pub passes_gpu_ms: f64,
    pub cull_gpu_ms: f64,
    pub cpu_ms: f64,
    /// Software occlusion's median CPU milliseconds per frame (its part of `cpu_ms`: choosing
    /// occluders, rasterizing, testing boxes); absent for other cullings.
    #[serde(default)]
    pub software_cpu_ms: Option<f64>,
    /// With shadows: casters drawn over the path, every caster into every cascade over the
    /// path (what `shadow_culling = none` draws), and the shadow passes' GPU ms.
    #[serde(default)]
    pub shadow_casters: Option<u64>,
    #[serde(default)]
    pub shadow_casters_all: Option<u64>,
    #[serde(default)]
    pub shadow_gpu_ms: f64,
    /// With shadows, over the path: the casters the oracle needed (a perfect caster culling's
    /// draws), drawn casters none needed (FP) and needed ones culled where the image differed
    /// (FN).
    #[serde(default)]
    pub shadow_casters_needed: Option<u64>,
    #[serde(default)]
    pub shadow_caster_false_positives: Option<u64>,
    #[serde(default)]
    pub shadow_caster_false_negatives: Option<u64>,
}

/// One run: its setting, where it ran, what it measured — or why it failed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunRecord {
    pub key: String,
    pub settings: Setting,
    pub device: DeviceRecord,
    /// The culling that ran (`auto` resolved) and every knob with its origin.
    pub culling: String,
    pub auto_reason: Option<String>,
    pub knobs: Vec<serde_json::Value>,
    pub error: Option<String>,
    pub wall_s: f64,
    pub totals: Option<TotalsRecord>,
    pub passes: Vec<PassRecord>,
    pub frames: Vec<FrameRecord>,
    /// The frame whose image differed most from the unculled one (then the most FN), its
    /// images kept beside results.json; absent where every frame was exact.
    #[serde(default)]
    pub worst_frame: Option<WorstFrame>,
}

/// A run's worst frame: which, how wrong, and its images (PNG files, relative to the output
/// directory: the setting's image, the unculled reference, and the diff — the reference in
/// grey, differing pixels red, visible instances culled magenta).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WorstFrame {
    pub frame: usize,
    pub differing_pixels: usize,
    pub false_negatives: usize,
    pub technique: String,
    pub reference: String,
    pub diff: String,
}

/// This binary's version and the commit it was built from.
pub fn build() -> String {
    format!("{} {}", env!("CARGO_PKG_VERSION"), env!("TILEGRAPH_COMMIT"))
}

fn device(ctx: &Context) -> DeviceRecord {
    DeviceRecord {
        build: build(),
        name: ctx.physical.identity.device_name.clone(),
        driver: ctx.physical.driver_name.clone(),
        driver_version: ctx.physical.driver_info.clone(),
        api: ctx.physical.identity.api_version_string(),
        profile: ctx.profile().name.clone(),
        profile_matched_by: ctx.selection.matched_by.to_string(),
    }
}

impl RunRecord {
    pub fn from_check(
        s: &Setting,
        ctx: &Context,
        resolved: &Resolved,
        check: CullCheck,
        wall_s: f64,
    ) -> RunRecord {
        let t = &check.totals;
        let totals = TotalsRecord {
            frames: t.frames,
            visible: t.visible,
            drawn: t.drawn,
            false_negatives: t.false_negatives + t.cluster_false_negatives,
            cluster_false_negatives: t.cluster_false_negatives,
            false_positives: t.false_positives,
            // Instances only: a rate of visible instances missed.
            fn_rate: if t.visible == 0 {
                0.0
            } else {
                t.false_negatives as f64 / t.visible as f64
            },
            fp_rate: t.false_positive_rate,
            frames_with_false_negatives: check
                .frames
                .iter()
                .filter(|f| {
                    f.false_negatives > 0 || f.clusters.is_some_and(|c| c.false_negatives > 0)
                })
                .count(),
            frames_image_equal: t.frames_image_equal,
            image_diff_pixels: t.image_diff_pixels,
            image_diff_pixels_depth_tie: t.image_diff_pixels_depth_tie,
            image_rmse: t.image_error.mse.sqrt(),
            image_psnr_db: t.image_error.psnr_db,
            image_max_channel_diff: t.image_error.max_channel_diff,
            image_max_depth_rel_diff: t.image_error.max_depth_rel_diff,
            triangles_drawn: t.triangles_drawn,
            frame_gpu_ms: t.frame_gpu_ms,
            frame_gpu_ms_p95: t.frame_gpu_ms_p95,
            ideal_frame_gpu_ms: t.ideal_frame_gpu_ms,
            passes_gpu_ms: t.passes_gpu_ms,
            cull_gpu_ms: t.cull_gpu_ms,
            cpu_ms: t.cpu_ms,
            software_cpu_ms: t.software_cpu_ms,
            shadow_casters: t.shadow_casters,
            shadow_casters_all: t.shadow_casters_all,
            shadow_gpu_ms: t.shadow_gpu_ms,
            shadow_casters_needed: t.shadow_casters_needed,
            shadow_caster_false_positives: t.shadow_caster_false_positives,
            shadow_caster_false_negatives: t.shadow_caster_false_negatives,
        };
        RunRecord {
            key: s.key(),
            settings: s.clone(),
            device: device(ctx),
            culling: check.technique.clone(),
            auto_reason: match (&resolved.auto_reason, &check.auto_review) {
                (Some(first), Some(then)) => Some(format!("{first}; then {then}")),
                (first, _) => first.clone(),
            },
            knobs: resolved
                .knobs
                .iter()
                .filter_map(|k| serde_json::to_value(k).ok())
                .collect(),
            error: None,
            wall_s,
            passes: t
                .passes
                .iter()
                .map(|p| PassRecord {
                    name: p.name.clone(),
                    median_gpu_ms: p.gpu_ms,
                    p95_gpu_ms: p.p95_gpu_ms,
                })
                .collect(),
            frames: check
                .frames
                .iter()
                .map(|f| FrameRecord {
                    frame: f.frame,
                    visible: f.visible,
                    drawn: f.drawn,
                    // Visible instances and clusters culled, as in the totals.
                    false_negatives: f.false_negatives
                        + f.clusters.map_or(0, |c| c.false_negatives),
                    false_positives: f.false_positives,
                    triangles_drawn: f.triangles_drawn,
                    image_equal: f.image_equal,
                    image_psnr_db: f.image_error.psnr_db,
                    shadow_casters: f.shadow_casters,
                    shadow_casters_needed: f.casters.map(|c| c.needed as u32),
                    shadow_caster_false_positives: f.casters.map(|c| c.false_positives as u32),
                    shadow_caster_false_negatives: f.casters.map(|c| c.false_negatives as u32),
                })
                .collect(),
            totals: Some(totals),
            worst_frame: None,
        }
    }

    /// A run the device could not do (a missing feature, say): recorded, and run again when
    /// the bench resumes.
    pub fn failed(s: &Setting, ctx: &Context, error: String) -> RunRecord {
        RunRecord {
            key: s.key(),
            settings: s.clone(),
            device: device(ctx),
            culling: s.culling.clone(),
            auto_reason: None,
            knobs: Vec::new(),
            error: Some(error),
            wall_s: 0.0,
            totals: None,
            passes: Vec::new(),
            frames: Vec::new(),
            worst_frame: None,
        }
    }
}

impl Results {
    /// The runs in `path`, or none when it does not exist. A file that does not parse, or of
    /// another version, is an error naming it (delete it to start over): a bench never
    /// overwrites results it cannot read.
    pub fn load_or_new(path: &Path) -> Result<Results, CliError> {
        let text = match std::fs::read_to_string(path) {
            Ok(t) => t,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                return Ok(Results {
                    version: RESULTS_VERSION,
                    runs: Vec::new(),
                })
            }
            Err(e) => {
                return Err(CliError::Usage(format!(
                    "bench: reading {}: {e}",
                    path.display()
                )))
            }
        };
        let r: Results = serde_json::from_str(&text).map_err(|e| {
            CliError::Usage(format!(
                "bench: {} is not a results file this tilegraph can resume from ({e}); move it away to start over",
                path.display()
            ))
        })?;
        if r.version != RESULTS_VERSION {
            return Err(CliError::Usage(format!(
                "bench: {} is results format {}, this tilegraph writes {RESULTS_VERSION}; move it away to start over",
                path.display(),
                r.version
            )));
        }
        Ok(r)
    }

    /// A finished run (failed ones run again).
    pub fn is_done(&self, key: &str) -> bool {
        self.get(key).is_some_and(|r| r.error.is_none())
    }

    pub fn get(&self, key: &str) -> Option<&RunRecord> {
        self.runs.iter().find(|r| r.key == key)
    }

    pub fn insert(&mut self, record: RunRecord) {
        match self.runs.iter_mut().find(|r| r.key == record.key) {
            Some(slot) => *slot = record,
            None => self.runs.push(record),
        }
    }

    pub fn save(&self, path: &Path) -> Result<(), CliError> {
        write_atomically(path, serde_json::to_string_pretty(self)?.as_bytes())
    }
}

/// Writes `bytes` to `path` through a temporary file in the same directory and a rename.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> Result<(), CliError> {
    let err = |e: std::io::Error| CliError::Write {
        path: path.to_path_buf(),
        reason: e.to_string(),
    };
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".partial");
    let tmp = std::path::PathBuf::from(tmp);
    std::fs::write(&tmp, bytes).map_err(err)?;
    std::fs::rename(&tmp, path).map_err(err)
}
