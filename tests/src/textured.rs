//! A small textured glTF scene made by the tests (no third-party asset): a checkered floor whose
//! texture repeats eight times (minification and mip selection at a grazing angle), a gradient
//! panel from a JPEG of odd size with clamped edges, an alpha-tested panel cut by a PNG's
//! alpha (a data URI), a blended striped panel, and an untextured box. Every image source the
//! loader reads but the GLB buffer view: files, a data URI; PNG and JPEG.

use std::path::{Path, PathBuf};

use serde_json::{json, Value};
use tilegraph_scene::{
    load_gltf_bytes, Camera, CameraPath, Limits, MemoryResources, PathKey, Scene,
};

/// The document and the files beside it.
pub struct TexturedAsset {
    pub gltf: Vec<u8>,
    pub files: Vec<(String, Vec<u8>)>,
}

/// Two views of the gallery: from the near edge of the floor at eye height looking at the
/// panels (the floor's checker recedes to the horizon), and from low beside the panels.
pub fn gallery_camera_path() -> CameraPath {
    let key = |eye: [f64; 3], target: [f64; 3]| PathKey {
        camera: Camera::looking_at(eye.into(), target.into()),
        cut: true,
    };
    CameraPath::new(
        "gallery",
        vec![
            key([0.4, 1.6, 5.5], [0.0, 0.7, -1.5]),
            key([4.5, 0.5, 2.5], [-1.0, 0.8, -1.0]),
        ],
    )
    .expect("a valid path")
}

impl TexturedAsset {
    /// Loaded from memory, with [`gallery_camera_path`].
    pub fn load(&self) -> Scene {
        let mut res = MemoryResources::default();
        for (name, bytes) in &self.files {
            res.files.insert(name.clone(), bytes.clone());
        }
        let mut scene = load_gltf_bytes(&self.gltf, "gallery.gltf", &res, &Limits::default())
            .expect("the textured gallery loads");
        scene.set_camera_path(gallery_camera_path());
        scene
    }

    /// Written into `dir` as `gallery.gltf`, its files and `gallery-camera.json` (the camera
    /// path, for `--camera-path`); the .gltf's path.
    pub fn write_to(&self, dir: &Path) -> std::io::Result<PathBuf> {
        std::fs::create_dir_all(dir)?;
        for (name, bytes) in &self.files {
            std::fs::write(dir.join(name), bytes)?;
        }
        std::fs::write(
            dir.join("gallery-camera.json"),
            gallery_camera_path().to_json(),
        )?;
        let path = dir.join("gallery.gltf");
        std::fs::write(&path, &self.gltf)?;
        Ok(path)
    }
}

