//! Property tests of bounds projection: the rect contains the projection of every point of the
//! volume, the sphere rect is tight, the nearest depth is never behind any point of the volume,
//! and the non-rect outcomes mean what they say.

use glam::{DVec3, EulerRot, Mat4, Quat, Vec3};
use proptest::prelude::*;
use tilegraph_cull::{
    project_aabb, project_sphere_view, Aabb, AabbExt, DepthConvention, Projection,
    ScreenProjection, Sphere,
};

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
        1 => (perspective(0.8, 1e-4, Some(1e7), r), 1.0),
        2 => (perspective(1.4, 0.5, Some(400.0), s), 2.0),
        3 => (perspective(0.5, 0.01, None, s), 0.7),
        // 30 m x 20 m and 12 m x 24 m.
        4 => (orthographic(10.0, -5.0, 500.0, s), 1.5),
        _ => (orthographic(12.0, 1.0, 300.0, r), 0.5),
    }
}

/// NDC x, y of a view-space point, and its view distance.
fn project_point(p: &Projection, aspect: f32, v: DVec3) -> (f64, f64, f64) {
    let (sx, sy) = p.ndc_scale(aspect);
    let dist = -v.z;
    let w = if p.is_perspective() { dist } else { 1.0 };
    (sx * v.x / w, sy * v.y / w, dist)
}

fn sphere_points(c: DVec3, r: f64, n: usize) -> impl Iterator<Item = DVec3> {
    (0..n).flat_map(move |i| {
        (0..n).map(move |j| {
            let theta = std::f64::consts::PI * i as f64 / (n - 1) as f64;
            let phi = 2.0 * std::f64::consts::PI * j as f64 / n as f64;
            c + DVec3::new(
                theta.sin() * phi.cos(),
                theta.sin() * phi.sin(),
                theta.cos(),
            ) * r
        })
    })
}

