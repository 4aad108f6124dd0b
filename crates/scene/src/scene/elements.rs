//! What a scene is made of: vertices, meshes and materials, and instances placing meshes in the
//! world with f64 translations and world bounds.

use bytemuck::{Pod, Zeroable};
use glam::{DAffine3, DVec3, Mat3, Mat4, Vec3};
use serde::Serialize;

use crate::bounds::{Aabb, DAabb, DSphere};
use crate::texture::TextureId;

use super::gpu::{GpuInstance, GpuMaterial, GpuMesh, SplitPoint};

/// One vertex of the shared vertex buffer. 32 bytes, std430-compatible (scalar floats only).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable, Serialize)]
pub struct Vertex {
    pub position: [f32; 3],
    pub normal: [f32; 3],
    pub uv: [f32; 2],
}

/// Index of a [`Mesh`] in [`Scene::meshes`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
pub struct MeshId(pub u32);

/// Index of a [`Material`] in [`Scene::materials`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
pub struct MaterialId(pub u32);

/// Index of an [`Instance`] in [`Scene::instances`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
pub struct InstanceId(pub u32);

impl MeshId {
    pub fn index(self) -> usize {
        self.0 as usize
    }
}
impl MaterialId {
    pub fn index(self) -> usize {
        self.0 as usize
    }
}
impl InstanceId {
    pub fn index(self) -> usize {
        self.0 as usize
    }
}

/// How a material's coverage is decided, which is what the visibility passes care about.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub enum MaterialClass {
    /// Writes depth, never discards: a strong occluder.
    Opaque,
    /// glTF alphaMode MASK: discards below `cutoff`; needs the alpha-tested pre-pass.
    AlphaTested { cutoff: f32 },
    /// glTF alphaMode BLEND: no depth write, drawn after the opaque work.
    Blended,
}

impl MaterialClass {
    /// The value stored in [`GpuMaterial::class`].
    pub fn gpu_code(self) -> u32 {
        match self {
            MaterialClass::Opaque => 0,
            MaterialClass::AlphaTested { .. } => 1,
            MaterialClass::Blended => 2,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Material {
    pub base_color: [f32; 4],
    pub class: MaterialClass,
    pub double_sided: bool,
    /// Multiplies `base_color` (glTF baseColorTexture, sampled with the mesh's UVs); its alpha
    /// is what an alpha-tested material tests.
    pub base_color_texture: Option<TextureId>,
    /// The engine's own shaders for this material: the id the renderer gave them when the
    /// engine registered them (`SceneRenderer::add_material`); `None` draws with tilegraph's.
    pub engine_material: Option<u32>,
}

impl Material {
    pub fn opaque(base_color: [f32; 4]) -> Self {
        Material {
            base_color,
            class: MaterialClass::Opaque,
            double_sided: false,
            base_color_texture: None,
            engine_material: None,
        }
    }
}

/// A tilegraph mesh: one glTF primitive, one material, a range of the shared buffers.
///
/// Indices are relative to `vertex_offset`, as `vkCmdDrawIndexed` expects.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Mesh {
    pub first_index: u32,
    pub index_count: u32,
    /// Added to every index; i32 because that is the type of `VkDrawIndexedIndirectCommand::vertexOffset`.
    pub vertex_offset: i32,
    pub vertex_count: u32,
    pub material: MaterialId,
    pub local_aabb: Aabb,
}

impl Mesh {
    pub fn triangle_count(&self) -> u32 {
        self.index_count / 3
    }

    /// Its entry of the GPU mesh table.
    pub fn gpu(&self) -> GpuMesh {
        GpuMesh {
            first_index: self.first_index,
            index_count: self.index_count,
            vertex_offset: self.vertex_offset,
            material: self.material.0,
            aabb_min: self.local_aabb.min.to_array(),
            _pad0: 0,
            aabb_max: self.local_aabb.max.to_array(),
            _pad1: 0,
        }
    }
}

impl Material {
    /// Its entry of the GPU material table.
    pub fn gpu(&self) -> GpuMaterial {
        GpuMaterial {
            base_color: self.base_color,
            class: self.class.gpu_code(),
            alpha_cutoff: match self.class {
                MaterialClass::AlphaTested { cutoff } => cutoff,
                _ => 0.0,
            },
            double_sided: u32::from(self.double_sided),
            texture: self
                .base_color_texture
                .map_or(GpuMaterial::NO_TEXTURE, |t| t.0),
        }
    }
}

/// A placement in the world: an f32 3x3 linear part (rotation, scale, shear) and an f64
/// translation. The split is what keeps large worlds precise: the translation is never rounded to
/// f32 until the camera position has been subtracted from it (see [`Transform::camera_relative`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transform {
    pub linear: Mat3,
    pub translation: DVec3,
}

impl Transform {
    pub const IDENTITY: Transform = Transform {
        linear: Mat3::IDENTITY,
        translation: DVec3::ZERO,
    };

