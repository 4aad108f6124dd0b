//! report.md: per scene and size, every setting's accuracy and cost, the Pareto front marked.

use std::fmt::Write;

use super::matrix::Labels;
use super::RunRecord;

/// The runs of one scene at one size: one Pareto plot, one table.
pub struct Group<'a> {
    pub scene: String,
    pub size: [u32; 2],
    pub runs: Vec<&'a RunRecord>,
}

impl<'a> Group<'a> {
    /// A file-name stem: `city-300-320x180`.
    pub fn stem(&self) -> String {
        let scene: String = self
            .scene
            .rsplit(['/', '\\'])
            .next()
            .unwrap_or(&self.scene)
            .chars()
            .map(|c| if c.is_ascii_alphanumeric() { c } else { '-' })
            .collect();
        format!("{scene}-{}x{}", self.size[0], self.size[1])
    }

    /// Whether its runs swept levels of detail (knob `lod_error_px` set on one of them).
    pub fn has_lod(&self) -> bool {
        self.runs
            .iter()
            .any(|r| r.settings.knobs.contains_key("lod_error_px"))
    }

    /// Whether a run measured shadow casters against the oracle.
    pub fn has_shadows(&self) -> bool {
        self.runs.iter().any(|r| {
            r.totals
                .as_ref()
                .is_some_and(|t| t.shadow_casters_needed.is_some())
        })
    }

    /// The runs that measured something, each with whether it is on the Pareto front of
    /// (frame GPU ms, FN rate): no other run is at least as fast and at least as accurate and
    /// better in one.
    pub fn measured(&self) -> Vec<(&'a RunRecord, bool)> {
        let ok: Vec<&'a RunRecord> = self
            .runs
            .iter()
            .copied()
            .filter(|r| r.totals.is_some())
            .collect();
        let point = |r: &RunRecord| {
            r.totals
                .as_ref()
                .map_or((0.0, 0.0), |t| (t.frame_gpu_ms, t.fn_rate))
        };
        ok.iter()
            .map(|r| {
                let (ms, fnr) = point(r);
                let dominated = ok.iter().any(|o| {
                    let (oms, ofn) = point(o);
                    oms <= ms && ofn <= fnr && (oms < ms || ofn < fnr)
                });
                (*r, !dominated)
            })
            .collect()
    }
}

/// Runs grouped by scene and size, in first-seen order.
pub fn groups<'a>(runs: &[&'a RunRecord]) -> Vec<Group<'a>> {
    let mut out: Vec<Group<'a>> = Vec::new();
    for r in runs {
        let s = &r.settings;
        match out
            .iter_mut()
            .find(|g| g.scene == s.scene && g.size == s.size)
        {
            Some(g) => g.runs.push(r),
            None => out.push(Group {
                scene: s.scene.clone(),
                size: s.size,
                runs: vec![r],
            }),
        }
    }
    out
}

pub fn markdown(runs: &[&RunRecord], labels: &Labels) -> String {
    let mut md = String::from("# tilegraph bench\n\n");
    let mut devices: Vec<String> = runs
        .iter()
        .map(|r| {
            format!(
                "{} ({} {}, Vulkan {})",
                r.device.name, r.device.driver, r.device.driver_version, r.device.api
            )
        })
        .collect();
    devices.sort();
    devices.dedup();
    let _ = writeln!(
        md,
        "tilegraph {}; device: {}. Every run renders its camera path three times — the exact \
         oracle, the unculled reference and the setting — and counts false negatives (visible but \
         culled; FN rate = FN / visible) and false positives (FP rate = FP / drawn) per frame; the \
         frame's GPU time is the median (and 95th percentile) of frames timed whole, two \
         timestamps each; culling ms and in-passes ms sum per-pass medians of frames timed per \
         pass (what lies between the passes — clears, stores, barriers — is in the frame only). \
         Conservative settings sit on FN rate 0; **bold** rows are the Pareto front of (frame GPU ms, FN rate); \
         each row's key labels its points in the plots. `report.html` holds the same with the worst frames' images.\n",
        env!("CARGO_PKG_VERSION"),
        devices.join("; ")
    );
    if runs.iter().any(|r| r.device.name.contains("llvmpipe")) {
        md.push_str(
            "On llvmpipe (a CPU rasterizer) per-pass times inside one render pass land where it \
             flushed and fragment counts are before the depth test: compare frame totals.\n\n",
        );
    }
    for g in groups(runs) {
        let _ = writeln!(
            md,
            "## {} at {}x{}\n\n![Pareto](pareto-{stem}.svg)\n![GPU time per pass](passes-{stem}.svg)\n",
            g.scene,
            g.size[0],
            g.size[1],
            stem = g.stem()
        );
        md.push_str(&table(&g, labels));
        md.push('\n');
        if g.has_shadows() {
            let _ = writeln!(md, "![Shadow casters](casters-{}.svg)\n", g.stem());
            md.push_str(&caster_table(&g, labels));
            md.push('\n');
        }
        if g.has_lod() {
            let _ = writeln!(md, "![Levels of detail](lod-{}.svg)\n", g.stem());
            md.push_str(&lod_table(&g, labels));
            md.push('\n');
        }
    }
    md
}

