//! The Pareto plot of one scene at one size, written as SVG by hand: it must read at the scale
//! `tune` works at (144 settings and more), and a browser test finds its parts by class.
//!
//! Two panels share the x axis, the frame's GPU ms (median): above, the FN rate on a scale that
//! keeps 0 apart from rare misses (a band for 0, then decades); below, the FP rate on a linear
//! scale. Colour says the culling, the marker's shape the shading; the front of (ms, FN rate)
//! is a line, each of its points labelled with its setting's short key (`s12`), which the
//! report's tables resolve into culling, shading and knob values. The legend (cullings,
//! shadings, front, ideal frame) stands right of the panels, never over them. The ideal frame
//! (the oracle's visible set drawn with no culling work) is a dashed vertical line.
//!
//! Classes the browser test reads: `plot-area` (each panel's rectangle, `data-panel` fn / fp),
//! `legend` (the legend's group), `point` (`data-key`, `data-front`, `data-panel`) and
//! `point-label` (`data-key`).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use super::matrix::Labels;
use super::report::Group;
use super::RunRecord;
use crate::markup::escape;
use crate::CliError;

const WIDTH: f64 = 980.0;
const HEIGHT: f64 = 590.0;
/// The panels' left and right edges; the legend starts right of them.
const LEFT: f64 = 84.0;
const RIGHT: f64 = 700.0;
const LEGEND_X: f64 = 728.0;
/// (top, bottom) of the FN panel and of the FP panel.
const FN_PANEL: (f64, f64) = (48.0, 300.0);
const FP_PANEL: (f64, f64) = (352.0, 530.0);
/// The FN panel's band for 0: its y is this far above the panel's bottom, the lowest decade
/// `ZERO_GAP` above that.
const ZERO_Y: f64 = 10.0;
const ZERO_GAP: f64 = 34.0;
const LABEL_FONT: f64 = 11.0;

/// Colours for cullings, in the order of their names (Tableau 10, then two more).
const PALETTE: [&str; 12] = [
    "#4e79a7", "#f28e2b", "#e15759", "#76b7b2", "#59a14f", "#edc948", "#b07aa1", "#ff9da7",
    "#9c755f", "#bab0ac", "#1b9e77", "#7570b3",
];

#[derive(Clone, Copy, Debug, PartialEq)]
enum Marker {
    Circle,
    Square,
    TriangleUp,
    Diamond,
    TriangleDown,
    Plus,
}

const MARKERS: [Marker; 6] = [
    Marker::Circle,
    Marker::Square,
    Marker::TriangleUp,
    Marker::Diamond,
    Marker::TriangleDown,
    Marker::Plus,
];

/// The FN axis: 0 in a band of its own at the bottom, then decades `lo..=hi` (powers of ten)
/// on a log scale, so that a rate of 1e-4 sits well apart from 0.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FnScale {
    lo: i32,
    hi: i32,
}

impl FnScale {
    /// Decades from the smallest non-zero rate's down to it, up to the largest's (at most 1);
    /// 1e-4..1e-1 when every rate is 0 (the scale still shows where a rare miss would sit).
    pub fn of(rates: impl Iterator<Item = f64>) -> FnScale {
        let nonzero: Vec<f64> = rates.filter(|r| r.is_finite() && *r > 0.0).collect();
        if nonzero.is_empty() {
            return FnScale { lo: -4, hi: -1 };
        }
        let min = nonzero.iter().copied().fold(f64::INFINITY, f64::min);
        let max = nonzero.iter().copied().fold(0.0f64, f64::max);
        let lo = (min.log10().floor() as i32).clamp(-9, -1);
        let hi = (max.log10().ceil() as i32).clamp(lo + 1, 0);
        FnScale { lo, hi }
    }

    /// The y of `rate` in a panel spanning `top..bottom`.
    pub fn y(&self, rate: f64, (top, bottom): (f64, f64)) -> f64 {
        if rate.is_nan() || rate <= 0.0 {
            return bottom - ZERO_Y;
        }
        let first = bottom - ZERO_Y - ZERO_GAP;
        let t = (rate.log10() - f64::from(self.lo)) / f64::from(self.hi - self.lo);
        first - t.clamp(0.0, 1.0) * (first - top - 8.0)
    }
}