fn png(w: u32, h: u32, texel: impl Fn(u32, u32) -> [u8; 4]) -> Vec<u8> {
    let data: Vec<u8> = (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .flat_map(|(x, y)| texel(x, y))
        .collect();
    let mut out = Vec::new();
    let mut enc = png::Encoder::new(&mut out, w, h);
    enc.set_color(png::ColorType::Rgba);
    enc.set_depth(png::BitDepth::Eight);
    let mut writer = enc.write_header().expect("png header");
    writer.write_image_data(&data).expect("png data");
    drop(writer);
    out
}

fn jpeg(w: u16, h: u16, texel: impl Fn(u32, u32) -> [u8; 3]) -> Vec<u8> {
    let data: Vec<u8> = (0..u32::from(h))
        .flat_map(|y| (0..u32::from(w)).map(move |x| (x, y)))
        .flat_map(|(x, y)| texel(x, y))
        .collect();
    let mut out = Vec::new();
    jpeg_encoder::Encoder::new(&mut out, 95)
        .encode(&data, w, h, jpeg_encoder::ColorType::Rgb)
        .expect("jpeg");
    out
}

/// One mesh: positions, normals, UVs, indices, material.
struct Part {
    positions: Vec<[f32; 3]>,
    normals: Vec<[f32; 3]>,
    uvs: Vec<[f32; 2]>,
    indices: Vec<u16>,
    material: u32,
}

/// A quad from corner `o` along `u` and `v`, UVs 0..`tiles` (v down the image, as glTF).
fn quad(o: [f32; 3], u: [f32; 3], v: [f32; 3], tiles: f32, material: u32) -> Part {
    let at = |a: f32, b: f32| {
        [
            o[0] + u[0] * a + v[0] * b,
            o[1] + u[1] * a + v[1] * b,
            o[2] + u[2] * a + v[2] * b,
        ]
    };
    let n = [
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    ];
    let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    let n = [n[0] / len, n[1] / len, n[2] / len];
    Part {
        positions: vec![at(0., 0.), at(1., 0.), at(1., 1.), at(0., 1.)],
        normals: vec![n; 4],
        uvs: vec![[0., tiles], [tiles, tiles], [tiles, 0.], [0., 0.]],
        indices: vec![0, 1, 2, 0, 2, 3],
        material,
    }
}

/// An axis-aligned box, faces outward.
fn cuboid(min: [f32; 3], max: [f32; 3], material: u32) -> Part {
    let d = [max[0] - min[0], max[1] - min[1], max[2] - min[2]];
    let faces = [
        quad(
            [min[0], min[1], max[2]],
            [d[0], 0., 0.],
            [0., d[1], 0.],
            1.,
            material,
        ),
        quad(
            [max[0], min[1], min[2]],
            [-d[0], 0., 0.],
            [0., d[1], 0.],
            1.,
            material,
        ),
        quad(
            [max[0], min[1], max[2]],
            [0., 0., -d[2]],
            [0., d[1], 0.],
            1.,
            material,
        ),
        quad(
            [min[0], min[1], min[2]],
            [0., 0., d[2]],
            [0., d[1], 0.],
            1.,
            material,
        ),
        quad(
            [min[0], max[1], max[2]],
            [d[0], 0., 0.],
            [0., 0., -d[2]],
            1.,
            material,
        ),
        quad(
            [min[0], min[1], min[2]],
            [d[0], 0., 0.],
            [0., 0., d[2]],
            1.,
            material,
        ),
    ];
    let mut part = Part {
        positions: Vec::new(),
        normals: Vec::new(),
        uvs: Vec::new(),
        indices: Vec::new(),
        material,
    };
    for f in faces {
        let base = part.positions.len() as u16;
        part.positions.extend(f.positions);
        part.normals.extend(f.normals);
        part.uvs.extend(f.uvs);
        part.indices.extend(f.indices.iter().map(|i| i + base));
    }
    part
}

/// The gallery (see the module docs).
pub fn textured_gallery() -> TexturedAsset {
    use base64::Engine;
    let checker = png(64, 64, |x, y| {
        if y < 4 {
            [40, 80, 220, 255]
        } else if ((x / 8) + (y / 8)).is_multiple_of(2) {
            [200, 60, 40, 255]
        } else {
            [240, 220, 180, 255]
        }
    });
    let gradient = jpeg(48, 40, |x, y| {
        [(x * 255 / 47) as u8, (y * 255 / 39) as u8, 128]
    });
    let leaf = png(32, 32, |x, y| {
        let (dx, dy) = (x as f32 - 15.5, y as f32 - 15.5);
        let r = (dx * dx + dy * dy).sqrt();
        let a = if (r as u32 / 3).is_multiple_of(2) && r < 15.0 {
            255
        } else {
            0
        };
        [30, 120 + (x * 4) as u8, 40, a]
    });
    let stripes = png(16, 16, |x, _| {
        if (x / 4).is_multiple_of(2) {
            [250, 220, 40, 200]
        } else {
            [120, 40, 160, 90]
        }
    });
    let leaf_uri = format!(
        "data:image/png;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(&leaf)
    );
    let parts = [
        quad([-6., 0., 6.], [12., 0., 0.], [0., 0., -12.], 8., 0),
        quad([-4., 0., -2.], [2.5, 0., 0.], [0., 2., 0.], 1., 1),
        quad([-0.8, 0., -1.], [2., 0., 0.], [0., 2., 0.], 1., 2),
        quad([2., 0., 0.], [2., 0., -1.], [0., 2., 0.], 1., 3),
        cuboid([-1.5, 0., 1.], [-0.5, 1., 2.], 4),
    ];
    let mut bin: Vec<u8> = Vec::new();
    let mut views = Vec::new();
    let mut accessors = Vec::new();
    let mut meshes = Vec::new();
    let mut view = |bin: &mut Vec<u8>, bytes: Vec<u8>| {
        while !bin.len().is_multiple_of(4) {
            bin.push(0);
        }
        views.push(json!({"buffer": 0, "byteOffset": bin.len(), "byteLength": bytes.len()}));
        bin.extend(bytes);
        views.len() - 1
    };
    for p in &parts {
        let f32s = |v: &[f32]| -> Vec<u8> { v.iter().flat_map(|x| x.to_le_bytes()).collect() };
        let flat3: Vec<f32> = p.positions.iter().flatten().copied().collect();
        let (mut lo, mut hi) = ([f32::MAX; 3], [f32::MIN; 3]);
        for q in &p.positions {
            for c in 0..3 {
                lo[c] = lo[c].min(q[c]);
                hi[c] = hi[c].max(q[c]);
            }
        }
        let pv = view(&mut bin, f32s(&flat3));
        let nv = view(
            &mut bin,
            f32s(&p.normals.iter().flatten().copied().collect::<Vec<_>>()),
        );
        let uv = view(
            &mut bin,
            f32s(&p.uvs.iter().flatten().copied().collect::<Vec<_>>()),
        );
        let iv = view(
            &mut bin,
            p.indices.iter().flat_map(|i| i.to_le_bytes()).collect(),
        );
        let n = p.positions.len();
        let a = accessors.len();
        accessors.push(json!({"bufferView": pv, "componentType": 5126, "count": n, "type": "VEC3", "min": lo, "max": hi}));
        accessors
            .push(json!({"bufferView": nv, "componentType": 5126, "count": n, "type": "VEC3"}));
        accessors
            .push(json!({"bufferView": uv, "componentType": 5126, "count": n, "type": "VEC2"}));
        accessors.push(json!({"bufferView": iv, "componentType": 5123, "count": p.indices.len(), "type": "SCALAR"}));
        meshes.push(json!({"primitives": [{"attributes": {"POSITION": a, "NORMAL": a + 1, "TEXCOORD_0": a + 2}, "indices": a + 3, "material": p.material}]}));
    }
    let textured = |t: u32| json!({"baseColorTexture": {"index": t}});
    let doc: Value = json!({
        "asset": {"version": "2.0", "generator": "tilegraph tests (textured gallery)"},
        "scene": 0,
        "scenes": [{"nodes": (0..parts.len()).collect::<Vec<_>>()}],
        "nodes": (0..parts.len()).map(|m| json!({"mesh": m})).collect::<Vec<_>>(),
        "meshes": meshes,
        "materials": [
            {"name": "checker floor", "pbrMetallicRoughness": textured(0)},
            {"name": "gradient", "pbrMetallicRoughness": textured(1), "doubleSided": true},
            {"name": "leaf", "alphaMode": "MASK", "alphaCutoff": 0.5, "doubleSided": true,
             "pbrMetallicRoughness": textured(2)},
            {"name": "stripes", "alphaMode": "BLEND", "doubleSided": true,
             "pbrMetallicRoughness": {"baseColorTexture": {"index": 3}, "baseColorFactor": [1.0, 1.0, 1.0, 0.9]}},
            {"name": "plain", "pbrMetallicRoughness": {"baseColorFactor": [0.3, 0.6, 0.9, 1.0]}}
        ],
        "textures": [
            {"source": 0, "sampler": 0},
            {"source": 1, "sampler": 1},
            {"source": 2, "sampler": 0},
            {"source": 3, "sampler": 0}
        ],
        "samplers": [
            {},
            {"wrapS": 33071, "wrapT": 33071}
        ],
        "images": [
            {"uri": "checker.png"},
            {"uri": "gradient.jpg"},
            {"uri": leaf_uri},
            {"uri": "stripes.png", "mimeType": "image/png"}
        ],
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{"uri": "gallery.bin", "byteLength": bin.len()}]
    });
    TexturedAsset {
        gltf: serde_json::to_vec_pretty(&doc).expect("json"),
        files: vec![
            ("gallery.bin".into(), bin),
            ("checker.png".into(), checker),
            ("gradient.jpg".into(), gradient),
            ("stripes.png".into(), stripes),
        ],
    }
}
