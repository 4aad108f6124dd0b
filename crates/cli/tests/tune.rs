//! `tilegraph tune` as a user runs it: the tuned profile loads, and `bench` re-measures its
//! pick with the same FN.

use std::process::Command;

fn tilegraph(args: &[&str], env: &[(&str, &str)]) -> (bool, String, String) {
    let mut c = Command::new(env!("CARGO_BIN_EXE_tilegraph"));
    c.args(args)
        .env_remove("TILEGRAPH_PROFILE")
        .env_remove("TILEGRAPH_PROFILE_DIR")
        .env("TILEGRAPH_VALIDATION", "required");
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

#[test]
fn a_tuned_profile_loads_and_bench_remeasures_its_pick() {
    let dir = std::env::temp_dir().join(format!("tilegraph-tune-{}", std::process::id()));
    std::fs::remove_dir_all(&dir).ok();
    let out = dir.join("tune");
    let (ok, stdout, err) = tilegraph(
        &[
            "tune",
            "--scene",
            "city:400",
            "--culling",
            "none,frustum,hiz-2phase",
            "--size",
            "160x90",
            "--frames",
            "4",
            "--profile",
            "mali-valhall",
            "--out",
            out.to_str().unwrap(),
        ],
        &[],
    );
    assert!(ok, "{err}");
    for want in [
        "# Pick: ",
        "# Runner-up: ",
        "# Held-out path",
        "# Device: ",
        "use it with TILEGRAPH_PROFILE_DIR=",
    ] {
        assert!(stdout.contains(want), "missing {want:?} in {stdout}");
    }
    assert!(
        !stdout.contains("OVERFIT"),
        "conservative picks hold on any path: {stdout}"
    );
    let profile = out.join("profiles/mali-valhall.toml");
    let text = std::fs::read_to_string(&profile).unwrap();
    assert!(text.starts_with("# Tuned by `tilegraph tune`"), "{text}");
    assert!(text.contains("[knobs]"), "{text}");
    let pick = stdout
        .lines()
        .find_map(|l| l.strip_prefix("# Pick: "))
        .unwrap()
        .to_string();
    let culling = pick.split_whitespace().next().unwrap().to_string();

    // The profile loads under TILEGRAPH_PROFILE_DIR, and bench with the profile's choice runs
    // the pick with the FN tune measured (0: the candidates were conservative).
    let profiles = out.join("profiles");
    let env = [("TILEGRAPH_PROFILE_DIR", profiles.to_str().unwrap())];
    let (ok, knobs, err) = tilegraph(&["knobs", "--profile", "mali-valhall"], &env);
    assert!(ok, "{err}");
    assert!(knobs.contains(&format!("culling = {culling}")), "{knobs}");
    let again = dir.join("again");
    let (ok, _, err) = tilegraph(
        &[
            "bench",
            "--scenes",
            "city:400",
            "--culling",
            "profile",
            "--shading",
            "profile",
            "--profiles",
            "mali-valhall",
            "--sizes",
            "160x90",
            "--frames",
            "4",
            "--out",
            again.to_str().unwrap(),
        ],
        &env,
    );
    assert!(ok, "{err}");
    let results: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(again.join("results.json")).unwrap())
            .unwrap();
    let run = &results["runs"][0];
    assert_eq!(run["culling"], culling.as_str(), "{run}");
    assert_eq!(run["totals"]["false_negatives"], 0);
    assert!(pick.contains("FN 0"), "{pick}");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn the_cluster_knobs_are_swept_with_a_cluster_technique() {
    let dir = std::env::temp_dir().join(format!("tilegraph-tune-cl-{}", std::process::id()));
    std::fs::remove_dir_all(&dir).ok();
    let (ok, stdout, err) = tilegraph(
        &[
            "tune",
            "--scene",
            "interior:200@one-mesh",
            "--culling",
            "frustum-clusters",
            "--size",
            "96x54",
            "--frames",
            "3",
            "--out",
            dir.to_str().unwrap(),
        ],
        &[],
    );
    assert!(ok, "{err}");
    assert!(stdout.contains("# Pick: frustum-clusters"), "{stdout}");
    let results: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("results.json")).unwrap()).unwrap();
    let mut gaps: Vec<String> = results["runs"]
        .as_array()
        .unwrap()
        .iter()
        // Stage 2 records the shadings cluster culling cannot run (visbuf) as failed runs.
        .filter(|r| r["culling"] == "frustum-clusters" && !r["totals"].is_null())
        .inspect(|r| assert_eq!(r["totals"]["false_negatives"], 0, "{r}"))
        .filter(|r| !r["settings"]["knobs"]["cluster_gap"].is_null())
        .map(|r| r["settings"]["knobs"]["cluster_gap"].to_string())
        .collect();
    gaps.sort();
    gaps.dedup();
    assert_eq!(gaps, ["0", "1", "2", "4", "8"], "{results}");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn an_impossible_constraint_is_refused_with_the_best_reached() {
    let dir = std::env::temp_dir().join(format!("tilegraph-tune-bad-{}", std::process::id()));
    let (ok, _, err) = tilegraph(
        &[
            "tune",
            "--scene",
            "city:100",
            "--max-fn-rate",
            "2",
            "--out",
            dir.to_str().unwrap(),
        ],
        &[],
    );
    assert!(!ok);
    assert!(err.contains("--max-fn-rate 2 is outside 0..=1"), "{err}");
}
