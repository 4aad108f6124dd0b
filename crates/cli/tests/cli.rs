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

/// `scene-info --write-clusters`: the file for a device build, with the levels of detail or,
/// `--without-levels`, without (fewer indices, the same clusters); both read back.
#[test]
fn cluster_files_are_written_with_or_without_levels() {
    let Some(helmet) = tilegraph_e2e::test_data("scenes/FlightHelmet/FlightHelmet.gltf") else {
        return;
    };
    let dir = std::env::temp_dir().join(format!("tg-cluster-files-{}", std::process::id()));
    let (with, without) = (dir.join("with.tgc"), dir.join("without.tgc"));
    let mut reports = Vec::new();
    for (file, extra) in [(&with, None), (&without, Some("--without-levels"))] {
        let mut args = vec!["scene-info", helmet.to_str().unwrap(), "--json"];
        args.extend(["--write-clusters", file.to_str().unwrap()]);
        args.extend(extra);
        let (ok, out, err) = tilegraph(&args, &[]);
        assert!(ok, "{err}");
        let v: serde_json::Value = serde_json::from_str(out.trim()).unwrap();
        reports.push(v["clusters"].clone());
    }
    let a = tilegraph_scene::clusters::ClusterData::read(&with).unwrap();
    let b = tilegraph_scene::clusters::ClusterData::read(&without).unwrap();
    assert_eq!(a.clusters, b.clusters);
    assert!(b.lods.is_empty() && !a.lods.is_empty());
    let level_indices: u64 = a.lods.iter().map(|l| u64::from(l.index_count)).sum();
    assert!(level_indices > 0);
    assert_eq!(
        a.indices.len() as u64,
        b.indices.len() as u64 + level_indices
    );
    assert_eq!(reports[0]["level_indices"], level_indices);
    assert_eq!(reports[1]["levels"], 0);
    assert!(std::fs::metadata(&with).unwrap().len() > std::fs::metadata(&without).unwrap().len());
    std::fs::remove_dir_all(&dir).ok();
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
    assert_eq!(v["degenerate"]["zero_area"], 0, "the city is clean: {v}");
    // The maze strews zero-area triangles and needles on purpose.
    let (ok, out, err) = tilegraph(&["scene-info", "maze:700", "--json"], &[]);
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(out.trim()).unwrap();
    for k in ["zero_area", "slivers"] {
        assert!(
            v["degenerate"][k].as_u64().is_some_and(|n| n > 0),
            "{k} in {v}"
        );
    }
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
            "--shading",
            "prepass",
            "--culling",
            "none",
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
        "lint (adreno-7xx): clean but 1 accepted finding (",
    ] {
        assert!(stdout.contains(want), "missing {want:?} in {stdout}");
    }
    assert_eq!(&std::fs::read(&out).unwrap()[..4], b"\x89PNG");
    std::fs::remove_file(&out).ok();
}

