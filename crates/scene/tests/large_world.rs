//! Large coordinates: the same scene at the origin and 10^6 m away gives the same view-space
//! positions (within 1e-3 m) through the camera-relative path, and the naive f32 path does not.

use glam::{DVec3, Mat4, Vec3};
use tilegraph_scene::{generate, load_with, LoadOptions, ProceduralKind, ProceduralParams, Scene};

const FAR: DVec3 = DVec3::new(1.0e6, 0.0, 1.0e6);

/// View-space positions of the 8 local-box corners of every instance, camera-relative path.
fn view_space(scene: &Scene, frame: usize) -> Vec<Vec3> {
    let cam = scene.camera_path().camera(frame).unwrap();
    let view = cam.view_relative();
    let recs = scene.gpu_instances(cam.eye);
    let mut out = Vec::with_capacity(recs.len() * 8);
    for (r, inst) in recs.iter().zip(scene.instances()) {
        let local = scene.mesh(inst.mesh).unwrap().local_aabb;
        let mv = view * r.model_matrix();
        for k in 0..8 {
            let p = Vec3::new(
                if k & 1 == 0 { local.min.x } else { local.max.x },
                if k & 2 == 0 { local.min.y } else { local.max.y },
                if k & 4 == 0 { local.min.z } else { local.max.z },
            );
            out.push(mv.transform_point3(p));
        }
    }
    out
}

/// The same with absolute f32 matrices: what a renderer without camera-relative transforms does.
fn view_space_naive(scene: &Scene, frame: usize) -> Vec<Vec3> {
    let cam = scene.camera_path().camera(frame).unwrap();
    let view = Mat4::look_at_rh(cam.eye.as_vec3(), cam.target.as_vec3(), cam.up);
    let mut out = Vec::new();
    for inst in scene.instances() {
        let local = scene.mesh(inst.mesh).unwrap().local_aabb;
        let t = inst.transform;
        let model = Mat4::from_mat3(t.linear) * Mat4::IDENTITY;
        let model = Mat4::from_translation(t.translation.as_vec3()) * model;
        let mv = view * model;
        for k in 0..8 {
            let p = Vec3::new(
                if k & 1 == 0 { local.min.x } else { local.max.x },
                if k & 2 == 0 { local.min.y } else { local.max.y },
                if k & 4 == 0 { local.min.z } else { local.max.z },
            );
            out.push(mv.transform_point3(p));
        }
    }
    out
}

fn max_diff(a: &[Vec3], b: &[Vec3]) -> f32 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (*x - *y).length())
        .fold(0.0, f32::max)
}

#[test]
fn a_scene_far_from_the_origin_keeps_its_view_space_precision() {
    let near = generate(
        ProceduralKind::City,
        ProceduralParams {
            size: 2_000,
            seed: 11,
        },
    )
    .unwrap();
    let mut far = near.clone();
    far.translate(FAR);
    assert!(far.bounds().min.x > 0.99e6);
    for frame in [0, 40, near.camera_path().len() - 1] {
        let a = view_space(&near, frame);
        let b = view_space(&far, frame);
        let d = max_diff(&a, &b);
        println!("frame {frame}: camera-relative max difference {d:e} m");
        assert!(d < 1e-3, "frame {frame}: {d} m");
        // The naive path at 10^6 m is off by centimetres: the test can tell the two apart.
        let naive = max_diff(&a, &view_space_naive(&far, frame));
        println!("frame {frame}: naive f32 max difference {naive:e} m");
        assert!(naive > 1e-3, "frame {frame}: naive {naive}");
    }
}

#[test]
fn load_options_origin_moves_scene_and_camera_together() {
    let opts = LoadOptions {
        origin: FAR,
        ..LoadOptions::default()
    };
    let far = load_with("interior:500:2", &opts).unwrap();
    let near = load_with("interior:500:2", &LoadOptions::default()).unwrap();
    assert!((far.bounds().min - near.bounds().min - FAR).length() < 1e-6);
    let d = max_diff(&view_space(&near, 10), &view_space(&far, 10));
    assert!(d < 1e-3, "{d}");
    let (a, b) = (
        near.camera_path().camera(10).unwrap(),
        far.camera_path().camera(10).unwrap(),
    );
    assert_eq!(b.eye - a.eye, FAR);
}
