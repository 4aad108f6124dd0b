//! The Khronos glTF-Validator's own test assets, each with the validator's report: the loader
//! never panics or hangs; where the validator finds errors in what the loader uses, the loader
//! fails with a typed error pointing at the same object; where it finds none, the loader loads
//! (or reports an empty scene). Known, reasoned disagreements are listed in `DISAGREEMENTS`.
//!
//! The agreement table is printed (`cargo test -p tilegraph-scene --test validator_suite --
//! --nocapture`) and must match the one in docs/SCENES.md; regenerate that one with
//! `TILEGRAPH_BLESS_DOCS=1 cargo test -p tilegraph-scene --test validator_suite`.

mod common;

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use serde_json::Value;
use tilegraph_scene::{load_gltf, Limits, SceneError};

/// Files where loader and validator legitimately disagree, and why. Each entry must still be a
/// disagreement (a stale entry fails the test), so the list cannot hide a fixed behaviour.
const DISAGREEMENTS: &[(&str, &str)] = &[
    (
        "asset/min_version_valid.gltf",
        "minVersion 2.1 is valid glTF, but it asks for a 2.1 loader; this one implements 2.0 and refuses, as minVersion intends",
    ),
    (
        "camera/infinite_znear.gltf",
        "`1e309` is valid JSON syntax but overflows f64; serde_json rejects the whole document, while the validator parses it as infinity and flags only the (unused) camera",
    ),
    (
        "root/named_objects.gltf",
        "buffer 0 has no uri in a .gltf (a placeholder): the validator checks structure only, the loader must read the drawn mesh's bytes and has none",
    ),
    (
        "root/unused_objects.gltf",
        "buffer 0 has no uri in a .gltf (a placeholder): the validator checks structure only, the loader must read the drawn mesh's bytes and has none",
    ),
    (
        "root/duplicate_extension_entry.gltf",
        "a duplicate in extensionsUsed/extensionsRequired names a supported extension twice; nothing the loader reads changes",
    ),
];

#[derive(Debug)]
struct Report {
    errors: Vec<(String, String)>, // (code, pointer) of severity 0
}

fn read_report(path: &Path) -> Option<Report> {
    let v: Value = serde_json::from_slice(&std::fs::read(path).ok()?).ok()?;
    let messages = v["issues"]["messages"].as_array()?;
    let errors = messages
        .iter()
        .filter(|m| m["severity"].as_u64() == Some(0))
        .map(|m| {
            (
                m["code"].as_str().unwrap_or("?").to_string(),
                m["pointer"].as_str().unwrap_or("").to_string(),
            )
        })
        .collect::<Vec<_>>();
    assert_eq!(
        v["issues"]["numErrors"].as_u64(),
        Some(errors.len() as u64),
        "{}: numErrors disagrees with the messages",
        path.display()
    );
    Some(Report { errors })
}

/// Whether a validator pointer lies in a part of the document the loader reads. The loader
/// ignores cameras, animations, skins, root extensions and extensionsUsed, and the texture
/// references inside materials but the base colour's. Images, textures and samplers it reads
/// only where a material's base colour reaches them: the validator's image and texture assets
/// reference theirs from no material, so a pointer there counts as unread.
fn used_by_loader(pointer: &str) -> bool {
    let first = pointer
        .trim_start_matches('/')
        .split('/')
        .next()
        .unwrap_or("");
    match first {
        "" => true, // the document or the GLB container itself
        "asset" | "buffers" | "bufferViews" | "accessors" | "meshes" | "nodes" | "scenes"
        | "scene" | "extensionsRequired" => true,
        "materials" => !pointer.contains("Texture") || pointer.contains("/baseColorTexture"),
        _ => false,
    }
}

/// Same object: equal pointers, or one a path-segment prefix of the other (the validator
/// sometimes points at `/accessors/0/byteOffset` where the loader names `/accessors/0`). The
/// document root (`""` or `"/"`) only matches itself.
fn same_object(a: &str, b: &str) -> bool {
    let (a, b) = (a.trim_end_matches('/'), b.trim_end_matches('/'));
    if a == b {
        return true;
    }
    if a.is_empty() || b.is_empty() {
        return false;
    }
    let under =
        |short: &str, long: &str| long.starts_with(short) && long[short.len()..].starts_with('/');
    under(a, b) || under(b, a)
}

enum LoaderVerdict {
    Loaded { instances: usize, triangles: u64 },
    Empty,
    Error(SceneError),
}