/// `tilegraph render` of a textured glTF (the tests' gallery written to disk: PNG and JPEG
/// files beside the .gltf, one image a data URI) draws its base-colour textures, checked
/// against tests/golden/textured-gallery-render.png; `scene-info` reports the textures.
#[test]
fn render_of_a_textured_gltf_matches_its_golden_image() {
    let dir = std::env::temp_dir().join(format!("tilegraph-gallery-{}", std::process::id()));
    let gltf = tilegraph_e2e::textured::textured_gallery()
        .write_to(&dir)
        .unwrap();
    let out = dir.join("frame.png");
    let camera = dir.join("gallery-camera.json");
    let (ok, _, err) = tilegraph(
        &[
            "render",
            gltf.to_str().unwrap(),
            "--camera-path",
            camera.to_str().unwrap(),
            "--profile",
            "lavapipe",
            "--size",
            "160x90",
            "--frames",
            "1",
            "--out",
            out.to_str().unwrap(),
        ],
        &[("TILEGRAPH_VALIDATION", "required")],
    );
    assert!(ok, "{err}");
    let img = tilegraph_e2e::golden::read_png(&out).unwrap();
    let golden = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../tests/golden/textured-gallery-render.png");
    if std::env::var_os("TILEGRAPH_BLESS").is_some() {
        tilegraph_e2e::golden::write_png(&golden, &img).unwrap();
    } else {
        tilegraph_e2e::golden::compare(&golden, &img, 2).unwrap();
    }
    let (ok, info, err) = tilegraph(&["scene-info", gltf.to_str().unwrap(), "--json"], &[]);
    assert!(ok, "{err}");
    let info: serde_json::Value = serde_json::from_str(&info).unwrap();
    assert_eq!(info["textures"], 4, "{info}");
    // Four images of 64x64, 48x40, 32x32 and 16x16, RGBA8 with full mip chains.
    assert!(
        info["texture_bytes"].as_u64().unwrap() > 4 * (64 * 64 + 48 * 40),
        "{info}"
    );
    std::fs::remove_dir_all(&dir).ok();
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
    // That finding is the pass's intended state on PowerVR (config/accepted_findings.toml):
    // marked with its reason and counted apart.
    let accepted = findings
        .iter()
        .filter(|f| f["accepted"].as_str().is_some_and(|r| !r.is_empty()))
        .count();
    assert!(accepted > 0, "{out}");
    assert_eq!(v["accepted_findings"], accepted, "{out}");
    assert_eq!(v["open_findings"], findings.len() - accepted, "{out}");
}