/// One group's image error against the full-detail, unculled frames (levels of detail trade
/// it for triangles): per setting, triangles per frame, frame ms, RMSE, PSNR (worst frame
/// too) and the largest channel difference.
pub fn lod_table(g: &Group<'_>, labels: &Labels) -> String {
    let mut md = String::from(
        "| setting | triangles / frame | frame ms | RMSE | PSNR dB | worst frame dB | largest difference | largest depth difference |\n|---|---|---|---|---|---|---|---|\n",
    );
    let db = |p: Option<f64>| p.map_or("exact".to_string(), |p| format!("{p:.1}"));
    for (r, _) in g.measured() {
        let Some(t) = &r.totals else { continue };
        let worst = r
            .frames
            .iter()
            .filter_map(|f| f.image_psnr_db)
            .min_by(f64::total_cmp);
        let _ = writeln!(
            md,
            "| {} | {:.0} | {:.3} | {:.2} | {} | {} | {} | {} |",
            labels.label(&r.settings),
            t.triangles_drawn as f64 / t.frames.max(1) as f64,
            t.frame_gpu_ms,
            t.image_rmse,
            db(t.image_psnr_db),
            db(worst),
            t.image_max_channel_diff,
            t.image_max_depth_rel_diff
                .map_or("-".to_string(), |d| format!("{:.2} %", 100.0 * d)),
        );
    }
    md
}

/// One group's shadow casters: per setting with shadows, the casters drawn and needed per
/// frame (the oracle's: those whose shadow can reach a visible pixel), drawn but not needed
/// (FP) and needed but culled where the image differed (FN), the shadow passes' GPU ms.
pub fn caster_table(g: &Group<'_>, labels: &Labels) -> String {
    let mut md = String::from(
        "| setting | casters drawn / frame | needed / frame | caster FP | caster FN | shadow ms |\n|---|---|---|---|---|---|\n",
    );
    for (r, _) in g.measured() {
        let Some(t) = &r.totals else { continue };
        let (Some(drawn), Some(needed)) = (t.shadow_casters, t.shadow_casters_needed) else {
            continue;
        };
        let frames = t.frames.max(1) as f64;
        let _ = writeln!(
            md,
            "| {} | {:.1} | {:.1} | {} | {} | {:.3} |",
            labels.label(&r.settings),
            drawn as f64 / frames,
            needed as f64 / frames,
            t.shadow_caster_false_positives.unwrap_or(0),
            t.shadow_caster_false_negatives.unwrap_or(0),
            t.shadow_gpu_ms
        );
    }
    md
}

/// One measured setting's row of a group's table (Markdown and HTML alike).
pub struct Row<'a> {
    pub run: &'a RunRecord,
    /// Its short key (`s12`, as the Pareto plot labels it).
    pub key: String,
    /// On the Pareto front of (frame GPU ms, FN rate).
    pub front: bool,
    /// The measured columns, as [`COLUMNS`] names them.
    pub cells: Vec<String>,
}

/// The measured columns of a group's table.
pub const COLUMNS: [&str; 12] = [
    "profile",
    "frames",
    "FN (frames)",
    "FN rate",
    "FP rate",
    "images equal",
    "culling ms",
    "in passes ms",
    "frame ms",
    "p95 ms",
    "ideal ms (efficiency)",
    "CPU ms",
];

/// Every measured setting of `g`, fastest first.
pub fn rows<'a>(g: &Group<'a>, labels: &Labels) -> Vec<Row<'a>> {
    let mut measured = g.measured();
    measured.sort_by(|a, b| {
        let ms = |r: &RunRecord| r.totals.as_ref().map_or(f64::MAX, |t| t.frame_gpu_ms);
        ms(a.0).total_cmp(&ms(b.0))
    });
    measured
        .into_iter()
        .filter_map(|(run, front)| {
            let t = run.totals.as_ref()?;
            let cells = vec![
                run.device.profile.clone(),
                t.frames.to_string(),
                format!("{} ({})", t.false_negatives, t.frames_with_false_negatives),
                format!("{:.4}", t.fn_rate),
                format!("{:.3}", t.fp_rate),
                match (t.image_diff_pixels, t.image_diff_pixels_depth_tie) {
                    (0, _) => format!("{}/{}", t.frames_image_equal, t.frames),
                    (d, ties) => format!(
                        "{}/{} ({d} px, {ties} ties)",
                        t.frames_image_equal, t.frames
                    ),
                },
                format!("{:.3}", t.cull_gpu_ms),
                format!("{:.3}", t.passes_gpu_ms),
                format!("{:.3}", t.frame_gpu_ms),
                format!("{:.3}", t.frame_gpu_ms_p95),
                match t.ideal_frame_gpu_ms {
                    Some(i) if t.frame_gpu_ms > 0.0 => {
                        format!("{i:.3} ({:.2})", i / t.frame_gpu_ms)
                    }
                    _ => "—".into(),
                },
                format!("{:.2}", t.cpu_ms),
            ];
            Some(Row {
                run,
                key: labels.short(&run.settings),
                front,
                cells,
            })
        })
        .collect()
}

/// One group's table: every measured setting, fastest first, keyed as the plot labels it, the
/// Pareto front in bold, then the settings that failed.
pub fn table(g: &Group<'_>, labels: &Labels) -> String {
    let mut md = format!(
        "| key | setting | {} |\n|---|---|{}\n",
        COLUMNS.join(" | "),
        "---|".repeat(COLUMNS.len())
    );
    for row in rows(g, labels) {
        let r = row.run;
        let mut label = labels.label(&r.settings);
        if r.settings.culling != r.culling {
            label = format!("{label} → {}", r.culling);
        }
        if row.front {
            label = format!("**{label}**");
        }
        let _ = writeln!(md, "| {} | {label} | {} |", row.key, row.cells.join(" | "));
    }
    for r in g.runs.iter().filter(|r| r.error.is_some()) {
        let _ = writeln!(
            md,
            "\nFailed: {} {} — {}",
            labels.short(&r.settings),
            labels.label(&r.settings),
            r.error.as_deref().unwrap_or_default()
        );
    }
    md
}
