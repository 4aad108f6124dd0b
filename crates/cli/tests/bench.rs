//! `tilegraph bench` as a user runs it: a smoke matrix on the default device (lavapipe in CI)
//! writes results, a report and SVG plots with every setting's points, and resumes.

use std::path::PathBuf;

mod common;
use common::tilegraph;

/// `relative` under the test data, or `None` (recorded as a skip).
fn test_data(relative: &str) -> Option<PathBuf> {
    tilegraph_scene::test_data::find(relative, &format!("{relative} in the smoke bench"))
}

const CULLINGS: [&str; 7] = [
    "none",
    "frustum",
    "hiz",
    "hiz-2phase",
    "oq",
    "oq-conditional",
    "raster-occlusion",
];
const CONSERVATIVE: [&str; 5] = [
    "none",
    "frustum",
    "hiz-2phase",
    "oq-conditional",
    "raster-occlusion",
];

#[test]
fn smoke_bench_writes_results_report_and_every_settings_points_and_resumes() {
    let out = std::env::temp_dir().join(format!("tilegraph-bench-{}", std::process::id()));
    std::fs::remove_dir_all(&out).ok();
    let mut scenes = vec![
        "city:400".to_string(),
        "forest:300".to_string(),
        "interior:300".to_string(),
    ];
    for f in [
        "scenes/FlightHelmet/FlightHelmet.gltf",
        "bench/GodotRooms/room.gltf",
    ] {
        if let Some(p) = test_data(f) {
            scenes.push(p.to_string_lossy().into_owned());
        }
    }
    let args: Vec<String> = [
        "bench",
        "--scenes",
        &scenes.join(","),
        "--culling",
        &CULLINGS.join(","),
        "--set",
        "opaque_sort=front-to-back,back-to-front",
        "--sizes",
        "160x90",
        "--frames",
        "2",
        "--out",
        out.to_str().unwrap(),
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    let (ok, stdout, err) = tilegraph(&args);
    assert!(ok, "{err}");
    let expected = scenes.len() * CULLINGS.len() * 2;
    assert!(
        stdout.contains(&format!(
            "bench: {expected} runs ({expected} new, 0 failed)"
        )),
        "{stdout}"
    );

    let results: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("results.json")).unwrap()).unwrap();
    let runs = results["runs"].as_array().unwrap();
    assert_eq!(runs.len(), expected);
    for r in runs {
        let t = &r["totals"];
        assert_eq!(t["frames"], 2, "{r}");
        assert_eq!(r["frames"].as_array().unwrap().len(), 2);
        assert!(t["frame_gpu_ms"].as_f64().unwrap() > 0.0, "{r}");
        assert!(r["device"]["driver"].is_string());
        assert!(!r["passes"].as_array().unwrap().is_empty());
        let culling = r["settings"]["culling"].as_str().unwrap();
        if CONSERVATIVE.contains(&culling) {
            assert_eq!(
                t["false_negatives"], 0,
                "{} {culling}",
                r["settings"]["scene"]
            );
            assert_eq!(
                t["frames_image_equal"], 2,
                "{} {culling}",
                r["settings"]["scene"]
            );
        }
    }
    let report = std::fs::read_to_string(out.join("report.md")).unwrap();
    for s in &scenes {
        assert!(
            report.contains(&format!("## {s} at 160x90")),
            "{s} missing from the report"
        );
    }

    // The report keys each setting (`s3`); the Pareto plot draws each key once per panel.
    let key_of = |label: &str| -> String {
        let row = report
            .lines()
            .find(|l| {
                let cells: Vec<&str> = l.split('|').map(str::trim).collect();
                cells.len() > 2 && cells[2].trim_matches('*') == label
            })
            .unwrap_or_else(|| panic!("no row for {label:?} in\n{report}"));
        row.split('|').nth(1).unwrap().trim().to_string()
    };
    assert!(out.join("report.html").is_file());

    // Every SVG parses; each Pareto plot has every setting's two points (FN and FP panels).
    let mut pareto = 0;
    for entry in std::fs::read_dir(&out).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "svg") {
            continue;
        }
        let text = std::fs::read_to_string(&path).unwrap();
        let doc =
            roxmltree::Document::parse(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let texts: Vec<String> = doc
            .descendants()
            .filter(|n| n.has_tag_name("text"))
            .filter_map(|n| n.text())
            .map(|t| t.trim().to_string())
            .collect();
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        if name.starts_with("pareto-") {
            pareto += 1;
            // The ideal frame, every setting's ceiling, drawn and named with its ms.
            assert!(
                texts
                    .iter()
                    .any(|t| t.starts_with("ideal frame ") && t.ends_with(" ms")),
                "{name}: no ideal frame in {texts:?}"
            );
            for culling in CULLINGS {
                for order in ["front-to-back", "back-to-front"] {
                    let key = key_of(&format!("{culling} opaque_sort={order}"));
                    let points = doc
                        .descendants()
                        .filter(|n| {
                            n.attribute("class") == Some("point")
                                && n.attribute("data-key") == Some(key.as_str())
                        })
                        .count();
                    assert_eq!(points, 2, "{name}: {culling} {order} ({key})");
                }
            }
        } else {
            assert!(name.starts_with("passes-"), "{name}");
            assert!(
                texts.iter().any(|t| t == "opaque"),
                "{name}: no opaque pass in {texts:?}"
            );
        }
    }
    assert_eq!(pareto, scenes.len());

    // Interrupted after all but one run: the rerun does that one only.
    let mut partial = results.clone();
    partial["runs"].as_array_mut().unwrap().pop();
    std::fs::write(out.join("results.json"), partial.to_string()).unwrap();
    let (ok, stdout, err) = tilegraph(&args);
    assert!(ok, "{err}");
    assert!(
        err.contains(&format!("{} of {expected} runs already in", expected - 1)),
        "{err}"
    );
    assert!(
        stdout.contains(&format!("bench: {expected} runs (1 new, 0 failed)")),
        "{stdout}"
    );
    std::fs::remove_dir_all(&out).ok();
}

