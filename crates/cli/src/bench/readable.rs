//! The report read in a real browser: a tune-sized sweep (144 settings, measured by nobody:
//! made up here, as `tune` on the city would leave them) written as `bench` writes it, its
//! Pareto SVG and its HTML report opened in headless Chromium, which measures what it drew —
//! no legend over a plotting area, every front point labelled near it, no two labels on each
//! other, the images decoded, a table row per setting.

use std::collections::BTreeMap;
use std::path::Path;
use std::process::Command;

use tilegraph_profile::knobs::KnobValue;

use super::results::{DeviceRecord, Results, RunRecord, TotalsRecord, WorstFrame};
use super::Setting;

/// What the page measures, written into `<pre id="layout-check">` for `--dump-dom`.
const CHECK: &str = r#"<script>
window.addEventListener('load', () => {
  const box = e => { const r = e.getBoundingClientRect(); return {x0: r.left, y0: r.top, x1: r.right, y1: r.bottom}; };
  const over = (a, b) => a.x0 < b.x1 && b.x0 < a.x1 && a.y0 < b.y1 && b.y0 < a.y1;
  const res = {plots: [], images: [], rows: document.querySelectorAll('table.runs tr[data-key]').length};
  for (const svg of document.querySelectorAll('svg.pareto')) {
    const areas = [...svg.querySelectorAll('.plot-area')].map(box);
    const fnArea = box(svg.querySelector('.plot-area[data-panel="fn"]'));
    const legend = box(svg.querySelector('.legend'));
    const labels = [...svg.querySelectorAll('.point-label')];
    const p = {areas: areas.length, legend_overlaps: areas.some(a => over(a, legend)),
               points: svg.querySelectorAll('.point[data-panel="fn"]').length,
               front: 0, unlabelled: [], far: [], outside: [], label_overlaps: 0,
               width: box(svg).x1 - box(svg).x0, height: box(svg).y1 - box(svg).y0};
    for (const pt of svg.querySelectorAll('.point[data-panel="fn"][data-front="1"]')) {
      p.front++;
      const key = pt.dataset.key;
      const l = labels.find(l => l.dataset.key === key);
      if (!l) { p.unlabelled.push(key); continue; }
      const b = box(pt), lb = box(l);
      const cx = (b.x0 + b.x1) / 2, cy = (b.y0 + b.y1) / 2;
      const dx = Math.max(lb.x0 - cx, 0, cx - lb.x1), dy = Math.max(lb.y0 - cy, 0, cy - lb.y1);
      if (Math.hypot(dx, dy) > 60) p.far.push(key);
      if (lb.x0 < fnArea.x0 || lb.x1 > fnArea.x1 || lb.y0 < fnArea.y0 || lb.y1 > fnArea.y1) p.outside.push(key);
    }
    const lbs = labels.map(box);
    for (let i = 0; i < lbs.length; i++) for (let j = i + 1; j < lbs.length; j++) if (over(lbs[i], lbs[j])) p.label_overlaps++;
    res.plots.push(p);
  }
  for (const img of document.images) res.images.push(img.complete && img.naturalWidth > 0);
  const out = document.createElement('pre');
  out.id = 'layout-check';
  out.textContent = JSON.stringify(res);
  document.body.appendChild(out);
});
</script>"#;

fn chromium() -> Option<&'static str> {
    [
        "chromium",
        "chromium-browser",
        "google-chrome",
        "google-chrome-stable",
    ]
    .into_iter()
    .find(|c| {
        Command::new(c)
            .arg("--version")
            .output()
            .is_ok_and(|o| o.status.success())
    })
}

/// Opens `page` in headless Chromium and returns what [`CHECK`] measured.
fn measure(browser: &str, page: &Path) -> serde_json::Value {
    let out = Command::new(browser)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--hide-scrollbars",
            "--window-size=1400,1000",
            "--dump-dom",
        ])
        .arg(format!("file://{}", page.display()))
        .output()
        .unwrap();
    let dom = String::from_utf8_lossy(&out.stdout);
    let at = dom.find("<pre id=\"layout-check\">").unwrap_or_else(|| {
        panic!(
            "{browser} ran no check on {}: {}",
            page.display(),
            String::from_utf8_lossy(&out.stderr)
        )
    });
    let json = &dom[at + "<pre id=\"layout-check\">".len()..];
    let json = &json[..json.find("</pre>").unwrap()];
    serde_json::from_str(&json.replace("&quot;", "\"").replace("&amp;", "&")).unwrap()
}

