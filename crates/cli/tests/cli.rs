//! The `tilegraph` binary as a user runs it.

use std::process::Command;

fn tilegraph(args: &[&str], env: &[(&str, &str)]) -> (bool, String, String) {
    let mut c = Command::new(env!("CARGO_BIN_EXE_tilegraph"));
    c.args(args).env_remove("TILEGRAPH_PROFILE");
    for (k, v) in env {
        c.env(k, v);
    }
    let out = c.output().expect("run tilegraph");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn devices_json(env: &[(&str, &str)]) -> Vec<serde_json::Value> {
    let (ok, out, err) = tilegraph(&["devices", "--json"], env);
    assert!(ok, "tilegraph devices --json failed: {err}");
    serde_json::from_str::<Vec<serde_json::Value>>(&out)
        .unwrap_or_else(|e| panic!("not JSON ({e}): {out}"))
}

#[test]
fn devices_json_names_the_profile_and_memory_per_use() {
    let devices = devices_json(&[]);
    assert!(
        !devices.is_empty(),
        "no Vulkan device (lavapipe is installed by cargo xtask deps)"
    );
    for d in &devices {
        for key in [
            "name",
            "vendor_id",
            "device_id",
            "driver_id",
            "device_type",
            "profile",
            "matched_by",
            "memory",
        ] {
            assert!(d.get(key).is_some(), "missing {key} in {d}");
        }
        for use_ in [
            "static_geometry",
            "gpu_only",
            "streaming",
            "readback",
            "staging",
            "transient_attachment",
        ] {
            assert!(
                d["memory"][use_]["type_index"].is_u64(),
                "memory.{use_} in {d}"
            );
        }
        if d["name"]
            .as_str()
            .is_some_and(|n| n.starts_with("llvmpipe"))
        {
            assert_eq!(d["profile"], "lavapipe");
            assert_eq!(d["forced"], false);
        }
    }
}

#[test]
fn a_forced_profile_is_named_and_said_to_be_forced() {
    for d in devices_json(&[("TILEGRAPH_PROFILE", "adreno-7xx")]) {
        assert_eq!(d["profile"], "adreno-7xx");
        assert_eq!(d["forced"], true);
        assert!(
            d["matched_by"]
                .as_str()
                .unwrap_or_default()
                .contains("forced"),
            "{d}"
        );
    }
}

#[test]
fn an_unknown_forced_profile_is_an_error_naming_it() {
    let (ok, _, err) = tilegraph(&["devices"], &[("TILEGRAPH_PROFILE", "voodoo-2")]);
    assert!(!ok);
    assert!(
        err.contains("voodoo-2") && err.contains("lavapipe"),
        "{err}"
    );
}

#[test]
fn demo_writes_a_png() {
    let out = std::env::temp_dir().join(format!("tilegraph-demo-{}.png", std::process::id()));
    let (ok, stdout, err) = tilegraph(
        &["demo", "--out", out.to_str().unwrap(), "--size", "64x36"],
        &[("TILEGRAPH_VALIDATION", "required")],
    );
    assert!(ok, "demo failed: {err}");
    assert!(stdout.contains("profile"), "{stdout}");
    let bytes = std::fs::read(&out).unwrap();
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
    std::fs::remove_file(&out).ok();
}

#[test]
fn scene_info_json_has_the_documented_fields() {
    let (ok, out, err) = tilegraph(&["scene-info", "city:500", "--json"], &[]);
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(out.trim()).unwrap();
    assert_eq!(v["instances"], 500);
    for k in ["meshes", "triangles"] {
        assert!(v[k].as_u64().is_some_and(|n| n > 0), "{k} in {v}");
    }
    for k in ["opaque", "alpha_tested", "blended"] {
        assert!(v["materials"][k].is_u64(), "materials.{k} in {v}");
    }
    assert_eq!(v["bounds"]["min"].as_array().map(Vec::len), Some(3));
    assert_eq!(v["bounds"]["max"].as_array().map(Vec::len), Some(3));
    let (ok, _, err) = tilegraph(&["scene-info", "/nonexistent.gltf"], &[]);
    assert!(!ok && err.contains("nonexistent"), "{err}");
}

#[test]
fn a_closed_output_pipe_ends_the_command_quietly() {
    // `tilegraph scene-info city | head -0`: the reader is gone before the first line.
    let mut child = Command::new(env!("CARGO_BIN_EXE_tilegraph"))
        .args(["scene-info", "city:50"])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("run tilegraph");
    drop(child.stdout.take());
    let out = child.wait_with_output().expect("wait for tilegraph");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "exit {:?}: {err}", out.status);
    assert!(!err.contains("panicked"), "{err}");
}

#[test]
fn render_writes_the_image_and_the_timing_table() {
    let out = std::env::temp_dir().join(format!("tilegraph-render-{}.png", std::process::id()));
    let (ok, stdout, err) = tilegraph(
        &[
            "render",
            "forest:200",
            "--technique",
            "prepass",
            "--profile",
            "adreno-7xx",
            "--size",
            "80x45",
            "--frames",
            "2",
            "--out",
            out.to_str().unwrap(),
        ],
        &[("TILEGRAPH_VALIDATION", "required")],
    );
    assert!(ok, "{err}");
    for want in [
        "depth-prepass",
        "alpha-tested",
        "GPU time per pass",
        "left out",
        "lint (adreno-7xx): 1 findings",
    ] {
        assert!(stdout.contains(want), "missing {want:?} in {stdout}");
    }
    assert_eq!(&std::fs::read(&out).unwrap()[..4], b"\x89PNG");
    std::fs::remove_file(&out).ok();
}

#[test]
fn devices_json_reports_the_state_rules_with_their_sources() {
    let devices = devices_json(&[("TILEGRAPH_PROFILE", "mali-valhall")]);
    let rules = devices[0]["state_rules"].as_array().expect("state_rules");
    assert!(!rules.is_empty());
    for r in rules {
        assert!(r["source"].as_str().is_some_and(|s| !s.is_empty()), "{r}");
    }
    assert!(devices[0]["passes"]["order"].is_array());
}

#[test]
fn lint_json_lists_findings_with_their_sources() {
    let (ok, out, err) = tilegraph(
        &[
            "lint",
            "forest:100",
            "--culling",
            "hiz-2phase",
            "--shading",
            "prepass",
            "--profile",
            "powervr-b",
            "--size",
            "64x36",
            "--json",
        ],
        &[("TILEGRAPH_VALIDATION", "required")],
    );
    assert!(ok, "{err}");
    let v: serde_json::Value =
        serde_json::from_str(&out).unwrap_or_else(|e| panic!("not JSON ({e}): {out}"));
    assert_eq!(v["profile"], "powervr-b");
    assert!(!v["render_passes"].as_array().unwrap().is_empty());
    let findings = v["findings"].as_array().unwrap();
    // PowerVR draws no pre-pass: the alpha-tested colour pass discards with depth writes.
    assert!(
        findings
            .iter()
            .any(|f| f["rule"] == "discard_with_depth_write"
                && f["effect"] == "disables_hsr"
                && f["source"]
                    .as_str()
                    .is_some_and(|s| s.contains("IMG-discard"))),
        "{out}"
    );
}
