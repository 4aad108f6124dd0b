//! A scene a game changes every frame, through handles: meshes streamed in and out, instances
//! added, removed, moved in batches (one call per frame, not per object), hidden, given the
//! local box of an animated mesh. Every change applies at the renderers' next record. A stale
//! handle is `TG_STATUS_INVALID_HANDLE`, a NaN or infinite transform
//! `TG_STATUS_INVALID_ARGUMENT`, each with a message naming the entry; a failed batch changes
//! nothing.

use glam::{DVec3, Mat3, Vec3};
use tilegraph_scene::{
    Aabb, InstanceFlags, InstanceHandle, InstanceId, MaterialId, MeshHandle, MeshId, Scene,
    SceneError, Transform, Vertex,
};

use crate::registry::{self, Kind};
use crate::scene::{material, TgMaterial, TgScene, TgVertex};
use crate::status::{arg, array, boundary, out, out_array, Failure, TgStatus};

/// Kept in the scene, not drawn (nor culled: it costs nothing per frame).
pub const TG_INSTANCE_HIDDEN: u32 = 1;
/// Drawn into shadow maps (instances of a loaded or created scene have it).
pub const TG_INSTANCE_CASTS_SHADOWS: u32 = 2;

/// A placement: a column-major 3x3 linear part and an f64 translation.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct TgTransform {
    pub linear: [f32; 9],
    pub translation: [f64; 3],
}

/// An instance to add: a mesh handle (`tg_scene_add_mesh`, `tg_scene_mesh_handle`), where,
/// and its TG_INSTANCE_* flags.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct TgInstanceDesc {
    pub mesh: u64,
    pub transform: TgTransform,
    pub flags: u32,
}

impl TgTransform {
    fn to_transform(self) -> Transform {
        Transform::new(
            Mat3::from_cols_array(&self.linear),
            DVec3::from_array(self.translation),
        )
    }
}

/// A scene error of a change: a stale handle is an invalid handle, a non-finite value an
/// invalid argument, a mesh still drawn in use.
fn change_failure(e: SceneError) -> Failure {
    let status = match e {
        SceneError::StaleHandle { .. } => TgStatus::InvalidHandle,
        SceneError::NonFinite { .. } => TgStatus::InvalidArgument,
        SceneError::MeshInUse { .. } => TgStatus::InUse,
        _ => TgStatus::Scene,
    };
    Failure::new(status, e.to_string())
}

/// Flags from their bits; `what` names the argument in the error (made only then).
fn flags(bits: u32, what: impl Fn() -> String) -> Result<InstanceFlags, Failure> {
    InstanceFlags::from_bits(bits).ok_or_else(|| {
        Failure::invalid(format!(
            "{}: flags {bits:#x} hold bits that are no TG_INSTANCE_* flag",
            what()
        ))
    })
}

thread_local! {
    /// A batch of moves as the scene takes them (kept: no allocation per frame).
    static MOVES: std::cell::RefCell<Vec<(InstanceHandle, Transform)>> =
        const { std::cell::RefCell::new(Vec::new()) };
}

/// Runs `f` on the scene, which renderers may draw: they follow its changes.
fn edit<R>(scene: TgScene, f: impl FnOnce(&mut Scene) -> Result<R, Failure>) -> Result<R, Failure> {
    registry::with_mut(scene.raw, Kind::Scene, "scene", f)
}

/// Adds a material; its index goes to `out_material`.
///
/// # Safety
/// `material` is readable, `out_material` writable.
#[no_mangle]
pub unsafe extern "C" fn tg_scene_add_material(
    scene: TgScene,
    material_desc: *const TgMaterial,
    out_material: *mut u32,
) -> TgStatus {
    boundary("tg_scene_add_material", || {
        // SAFETY: the caller's contract.
        let m = unsafe { arg(material_desc, "material") }?;
        // SAFETY: as above.
        let out_material = unsafe { out(out_material, "out_material") }?;
        let m = material(0, m)?;
        *out_material = edit(scene, |s| s.add_material(m).map_err(change_failure))?.0;
        Ok(())
    })
}

/// Adds a mesh: its vertices and indices (relative to its first vertex) go into free ranges of
/// the scene's shared buffers; renderers copy them to the GPU at their next record. Its handle
/// goes to `out_mesh`. Refused (TG_STATUS_SCENE) on a scene with clusters attached.
///
/// # Safety
/// The arrays hold their counts; `out_mesh` is writable.
#[no_mangle]
pub unsafe extern "C" fn tg_scene_add_mesh(
    scene: TgScene,
    vertices: *const TgVertex,
    vertex_count: u32,
    indices: *const u32,
    index_count: u32,
    material_index: u32,
    out_mesh: *mut u64,
) -> TgStatus {
    boundary("tg_scene_add_mesh", || {
        // SAFETY: the caller's contract.
        let (v, i, out_mesh) = unsafe {
            (
                array(vertices, vertex_count as usize, "vertices")?,
                array(indices, index_count as usize, "indices")?,
                out(out_mesh, "out_mesh")?,
            )
        };
        *out_mesh = 0;
        let v: Vec<Vertex> = v
            .iter()
            .map(|v| Vertex {
                position: v.position,
                normal: v.normal,
                uv: v.uv,
            })
            .collect();
        let h = edit(scene, |s| {
            s.add_mesh(&v, i, MaterialId(material_index))
                .map_err(Failure::from)
        })?;
        *out_mesh = h.to_bits();
        Ok(())
    })
}

