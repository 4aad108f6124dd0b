//! `tilegraph bottleneck` on lavapipe (validation required): every probe runs and is timed,
//! occlusion culling gives way to frustum culling under them, and a constructed case whose
//! bottleneck is known — a heavy material, thousands of ALU iterations a pixel — is named
//! fragment shading.

mod common;
use common::tilegraph;

#[test]
fn a_heavy_material_is_named_fragment_shading() {
    let (ok, out, err) = tilegraph(&[
        "bottleneck",
        "city:100",
        "--culling",
        "hiz-2phase",
        "--size",
        "160x90",
        "--frames",
        "3",
        "--heavy",
        "3000",
        "--json",
    ]);
    assert!(ok, "{err}");
    let r: serde_json::Value = serde_json::from_str(&out).unwrap_or_else(|e| panic!("{e}: {out}"));
    let m = &r["measured"];
    for probe in [
        "frame_gpu_ms",
        "cpu_ms",
        "trivial_fragment_ms",
        "tiny_resolution_ms",
        "trivial_vertex_ms",
        "quarter_triangles_ms",
        "quarter_instances_ms",
    ] {
        let ms = m[probe].as_f64().unwrap_or(-1.0);
        assert!(ms > 0.0 && ms.is_finite(), "{probe}: {r}");
    }
    assert_eq!(r["stage"], "fragment", "{r}");
    // HiZ reads the depth the probes change: they run with frustum culling, the frame as
    // configured timed too.
    assert_eq!(r["culling"], "hiz-2phase", "{r}");
    assert_eq!(r["probe_culling"], "frustum", "{r}");
    assert!(
        r["configured_frame_gpu_ms"]
            .as_f64()
            .is_some_and(|ms| ms > 0.0),
        "{r}"
    );
    assert!(
        r["advice"].as_str().is_some_and(|a| a.contains("prepass")),
        "{r}"
    );
}

#[test]
fn the_probes_need_a_forward_colour_pass() {
    let (ok, _, err) = tilegraph(&[
        "bottleneck",
        "city:100",
        "--shading",
        "visbuf",
        "--size",
        "64x36",
        "--frames",
        "1",
    ]);
    assert!(!ok);
    assert!(
        err.contains("visbuf") && err.contains("bottleneck"),
        "{err}"
    );
}
