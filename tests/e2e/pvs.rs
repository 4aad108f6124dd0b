//! Precomputed visible sets on lavapipe (validation on): a set baked with the oracle's id
//! render is exact at its own viewpoints (a camera there, with the bake's faces and
//! resolution, culls no visible instance and draws the unculled image); dilation only adds
//! instances and never adds a miss; outside the baked region every instance in the frustum is
//! drawn; a set baked for other geometry is a typed error; the file round-trips.

use std::sync::Arc;

use tilegraph_passes::cull::Culling;
use tilegraph_passes::cullcheck::{cull_check_options, CheckExtras, CullCheck};
use tilegraph_passes::pvs::{face_cameras, viewpoints};
use tilegraph_passes::{RenderError, RenderOptions, SceneRenderer};
use tilegraph_scene::{CameraPath, PathKey, Scene};
use tilegraph_vk::Context;

const FACE: u32 = 32;

fn check(g: &Context, scene: &Scene, options: RenderOptions, path: &CameraPath) -> CullCheck {
    cull_check_options(g, scene, options, path, None, CheckExtras::default()).unwrap()
}

#[test]
fn a_visible_set_is_exact_at_its_samples_and_dilation_only_adds() {
    let scene = tilegraph_scene::load("city:300").unwrap();
    let own = scene.camera_path().clone();
    let (g, spec, pvs) = tilegraph_e2e::bake_path_pvs(&scene, FACE);
    pvs.validate().unwrap();
    let (dims, eyes) = viewpoints(&spec);
    assert_eq!(pvs.dims, dims);
    assert_eq!(pvs.cells.len(), eyes.len());
    let stored = pvs.stored_ids();
    println!(
        "{} cells ({:?}), {stored} ids, {:.1} s",
        pvs.cells.len(),
        pvs.dims,
        pvs.bake_seconds
    );
    assert!(stored > 0);
    // The file round-trips.
    let text = serde_json::to_string(&pvs).unwrap();
    let back: tilegraph_cull::Pvs = serde_json::from_str(&text).unwrap();
    assert!(back.cells == pvs.cells && back.dims == pvs.dims && back.instances == pvs.instances);
    // JSON keeps f64 to within an ulp (serde_json without float_roundtrip).
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-12 * a.abs().max(1.0);
    assert!((0..3).all(|a| close(back.cell[a], pvs.cell[a])));
    assert!((0..3).all(|a| close(back.origin[a], pvs.origin[a])));
    let pvs = Arc::new(pvs);
    let options = |dilation: u32, size: u32| RenderOptions {
        width: size,
        height: size,
        culling: Culling::Pvs,
        pvs: Some(Arc::clone(&pvs)),
        pvs_dilation: dilation,
        ..Default::default()
    };

    // Exact at its samples: the six faces of a cell's viewpoint, at the bake's resolution.
    let busiest = (0..pvs.cells.len())
        .max_by_key(|&k| pvs.cells[k].len())
        .unwrap();
    let keys: Vec<PathKey> = face_cameras(eyes[busiest][0])
        .into_iter()
        .map(|camera| PathKey { camera, cut: true })
        .collect();
    let faces = CameraPath::new("the bake's faces", keys).unwrap();
    let r = check(&g, &scene, options(0, FACE), &faces);
    assert!(r.totals.visible > 0);
    for f in &r.frames {
        assert_eq!(
            f.false_negatives, 0,
            "face {} culled {:?}",
            f.frame, f.false_negative_ids
        );
        assert!(
            f.image_equal,
            "face {}: {} pixels differ",
            f.frame, f.image_diff_pixels
        );
    }

    // Dilation only adds: per frame, more drawn and no more missed.
    let path = CameraPath::new("first frames", own.keys()[..12.min(own.len())].to_vec()).unwrap();
    let tight = check(&g, &scene, options(0, 96), &path);
    let wide = check(&g, &scene, options(1, 96), &path);
    for (a, b) in tight.frames.iter().zip(&wide.frames) {
        assert!(
            b.drawn >= a.drawn,
            "frame {}: {} < {}",
            a.frame,
            b.drawn,
            a.drawn
        );
        assert!(b.false_negatives <= a.false_negatives, "frame {}", a.frame);
    }
    println!(
        "dilation 0: drawn {} FN {}; dilation 1: drawn {} FN {}",
        tight.totals.drawn,
        tight.totals.false_negatives,
        wide.totals.drawn,
        wide.totals.false_negatives
    );

    // Outside the region: everything in the frustum, as frustum culling on the CPU lists.
    let mut far = own.keys()[0];
    let away = glam::DVec3::new(0.0, 5000.0, 0.0);
    far.camera.eye += away;
    far.camera.target += away;
    far.cut = true;
    let outside = CameraPath::new("outside", vec![far]).unwrap();
    let r = check(&g, &scene, options(0, 96), &outside);
    assert_eq!(r.totals.false_negatives, 0);

    // A set baked for other geometry is refused with a typed error.
    let other = tilegraph_scene::load("city:301").unwrap();
    match SceneRenderer::new(&g, &other, options(0, 96)) {
        Err(RenderError::Pvs { reason }) => assert!(reason.contains("other geometry"), "{reason}"),
        Err(e) => panic!("unexpected error {e}"),
        Ok(r) => {
            r.destroy(&g);
            panic!("a set for other geometry was accepted")
        }
    }
    // And culling pvs without one.
    let none = RenderOptions {
        pvs: None,
        ..options(0, 96)
    };
    assert!(matches!(
        SceneRenderer::new(&g, &scene, none),
        Err(RenderError::Pvs { .. })
    ));
}