#[test]
fn a_results_file_it_cannot_read_is_not_overwritten() {
    let out = std::env::temp_dir().join(format!("tilegraph-bench-bad-{}", std::process::id()));
    std::fs::create_dir_all(&out).unwrap();
    std::fs::write(out.join("results.json"), b"{ not json").unwrap();
    let args: Vec<String> = [
        "bench",
        "--scenes",
        "city:100",
        "--culling",
        "none",
        "--frames",
        "1",
        "--out",
        out.to_str().unwrap(),
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    let (ok, _, err) = tilegraph(&args);
    assert!(!ok);
    assert!(
        err.contains("is not a results file this tilegraph can resume from"),
        "{err}"
    );
    assert_eq!(
        std::fs::read(out.join("results.json")).unwrap(),
        b"{ not json"
    );
    std::fs::remove_dir_all(&out).ok();
}

/// A sweep of `lod_error_px` on FlightHelmet: the full-detail run is exact, the coarser one
/// draws fewer triangles for a measured image error, and the report has the levels-of-detail
/// plot and table.
#[test]
fn a_level_of_detail_sweep_plots_image_error_against_cost() {
    let Some(helmet) = test_data("scenes/FlightHelmet/FlightHelmet.gltf") else {
        return;
    };
    let out = std::env::temp_dir().join(format!("tilegraph-bench-lod-{}", std::process::id()));
    std::fs::remove_dir_all(&out).ok();
    let args: Vec<String> = [
        "bench",
        "--scenes",
        helmet.to_str().unwrap(),
        "--culling",
        "hiz-2phase",
        "--set",
        "lod_error_px=0,2",
        "--sizes",
        "160x90",
        "--frames",
        "2",
        "--out",
        out.to_str().unwrap(),
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    let (ok, stdout, err) = tilegraph(&args);
    assert!(ok, "{err}");
    assert!(
        stdout.contains("lod-FlightHelmet-gltf-160x90.svg"),
        "{stdout}"
    );
    let results: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("results.json")).unwrap()).unwrap();
    let run = |px: &str| {
        results["runs"]
            .as_array()
            .unwrap()
            .iter()
            .find(|r| r["settings"]["knobs"]["lod_error_px"] == px)
            .unwrap_or_else(|| panic!("no run at {px} px"))["totals"]
            .clone()
    };
    let (full, coarse) = (run("0"), run("2"));
    assert_eq!(full["frames_image_equal"], 2, "{full}");
    assert!(
        full["image_psnr_db"].is_null() && full["image_rmse"] == 0.0,
        "{full}"
    );
    assert!(
        coarse["triangles_drawn"].as_u64() < full["triangles_drawn"].as_u64(),
        "{coarse} {full}"
    );
    assert!(
        coarse["image_psnr_db"].as_f64().is_some_and(|p| p > 20.0),
        "{coarse}"
    );
    let report = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(report.contains("![Levels of detail](lod-FlightHelmet-gltf-160x90.svg)"));
    assert!(report.contains("| hiz-2phase lod_error_px=2 |"), "{report}");
    let svg = std::fs::read_to_string(out.join("lod-FlightHelmet-gltf-160x90.svg")).unwrap();
    assert!(svg.contains("lod_error_px=2"), "the plot names its points");
    std::fs::remove_dir_all(&out).ok();
}
