//! Hand-built glTF files: what must load (strips, fans, missing normals and UVs, sparse
//! accessors, hierarchies, every buffer source) and what must fail with a typed error naming the
//! element (missing/truncated buffers, out-of-range accessors and indices, NaN and infinity,
//! loops, empty scenes, files that are not glTF).

use glam::{DVec3, Vec3};
use serde_json::{json, Value};
use tilegraph_scene::{
    load_gltf_bytes, Limits, MaterialClass, MemoryResources, NoResources, Scene, SceneError,
};

/// Little-endian bytes of f32s / u16s / u32s.
fn f32s(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}
fn u16s(v: &[u16]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// A unit quad in the xz plane: 4 positions (48 bytes), 4 normals (48), 6 u16 indices (12).
fn quad_bin() -> Vec<u8> {
    let mut b = f32s(&[0., 0., 0., 1., 0., 0., 1., 0., 1., 0., 0., 1.]);
    b.extend(f32s(&[0., 1., 0., 0., 1., 0., 0., 1., 0., 0., 1., 0.]));
    b.extend(u16s(&[0, 2, 1, 0, 3, 2]));
    b
}

/// The quad's document with an external buffer `quad.bin`.
fn quad_doc() -> Value {
    json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "translation": [10.0, 0.0, 0.0]}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1}, "indices": 2, "material": 0}]}],
        "materials": [{"alphaMode": "MASK", "alphaCutoff": 0.25, "doubleSided": true,
                       "pbrMetallicRoughness": {"baseColorFactor": [1.0, 0.5, 0.25, 1.0]}}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3"},
            {"bufferView": 0, "byteOffset": 48, "componentType": 5126, "count": 4, "type": "VEC3"},
            {"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"}
        ],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 96},
            {"buffer": 0, "byteOffset": 96, "byteLength": 12}
        ],
        "buffers": [{"uri": "quad.bin", "byteLength": 108}]
    })
}

fn load_doc(doc: &Value, bin: &[u8]) -> Result<Scene, SceneError> {
    let mut res = MemoryResources::default();
    res.files.insert("quad.bin".into(), bin.to_vec());
    load_gltf_bytes(
        doc.to_string().as_bytes(),
        "quad.gltf",
        &res,
        &Limits::default(),
    )
}

fn glb(doc: &Value, bin: &[u8]) -> Vec<u8> {
    let mut doc = doc.clone();
    doc["buffers"][0].as_object_mut().unwrap().remove("uri");
    let json = doc.to_string();
    let mut json = json.into_bytes();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let mut bin = bin.to_vec();
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut out = b"glTF".to_vec();
    out.extend(2u32.to_le_bytes());
    out.extend((total as u32).to_le_bytes());
    out.extend((json.len() as u32).to_le_bytes());
    out.extend(b"JSON");
    out.extend(json);
    out.extend((bin.len() as u32).to_le_bytes());
    out.extend(b"BIN\0");
    out.extend(bin);
    out
}

/// Asserts `result` is the error `kind` at `pointer`, and that its message names the file.
#[track_caller]
fn expect_err(result: Result<Scene, SceneError>, kind: &str, pointer: Option<&str>) -> SceneError {
    match result {
        Ok(s) => panic!(
            "expected a {kind} error, loaded {} instances",
            s.instances().len()
        ),
        Err(e) => {
            assert_eq!(e.kind(), kind, "{e}");
            if let Some(p) = pointer {
                assert_eq!(e.pointer(), Some(p), "{e}");
            }
            e
        }
    }
}

