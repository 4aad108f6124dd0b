//! Projection of bounding volumes to a screen rectangle plus a conservative nearest depth.
//!
//! All arithmetic is f64 from f32 inputs; the rect is rounded outward to f32 and the depth is
//! rounded toward the camera, then moved [`DEPTH_MARGIN_ULPS`] further toward it.

use glam::{Affine3A, DVec3, Mat4, Vec2};
use tilegraph_types::round::{f64_to_f32_round_down, f64_to_f32_round_up};

use crate::bounds::{Aabb, AabbExt, Obb, Sphere};
use crate::camera::{Projection, ProjectionExt};
use crate::check::finite_mat4;
use crate::screen::NdcRect;
use crate::CullError;

/// f32 steps the reported nearest depth is moved toward the camera beyond the exact value.
/// The GPU rasterizer computes fragment depth from an f32 matrix and f32 view-space positions
/// (a few ulps of relative error); without this margin an object exactly coplanar with its
/// occluder could be culled by an ulp.
pub const DEPTH_MARGIN_ULPS: u32 = 4;

/// A volume that projects to a proper screen rectangle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProjectedBounds {
    /// Tight NDC rectangle of the volume's silhouette (exact for spheres; the hull of the 8
    /// projected corners for boxes), rounded outward to f32.
    pub rect_ndc: NdcRect,
    /// The depth of the volume's nearest point (nearest distance along the view axis), in the
    /// projection's depth convention, never farther than the exact value.
    pub nearest_depth: f32,
}

/// The result of projecting a bounding volume.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ScreenProjection {
    Projected(ProjectedBounds),
    /// Part of the volume is nearer than the near plane (its projection is unbounded or wraps
    /// around): treat as visible.
    TouchesNearPlane,
    /// The eye is inside the volume (perspective only): treat as visible.
    CameraInside,
    /// The whole volume is nearer than the near plane: behind the camera or between the eye and
    /// the near plane. It draws nothing; rejecting it is the frustum test's job (its near plane
    /// does). No rect is produced, because projecting points behind the eye gives a mirrored,
    /// meaningless one.
    BeforeNearPlane,
}

impl ScreenProjection {
    /// True unless the volume projected to a rect: such volumes are always kept by HiZ.
    pub fn is_always_visible(&self) -> bool {
        !matches!(self, ScreenProjection::Projected(_))
    }
}

fn affine_view(view_from_world: &Mat4) -> Result<Affine3A, CullError> {
    finite_mat4("view_from_world", view_from_world)?;
    let r = view_from_world.row(3);
    if r.x != 0.0 || r.y != 0.0 || r.z != 0.0 || r.w != 1.0 {
        return Err(CullError::InvalidProjection {
            parameter: "view_from_world row 3",
            value: r.w,
            reason: "a view matrix must be affine (last row 0, 0, 0, 1)",
        });
    }
    Ok(Affine3A::from_mat4(*view_from_world))
}

fn depth_of_nearest(projection: &Projection, nearest_distance_m: f64) -> f32 {
    let convention = projection.depth_convention();
    let exact = projection.depth_at_distance(nearest_distance_m);
    convention.nudge_toward_near(convention.round_toward_near(exact), DEPTH_MARGIN_ULPS)
}

fn outward_rect(min: (f64, f64), max: (f64, f64)) -> NdcRect {
    // Far off screen (finite but past f32's range at huge coordinates) the exact value does not
    // matter, only the side: saturate instead of rounding to an infinity that reads as bad
    // input. NaN stays NaN and is rejected downstream.
    let limit = f64::from(f32::MAX);
    let c = |v: f64| v.clamp(-limit, limit);
    NdcRect {
        min: Vec2::new(
            f64_to_f32_round_down(c(min.0)),
            f64_to_f32_round_down(c(min.1)),
        ),
        max: Vec2::new(f64_to_f32_round_up(c(max.0)), f64_to_f32_round_up(c(max.1))),
    }
}