/// Removes a mesh no instance draws any more (TG_STATUS_IN_USE otherwise); its ranges of the
/// shared buffers are free for the next mesh.
#[no_mangle]
pub extern "C" fn tg_scene_remove_mesh(scene: TgScene, mesh: u64) -> TgStatus {
    boundary("tg_scene_remove_mesh", || {
        edit(scene, |s| {
            s.remove_mesh(MeshHandle::from_bits(mesh))
                .map_err(change_failure)
        })
    })
}

/// Makes the copy of `mesh` with its winding reversed that instances under a mirroring
/// transform (negative determinant) draw, if not made yet. Instances make it themselves on
/// first use, except on a scene with clusters attached (its geometry is fixed): there a mesh
/// an instance may mirror needs this call before `tg_scene_attach_clusters`.
#[no_mangle]
pub extern "C" fn tg_scene_prepare_mirroring(scene: TgScene, mesh: u64) -> TgStatus {
    boundary("tg_scene_prepare_mirroring", || {
        edit(scene, |s| {
            s.prepare_mirroring(MeshHandle::from_bits(mesh))
                .map_err(change_failure)
        })
    })
}

/// The handle of mesh `index` of a loaded or created scene (its meshes in order).
///
/// # Safety
/// `out_mesh` is writable.
#[no_mangle]
pub unsafe extern "C" fn tg_scene_mesh_handle(
    scene: TgScene,
    index: u32,
    out_mesh: *mut u64,
) -> TgStatus {
    boundary("tg_scene_mesh_handle", || {
        // SAFETY: the caller's contract.
        let out_mesh = unsafe { out(out_mesh, "out_mesh") }?;
        registry::with(scene.raw, Kind::Scene, "scene", |s: &Scene| {
            let h = s.mesh_handle(MeshId(index)).ok_or_else(|| {
                Failure::invalid(format!(
                    "no mesh {index} (the scene has {} mesh slots)",
                    s.meshes().len()
                ))
            })?;
            *out_mesh = h.to_bits();
            Ok(())
        })
    })
}

/// The handle of instance `index` of a loaded or created scene (its instances in order).
///
/// # Safety
/// `out_instance` is writable.
#[no_mangle]
pub unsafe extern "C" fn tg_scene_instance_handle(
    scene: TgScene,
    index: u32,
    out_instance: *mut u64,
) -> TgStatus {
    boundary("tg_scene_instance_handle", || {
        // SAFETY: the caller's contract.
        let out_instance = unsafe { out(out_instance, "out_instance") }?;
        registry::with(scene.raw, Kind::Scene, "scene", |s: &Scene| {
            let h = s.instance_handle(InstanceId(index)).ok_or_else(|| {
                Failure::new(
                    TgStatus::InvalidHandle,
                    format!("no live instance in slot {index}"),
                )
            })?;
            *out_instance = h.to_bits();
            Ok(())
        })
    })
}

/// Adds `count` instances; their handles go to `out_instances` (in order). All or nothing: an
/// error (a stale mesh handle, a non-finite transform, unknown flags) names the entry and adds
/// none. An instance under a mirroring transform (negative determinant) draws its mesh with
/// the winding reversed, so its front faces stay front (`tg_scene_prepare_mirroring`).
///
/// # Safety
/// `descs` holds `count` elements, `out_instances` room for `count`.
#[no_mangle]
pub unsafe extern "C" fn tg_scene_add_instances(
    scene: TgScene,
    descs: *const TgInstanceDesc,
    count: u32,
    out_instances: *mut u64,
) -> TgStatus {
    boundary("tg_scene_add_instances", || {
        // SAFETY: the caller's contract.
        let (descs, outs) = unsafe {
            (
                array(descs, count as usize, "descs")?,
                out_array(out_instances, count as usize, "out_instances")?,
            )
        };
        edit(scene, |s| {
            for (k, d) in descs.iter().enumerate() {
                let f = flags(d.flags, || format!("descs[{k}]"))?;
                match s.add_instance(MeshHandle::from_bits(d.mesh), d.transform.to_transform(), f) {
                    Ok(h) => outs[k] = h.to_bits(),
                    Err(e) => {
                        for &added in &outs[..k] {
                            // Just added: live, so this cannot fail.
                            let _ = s.remove_instance(InstanceHandle::from_bits(added));
                        }
                        let f = change_failure(e);
                        return Err(Failure::new(f.status, format!("descs[{k}]: {}", f.message)));
                    }
                }
            }
            Ok(())
        })
    })
}

