//! Precomputed visible sets: baked on the desktop by `tilegraph pvs` (docs/CULLING.md,
//! "Precomputed visible sets"), shipped with the game, read here from a file or from memory
//! (an Android asset), and handed to a renderer or a view that culls with `TG_CULLING_PVS`.

use std::ffi::c_char;
use std::sync::Arc;

use tilegraph_cull::Pvs;

use crate::registry::{self, Kind};
use crate::status::{array, boundary, out, string, Failure, TgStatus};

/// A precomputed visible set.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TgPvs {
    pub raw: u64,
}

/// What a visible set holds.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default)]
pub struct TgPvsInfo {
    /// The instance slots of the scene it was baked for.
    pub instances: u32,
    /// Cells per axis, and a cell's size per axis (m).
    pub cells: [u32; 3],
    pub cell_size: [f64; 3],
    /// Viewpoints sampled per cell, and the side in pixels of each of their six faces.
    pub samples: u32,
    pub face_px: u32,
    /// Instance ids stored over every cell.
    pub stored_ids: u64,
}

fn insert(pvs: Pvs, out_pvs: &mut TgPvs) -> Result<(), Failure> {
    *out_pvs = TgPvs {
        raw: registry::insert(Kind::Pvs, Arc::new(pvs))?,
    };
    Ok(())
}

fn invalid_set(e: tilegraph_cull::CullError) -> Failure {
    Failure::new(TgStatus::Scene, e.to_string())
}

/// Reads a visible set from the file at `path` (the JSON `tilegraph pvs` writes) and checks
/// it. A file that is not one is TG_STATUS_SCENE, its message says why. Like every handle, the
/// set belongs to the thread that made it: load it on the thread that makes the renderer.
///
/// # Safety
/// `path` is a NUL-terminated string; `out_pvs` is writable.
#[no_mangle]
pub unsafe extern "C" fn tg_pvs_load(path: *const c_char, out_pvs: *mut TgPvs) -> TgStatus {
    boundary("tg_pvs_load", || {
        // SAFETY: the caller's contract.
        let path = unsafe { string(path, "path") }?;
        // SAFETY: as above.
        let out_pvs = unsafe { out(out_pvs, "out_pvs") }?;
        *out_pvs = TgPvs { raw: 0 };
        let bytes = std::fs::read(path)
            .map_err(|e| Failure::new(TgStatus::Scene, format!("reading {path}: {e}")))?;
        insert(Pvs::from_json(&bytes).map_err(invalid_set)?, out_pvs)
    })
}

/// Reads a visible set from `size` bytes of a file's content (an Android asset read through
/// the AAssetManager, say); the bytes are not kept.
///
/// # Safety
/// `data` holds `size` readable bytes; `out_pvs` is writable.
#[no_mangle]
pub unsafe extern "C" fn tg_pvs_load_memory(
    data: *const u8,
    size: usize,
    out_pvs: *mut TgPvs,
) -> TgStatus {
    boundary("tg_pvs_load_memory", || {
        // SAFETY: the caller's contract.
        let bytes = unsafe { array(data, size, "data") }?;
        // SAFETY: as above.
        let out_pvs = unsafe { out(out_pvs, "out_pvs") }?;
        *out_pvs = TgPvs { raw: 0 };
        insert(Pvs::from_json(bytes).map_err(invalid_set)?, out_pvs)
    })
}

/// What `pvs` holds.
///
/// # Safety
/// `out_info` is writable.
#[no_mangle]
pub unsafe extern "C" fn tg_pvs_info(pvs: TgPvs, out_info: *mut TgPvsInfo) -> TgStatus {
    boundary("tg_pvs_info", || {
        // SAFETY: the caller's contract.
        let out_info = unsafe { out(out_info, "out_info") }?;
        registry::with(pvs.raw, Kind::Pvs, "pvs", |p: &Arc<Pvs>| {
            *out_info = TgPvsInfo {
                instances: p.instances,
                cells: p.dims,
                cell_size: p.cell,
                samples: p.samples,
                face_px: p.face_px,
                stored_ids: p.stored_ids() as u64,
            };
            Ok(())
        })
    })
}

/// Destroys a visible set. Renderers and views made with it keep their own reference, so it
/// may be destroyed as soon as they are made. A zero handle is a no-op.
#[no_mangle]
pub extern "C" fn tg_pvs_destroy(pvs: TgPvs) -> TgStatus {
    boundary("tg_pvs_destroy", || {
        if pvs.raw == 0 {
            return Ok(());
        }
        registry::remove::<Arc<Pvs>>(pvs.raw, Kind::Pvs, "pvs").map(drop)
    })
}

/// The set a description names (`None` for a zero handle).
pub(crate) fn of(pvs: TgPvs, name: &str) -> Result<Option<Arc<Pvs>>, Failure> {
    if pvs.raw == 0 {
        return Ok(None);
    }
    registry::with(pvs.raw, Kind::Pvs, name, |p: &Arc<Pvs>| {
        Ok(Some(Arc::clone(p)))
    })
}