/// Round tick values covering `lo..hi`, about `n` of them.
fn ticks(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    let span = (hi - lo).max(1e-9);
    let raw = span / n.max(1) as f64;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * mag)
        .find(|s| *s >= raw)
        .unwrap_or(10.0 * mag);
    let first = (lo / step).ceil() as i64;
    (first..first + 64)
        .map(|k| k as f64 * step)
        .take_while(|v| *v <= hi + step * 1e-6)
        .collect()
}

fn tick_text(v: f64, step: f64) -> String {
    let decimals = (-step.log10().floor()).clamp(0.0, 6.0) as usize;
    format!("{v:.decimals$}")
}

fn decade_text(e: i32) -> String {
    match e {
        0 => "1".into(),
        -1 => "0.1".into(),
        -2 => "0.01".into(),
        _ => format!("1e{e}"),
    }
}

/// An axis-aligned box: (x0, y0, x1, y1).
type Rect = (f64, f64, f64, f64);

fn overlaps(a: Rect, b: Rect) -> bool {
    a.0 < b.2 && b.0 < a.2 && a.1 < b.3 && b.1 < a.3
}

/// A label's box when its text starts at (x, baseline y): a generous width estimate (the
/// browser's sans-serif at 11 px is about 5.6 px a character).
fn label_box(text: &str, x: f64, y: f64) -> Rect {
    let w = 6.4 * text.chars().count() as f64 + 2.0;
    (x - 1.0, y - LABEL_FONT, x + w, y + 3.0)
}

/// Where each front point's label goes: the first spot around the point, nearest first, that
/// stays in the panel and overlaps no label placed before it nor any point; failing that, one
/// that overlaps no label; failing that, the nearest in the panel. Returns (x, y, needs a
/// leader line) per point.
fn place_labels(
    points: &[(String, f64, f64)],
    others: &[(f64, f64)],
    panel: Rect,
) -> Vec<(f64, f64, bool)> {
    let mut placed: Vec<Rect> = Vec::new();
    let mut out = Vec::new();
    for (text, px, py) in points {
        let w = 6.4 * text.chars().count() as f64 + 2.0;
        let mut spots = Vec::new();
        for r in [9.0, 20.0, 32.0, 46.0] {
            for (dx, dy) in [
                (1.0, 0.0),
                (0.0, -1.0),
                (-1.0, 0.0),
                (0.0, 1.0),
                (0.7, -0.7),
                (-0.7, -0.7),
                (0.7, 0.7),
                (-0.7, 0.7),
            ] {
                let x = px + dx * r
                    - if dx < 0.0 {
                        w
                    } else if dx == 0.0 {
                        w / 2.0
                    } else {
                        0.0
                    };
                let y = py
                    + dy * r
                    + if dy > 0.0 {
                        LABEL_FONT
                    } else if dy == 0.0 {
                        4.0
                    } else {
                        0.0
                    };
                spots.push((x, y, r > 9.0));
            }
        }
        let inside = |b: Rect| b.0 >= panel.0 && b.2 <= panel.2 && b.1 >= panel.1 && b.3 <= panel.3;
        let free_of_labels = |b: Rect| !placed.iter().any(|p| overlaps(*p, b));
        let free_of_points = |b: Rect| {
            !others
                .iter()
                .any(|&(ox, oy)| overlaps(b, (ox - 5.0, oy - 5.0, ox + 5.0, oy + 5.0)))
        };
        let pick = spots
            .iter()
            .find(|s| {
                let b = label_box(text, s.0, s.1);
                inside(b) && free_of_labels(b) && free_of_points(b)
            })
            .or_else(|| {
                spots.iter().find(|s| {
                    let b = label_box(text, s.0, s.1);
                    inside(b) && free_of_labels(b)
                })
            })
            .or_else(|| spots.iter().find(|s| inside(label_box(text, s.0, s.1))))
            .copied()
            .unwrap_or((*px + 9.0, *py + 4.0, false));
        placed.push(label_box(text, pick.0, pick.1));
        out.push(pick);
    }
    out
}

/// How a marker is written: attributes on its element, outlined in black on the front, and a
/// hover title inside it (none in the legend).
#[derive(Default)]
struct Mark<'a> {
    attrs: &'a str,
    front: bool,
    title: &'a str,
}