#[test]
fn the_quad_loads_from_every_buffer_source() {
    let doc = quad_doc();
    let bin = quad_bin();
    let external = load_doc(&doc, &bin).unwrap();
    let from_glb = load_gltf_bytes(
        &glb(&doc, &bin),
        "quad.glb",
        &NoResources,
        &Limits::default(),
    )
    .unwrap();
    let mut data_uri = doc.clone();
    use base64::Engine as _;
    data_uri["buffers"][0]["uri"] = json!(format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(&bin)
    ));
    let embedded = load_gltf_bytes(
        data_uri.to_string().as_bytes(),
        "q.gltf",
        &NoResources,
        &Limits::default(),
    )
    .unwrap();
    for s in [&external, &from_glb, &embedded] {
        let info = s.info();
        assert_eq!((info.instances, info.meshes, info.triangles), (1, 1, 2));
        assert_eq!(info.materials.alpha_tested, 1);
        let m = s.materials()[0];
        assert_eq!(m.class, MaterialClass::AlphaTested { cutoff: 0.25 });
        assert!(m.double_sided);
        assert_eq!(m.base_color, [1.0, 0.5, 0.25, 1.0]);
        // The quad's box, grown by a few f32 ulps (bounds enclose what the GPU draws).
        let b = s.bounds();
        let near = |a: DVec3, b: DVec3| (a - b).abs().max_element() < 1e-5;
        assert!(near(b.min, DVec3::new(10.0, 0.0, 0.0)), "{b:?}");
        assert!(near(b.max, DVec3::new(11.0, 0.0, 1.0)), "{b:?}");
        assert!(b.min.cmple(DVec3::new(10.0, 0.0, 0.0)).all());
        assert!(b.max.cmpge(DVec3::new(11.0, 0.0, 1.0)).all());
        // Missing TEXCOORD_0: zeros.
        assert!(s.vertices().iter().all(|v| v.uv == [0.0, 0.0]));
        assert_eq!(s.meshes()[0].local_aabb.max, Vec3::new(1.0, 0.0, 1.0));
    }
}

#[test]
fn hierarchy_composes_and_meshes_split_into_primitives() {
    let mut doc = quad_doc();
    // A parent that scales by 2 and turns 90 degrees about y; the mesh gets a second primitive.
    doc["nodes"] = json!([
        {"children": [1], "scale": [2.0, 2.0, 2.0], "rotation": [0.0, 0.70710677, 0.0, 0.70710677]},
        {"mesh": 0, "translation": [1.0, 0.0, 0.0]}
    ]);
    doc["meshes"][0]["primitives"] = json!([
        {"attributes": {"POSITION": 0, "NORMAL": 1}, "indices": 2},
        {"attributes": {"POSITION": 0, "NORMAL": 1}, "indices": 2, "material": 0}
    ]);
    let s = load_doc(&doc, &quad_bin()).unwrap();
    let c = s.gltf_counts().unwrap();
    assert_eq!(
        (c.nodes, c.meshes, c.primitives, c.nodes_in_scene),
        (2, 1, 2, 2)
    );
    assert_eq!(s.instances().len(), 2, "one instance per primitive");
    assert_eq!(s.meshes().len(), 2);
    // The two primitives share the vertex accessors, so they share vertices.
    assert_eq!(s.vertices().len(), 4);
    assert_eq!(s.meshes()[0].vertex_offset, s.meshes()[1].vertex_offset);
    // Default material appended for the primitive without one.
    assert_eq!(s.materials().len(), 2);
    // Local (1,0,0) -> parent: rotate 90 about y -> (0,0,-1), scale 2 -> (0,0,-2).
    let t = s.instances()[0].transform;
    assert!(
        (t.translation - DVec3::new(0.0, 0.0, -2.0)).length() < 1e-6,
        "{:?}",
        t.translation
    );
    let corner = t.transform_point(Vec3::new(1.0, 0.0, 1.0));
    assert!(
        (corner - DVec3::new(2.0, 0.0, -4.0)).length() < 1e-5,
        "{corner:?}"
    );
}

#[test]
fn strips_fans_and_unindexed_primitives_load_with_computed_normals() {
    let mut doc = quad_doc();
    // Positions only, no indices: 4 vertices as a strip (2 triangles) and as a fan (2).
    for (mode, tris) in [(5, 2), (6, 2), (4, 1)] {
        doc["meshes"][0]["primitives"] = json!([{"attributes": {"POSITION": 0}, "mode": mode}]);
        let s = load_doc(&doc, &quad_bin()).unwrap();
        assert_eq!(s.triangles_drawn(), tris, "mode {mode}");
        // Flat normals: one vertex per corner, each normal perpendicular to the quad.
        assert_eq!(s.vertices().len() as u64, 3 * tris);
        for v in s.vertices() {
            assert!(
                (Vec3::from_array(v.normal).abs() - Vec3::Y).length() < 1e-6,
                "{:?}",
                v.normal
            );
        }
    }
    // Points and lines are skipped; with nothing else the scene is empty.
    doc["meshes"][0]["primitives"] = json!([{"attributes": {"POSITION": 0}, "mode": 1}]);
    expect_err(load_doc(&doc, &quad_bin()), "empty-scene", None);
}

