//! Every real scene under `$TILEGRAPH_TEST_DATA/scenes/` loads, and its counts agree with the
//! numbers its LICENSE.md states (parsed from the file, not copied here).

mod common;

use std::collections::HashSet;
use std::path::{Path, PathBuf};

use serde_json::Value;
use tilegraph_scene::{load, Limits};

/// The counts a LICENSE.md states on its "Contents:" line, e.g.
/// "Contents: 6 nodes, 5 meshes, 5 primitives, 94,722 triangles; one material is BLEND".
#[derive(Debug, Default)]
struct Stated {
    nodes: Option<u64>,
    meshes: Option<u64>,
    primitives: Option<u64>,
    triangles: Option<u64>,
    blend_materials: Option<u64>,
    mask_materials: Option<u64>,
}

fn number(word: &str) -> Option<u64> {
    let w = word
        .trim_matches(|c: char| !c.is_alphanumeric())
        .to_ascii_lowercase();
    let words = [
        "zero", "one", "two", "three", "four", "five", "six", "seven", "eight", "nine", "ten",
    ];
    if let Some(n) = words.iter().position(|x| *x == w) {
        return Some(n as u64);
    }
    w.replace(',', "").parse().ok()
}

fn parse_license(text: &str) -> Stated {
    let mut s = Stated::default();
    let Some(line) = text.lines().find(|l| l.contains("Contents:")) else {
        return s;
    };
    let words: Vec<&str> = line.split_whitespace().collect();
    for (i, w) in words.iter().enumerate().skip(1) {
        let n = number(words[i - 1]);
        let noun = w
            .trim_matches(|c: char| !c.is_alphanumeric())
            .to_ascii_lowercase();
        match noun.as_str() {
            "node" | "nodes" => s.nodes = s.nodes.or(n),
            "mesh" | "meshes" => s.meshes = s.meshes.or(n),
            "primitive" | "primitives" => s.primitives = s.primitives.or(n),
            "triangle" | "triangles" => s.triangles = s.triangles.or(n),
            "material" | "materials" => {
                // "one material is BLEND" / "two materials are MASK"
                let verdict = words
                    .get(i + 2)
                    .map(|v| v.trim_matches(|c: char| !c.is_alphanumeric()));
                match verdict {
                    Some("BLEND") => s.blend_materials = n,
                    Some("MASK") => s.mask_materials = n,
                    _ => {}
                }
            }
            _ => {}
        }
    }
    s
}

/// Instances expected from the JSON itself: over the nodes reached from the default scene, the
/// primitives of each node's mesh. Computed independently of the loader.
fn expected_instances(gltf: &Path) -> Option<u64> {
    let doc: Value = serde_json::from_slice(&std::fs::read(gltf).ok()?).ok()?;
    let nodes = doc["nodes"].as_array()?;
    let scene = doc["scene"].as_u64().unwrap_or(0) as usize;
    let mut stack: Vec<usize> = doc["scenes"][scene]["nodes"]
        .as_array()?
        .iter()
        .filter_map(|v| v.as_u64().map(|n| n as usize))
        .collect();
    let mut seen = HashSet::new();
    let mut instances = 0;
    while let Some(n) = stack.pop() {
        if !seen.insert(n) {
            continue;
        }
        let node = &nodes[n];
        if let Some(m) = node["mesh"].as_u64() {
            instances += doc["meshes"][m as usize]["primitives"].as_array()?.len() as u64;
        }
        if let Some(children) = node["children"].as_array() {
            stack.extend(
                children
                    .iter()
                    .filter_map(|c| c.as_u64().map(|c| c as usize)),
            );
        }
    }
    Some(instances)
}

fn scene_files(dir: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .into_iter()
        .flatten()
        .flatten()
        .map(|e| e.path())
        .filter(|p| {
            p.extension()
                .and_then(|e| e.to_str())
                .is_some_and(|e| e.eq_ignore_ascii_case("gltf") || e.eq_ignore_ascii_case("glb"))
        })
        .collect();
    files.sort();
    files
}

