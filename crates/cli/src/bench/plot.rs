//! The bench's SVG plots drawn with plotters: the GPU time per pass of each setting as stacked
//! bars, and the shadow casters. (The Pareto plot is `pareto.rs`'s.)

use std::path::{Path, PathBuf};

use plotters::prelude::*;

use super::matrix::Labels;
use super::report::Group;
use super::{RunRecord, Setting};
use crate::CliError;

fn colour(i: usize) -> RGBColor {
    let c = Palette99::pick(i).to_rgba();
    RGBColor(c.0, c.1, c.2)
}

fn write_err(path: &Path) -> impl Fn(String) -> CliError {
    let path = path.to_path_buf();
    move |reason| CliError::Write {
        path: path.clone(),
        reason,
    }
}

/// `casters-<scene>-<WxH>.svg`: per setting with shadows, x the shadow passes' GPU ms, y the
/// casters drawn per frame (filled; the front of (ms, casters) joined) and the caster FN per
/// frame (crosses, 0 for an exact culling); the oracle's needed casters per frame — what a
/// perfect caster culling would draw — a dashed line.
pub fn casters(out: &Path, g: &Group<'_>, labels: &Labels) -> Result<PathBuf, CliError> {
    let path = out.join(format!("casters-{}.svg", g.stem()));
    let err = write_err(&path);
    let points: Vec<_> = g
        .measured()
        .into_iter()
        .filter_map(|(r, _)| {
            let t = r.totals.as_ref()?;
            let frames = t.frames.max(1) as f64;
            let per_frame = |v: Option<u64>| v.map(|v| v as f64 / frames);
            Some((
                labels.label(&r.settings),
                t.shadow_gpu_ms,
                per_frame(t.shadow_casters)?,
                per_frame(t.shadow_casters_needed)?,
                per_frame(t.shadow_caster_false_negatives).unwrap_or(0.0),
            ))
        })
        .collect();
    let max_ms = points.iter().map(|p| p.1).fold(1e-3, f64::max) * 1.15;
    let max_casters = points.iter().map(|p| p.2.max(p.4)).fold(1.0, f64::max) * 1.15;
    let needed = points.iter().map(|p| p.3).fold(0.0, f64::max);
    let height = 420 + 18 * points.len() as u32;
    {
        let root = SVGBackend::new(&path, (900, height)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(e.to_string()))?;
        let mut chart = ChartBuilder::on(&root)
            .caption(
                format!(
                    "{} {}x{}: shadow casters drawn (filled), caster FN (x) and needed (dashed) per frame against shadow GPU ms",
                    g.scene, g.size[0], g.size[1]
                ),
                ("sans-serif", 16),
            )
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(64)
            .build_cartesian_2d(0.0..max_ms, 0.0..max_casters)
            .map_err(|e| err(e.to_string()))?;
        chart
            .configure_mesh()
            .x_desc("shadow passes GPU ms (median)")
            .y_desc("casters per frame")
            .draw()
            .map_err(|e| err(e.to_string()))?;
        chart
            .draw_series(DashedLineSeries::new(
                [(0.0, needed), (max_ms, needed)],
                6,
                4,
                BLACK.stroke_width(1),
            ))
            .map_err(|e| err(e.to_string()))?
            .label(format!("needed by the visible pixels ({needed:.1})"))
            .legend(|(x, y)| PathElement::new([(x - 8, y), (x + 8, y)], BLACK));
        for (i, (label, ms, drawn, _, fn_)) in points.iter().enumerate() {
            let c = colour(i);
            chart
                .draw_series([Circle::new((*ms, *drawn), 6, c.filled())])
                .map_err(|e| err(e.to_string()))?
                .label(format!("{label}: {drawn:.1} drawn, FN {fn_:.1}"))
                .legend(move |(x, y)| Circle::new((x, y), 5, c.filled()));
            chart
                .draw_series([Cross::new((*ms, *fn_), 5, c.stroke_width(2))])
                .map_err(|e| err(e.to_string()))?;
        }
        let mut front: Vec<(f64, f64)> = points
            .iter()
            .filter(|p| {
                !points
                    .iter()
                    .any(|o| o.1 <= p.1 && o.2 <= p.2 && (o.1 < p.1 || o.2 < p.2))
            })
            .map(|p| (p.1, p.2))
            .collect();
        front.sort_by(|a, b| a.0.total_cmp(&b.0));
        chart
            .draw_series(LineSeries::new(front, BLACK.stroke_width(1)))
            .map_err(|e| err(e.to_string()))?;
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()
            .map_err(|e| err(e.to_string()))?;
        root.present().map_err(|e| err(e.to_string()))?;
    }
    Ok(path)
}