/// A polygon marker's corners on a unit radius (the circle and square are elements of their own).
fn corners(m: Marker) -> &'static [(f64, f64)] {
    match m {
        Marker::Circle | Marker::Square => &[],
        Marker::TriangleUp => &[(0.0, -1.1), (1.0, 0.7), (-1.0, 0.7)],
        Marker::Diamond => &[(0.0, -1.2), (1.0, 0.0), (0.0, 1.2), (-1.0, 0.0)],
        Marker::TriangleDown => &[(0.0, 1.1), (1.0, -0.7), (-1.0, -0.7)],
        Marker::Plus => &[
            (-0.35, -1.0),
            (0.35, -1.0),
            (0.35, -0.35),
            (1.0, -0.35),
            (1.0, 0.35),
            (0.35, 0.35),
            (0.35, 1.0),
            (-0.35, 1.0),
            (-0.35, 0.35),
            (-1.0, 0.35),
            (-1.0, -0.35),
            (-0.35, -0.35),
        ],
    }
}

fn marker(svg: &mut String, m: Marker, (x, y): (f64, f64), r: f64, fill: &str, mark: &Mark<'_>) {
    let stroke = if mark.front {
        "stroke=\"#000\" stroke-width=\"1.2\""
    } else {
        "stroke=\"#fff\" stroke-width=\"0.6\" fill-opacity=\"0.8\""
    };
    let (element, shape) = match m {
        Marker::Circle => (
            "circle",
            format!("cx=\"{x:.1}\" cy=\"{y:.1}\" r=\"{r:.1}\""),
        ),
        Marker::Square => (
            "rect",
            format!(
                "x=\"{:.1}\" y=\"{:.1}\" width=\"{:.1}\" height=\"{:.1}\"",
                x - 0.85 * r,
                y - 0.85 * r,
                1.7 * r,
                1.7 * r
            ),
        ),
        polygon => {
            let points: Vec<String> = corners(polygon)
                .iter()
                .map(|(px, py)| format!("{:.1},{:.1}", x + px * r, y + py * r))
                .collect();
            ("polygon", format!("points=\"{}\"", points.join(" ")))
        }
    };
    let open = format!("<{element} {} {shape} fill=\"{fill}\" {stroke}", mark.attrs);
    let _ = if mark.title.is_empty() {
        writeln!(svg, "{open}/>")
    } else {
        writeln!(svg, "{open}>{}</{element}>", mark.title)
    };
}

/// One measured setting as the plot sees it.
struct Point<'a> {
    run: &'a RunRecord,
    key: String,
    front: bool,
    ms: f64,
    fn_rate: f64,
    fp_rate: f64,
    colour: &'static str,
    marker: Marker,
}

/// Writes `pareto-<scene>-<WxH>.svg`.
pub fn write(out: &Path, g: &Group<'_>, labels: &Labels) -> Result<PathBuf, CliError> {
    let path = out.join(format!("pareto-{}.svg", g.stem()));
    super::results::write_atomically(&path, svg(g, labels).as_bytes())?;
    Ok(path)
}

