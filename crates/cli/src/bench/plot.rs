//! The bench's SVG plots (plotters): a Pareto plot per scene and size — x the frame's GPU ms,
//! y the FN rate (filled) and FP rate (hollow) of each setting, one series per setting, the
//! front of (ms, FN rate) joined, the ideal frame a dashed vertical line — and the GPU time per pass of each setting as stacked bars.

use std::path::{Path, PathBuf};

use plotters::prelude::*;

use super::matrix::Labels;
use super::report::Group;
use super::results::RunRecord;
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

/// The least ideal frame of the group's runs (each check times the oracle's visible set of its
/// own frames; a cluster technique's on the scene with its indices in cluster order).
fn ideal_ms(runs: &[(&RunRecord, bool)]) -> Option<f64> {
    runs.iter()
        .filter_map(|(r, _)| r.totals.as_ref().and_then(|t| t.ideal_frame_gpu_ms))
        .filter(|m| m.is_finite() && *m > 0.0)
        .min_by(f64::total_cmp)
}

/// `pareto-<scene>-<WxH>.svg`.
pub fn pareto(out: &Path, g: &Group<'_>, labels: &Labels) -> Result<PathBuf, CliError> {
    let path = out.join(format!("pareto-{}.svg", g.stem()));
    let err = write_err(&path);
    let runs = g.measured();
    let max_ms = runs
        .iter()
        .filter_map(|(r, _)| r.totals.as_ref().map(|t| t.frame_gpu_ms))
        .fold(ideal_ms(&runs).unwrap_or(0.0), f64::max)
        .max(1e-3)
        * 1.15;
    let max_rate = runs
        .iter()
        .filter_map(|(r, _)| r.totals.as_ref().map(|t| t.fn_rate.max(t.fp_rate)))
        .fold(0.05f64, f64::max)
        .min(1.0)
        * 1.1;
    let height = 420 + 18 * runs.len() as u32;
    {
        let root = SVGBackend::new(&path, (900, height)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(e.to_string()))?;
        let mut chart = ChartBuilder::on(&root)
            .caption(
                format!(
                    "{} {}x{}: FN rate (filled) and FP rate (hollow) against frame GPU ms",
                    g.scene, g.size[0], g.size[1]
                ),
                ("sans-serif", 18),
            )
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(56)
            .build_cartesian_2d(0.0..max_ms, 0.0..max_rate)
            .map_err(|e| err(e.to_string()))?;
        chart
            .configure_mesh()
            .x_desc("frame GPU ms (median)")
            .y_desc("rate")
            .draw()
            .map_err(|e| err(e.to_string()))?;
        for (i, (r, front)) in runs.iter().enumerate() {
            let Some(t) = &r.totals else { continue };
            let c = colour(i);
            let size = if *front { 7 } else { 5 };
            let points = [
                (t.frame_gpu_ms, t.fn_rate, true),
                (t.frame_gpu_ms, t.fp_rate, false),
            ];
            chart
                .draw_series(points.iter().map(|&(x, y, filled)| {
                    let style = if filled {
                        c.filled()
                    } else {
                        c.stroke_width(2)
                    };
                    Circle::new((x, y), size, style)
                }))
                .map_err(|e| err(e.to_string()))?
                .label(format!(
                    "{}{}",
                    labels.label(&r.settings),
                    if *front { " (front)" } else { "" }
                ))
                .legend(move |(x, y)| Circle::new((x, y), 5, c.filled()));
        }
        let mut front: Vec<(f64, f64)> = runs
            .iter()
            .filter(|(_, f)| *f)
            .filter_map(|(r, _)| r.totals.as_ref().map(|t| (t.frame_gpu_ms, t.fn_rate)))
            .collect();
        front.sort_by(|a, b| a.0.total_cmp(&b.0));
        chart
            .draw_series(LineSeries::new(front, BLACK.stroke_width(1)))
            .map_err(|e| err(e.to_string()))?;
        // The ideal frame (the oracle's visible set drawn with no culling work): the ceiling
        // every setting's frame is measured against, a dashed vertical line.
        if let Some(ideal) = ideal_ms(&runs) {
            chart
                .draw_series(DashedLineSeries::new(
                    [(ideal, 0.0), (ideal, max_rate)],
                    6,
                    4,
                    BLACK.stroke_width(1),
                ))
                .map_err(|e| err(e.to_string()))?
                .label(format!("ideal frame {ideal:.3} ms (dashed)"))
                .legend(|(x, y)| PathElement::new(vec![(x - 6, y), (x + 6, y)], BLACK));
        }
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

/// `passes-<scene>-<WxH>.svg`: one bar per setting, a segment per pass (median GPU ms).
pub fn passes(out: &Path, g: &Group<'_>, labels: &Labels) -> Result<PathBuf, CliError> {
    let path = out.join(format!("passes-{}.svg", g.stem()));
    let err = write_err(&path);
    let runs: Vec<_> = g.measured().into_iter().map(|(r, _)| r).collect();
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
    let names: Vec<String> = runs.iter().map(|r| labels.label(&r.settings)).collect();
    let height = 140 + 28 * runs.len().max(1) as u32 + 16 * pass_names.len() as u32;
    {
        let root = SVGBackend::new(&path, (1000, height)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(e.to_string()))?;
        let n = runs.len().max(1) as f64;
        let mut chart = ChartBuilder::on(&root)
            .caption(
                format!(
                    "{} {}x{}: GPU ms per pass (medians)",
                    g.scene, g.size[0], g.size[1]
                ),
                ("sans-serif", 18),
            )
            .margin(12)
            .x_label_area_size(36)
            .y_label_area_size(300)
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
            chart
                .draw_series(bars)
                .map_err(|e| err(e.to_string()))?
                .label(pass.clone())
                .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 10, y + 5)], c.filled()));
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::LowerRight)
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()
            .map_err(|e| err(e.to_string()))?;
        root.present().map_err(|e| err(e.to_string()))?;
    }
    Ok(path)
}
