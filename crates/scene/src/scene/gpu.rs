//! The scene's records as the shaders read them (std430 layouts, mirrored in
//! `shaders/common/scene.glsl`).

use bytemuck::{Pod, Zeroable};
use glam::{Mat4, Vec4};

/// Per-instance record uploaded each frame. 80 bytes, std430 layout (mirrored by `Instance` in
/// shaders/common/scene.glsl, checked by crates/passes' `shader_layouts` test):
///
/// ```glsl
/// struct Instance {
///     vec4 model_rows[3];               // rows of the camera-relative 3x4 model matrix
///     vec3 center; uint mesh;           // camera-relative bounds centre (AABB and sphere)
///     vec3 half_extents; float radius;  // world AABB half extents, bounding-sphere radius
/// };
/// ```
///
/// The material id and class are one indirection away, `meshes[mesh].material` and
/// `materials[...].class` ([`GpuMesh`], [`GpuMaterial`]), which keeps the record at 80 bytes: it
/// is streamed every frame, so every 16 bytes is about 15% of the per-frame cost. The instance
/// index is the record's position in the array. The model matrix is stored as three rows (the
/// affine 3x4) to save 16 bytes; the vertex shader computes `world = vec4(pos, 1) * mat3x4(rows)`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuInstance {
    pub model_rows: [[f32; 4]; 3],
    pub center: [f32; 3],
    pub mesh: u32,
    pub half_extents: [f32; 3],
    pub radius: f32,
}

impl GpuInstance {
    /// The camera-relative model matrix as a `Mat4`, for CPU references.
    pub fn model_matrix(&self) -> Mat4 {
        let r = &self.model_rows;
        Mat4::from_cols(
            Vec4::new(r[0][0], r[1][0], r[2][0], 0.0),
            Vec4::new(r[0][1], r[1][1], r[2][1], 0.0),
            Vec4::new(r[0][2], r[1][2], r[2][2], 0.0),
            Vec4::new(r[0][3], r[1][3], r[2][3], 1.0),
        )
    }
}

/// Mesh table entry for the GPU. 48 bytes, std430 (`uint first_index, index_count; int
/// vertex_offset; uint material; vec3 aabb_min; uint pad; vec3 aabb_max; uint pad;`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuMesh {
    pub first_index: u32,
    pub index_count: u32,
    pub vertex_offset: i32,
    pub material: u32,
    pub aabb_min: [f32; 3],
    pub _pad0: u32,
    pub aabb_max: [f32; 3],
    pub _pad1: u32,
}

/// Material table entry for the GPU. 32 bytes, std430 (`vec4 base_color; uint class; float
/// alpha_cutoff; uint double_sided; uint pad;`). `class`: 0 opaque, 1 alpha-tested, 2 blended.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuMaterial {
    pub base_color: [f32; 4],
    pub class: u32,
    pub alpha_cutoff: f32,
    pub double_sided: u32,
    pub _pad: u32,
}
