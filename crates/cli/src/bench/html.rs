//! report.html: the report as one self-contained file a browser opens — per scene and size the
//! Pareto plot (inline SVG), the GPU time per pass, and the table of settings keyed as the plot
//! labels them, each knob a column; then the worst frames' images (the setting's, the unculled
//! reference and their diff, embedded as PNG data) of the settings that missed.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use base64::Engine as _;

use super::matrix::Labels;
use super::report::{groups, rows, COLUMNS};
use super::RunRecord;
use crate::markup::escape;
use crate::CliError;

/// How many of the worst frames the report shows (the settings whose images differ most).
const WORST_FRAMES: usize = 8;

const STYLE: &str = "body{font-family:sans-serif;margin:24px;max-width:1400px;color:#222}\
table{border-collapse:collapse;font-size:12px;margin:12px 0}\
th,td{border:1px solid #ccc;padding:3px 6px;text-align:right}\
th{background:#eee}td.text{text-align:left}tr.front td{font-weight:bold;background:#f4f8ff}\
figure{margin:12px 0}figcaption{font-size:12px;color:#555}\
.frames{display:flex;gap:8px;flex-wrap:wrap}.frames img{image-rendering:pixelated;max-width:440px;border:1px solid #aaa}";

/// Writes `report.html` into `out` (where the plots of `runs` were written).
pub fn write(out: &Path, runs: &[&RunRecord], labels: &Labels) -> Result<PathBuf, CliError> {
    let path = out.join("report.html");
    super::results::write_atomically(&path, html(out, runs, labels).as_bytes())?;
    Ok(path)
}

/// An SVG file of `out`, to inline: its `<svg>` element on, any XML prolog dropped.
fn inline_svg(out: &Path, name: &str) -> Option<String> {
    let text = std::fs::read_to_string(out.join(name)).ok()?;
    let at = text.find("<svg")?;
    Some(text[at..].to_string())
}

/// A PNG file of `out` as a data URI (`None` where it cannot be read).
fn png_uri(out: &Path, name: &str) -> Option<String> {
    let bytes = std::fs::read(out.join(name)).ok()?;
    Some(format!(
        "data:image/png;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(bytes)
    ))
}