/// 144 settings as `tune` on the city would leave them: 8 cullings × 18 knob settings, the
/// exact ones at FN 0, the others missing a little or a lot; two with a worst frame on disk.
fn sweep(out: &Path) -> (Vec<Setting>, Results) {
    let cullings = [
        ("frustum", false),
        ("hiz", true),
        ("hiz-2phase", false),
        ("oq", true),
        ("oq-conditional", false),
        ("raster-occlusion", false),
        ("reproject", true),
        ("software-occlusion", false),
    ];
    let mut settings = Vec::new();
    let mut results = Results::default();
    let image = tilegraph_vk::readback::RgbaImage {
        width: 16,
        height: 9,
        pixels: vec![128; 16 * 9 * 4],
    };
    for (c, (culling, misses)) in cullings.iter().enumerate() {
        for k in 0..18u32 {
            let mut knobs = BTreeMap::new();
            knobs.insert("hiz_bias".to_string(), KnobValue::Integer(k % 6));
            knobs.insert(
                "hiz_mode".to_string(),
                KnobValue::Name(["pow2", "npot", "exact"][(k / 6) as usize].into()),
            );
            let s = Setting {
                scene: "city:10000".into(),
                profile: None,
                size: [320, 180],
                camera_path: None,
                shading: if k % 2 == 0 { "forward" } else { "prepass" }.into(),
                culling: culling.to_string(),
                knobs,
            };
            // A made-up but tune-like spread: the misses faster the more they miss.
            let i = c as u32 * 18 + k;
            let wobble = f64::from(i.wrapping_mul(2_654_435_761) >> 20) / 4096.0;
            let fn_rate = if *misses && k % 3 != 0 {
                10f64.powf(-4.0 + 2.5 * f64::from(k % 6) / 5.0)
            } else {
                0.0
            };
            let ms = 0.55 + 0.05 * c as f64 + 0.25 * wobble - 0.9 * fn_rate.sqrt();
            let mut r = RunRecord {
                key: s.key(),
                settings: s.clone(),
                device: DeviceRecord {
                    build: "test".into(),
                    name: "made-up GPU".into(),
                    driver: "none".into(),
                    driver_version: "0".into(),
                    api: "1.3".into(),
                    profile: "desktop-generic".into(),
                    profile_matched_by: "forced".into(),
                },
                culling: culling.to_string(),
                auto_reason: None,
                knobs: Vec::new(),
                error: None,
                wall_s: 1.0,
                totals: Some(TotalsRecord {
                    frames: 24,
                    visible: 24_000,
                    drawn: 30_000,
                    false_negatives: (fn_rate * 24_000.0) as usize,
                    cluster_false_negatives: 0,
                    false_positives: 6000,
                    fn_rate,
                    fp_rate: 0.05 + 0.3 * wobble,
                    frames_with_false_negatives: usize::from(fn_rate > 0.0) * 3,
                    frames_image_equal: if fn_rate > 0.0 { 21 } else { 24 },
                    image_diff_pixels: 0,
                    image_diff_pixels_depth_tie: 0,
                    image_rmse: 0.0,
                    image_psnr_db: None,
                    image_max_channel_diff: 0,
                    image_max_depth_rel_diff: None,
                    triangles_drawn: 1_000_000,
                    frame_gpu_ms: ms,
                    frame_gpu_ms_p95: ms * 1.1,
                    ideal_frame_gpu_ms: Some(0.5),
                    passes_gpu_ms: ms * 0.9,
                    cull_gpu_ms: 0.05,
                    cpu_ms: 0.2,
                    software_cpu_ms: None,
                    shadow_casters: None,
                    shadow_casters_all: None,
                    shadow_gpu_ms: 0.0,
                    shadow_casters_needed: None,
                    shadow_caster_false_positives: None,
                    shadow_caster_false_negatives: None,
                }),
                passes: vec![
                    super::results::PassRecord {
                        name: "cull".into(),
                        median_gpu_ms: 0.05,
                        p95_gpu_ms: 0.06,
                    },
                    super::results::PassRecord {
                        name: "colour".into(),
                        median_gpu_ms: ms * 0.85,
                        p95_gpu_ms: ms,
                    },
                ],
                frames: Vec::new(),
                worst_frame: None,
            };
            if i == 20 || i == 23 {
                let stem = format!("frames/t{i}");
                for what in ["technique", "reference", "diff"] {
                    crate::image_io::write_png(&out.join(format!("{stem}-{what}.png")), &image)
                        .unwrap();
                }
                r.worst_frame = Some(WorstFrame {
                    frame: 3,
                    differing_pixels: 40 + i as usize,
                    false_negatives: 2,
                    technique: format!("{stem}-technique.png"),
                    reference: format!("{stem}-reference.png"),
                    diff: format!("{stem}-diff.png"),
                });
            }
            results.runs.push(r);
            settings.push(s);
        }
    }
    (settings, results)
}