struct Row {
    file: String,
    report: Report,
    verdict: LoaderVerdict,
    agreement: String,
    agrees: bool,
}

fn collect(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).into_iter().flatten().flatten() {
        let p = e.path();
        if p.is_dir() {
            collect(&p, out);
        } else if p
            .extension()
            .and_then(|x| x.to_str())
            .is_some_and(|x| x == "gltf" || x == "glb")
        {
            out.push(p);
        }
    }
}

fn judge(file: &str, report: &Report, verdict: &LoaderVerdict) -> (bool, String) {
    let used: Vec<&(String, String)> = report
        .errors
        .iter()
        .filter(|(_, p)| used_by_loader(p))
        .collect();
    match verdict {
        LoaderVerdict::Error(e) => {
            let ptr = e.pointer().unwrap_or("(none)");
            if let Some((code, vp)) = used
                .iter()
                .find(|(_, vp)| e.pointer().is_some_and(|lp| same_object(lp, vp)))
            {
                let exact = if vp.trim_end_matches('/') == ptr.trim_end_matches('/') {
                    "same pointer"
                } else {
                    "same object"
                };
                (true, format!("agree: both reject ({exact}; {code})"))
            } else if !used.is_empty() {
                (
                    false,
                    format!("DIFFERENT OBJECT: loader `{ptr}`, validator {:?}", used),
                )
            } else if report.errors.is_empty() {
                (
                    false,
                    "LOADER STRICTER: the validator reports no error".into(),
                )
            } else {
                (false, format!("LOADER STRICTER: the validator's errors ({:?}) are in parts the loader does not read", report.errors))
            }
        }
        LoaderVerdict::Loaded { .. } | LoaderVerdict::Empty => {
            if used.is_empty() && report.errors.is_empty() {
                (true, "agree: valid".into())
            } else if used.is_empty() {
                // Not agreement: the validator rejects the file. Legitimate, and labelled so.
                let mut parts: Vec<String> = report
                    .errors
                    .iter()
                    .map(|(_, p)| {
                        let first = p.trim_start_matches('/').split('/').next().unwrap_or("");
                        if first == "materials" {
                            format!(
                                "{p} (a texture reference other than the base colour's, ignored)"
                            )
                        } else {
                            format!("/{first}")
                        }
                    })
                    .collect();
                parts.dedup();
                (
                    true,
                    format!(
                        "disagree (legitimate): the validator's errors are only in {}, which the loader does not read",
                        parts.join(", ")
                    ),
                )
            } else {
                (
                    false,
                    format!("LOADER MISSED: validator errors {used:?} in {file}"),
                )
            }
        }
    }
}

fn verdict_text(v: &LoaderVerdict) -> String {
    match v {
        LoaderVerdict::Loaded {
            instances,
            triangles,
        } => format!("loads: {instances} instances, {triangles} triangles"),
        LoaderVerdict::Empty => "empty scene (no geometry)".into(),
        LoaderVerdict::Error(e) => format!(
            "{} at `{}`",
            e.kind(),
            match e.pointer() {
                Some("") | None => "/",
                Some(p) => p,
            }
        ),
    }
}

fn validator_text(r: &Report) -> String {
    if r.errors.is_empty() {
        return "valid".into();
    }
    let mut parts: Vec<String> = r
        .errors
        .iter()
        .map(|(c, p)| format!("{c} `{}`", if p.is_empty() { "/" } else { p }))
        .collect();
    parts.dedup();
    if parts.len() > 3 {
        let more = parts.len() - 3;
        parts.truncate(3);
        parts.push(format!("+{more} more"));
    }
    parts.join(", ")
}

fn table(rows: &[Row]) -> String {
    let mut s = String::from("| file | validator | loader | agreement |\n|---|---|---|---|\n");
    for r in rows {
        s.push_str(&format!(
            "| {} | {} | {} | {} |\n",
            r.file,
            validator_text(&r.report).replace('|', "\\|"),
            verdict_text(&r.verdict),
            r.agreement.replace('|', "\\|")
        ));
    }
    s
}

const BEGIN: &str = "<!-- validator-table:begin -->";
const END: &str = "<!-- validator-table:end -->";

