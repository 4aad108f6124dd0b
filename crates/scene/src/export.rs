//! Writes a [`Scene`] as a self-contained GLB: one node per instance, one glTF mesh (one
//! primitive) per tilegraph mesh, vertex data interleaved exactly as [`Vertex`] lays it out.
//!
//! Used to hand procedural scenes to other tools, and by the tests to round-trip the generator
//! through the loader.

use std::collections::HashMap;

use serde_json::{json, Value};

use crate::gltf_load::glb;
use crate::scene::{MaterialClass, Scene, Vertex};

const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;
const FLOAT: u32 = 5126;
const UNSIGNED_INT: u32 = 5125;

/// The scene as GLB bytes. Translations are written as f32 (glTF has no f64), so a scene far
/// from the origin loses precision in the file, not in memory.
pub fn to_glb(scene: &Scene) -> Vec<u8> {
    // A mirroring instance (negative determinant) draws a mesh whose winding the loader already
    // reversed; glTF readers reverse the winding of such nodes themselves, so those instances
    // get a copy with the winding turned back (appended to the indices).
    let mut indices: Vec<u32> = scene.indices().to_vec();
    let mut rewound: HashMap<u32, (u32, u32)> = HashMap::new();
    for inst in scene.instances() {
        if inst.transform.linear.determinant() >= 0.0 || rewound.contains_key(&inst.mesh.0) {
            continue;
        }
        let Some(mesh) = scene.meshes().get(inst.mesh.index()) else {
            continue;
        };
        let first = mesh.first_index as usize;
        let Some(range) = scene
            .indices()
            .get(first..first + mesh.index_count as usize)
        else {
            continue;
        };
        let start = indices.len() as u32;
        indices.extend(range.chunks_exact(3).flat_map(|t| [t[0], t[2], t[1]]));
        rewound.insert(inst.mesh.0, (start, indices.len() as u32 - start));
    }
    let vertex_bytes: &[u8] = bytemuck::cast_slice(scene.vertices());
    let index_bytes: &[u8] = bytemuck::cast_slice(&indices);
    let mut bin = Vec::with_capacity(vertex_bytes.len() + index_bytes.len());
    bin.extend_from_slice(vertex_bytes);
    bin.extend_from_slice(index_bytes);
    let stride = std::mem::size_of::<Vertex>();

    let mut accessors: Vec<Value> = Vec::new();
    let mut shared: HashMap<(i32, u32), [usize; 3]> = HashMap::new();
    let mut meshes = Vec::with_capacity(scene.meshes().len());
    let mut mesh_attrs: Vec<[usize; 3]> = Vec::with_capacity(scene.meshes().len());
    for mesh in scene.meshes() {
        let key = (mesh.vertex_offset, mesh.vertex_count);
        let attrs = match shared.get(&key) {
            Some(&a) => a,
            None => {
                let start = mesh.vertex_offset.max(0) as usize;
                let range = scene
                    .vertices()
                    .get(start..start + mesh.vertex_count as usize)
                    .unwrap_or(&[]);
                let mut min = [f32::INFINITY; 3];
                let mut max = [f32::NEG_INFINITY; 3];
                for v in range {
                    for k in 0..3 {
                        min[k] = min[k].min(v.position[k]);
                        max[k] = max[k].max(v.position[k]);
                    }
                }
                let base = start * stride;
                let first = accessors.len();
                accessors.push(
                    json!({"bufferView": 0, "byteOffset": base, "componentType": FLOAT,
                    "count": mesh.vertex_count, "type": "VEC3", "min": min, "max": max}),
                );
                accessors.push(
                    json!({"bufferView": 0, "byteOffset": base + 12, "componentType": FLOAT,
                    "count": mesh.vertex_count, "type": "VEC3"}),
                );
                accessors.push(
                    json!({"bufferView": 0, "byteOffset": base + 24, "componentType": FLOAT,
                    "count": mesh.vertex_count, "type": "VEC2"}),
                );
                let a = [first, first + 1, first + 2];
                shared.insert(key, a);
                a
            }
        };
        mesh_attrs.push(attrs);
        let indices = accessors.len();
        accessors.push(
            json!({"bufferView": 1, "byteOffset": mesh.first_index as usize * 4,
            "componentType": UNSIGNED_INT, "count": mesh.index_count, "type": "SCALAR"}),
        );
        meshes.push(json!({"primitives": [{
            "attributes": {"POSITION": attrs[0], "NORMAL": attrs[1], "TEXCOORD_0": attrs[2]},
            "indices": indices, "material": mesh.material.0}]}));
    }
    // The rewound copies, after the scene's meshes: scene mesh -> glTF mesh.
    let mut rewound_mesh: HashMap<u32, usize> = HashMap::new();
    let mut sorted: Vec<(u32, (u32, u32))> = rewound.into_iter().collect();
    sorted.sort_unstable();
    for (m, (start, count)) in sorted {
        let (Some(mesh), Some(attrs)) =
            (scene.meshes().get(m as usize), mesh_attrs.get(m as usize))
        else {
            continue;
        };
        let idx = accessors.len();
        accessors.push(json!({"bufferView": 1, "byteOffset": start as usize * 4,
            "componentType": UNSIGNED_INT, "count": count, "type": "SCALAR"}));
        rewound_mesh.insert(m, meshes.len());
        meshes.push(json!({"primitives": [{
            "attributes": {"POSITION": attrs[0], "NORMAL": attrs[1], "TEXCOORD_0": attrs[2]},
            "indices": idx, "material": mesh.material.0}]}));
    }

    let materials: Vec<Value> = scene
        .materials()
        .iter()
        .map(|m| {
            let mut v = json!({"pbrMetallicRoughness": {"baseColorFactor": m.base_color},
                "doubleSided": m.double_sided});
            match m.class {
                MaterialClass::Opaque => {}
                MaterialClass::AlphaTested { cutoff } => {
                    v["alphaMode"] = json!("MASK");
                    v["alphaCutoff"] = json!(cutoff);
                }
                MaterialClass::Blended => v["alphaMode"] = json!("BLEND"),
            }
            v
        })
        .collect();

    let nodes: Vec<Value> = scene
        .instances()
        .iter()
        .map(|inst| {
            let l = inst.transform.linear;
            let t = inst.transform.translation.as_vec3();
            let mesh = rewound_mesh
                .get(&inst.mesh.0)
                .filter(|_| l.determinant() < 0.0)
                .copied()
                .unwrap_or(inst.mesh.0 as usize);
            json!({"mesh": mesh, "matrix": [
                l.x_axis.x, l.x_axis.y, l.x_axis.z, 0.0,
                l.y_axis.x, l.y_axis.y, l.y_axis.z, 0.0,
                l.z_axis.x, l.z_axis.y, l.z_axis.z, 0.0,
                t.x, t.y, t.z, 1.0]})
        })
        .collect();

    let mut views = vec![
        json!({"buffer": 0, "byteOffset": 0, "byteLength": vertex_bytes.len().max(4),
        "byteStride": stride, "target": ARRAY_BUFFER}),
    ];
    if !index_bytes.is_empty() {
        views.push(
            json!({"buffer": 0, "byteOffset": vertex_bytes.len(), "byteLength": index_bytes.len(),
            "target": ELEMENT_ARRAY_BUFFER}),
        );
    }
    let doc = json!({
        "asset": {"version": "2.0", "generator": "tilegraph-scene"},
        "scene": 0,
        "scenes": [{"name": scene.name(), "nodes": (0..nodes.len()).collect::<Vec<_>>()}],
        "nodes": nodes,
        "meshes": meshes,
        "materials": materials,
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{"byteLength": bin.len().max(4)}],
    });
    if bin.len() < 4 {
        bin.resize(4, 0);
    }
    let json_text = doc.to_string();
    glb::write(json_text.as_bytes(), Some(&bin))
}
