//! The scene's records as the shaders read them (std430 layouts, mirrored in
//! `shaders/common/scene.glsl`).

use bytemuck::{Pod, Zeroable};
use glam::{DVec3, Mat4, Vec3, Vec4};

/// A world position as two f32, `high + low`: `high` the position rounded to f32, `low` what
/// rounding left (itself rounded). Differences of two split positions, taken part by part,
/// are precise to about an f32 ulp of the difference, not of the positions: what keeps a world
/// of 10^6 m precise on a GPU without `shaderFloat64` (mobile GPUs lack it).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SplitPoint {
    pub high: Vec3,
    pub low: Vec3,
}

impl SplitPoint {
    pub fn new(p: DVec3) -> Self {
        let high = p.as_vec3();
        SplitPoint {
            high,
            low: (p - high.as_dvec3()).as_vec3(),
        }
    }
}

/// Per-instance record, resident on the GPU and uploaded only when the instance changes. 96
/// bytes, std430, in **world space** (mirrored by `InstanceRecord` in
/// shaders/common/scene.glsl, checked by crates/passes' `shader_layouts` test):
///
/// ```glsl
/// struct InstanceRecord {
///     vec4 rows[3];                    // rows of the linear part; w: translation, high part
///     vec3 translation_low; uint mesh; // translation, low part ([`SplitPoint`])
///     vec3 center_offset; float radius; // bounds centre minus translation; sphere radius
///     vec3 half_extents; uint flags;   // world AABB half extents; `InstanceFlags`
/// };
/// ```
///
/// The shaders make it camera-relative ([`RelativeInstance`], `instance_at` in scene.glsl)
/// from the frame's split eye, exactly as [`GpuInstance::relative`] does on the CPU.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuInstance {
    pub rows: [[f32; 4]; 3],
    pub translation_low: [f32; 3],
    pub mesh: u32,
    pub center_offset: [f32; 3],
    pub radius: f32,
    pub half_extents: [f32; 3],
    pub flags: u32,
}

/// An instance relative to the camera, as the shaders compute it from a [`GpuInstance`] and the
/// frame's eye: the f32 model matrix with the eye at the origin and the bounds around it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RelativeInstance {
    /// Rows of the camera-relative affine 3x4 model matrix.
    pub model_rows: [[f32; 4]; 3],
    pub center: [f32; 3],
    pub mesh: u32,
    pub half_extents: [f32; 3],
    pub radius: f32,
}

impl GpuInstance {
    /// The record seen from `eye`, computed as `instance_at` in scene.glsl does — the same f32
    /// operations in the same order (the shader marks them `precise`: no fused or reordered
    /// arithmetic) — so a CPU reference sees what the GPU draws.
    ///
    /// The translation becomes `(high - eye.high) + (low - eye.low)`; the bounds centre is that
    /// plus the f32 offset, so the box and the vertices are placed from the same translation and
    /// its rounding cancels between them. The box grows by a few ulps of the translation, the
    /// centre and the offset: what rounding the centre, the offset and the vertex transform may
    /// move a vertex by.
    pub fn relative(&self, eye: &SplitPoint) -> RelativeInstance {
        let r = &self.rows;
        let high = Vec3::new(r[0][3], r[1][3], r[2][3]);
        let low = Vec3::from_array(self.translation_low);
        let t = (high - eye.high) + (low - eye.low);
        let offset = Vec3::from_array(self.center_offset);
        let c = t + offset;
        let pad = (t.abs() + c.abs() + offset.abs()) * (2.0 * f32::EPSILON);
        RelativeInstance {
            model_rows: [
                [r[0][0], r[0][1], r[0][2], t.x],
                [r[1][0], r[1][1], r[1][2], t.y],
                [r[2][0], r[2][1], r[2][2], t.z],
            ],
            center: c.to_array(),
            mesh: self.mesh,
            half_extents: (Vec3::from_array(self.half_extents) + pad).to_array(),
            radius: self.radius + pad.length(),
        }
    }
}

impl RelativeInstance {
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
/// vertex_offset; uint material; vec3 aabb_min; uint pad; vec3 aabb_max; uint pad;`). A removed
/// mesh is all zeros but its material: it draws nothing.
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
    /// The base-colour texture's index in the scene's textures, [`GpuMaterial::NO_TEXTURE`]
    /// when it has none.
    pub texture: u32,
}

impl GpuMaterial {
    pub const NO_TEXTURE: u32 = u32::MAX;
}
