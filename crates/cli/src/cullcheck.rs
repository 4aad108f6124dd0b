//! `tilegraph cull-check`: a culling technique against the exact oracle along a camera path.

use std::path::Path;

use tilegraph_passes::cullcheck::{
    cull_check_options, CheckExtras, CullCheck, FailedFrame, OnFailure,
};
use tilegraph_passes::knobs::Resolved;
use tilegraph_passes::RenderOptions;
use tilegraph_profile::knobs::KnobSettings;
use tilegraph_vk::{Context, Feature, FeatureRequest};

use crate::run::{RunArgs, TechniqueMeant};
use crate::CliError;

/// The device features the oracle and the GPU culling lists need (the visibility buffer's ids,
/// indirect counts); the culling's own are optional until the renderer checks them.
pub fn oracle_features() -> FeatureRequest {
    FeatureRequest::executor().require([
        Feature::GeometryShader,
        Feature::DrawIndirectCount,
        Feature::MultiDrawIndirect,
        Feature::HostQueryReset,
    ])
}

/// Runs the check on a context of its own.
pub fn run(a: &RunArgs, save_frames: Option<&Path>) -> Result<(), CliError> {
    let knobs = a.knob_settings(TechniqueMeant::Culling)?;
    let scene = crate::run::load_scene(&a.scene, crate::run::wants_clusters(&knobs))?;
    if let Some(dir) = save_frames {
        std::fs::create_dir_all(dir).map_err(|e| CliError::Write {
            path: dir.to_path_buf(),
            reason: e.to_string(),
        })?;
    }
    let (report, resolved, caveat) =
        crate::run::on_context(a.context_options(oracle_features()), |ctx| {
            let (report, resolved) = check(ctx, a, &knobs, &scene, save_frames)?;
            Ok((report, resolved, crate::device_caveat(ctx)))
        })?;
    print(a, &report, &resolved, caveat)
}

/// The check on `ctx` with `a`'s knobs.
pub fn check(
    ctx: &Context,
    a: &RunArgs,
    knobs: &KnobSettings,
    scene: &tilegraph_scene::Scene,
    save_frames: Option<&Path>,
) -> Result<(CullCheck, Resolved), CliError> {
    let path = a.camera_path(scene)?;
    let (w, h) = a.size.unwrap_or((320, 180));
    let mut o = RenderOptions {
        width: w,
        height: h,
        ..Default::default()
    };
    o.pvs = a.load_pvs()?;
    let resolved = RunArgs::resolve(ctx, scene, knobs, &mut o)?;
    let mut save = |f: &FailedFrame<'_>| -> Result<(), String> {
        let Some(dir) = save_frames else {
            return Ok(());
        };
        let n = f.check.frame;
        for (what, image) in [
            ("technique", f.technique),
            ("reference", f.reference),
            ("diff", &f.diff),
        ] {
            crate::image_io::write_png(&dir.join(format!("frame-{n:04}-{what}.png")), image)
                .map_err(|e| e.to_string())?;
        }
        Ok(())
    };
    let bar = indicatif::ProgressBar::new(0);
    let mut progress = |done: usize, all: usize| {
        bar.set_length(all as u64);
        bar.set_position(done as u64);
    };
    let extras = CheckExtras {
        auto: resolved.auto_trial(crate::run::auto_inputs(ctx, scene, o.pvs.as_deref())),
        on_failure: save_frames.map(|_| &mut save as OnFailure<'_>),
        on_frame: Some(&mut progress),
        motion: crate::run::split_motion(&a.scene)?.1,
        timing_warmup: crate::run::TIMING_WARMUP,
    };
    let check = cull_check_options(ctx, scene, o, &path, a.frames.map(|f| f as usize), extras);
    bar.finish_and_clear();
    let check = check?;
    Ok((check, resolved))
}