/// How many settings the per-pass plot shows at most, fastest first (the front's always).
const PASS_BARS: usize = 24;

/// `passes-<scene>-<WxH>.svg`: a bar per setting, a segment per pass (median GPU ms): the
/// [`PASS_BARS`] fastest settings and the Pareto front, fastest on top, each named by its short
/// key and culling; the passes' colours in a legend right of the bars.
pub fn passes(out: &Path, g: &Group<'_>, labels: &Labels) -> Result<PathBuf, CliError> {
    let path = out.join(format!("passes-{}.svg", g.stem()));
    let err = write_err(&path);
    let mut measured = g.measured();
    measured.sort_by(|a, b| {
        let ms = |r: &RunRecord| r.totals.as_ref().map_or(f64::MAX, |t| t.frame_gpu_ms);
        ms(a.0).total_cmp(&ms(b.0))
    });
    let all = measured.len();
    let runs: Vec<&RunRecord> = measured
        .iter()
        .enumerate()
        .filter(|(i, (_, front))| *i < PASS_BARS || *front)
        .map(|(_, (r, _))| *r)
        .collect();
    let mut pass_names: Vec<String> = Vec::new();
    for r in &runs {
        for p in &r.passes {
            if !pass_names.contains(&p.name) {
                pass_names.push(p.name.clone());
            }
        }
    }
    let max_ms = runs
        .iter()
        .map(|r| r.passes.iter().map(|p| p.median_gpu_ms).sum::<f64>())
        .fold(0.0f64, f64::max)
        .max(1e-3)
        * 1.1;
    // Fastest on top: the chart's y grows upwards.
    let names: Vec<String> = runs
        .iter()
        .rev()
        .map(|r| format!("{} {}", labels.short(&r.settings), r.settings.culling))
        .collect();
    let height = (120 + 22 * runs.len().max(1)).max(140 + 18 * pass_names.len()) as u32;
    {
        let root = SVGBackend::new(&path, (1000, height)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(e.to_string()))?;
        let (bars_area, legend_area) = root.split_horizontally(790);
        let n = runs.len().max(1) as f64;
        let shown = if runs.len() < all {
            format!(
                ", the {} fastest of {all} settings and the front",
                runs.len()
            )
        } else {
            String::new()
        };
        let mut chart = ChartBuilder::on(&bars_area)
            .caption(
                format!(
                    "{} {}x{}: GPU ms per pass (medians){shown}",
                    g.scene, g.size[0], g.size[1]
                ),
                ("sans-serif", 15),
            )
            .margin(12)
            .x_label_area_size(36)
            .y_label_area_size(190)
            .build_cartesian_2d(0.0..max_ms, 0.0..n)
            .map_err(|e| err(e.to_string()))?;
        chart
            .configure_mesh()
            .disable_y_mesh()
            .y_labels(runs.len().max(1) * 2 + 1)
            .y_label_formatter(&|y| {
                let i = (y - 0.5).round();
                if (y - 0.5 - i).abs() < 1e-6 && i >= 0.0 {
                    names.get(i as usize).cloned().unwrap_or_default()
                } else {
                    String::new()
                }
            })
            .x_desc("GPU ms")
            .draw()
            .map_err(|e| err(e.to_string()))?;
        for (pi, pass) in pass_names.iter().enumerate() {
            let c = colour(pi);
            let bars: Vec<Rectangle<(f64, f64)>> = runs
                .iter()
                .rev()
                .enumerate()
                .filter_map(|(i, r)| {
                    let start: f64 = r
                        .passes
                        .iter()
                        .take_while(|p| p.name != *pass)
                        .map(|p| p.median_gpu_ms)
                        .sum();
                    let p = r.passes.iter().find(|p| p.name == *pass)?;
                    let y = i as f64;
                    Some(Rectangle::new(
                        [(start, y + 0.15), (start + p.median_gpu_ms, y + 0.85)],
                        c.filled(),
                    ))
                })
                .collect();
            chart.draw_series(bars).map_err(|e| err(e.to_string()))?;
            // The legend, right of the bars.
            let y = 48 + 18 * pi as i32;
            legend_area
                .draw(&Rectangle::new([(8, y - 5), (18, y + 5)], c.filled()))
                .map_err(|e| err(e.to_string()))?;
            legend_area
                .draw(&Text::new(
                    pass.clone(),
                    (24, y - 6),
                    ("sans-serif", 12).into_font(),
                ))
                .map_err(|e| err(e.to_string()))?;
        }
        root.present().map_err(|e| err(e.to_string()))?;
    }
    Ok(path)
}

/// A setting of a levels-of-detail plot: its label, image error (RMSE), frame ms, triangles
/// per frame.
struct LodPoint {
    label: String,
    error: f64,
    ms: f64,
    triangles: f64,
    /// Its series: the settings that differ in `lod_error_px` only share one.
    series: usize,
}

