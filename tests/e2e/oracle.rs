//! The oracle tested on its own (lavapipe, validation on): the pixels the GPU visibility buffer
//! gives each instance — what `cull-check` takes as the exact visible set — against a CPU ray
//! caster in f64 (`tilegraph_cull::reference`), on random scenes of boxes, at the extremes of
//! projection (reverse and standard depth, finite and infinite far planes, near planes from
//! 1e-4 m, wide and narrow fields of view) and viewport (1x1, 7x369, 160x90). The two are
//! different machines — a rasterizer with snapped vertices against exact rays through pixel
//! centres — so they may disagree where a box's edge passes within a sub-pixel step of a pixel
//! centre; anything else is a bug in one of them. Held: at least 99 % of pixels agree, every box
//! either sees in 3 pixels or more the other sees too, and no id is invented.

use glam::{DVec3, Mat3, Vec3};
use tilegraph_cull::reference::{render_boxes, BACKGROUND_ID};
use tilegraph_cull::{Aabb, DepthFormat, Extent2d};
use tilegraph_e2e::gpu_with;
use tilegraph_passes::cull::Culling;
use tilegraph_passes::{RenderOptions, SceneRenderer, Technique};
use tilegraph_scene::{
    Camera, CameraPath, DepthConvention, Material, PathKey, Projection, Scene, SceneBuilder,
    Transform, Vertex,
};

/// A unit cube's 24 vertices (outward normals) and 36 indices, counter-clockwise from outside.
fn cube() -> (Vec<Vertex>, Vec<u32>) {
    let mut vertices = Vec::new();
    let mut indices = Vec::new();
    for axis in 0..3 {
        for sign in [-1.0f32, 1.0] {
            let mut n = [0.0; 3];
            n[axis] = sign;
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            let base = vertices.len() as u32;
            for (a, b) in [(-0.5, -0.5), (0.5, -0.5), (0.5, 0.5), (-0.5, 0.5)] {
                let mut p = [0.0; 3];
                p[axis] = 0.5 * sign;
                p[u] = a;
                p[v] = b;
                vertices.push(Vertex {
                    position: p,
                    normal: n,
                    uv: [0.0, 0.0],
                });
            }
            let quad = if sign > 0.0 {
                [0, 1, 2, 0, 2, 3]
            } else {
                [0, 2, 1, 0, 3, 2]
            };
            indices.extend(quad.iter().map(|i| base + i));
        }
    }
    (vertices, indices)
}

/// `n` random boxes in front of a camera at the origin looking down -z, none reaching within
/// 0.5 m of the eye (the rasterizer culls back faces; the ray caster sees a cut box's inside).
fn boxes(seed: u64, n: usize) -> Vec<Aabb> {
    // splitmix64: deterministic, no dependency.
    let mut state = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ 0x2545_F491_4F6C_DD1D;
    let mut unit = move || {
        state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f32 / (1u64 << 53) as f32
    };
    let mut range = move |a: f32, b: f32| a + (b - a) * unit();
    (0..n)
        .map(|_| {
            let c = Vec3::new(range(-12.0, 12.0), range(-8.0, 8.0), range(-40.0, -3.0));
            let h = Vec3::new(range(0.05, 2.5), range(0.05, 2.5), range(0.05, 2.5));
            Aabb::new(c - h, c + h)
        })
        .collect()
}

fn scene_of(boxes: &[Aabb], camera: Camera) -> Scene {
    let mut b = SceneBuilder::new("boxes");
    let material = b.add_material(Material::opaque([0.7, 0.6, 0.5, 1.0]));
    let (vertices, indices) = cube();
    let mesh = b.add_mesh(&vertices, &indices, material).unwrap();
    for bx in boxes {
        let size = bx.max - bx.min;
        let t = Transform::new(
            Mat3::from_diagonal(size),
            ((bx.min + bx.max) * 0.5).as_dvec3(),
        );
        b.add_instance(t, mesh).unwrap();
    }
    let path = CameraPath::new("one view", vec![PathKey { camera, cut: true }]).unwrap();
    b.build(Some(path)).unwrap()
}

