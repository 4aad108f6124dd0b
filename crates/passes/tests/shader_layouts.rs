//! The structs of `shaders/common/scene.glsl` and their Rust mirrors agree on size and member
//! offsets. Read from the committed SPIR-V (names are stripped by `-O`, so structs are matched
//! by their member-offset signature, and arrays by their stride).

use std::collections::HashMap;
use std::mem::{offset_of, size_of};

use tilegraph_passes::gpu_scene::FrameUniforms;
use tilegraph_scene::{GpuInstance, GpuMaterial, GpuMesh};

const OP_TYPE_RUNTIME_ARRAY: u32 = 29;
const OP_DECORATE: u32 = 71;
const OP_MEMBER_DECORATE: u32 = 72;
const DECORATION_ARRAY_STRIDE: u32 = 6;
const DECORATION_OFFSET: u32 = 35;

/// Per struct id: member offsets in member order; per struct id: stride of a runtime array of it.
fn layouts(spv: &[u8]) -> (HashMap<u32, Vec<u32>>, HashMap<u32, u32>) {
    let words: Vec<u32> = spv
        .chunks_exact(4)
        .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    assert_eq!(words[0], 0x0723_0203, "not SPIR-V");
    let mut offsets: HashMap<u32, Vec<(u32, u32)>> = HashMap::new();
    let mut strides: HashMap<u32, u32> = HashMap::new();
    let mut arrays: HashMap<u32, u32> = HashMap::new(); // array id -> element type id
    let mut i = 5;
    while i < words.len() {
        let count = (words[i] >> 16) as usize;
        let op = words[i] & 0xFFFF;
        let ins = &words[i..i + count.max(1)];
        match op {
            OP_MEMBER_DECORATE if ins[3] == DECORATION_OFFSET => {
                offsets.entry(ins[1]).or_default().push((ins[2], ins[4]))
            }
            OP_DECORATE if ins[2] == DECORATION_ARRAY_STRIDE => {
                strides.insert(ins[1], ins[3]);
            }
            OP_TYPE_RUNTIME_ARRAY => {
                arrays.insert(ins[1], ins[2]);
            }
            _ => {}
        }
        i += count.max(1);
    }
    let structs = offsets
        .into_iter()
        .map(|(id, mut v)| {
            v.sort();
            (id, v.into_iter().map(|(_, o)| o).collect())
        })
        .collect();
    let element_stride = arrays
        .into_iter()
        .filter_map(|(arr, elem)| strides.get(&arr).map(|s| (elem, *s)))
        .collect();
    (structs, element_stride)
}

fn assert_struct(
    spv: &[u8],
    shader: &str,
    what: &str,
    rust_offsets: &[usize],
    rust_size: usize,
    in_array: bool,
) {
    let (structs, element_stride) = layouts(spv);
    let want: Vec<u32> = rust_offsets.iter().map(|o| *o as u32).collect();
    let found: Vec<u32> = structs
        .iter()
        .filter(|(_, v)| **v == want)
        .map(|(id, _)| *id)
        .collect();
    assert!(
        !found.is_empty(),
        "{shader}: no struct with {what}'s offsets {want:?}; structs: {:?}",
        structs.values().collect::<Vec<_>>()
    );
    if in_array {
        let strides: Vec<u32> = found
            .iter()
            .filter_map(|id| element_stride.get(id).copied())
            .collect();
        assert!(
            strides.contains(&(rust_size as u32)),
            "{shader}: {what} array stride {strides:?} != Rust size {rust_size}"
        );
    }
}

#[test]
fn instance_mesh_material_and_frame_match_rust() {
    let forward_vert = include_bytes!("../../../shaders/spv/forward.vert.spv");
    let resolve = include_bytes!("../../../shaders/spv/visbuf_resolve_sampled.frag.spv");
    assert_eq!(size_of::<GpuInstance>(), 96);
    assert_struct(
        forward_vert,
        "forward.vert",
        "InstanceRecord",
        &[
            offset_of!(GpuInstance, rows),
            offset_of!(GpuInstance, translation_low),
            offset_of!(GpuInstance, mesh),
            offset_of!(GpuInstance, center_offset),
            offset_of!(GpuInstance, radius),
            offset_of!(GpuInstance, half_extents),
            offset_of!(GpuInstance, flags),
        ],
        size_of::<GpuInstance>(),
        true,
    );
    assert_struct(
        forward_vert,
        "forward.vert",
        "Mesh",
        &[
            offset_of!(GpuMesh, first_index),
            offset_of!(GpuMesh, index_count),
            offset_of!(GpuMesh, vertex_offset),
            offset_of!(GpuMesh, material),
            offset_of!(GpuMesh, aabb_min),
            offset_of!(GpuMesh, _pad0),
            offset_of!(GpuMesh, aabb_max),
            offset_of!(GpuMesh, _pad1),
        ],
        size_of::<GpuMesh>(),
        true,
    );
    assert_struct(
        resolve,
        "visbuf_resolve_sampled.frag",
        "Material",
        &[
            offset_of!(GpuMaterial, base_color),
            offset_of!(GpuMaterial, class),
            offset_of!(GpuMaterial, alpha_cutoff),
            offset_of!(GpuMaterial, double_sided),
            offset_of!(GpuMaterial, texture),
        ],
        size_of::<GpuMaterial>(),
        true,
    );
    assert_struct(
        resolve,
        "visbuf_resolve_sampled.frag",
        "Frame",
        &[
            offset_of!(FrameUniforms, view_proj),
            offset_of!(FrameUniforms, light_dir),
            offset_of!(FrameUniforms, light_color),
            offset_of!(FrameUniforms, params),
            offset_of!(FrameUniforms, viewport),
            offset_of!(FrameUniforms, inv_view_proj),
            offset_of!(FrameUniforms, depth_params),
            offset_of!(FrameUniforms, eye_high),
            offset_of!(FrameUniforms, eye_low),
            offset_of!(FrameUniforms, view_forward),
            offset_of!(FrameUniforms, shadow_clip),
            offset_of!(FrameUniforms, shadow_far),
            offset_of!(FrameUniforms, shadow_texel),
            offset_of!(FrameUniforms, shadow_params),
            offset_of!(FrameUniforms, shadow_info),
            offset_of!(FrameUniforms, caster_planes),
            offset_of!(FrameUniforms, caster_counts),
            offset_of!(FrameUniforms, caster_floor),
            offset_of!(FrameUniforms, caster_reach),
            offset_of!(FrameUniforms, material_work),
        ],
        size_of::<FrameUniforms>(),
        false,
    );
}

#[test]
fn cluster_matches_rust() {
    use tilegraph_scene::clusters::GpuCluster;
    let cull = include_bytes!("../../../shaders/spv/cluster_cull.comp.spv");
    assert_eq!(size_of::<GpuCluster>(), 80);
    let pad = offset_of!(GpuCluster, _pad);
    assert_struct(
        cull,
        "cluster_cull.comp",
        "Cluster",
        &[
            offset_of!(GpuCluster, center),
            offset_of!(GpuCluster, first_index),
            offset_of!(GpuCluster, half_extents),
            offset_of!(GpuCluster, index_count),
            offset_of!(GpuCluster, cone_apex),
            offset_of!(GpuCluster, cone_cutoff),
            offset_of!(GpuCluster, cone_axis),
            offset_of!(GpuCluster, cone_reach),
            offset_of!(GpuCluster, cone_thinness),
            pad,
            pad + 4,
            pad + 8,
        ],
        size_of::<GpuCluster>(),
        true,
    );
}