#[test]
fn loader_agrees_with_the_gltf_validator() {
    let Some(root) = common::test_data("gltf-validator") else {
        return;
    };
    let mut files = Vec::new();
    collect(&root, &mut files);
    files.sort();
    assert!(
        files.len() > 100,
        "expected the validator suite, found {} files",
        files.len()
    );

    let mut rows = Vec::new();
    let mut panics = Vec::new();
    for path in &files {
        let rel = path
            .strip_prefix(&root)
            .unwrap()
            .to_string_lossy()
            .replace('\\', "/");
        let report_path = PathBuf::from(format!("{}.report.json", path.display()));
        let Some(report) = read_report(&report_path) else {
            panic!("{rel}: no readable report at {}", report_path.display());
        };
        let start = Instant::now();
        let result = common::no_panic(|| load_gltf(path, &Limits::default()));
        let took = start.elapsed();
        assert!(
            took < Duration::from_secs(5),
            "{rel}: took {took:?} (a hang?)"
        );
        let verdict = match result {
            Err(msg) => {
                panics.push(format!("{rel}: {msg}"));
                continue;
            }
            Ok(Ok(scene)) => LoaderVerdict::Loaded {
                instances: scene.instances().len(),
                triangles: scene.triangles_drawn(),
            },
            Ok(Err(SceneError::EmptyScene { .. })) => LoaderVerdict::Empty,
            Ok(Err(e)) => {
                // A typed error names the file it came from.
                assert!(
                    e.to_string().contains(&path.display().to_string()),
                    "{rel}: {e}"
                );
                LoaderVerdict::Error(e)
            }
        };
        let (agrees, mut agreement) = judge(&rel, &report, &verdict);
        let known = DISAGREEMENTS.iter().find(|(f, _)| *f == rel);
        if let Some((_, reason)) = known {
            assert!(
                !agrees,
                "{rel} is listed as a disagreement but now agrees: remove it from DISAGREEMENTS"
            );
            agreement = format!("disagree (legitimate): {reason}");
        }
        rows.push(Row {
            file: rel,
            report,
            verdict,
            agreement,
            agrees: agrees || known.is_some(),
        });
    }
    assert!(
        panics.is_empty(),
        "the loader panicked on:\n{}",
        panics.join("\n")
    );

    let md = table(&rows);
    let n_agree = rows
        .iter()
        .filter(|r| r.agreement.starts_with("agree"))
        .count();
    let n_legit = rows
        .iter()
        .filter(|r| r.agreement.starts_with("disagree (legitimate)"))
        .count();
    let n_loaded = rows
        .iter()
        .filter(|r| matches!(r.verdict, LoaderVerdict::Loaded { .. }))
        .count();
    let summary = format!(
        "{} files: {n_agree} agree, {n_legit} legitimate disagreements, {} unexplained; {n_loaded} load with geometry.\n",
        rows.len(),
        rows.len() - n_agree - n_legit,
    );
    println!("{summary}\n{md}");

    let bad: Vec<String> = rows
        .iter()
        .filter(|r| !r.agrees)
        .map(|r| format!("{}: {}", r.file, r.agreement))
        .collect();
    assert!(
        bad.is_empty(),
        "unexplained disagreements:\n{}",
        bad.join("\n")
    );

    // Keep docs/SCENES.md's copy of the table current.
    let docs = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/SCENES.md"));
    let block = format!("{BEGIN}\n{summary}\n{md}{END}");
    let text = std::fs::read_to_string(&docs).unwrap_or_default();
    let (Some(b), Some(e)) = (text.find(BEGIN), text.find(END)) else {
        panic!("{} has no {BEGIN} ... {END} section", docs.display());
    };
    let current = &text[b..e + END.len()];
    if std::env::var_os("TILEGRAPH_BLESS_DOCS").is_some() {
        std::fs::write(&docs, text.replace(current, &block)).unwrap();
    } else {
        assert!(
            current == block,
            "docs/SCENES.md's validator table is stale: rerun with TILEGRAPH_BLESS_DOCS=1"
        );
    }
}

#[test]
fn pointer_matching() {
    assert!(same_object("/accessors/0", "/accessors/0/byteOffset"));
    assert!(same_object("/buffers/0/uri", "/buffers/0"));
    assert!(same_object("", "/"));
    assert!(!same_object("", "/accessors/0"));
    assert!(!same_object("/accessors/1", "/accessors/10"));
    assert!(used_by_loader("/bufferViews/0/byteStride"));
    assert!(!used_by_loader("/images/0/uri"));
    assert!(!used_by_loader("/materials/0/normalTexture/index"));
    assert!(used_by_loader(
        "/materials/0/pbrMetallicRoughness/baseColorTexture/index"
    ));
}