/// The SVG document of `g`'s Pareto plot.
pub fn svg(g: &Group<'_>, labels: &Labels) -> String {
    let measured = g.measured();
    let mut cullings: Vec<&str> = measured
        .iter()
        .map(|(r, _)| r.settings.culling.as_str())
        .collect();
    cullings.sort_unstable();
    cullings.dedup();
    let mut shadings: Vec<&str> = measured
        .iter()
        .map(|(r, _)| r.settings.shading.as_str())
        .collect();
    shadings.sort_unstable();
    shadings.dedup();
    let points: Vec<Point<'_>> = measured
        .iter()
        .filter_map(|&(run, front)| {
            let t = run.totals.as_ref()?;
            let c = cullings
                .iter()
                .position(|c| *c == run.settings.culling)
                .unwrap_or(0);
            let s = shadings
                .iter()
                .position(|s| *s == run.settings.shading)
                .unwrap_or(0);
            Some(Point {
                run,
                key: labels.short(&run.settings),
                front,
                ms: t.frame_gpu_ms,
                fn_rate: t.fn_rate,
                fp_rate: t.fp_rate,
                colour: PALETTE[c % PALETTE.len()],
                marker: MARKERS[s % MARKERS.len()],
            })
        })
        .collect();
    let ideal = measured
        .iter()
        .filter_map(|(r, _)| r.totals.as_ref().and_then(|t| t.ideal_frame_gpu_ms))
        .filter(|m| m.is_finite() && *m > 0.0)
        .min_by(f64::total_cmp);

    // x: the frame ms of every point and the ideal frame, from 0 where that wastes little.
    let all_ms = points
        .iter()
        .map(|p| p.ms)
        .chain(ideal)
        .filter(|m| m.is_finite());
    let (mut lo, mut hi) = all_ms.fold((f64::INFINITY, 0.0f64), |(a, b), m| (a.min(m), b.max(m)));
    if !lo.is_finite() || hi <= 0.0 {
        (lo, hi) = (0.0, 1.0);
    }
    let pad = 0.06 * (hi - lo).max(hi * 0.05);
    let x_lo = if lo < 0.35 * hi {
        0.0
    } else {
        (lo - pad).max(0.0)
    };
    let x_hi = hi + pad;
    let xt = ticks(x_lo, x_hi, 8);
    let x_step = xt
        .windows(2)
        .map(|w| w[1] - w[0])
        .next()
        .unwrap_or(x_hi - x_lo);
    let x_of = |ms: f64| LEFT + (ms - x_lo) / (x_hi - x_lo) * (RIGHT - LEFT);
    let fn_scale = FnScale::of(points.iter().map(|p| p.fn_rate));
    let fp_hi = points
        .iter()
        .map(|p| p.fp_rate)
        .fold(0.05f64, f64::max)
        .min(1.0)
        * 1.08;
    let fp_y = |r: f64| FP_PANEL.1 - (r / fp_hi).clamp(0.0, 1.0) * (FP_PANEL.1 - FP_PANEL.0 - 6.0);

    let mut s = String::new();
    let _ = writeln!(
        s,
        "<svg xmlns=\"http://www.w3.org/2000/svg\" class=\"pareto\" width=\"{WIDTH}\" height=\"{HEIGHT}\" \
         viewBox=\"0 0 {WIDTH} {HEIGHT}\" font-family=\"sans-serif\" font-size=\"11\">"
    );
    s.push_str("<rect width=\"100%\" height=\"100%\" fill=\"#fff\"/>\n");
    let _ = writeln!(
        s,
        "<text x=\"{LEFT}\" y=\"22\" font-size=\"15\">{} {}x{}: {} settings, frame GPU ms against FN rate (above) and FP rate (below)</text>",
        escape(&g.scene),
        g.size[0],
        g.size[1],
        points.len()
    );
    for (panel, name, title) in [
        (FN_PANEL, "fn", "FN rate (visible culled)"),
        (FP_PANEL, "fp", "FP rate (hidden drawn)"),
    ] {
        let _ = writeln!(
            s,
            "<rect class=\"plot-area\" data-panel=\"{name}\" x=\"{LEFT}\" y=\"{}\" width=\"{}\" height=\"{}\" fill=\"#fafafa\" stroke=\"#444\"/>",
            panel.0,
            RIGHT - LEFT,
            panel.1 - panel.0
        );
        let _ = writeln!(
            s,
            "<text transform=\"translate(16,{:.1}) rotate(-90)\" text-anchor=\"middle\">{title}</text>",
            0.5 * (panel.0 + panel.1)
        );
        for &v in &xt {
            let x = x_of(v);
            let _ = writeln!(
                s,
                "<line x1=\"{x:.1}\" y1=\"{}\" x2=\"{x:.1}\" y2=\"{}\" stroke=\"#e4e4e4\"/><text x=\"{x:.1}\" y=\"{}\" text-anchor=\"middle\">{}</text>",
                panel.0,
                panel.1,
                panel.1 + 14.0,
                tick_text(v, x_step)
            );
        }
    }
    let _ = writeln!(
        s,
        "<text x=\"{:.1}\" y=\"{}\" text-anchor=\"middle\">frame GPU ms (median)</text>",
        0.5 * (LEFT + RIGHT),
        FP_PANEL.1 + 32.0
    );
    // The FN axis: 0, a break, then decades.
    let hline = |s: &mut String, y: f64, text: &str, dash: bool| {
        let _ = writeln!(
            s,
            "<line x1=\"{LEFT}\" y1=\"{y:.1}\" x2=\"{RIGHT}\" y2=\"{y:.1}\" stroke=\"#ddd\"{}/><text x=\"{}\" y=\"{:.1}\" text-anchor=\"end\">{text}</text>",
            if dash { " stroke-dasharray=\"2,3\"" } else { "" },
            LEFT - 5.0,
            y + 4.0
        );
    };
    hline(&mut s, fn_scale.y(0.0, FN_PANEL), "0", true);
    for e in fn_scale.lo..=fn_scale.hi {
        hline(
            &mut s,
            fn_scale.y(10f64.powi(e), FN_PANEL),
            &decade_text(e),
            false,
        );
    }
    let brk = FN_PANEL.1 - ZERO_Y - 0.5 * ZERO_GAP;
    let _ = writeln!(
        s,
        "<path d=\"M{:.1},{:.1} l8,-4 M{:.1},{:.1} l8,-4\" stroke=\"#444\"/>",
        LEFT - 4.0,
        brk + 2.0,
        LEFT - 4.0,
        brk + 6.0
    );
    let fpt = ticks(0.0, fp_hi, 4);
    let fp_step = fpt.windows(2).map(|w| w[1] - w[0]).next().unwrap_or(fp_hi);
    for &v in &fpt {
        hline(&mut s, fp_y(v), &tick_text(v, fp_step), false);
    }
    if let Some(ideal) = ideal {
        let x = x_of(ideal);
        for panel in [FN_PANEL, FP_PANEL] {
            let _ = writeln!(
                s,
                "<line class=\"ideal\" x1=\"{x:.1}\" y1=\"{}\" x2=\"{x:.1}\" y2=\"{}\" stroke=\"#000\" stroke-dasharray=\"6,4\"/>",
                panel.0,
                panel.1
            );
        }
    }

    // The front, a line through its points in order of ms.
    let mut front: Vec<&Point<'_>> = points.iter().filter(|p| p.front).collect();
    front.sort_by(|a, b| a.ms.total_cmp(&b.ms));
    let line: Vec<String> = front
        .iter()
        .map(|p| format!("{:.1},{:.1}", x_of(p.ms), fn_scale.y(p.fn_rate, FN_PANEL)))
        .collect();
    if line.len() > 1 {
        let _ = writeln!(
            s,
            "<polyline class=\"front\" points=\"{}\" fill=\"none\" stroke=\"#000\" stroke-width=\"1.5\"/>",
            line.join(" ")
        );
    }
    // Points: the rest first, the front on top.
    let mut order: Vec<&Point<'_>> = points.iter().collect();
    order.sort_by_key(|p| p.front);
    for p in &order {
        let title = format!(
            "<title>{} {}: {:.3} ms, FN rate {:.5}, FP rate {:.3}</title>",
            p.key,
            escape(&labels.label(&p.run.settings)),
            p.ms,
            p.fn_rate,
            p.fp_rate
        );
        for (panel, y) in [
            ("fn", fn_scale.y(p.fn_rate, FN_PANEL)),
            ("fp", fp_y(p.fp_rate)),
        ] {
            let attrs = format!(
                "class=\"point\" data-panel=\"{panel}\" data-key=\"{}\" data-front=\"{}\"",
                p.key,
                u8::from(p.front)
            );
            let r = if p.front { 5.5 } else { 4.0 };
            let mark = Mark {
                attrs: &attrs,
                front: p.front,
                title: &title,
            };
            marker(&mut s, p.marker, (x_of(p.ms), y), r, p.colour, &mark);
        }
    }
    // The front's labels.
    let targets: Vec<(String, f64, f64)> = front
        .iter()
        .map(|p| (p.key.clone(), x_of(p.ms), fn_scale.y(p.fn_rate, FN_PANEL)))
        .collect();
    let others: Vec<(f64, f64)> = points
        .iter()
        .map(|p| (x_of(p.ms), fn_scale.y(p.fn_rate, FN_PANEL)))
        .collect();
    let spots = place_labels(&targets, &others, (LEFT, FN_PANEL.0, RIGHT, FN_PANEL.1));
    for ((text, px, py), (x, y, leader)) in targets.iter().zip(spots) {
        if leader {
            let b = label_box(text, x, y);
            let (cx, cy) = (px.clamp(b.0, b.2), py.clamp(b.1, b.3));
            let _ = writeln!(
                s,
                "<line x1=\"{px:.1}\" y1=\"{py:.1}\" x2=\"{cx:.1}\" y2=\"{cy:.1}\" stroke=\"#888\" stroke-width=\"0.8\"/>"
            );
        }
        let _ = writeln!(
            s,
            "<text class=\"point-label\" data-key=\"{text}\" x=\"{x:.1}\" y=\"{y:.1}\">{text}</text>"
        );
    }
    legend(&mut s, &cullings, &shadings, ideal);
    s.push_str("</svg>\n");
    s
}