#[test]
fn bad_input_is_a_clear_error_naming_it() {
    let dir = std::env::temp_dir().join(format!("tilegraph-bad-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("level.gltf"), b"{}").unwrap();
    let bare = dir.join("bare.json");
    std::fs::write(&bare, br#"[{"eye": [0,0,0], "target": [0,0,-1]}]"#).unwrap();
    let png = dir.join("e.jpg");
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (vec!["render", "city", "--frames", "0"], "0 is not in 1.."),
        (vec!["render", "city:0"], "needs at least one instance"),
        (
            vec!["render", "city", "--out", png.to_str().unwrap()],
            "name the file .png",
        ),
        (
            vec!["render", dir.to_str().unwrap()],
            "is a directory; the glTF files in it: level.gltf",
        ),
        (
            vec!["render", "city", "--set", "oq_group=0"],
            "knob oq_group: \"0\" is outside its domain",
        ),
        (
            vec!["cull-check", "city", "--set", "raster_occlusion_scale=3"],
            "knob raster_occlusion_scale: \"3\" is outside its domain (1, 2, 4)",
        ),
        (
            vec!["lint", "city", "--set", "oq_groop=2"],
            "unknown knob \"oq_groop\"",
        ),
        (
            vec!["render", "city", "--set", "oq_group"],
            "not of the form knob=value",
        ),
        (
            vec!["render", "city", "--culling", "hiz-3phase"],
            "knob culling: \"hiz-3phase\" is outside its domain",
        ),
        (
            vec![
                "cull-check",
                "city",
                "--camera-path",
                bare.to_str().unwrap(),
            ],
            "a bare array: a camera path is an object",
        ),
    ];
    for (args, want) in cases {
        let (ok, out, err) = tilegraph(&args, &[("TILEGRAPH_VALIDATION", "required")]);
        assert!(!ok, "{args:?} succeeded: {out}");
        assert!(err.contains(want), "{args:?}: missing {want:?} in {err}");
    }
    assert!(!png.exists(), "nothing is written under a refused name");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn knobs_the_run_cannot_use_are_errors_and_the_flag_is_credited() {
    let out = std::env::temp_dir().join(format!("tilegraph-knobs-{}.png", std::process::id()));
    let o = out.to_str().unwrap();
    let env = [("TILEGRAPH_VALIDATION", "required")];
    let small = ["--size", "32x18", "--frames", "1", "--out", o];
    let run = |extra: &[&str], env: &[(&str, &str)]| {
        let args: Vec<&str> = extra.iter().chain(small.iter()).copied().collect();
        tilegraph(&args, env)
    };
    let (ok, _, err) = run(
        &[
            "render",
            "city:300",
            "--culling",
            "hiz",
            "--set",
            "oq_group=4",
        ],
        &env,
    );
    assert!(!ok);
    assert!(
        err.contains(
            "knob oq_group applies to culling oq, oq-conditional, and this run culls with hiz"
        ),
        "{err}"
    );
    let (ok, _, err) = run(&["render", "city:300", "--set", "alpha_prepass=off"], &env);
    assert!(!ok);
    assert!(err.contains("has no alpha-tested geometry"), "{err}");
    let (ok, _, err) = run(
        &[
            "render",
            "forest:300",
            "--culling",
            "hiz-2phase",
            "--set",
            "alpha_prepass=off",
        ],
        &env,
    );
    assert!(!ok);
    assert!(
        err.contains("culling hiz-2phase draws alpha-tested depth in its own pre-pass"),
        "{err}"
    );
    let (ok, _, err) = run(
        &[
            "render",
            "forest:300",
            "--culling",
            "none",
            "--set",
            "alpha_prepass=off",
        ],
        &env,
    );
    assert!(ok, "{err}");
    // A depth pre-pass the profile wants can be turned off, and the frame setup says by what;
    // two-phase culling draws its own.
    let (ok, stdout, err) = run(
        &[
            "render",
            "city:300",
            "--profile",
            "mali-valhall",
            "--culling",
            "none",
            "--set",
            "depth_prepass=off",
        ],
        &env,
    );
    assert!(ok, "{err}");
    assert!(
        stdout.contains("left out knob depth_prepass = off, over profile mali-valhall's choice"),
        "{stdout}"
    );
    let (ok, _, err) = run(
        &[
            "render",
            "city:300",
            "--culling",
            "hiz-2phase",
            "--set",
            "depth_prepass=off",
        ],
        &env,
    );
    assert!(!ok);
    assert!(
        err.contains("culling hiz-2phase draws its own depth pre-pass"),
        "{err}"
    );
    // The flag wins over the variable, and says so.
    let (ok, stdout, err) = run(
        &["render", "city:100", "--profile", "mali-valhall"],
        &[
            ("TILEGRAPH_VALIDATION", "required"),
            ("TILEGRAPH_PROFILE", "adreno-7xx"),
        ],
    );
    assert!(ok, "{err}");
    assert!(
        stdout.contains("profile mali-valhall (forced by --profile mali-valhall)"),
        "{stdout}"
    );
    // The old spelling still works, and says what replaces it.
    let (ok, _, err) = run(&["render", "city:100", "--technique", "prepass"], &env);
    assert!(ok, "{err}");
    assert!(
        err.contains("--technique is deprecated: use --shading prepass"),
        "{err}"
    );
    // `render` culls, and `--json` says with what and why.
    let (ok, stdout, err) = run(
        &[
            "render",
            "forest:300",
            "--culling",
            "hiz-2phase",
            "--set",
            "hiz_npot=pad-to-pow2",
            "--json",
        ],
        &env,
    );
    assert!(ok, "{err}");
    let v: serde_json::Value =
        serde_json::from_str(&stdout).unwrap_or_else(|e| panic!("not JSON ({e}): {stdout}"));
    assert_eq!(v["culling"], "hiz-2phase");
    let knobs = v["knobs"].as_array().unwrap();
    let knob = |n: &str| knobs.iter().find(|k| k["name"] == n).cloned();
    assert_eq!(knob("hiz_npot").unwrap()["value"], "pad-to-pow2");
    assert_eq!(knob("hiz_npot").unwrap()["origin"], "run");
    assert!(
        knob("oq_group").is_none(),
        "not offered to hiz-2phase: {stdout}"
    );
    assert!(
        knob("alpha_prepass").is_none(),
        "hiz-2phase pre-passes alpha itself: {stdout}"
    );
    assert!(v["frame_gpu_ms"].as_f64().unwrap() > 0.0);
    assert!(v["gpu_ms"]
        .as_array()
        .unwrap()
        .iter()
        .any(|p| p["pass"] == "hiz-build"));
    // auto says why it chose.
    let (ok, stdout, err) = run(&["render", "city:100", "--culling", "auto", "--json"], &env);
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    // Then it timed the candidates on this device and kept the fastest.
    let trial = v["auto_trial"].as_str().unwrap();
    let kept = v["culling"].as_str().unwrap();
    assert!(trial.contains(&format!("— {kept} is fastest")), "{trial}");
    for candidate in ["none", "frustum", "hiz-2phase", "software-occlusion"] {
        assert!(trial.contains(&format!("{candidate} ")), "{trial}");
    }
    // Each candidate's whole-frame time arrived (a frame of city:100 takes milliseconds here).
    assert!(!trial.contains(" 0.000 ms"), "{trial}");
    // Under the visibility buffer, which has no depth pre-pass for query boxes, the trial
    // leaves same-frame queries out (it failed on them before).
    let (ok, stdout, err) = run(
        &["render", "city:100", "--shading", "visbuf", "--json"],
        &env,
    );
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    let trial = v["auto_trial"].as_str().unwrap();
    assert!(
        trial.contains("hiz-2phase ") && !trial.contains("oq-conditional"),
        "{trial}"
    );
    assert!(
        v["auto_reason"]
            .as_str()
            .unwrap()
            .contains("fewer than 256"),
        "{stdout}"
    );
    std::fs::remove_file(&out).ok();
}

/// Next-frame queries inside the visibility buffer's render pass: the depth they test is not
/// kept (DONT_CARE), and that store must wait for every earlier subpass's depth test (a
/// synchronization-validation hazard found by `tilegraph tune`). Four frames reach it.
#[test]
fn visbuf_with_occlusion_queries_is_clean_under_synchronization_validation() {
    let (ok, out, err) = tilegraph(
        &[
            "cull-check",
            "city:400",
            "--culling",
            "oq",
            "--shading",
            "visbuf",
            "--size",
            "160x90",
            "--frames",
            "4",
        ],
        &[("TILEGRAPH_VALIDATION", "required")],
    );
    assert!(ok, "{err}");
    assert!(out.contains("images equal"), "{out}");
    assert!(!err.contains("SYNC-HAZARD"), "{err}");
}

/// `--save-frames` writes the technique's image, the reference and a diff for exactly the
/// frames that went wrong. Next-frame queries, one per instance, lose instances as they come
/// into view.
#[test]
fn cull_check_saves_the_frames_that_went_wrong() {
    let dir = std::env::temp_dir().join(format!("tilegraph-saved-{}", std::process::id()));
    std::fs::remove_dir_all(&dir).ok();
    let (ok, out, err) = tilegraph(
        &[
            "cull-check",
            "city:1500",
            "--culling",
            "oq",
            // One query per instance, every instance tested every frame: the one-frame lag shows.
            "--set",
            "oq_group=1",
            "--set",
            "occlusion_recheck=1",
            "--size",
            "160x90",
            "--frames",
            "12",
            "--json",
            "--save-frames",
            dir.to_str().unwrap(),
        ],
        &[("TILEGRAPH_VALIDATION", "required")],
    );
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    let wrong: Vec<u64> = v["frames"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|f| f["false_negatives"].as_u64().unwrap() > 0 || f["image_equal"] == false)
        .map(|f| f["frame"].as_u64().unwrap())
        .collect();
    assert!(!wrong.is_empty(), "next-frame queries lost nothing: {out}");
    let mut saved: Vec<String> = std::fs::read_dir(&dir)
        .map(|d| {
            d.map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
                .collect()
        })
        .unwrap_or_default();
    saved.sort();
    let mut expected: Vec<String> = wrong
        .iter()
        .flat_map(|n| ["diff", "reference", "technique"].map(|w| format!("frame-{n:04}-{w}.png")))
        .collect();
    expected.sort();
    assert_eq!(saved, expected);
    for f in &saved {
        assert_eq!(&std::fs::read(dir.join(f)).unwrap()[..4], b"\x89PNG");
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// `tilegraph graph`: the plan with a reason for every decision, as text, JSON and DOT.
#[test]
fn graph_explains_the_plan_of_a_scene_frame() {
    let env = [("TILEGRAPH_VALIDATION", "required")];
    let base = [
        "graph",
        "forest:300",
        "--profile",
        "mali-valhall",
        "--culling",
        "hiz-2phase",
        "--size",
        "64x36",
    ];
    let (ok, out, err) = tilegraph(&[&base[..], &["--json"]].concat(), &env);
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["profile"], "mali-valhall");
    let reasons = v["reasons"].as_array().unwrap();
    for topic in ["merge", "load", "store", "barrier", "traffic"] {
        assert!(
            reasons
                .iter()
                .any(|r| r["topic"] == topic && !r["why"].as_str().unwrap().is_empty()),
            "no {topic} reason in {out}"
        );
    }
    // Two-phase culling splits depth around the pyramid build: the late depth pass says so.
    assert!(
        reasons.iter().any(|r| r["subject"] == "depth-prepass-late"
            && r["why"]
                .as_str()
                .unwrap()
                .contains("compute or transfer step")),
        "{out}"
    );
    let (ok, dot, err) = tilegraph(&[&base[..], &["--dot"]].concat(), &env);
    assert!(ok, "{err}");
    assert!(dot.trim_start().starts_with("digraph"), "{dot}");
    let (ok, text, err) = tilegraph(&base, &env);
    assert!(ok, "{err}");
    assert!(
        text.contains("why:") && text.contains("render pass"),
        "{text}"
    );
    // A cluster technique's plan and lint: the scene's clusters are built for them.
    let clustered = [
        "forest:300",
        "--culling",
        "hiz-2phase-clusters",
        "--size",
        "64x36",
    ];
    let (ok, text, err) = tilegraph(&[&["graph"][..], &clustered].concat(), &env);
    assert!(ok, "{err}");
    for pass in [
        "cluster-cull-late",
        "cluster-place-late",
        "cluster-emit-late",
    ] {
        assert!(text.contains(pass), "no {pass} in {text}");
    }
    let (ok, _, err) = tilegraph(&[&["lint"][..], &clustered].concat(), &env);
    assert!(ok, "{err}");
}

/// D16 depth end to end (knob `depth_format`): the conservative techniques stay exact — FN 0 and
/// the unculled image on every frame — with the pyramid built from the 16-bit depth.
#[test]
fn d16_depth_keeps_conservative_culling_exact() {
    for culling in ["hiz-2phase", "oq-conditional", "raster-occlusion"] {
        let (ok, out, err) = tilegraph(
            &[
                "cull-check",
                "city:1500",
                "--culling",
                culling,
                "--set",
                "depth_format=d16",
                "--size",
                "160x90",
                "--frames",
                "8",
                "--json",
            ],
            &[("TILEGRAPH_VALIDATION", "required")],
        );
        assert!(ok, "{culling}: {err}");
        let v: serde_json::Value = serde_json::from_str(&out).unwrap();
        assert_eq!(v["totals"]["false_negatives"], 0, "{culling}");
        assert_eq!(v["totals"]["frames_image_equal"], 8, "{culling}");
    }
    let (ok, plan, err) = tilegraph(
        &[
            "graph",
            "city:300",
            "--culling",
            "none",
            "--set",
            "depth_format=d16",
            "--size",
            "64x36",
        ],
        &[("TILEGRAPH_VALIDATION", "required")],
    );
    assert!(ok, "{err}");
    assert!(plan.contains("D16_UNORM"), "{plan}");
}

/// A moving scene through the CLI (`SPEC@moving[:MOVERS[:SPAWNS[:SEED[:MIRRORS]]]]`):
/// cull-check moves it frame by frame (half the movers turning mirrored) for the oracle, the
/// reference and the technique alike; render draws it; a malformed motion is a usage error
/// naming the form.
#[test]
fn moving_scenes_are_checked_and_rendered_from_their_spec() {
    let (ok, out, err) = tilegraph(
        &[
            "cull-check",
            "city:600@moving:0.3:4:2:0.5",
            "--culling",
            "hiz-2phase",
            "--size",
            "160x90",
            "--frames",
            "8",
            "--json",
        ],
        &[("TILEGRAPH_VALIDATION", "required")],
    );
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["totals"]["false_negatives"], 0, "{out}");
    assert_eq!(v["totals"]["frames_image_equal"], 8, "{out}");
    // No ideal frame for a moving scene (it would be copied whole every frame).
    assert!(v["totals"]["ideal_frame_gpu_ms"].is_null(), "{out}");
    let png = std::env::temp_dir().join(format!("tilegraph-moving-{}.png", std::process::id()));
    let (ok, _, err) = tilegraph(
        &[
            "render",
            "city:600@moving",
            "--size",
            "64x36",
            "--frames",
            "3",
            "--out",
            png.to_str().unwrap(),
        ],
        &[("TILEGRAPH_VALIDATION", "required")],
    );
    assert!(ok, "{err}");
    assert!(png.exists());
    std::fs::remove_file(&png).ok();
    let (ok, _, err) = tilegraph(&["scene-info", "city:600@moving:2"], &[]);
    assert!(!ok);
    assert!(err.contains("MOVERS is a share from 0 to 1"), "{err}");
    let (ok, _, err) = tilegraph(&["scene-info", "city:600@moving:0.3:4:2:2"], &[]);
    assert!(!ok);
    assert!(err.contains("MIRRORS is a share from 0 to 1"), "{err}");
}

/// `--camera-path walk[:SEED]`: a walk at eye height through the scene (one-mesh levels too),
/// checked like any path; a malformed seed is a usage error naming the form.
#[test]
fn walks_at_eye_height_are_named_camera_paths() {
    let (ok, out, err) = tilegraph(
        &[
            "cull-check",
            "interior:300@one-mesh",
            "--camera-path",
            "walk:4",
            "--culling",
            "hiz-2phase-clusters",
            "--size",
            "96x54",
            "--frames",
            "4",
            "--json",
        ],
        &[("TILEGRAPH_VALIDATION", "required")],
    );
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["totals"]["false_negatives"], 0, "{out}");
    assert_eq!(v["totals"]["cluster_false_negatives"], 0, "{out}");
    assert_eq!(v["totals"]["frames_image_equal"], 4, "{out}");
    assert!(
        v["frames"][0]["clusters"]["visible"].as_u64().unwrap_or(0) > 0,
        "{out}"
    );
    // The ideal frame: the oracle's visible set drawn without culling work, and the technique's
    // efficiency against it.
    let ideal = v["totals"]["ideal_frame_gpu_ms"].as_f64().unwrap_or(0.0);
    let efficiency = v["totals"]["efficiency"].as_f64().unwrap_or(0.0);
    assert!(
        ideal > 0.0 && efficiency > 0.0 && efficiency.is_finite(),
        "{out}"
    );
    let (ok, _, err) = tilegraph(
        &[
            "cull-check",
            "city:100",
            "--camera-path",
            "walk:x",
            "--frames",
            "1",
        ],
        &[],
    );
    assert!(!ok && err.contains("walk:SEED"), "{err}");
}

/// A JSON camera path that looks straight down (a top-down camera) and straight up, giving no
/// `up`, is checked like any path: no frame is refused for an up parallel to the view.
#[test]
fn a_top_down_json_path_without_up_is_checked() {
    let path = std::env::temp_dir().join(format!("tilegraph-top-down-{}.json", std::process::id()));
    std::fs::write(
        &path,
        r#"{"frames": [
            {"eye": [0, 30, 0], "target": [0, 0, 0], "cut": true},
            {"eye": [2, 12, 1], "target": [2, 0, 1]},
            {"eye": [2, 2.5, 1], "target": [2, 0, 1], "near": 0.01},
            {"eye": [1, 0.5, 1], "target": [1, 9, 1], "cut": true}
        ]}"#,
    )
    .unwrap();
    let (ok, out, err) = tilegraph(
        &[
            "cull-check",
            "maze:300",
            "--camera-path",
            path.to_str().unwrap(),
            "--culling",
            "hiz-2phase",
            "--size",
            "96x54",
            "--frames",
            "4",
            "--json",
        ],
        &[("TILEGRAPH_VALIDATION", "required")],
    );
    std::fs::remove_file(&path).ok();
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["totals"]["false_negatives"], 0, "{out}");
    assert_eq!(v["totals"]["frames_image_equal"], 4, "{out}");
    assert!(v["totals"]["visible"].as_u64().unwrap_or(0) > 0, "{out}");
}

