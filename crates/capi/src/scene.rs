//! Scenes: uploaded from plain arrays (no glTF needed), or loaded from a glTF file or a
//! procedural spec; the cameras of a scene's path.

use std::collections::HashMap;
use std::ffi::c_char;

use glam::{DVec3, Mat3, Vec3};
use tilegraph_scene::{
    Camera, DepthConvention, Material, MaterialClass, MaterialId, MeshId, Projection, Scene,
    SceneBuilder, Transform, Vertex,
};

use crate::registry::{self, Kind};
use crate::status::{arg, array, boundary, out, string, Failure, TgStatus};

/// A scene.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TgScene {
    pub raw: u64,
}

/// How a material's coverage is decided.
#[repr(u32)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TgMaterialClass {
    /// Writes depth, never discards.
    Opaque = 0,
    /// Discards below `alpha_cutoff` (glTF alphaMode MASK).
    AlphaTested = 1,
    /// Blended, no depth write, drawn back to front after the opaque work.
    Blended = 2,
}

/// One vertex: 32 bytes, 4-byte aligned.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct TgVertex {
    pub position: [f32; 3],
    pub normal: [f32; 3],
    pub uv: [f32; 2],
}

#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct TgMaterial {
    pub base_color: [f32; 4],
    /// A TgMaterialClass.
    pub material_class: u32,
    /// For TG_MATERIAL_CLASS_ALPHA_TESTED: alpha below it is discarded.
    pub alpha_cutoff: f32,
    /// Non-zero: drawn without back-face culling.
    pub double_sided: u32,
}

/// A mesh: a range of the scene's vertices and indices (indices relative to `first_vertex`)
/// with one material.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct TgMesh {
    pub first_vertex: u32,
    pub vertex_count: u32,
    pub first_index: u32,
    pub index_count: u32,
    pub material: u32,
}

/// A mesh placed in the world: a column-major 3x3 linear part (rotation, scale) and an f64
/// translation (large worlds keep millimetres).
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct TgInstance {
    pub linear: [f32; 9],
    pub translation: [f64; 3],
    pub mesh: u32,
}

/// A scene as plain arrays. Arrays must be aligned for their element type.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct TgSceneDesc {
    /// The scene's name in messages (may be null).
    pub name: *const c_char,
    pub vertices: *const TgVertex,
    pub vertex_count: u32,
    pub indices: *const u32,
    pub index_count: u32,
    pub materials: *const TgMaterial,
    pub material_count: u32,
    pub meshes: *const TgMesh,
    pub mesh_count: u32,
    pub instances: *const TgInstance,
    pub instance_count: u32,
}

/// A camera: f64 eye and target, a perspective or (`ortho_half_height` non-zero) an
/// orthographic projection.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct TgCamera {
    pub eye: [f64; 3],
    pub target: [f64; 3],
    pub up: [f32; 3],
    /// Vertical field of view, radians (perspective).
    pub fov_y: f32,
    pub near_plane: f32,
    /// 0: an infinite far plane (perspective only; an orthographic camera needs one).
    pub far_plane: f32,
    /// Non-zero: reverse-Z (near at depth 1), tilegraph's default; zero: standard depth.
    pub reverse_z: u32,
    /// Non-zero: an orthographic camera seeing this many metres above and below its axis (the
    /// width follows the target's aspect; `fov_y` is ignored).
    pub ortho_half_height: f32,
}

impl TgCamera {
    pub(crate) fn from_camera(c: &Camera) -> Self {
        let (fov_y, near_plane, far_plane, depth, ortho_half_height) = match c.projection {
            Projection::Perspective {
                fov_y_rad,
                near,
                far,
                depth,
            } => (fov_y_rad, near, far.unwrap_or(0.0), depth, 0.0),
            Projection::Orthographic {
                half_height,
                near,
                far,
                depth,
            } => (0.0, near, far, depth, half_height),
        };
        TgCamera {
            eye: c.eye.to_array(),
            target: c.target.to_array(),
            up: c.up.to_array(),
            fov_y,
            near_plane,
            far_plane,
            reverse_z: u32::from(depth == DepthConvention::Reverse),
            ortho_half_height,
        }
    }