fn print(
    a: &RunArgs,
    report: &CullCheck,
    resolved: &Resolved,
    caveat: Option<&str>,
) -> Result<(), CliError> {
    if a.json {
        outln!("{}", serde_json::to_string(report)?)?;
        return Ok(());
    }
    outln!(
        "{} on {:?} ({} instances culled on the GPU), profile {}, {}x{}, {} frames",
        report.technique,
        report.scene,
        report.totals.instances,
        report.profile,
        report.size[0],
        report.size[1],
        report.totals.frames
    )?;
    for line in resolved.describe() {
        outln!("  {line}")?;
    }
    if let Some(why) = &report.auto_review {
        outln!("  then {why}")?;
    }
    // A cluster technique's frames also compare clusters (visible, drawn, FN, FP).
    let clusters = report.frames.iter().any(|f| f.clusters.is_some());
    let cluster_columns = |f: Option<&tilegraph_passes::cullcheck::ClusterCheck>| match f {
        Some(c) => format!(
            " {:>9} {:>9} {:>6} {:>8}",
            c.visible, c.drawn, c.false_negatives, c.false_positives
        ),
        None if clusters => format!(" {:>9} {:>9} {:>6} {:>8}", "-", "-", "-", "-"),
        None => String::new(),
    };
    outln!(
        "{:>6} {:>4} {:>8} {:>8} {:>6} {:>8} {:>12}{}",
        "frame",
        "cut",
        "visible",
        "drawn",
        "FN",
        "FP",
        "image equal",
        if clusters {
            format!(" {:>9} {:>9} {:>6} {:>8}", "clusters", "drawn", "FN", "FP")
        } else {
            String::new()
        }
    )?;
    for f in &report.frames {
        outln!(
            "{:>6} {:>4} {:>8} {:>8} {:>6} {:>8} {:>12}{}",
            f.frame,
            if f.cut { "cut" } else { "" },
            f.visible,
            f.drawn,
            f.false_negatives,
            f.false_positives,
            f.image_equal,
            cluster_columns(f.clusters.as_ref())
        )?;
    }
    let t = &report.totals;
    outln!(
        "totals: visible {} drawn {} FN {} (in {} frames) FP {} (rate {:.3}); images equal {}/{}; triangles drawn {}; culling GPU {:.3} ms of {:.3} ms per frame (medians)",
        t.visible, t.drawn, t.false_negatives, t.frames_with_false_negatives, t.false_positives, t.false_positive_rate, t.frames_image_equal, t.frames, t.triangles_drawn, t.cull_gpu_ms, t.frame_gpu_ms
    )?;
    if t.image_diff_pixels > 0 {
        outln!(
            "images differ in {} pixels over the path, {} of them depth ties (both frames hold the same depth there, and another surface at that depth won: depth precision and draw order, not culling){}; {} neither",
            t.image_diff_pixels,
            t.image_diff_pixels_depth_tie,
            match t.image_diff_pixels_stray {
                0 => String::new(),
                n => format!(", {n} stray (below)"),
            },
            t.image_diff_pixels_unexplained
        )?;
    }
    if t.stray_only + t.cluster_stray_only + t.image_diff_pixels_stray > 0 {
        outln!(
            "stray pixels: {} of the differing pixels are a degenerate triangle's, which the rasterizer draws at a depth the triangle never reaches or covers differently from draw to draw (in the unculled frame or the technique's: no culling keeps or makes them); {} culled instances and {} culled clusters were seen only through pixels off their triangles' depth and count neither visible nor FN",
            t.image_diff_pixels_stray, t.stray_only, t.cluster_stray_only
        )?;
    }
    if let Some(ms) = t.software_cpu_ms {
        outln!("software occlusion: {ms:.3} CPU ms per frame (median)")?;
    }
    if let (Some(ideal), Some(e)) = (t.ideal_frame_gpu_ms, t.efficiency) {
        let set = if clusters {
            "visible clusters"
        } else {
            "visible instances"
        };
        outln!(
            "ideal frame (the oracle's {set}, no culling work): {ideal:.3} ms; efficiency {e:.2}"
        )?;
    }
    if clusters {
        outln!(
            "clusters: FN {} (in {} frames) FP {}",
            t.cluster_false_negatives,
            t.frames_with_cluster_false_negatives,
            t.cluster_false_positives
        )?;
    }
    if let (Some(drawn), Some(all)) = (t.shadow_casters, t.shadow_casters_all) {
        outln!(
            "shadow casters: {drawn} drawn of {all} (every caster into every cascade, the reference's); shadow passes {:.3} ms",
            t.shadow_gpu_ms
        )?;
    }
    if let (Some(needed), Some(fp), Some(fn_)) = (
        t.shadow_casters_needed,
        t.shadow_caster_false_positives,
        t.shadow_caster_false_negatives,
    ) {
        outln!(
            "shadow casters against the oracle: {needed} needed by visible pixels; FP {fp} (drawn, none needed); FN {fn_} (needed and culled where the image differs)"
        )?;
    }
    if let Some(c) = caveat {
        outln!("{c}")?;
    }
    Ok(())
}