/// `auto` times a visible set given for the scene only where the profile says
/// `auto_pvs = "allow"` (no shipped profile does).
#[test]
fn auto_times_a_given_visible_set_only_where_the_profile_allows() {
    let dir = std::env::temp_dir().join(format!("tilegraph-auto-pvs-{}", std::process::id()));
    let profiles = dir.join("profiles");
    std::fs::create_dir_all(&profiles).unwrap();
    let set = dir.join("city.pvs.json");
    let set = set.to_str().unwrap();
    let (ok, _, err) = tilegraph(
        &[
            "pvs",
            "city:300",
            "--cell",
            "40",
            "--samples",
            "1",
            "--face-px",
            "32",
            "--out",
            set,
        ],
        &[],
    );
    assert!(ok, "{err}");
    let lavapipe = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../config/profiles/lavapipe.toml"
    ))
    .unwrap();
    assert!(lavapipe.contains("[passes]"));
    std::fs::write(
        profiles.join("lavapipe.toml"),
        lavapipe.replacen("[passes]", "[passes]\nauto_pvs = \"allow\"", 1),
    )
    .unwrap();
    let trial = |env: &[(&str, &str)]| {
        let (ok, out, err) = tilegraph(
            &[
                "cull-check",
                "city:300",
                "--culling",
                "auto",
                "--pvs",
                set,
                "--size",
                "160x90",
                "--frames",
                "48",
            ],
            env,
        );
        assert!(ok, "{err}");
        let text = format!("{out}{err}");
        text.lines()
            .find(|l| l.contains("auto timed on this device"))
            .unwrap_or_else(|| panic!("no trial in {text}"))
            .to_string()
    };
    let shipped = trial(&[]);
    assert!(!shipped.contains(" pvs "), "{shipped}");
    let allowed = trial(&[("TILEGRAPH_PROFILE_DIR", profiles.to_str().unwrap())]);
    assert!(allowed.contains(" pvs "), "{allowed}");
    std::fs::remove_dir_all(&dir).ok();
}

