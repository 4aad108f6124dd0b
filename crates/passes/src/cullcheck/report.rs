//! What a check reports: each frame's comparison, the totals over the path, and the whole
//! report (`tilegraph cull-check --json`).

use serde::Serialize;

use super::{CasterCheck, ClusterCheck, ImageError};

/// One frame's comparison.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FrameCheck {
    pub frame: usize,
    /// The camera jumped to this frame.
    pub cut: bool,
    pub visible: usize,
    pub drawn: usize,
    pub false_negatives: usize,
    pub false_positives: usize,
    pub image_equal: bool,
    /// Pixels where the technique's image differs from the unculled one.
    pub image_diff_pixels: usize,
    /// Of those, pixels whose owner in the oracle was drawn by the technique: a draw-order tie
    /// between coplanar or intersecting surfaces (two-phase culling draws some instances in its
    /// second phase), not a culling error. A culling error shows as a difference at a pixel whose
    /// owner was culled.
    pub image_diff_pixels_owner_drawn: usize,
    /// Of the differing pixels, those where both frames hold the same depth, bit for bit: the
    /// nearest surface is there, and of surfaces at its depth (or at the cleared depth, where
    /// an EQUAL test lets them through) another won — a tie that depth precision makes (D16,
    /// or standard depth with a tiny near plane), resolved by draw order, not a culling error.
    pub image_diff_pixels_depth_tie: usize,
    /// Of the differing pixels, those whose owner in the oracle is stray: drawn at a depth its
    /// triangle never reaches (a degenerate sliver's ill-conditioned depth plane, `stray.rs`),
    /// a rasterizer's artefact that no culling can be held to.
    pub image_diff_pixels_stray: usize,
    /// Of the differing pixels, those neither a depth tie nor stray: what to look at.
    pub image_diff_pixels_unexplained: usize,
    /// How far the image lies from the reference (levels of detail trade this for triangles;
    /// an exact technique's is zero).
    pub image_error: ImageError,
    /// Triangles of the drawn instances (with levels of detail, of the levels drawn).
    pub triangles_drawn: u64,
    /// Up to 8 instance ids that were visible but culled (for debugging).
    pub false_negative_ids: Vec<u32>,
    /// Instances the technique culled whose every pixel in the oracle is stray (see
    /// `image_diff_pixels_stray`): counted neither visible nor false negative.
    pub stray_only: usize,
    /// Below the instance, for a cluster technique: visible clusters culled are false
    /// negatives too (`None`: not a cluster technique, or the oracle's ids hold no triangle).
    pub clusters: Option<ClusterCheck>,
    /// With shadows: the casters the technique drew into its cascades (summed), and those
    /// the reference drew — every caster into every cascade, so the image comparison checks
    /// the caster culling too (`None` without shadows or a GPU draw count).
    pub shadow_casters: Option<u32>,
    pub shadow_casters_all: Option<u32>,
    /// With shadows, the casters against the oracle's: needed by the visible pixels, drawn
    /// but not needed (FP), needed and culled where the image differs (FN) — summed over the
    /// cascades (`casters.rs`). `None` without shadows or a GPU draw count.
    pub casters: Option<CasterCheck>,
}