/// Projects a sphere given in VIEW space.
///
/// Perspective: the extreme NDC x of the silhouette is reached on the two planes through the
/// eye that contain the view y axis and touch the sphere; their tangent points depend only on
/// the centre's (x, z) and the radius, so the bound is a 2D circle-tangent problem per axis
/// (Mara & McGuire 2013). With C = (c, z) the centre in that plane, d^2 = c^2 + z^2 and
/// t = sqrt(d^2 - r^2) the tangent length, the directions to the two tangent points are
/// (t c - r z, r c + t z) and (t c + r z, -r c + t z); NDC = scale * coordinate / distance
/// for each. The same for y. The rectangle is exact (tight) for the silhouette.
///
/// Orthographic: centre +/- radius, scaled.
///
/// `aspect` is the viewport's width / height, which the projection leaves open.
pub fn project_sphere_view(
    sphere_view: &Sphere,
    projection: &Projection,
    aspect: f32,
) -> Result<ScreenProjection, CullError> {
    sphere_view.validate("sphere")?;
    projection.validate(aspect)?;
    let c = sphere_view.center.as_dvec3();
    let r = f64::from(sphere_view.radius);
    let near = f64::from(projection.near());
    let (sx, sy) = projection.ndc_scale(aspect);
    // Distance along the view axis is -z.
    let nearest = -c.z - r;
    let farthest = -c.z + r;

    if projection.is_perspective() && c.length_squared() <= r * r {
        return Ok(ScreenProjection::CameraInside);
    }
    if farthest < near {
        return Ok(ScreenProjection::BeforeNearPlane);
    }
    if nearest < near {
        return Ok(ScreenProjection::TouchesNearPlane);
    }

    let (x_range, y_range) = if projection.is_perspective() {
        (
            tangent_ndc_range(c.x, c.z, r, sx),
            tangent_ndc_range(c.y, c.z, r, sy),
        )
    } else {
        let xs = (sx * (c.x - r), sx * (c.x + r));
        let ys = (sy * (c.y - r), sy * (c.y + r));
        (
            (xs.0.min(xs.1), xs.0.max(xs.1)),
            (ys.0.min(ys.1), ys.0.max(ys.1)),
        )
    };
    Ok(ScreenProjection::Projected(ProjectedBounds {
        rect_ndc: outward_rect((x_range.0, y_range.0), (x_range.1, y_range.1)),
        nearest_depth: depth_of_nearest(projection, nearest),
    }))
}

/// NDC range of a sphere along one axis: `a` is the centre's coordinate on that axis, `z` its
/// view z (negative, with the whole sphere beyond the near plane), `scale` the NDC scale.
fn tangent_ndc_range(a: f64, z: f64, r: f64, scale: f64) -> (f64, f64) {
    // d^2 - r^2 > 0 because |z| > r when the sphere lies beyond the near plane.
    let t = (a * a + z * z - r * r).max(0.0).sqrt();
    let to_ndc = |u: f64, w: f64| scale * u / -w;
    let p = to_ndc(t * a - r * z, r * a + t * z);
    let q = to_ndc(t * a + r * z, -r * a + t * z);
    (p.min(q), p.max(q))
}

/// Projects a sphere given in world space through `view_from_world` (affine; a rigid view
/// keeps the radius, a scaling one enlarges it conservatively).
pub fn project_sphere(
    sphere_world: &Sphere,
    view_from_world: &Mat4,
    projection: &Projection,
    aspect: f32,
) -> Result<ScreenProjection, CullError> {
    let view = affine_view(view_from_world)?;
    project_sphere_view(&sphere_world.transformed(&view)?, projection, aspect)
}

/// Projects a world-space AABB: the rect of its 8 projected corners.
pub fn project_aabb(
    aabb_world: &Aabb,
    view_from_world: &Mat4,
    projection: &Projection,
    aspect: f32,
) -> Result<ScreenProjection, CullError> {
    aabb_world.validate("aabb")?;
    project_obb(&Obb::from(*aabb_world), view_from_world, projection, aspect)
}