    fn projection(&self) -> Projection {
        let depth = if self.reverse_z != 0 {
            DepthConvention::Reverse
        } else {
            DepthConvention::Standard
        };
        if self.ortho_half_height != 0.0 {
            Projection::Orthographic {
                half_height: self.ortho_half_height,
                near: self.near_plane,
                far: self.far_plane,
                depth,
            }
        } else {
            Projection::Perspective {
                fov_y_rad: self.fov_y,
                near: self.near_plane,
                far: (self.far_plane != 0.0).then_some(self.far_plane),
                depth,
            }
        }
    }

    /// The camera, checked (finite, a view direction, a valid projection).
    pub(crate) fn to_camera(self) -> Result<Camera, Failure> {
        let camera = Camera {
            eye: DVec3::from_array(self.eye),
            target: DVec3::from_array(self.target),
            up: Vec3::from_array(self.up),
            projection: self.projection(),
        };
        camera
            .validate()
            .map_err(|(field, reason)| Failure::invalid(format!("camera {field}: {reason}")))?;
        Ok(camera)
    }
}

pub(crate) fn material(index: usize, m: &TgMaterial) -> Result<Material, Failure> {
    let class = match m.material_class {
        0 => MaterialClass::Opaque,
        1 => MaterialClass::AlphaTested {
            cutoff: m.alpha_cutoff,
        },
        2 => MaterialClass::Blended,
        c => {
            return Err(Failure::invalid(format!(
                "materials[{index}].material_class {c} is no TgMaterialClass"
            )))
        }
    };
    Ok(Material {
        base_color: m.base_color,
        class,
        double_sided: m.double_sided != 0,
        base_color_texture: None,
        engine_material: None,
    })
}

/// A scene material as C sees it.
pub(crate) fn material_desc(m: &Material) -> TgMaterial {
    let (material_class, alpha_cutoff) = match m.class {
        MaterialClass::Opaque => (TgMaterialClass::Opaque, 0.0),
        MaterialClass::AlphaTested { cutoff } => (TgMaterialClass::AlphaTested, cutoff),
        MaterialClass::Blended => (TgMaterialClass::Blended, 0.0),
    };
    TgMaterial {
        base_color: m.base_color,
        material_class: material_class as u32,
        alpha_cutoff,
        double_sided: u32::from(m.double_sided),
    }
}

/// The scene `desc` describes, checked element by element.
fn build(desc: &TgSceneDesc) -> Result<Scene, Failure> {
    // SAFETY: the caller's contract (tg_scene_create).
    let name = if desc.name.is_null() {
        "scene"
    } else {
        // SAFETY: as above.
        unsafe { string(desc.name, "desc->name") }?
    };
    // SAFETY: as above: each array holds its count of elements.
    let (vertices, indices, materials, meshes, instances) = unsafe {
        (
            array(desc.vertices, desc.vertex_count as usize, "desc->vertices")?,
            array(desc.indices, desc.index_count as usize, "desc->indices")?,
            array(
                desc.materials,
                desc.material_count as usize,
                "desc->materials",
            )?,
            array(desc.meshes, desc.mesh_count as usize, "desc->meshes")?,
            array(
                desc.instances,
                desc.instance_count as usize,
                "desc->instances",
            )?,
        )
    };
    if instances.is_empty() || meshes.is_empty() || materials.is_empty() {
        return Err(Failure::invalid(format!(
            "a scene needs instances, meshes and materials (counts {}, {}, {})",
            instances.len(),
            meshes.len(),
            materials.len()
        )));
    }
    let mut b = SceneBuilder::new(name);
    for (i, m) in materials.iter().enumerate() {
        b.add_material(material(i, m)?);
    }
    let vertices: Vec<Vertex> = vertices
        .iter()
        .map(|v| Vertex {
            position: v.position,
            normal: v.normal,
            uv: v.uv,
        })
        .collect();
    // Meshes over the same vertex range (an engine's one vertex buffer, indexed absolutely)
    // share its vertices once: the first mesh adds them, the others draw over them.
    let mut ranges: HashMap<(u32, u32), MeshId> = HashMap::new();
    for (i, m) in meshes.iter().enumerate() {
        let range = |first: u32, count: u32, len: usize, what: &str| {
            let (first, count) = (first as usize, count as usize);
            if first.checked_add(count).is_none_or(|end| end > len) {
                return Err(Failure::invalid(format!(
                    "meshes[{i}]: {what} {first}..{} is past the {len} given",
                    first.saturating_add(count)
                )));
            }
            Ok(first..first + count)
        };
        let v = range(m.first_vertex, m.vertex_count, vertices.len(), "vertices")?;
        let x = range(m.first_index, m.index_count, indices.len(), "indices")?;
        let material = MaterialId(m.material);
        match ranges.get(&(m.first_vertex, m.vertex_count)) {
            Some(&shared) => b.add_mesh_sharing(shared, &indices[x], material)?,
            None => {
                let id = b.add_mesh(&vertices[v], &indices[x], material)?;
                ranges.insert((m.first_vertex, m.vertex_count), id);
                id
            }
        };
    }
    for inst in instances {
        let transform = Transform::new(
            Mat3::from_cols_array(&inst.linear),
            DVec3::from_array(inst.translation),
        );
        b.add_instance(transform, MeshId(inst.mesh))?;
    }
    Ok(b.build(None)?)
}