#[test]
fn plots_and_report_read_at_144_settings_in_a_real_browser() {
    let out = std::env::temp_dir().join(format!("tilegraph-readable-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    std::fs::create_dir_all(&out).unwrap();
    let (settings, results) = sweep(&out);
    assert_eq!(settings.len(), 144);
    super::write_outputs(&out, &results, &settings).unwrap();
    let svg = out.join("pareto-city-10000-320x180.svg");
    let text = std::fs::read_to_string(&svg).unwrap();
    assert!(text.contains("class=\"legend\""), "{text}");

    let Some(browser) = chromium() else {
        // `cargo xtask test` installs Chromium: a missing one fails there, unless the machine
        // is declared to lack the tools; the skip is recorded either way.
        let allowed = std::env::var_os("TILEGRAPH_ALLOW_MISSING_TOOLS").is_some_and(|v| v == "1");
        tilegraph_scene::test_data::skipped(
            "the report's check in headless Chromium",
            "no chromium on PATH (cargo xtask deps installs it)",
        );
        assert!(
            allowed,
            "no chromium on PATH: `cargo xtask deps` installs it \
             (TILEGRAPH_ALLOW_MISSING_TOOLS=1 skips this check on a machine without it)"
        );
        return;
    };
    // The SVG alone, as an image viewer shows it (inline, so the script can reach it).
    let page = out.join("svg-check.html");
    std::fs::write(
        &page,
        format!("<!DOCTYPE html><html><body>{text}{CHECK}</body></html>"),
    )
    .unwrap();
    let svg_check = measure(browser, &page);
    // The report as written, with the check appended.
    let report = std::fs::read_to_string(out.join("report.html")).unwrap();
    let page = out.join("report-check.html");
    std::fs::write(&page, report.replace("</body>", &format!("{CHECK}</body>"))).unwrap();
    let report_check = measure(browser, &page);

    for (what, check) in [("SVG", &svg_check), ("report", &report_check)] {
        let plots = check["plots"].as_array().unwrap();
        assert_eq!(plots.len(), 1, "{what}: {check}");
        let p = &plots[0];
        assert_eq!(p["areas"], 2, "{what}: {p}");
        assert_eq!(p["points"], 144, "{what}: {p}");
        assert_eq!(
            p["legend_overlaps"], false,
            "{what}: the legend covers a panel: {p}"
        );
        assert!(p["front"].as_u64().unwrap() >= 3, "{what}: {p}");
        for list in ["unlabelled", "far", "outside"] {
            assert!(
                p[list].as_array().unwrap().is_empty(),
                "{what}: front points {list}: {p}"
            );
        }
        assert_eq!(p["label_overlaps"], 0, "{what}: labels on each other: {p}");
        assert!(
            p["width"].as_f64().unwrap() <= 1000.0 && p["height"].as_f64().unwrap() <= 700.0,
            "{what}: {p}"
        );
    }
    assert_eq!(report_check["rows"], 144, "{report_check}");
    let images = report_check["images"].as_array().unwrap();
    assert_eq!(
        images.len(),
        6,
        "two worst frames, three images each: {report_check}"
    );
    assert!(images.iter().all(|ok| ok == true), "{report_check}");
    let _ = std::fs::remove_dir_all(&out);
}
