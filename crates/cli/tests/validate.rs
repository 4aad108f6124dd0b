//! `tilegraph validate` on a game's directory (lavapipe, validation required): a glTF scene of
//! its own with its camera path and a built-in city, two forced profiles. Blessed, it passes;
//! an altered golden fails that check (JUnit `golden`, the frame and its diff written); a
//! camera path that jumps without saying so (no cut) makes single-phase HiZ cull visible
//! instances (JUnit `culling`); bad input names the file.

use std::path::{Path, PathBuf};

mod common;
use common::tilegraph;

fn config(culling: &str, city_path: Option<&str>) -> String {
    let path = city_path.map_or(String::new(), |p| format!("camera_path = \"{p}\"\n"));
    format!(
        "size = \"96x54\"\nframes = 3\nprofiles = [\"mali-valhall\", \"adreno-7xx\"]\n\
         shading = [\"forward\"]\nculling = [\"{culling}\"]\n\n\
         [[scene]]\nfile = \"scenes/gallery.gltf\"\ncamera_path = \"scenes/gallery-camera.json\"\n\n\
         [[scene]]\nname = \"city\"\nspec = \"city:300\"\n{path}"
    )
}

/// The game's directory: the textured gallery (glTF, PNG, JPEG, its camera path) and the
/// config.
fn game_dir(name: &str) -> PathBuf {
    let dir =
        std::env::temp_dir().join(format!("tilegraph-validate-{name}-{}", std::process::id()));
    std::fs::remove_dir_all(&dir).ok();
    tilegraph_e2e::textured::textured_gallery()
        .write_to(&dir.join("scenes"))
        .unwrap();
    std::fs::write(dir.join("validate.toml"), config("hiz-2phase", None)).unwrap();
    dir
}

fn junit(dir: &Path) -> String {
    std::fs::read_to_string(dir.join("validate-out/junit.xml")).unwrap()
}

/// The failures of the JUnit report, as (suite, case, type).
fn failures(xml: &str) -> Vec<(String, String, String)> {
    let doc = roxmltree::Document::parse(xml).unwrap();
    doc.descendants()
        .filter(|n| n.has_tag_name("failure"))
        .map(|f| {
            let case = f.parent().unwrap();
            (
                case.attribute("classname").unwrap().to_string(),
                case.attribute("name").unwrap().to_string(),
                f.attribute("type").unwrap().to_string(),
            )
        })
        .collect()
}

