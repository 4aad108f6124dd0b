//! Base-colour textures from glTF: every image source (file, data URI, GLB buffer view), PNG and
//! JPEG, the UV set the material names, samplers, sharing, and the typed errors of images that
//! cannot be used.

use serde_json::{json, Value};
use tilegraph_scene::texture::Wrap;
use tilegraph_scene::{load_gltf_bytes, Limits, MemoryResources, Scene, SceneError};

fn f32s(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// A quad: positions (48 bytes), UV set 0 (32), UV set 1 (32), u16 indices (12).
fn quad_bin() -> Vec<u8> {
    let mut b = f32s(&[0., 0., 0., 1., 0., 0., 1., 0., 1., 0., 0., 1.]);
    b.extend(f32s(&[0., 0., 1., 0., 1., 1., 0., 1.]));
    b.extend(f32s(&[0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5]));
    b.extend([0u16, 2, 1, 0, 3, 2].iter().flat_map(|x| x.to_le_bytes()));
    b
}

fn png(w: u32, h: u32, rgba: [u8; 4]) -> Vec<u8> {
    let mut out = Vec::new();
    let mut enc = png::Encoder::new(&mut out, w, h);
    enc.set_color(png::ColorType::Rgba);
    enc.set_depth(png::BitDepth::Eight);
    let mut writer = enc.write_header().unwrap();
    let data: Vec<u8> = (0..w * h).flat_map(|_| rgba).collect();
    writer.write_image_data(&data).unwrap();
    drop(writer);
    out
}

fn jpeg(w: u16, h: u16, rgb: [u8; 3]) -> Vec<u8> {
    let mut out = Vec::new();
    let data: Vec<u8> = (0..u32::from(w) * u32::from(h)).flat_map(|_| rgb).collect();
    jpeg_encoder::Encoder::new(&mut out, 100)
        .encode(&data, w, h, jpeg_encoder::ColorType::Rgb)
        .unwrap();
    out
}

/// A document drawing the quad twice with materials `materials`; `images`, `textures`,
/// `samplers` as given; buffer 0 is `quad.bin`, and `extra_views` follow the quad's views.
fn doc(materials: Value, textures: Value, images: Value, samplers: Option<Value>) -> Value {
    let mut d = json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0, 1]}],
        "nodes": [{"mesh": 0}, {"mesh": 1, "translation": [2.0, 0.0, 0.0]}],
        "meshes": [
            {"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1, "TEXCOORD_1": 2}, "indices": 3, "material": 0}]},
            {"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1, "TEXCOORD_1": 2}, "indices": 3, "material": 1}]}
        ],
        "materials": materials,
        "textures": textures,
        "images": images,
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3"},
            {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC2"},
            {"bufferView": 1, "byteOffset": 32, "componentType": 5126, "count": 4, "type": "VEC2"},
            {"bufferView": 2, "componentType": 5123, "count": 6, "type": "SCALAR"}
        ],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 48},
            {"buffer": 0, "byteOffset": 48, "byteLength": 64},
            {"buffer": 0, "byteOffset": 112, "byteLength": 12}
        ],
        "buffers": [{"uri": "quad.bin", "byteLength": 124}]
    });
    if let Some(s) = samplers {
        d["samplers"] = s;
    }
    d
}

fn textured(texture: u32, tex_coord: u32) -> Value {
    json!({"pbrMetallicRoughness": {"baseColorTexture": {"index": texture, "texCoord": tex_coord}}})
}

fn load(doc: &Value, files: &[(&str, Vec<u8>)], limits: &Limits) -> Result<Scene, SceneError> {
    let mut res = MemoryResources::default();
    res.files.insert("quad.bin".into(), quad_bin());
    for (name, bytes) in files {
        res.files.insert((*name).into(), bytes.clone());
    }
    load_gltf_bytes(doc.to_string().as_bytes(), "tex.gltf", &res, limits)
}

#[test]
fn png_from_a_file_and_jpeg_from_a_data_uri_are_decoded_and_mipmapped() {
    use base64::Engine;
    let jpg = jpeg(6, 4, [40, 200, 90]);
    let uri = format!(
        "data:image/jpeg;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(&jpg)
    );
    let d = doc(
        json!([textured(0, 0), textured(1, 0)]),
        json!([{"source": 0, "sampler": 0}, {"source": 1}]),
        json!([{"uri": "red%20tile.png"}, {"uri": uri}]),
        Some(json!([{"wrapS": 33071, "wrapT": 33648, "magFilter": 9728, "minFilter": 9985}])),
    );
    let s = load(
        &d,
        &[("red tile.png", png(8, 2, [255, 0, 0, 128]))],
        &Limits::default(),
    )
    .unwrap();
    assert_eq!(s.textures().len(), 2);
    let red = &s.textures()[0];
    assert_eq!((red.width(), red.height(), red.levels().len()), (8, 2, 4));
    assert_eq!(&red.level_pixels(3).unwrap(), &[255, 0, 0, 128]);
    assert_eq!(red.sampler.wrap_u, Wrap::ClampToEdge);
    assert_eq!(red.sampler.wrap_v, Wrap::MirroredRepeat);
    assert!(!red.sampler.mag_linear && red.sampler.min_linear && !red.sampler.mip_linear);
    let green = &s.textures()[1];
    assert_eq!((green.width(), green.height()), (6, 4));
    let px = green.level_pixels(0).unwrap();
    // JPEG is lossy: within a few levels of the flat colour.
    for (got, want) in px[..3].iter().zip([40u8, 200, 90]) {
        assert!(got.abs_diff(want) <= 3, "{:?}", &px[..4]);
    }
    assert_eq!(px[3], 255);
    let mats: Vec<_> = s.materials().iter().map(|m| m.base_color_texture).collect();
    assert_eq!(
        mats,
        [
            Some(tilegraph_scene::TextureId(0)),
            Some(tilegraph_scene::TextureId(1))
        ]
    );
    assert_eq!(
        s.texture_bytes(),
        (red.byte_size() + green.byte_size()) as u64
    );
    assert_eq!(s.info().textures, 2);
}