/// What a panel's y axis reads of a point.
type Axis = fn(&LodPoint) -> f64;

/// `lod-<scene>-<WxH>.svg`: levels of detail's trade, two panels sharing the x axis — the
/// image error against the full-detail, unculled frame (RMSE per channel over the path, 8-bit
/// levels; 0 exact) — with the frame's GPU ms (median) left and the triangles drawn per frame
/// right; a point per setting, a colour per series (settings equal but for `lod_error_px`: one
/// camera path, culling, shading…), each series' Pareto front (no other of its points has less
/// error and less cost) joined.
pub fn lod(out: &Path, g: &Group<'_>, labels: &Labels) -> Result<PathBuf, CliError> {
    let path = out.join(format!("lod-{}.svg", g.stem()));
    let err = write_err(&path);
    let mut series: Vec<Setting> = Vec::new();
    let points: Vec<LodPoint> = g
        .measured()
        .into_iter()
        .filter_map(|(r, _)| {
            let t = r.totals.as_ref()?;
            let psnr = t
                .image_psnr_db
                .map_or("exact".to_string(), |p| format!("{p:.1} dB"));
            let mut key = r.settings.clone();
            key.knobs.remove("lod_error_px");
            let index = series.iter().position(|s| *s == key).unwrap_or_else(|| {
                series.push(key);
                series.len() - 1
            });
            Some(LodPoint {
                label: format!("{} ({psnr})", labels.label(&r.settings)),
                error: t.image_rmse,
                ms: t.frame_gpu_ms,
                triangles: t.triangles_drawn as f64 / t.frames.max(1) as f64,
                series: index,
            })
        })
        .collect();
    let max_error = points.iter().map(|p| p.error).fold(1e-3, f64::max) * 1.15;
    let short = g.scene.rsplit(['/', '\\']).next().unwrap_or(&g.scene);
    let height = 460 + 18 * points.len() as u32;
    {
        let root = SVGBackend::new(&path, (1200, height)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(e.to_string()))?;
        let (top, legend) = root.split_vertically(420);
        let panels = top.split_evenly((1, 2));
        let axes: [(&str, Axis); 2] = [
            ("frame GPU ms (median)", |p| p.ms),
            ("triangles drawn per frame", |p| p.triangles),
        ];
        for (panel, (y_desc, y)) in panels.iter().zip(axes) {
            let max_y = points.iter().map(y).fold(1e-3, f64::max) * 1.15;
            let mut chart = ChartBuilder::on(panel)
                .caption(
                    format!("{short} {}x{}: {y_desc}", g.size[0], g.size[1]),
                    ("sans-serif", 15),
                )
                .margin(12)
                .x_label_area_size(40)
                .y_label_area_size(72)
                .build_cartesian_2d(0.0..max_error, 0.0..max_y)
                .map_err(|e| err(e.to_string()))?;
            chart
                .configure_mesh()
                .x_desc("image error vs full detail: RMSE per channel (8-bit levels)")
                .y_desc(y_desc)
                .draw()
                .map_err(|e| err(e.to_string()))?;
            for p in &points {
                chart
                    .draw_series([Circle::new((p.error, y(p)), 6, colour(p.series).filled())])
                    .map_err(|e| err(e.to_string()))?;
            }
            for k in 0..series.len() {
                let own: Vec<&LodPoint> = points.iter().filter(|p| p.series == k).collect();
                let mut front: Vec<(f64, f64)> = own
                    .iter()
                    .filter(|p| {
                        !own.iter().any(|o| {
                            o.error <= p.error && y(o) <= y(p) && (o.error < p.error || y(o) < y(p))
                        })
                    })
                    .map(|p| (p.error, y(p)))
                    .collect();
                front.sort_by(|a, b| a.0.total_cmp(&b.0));
                chart
                    .draw_series(LineSeries::new(front, colour(k).stroke_width(1)))
                    .map_err(|e| err(e.to_string()))?;
            }
        }
        for (i, p) in points.iter().enumerate() {
            let at = (24, 8 + 18 * i as i32);
            legend
                .draw(&Circle::new(at, 5, colour(p.series).filled()))
                .map_err(|e| err(e.to_string()))?;
            let text = format!(
                "{}: {:.3} ms, {:.0} triangles, RMSE {:.2}",
                p.label, p.ms, p.triangles, p.error
            );
            legend
                .draw(&Text::new(text, (at.0 + 14, at.1 - 7), ("sans-serif", 13)))
                .map_err(|e| err(e.to_string()))?;
        }
        root.present().map_err(|e| err(e.to_string()))?;
    }
    Ok(path)
}