/// Projects a world-space oriented box: the rect of its 8 projected corners.
///
/// The volume is handled as a parallelepiped in view space (centre + 3 half-edge vectors).
/// The eye is inside iff, for each face-normal direction n_i = e_j x e_k, |n_i . c| <= |n_i . e_i|
/// (flat boxes have no interior and fall through to the near-plane cases).
pub fn project_obb(
    obb_world: &Obb,
    view_from_world: &Mat4,
    projection: &Projection,
    aspect: f32,
) -> Result<ScreenProjection, CullError> {
    obb_world.validate("obb")?;
    affine_view(view_from_world)?;
    projection.validate(aspect)?;
    // Composed in f64: an f32 view * world_from_local product would add its own rounding to
    // the corners (and hence to the nearest depth).
    let view = view_from_world.as_dmat4();
    let center = view.transform_point3(obb_world.center_f64());
    let half_edges = obb_world
        .half_edges_f64()
        .map(|e| view.transform_vector3(e));
    let corners = obb_world.corners_f64().map(|c| view.transform_point3(c));
    let near = f64::from(projection.near());

    if projection.is_perspective() && eye_inside(center, half_edges) {
        return Ok(ScreenProjection::CameraInside);
    }
    let nearest = corners.iter().map(|p| -p.z).fold(f64::INFINITY, f64::min);
    let farthest = corners
        .iter()
        .map(|p| -p.z)
        .fold(f64::NEG_INFINITY, f64::max);
    if farthest < near {
        return Ok(ScreenProjection::BeforeNearPlane);
    }
    if nearest < near {
        return Ok(ScreenProjection::TouchesNearPlane);
    }

    let (sx, sy) = projection.ndc_scale(aspect);
    let mut lo = (f64::INFINITY, f64::INFINITY);
    let mut hi = (f64::NEG_INFINITY, f64::NEG_INFINITY);
    for p in &corners {
        let w = if projection.is_perspective() {
            -p.z
        } else {
            1.0
        };
        let (x, y) = (sx * p.x / w, sy * p.y / w);
        lo = (lo.0.min(x), lo.1.min(y));
        hi = (hi.0.max(x), hi.1.max(y));
    }
    Ok(ScreenProjection::Projected(ProjectedBounds {
        rect_ndc: outward_rect(lo, hi),
        nearest_depth: depth_of_nearest(projection, nearest),
    }))
}