/// A GLB's image in a buffer view; two materials sharing one texture make one texture; the
/// material's texCoord 1 picks the second UV set.
#[test]
fn buffer_view_images_are_shared_and_tex_coord_picks_the_uv_set() {
    let image = png(2, 2, [0, 0, 255, 255]);
    let mut bin = quad_bin();
    let offset = bin.len();
    bin.extend(&image);
    let mut d = doc(
        json!([textured(0, 1), textured(0, 1)]),
        json!([{"source": 0}]),
        json!([{"bufferView": 3, "mimeType": "image/png"}]),
        None,
    );
    d["bufferViews"]
        .as_array_mut()
        .unwrap()
        .push(json!({"buffer": 0, "byteOffset": offset, "byteLength": image.len()}));
    d["buffers"][0]["byteLength"] = json!(bin.len());
    let mut res = MemoryResources::default();
    res.files.insert("quad.bin".into(), bin);
    let s = load_gltf_bytes(
        d.to_string().as_bytes(),
        "tex.gltf",
        &res,
        &Limits::default(),
    )
    .unwrap();
    assert_eq!(s.textures().len(), 1);
    assert!(
        s.vertices().iter().all(|v| v.uv == [0.5, 0.5]),
        "TEXCOORD_1 read"
    );
}

#[track_caller]
fn expect_image_err(result: Result<Scene, SceneError>, kind: &str, pointer: &str) {
    match result {
        Ok(_) => panic!("expected a {kind} error at {pointer}"),
        Err(e) => {
            assert_eq!((e.kind(), e.pointer()), (kind, Some(pointer)), "{e}");
            assert!(e.to_string().contains("tex.gltf"), "{e}");
        }
    }
}

#[test]
fn unusable_images_are_typed_errors_naming_the_image() {
    let one = |images: Value| {
        doc(
            json!([textured(0, 0), {}]),
            json!([{"source": 0}]),
            images,
            None,
        )
    };
    let lim = Limits::default();
    expect_image_err(
        load(&one(json!([{"uri": "gone.png"}])), &[], &lim),
        "image",
        "/images/0/uri",
    );
    expect_image_err(
        load(
            &one(json!([{"uri": "x.png"}])),
            &[("x.png", b"\x89PNG\r\n\x1a\n broken".to_vec())],
            &lim,
        ),
        "image",
        "/images/0",
    );
    expect_image_err(
        load(
            &one(json!([{"uri": "x.bin"}])),
            &[("x.bin", b"GIF89a".to_vec())],
            &lim,
        ),
        "image",
        "/images/0",
    );
    expect_image_err(
        load(
            &one(json!([{"uri": "x.webp", "mimeType": "image/webp"}])),
            &[],
            &lim,
        ),
        "image",
        "/images/0/mimeType",
    );
    expect_image_err(
        load(&one(json!([{"uri": "../x.png"}])), &[], &lim),
        "image",
        "/images/0/uri",
    );
    expect_image_err(
        load(
            &one(json!([{"uri": "https://example.com/x.png"}])),
            &[],
            &lim,
        ),
        "image",
        "/images/0/uri",
    );
    let small = Limits {
        max_texture_pixels: 15,
        ..Limits::default()
    };
    expect_image_err(
        load(
            &one(json!([{"uri": "x.png"}])),
            &[("x.png", png(4, 4, [0; 4]))],
            &small,
        ),
        "image",
        "/images/0",
    );
    // Two images of 16 pixels each under a limit of 20 in all: the second is refused, named.
    let two = doc(
        json!([textured(0, 0), textured(1, 0)]),
        json!([{"source": 0}, {"source": 1}]),
        json!([{"uri": "x.png"}, {"uri": "x.png"}]),
        None,
    );
    let total = Limits {
        max_texture_pixels_total: 20,
        ..Limits::default()
    };
    let files = [("x.png", png(4, 4, [0; 4]))];
    expect_image_err(load(&two, &files, &total), "image", "/images/1");
    assert!(load(&two, &files, &lim).is_ok());
    let missing_texture = doc(
        json!([textured(3, 0), {}]),
        json!([{"source": 0}]),
        json!([{"uri": "x.png"}]),
        None,
    );
    expect_image_err(
        load(&missing_texture, &[], &lim),
        "unresolved-reference",
        "/materials/0/pbrMetallicRoughness/baseColorTexture/index",
    );
}

/// Images no material's base colour reaches are never read: a broken normal map or an unused
/// image does not fail the load.
#[test]
fn images_no_base_colour_reaches_are_not_read() {
    let d = doc(
        json!([{"normalTexture": {"index": 0}}, {}]),
        json!([{"source": 0}]),
        json!([{"uri": "gone.png"}]),
        None,
    );
    let s = load(&d, &[], &Limits::default()).unwrap();
    assert!(s.textures().is_empty());
}