/// Removes `count` instances. All or nothing: a stale or repeated handle names the entry and
/// removes none.
///
/// # Safety
/// `instances` holds `count` elements.
#[no_mangle]
pub unsafe extern "C" fn tg_scene_remove_instances(
    scene: TgScene,
    instances: *const u64,
    count: u32,
) -> TgStatus {
    boundary("tg_scene_remove_instances", || {
        // SAFETY: the caller's contract.
        let ids = unsafe { array(instances, count as usize, "instances") }?;
        edit(scene, |s| {
            for (k, &raw) in ids.iter().enumerate() {
                let h = InstanceHandle::from_bits(raw);
                s.instance(h).map_err(|e| {
                    let f = change_failure(e);
                    Failure::new(f.status, format!("instances[{k}]: {}", f.message))
                })?;
                if ids[..k].contains(&raw) {
                    return Err(Failure::invalid(format!(
                        "instances[{k}]: the same handle as an earlier entry"
                    )));
                }
            }
            for &raw in ids {
                s.remove_instance(InstanceHandle::from_bits(raw))
                    .map_err(change_failure)?;
            }
            Ok(())
        })
    })
}

/// Moves `count` instances: `instances[k]` to `transforms[k]`. One call a frame for every
/// moving object. All or nothing: a stale handle or a non-finite transform names the entry and
/// moves none. A transform that turns mirroring (or back) switches the winding drawn.
///
/// # Safety
/// Both arrays hold `count` elements.
#[no_mangle]
pub unsafe extern "C" fn tg_scene_set_transforms(
    scene: TgScene,
    instances: *const u64,
    transforms: *const TgTransform,
    count: u32,
) -> TgStatus {
    boundary("tg_scene_set_transforms", || {
        // SAFETY: the caller's contract.
        let (ids, ts) = unsafe {
            (
                array(instances, count as usize, "instances")?,
                array(transforms, count as usize, "transforms")?,
            )
        };
        MOVES.with(|moves| {
            let mut moves = moves.borrow_mut();
            moves.clear();
            moves.extend(
                ids.iter()
                    .zip(ts)
                    .map(|(&h, t)| (InstanceHandle::from_bits(h), t.to_transform())),
            );
            edit(scene, |s| s.set_transforms(&moves).map_err(change_failure))
        })
    })
}

/// Sets `count` instances' TG_INSTANCE_* flags: `flags[k]` for `instances[k]`. All or nothing.
///
/// # Safety
/// Both arrays hold `count` elements.
#[no_mangle]
pub unsafe extern "C" fn tg_scene_set_flags(
    scene: TgScene,
    instances: *const u64,
    flag_bits: *const u32,
    count: u32,
) -> TgStatus {
    boundary("tg_scene_set_flags", || {
        // SAFETY: the caller's contract.
        let (ids, bits) = unsafe {
            (
                array(instances, count as usize, "instances")?,
                array(flag_bits, count as usize, "flags")?,
            )
        };
        edit(scene, |s| {
            for (k, (&raw, &b)) in ids.iter().zip(bits).enumerate() {
                flags(b, || format!("flags[{k}]"))?;
                s.instance(InstanceHandle::from_bits(raw)).map_err(|e| {
                    let f = change_failure(e);
                    Failure::new(f.status, format!("instances[{k}]: {}", f.message))
                })?;
            }
            for (&raw, &b) in ids.iter().zip(bits) {
                let f = flags(b, || "flags".into())?;
                s.set_flags(InstanceHandle::from_bits(raw), f)
                    .map_err(change_failure)?;
            }
            Ok(())
        })
    })
}

/// Gives an instance the local box of its animated mesh (a skinned character: the box of every
/// pose), which culling then tests; null `min` and `max` give it back its mesh's box.
///
/// # Safety
/// `min` and `max` are both null or both readable float[3].
#[no_mangle]
pub unsafe extern "C" fn tg_scene_set_local_bounds(
    scene: TgScene,
    instance: u64,
    min: *const [f32; 3],
    max: *const [f32; 3],
) -> TgStatus {
    boundary("tg_scene_set_local_bounds", || {
        let local = if min.is_null() && max.is_null() {
            None
        } else {
            // SAFETY: the caller's contract.
            let (lo, hi) = unsafe { (arg(min, "min")?, arg(max, "max")?) };
            Some(Aabb::new(Vec3::from_array(*lo), Vec3::from_array(*hi)))
        };
        edit(scene, |s| {
            s.set_local_bounds(InstanceHandle::from_bits(instance), local)
                .map_err(change_failure)
        })
    })
}

/// Where a live instance is.
///
/// # Safety
/// `out_transform` is writable.
#[no_mangle]
pub unsafe extern "C" fn tg_scene_instance_transform(
    scene: TgScene,
    instance: u64,
    out_transform: *mut TgTransform,
) -> TgStatus {
    boundary("tg_scene_instance_transform", || {
        // SAFETY: the caller's contract.
        let out_transform = unsafe { out(out_transform, "out_transform") }?;
        registry::with(scene.raw, Kind::Scene, "scene", |s: &Scene| {
            let t = s
                .instance(InstanceHandle::from_bits(instance))
                .map_err(change_failure)?
                .transform;
            *out_transform = TgTransform {
                linear: t.linear.to_cols_array(),
                translation: t.translation.to_array(),
            };
            Ok(())
        })
    })
}