/// Right of the panels: colour per culling, shape per shading, the front and the ideal frame.
fn legend(s: &mut String, cullings: &[&str], shadings: &[&str], ideal: Option<f64>) {
    s.push_str("<g class=\"legend\">\n");
    let mut y = FN_PANEL.0 + 4.0;
    let heading = |s: &mut String, y: &mut f64, text: &str| {
        let _ = writeln!(
            s,
            "<text x=\"{LEGEND_X}\" y=\"{:.1}\" font-weight=\"bold\">{text}</text>",
            *y + 4.0
        );
        *y += 18.0;
    };
    heading(s, &mut y, "culling (colour)");
    for (i, c) in cullings.iter().enumerate() {
        legend_entry(s, (Marker::Circle, PALETTE[i % PALETTE.len()]), &mut y, c);
    }
    y += 6.0;
    heading(s, &mut y, "shading (shape)");
    for (i, sh) in shadings.iter().enumerate() {
        legend_entry(s, (MARKERS[i % MARKERS.len()], "#666"), &mut y, sh);
    }
    y += 6.0;
    let _ = writeln!(
        s,
        "<line x1=\"{LEGEND_X}\" y1=\"{y:.1}\" x2=\"{}\" y2=\"{y:.1}\" stroke=\"#000\" stroke-width=\"1.5\"/><text x=\"{}\" y=\"{:.1}\">front of (ms, FN), keys as in the table</text>",
        LEGEND_X + 12.0,
        LEGEND_X + 16.0,
        y + 4.0
    );
    y += 17.0;
    if let Some(ideal) = ideal {
        let _ = writeln!(
            s,
            "<line x1=\"{LEGEND_X}\" y1=\"{y:.1}\" x2=\"{}\" y2=\"{y:.1}\" stroke=\"#000\" stroke-dasharray=\"4,3\"/><text x=\"{}\" y=\"{:.1}\">ideal frame {ideal:.3} ms</text>",
            LEGEND_X + 12.0,
            LEGEND_X + 16.0,
            y + 4.0
        );
    }
    s.push_str("</g>\n");
}