#[test]
fn sparse_accessors_and_small_index_types_load() {
    let mut bin = quad_bin();
    // Sparse: replace vertex 2's position with (1, 5, 1): index u8 [2] at 108, value at 112.
    bin.extend([2u8, 0, 0, 0]);
    bin.extend(f32s(&[1.0, 5.0, 1.0]));
    // u8 indices at 124.
    bin.extend([0u8, 2, 1, 0, 3, 2, 0, 0]);
    let mut doc = quad_doc();
    doc["buffers"][0]["byteLength"] = json!(bin.len());
    doc["bufferViews"] = json!([
        {"buffer": 0, "byteOffset": 0, "byteLength": 96},
        {"buffer": 0, "byteOffset": 96, "byteLength": 12},
        {"buffer": 0, "byteOffset": 108, "byteLength": 16},
        {"buffer": 0, "byteOffset": 124, "byteLength": 6}
    ]);
    doc["accessors"][0]["sparse"] = json!({"count": 1,
        "indices": {"bufferView": 2, "componentType": 5121},
        "values": {"bufferView": 2, "byteOffset": 4}});
    doc["accessors"][2] =
        json!({"bufferView": 3, "componentType": 5121, "count": 6, "type": "SCALAR"});
    let s = load_doc(&doc, &bin).unwrap();
    let max_y = s.bounds().max.y;
    assert!((5.0..5.0 + 1e-5).contains(&max_y), "{max_y}");
    assert_eq!(s.triangles_drawn(), 2);
}

#[test]
fn bad_buffers_name_the_buffer() {
    let doc = quad_doc();
    let bin = quad_bin();
    // Missing external file.
    let e = expect_err(
        load_gltf_bytes(
            doc.to_string().as_bytes(),
            "quad.gltf",
            &NoResources,
            &Limits::default(),
        ),
        "buffer",
        Some("/buffers/0/uri"),
    );
    assert!(e.to_string().starts_with("quad.gltf: "), "{e}");
    // Truncated external file.
    expect_err(load_doc(&doc, &bin[..100]), "buffer", Some("/buffers/0"));
    // Truncated GLB BIN chunk (byteLength larger than the chunk): the header no longer matches.
    let g = glb(&doc, &bin);
    expect_err(
        load_gltf_bytes(
            &g[..g.len() - 8],
            "quad.glb",
            &NoResources,
            &Limits::default(),
        ),
        "glb",
        Some(""),
    );
    // A GLB whose JSON wants more bytes than its BIN chunk has.
    let mut d = doc.clone();
    d["buffers"][0]["byteLength"] = json!(200);
    expect_err(
        load_gltf_bytes(&glb(&d, &bin), "quad.glb", &NoResources, &Limits::default()),
        "buffer",
        Some("/buffers/0"),
    );
    // A placeholder buffer that is used.
    let mut d = doc.clone();
    d["buffers"][0].as_object_mut().unwrap().remove("uri");
    expect_err(load_doc(&d, &bin), "buffer", Some("/buffers/0"));
}