fn html(out: &Path, runs: &[&RunRecord], labels: &Labels) -> String {
    let mut h = format!(
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>tilegraph bench</title><style>{STYLE}</style></head><body>\n<h1>tilegraph bench</h1>\n"
    );
    let mut devices: Vec<String> = runs
        .iter()
        .map(|r| {
            format!(
                "{} ({} {}, Vulkan {}), tilegraph {}",
                r.device.name,
                r.device.driver,
                r.device.driver_version,
                r.device.api,
                r.device.build
            )
        })
        .collect();
    devices.sort();
    devices.dedup();
    let _ = writeln!(
        h,
        "<p>{} settings on {}. Each ran its camera path against the exact oracle: FN rate = \
         visible instances culled / visible, FP rate = hidden instances drawn / drawn; frame ms \
         is the median of frames timed whole. Plots label the Pareto front of (frame ms, FN \
         rate) with the settings' keys, which the tables resolve; the front's rows are bold.</p>",
        runs.len(),
        escape(&devices.join("; "))
    );
    for g in groups(runs) {
        let stem = g.stem();
        let _ = writeln!(
            h,
            "<h2>{} at {}x{}</h2>\n<figure>{}</figure>",
            escape(&g.scene),
            g.size[0],
            g.size[1],
            super::pareto::svg(&g, labels)
        );
        for (name, what) in [
            (format!("passes-{stem}.svg"), "GPU time per pass"),
            (format!("casters-{stem}.svg"), "shadow casters"),
        ] {
            if let Some(svg) = inline_svg(out, &name) {
                let _ = writeln!(h, "<figure>{svg}<figcaption>{what}</figcaption></figure>");
            }
        }
        // The table: key, culling (shading), a column per knob, then the measured columns.
        h.push_str("<table class=\"runs\"><tr><th>key</th><th>culling</th>");
        if labels.shading_varies() {
            h.push_str("<th>shading</th>");
        }
        for k in labels.knob_names() {
            let _ = write!(h, "<th>{}</th>", escape(k));
        }
        for c in COLUMNS {
            let _ = write!(h, "<th>{}</th>", escape(c));
        }
        h.push_str("</tr>\n");
        for row in rows(&g, labels) {
            let s = &row.run.settings;
            let culling = if s.culling == row.run.culling {
                s.culling.clone()
            } else {
                format!("{} → {}", s.culling, row.run.culling)
            };
            let _ = write!(
                h,
                "<tr{} data-key=\"{}\"><td class=\"text\">{}</td><td class=\"text\">{}</td>",
                if row.front { " class=\"front\"" } else { "" },
                row.key,
                row.key,
                escape(&culling)
            );
            if labels.shading_varies() {
                let _ = write!(h, "<td class=\"text\">{}</td>", escape(&s.shading));
            }
            for k in labels.knob_names() {
                let v = s.knobs.get(k).map_or(String::new(), |v| v.to_string());
                let _ = write!(h, "<td class=\"text\">{}</td>", escape(&v));
            }
            for c in &row.cells {
                let _ = write!(h, "<td>{}</td>", escape(c));
            }
            h.push_str("</tr>\n");
        }
        h.push_str("</table>\n");
        for r in g.runs.iter().filter(|r| r.error.is_some()) {
            let _ = writeln!(
                h,
                "<p>Failed: {} {} — {}</p>",
                labels.short(&r.settings),
                escape(&labels.label(&r.settings)),
                escape(r.error.as_deref().unwrap_or_default())
            );
        }
    }
    worst_frames(&mut h, out, runs, labels);
    h.push_str("</body></html>\n");
    h
}

/// The settings whose images differ most, each with its worst frame's three images.
fn worst_frames(h: &mut String, out: &Path, runs: &[&RunRecord], labels: &Labels) {
    h.push_str("<h2>Worst frames</h2>\n");
    let mut worst: Vec<(&RunRecord, &super::WorstFrame)> = runs
        .iter()
        .filter_map(|r| r.worst_frame.as_ref().map(|w| (*r, w)))
        .collect();
    if worst.is_empty() {
        h.push_str("<p>Every frame of every setting equals the unculled image.</p>\n");
        return;
    }
    worst.sort_by(|a, b| {
        (b.1.differing_pixels, b.1.false_negatives)
            .cmp(&(a.1.differing_pixels, a.1.false_negatives))
    });
    let _ = writeln!(
        h,
        "<p>{} settings drew a frame unlike the unculled image; the {} worst: the setting's \
         image, the unculled reference, and the diff (the reference in grey, differing pixels \
         red, visible instances culled magenta).</p>",
        worst.len(),
        worst.len().min(WORST_FRAMES)
    );
    for (r, w) in worst.into_iter().take(WORST_FRAMES) {
        let _ = writeln!(
            h,
            "<h3>{} {} ({} {}x{}): frame {}, {} pixels differ, FN {}</h3>\n<div class=\"frames\">",
            labels.short(&r.settings),
            escape(&labels.label(&r.settings)),
            escape(&r.settings.scene),
            r.settings.size[0],
            r.settings.size[1],
            w.frame,
            w.differing_pixels,
            w.false_negatives
        );
        for (file, what) in [
            (&w.technique, "setting"),
            (&w.reference, "unculled"),
            (&w.diff, "diff"),
        ] {
            match png_uri(out, file) {
                Some(uri) => {
                    let _ = writeln!(
                        h,
                        "<figure><img class=\"frame\" alt=\"{what}\" src=\"{uri}\"><figcaption>{what}</figcaption></figure>"
                    );
                }
                None => {
                    let _ = writeln!(h, "<p>({what}: {} is missing)</p>", escape(file));
                }
            }
        }
        h.push_str("</div>\n");
    }
}
