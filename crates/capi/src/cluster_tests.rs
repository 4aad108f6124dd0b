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
