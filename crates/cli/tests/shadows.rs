//! Shadows through the CLI (lavapipe, validation required): `cull-check` compares the
//! technique's frame — its instance culling and its caster culling — with a reference that
//! draws every caster into every cascade, reports both counts, and the casters against the
//! oracle's (needed, FP, FN); `render --json` reports the
//! casters drawn per cascade.

mod common;
use common::tilegraph;

const SHADOWS: [&str; 6] = [
    "--set",
    "shadow_cascades=3",
    "--set",
    "shadow_culling=receivers-hiz",
    "--set",
    "shadow_resolution=256",
];

#[test]
fn cull_check_holds_caster_culling_to_the_image_of_every_caster() {
    let mut args = vec![
        "cull-check",
        "city:300",
        "--culling",
        "hiz-2phase",
        "--shading",
        "prepass",
        "--size",
        "160x90",
        "--frames",
        "4",
        "--json",
    ];
    args.extend(SHADOWS);
    let (ok, out, err) = tilegraph(&args);
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    let t = &v["totals"];
    assert_eq!(t["frames_image_equal"], t["frames"], "{out}");
    let drawn = t["shadow_casters"].as_u64().unwrap();
    let all = t["shadow_casters_all"].as_u64().unwrap();
    println!("casters drawn {drawn} of {all}");
    assert!(0 < drawn && drawn < all, "{out}");
    assert!(t["shadow_gpu_ms"].as_f64().unwrap() > 0.0, "{out}");
    for f in v["frames"].as_array().unwrap() {
        assert!(f["shadow_casters"].as_u64().unwrap() > 0, "{f}");
    }
    // Against the oracle: the casters the visible pixels need were all drawn (an exact
    // culling), so the false positives are the rest of what was drawn, and no caster is a
    // false negative.
    let needed = t["shadow_casters_needed"].as_u64().unwrap();
    let fp = t["shadow_caster_false_positives"].as_u64().unwrap();
    assert_eq!(t["shadow_caster_false_negatives"], 0, "{out}");
    assert!(0 < needed && needed <= drawn, "{out}");
    assert_eq!(fp, drawn - needed, "{out}");
    for f in v["frames"].as_array().unwrap() {
        assert_eq!(f["casters"]["needed_culled"], 0, "{f}");
    }
}

#[test]
fn render_reports_the_casters_of_each_cascade() {
    let out_png =
        std::env::temp_dir().join(format!("tilegraph-shadows-{}.png", std::process::id()));
    let out_arg = out_png.to_str().unwrap().to_string();
    let mut args = vec![
        "render", "city:300", "--size", "160x90", "--frames", "2", "--json", "--out", &out_arg,
    ];
    args.extend(SHADOWS);
    let (ok, out, err) = tilegraph(&args);
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    let casters: Vec<u64> = v["shadow_casters"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c.as_u64().unwrap())
        .collect();
    assert_eq!(casters.len(), 4, "{out}");
    assert!(
        casters[..3].iter().all(|&c| c > 0) && casters[3] == 0,
        "{casters:?}"
    );
    let passes: Vec<&str> = v["gpu_ms"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|p| p["pass"].as_str())
        .collect();
    assert!(passes.contains(&"shadow-cascades"), "{passes:?}");
    std::fs::remove_file(&out_png).ok();
}

#[test]
fn bench_reports_and_plots_the_casters_of_each_caster_culling() {
    let out = std::env::temp_dir().join(format!("tilegraph-shadow-bench-{}", std::process::id()));
    let out_arg = out.to_str().unwrap().to_string();
    let args = [
        "bench",
        "--scenes",
        "city:300",
        "--culling",
        "frustum",
        "--set",
        "shadow_cascades=2",
        "--set",
        "shadow_resolution=256",
        "--set",
        "shadow_culling=none,receivers",
        "--sizes",
        "160x90",
        "--frames",
        "2",
        "--out",
        &out_arg,
    ];
    let (ok, _, err) = tilegraph(&args);
    assert!(ok, "{err}");
    let results: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("results.json")).unwrap()).unwrap();
    let runs = results["runs"].as_array().unwrap();
    assert_eq!(runs.len(), 2, "{results}");
    // Both draw every caster the oracle needs; `receivers` draws fewer, so fewer FP.
    let fp: Vec<u64> = runs
        .iter()
        .map(|r| {
            let t = &r["totals"];
            assert_eq!(t["shadow_caster_false_negatives"], 0, "{t}");
            let needed = t["shadow_casters_needed"].as_u64().unwrap();
            assert!(
                needed > 0 && needed <= t["shadow_casters"].as_u64().unwrap(),
                "{t}"
            );
            t["shadow_caster_false_positives"].as_u64().unwrap()
        })
        .collect();
    assert!(fp.iter().min() < fp.iter().max(), "{fp:?}");
    let report = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(report.contains("| casters drawn / frame |"), "{report}");
    let svg = std::fs::read_to_string(out.join("casters-city-300-160x90.svg")).unwrap();
    assert!(svg.contains("needed by the visible pixels"), "{svg}");
    std::fs::remove_dir_all(&out).ok();
}