    pub fn new(linear: Mat3, translation: DVec3) -> Self {
        Transform {
            linear,
            translation,
        }
    }

    pub fn from_translation(translation: DVec3) -> Self {
        Transform {
            linear: Mat3::IDENTITY,
            translation,
        }
    }

    /// From an f64 affine transform (the glTF loader composes node hierarchies in f64).
    pub fn from_daffine(a: &DAffine3) -> Self {
        Transform {
            linear: a.matrix3.as_mat3(),
            translation: a.translation,
        }
    }

    pub fn to_daffine(&self) -> DAffine3 {
        DAffine3 {
            matrix3: self.linear.as_dmat3(),
            translation: self.translation,
        }
    }

    /// The f32 model matrix with the camera at the origin: translation minus eye, subtracted in f64.
    pub fn camera_relative(&self, eye: DVec3) -> Mat4 {
        let t = (self.translation - eye).as_vec3();
        Mat4::from_cols(
            self.linear.x_axis.extend(0.0),
            self.linear.y_axis.extend(0.0),
            self.linear.z_axis.extend(0.0),
            t.extend(1.0),
        )
    }

    /// A local point in world space, in f64.
    pub fn transform_point(&self, p: Vec3) -> DVec3 {
        self.translation + (self.linear * p).as_dvec3()
    }

    pub fn is_finite(&self) -> bool {
        self.linear.is_finite() && self.translation.is_finite()
    }
}

/// World bounds of an instance: an AABB and a sphere that share one f64 centre.
///
/// Only the centre needs f64; extents and radius are sizes, which f32 holds fine at any distance
/// from the origin. Per frame they become camera-relative f32 ([`GpuInstance`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InstanceBounds {
    pub center: DVec3,
    pub half_extents: Vec3,
    pub radius: f32,
}

impl InstanceBounds {
    pub fn aabb(&self) -> DAabb {
        let h = self.half_extents.as_dvec3();
        DAabb::new(self.center - h, self.center + h)
    }

    pub fn sphere(&self) -> DSphere {
        DSphere {
            center: self.center,
            radius: f64::from(self.radius),
        }
    }
}

/// One object: a mesh placed in the world, with its flags.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Instance {
    pub transform: Transform,
    /// The mesh drawn: the one given, or under a mirroring transform its copy with every
    /// triangle turned (`Scene::prepare_mirroring`).
    pub mesh: MeshId,
    pub bounds: InstanceBounds,
    pub flags: InstanceFlags,
}

impl Instance {
    /// Its world-space record for the GPU ([`GpuInstance`]): the linear part, the translation
    /// split high + low, the bounds centre as an f32 offset from the translation.
    #[inline]
    pub fn gpu_record(&self) -> GpuInstance {
        let t = SplitPoint::new(self.transform.translation);
        let offset = (self.bounds.center - self.transform.translation).as_vec3();
        let l = self.transform.linear;
        GpuInstance {
            rows: [
                [l.x_axis.x, l.y_axis.x, l.z_axis.x, t.high.x],
                [l.x_axis.y, l.y_axis.y, l.z_axis.y, t.high.y],
                [l.x_axis.z, l.y_axis.z, l.z_axis.z, t.high.z],
            ],
            translation_low: t.low.to_array(),
            mesh: self.mesh.0,
            center_offset: offset.to_array(),
            radius: self.bounds.radius,
            half_extents: self.bounds.half_extents.to_array(),
            flags: self.flags.bits(),
        }
    }
}