/// Totals over the path.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Totals {
    pub frames: usize,
    /// Opaque and alpha-tested instances (what the comparison covers).
    pub instances: usize,
    pub visible: usize,
    pub drawn: usize,
    pub false_negatives: usize,
    pub false_positives: usize,
    /// FP / drawn.
    pub false_positive_rate: f64,
    pub frames_with_false_negatives: usize,
    /// Visible clusters culled, over the path (cluster techniques; 0 otherwise).
    pub cluster_false_negatives: usize,
    /// Frames with a visible cluster culled.
    pub frames_with_cluster_false_negatives: usize,
    /// Clusters drawn that owned no pixel (cluster techniques).
    pub cluster_false_positives: usize,
    /// Culled instances and clusters seen only through stray pixels (`FrameCheck::stray_only`,
    /// `ClusterCheck::stray_only`), over the path.
    pub stray_only: usize,
    pub cluster_stray_only: usize,
    pub frames_image_equal: usize,
    /// Pixels that differ from the references over the path, and of those the depth ties
    /// (`FrameCheck::image_diff_pixels_depth_tie`).
    pub image_diff_pixels: usize,
    pub image_diff_pixels_depth_tie: usize,
    /// Of the differing pixels, those whose owner in the oracle is stray
    /// (`FrameCheck::image_diff_pixels_stray`).
    pub image_diff_pixels_stray: usize,
    pub image_diff_pixels_unexplained: usize,
    /// The frames' images against the references', together (mean squared error over the
    /// path, the largest difference).
    pub image_error: ImageError,
    pub triangles_drawn: u64,
    /// Median GPU milliseconds of the culling passes (culling compute, pyramid builds, query,
    /// result-copy and raster-occlusion passes), summed, from timestamps around each pass in
    /// a second pass along the path with frames back to back (no readbacks between them).
    pub cull_gpu_ms: f64,
    /// Median GPU milliseconds of the whole frame, from two timestamps around it (and no
    /// other query) in a third pass along the path: what an engine's frame costs, clears,
    /// loads, stores and barriers between the passes included.
    pub frame_gpu_ms: f64,
    /// The 95th percentile of the same frames.
    pub frame_gpu_ms_p95: f64,
    /// With shadows: casters the technique drew, and every caster into every cascade, summed
    /// over the path; the shadow passes' medians (culling and cascades), summed.
    pub shadow_casters: Option<u64>,
    pub shadow_casters_all: Option<u64>,
    pub shadow_gpu_ms: f64,
    /// With shadows: the casters the oracle's frames needed (a perfect caster culling's
    /// draws, at box level), the drawn casters none needed (FP) and the needed ones culled where
    /// the image differed (FN), summed over the path.
    pub shadow_casters_needed: Option<u64>,
    pub shadow_caster_false_positives: Option<u64>,
    pub shadow_caster_false_negatives: Option<u64>,
    /// The **ideal frame**: the oracle's visible set of each frame drawn with no culling work
    /// (everything else hidden), timed whole like `frame_gpu_ms` — what a perfect culling would
    /// cost on this GPU, the ceiling of every technique. The set is the visible instances,
    /// drawn whole; for a cluster technique, their visible clusters only (each instance's runs
    /// of them). `None` for a moving scene.
    pub ideal_frame_gpu_ms: Option<f64>,
    /// `ideal_frame_gpu_ms / frame_gpu_ms`: 1 is as good as culling gets.
    pub efficiency: Option<f64>,
    /// The passes' median GPU milliseconds summed (the second pass): the frame without what
    /// lies between its passes; `frame_gpu_ms - passes_gpu_ms` is that. On lavapipe it misses
    /// most rasterization, which runs when a render pass's tiles are flushed.
    pub passes_gpu_ms: f64,
    /// Median CPU milliseconds the tested renderer's frame took to record and submit (with
    /// what waiting for a free frame slot cost), frames back to back (the third pass).
    pub cpu_ms: f64,
    /// With software occlusion: the median CPU milliseconds of its part of those frames
    /// (choosing occluders, rasterizing, testing boxes).
    pub software_cpu_ms: Option<f64>,
    /// Median GPU milliseconds of each pass of the tested frame, in recording order.
    pub passes: Vec<PassTime>,
}

/// One pass's GPU time over the path: median and 95th percentile.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PassTime {
    pub name: String,
    pub gpu_ms: f64,
    pub p95_gpu_ms: f64,
}

/// The whole report (`tilegraph cull-check --json`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CullCheck {
    /// The culling that ran (after `auto`'s review, the one it switched to).
    pub technique: String,
    /// `auto`'s trial: what it timed and what it kept (`None` when the culling was given).
    pub auto_review: Option<String>,
    pub scene: String,
    pub profile: String,
    pub size: [u32; 2],
    pub frames: Vec<FrameCheck>,
    pub totals: Totals,
}