#[test]
fn validate_passes_when_blessed_and_fails_on_an_altered_golden_and_a_miss() {
    let dir = game_dir("flow");
    let d = dir.to_str().unwrap();
    let (ok, out, err) = tilegraph(&["validate", d, "--bless"]);
    assert!(ok, "{out}\n{err}");
    let goldens: Vec<_> = std::fs::read_dir(dir.join("goldens")).unwrap().collect();
    assert_eq!(goldens.len(), 4, "2 scenes x 2 profiles x 1 shading");

    let (ok, out, err) = tilegraph(&["validate", d]);
    assert!(ok, "{out}\n{err}");
    let xml = junit(&dir);
    assert!(failures(&xml).is_empty(), "{xml}");
    // 2 scenes x 2 profiles x (golden-and-lint + hiz-2phase) + 2 teardowns.
    assert!(xml.contains("tests=\"10\" failures=\"0\""), "{xml}");

    // A golden altered: that check fails, and only it; the frame and its diff are written.
    let golden = dir.join("goldens/gallery-mali-valhall-forward.png");
    let mut img = read_png(&golden);
    for p in img.2.chunks_exact_mut(4).take(100) {
        p[0] = p[0].wrapping_add(64);
    }
    write_png(&golden, &img);
    let (ok, _, err) = tilegraph(&["validate", d]);
    assert!(!ok, "an altered golden passed");
    assert!(err.contains("1 of 10 checks failed"), "{err}");
    let f = failures(&junit(&dir));
    assert_eq!(
        f,
        [(
            "gallery".to_string(),
            "mali-valhall/forward/golden-and-lint".to_string(),
            "golden".to_string()
        )]
    );
    for file in [
        "gallery-mali-valhall-forward.png",
        "gallery-mali-valhall-forward-diff.png",
    ] {
        assert!(dir.join("validate-out").join(file).is_file(), "{file}");
    }
    let report = std::fs::read_to_string(dir.join("validate-out/report.md")).unwrap();
    assert!(report.contains("100 pixels differ"), "{report}");

    // Bless again; then the city walked along a path that jumps without a cut, under
    // single-phase HiZ (which trusts last frame's depth): visible instances are culled.
    let (ok, _, err) = tilegraph(&["validate", d, "--bless"]);
    assert!(ok, "{err}");
    std::fs::write(dir.join("jump.json"), jump_path()).unwrap();
    std::fs::write(dir.join("validate.toml"), config("hiz", Some("jump.json"))).unwrap();
    let (ok, out, err) = tilegraph(&["validate", d, "--bless"]);
    assert!(!ok, "a culling that misses passed:\n{out}");
    let f = failures(&junit(&dir));
    println!(
        "{}",
        std::fs::read_to_string(dir.join("validate-out/report.md")).unwrap()
    );
    assert!(!f.is_empty(), "{err}");
    assert!(
        f.iter().all(|(suite, case, kind)| suite == "city"
            && case.ends_with("/hiz/exact")
            && kind == "culling"),
        "{f:?}"
    );
    let summary: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.join("validate-out/summary.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(
        summary["failed"].as_u64(),
        Some(f.len() as u64),
        "{summary}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn bad_input_names_the_file() {
    let dir = game_dir("bad");
    let d = dir.to_str().unwrap();
    // A scene file that is not there.
    let missing = config("hiz-2phase", None).replace("scenes/gallery.gltf", "scenes/nowhere.gltf");
    std::fs::write(dir.join("validate.toml"), missing).unwrap();
    let (ok, _, err) = tilegraph(&["validate", d]);
    assert!(!ok && err.contains("nowhere.gltf"), "{err}");
    // A golden of another size.
    std::fs::write(dir.join("validate.toml"), config("hiz-2phase", None)).unwrap();
    let (ok, _, err) = tilegraph(&["validate", d, "--bless"]);
    assert!(ok, "{err}");
    let golden = dir.join("goldens/city-mali-valhall-forward.png");
    write_png(&golden, &(8, 8, vec![0; 8 * 8 * 4]));
    let (ok, _, err) = tilegraph(&["validate", d]);
    assert!(
        !ok && err.contains("city-mali-valhall-forward.png") && err.contains("8x8"),
        "{err}"
    );
    // An unknown key in the config.
    std::fs::write(dir.join("validate.toml"), "sizes = \"1x1\"\n").unwrap();
    let (ok, _, err) = tilegraph(&["validate", d]);
    assert!(
        !ok && err.contains("validate.toml") && err.contains("sizes"),
        "{err}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// The city's own path, every second key, with its cuts removed: the camera jumps between
/// frames and says nothing.
fn jump_path() -> String {
    let scene = tilegraph_scene::load("city:300").unwrap();
    let keys: Vec<_> = scene
        .camera_path()
        .keys()
        .iter()
        .step_by(40)
        .take(3)
        .map(|k| tilegraph_scene::PathKey {
            camera: k.camera,
            cut: false,
        })
        .collect();
    tilegraph_scene::CameraPath::new("jump", keys)
        .unwrap()
        .to_json()
}

fn read_png(path: &Path) -> (u32, u32, Vec<u8>) {
    let mut r = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()))
        .read_info()
        .unwrap();
    let mut buf = vec![0; r.output_buffer_size()];
    let info = r.next_frame(&mut buf).unwrap();
    buf.truncate(info.buffer_size());
    (info.width, info.height, buf)
}

fn write_png(path: &Path, (w, h, pixels): &(u32, u32, Vec<u8>)) {
    let mut enc = png::Encoder::new(std::fs::File::create(path).unwrap(), *w, *h);
    enc.set_color(png::ColorType::Rgba);
    enc.set_depth(png::BitDepth::Eight);
    let mut wr = enc.write_header().unwrap();
    wr.write_image_data(pixels).unwrap();
    wr.finish().unwrap();
}
