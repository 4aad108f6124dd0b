//! Prebuilt clusters through the C ABI: a file written on the desktop attaches to the scene it
//! was built from, and a wrong file, a missing one or a null path is a status with a message.

use std::ffi::{CStr, CString};

use crate::scene::{tg_scene_attach_clusters, tg_scene_destroy, tg_scene_load};
use crate::status::tg_last_error;
use crate::{TgScene, TgStatus};

fn load(spec: &str) -> TgScene {
    let spec = CString::new(spec).unwrap();
    let mut scene = TgScene { raw: 0 };
    // SAFETY: a NUL-terminated spec and a writable out-pointer.
    assert_eq!(
        unsafe { tg_scene_load(spec.as_ptr(), &mut scene) },
        TgStatus::Ok
    );
    scene
}

fn attach(scene: TgScene, path: &std::path::Path) -> (TgStatus, String) {
    let path = CString::new(path.to_str().unwrap()).unwrap();
    // SAFETY: a NUL-terminated path.
    let status = unsafe { tg_scene_attach_clusters(scene, path.as_ptr()) };
    // SAFETY: tg_last_error returns a NUL-terminated string valid until the next call.
    let message = unsafe { CStr::from_ptr(tg_last_error()) }
        .to_string_lossy()
        .into_owned();
    (status, message)
}

#[test]
fn prebuilt_clusters_attach_to_their_scene_only() {
    let dir = std::env::temp_dir().join(format!("tilegraph-capi-clusters-{}", std::process::id()));
    let write = |spec: &str| {
        let scene = tilegraph_scene::load(spec).unwrap();
        let (data, _) = tilegraph_scene::clusters::build(&scene).unwrap();
        let path = dir.join(format!("{}.tgclusters", spec.replace(':', "-")));
        data.write(&path).unwrap();
        path
    };
    let interior = write("interior:40");
    let forest = write("forest:40");
    let scene = load("interior:40");
    let (status, message) = attach(scene, &forest);
    assert_eq!(status, TgStatus::Scene, "{message}");
    assert!(message.contains("fingerprint"), "{message}");
    let (status, message) = attach(scene, &dir.join("missing.tgclusters"));
    assert_eq!(status, TgStatus::Scene, "{message}");
    assert!(message.contains("missing.tgclusters"), "{message}");
    // SAFETY: a null path is reported, not read.
    assert_eq!(
        unsafe { tg_scene_attach_clusters(scene, std::ptr::null()) },
        TgStatus::NullPointer
    );
    let (status, message) = attach(scene, &interior);
    assert_eq!(status, TgStatus::Ok, "{message}");
    assert_eq!(tg_scene_destroy(scene), TgStatus::Ok);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// With clusters attached, the copy of a mesh with its winding turned (what mirroring
/// instances draw) is made through the ABI, once; a handle that names no mesh is an invalid
/// handle.
#[test]
fn a_mirrored_copy_is_prepared_with_clusters_attached() {
    use crate::changes::{tg_scene_mesh_handle, tg_scene_prepare_mirroring};
    let spec = "forest:30";
    let built = tilegraph_scene::load(spec).unwrap();
    let meshes = built.meshes().len() as u32;
    let (data, _) = tilegraph_scene::clusters::build(&built).unwrap();
    let path = std::env::temp_dir().join(format!(
        "tilegraph-capi-mirror-{}.tgclusters",
        std::process::id()
    ));
    data.write(&path).unwrap();
    let scene = load(spec);
    let (status, message) = attach(scene, &path);
    assert_eq!(status, TgStatus::Ok, "{message}");
    let mut mesh = 0u64;
    // SAFETY: a writable out-pointer.
    assert_eq!(
        unsafe { tg_scene_mesh_handle(scene, 0, &mut mesh) },
        TgStatus::Ok
    );
    let mut copy = 0u64;
    // SAFETY: as above.
    let copy_status = |copy: &mut u64| unsafe { tg_scene_mesh_handle(scene, meshes, copy) };
    assert_eq!(
        copy_status(&mut copy),
        TgStatus::InvalidArgument,
        "no copy yet"
    );
    assert_eq!(tg_scene_prepare_mirroring(scene, mesh), TgStatus::Ok);
    assert_eq!(tg_scene_prepare_mirroring(scene, mesh), TgStatus::Ok);
    assert_eq!(
        copy_status(&mut copy),
        TgStatus::Ok,
        "the copy is mesh {meshes}"
    );
    // SAFETY: as above.
    let after = unsafe { tg_scene_mesh_handle(scene, meshes + 1, &mut copy) };
    assert_eq!(after, TgStatus::InvalidArgument, "made once");
    assert_eq!(
        tg_scene_prepare_mirroring(scene, u64::MAX),
        TgStatus::InvalidHandle
    );
    assert_eq!(tg_scene_destroy(scene), TgStatus::Ok);
    std::fs::remove_file(&path).unwrap();
}