#[test]
fn the_visibility_buffer_sees_what_a_ray_caster_sees() {
    let projections = [
        Projection::tilegraph_default(1.0, 0.1),
        Projection::Perspective {
            fov_y_rad: 2.6,
            near: 1e-4,
            far: None,
            depth: DepthConvention::Reverse,
        },
        Projection::Perspective {
            fov_y_rad: 0.9,
            near: 0.2,
            far: Some(60.0),
            depth: DepthConvention::Standard,
        },
        Projection::Perspective {
            fov_y_rad: 0.05,
            near: 1.0,
            far: Some(1000.0),
            depth: DepthConvention::Reverse,
        },
    ];
    let sizes = [(160u32, 90u32), (7, 369), (1, 1)];
    let options = |w, h| RenderOptions {
        technique: Technique::Visbuf,
        culling: Culling::None,
        capture_ids: true,
        width: w,
        height: h,
        ..Default::default()
    };
    let g = gpu_with(Some("lavapipe"), options(1, 1).device_features()).unwrap();
    let mut worst = 1.0f64;
    let mut boxes_seen = 0;
    for seed in 0..6u64 {
        let set = boxes(seed, 60);
        for (k, projection) in projections.iter().enumerate() {
            let (w, h) = sizes[(seed as usize + k) % sizes.len()];
            let camera = Camera {
                eye: DVec3::ZERO,
                target: DVec3::new(0.1, -0.05, -1.0),
                up: Vec3::Y,
                projection: *projection,
            };
            let scene = scene_of(&set, camera);
            let mut r = SceneRenderer::new(&g, &scene, options(w, h)).unwrap();
            r.render(&g, &scene, &camera).unwrap();
            let gpu = r.read_instance_ids(&g).unwrap().unwrap();
            r.destroy(&g);
            let extent = Extent2d::new(w, h);
            let view = camera.view_world().as_mat4();
            let aspect = w as f32 / h as f32;
            let cpu = render_boxes(
                &view,
                projection,
                aspect,
                extent,
                DepthFormat::D32Float,
                &set,
            );
            let what = format!("seed {seed}, projection {k}, {w}x{h}");
            assert_eq!(gpu.len(), cpu.ids.len(), "{what}");
            let agree = gpu.iter().zip(&cpu.ids).filter(|(a, b)| a == b).count();
            let share = agree as f64 / gpu.len() as f64;
            worst = worst.min(share);
            let count = |ids: &[u32], id: u32| ids.iter().filter(|&&x| x == id).count();
            for id in 0..set.len() as u32 {
                let (c, gp) = (count(&cpu.ids, id), count(&gpu, id));
                assert!(
                    !(c >= 3 && gp == 0),
                    "{what}: box {id} covers {c} pixels for the ray caster, none on the GPU"
                );
                assert!(
                    !(gp >= 3 && c == 0),
                    "{what}: box {id} covers {gp} pixels on the GPU, none for the ray caster"
                );
            }
            assert!(
                gpu.iter()
                    .all(|&id| id == BACKGROUND_ID || (id as usize) < set.len()),
                "{what}: an id no instance has"
            );
            if w * h >= 100 {
                assert!(
                    share >= 0.99,
                    "{what}: {agree} of {} pixels agree",
                    gpu.len()
                );
                let mut seen: Vec<u32> = gpu
                    .iter()
                    .copied()
                    .filter(|&i| i != BACKGROUND_ID)
                    .collect();
                seen.sort_unstable();
                seen.dedup();
                boxes_seen += seen.len();
            }
        }
    }
    println!("worst pixel agreement {worst:.4}, {boxes_seen} boxes in view over the cases");
    assert!(
        boxes_seen >= 100,
        "only {boxes_seen} boxes in view: the test compares little"
    );
}