#[test]
fn out_of_range_accessors_views_and_indices_are_caught_before_reading() {
    let bin = quad_bin();
    let mut d = quad_doc();
    d["accessors"][0]["count"] = json!(40);
    expect_err(load_doc(&d, &bin), "out-of-bounds", Some("/accessors/0"));

    let mut d = quad_doc();
    d["bufferViews"][1]["byteLength"] = json!(4000);
    expect_err(
        load_doc(&d, &bin),
        "out-of-bounds",
        Some("/bufferViews/1/byteLength"),
    );

    let mut d = quad_doc();
    d["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = json!(9);
    expect_err(
        load_doc(&d, &bin),
        "unresolved-reference",
        Some("/meshes/0/primitives/0/attributes/POSITION"),
    );

    let mut d = quad_doc();
    d["meshes"][0]["primitives"][0]["indices"] = json!(3);
    expect_err(
        load_doc(&d, &bin),
        "unresolved-reference",
        Some("/meshes/0/primitives/0/indices"),
    );

    // An index (7) past the 4 vertices.
    let mut b = bin.clone();
    b[96 + 2..96 + 4].copy_from_slice(&7u16.to_le_bytes());
    let e = expect_err(
        load_doc(&quad_doc(), &b),
        "index-out-of-range",
        Some("/meshes/0/primitives/0/indices"),
    );
    assert!(matches!(
        e,
        SceneError::IndexOutOfRange {
            index: 7,
            position: 1,
            vertex_count: 4,
            ..
        }
    ));

    // Positions that are not VEC3 floats.
    let mut d = quad_doc();
    d["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = json!(2);
    expect_err(
        load_doc(&d, &bin),
        "invalid",
        Some("/meshes/0/primitives/0/attributes/POSITION"),
    );

    // Offsets near u64::MAX on a placeholder buffer (its byteLength is never checked against
    // bytes): must be an error, not an overflow.
    let huge = json!({"asset": {"version": "2.0"},
        "buffers": [{"byteLength": 18446744073709551615u64}],
        "bufferViews": [{"buffer": 0, "byteOffset": 18446744073709551000u64, "byteLength": 600}],
        "accessors": [{"bufferView": 0, "byteOffset": 18446744073709551000u64, "componentType": 5126,
                       "count": 1, "type": "VEC3"}]});
    expect_err(
        load_gltf_bytes(
            huge.to_string().as_bytes(),
            "huge.gltf",
            &NoResources,
            &Limits::default(),
        ),
        "out-of-bounds",
        Some("/accessors/0/byteOffset"),
    );

    // Attribute counts that differ.
    let mut d = quad_doc();
    d["accessors"][1]["count"] = json!(3);
    expect_err(
        load_doc(&d, &bin),
        "invalid",
        Some("/meshes/0/primitives/0/attributes/NORMAL"),
    );
}

#[test]
fn non_finite_values_are_errors_not_nans_in_the_scene() {
    let bin = quad_bin();
    // 1e39 overflows f32: an infinite translation.
    let mut d = quad_doc();
    d["nodes"][0]["translation"] = json!([1e39, 0.0, 0.0]);
    expect_err(
        load_doc(&d, &bin),
        "non-finite",
        Some("/nodes/0/translation"),
    );
    let mut d = quad_doc();
    d["nodes"][0] = json!({"mesh": 0, "matrix": [1,0,0,0, 0,1e39,0,0, 0,0,1,0, 0,0,0,1]});
    expect_err(load_doc(&d, &bin), "non-finite", Some("/nodes/0/matrix"));
    let mut d = quad_doc();
    d["nodes"][0]["rotation"] = json!([0.0, 0.0, 0.0, 0.0]);
    expect_err(load_doc(&d, &bin), "invalid", Some("/nodes/0/rotation"));
    // A world transform that overflows through the hierarchy.
    let mut d = quad_doc();
    d["nodes"] = json!([{"children": [1], "scale": [1e30, 1e30, 1e30]}, {"mesh": 0, "scale": [1e30, 1e30, 1e30]}]);
    expect_err(load_doc(&d, &bin), "non-finite", Some("/nodes/1"));
    // NaN and infinity in the position data.
    for bad in [f32::NAN, f32::INFINITY] {
        let mut b = bin.clone();
        b[16..20].copy_from_slice(&bad.to_le_bytes());
        let e = expect_err(
            load_doc(&quad_doc(), &b),
            "non-finite",
            Some("/accessors/0"),
        );
        assert!(e.to_string().contains("/meshes/0/primitives/0"), "{e}");
    }
}

#[test]
fn broken_hierarchies_and_scenes() {
    let bin = quad_bin();
    let mut d = quad_doc();
    d["scenes"] = json!([{"nodes": []}]);
    expect_err(load_doc(&d, &bin), "invalid", Some("/scenes/0/nodes"));
    // A loop is found whether or not a scene reaches it.
    d["nodes"] = json!([{"children": [1]}, {"children": [0], "mesh": 0}]);
    d.as_object_mut().unwrap().remove("scenes");
    d.as_object_mut().unwrap().remove("scene");
    expect_err(load_doc(&d, &bin), "hierarchy", None);

    let mut d = quad_doc();
    d["nodes"] = json!([{"children": [2]}, {"children": [2]}, {"mesh": 0}]);
    d["scenes"] = json!([{"nodes": [0, 1]}]);
    expect_err(load_doc(&d, &bin), "hierarchy", Some("/nodes/1/children/0"));

    let mut d = quad_doc();
    d["scenes"] = json!([{"nodes": [0, 0]}]);
    expect_err(load_doc(&d, &bin), "invalid", Some("/scenes/0/nodes/1"));

    let mut d = quad_doc();
    d["scene"] = json!(3);
    expect_err(load_doc(&d, &bin), "unresolved-reference", Some("/scene"));

    // No mesh anywhere: the empty-scene error.
    let mut d = quad_doc();
    d["nodes"] = json!([{"name": "empty"}]);
    let e = expect_err(load_doc(&d, &bin), "empty-scene", None);
    assert!(e.to_string().contains("quad.gltf"), "{e}");
}

#[test]
fn files_that_are_not_gltf() {
    let none = NoResources;
    let l = Limits::default();
    expect_err(
        load_gltf_bytes(b"\x89PNG\r\n\x1a\n....", "x.gltf", &none, &l),
        "not-gltf",
        Some(""),
    );
    expect_err(load_gltf_bytes(b"", "x.gltf", &none, &l), "json", Some(""));
    expect_err(
        load_gltf_bytes(b"{\"asset\": ", "x.gltf", &none, &l),
        "json",
        Some(""),
    );
    expect_err(
        load_gltf_bytes(b"[1, 2]", "x.gltf", &none, &l),
        "invalid",
        Some(""),
    );
    expect_err(
        load_gltf_bytes(b"{\"asset\": {\"version\": \"1.0\"}}", "x.gltf", &none, &l),
        "invalid",
        Some("/asset/version"),
    );
    expect_err(
        load_gltf_bytes(b"glTF\x01\0\0\0", "x.glb", &none, &l),
        "glb",
        Some(""),
    );
    expect_err(
        load_gltf_bytes(b"PK\x03\x04", "x.glb", &none, &l),
        "glb",
        Some(""),
    );
    let required = json!({"asset": {"version": "2.0"}, "extensionsUsed": ["KHR_draco_mesh_compression"],
        "extensionsRequired": ["KHR_draco_mesh_compression"]});
    expect_err(
        load_gltf_bytes(required.to_string().as_bytes(), "x.gltf", &none, &l),
        "unsupported-extension",
        Some("/extensionsRequired/0"),
    );
}

#[test]
fn limits_stop_hostile_counts_before_allocating() {
    // An accessor without a bufferView is all zeros: a count of 2^31 would be 24 GiB of
    // positions. Tiny file, huge allocation: the limit refuses it.
    let mut d = quad_doc();
    d["accessors"]
        .as_array_mut()
        .unwrap()
        .push(json!({"componentType": 5126, "count": 2147483647u64, "type": "VEC3"}));
    d["meshes"][0]["primitives"] = json!([{"attributes": {"POSITION": 3}}]);
    expect_err(
        load_doc(&d, &quad_bin()),
        "limit-exceeded",
        Some("/meshes/0/primitives/0"),
    );
    let limits = Limits {
        max_instances: 3,
        ..Limits::default()
    };
    let mut d = quad_doc();
    d["nodes"] = json!([{"mesh": 0}, {"mesh": 0}, {"mesh": 0}, {"mesh": 0}]);
    d["scenes"] = json!([{"nodes": [0, 1, 2, 3]}]);
    let mut res = MemoryResources::default();
    res.files.insert("quad.bin".into(), quad_bin());
    expect_err(
        load_gltf_bytes(d.to_string().as_bytes(), "quad.gltf", &res, &limits),
        "limit-exceeded",
        Some("/nodes/3"),
    );
}

/// Strips and fans triple their index count, and flat normals need a vertex per corner: the
/// limits apply to what a primitive expands to, checked before expanding. A 2^28-index strip of
/// zero positions in a tiny file would otherwise build 3 GiB of indices and 24 GiB of vertices.
#[test]
fn limits_apply_to_expanded_strips_and_flat_normal_vertices() {
    let mut d = quad_doc();
    d["accessors"]
        .as_array_mut()
        .unwrap()
        .push(json!({"componentType": 5125, "count": 268_435_456u64, "type": "SCALAR"}));
    d["meshes"][0]["primitives"] =
        json!([{"attributes": {"POSITION": 0, "NORMAL": 1}, "indices": 3, "mode": 5}]);
    expect_err(
        load_doc(&d, &quad_bin()),
        "limit-exceeded",
        Some("/meshes/0/primitives/0"),
    );
    // The quad as a triangle list without normals: 6 corners, so 6 flat-shaded vertices.
    let mut d = quad_doc();
    d["meshes"][0]["primitives"] = json!([{"attributes": {"POSITION": 0}, "indices": 2}]);
    let load = |max_vertices| {
        let mut res = MemoryResources::default();
        res.files.insert("quad.bin".into(), quad_bin());
        let limits = Limits {
            max_vertices,
            ..Limits::default()
        };
        load_gltf_bytes(d.to_string().as_bytes(), "quad.gltf", &res, &limits)
    };
    assert_eq!(load(6).unwrap().vertices().len(), 6);
    expect_err(load(5), "limit-exceeded", Some("/meshes/0/primitives/0"));
}

/// A buffer URI is a relative path inside the file's directory: an absolute path or `..` is an
/// error naming the buffer (no reading /dev/zero or a key file), and a real file is read only up
/// to its byteLength.
#[test]
fn buffer_uris_stay_inside_the_directory_and_read_only_what_they_declare() {
    let dir = std::env::temp_dir().join(format!("tilegraph-uri-{}", std::process::id()));
    std::fs::create_dir_all(dir.join("sub")).unwrap();
    let mut bin = quad_bin();
    bin.extend(vec![0u8; 4096]);
    std::fs::write(dir.join("sub").join("quad.bin"), &bin).unwrap();
    let resolver = tilegraph_scene::FileResolver {
        base: dir.join("sub"),
    };
    let load = |uri: &str| {
        let mut d = quad_doc();
        d["buffers"][0]["uri"] = json!(uri);
        load_gltf_bytes(
            d.to_string().as_bytes(),
            "quad.gltf",
            &resolver,
            &Limits::default(),
        )
    };
    assert_eq!(load("quad.bin").unwrap().triangles_drawn(), 2);
    for uri in [
        "/dev/zero",
        "%2Fdev%2Fzero",
        "../sub/quad.bin",
        "sub/../../x.bin",
    ] {
        let e = expect_err(load(uri), "buffer", Some("/buffers/0/uri"));
        assert!(e.to_string().contains("relative path"), "{uri}: {e}");
    }
    // A symbolic link inside the directory that points out of it is refused too.
    #[cfg(unix)]
    {
        std::fs::write(dir.join("outside.bin"), &bin).unwrap();
        std::os::unix::fs::symlink(dir.join("outside.bin"), dir.join("sub").join("link.bin"))
            .unwrap();
        let e = load("link.bin").expect_err("a link out of the directory");
        assert!(e.to_string().contains("outside"), "{e}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// glTF: a node whose transform mirrors (negative determinant) has clockwise front faces. Its
/// instance draws a copy of the mesh with the winding reversed, so after the transform every
/// triangle still faces where the unmirrored one does (counter-clockwise front faces).
#[test]
fn mirrored_nodes_draw_a_mesh_with_reversed_winding() {
    let mut d = quad_doc();
    d["nodes"] = json!([{"mesh": 0}, {"mesh": 0, "scale": [-1.0, 1.0, 1.0]}, {"mesh": 0, "scale": [-2.0, 1.0, 1.0]}]);
    d["scenes"] = json!([{"nodes": [0, 1, 2]}]);
    let s = load_doc(&d, &quad_bin()).unwrap();
    let inst = s.instances();
    assert_eq!(inst.len(), 3);
    assert_ne!(
        inst[0].mesh, inst[1].mesh,
        "the mirrored node draws another mesh"
    );
    assert_eq!(inst[1].mesh, inst[2].mesh, "one mirrored copy per mesh");
    // World-space geometric normal of each instance's first triangle.
    let normal = |i: usize| {
        let m = s.mesh(inst[i].mesh).unwrap();
        let first = m.first_index as usize;
        let p = |k: usize| {
            let v = s.indices()[first + k] as i64 + i64::from(m.vertex_offset);
            let local = Vec3::from_array(s.vertices()[v as usize].position);
            inst[i].transform.transform_point(local)
        };
        (p(1) - p(0)).cross(p(2) - p(0)).normalize()
    };
    let n0 = normal(0);
    assert!(n0.y > 0.99, "{n0:?}");
    for i in [1, 2] {
        let n = normal(i);
        assert!(n.y > 0.99, "instance {i}: {n:?} (inside-out)");
    }

    // Exported and loaded again: still facing up (the export must not hand a reader the
    // already-reversed copy, which it would reverse once more).
    let again = load_gltf_bytes(
        &tilegraph_scene::export::to_glb(&s),
        "again.glb",
        &NoResources,
        &Limits::default(),
    )
    .unwrap();
    let inst = again.instances();
    assert_eq!(inst.len(), 3);
    for (i, it) in inst.iter().enumerate() {
        let m = again.mesh(it.mesh).unwrap();
        let first = m.first_index as usize;
        let p = |k: usize| {
            let v = again.indices()[first + k] as i64 + i64::from(m.vertex_offset);
            let local = Vec3::from_array(again.vertices()[v as usize].position);
            it.transform.transform_point(local)
        };
        let n = (p(1) - p(0)).cross(p(2) - p(0)).normalize();
        assert!(n.y > 0.99, "re-loaded instance {i}: {n:?} (inside-out)");
    }
}

/// Glass (`KHR_materials_transmission` with a factor above 0) lets the scene behind it show:
/// it is drawn as blended, whatever its alpha mode, so culling never treats it as an occluder.
#[test]
fn transmissive_materials_are_blended() {
    for (factor, blended) in [(Some(1.0), true), (Some(0.0), false), (None, false)] {
        let mut doc = quad_doc();
        // OPAQUE: its alpha is ignored (glTF), and stays so when drawn blended.
        doc["materials"][0] = json!({"alphaMode": "OPAQUE",
            "pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 0.25]}});
        if let Some(f) = factor {
            doc["extensionsUsed"] = json!(["KHR_materials_transmission"]);
            doc["materials"][0]["extensions"] =
                json!({"KHR_materials_transmission": {"transmissionFactor": f}});
        }
        let s = load_doc(&doc, &quad_bin()).unwrap();
        let class = s.materials()[0].class;
        assert_eq!(
            class == tilegraph_scene::MaterialClass::Blended,
            blended,
            "transmission {factor:?}: {class:?}"
        );
        if blended {
            assert_eq!(s.materials()[0].base_color[3], 1.0);
        }
    }
    // MASK keeps its cut-out.
    let mut doc = quad_doc();
    doc["extensionsUsed"] = json!(["KHR_materials_transmission"]);
    doc["materials"][0]["extensions"] =
        json!({"KHR_materials_transmission": {"transmissionFactor": 1.0}});
    let s = load_doc(&doc, &quad_bin()).unwrap();
    assert!(matches!(
        s.materials()[0].class,
        MaterialClass::AlphaTested { .. }
    ));
}

/// A .gltf opened by a bare file name (in the working directory) has an empty base directory:
/// its buffers are read from the working directory.
#[test]
fn buffers_next_to_a_gltf_in_the_working_directory_load() {
    let name = format!("tilegraph-cwd-{}.bin", std::process::id());
    std::fs::write(&name, quad_bin()).unwrap();
    let resolver = tilegraph_scene::FileResolver {
        base: std::path::PathBuf::new(),
    };
    let mut d = quad_doc();
    d["buffers"][0]["uri"] = json!(name.clone());
    let loaded = load_gltf_bytes(
        d.to_string().as_bytes(),
        "quad.gltf",
        &resolver,
        &Limits::default(),
    );
    std::fs::remove_file(&name).unwrap();
    assert_eq!(loaded.unwrap().triangles_drawn(), 2);
}

/// Primitives without normals are de-indexed from their whole POSITION accessor: the vertices
/// read count against the vertex limit too, or a few-KB file of huge data-less accessors (read
/// as zeros) could make the loader allocate far more than the vertices it keeps.
#[test]
fn vertices_read_count_against_the_vertex_limit() {
    let doc = |accessors: usize| {
        let mut prims = Vec::new();
        let mut accs = Vec::new();
        for a in 0..accessors {
            accs.push(json!({"componentType": 5126, "count": 600, "type": "VEC3"}));
            prims.push(json!({"attributes": {"POSITION": a}, "indices": accessors}));
        }
        accs.push(json!({"bufferView": 0, "componentType": 5123, "count": 3, "type": "SCALAR"}));
        json!({
            "asset": {"version": "2.0"},
            "scenes": [{"nodes": [0]}],
            "nodes": [{"mesh": 0}],
            "meshes": [{"primitives": prims}],
            "accessors": accs,
            "bufferViews": [{"buffer": 0, "byteLength": 6}],
            "buffers": [{"uri": "quad.bin", "byteLength": 6}]
        })
    };
    let limits = Limits {
        max_vertices: 1000,
        ..Limits::default()
    };
    let load = |d: &Value| {
        let mut res = MemoryResources::default();
        res.files.insert("quad.bin".into(), u16s(&[0, 1, 2]));
        load_gltf_bytes(d.to_string().as_bytes(), "many.gltf", &res, &limits)
    };
    // One 600-vertex accessor, shared by two primitives: read once, 6 vertices kept.
    let mut shared = doc(1);
    shared["meshes"][0]["primitives"] = json!([
        {"attributes": {"POSITION": 0}, "indices": 1},
        {"attributes": {"POSITION": 0}, "indices": 1}
    ]);
    assert!(load(&shared).is_ok());
    // Two distinct ones: 1,200 vertices read for 6 kept, over the limit of 1,000.
    let err = load(&doc(2)).expect_err("1,200 vertices read");
    assert!(err.to_string().contains("vertices"), "{err}");
}

/// KHR_mesh_quantization: normals may be normalized signed shorts (read as unit vectors); plain
/// integers are invalid there and would be huge vectors, so they are an error naming the
/// attribute.
#[test]
fn quantized_normals_must_be_normalized_signed_integers() {
    let mut bin = f32s(&[0., 0., 0., 1., 0., 0., 1., 0., 1., 0., 0., 1.]);
    for _ in 0..4 {
        // (0, 1, 0) as normalized shorts, padded to the 8-byte stride.
        for v in [0i16, 32767, 0, 0] {
            bin.extend(v.to_le_bytes());
        }
    }
    bin.extend(u16s(&[0, 2, 1, 0, 3, 2]));
    let mut doc = quad_doc();
    doc["extensionsUsed"] = json!(["KHR_mesh_quantization"]);
    doc["extensionsRequired"] = json!(["KHR_mesh_quantization"]);
    doc["buffers"][0]["byteLength"] = json!(bin.len());
    doc["bufferViews"] = json!([
        {"buffer": 0, "byteOffset": 0, "byteLength": 48},
        {"buffer": 0, "byteOffset": 48, "byteLength": 32, "byteStride": 8},
        {"buffer": 0, "byteOffset": 80, "byteLength": 12}
    ]);
    doc["accessors"] = json!([
        {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3"},
        {"bufferView": 1, "componentType": 5122, "normalized": true, "count": 4, "type": "VEC3"},
        {"bufferView": 2, "componentType": 5123, "count": 6, "type": "SCALAR"}
    ]);
    let s = load_doc(&doc, &bin).unwrap();
    assert_eq!(s.triangles_drawn(), 2);
    assert!(
        s.vertices()
            .iter()
            .all(|v| (Vec3::from(v.normal) - Vec3::Y).length() < 1e-4),
        "{:?}",
        s.vertices()
    );
    doc["accessors"][1]["normalized"] = json!(false);
    expect_err(
        load_doc(&doc, &bin),
        "invalid",
        Some("/meshes/0/primitives/0/attributes/NORMAL"),
    );
}