/// A handle to an instance a game holds: its slot and the slot's generation. A removed
/// instance's handle (every copy of it) is stale: using it is [`SceneError::StaleHandle`](crate::SceneError),
/// never a change to whichever instance takes the slot next.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
pub struct InstanceHandle {
    pub(crate) slot: u32,
    pub(crate) generation: u32,
}

/// A handle to a mesh: its index and the index's generation.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
pub struct MeshHandle {
    pub(crate) index: u32,
    pub(crate) generation: u32,
}

impl InstanceHandle {
    /// The slot: the instance's index in [`Scene::instances`](crate::Scene::instances) and on
    /// the GPU.
    pub fn id(self) -> InstanceId {
        InstanceId(self.slot)
    }
    pub fn generation(self) -> u32 {
        self.generation
    }
    /// The handle as one integer (slot in the low 32 bits), for a C ABI or a save file.
    pub fn to_bits(self) -> u64 {
        u64::from(self.generation) << 32 | u64::from(self.slot)
    }
    pub fn from_bits(bits: u64) -> Self {
        InstanceHandle {
            slot: bits as u32,
            generation: (bits >> 32) as u32,
        }
    }
}

impl MeshHandle {
    pub fn id(self) -> MeshId {
        MeshId(self.index)
    }
    pub fn generation(self) -> u32 {
        self.generation
    }
    /// The handle as one integer (index in the low 32 bits).
    pub fn to_bits(self) -> u64 {
        u64::from(self.generation) << 32 | u64::from(self.index)
    }
    pub fn from_bits(bits: u64) -> Self {
        MeshHandle {
            index: bits as u32,
            generation: (bits >> 32) as u32,
        }
    }
}

/// What an instance is besides its mesh and place: hidden (kept, not drawn), casting shadows.
/// The bits are the record's `flags` on the GPU.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
pub struct InstanceFlags(u32);

impl InstanceFlags {
    pub const NONE: InstanceFlags = InstanceFlags(0);
    /// Kept in the scene, not drawn (and not culled: it costs nothing per frame).
    pub const HIDDEN: InstanceFlags = InstanceFlags(1);
    /// Drawn into shadow maps (what an instance of a built scene starts with).
    pub const CASTS_SHADOWS: InstanceFlags = InstanceFlags(2);
    /// A free slot (no instance). Never set by a caller.
    pub(crate) const FREE: InstanceFlags = InstanceFlags(1 << 31);
    const PUBLIC: u32 = 0b11;

    /// Flags from their bits; `None` for an unknown bit.
    pub fn from_bits(bits: u32) -> Option<Self> {
        (bits & !Self::PUBLIC == 0).then_some(InstanceFlags(bits))
    }
    pub fn bits(self) -> u32 {
        self.0
    }
    pub fn contains(self, other: InstanceFlags) -> bool {
        self.0 & other.0 == other.0
    }
    /// Drawn: neither hidden nor a free slot.
    pub fn is_drawn(self) -> bool {
        self.0 & (Self::HIDDEN.0 | Self::FREE.0) == 0
    }
    pub(crate) fn is_free(self) -> bool {
        self.contains(Self::FREE)
    }
    /// Without the bits a caller may not set.
    pub(crate) fn public(self) -> Self {
        InstanceFlags(self.0 & Self::PUBLIC)
    }
}

impl Default for InstanceFlags {
    fn default() -> Self {
        InstanceFlags::CASTS_SHADOWS
    }
}

impl std::ops::BitOr for InstanceFlags {
    type Output = InstanceFlags;
    fn bitor(self, rhs: InstanceFlags) -> InstanceFlags {
        InstanceFlags(self.0 | rhs.0)
    }
}
