//! Property tests of the frustum tests: the plane test never rejects what the SAT accepts, and
//! the SAT never rejects a box that has a point inside the frustum.

use glam::{Affine3A, DVec3, EulerRot, Mat4, Quat, Vec3};
use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use tilegraph_cull::{Aabb, AabbExt, DepthConvention, Frustum, Obb, Projection};

/// A projection and the aspect of the viewport it is used on.
fn projection(kind: u8) -> (Projection, f32) {
    let (s, r) = (DepthConvention::Standard, DepthConvention::Reverse);
    let perspective = |fov_y_rad, near, far, depth| Projection::Perspective {
        fov_y_rad,
        near,
        far,
        depth,
    };
    let orthographic = |half_height, near, far, depth| Projection::Orthographic {
        half_height,
        near,
        far,
        depth,
    };
    match kind % 6 {
        0 => (Projection::tilegraph_default(1.1, 0.1), 1.6),
        1 => (perspective(0.8, 0.05, Some(60.0), r), 1.0),
        2 => (perspective(1.4, 0.5, Some(40.0), s), 2.0),
        3 => (perspective(0.5, 0.01, None, s), 0.7),
        // 30 m x 20 m and 12 m x 24 m.
        4 => (orthographic(10.0, -5.0, 50.0, s), 1.5),
        _ => (orthographic(12.0, 1.0, 30.0, r), 0.5),
    }
}

struct Setup {
    frustum: Frustum,
    eye: Vec3,
    forward: Vec3,
}

fn setup(kind: u8, eye: [f32; 3], yaw: f32, pitch: f32, roll: f32) -> Setup {
    let (p, aspect) = projection(kind);
    let eye = Vec3::from(eye);
    let rot = Quat::from_euler(EulerRot::YXZ, yaw, pitch, roll);
    let forward = rot * Vec3::NEG_Z;
    let up = rot * Vec3::Y;
    let view = Mat4::look_at_rh(eye, eye + forward, up);
    let frustum =
        Frustum::from_clip_from_world(&(p.matrix(aspect) * view), p.depth_convention()).unwrap();
    Setup {
        frustum,
        eye,
        forward,
    }
}

/// Points of the box to probe: corners, face centres, the centre, and random interior points.
fn samples(obb: &Obb, rng: &mut Pcg64) -> Vec<DVec3> {
    let c = obb.center_f64();
    let e = obb.half_edges_f64();
    let mut out = Vec::new();
    for i in -1..=1 {
        for j in -1..=1 {
            for k in -1..=1 {
                out.push(c + e[0] * f64::from(i) + e[1] * f64::from(j) + e[2] * f64::from(k));
            }
        }
    }
    for _ in 0..200 {
        let s: [f64; 3] = std::array::from_fn(|_| rng.random_range(-1.0..=1.0));
        out.push(c + e[0] * s[0] + e[1] * s[1] + e[2] * s[2]);
    }
    out
}

proptest! {
    // PROPTEST_CASES asks for more (an explicit `cases` would ignore it).
    #![proptest_config(ProptestConfig {
        cases: std::env::var("PROPTEST_CASES").ok().and_then(|v| v.parse().ok()).unwrap_or(1024),
        ..ProptestConfig::default()
    })]

    #[test]
    fn plane_rejection_implies_sat_rejection_and_sat_rejection_is_sound(
        kind in 0u8..6,
        eye in prop::array::uniform3(-50.0f32..50.0),
        yaw in -3.2f32..3.2, pitch in -1.5f32..1.5, roll in -3.2f32..3.2,
        dist in -10.0f32..70.0,
        offset in prop::array::uniform3(-30.0f32..30.0),
        half in prop::array::uniform3(0.0f32..15.0),
        flat_axis in 0usize..5,
        box_rot in prop::array::uniform3(-3.2f32..3.2),
        seed in any::<u64>(),
    ) {
        let s = setup(kind, eye, yaw, pitch, roll);
        let center = s.eye + s.forward * dist + Vec3::from(offset);
        let mut half = Vec3::from(half);
        if flat_axis < 3 {
            half[flat_axis] = 0.0; // zero-extent boxes (flat, or a segment/point when repeated)
        }
        let aabb = Aabb::from_center_half_extents(center, half).unwrap();
        let obb = Obb::new(
            Aabb::from_center_half_extents(Vec3::ZERO, half).unwrap(),
            Affine3A::from_rotation_translation(Quat::from_euler(EulerRot::XYZ, box_rot[0], box_rot[1], box_rot[2]), center),
        ).unwrap();
        let mut rng = Pcg64::seed_from_u64(seed);
        for (label, plane, sat, probe) in [
            ("aabb", s.frustum.test_aabb(&aabb).unwrap(), s.frustum.sat_aabb(&aabb).unwrap(), Obb::from(aabb)),
            ("obb", s.frustum.test_obb(&obb).unwrap(), s.frustum.sat_obb(&obb).unwrap(), obb),
        ] {
            prop_assert!(!plane.is_outside() || sat.is_separated(), "{label}: plane {plane:?} but sat {sat:?}");
            if sat.is_separated() {
                for p in samples(&probe, &mut rng) {
                    prop_assert!(!s.frustum.contains_point(p), "{label}: {sat:?} but {p} is inside");
                }
            }
        }
    }
}

/// Non-vacuity: on a fixed scatter of boxes the SAT separates strictly more than the plane test
/// for every projection kind (the plane test's false positives exist and are found).
#[test]
fn sat_finds_plane_test_false_positives_for_every_projection() {
    for kind in 0..6u8 {
        let s = setup(kind, [1.0, 2.0, 3.0], 0.4, 0.2, 0.7);
        let mut rng = Pcg64::seed_from_u64(u64::from(kind));
        let boxes: Vec<Aabb> = (0..3000)
            .map(|_| {
                let c = s.eye
                    + s.forward * rng.random_range(-5.0..60.0)
                    + Vec3::new(
                        rng.random_range(-40.0..40.0),
                        rng.random_range(-40.0..40.0),
                        rng.random_range(-40.0..40.0),
                    );
                let h = Vec3::new(
                    rng.random_range(0.0..6.0),
                    rng.random_range(0.0..6.0),
                    rng.random_range(0.0..6.0),
                );
                Aabb::from_center_half_extents(c, h).unwrap()
            })
            .collect();
        let acc = tilegraph_cull::measure_plane_test_false_positives(&s.frustum, &boxes).unwrap();
        assert_eq!(acc.plane_wrongly_rejected, 0, "kind {kind}: {acc:?}");
        assert!(acc.plane_false_positives > 0, "kind {kind}: {acc:?}");
        assert!(acc.sat_outside > acc.plane_outside);
    }
}