/// One legend line at `y`: a marker and its text; `y` moves to the next line.
fn legend_entry(s: &mut String, (m, colour): (Marker, &str), y: &mut f64, text: &str) {
    marker(s, m, (LEGEND_X + 6.0, *y), 5.0, colour, &Mark::default());
    let _ = writeln!(
        s,
        "<text x=\"{}\" y=\"{:.1}\">{}</text>",
        LEGEND_X + 16.0,
        *y + 4.0,
        escape(text)
    );
    *y += 17.0;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn zero_and_a_rare_miss_sit_apart_on_the_fn_axis() {
        let scale = FnScale::of([0.0, 1e-4, 0.02].into_iter());
        assert_eq!(scale, FnScale { lo: -4, hi: -1 });
        let zero = scale.y(0.0, FN_PANEL);
        let rare = scale.y(1e-4, FN_PANEL);
        let often = scale.y(0.02, FN_PANEL);
        assert!(zero - rare >= 30.0, "0 at {zero}, 1e-4 at {rare}");
        assert!(rare > often && often > FN_PANEL.0, "{rare} {often}");
        // Every rate 0: the scale still shows decades above the zero band.
        let none = FnScale::of([0.0, 0.0].into_iter());
        assert!(none.y(0.0, FN_PANEL) > none.y(1e-4, FN_PANEL));
    }

    #[test]
    fn ticks_are_round_and_cover_the_range() {
        let t = ticks(0.0, 1.0, 5);
        assert_eq!(t.len(), 6, "{t:?}");
        assert!(t
            .iter()
            .zip([0.0, 0.2, 0.4, 0.6, 0.8, 1.0])
            .all(|(a, b)| (a - b).abs() < 1e-9));
        let t = ticks(0.83, 1.47, 8);
        assert!(t.first().is_some_and(|v| *v >= 0.83) && t.last().is_some_and(|v| *v <= 1.47));
        assert!(t.len() >= 4, "{t:?}");
    }

    #[test]
    fn labels_avoid_each_other() {
        let pts: Vec<(String, f64, f64)> = (0..6)
            .map(|i| (format!("s{}", 10 + i), 300.0 + 3.0 * i as f64, 200.0))
            .collect();
        let spots = place_labels(&pts, &[], (LEFT, FN_PANEL.0, RIGHT, FN_PANEL.1));
        let boxes: Vec<Rect> = pts
            .iter()
            .zip(&spots)
            .map(|((t, _, _), (x, y, _))| label_box(t, *x, *y))
            .collect();
        for (i, a) in boxes.iter().enumerate() {
            for b in &boxes[i + 1..] {
                assert!(!overlaps(*a, *b), "{a:?} {b:?}");
            }
        }
    }
}