/// Uploads nothing yet: builds a scene from plain arrays (a renderer uploads it). Every
/// element is checked: indices in range, finite values, existing materials and meshes.
///
/// # Safety
/// `desc` and its arrays are valid for their counts; `out_scene` is writable.
#[no_mangle]
pub unsafe extern "C" fn tg_scene_create(
    desc: *const TgSceneDesc,
    out_scene: *mut TgScene,
) -> TgStatus {
    boundary("tg_scene_create", || {
        // SAFETY: the caller's contract.
        let desc = unsafe { arg(desc, "desc") }?;
        // SAFETY: as above.
        let out_scene = unsafe { out(out_scene, "out_scene") }?;
        *out_scene = TgScene { raw: 0 };
        let scene = build(desc)?;
        *out_scene = TgScene {
            raw: registry::insert(Kind::Scene, scene)?,
        };
        Ok(())
    })
}

/// Loads a scene from a spec: a glTF path (.gltf or .glb), or a procedural scene such as
/// "city:300" (docs/SCENES.md).
///
/// # Safety
/// `spec` is a NUL-terminated string; `out_scene` is writable.
#[no_mangle]
pub unsafe extern "C" fn tg_scene_load(spec: *const c_char, out_scene: *mut TgScene) -> TgStatus {
    boundary("tg_scene_load", || {
        // SAFETY: the caller's contract.
        let spec = unsafe { string(spec, "spec") }?;
        // SAFETY: as above.
        let out_scene = unsafe { out(out_scene, "out_scene") }?;
        *out_scene = TgScene { raw: 0 };
        let scene = tilegraph_scene::load(spec)?;
        *out_scene = TgScene {
            raw: registry::insert(Kind::Scene, scene)?,
        };
        Ok(())
    })
}

/// Attaches prebuilt clusters to a scene, read from the file at `path` (written on the desktop
/// by `tilegraph scene-info SCENE --write-clusters FILE`, or by the engine's own asset
/// pipeline in that format): the cluster techniques (TG_CULLING_FRUSTUM_CLUSTERS,
/// TG_CULLING_HIZ_TWO_PHASE_CLUSTERS) need them. The file must have been built from this
/// scene's geometry; the scene's index buffer is then in cluster order. Refused with
/// TG_STATUS_IN_USE while renderers made from the scene exist.
///
/// # Safety
/// `path` is a NUL-terminated string.
#[no_mangle]
pub unsafe extern "C" fn tg_scene_attach_clusters(scene: TgScene, path: *const c_char) -> TgStatus {
    boundary("tg_scene_attach_clusters", || {
        // SAFETY: the caller's contract.
        let path = unsafe { string(path, "path") }?;
        let data = tilegraph_scene::clusters::ClusterData::read(std::path::Path::new(path))?;
        registry::with_unused_mut(scene.raw, Kind::Scene, "scene", |s: &mut Scene| {
            Ok(s.attach_clusters(data)?)
        })
    })
}