#[test]
fn every_shipped_scene_matches_its_license_counts() {
    let Some(root) = common::test_data("scenes") else {
        return;
    };
    let mut dirs: Vec<PathBuf> = std::fs::read_dir(&root)
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.is_dir())
        .collect();
    dirs.sort();
    assert!(
        !dirs.is_empty(),
        "no scene directory under {}",
        root.display()
    );
    for dir in dirs {
        let license = std::fs::read_to_string(dir.join("LICENSE.md")).unwrap_or_default();
        let stated = parse_license(&license);
        let files = scene_files(&dir);
        assert!(!files.is_empty(), "{}: no .gltf/.glb", dir.display());
        for file in files {
            let spec = file.to_str().unwrap();
            let scene = load(spec).unwrap_or_else(|e| panic!("{e}"));
            let info = scene.info();
            println!("{}\n{info}\n", file.display());
            let counts = scene.gltf_counts().copied().unwrap();
            // A LICENSE that states nothing would make this test vacuous.
            assert!(
                stated.nodes.is_some() && stated.triangles.is_some(),
                "{}: {stated:?}",
                dir.display()
            );
            if let Some(n) = stated.nodes {
                assert_eq!(counts.nodes as u64, n, "{}: nodes", file.display());
            }
            if let Some(n) = stated.meshes {
                assert_eq!(counts.meshes as u64, n, "{}: glTF meshes", file.display());
            }
            if let Some(n) = stated.primitives {
                assert_eq!(
                    counts.primitives as u64,
                    n,
                    "{}: primitives",
                    file.display()
                );
                assert_eq!(
                    info.meshes,
                    n,
                    "{}: one tilegraph mesh per primitive",
                    file.display()
                );
            }
            if let Some(n) = stated.triangles {
                assert_eq!(info.triangles, n, "{}: triangles", file.display());
            }
            if let Some(n) = stated.blend_materials {
                assert_eq!(
                    info.materials.blended,
                    n,
                    "{}: BLEND materials",
                    file.display()
                );
            }
            if let Some(n) = stated.mask_materials {
                assert_eq!(
                    info.materials.alpha_tested,
                    n,
                    "{}: MASK materials",
                    file.display()
                );
            }
            if let Some(n) = expected_instances(&file) {
                assert_eq!(info.instances, n, "{}: instances", file.display());
            }
            // Bounds hold every instance, and every instance's sphere holds its AABB's centre.
            let b = scene.bounds();
            for inst in scene.instances() {
                assert!(b.contains_box(&inst.bounds.aabb(), 1e-6));
                assert!(inst.bounds.radius >= 0.0);
            }
            // The same bytes through the from-bytes entry point give the same scene.
            let bytes = std::fs::read(&file).unwrap();
            let resolver = tilegraph_scene::FileResolver { base: dir.clone() };
            let again =
                tilegraph_scene::load_gltf_bytes(&bytes, spec, &resolver, &Limits::default())
                    .unwrap();
            assert_eq!(again.info(), info);
        }
    }
}

#[test]
fn license_parser_reads_the_contents_line() {
    let s = parse_license(
        "- Contents: 6 nodes, 5 meshes, 5 primitives, 94,722 triangles; one material is BLEND (X).",
    );
    assert_eq!(s.nodes, Some(6));
    assert_eq!(s.meshes, Some(5));
    assert_eq!(s.primitives, Some(5));
    assert_eq!(s.triangles, Some(94_722));
    assert_eq!(s.blend_materials, Some(1));
}

#[test]
fn scene_info_json_has_the_documented_shape() {
    let Some(root) = common::test_data("scenes/FlightHelmet") else {
        return;
    };
    let scene = load(root.join("FlightHelmet.gltf").to_str().unwrap()).unwrap();
    let v = serde_json::to_value(scene.info()).unwrap();
    for key in ["instances", "meshes", "triangles", "bounds", "materials"] {
        assert!(v.get(key).is_some(), "missing `{key}` in {v}");
    }
    for key in ["opaque", "alpha_tested", "blended"] {
        assert!(v["materials"][key].is_u64(), "materials.{key}");
    }
    let b = scene.bounds();
    assert_eq!(v["bounds"]["min"], serde_json::json!(b.min.to_array()));
    assert_eq!(v["bounds"]["max"], serde_json::json!(b.max.to_array()));
    assert_eq!(v["instances"], scene.instances().len());
    assert_eq!(v["triangles"], scene.triangles_drawn());
    assert_eq!(v["nodes"], scene.gltf_counts().unwrap().nodes);
}
