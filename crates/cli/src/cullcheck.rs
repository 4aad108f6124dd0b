//! `tilegraph cull-check`: a culling technique against the exact oracle along a camera path.

use std::path::Path;

use tilegraph_passes::cull::Culling;
use tilegraph_passes::cullcheck::{cull_check_with, CheckOptions};
use tilegraph_scene::CameraPath;
use tilegraph_vk::{Context, ContextOptions, Feature};

use crate::CliError;

pub struct Args<'a> {
    pub scene: &'a str,
    pub culling: Culling,
    pub camera_path: Option<&'a Path>,
    pub size: (u32, u32),
    pub profile: Option<&'a str>,
    pub frames: Option<usize>,
    pub hiz_npot: tilegraph_cull::NpotMode,
    pub oq_group: usize,
    pub raster_occlusion_scale: u32,
    pub json: bool,
}

pub fn run(a: &Args<'_>) -> Result<(), CliError> {
    let scene = tilegraph_scene::load(a.scene)?;
    let path = match a.camera_path {
        Some(p) => CameraPath::load_json(p)?,
        None => scene.camera_path().clone(),
    };
    let mut options = ContextOptions::from_env();
    if let Some(p) = a.profile {
        options.profile = Some(p.to_string());
    }
    // The oracle's visibility buffer and the GPU culling lists.
    options.features.required.extend([
        Feature::GeometryShader,
        Feature::DrawIndirectCount,
        Feature::MultiDrawIndirect,
        Feature::HostQueryReset,
    ]);
    if a.culling.conditional() {
        // Asked for only when used: without it, the renderer's typed error names the extension.
        options
            .features
            .optional
            .insert(Feature::ConditionalRendering);
    }
    if a.culling == Culling::RasterOcclusion {
        options
            .features
            .optional
            .insert(Feature::FragmentStoresAndAtomics);
    }
    let ctx = Context::new(options)?;
    let report = cull_check_with(
        &ctx,
        &scene,
        a.culling,
        &path,
        a.size,
        a.frames,
        &CheckOptions {
            hiz_mode: a.hiz_npot,
            oq_group: a.oq_group,
            raster_occlusion_scale: a.raster_occlusion_scale,
        },
    )?;
    // Validation through the teardown: objects left alive are reported there.
    ctx.destroy_checked()?;
    if a.json {
        outln!("{}", serde_json::to_string(&report)?)?;
        return Ok(());
    }
    outln!(
        "{} on {:?} ({} instances culled on the GPU), profile {}, {}x{}, {} frames",
        report.technique,
        report.scene,
        report.totals.instances,
        report.profile,
        a.size.0,
        a.size.1,
        report.totals.frames
    )?;
    outln!(
        "{:>6} {:>4} {:>8} {:>8} {:>6} {:>8} {:>12}",
        "frame",
        "cut",
        "visible",
        "drawn",
        "FN",
        "FP",
        "image equal"
    )?;
    for f in &report.frames {
        outln!(
            "{:>6} {:>4} {:>8} {:>8} {:>6} {:>8} {:>12}",
            f.frame,
            if f.cut { "cut" } else { "" },
            f.visible,
            f.drawn,
            f.false_negatives,
            f.false_positives,
            f.image_equal
        )?;
    }
    let t = &report.totals;
    outln!(
        "totals: visible {} drawn {} FN {} (in {} frames) FP {} (rate {:.3}); images equal {}/{}; triangles drawn {}; culling GPU {:.3} ms of {:.3} ms per frame (medians)",
        t.visible, t.drawn, t.false_negatives, t.frames_with_false_negatives, t.false_positives, t.false_positive_rate, t.frames_image_equal, t.frames, t.triangles_drawn, t.cull_gpu_ms, t.frame_gpu_ms
    )?;
    Ok(())
}