/// Destroys a scene (renderers drawing it are destroyed first: TG_STATUS_IN_USE otherwise).
/// A zero handle is a no-op.
#[no_mangle]
pub extern "C" fn tg_scene_destroy(scene: TgScene) -> TgStatus {
    boundary("tg_scene_destroy", || {
        if scene.raw == 0 {
            return Ok(());
        }
        registry::remove::<Scene>(scene.raw, Kind::Scene, "scene").map(drop)
    })
}

/// The number of instances and of cameras in the scene's camera path.
///
/// # Safety
/// The out-pointers are writable (either may be null).
#[no_mangle]
pub unsafe extern "C" fn tg_scene_counts(
    scene: TgScene,
    out_instances: *mut u32,
    out_path_cameras: *mut u32,
) -> TgStatus {
    boundary("tg_scene_counts", || {
        registry::with(scene.raw, Kind::Scene, "scene", |s: &Scene| {
            if !out_instances.is_null() {
                // SAFETY: the caller's contract.
                unsafe { *out(out_instances, "out_instances")? = s.instances().len() as u32 };
            }
            if !out_path_cameras.is_null() {
                // SAFETY: as above.
                unsafe {
                    *out(out_path_cameras, "out_path_cameras")? = s.camera_path().len() as u32
                };
            }
            Ok(())
        })
    })
}

/// Camera `index` of the scene's camera path, and whether the path cuts (jumps) to it.
///
/// # Safety
/// `out_camera` is writable; `out_cut` is writable or null.
#[no_mangle]
pub unsafe extern "C" fn tg_scene_path_camera(
    scene: TgScene,
    index: u32,
    out_camera: *mut TgCamera,
    out_cut: *mut u32,
) -> TgStatus {
    boundary("tg_scene_path_camera", || {
        // SAFETY: the caller's contract.
        let out_camera = unsafe { out(out_camera, "out_camera") }?;
        registry::with(scene.raw, Kind::Scene, "scene", |s: &Scene| {
            let keys = s.camera_path().keys();
            let key = keys.get(index as usize).ok_or_else(|| {
                Failure::invalid(format!(
                    "camera {index} is past the path's {} cameras",
                    keys.len()
                ))
            })?;
            *out_camera = TgCamera::from_camera(&key.camera);
            if !out_cut.is_null() {
                // SAFETY: the caller's contract.
                unsafe { *out(out_cut, "out_cut")? = u32::from(key.cut || index == 0) };
            }
            Ok(())
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An engine's meshes indexing one vertex buffer absolutely (each mesh's range the whole
    /// buffer) share it: the vertices are added once, not once per mesh.
    #[test]
    fn meshes_over_one_vertex_range_share_it() {
        let v = |x: f32, y: f32| TgVertex {
            position: [x, y, 0.0],
            normal: [0.0, 0.0, 1.0],
            uv: [x, y],
        };
        let vertices = [v(0.0, 0.0), v(1.0, 0.0), v(0.0, 1.0), v(1.0, 1.0)];
        let indices = [0u32, 1, 2, 1, 3, 2];
        let materials = [TgMaterial {
            base_color: [1.0; 4],
            material_class: TgMaterialClass::Opaque as u32,
            alpha_cutoff: 0.0,
            double_sided: 0,
        }];
        let mesh = |first_index: u32| TgMesh {
            first_vertex: 0,
            vertex_count: 4,
            first_index,
            index_count: 3,
            material: 0,
        };
        let meshes = [mesh(0), mesh(3)];
        let instances = [0u32, 1].map(|m| TgInstance {
            linear: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
            translation: [0.0, 0.0, -5.0],
            mesh: m,
        });
        let desc = TgSceneDesc {
            name: std::ptr::null(),
            vertices: vertices.as_ptr(),
            vertex_count: 4,
            indices: indices.as_ptr(),
            index_count: 6,
            materials: materials.as_ptr(),
            material_count: 1,
            meshes: meshes.as_ptr(),
            mesh_count: 2,
            instances: instances.as_ptr(),
            instance_count: 2,
        };
        let scene = build(&desc).unwrap();
        assert_eq!(scene.vertices().len(), 4);
        assert_eq!(scene.meshes().len(), 2);
        assert_eq!(scene.triangles_drawn(), 2);
    }
}