fn eye_inside(center: DVec3, e: [DVec3; 3]) -> bool {
    let normals = [e[1].cross(e[2]), e[2].cross(e[0]), e[0].cross(e[1])];
    normals.iter().zip(e.iter()).all(|(n, ei)| {
        let extent = n.dot(*ei).abs();
        extent > 0.0 && n.dot(center).abs() <= extent
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::depth::DepthConvention;
    use glam::Vec3;

    /// The viewport `reverse_inf` is used on.
    const WIDE: f32 = 16.0 / 9.0;

    fn reverse_inf() -> Projection {
        Projection::tilegraph_default(1.0, 0.1)
    }

    /// A box 10^38 m wide in front of the camera: its NDC extent passes f32's range. The rect
    /// saturates (finite, covering the screen) instead of turning into infinities.
    #[test]
    fn huge_finite_bounds_saturate_to_a_finite_rect() {
        let b = Aabb::try_new(Vec3::new(-1e38, -1.0, -1.0), Vec3::new(1e38, 1.0, -0.5)).unwrap();
        let square = Projection::tilegraph_default(1.0, 0.1);
        let p = projected(project_aabb(&b, &Mat4::IDENTITY, &square, 1.0).unwrap());
        assert_eq!(p.rect_ndc.min.x, -f32::MAX);
        assert_eq!(p.rect_ndc.max.x, f32::MAX);
        assert!(p.rect_ndc.min.y.is_finite() && p.rect_ndc.max.y.is_finite());
    }

    fn projected(p: ScreenProjection) -> ProjectedBounds {
        match p {
            ScreenProjection::Projected(b) => b,
            other => panic!("expected a rect, got {other:?}"),
        }
    }

    #[test]
    fn centred_sphere_is_symmetric_and_tight() {
        let p = reverse_inf();
        let s = Sphere::new(Vec3::new(0.0, 0.0, -10.0), 1.0).unwrap();
        let b = projected(project_sphere_view(&s, &p, WIDE).unwrap());
        let (sx, sy) = p.ndc_scale(WIDE);
        // On axis: tan of the half-angle subtended = r / sqrt(d^2 - r^2).
        let half = 1.0 / (100.0f64 - 1.0).sqrt();
        assert!((f64::from(b.rect_ndc.max.x) - sx * half).abs() < 1e-6);
        assert!((f64::from(b.rect_ndc.max.y) - -sy * half).abs() < 1e-6);
        assert!((b.rect_ndc.min.x + b.rect_ndc.max.x).abs() < 1e-6);
        // Nearest point at 9 m: reverse infinite depth = 0.1 / 9, never farther (smaller).
        assert!(b.nearest_depth >= (0.1f64 / 9.0) as f32);
        assert!(f64::from(b.nearest_depth) - 0.1 / 9.0 < 1e-8);
    }

    #[test]
    fn off_axis_sphere_rect_contains_every_surface_point_and_touches_the_extremes() {
        let p = reverse_inf();
        let (sx, sy) = p.ndc_scale(WIDE);
        let s = Sphere::new(Vec3::new(3.0, -2.0, -6.0), 1.5).unwrap();
        let b = projected(project_sphere_view(&s, &p, WIDE).unwrap());
        let mut extreme = (
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
        );
        let n = 400;
        for i in 0..n {
            for j in 0..n {
                let theta = std::f64::consts::PI * (i as f64 + 0.5) / n as f64;
                let phi = 2.0 * std::f64::consts::PI * j as f64 / n as f64;
                let q = s.center.as_dvec3()
                    + DVec3::new(
                        theta.sin() * phi.cos(),
                        theta.sin() * phi.sin(),
                        theta.cos(),
                    ) * 1.5;
                let (x, y) = (sx * q.x / -q.z, sy * q.y / -q.z);
                assert!(x >= f64::from(b.rect_ndc.min.x) && x <= f64::from(b.rect_ndc.max.x));
                assert!(y >= f64::from(b.rect_ndc.min.y) && y <= f64::from(b.rect_ndc.max.y));
                extreme = (
                    extreme.0.min(x),
                    extreme.1.max(x),
                    extreme.2.min(y),
                    extreme.3.max(y),
                );
            }
        }
        // Tight: the sampled silhouette reaches the rect within the sampling resolution.
        assert!((extreme.0 - f64::from(b.rect_ndc.min.x)).abs() < 1e-3);
        assert!((extreme.1 - f64::from(b.rect_ndc.max.x)).abs() < 1e-3);
        assert!((extreme.2 - f64::from(b.rect_ndc.min.y)).abs() < 1e-3);
        assert!((extreme.3 - f64::from(b.rect_ndc.max.y)).abs() < 1e-3);
    }

    #[test]
    fn near_plane_cases() {
        let p = reverse_inf();
        let inside = Sphere::new(Vec3::new(0.0, 0.0, -0.5), 1.0).unwrap();
        assert_eq!(
            project_sphere_view(&inside, &p, WIDE).unwrap(),
            ScreenProjection::CameraInside
        );
        let crossing = Sphere::new(Vec3::new(2.0, 0.0, -0.5), 1.0).unwrap();
        assert_eq!(
            project_sphere_view(&crossing, &p, WIDE).unwrap(),
            ScreenProjection::TouchesNearPlane
        );
        let behind = Sphere::new(Vec3::new(0.0, 0.0, 5.0), 1.0).unwrap();
        assert_eq!(
            project_sphere_view(&behind, &p, WIDE).unwrap(),
            ScreenProjection::BeforeNearPlane
        );
        let view = Mat4::IDENTITY;
        let box_behind =
            Aabb::try_new(Vec3::new(-1.0, -1.0, 2.0), Vec3::new(1.0, 1.0, 3.0)).unwrap();
        assert_eq!(
            project_aabb(&box_behind, &view, &p, WIDE).unwrap(),
            ScreenProjection::BeforeNearPlane
        );
        let box_around = Aabb::try_new(Vec3::splat(-1.0), Vec3::splat(1.0)).unwrap();
        assert_eq!(
            project_aabb(&box_around, &view, &p, WIDE).unwrap(),
            ScreenProjection::CameraInside
        );
        let box_crossing =
            Aabb::try_new(Vec3::new(0.5, -1.0, -3.0), Vec3::new(1.0, 1.0, 1.0)).unwrap();
        assert_eq!(
            project_aabb(&box_crossing, &view, &p, WIDE).unwrap(),
            ScreenProjection::TouchesNearPlane
        );
    }

    #[test]
    fn aabb_rect_contains_projected_corners_and_depth_is_nearest() {
        for depth in [DepthConvention::Standard, DepthConvention::Reverse] {
            let aspect = 1.3;
            let p = Projection::Perspective {
                fov_y_rad: 0.9,
                near: 0.05,
                far: Some(300.0),
                depth,
            };
            let view = Mat4::look_at_rh(
                Vec3::new(1.0, 2.0, 3.0),
                Vec3::new(0.0, 0.0, -20.0),
                Vec3::Y,
            );
            let b =
                Aabb::try_new(Vec3::new(-2.0, -1.0, -15.0), Vec3::new(1.0, 3.0, -11.0)).unwrap();
            let pb = projected(project_aabb(&b, &view, &p, aspect).unwrap());
            let clip = p.matrix(aspect) * view;
            for c in b.corners() {
                let q = clip * c.extend(1.0);
                let (x, y, z) = (q.x / q.w, q.y / q.w, q.z / q.w);
                assert!(x >= pb.rect_ndc.min.x - 1e-5 && x <= pb.rect_ndc.max.x + 1e-5);
                assert!(y >= pb.rect_ndc.min.y - 1e-5 && y <= pb.rect_ndc.max.y + 1e-5);
                assert!(
                    !depth.is_strictly_behind(pb.nearest_depth, z)
                        || (pb.nearest_depth - z).abs() < 1e-6
                );
            }
        }
    }

    #[test]
    fn orthographic_sphere_and_box() {
        // 20 m x 10 m.
        let (p, aspect) = (
            Projection::Orthographic {
                half_height: 5.0,
                near: 0.0,
                far: 100.0,
                depth: DepthConvention::Standard,
            },
            2.0,
        );
        let s = Sphere::new(Vec3::new(5.0, 2.0, -50.0), 1.0).unwrap();
        let b = projected(project_sphere_view(&s, &p, aspect).unwrap());
        assert!((b.rect_ndc.min.x - 0.4).abs() < 1e-6 && (b.rect_ndc.max.x - 0.6).abs() < 1e-6);
        // +y is up, so the rect lies in the upper (negative NDC y) half.
        assert!((b.rect_ndc.min.y + 0.6).abs() < 1e-6 && (b.rect_ndc.max.y + 0.2).abs() < 1e-6);
        assert!((b.nearest_depth - 0.49).abs() < 1e-6);
        let crossing = Sphere::new(Vec3::new(0.0, 0.0, 0.5), 1.0).unwrap();
        assert_eq!(
            project_sphere_view(&crossing, &p, aspect).unwrap(),
            ScreenProjection::TouchesNearPlane
        );
    }

    #[test]
    fn non_affine_view_is_an_error() {
        let p = reverse_inf();
        let b = Aabb::try_new(Vec3::splat(-1.0), Vec3::splat(1.0)).unwrap();
        assert!(matches!(
            project_aabb(&b, &p.matrix(WIDE), &p, WIDE),
            Err(CullError::InvalidProjection { .. })
        ));
    }
}
