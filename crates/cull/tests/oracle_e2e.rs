//! End to end against the oracle: random box scenes are ray-cast into a depth and an id buffer;
//! the exact visible set comes from the id buffer; the drawn set is what survives the frustum
//! test and HiZ (built from that same depth, so every visible object's own pixels are in it).
//! No visible object may be culled (FN = 0), in either NPOT fix, convention or depth format.

use glam::{EulerRot, Mat4, Quat, Vec3};
use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use tilegraph_cull::reference::{render_boxes, BACKGROUND_ID};
use tilegraph_cull::{
    project_aabb, visible_set_from_id_buffer, Aabb, AabbExt, CullStats, DepthConvention,
    DepthFormat, Extent2d, ExtentExt, Frustum, HizPyramid, InstanceSet, NpotMode, Projection,
};

/// A projection used on a viewport of any aspect (the orthographic ones are 30 and 40 m tall).
fn projection(kind: u32) -> Projection {
    let (s, r) = (DepthConvention::Standard, DepthConvention::Reverse);
    match kind % 5 {
        0 => Projection::tilegraph_default(1.0, 0.1),
        1 => Projection::Perspective {
            fov_y_rad: 1.2,
            near: 0.05,
            far: Some(80.0),
            depth: r,
        },
        2 => Projection::Perspective {
            fov_y_rad: 0.9,
            near: 0.2,
            far: Some(120.0),
            depth: s,
        },
        3 => Projection::Orthographic {
            half_height: 15.0,
            near: -10.0,
            far: 100.0,
            depth: s,
        },
        _ => Projection::Orthographic {
            half_height: 20.0,
            near: 0.0,
            far: 90.0,
            depth: r,
        },
    }
}

struct Outcome {
    stats: Vec<CullStats>,
}

fn run_scene(seed: u64) -> Outcome {
    let mut rng = Pcg64::seed_from_u64(seed);
    let sizes = [
        (27u32, 13u32),
        (64, 48),
        (33, 17),
        (40, 40),
        (1, 1),
        (2, 1),
        (3, 3),
        (96, 7),
    ];
    let (w, h) = sizes[rng.random_range(0..sizes.len())];
    let extent = Extent2d::try_new(w, h).unwrap();
    let (p, aspect) = (projection(rng.random_range(0..5)), w as f32 / h as f32);
    let conv = p.depth_convention();
    let format = if rng.random_range(0..2u32) == 0 {
        DepthFormat::D32Float
    } else {
        DepthFormat::D16Unorm
    };
    let rot = Quat::from_euler(
        EulerRot::YXZ,
        rng.random_range(-3.2..3.2),
        rng.random_range(-0.8..0.8),
        0.0,
    );
    let eye = Vec3::new(
        rng.random_range(-5.0..5.0),
        rng.random_range(-5.0..5.0),
        rng.random_range(-5.0..5.0),
    );
    let forward = rot * Vec3::NEG_Z;
    let view = Mat4::look_at_rh(eye, eye + forward, rot * Vec3::Y);
    // Big occluders near the camera, many small objects behind them, some around and behind.
    let n = rng.random_range(10..60usize);
    let boxes: Vec<Aabb> = (0..n)
        .map(|i| {
            let dist = if i < 4 {
                rng.random_range(3.0..12.0)
            } else {
                rng.random_range(-10.0..70.0)
            };
            let spread = if i < 4 { 4.0 } else { 25.0 };
            let c = eye
                + forward * dist
                + rot
                    * Vec3::new(
                        rng.random_range(-spread..spread),
                        rng.random_range(-spread..spread),
                        0.0,
                    );
            let half = if i < 4 {
                Vec3::new(
                    rng.random_range(2.0..8.0),
                    rng.random_range(2.0..8.0),
                    rng.random_range(0.1..1.0),
                )
            } else {
                Vec3::new(
                    rng.random_range(0.0..2.0),
                    rng.random_range(0.0..2.0),
                    rng.random_range(0.0..2.0),
                )
            };
            Aabb::from_center_half_extents(c, half).unwrap()
        })
        .collect();
    let render = render_boxes(&view, &p, aspect, extent, format, &boxes);
    let visible = visible_set_from_id_buffer(&render.ids, BACKGROUND_ID);
    let frustum = Frustum::from_clip_from_world(&(p.matrix(aspect) * view), conv).unwrap();
    let mut stats = Vec::new();
    for mode in [NpotMode::EdgeAware, NpotMode::PadToPow2] {
        let hiz = HizPyramid::build(&render.depth, extent, conv, format, mode).unwrap();
        let drawn: InstanceSet = boxes
            .iter()
            .enumerate()
            .filter(|(_, b)| {
                !frustum.test_aabb(b).unwrap().is_outside()
                    && !hiz
                        .test_projection(&project_aabb(b, &view, &p, aspect).unwrap())
                        .unwrap()
                        .is_culled()
            })
            .map(|(i, _)| i as u32)
            .collect();
        let s = CullStats::compare(&visible, &drawn, n as u32).unwrap();
        assert_eq!(
            s.false_negatives, 0,
            "seed {seed} {mode:?} {conv:?} {format:?} {w}x{h}: visible ids culled: {:?}",
            s.false_negative_ids
        );
        stats.push(s);
    }
    Outcome { stats }
}

proptest! {
    // PROPTEST_CASES asks for more (an explicit `cases` would ignore it).
    #![proptest_config(ProptestConfig {
        cases: std::env::var("PROPTEST_CASES").ok().and_then(|v| v.parse().ok()).unwrap_or(256),
        ..ProptestConfig::default()
    })]

    #[test]
    fn no_visible_object_is_culled(seed in any::<u64>()) {
        run_scene(seed);
    }
}

/// Over a fixed set of scenes the pipeline does cull hidden objects (the FN = 0 property is not
/// met by culling nothing), and reports its numbers.
#[test]
fn culling_happens_and_is_reported() {
    let mut hidden = 0u32;
    let mut hidden_drawn = 0u32;
    for seed in 0..40 {
        for s in run_scene(seed).stats {
            hidden += s.instances - s.visible;
            hidden_drawn += s.false_positives;
        }
    }
    println!("hidden {hidden}, drawn anyway {hidden_drawn}");
    assert!(hidden > 0);
    assert!(
        hidden_drawn < hidden,
        "nothing hidden was culled: {hidden_drawn} of {hidden}"
    );
}