/// `graph --async-compute` shows the queues: the HiZ build on the async compute queue beside
/// the shadow cascades, each submission with its waits and their reasons, and the `queue` and
/// `wait` explanations; `--async-compute off` keeps one queue and says why the build stays on
/// it.
#[test]
fn graph_shows_queues_and_cross_queue_waits() {
    let base = [
        "graph",
        "city:300",
        "--culling",
        "hiz-2phase",
        "--shading",
        "prepass",
        "--set",
        "shadow_cascades=2",
    ];
    let with = |flag: &str| {
        let mut args = base.to_vec();
        args.extend(["--async-compute", flag]);
        let (ok, out, err) = tilegraph(&args, &[("TILEGRAPH_VALIDATION", "required")]);
        assert!(ok, "{err}");
        out
    };
    let out = with("exclusive");
    assert!(
        out.contains("submissions on 2 queues (exclusive sharing)"),
        "{out}"
    );
    assert!(
        out.contains("hiz-build") && out.contains("compute (async)"),
        "{out}"
    );
    assert!(
        out.contains("submission 1 on the async-compute queue"),
        "{out}"
    );
    assert!(
        out.contains("waits for submission 0") && out.contains("frame start"),
        "{out}"
    );
    assert!(
        out.contains("(ownership)") && out.contains("release to async-compute"),
        "{out}"
    );
    assert!(
        out.contains("queue    hiz-build") && out.contains("wait     submission"),
        "{out}"
    );
    let out = with("concurrent");
    assert!(
        out.contains("(concurrent sharing)") && !out.contains("(ownership)"),
        "{out}"
    );
    let out = with("off");
    assert!(!out.contains("submission 1"), "{out}");
    assert!(out.contains("async compute is off"), "{out}");
}