proptest! {
    // PROPTEST_CASES asks for more (an explicit `cases` would ignore it).
    #![proptest_config(ProptestConfig {
        cases: std::env::var("PROPTEST_CASES").ok().and_then(|v| v.parse().ok()).unwrap_or(1024),
        ..ProptestConfig::default()
    })]

    #[test]
    fn sphere_projection_is_conservative_and_tight(
        kind in 0u8..6,
        c in prop::array::uniform3(-60.0f32..60.0),
        r in 0.0f32..20.0,
    ) {
        let (p, aspect) = projection(kind);
        let s = Sphere::new(Vec3::from(c), r).unwrap();
        let center = s.center.as_dvec3();
        let radius = f64::from(r);
        let near = f64::from(p.near());
        match project_sphere_view(&s, &p, aspect).unwrap() {
            ScreenProjection::Projected(b) => {
                let conv = p.depth_convention();
                for q in sphere_points(center, radius, 120) {
                    let (x, y, dist) = project_point(&p, aspect, q);
                    prop_assert!(dist >= near * (1.0 - 1e-12));
                    let eps = 1e-9 * (1.0 + x.abs().max(y.abs()));
                    prop_assert!(x >= f64::from(b.rect_ndc.min.x) - eps && x <= f64::from(b.rect_ndc.max.x) + eps);
                    prop_assert!(y >= f64::from(b.rect_ndc.min.y) - eps && y <= f64::from(b.rect_ndc.max.y) + eps);
                    let d = p.depth_at_distance(dist);
                    prop_assert!(!conv.is_strictly_behind(b.nearest_depth, d as f32) || f64::from(b.nearest_depth) == d,
                        "nearest {} behind point depth {d}", b.nearest_depth);
                }
                // Tight: each rect edge is the image of a plane (through the eye for
                // perspective, parallel to the view axis for orthographic) that touches the
                // sphere. Checked analytically: sampling is useless near grazing angles, where
                // NDC changes arbitrarily fast along the surface.
                let (sx, sy) = p.ndc_scale(aspect);
                for (edge, scale, coord) in [
                    (b.rect_ndc.min.x, sx, center.x),
                    (b.rect_ndc.max.x, sx, center.x),
                    (b.rect_ndc.min.y, sy, center.y),
                    (b.rect_ndc.max.y, sy, center.y),
                ] {
                    let e = f64::from(edge);
                    let distance = if p.is_perspective() {
                        // Plane scale * u + e * z = 0 (u the axis coordinate).
                        (scale * coord + e * center.z).abs() / (scale * scale + e * e).sqrt()
                    } else {
                        (coord - e / scale).abs()
                    };
                    prop_assert!((distance - radius).abs() <= 1e-5 * (1.0 + radius + center.length()),
                        "edge {e}: plane at {distance} from the centre, radius {radius}");
                }
            }
            ScreenProjection::CameraInside => prop_assert!(p.is_perspective() && center.length() <= radius),
            ScreenProjection::BeforeNearPlane => prop_assert!(-center.z + radius < near),
            ScreenProjection::TouchesNearPlane => {
                prop_assert!(-center.z - radius < near && -center.z + radius >= near)
            }
        }
    }

    #[test]
    fn box_projection_contains_every_point_and_depth_is_nearest(
        kind in 0u8..6,
        eye in prop::array::uniform3(-20.0f32..20.0),
        yaw in -3.2f32..3.2, pitch in -1.5f32..1.5,
        c in prop::array::uniform3(-60.0f32..60.0),
        half in prop::array::uniform3(0.0f32..10.0),
        samples in prop::collection::vec(prop::array::uniform3(-1.0f64..=1.0), 40),
    ) {
        let (p, aspect) = projection(kind);
        let rot = Quat::from_euler(EulerRot::YXZ, yaw, pitch, 0.0);
        let eye = Vec3::from(eye);
        let view = Mat4::look_at_rh(eye, eye + rot * Vec3::NEG_Z, rot * Vec3::Y);
        let b = Aabb::from_center_half_extents(Vec3::from(c), Vec3::from(half)).unwrap();
        let view64 = view.as_dmat4();
        let (bc, bh) = (b.center().as_dvec3(), b.half_extents().as_dvec3());
        let mut pts: Vec<DVec3> = b.corners().iter().map(|q| q.as_dvec3()).collect();
        pts.extend(samples.iter().map(|s| bc + bh * DVec3::from(*s)));
        let view_pts: Vec<DVec3> = pts.iter().map(|q| view64.transform_point3(*q)).collect();
        let near = f64::from(p.near());
        match project_aabb(&b, &view, &p, aspect).unwrap() {
            ScreenProjection::Projected(pb) => {
                let conv = p.depth_convention();
                for v in &view_pts {
                    let (x, y, dist) = project_point(&p, aspect, *v);
                    // The view matrix is f32: allow its rounding (relative 1e-6 of the coordinates).
                    let eps = 1e-5 * (1.0 + x.abs().max(y.abs()));
                    prop_assert!(dist >= near - 1e-5 * (1.0 + dist.abs()));
                    prop_assert!(x >= f64::from(pb.rect_ndc.min.x) - eps && x <= f64::from(pb.rect_ndc.max.x) + eps);
                    prop_assert!(y >= f64::from(pb.rect_ndc.min.y) - eps && y <= f64::from(pb.rect_ndc.max.y) + eps);
                    let d = p.depth_at_distance(dist.max(near)) as f32;
                    let slack = 1e-5 * d.abs().max(1e-3);
                    prop_assert!(!conv.is_strictly_behind(pb.nearest_depth, d + slack) || !conv.is_strictly_behind(pb.nearest_depth, d - slack),
                        "nearest {} behind point depth {d}", pb.nearest_depth);
                }
            }
            ScreenProjection::BeforeNearPlane => {
                for v in &view_pts {
                    prop_assert!(-v.z < near + 1e-4 * (1.0 + v.z.abs()));
                }
            }
            ScreenProjection::TouchesNearPlane => {
                let min = view_pts.iter().map(|v| -v.z).fold(f64::INFINITY, f64::min);
                prop_assert!(min < near + 1e-4 * (1.0 + min.abs()));
            }
            ScreenProjection::CameraInside => {
                prop_assert!(p.is_perspective());
                let e = eye.as_dvec3();
                let tol = 1e-4 * (1.0 + e.abs().max_element());
                prop_assert!((e - b.min.as_dvec3()).min_element() >= -tol && (b.max.as_dvec3() - e).min_element() >= -tol);
            }
        }
    }
}
