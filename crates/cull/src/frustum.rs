//! View frustum: plane extraction (Gribb-Hartmann, Vulkan 0..1 depth), the conservative plane
//! tests, and the exact separating-axis test against boxes.
//!
//! Planes are `n . p + d >= 0` inside, with unit `n`, in whatever space the matrix maps from
//! (world space for a view-projection matrix). Everything is evaluated in f64: the CPU
//! reference should not add rounding of its own to the question it answers.

use glam::{DMat4, DVec3, DVec4, Mat4, Vec4};
use serde::{Deserialize, Serialize};

use crate::bounds::{Aabb, AabbExt, Obb, Sphere};
use crate::check::finite_mat4;
use crate::depth::DepthConvention;
use crate::CullError;

/// One of the six frustum planes. `Top` is the plane through NDC y = -1, which the y-flipped
/// projection puts at the top row of the screen.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum FrustumPlane {
    Left,
    Right,
    Top,
    Bottom,
    Near,
    Far,
}

impl FrustumPlane {
    pub const ALL: [FrustumPlane; 6] = [
        FrustumPlane::Left,
        FrustumPlane::Right,
        FrustumPlane::Top,
        FrustumPlane::Bottom,
        FrustumPlane::Near,
        FrustumPlane::Far,
    ];

    fn index(self) -> usize {
        self as usize
    }
}

/// A plane `normal . p + d = 0`, unit normal pointing into the frustum.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Plane {
    pub normal: DVec3,
    pub d: f64,
}

impl Plane {
    pub fn signed_distance(&self, p: DVec3) -> f64 {
        self.normal.dot(p) + self.d
    }

    /// For upload: (nx, ny, nz, d) in f32.
    pub fn to_vec4(&self) -> Vec4 {
        Vec4::new(
            self.normal.x as f32,
            self.normal.y as f32,
            self.normal.z as f32,
            self.d as f32,
        )
    }
}

/// Result of the plane test.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum PlaneTest {
    /// Entirely on the inner side of every plane.
    Inside,
    /// Not rejected by any single plane. May still be outside (near frustum edges/corners):
    /// these are the plane test's false positives that the SAT measures.
    Intersecting,
    /// Entirely on the outer side of this plane.
    Outside(FrustumPlane),
}

impl PlaneTest {
    pub fn is_outside(self) -> bool {
        matches!(self, PlaneTest::Outside(_))
    }
}

/// The axis that separated a box from the frustum in the SAT.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum SeparatingAxis {
    /// A frustum face (the plane test's own axes).
    FrustumFace(FrustumPlane),
    /// The face that closes an infinite frustum behind the box (see [`Frustum::sat_obb`]).
    ClampedFarFace,
    /// A face normal of the box (index 0..3 of its local axes).
    BoxFace(u8),
    /// Cross product of box edge `box_edge` (0..3) with frustum edge `frustum_edge` (0..12).
    EdgeCross { box_edge: u8, frustum_edge: u8 },
}

/// Result of the exact separating-axis test.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum SatTest {
    /// The closed box and the closed frustum share at least one point.
    Overlapping,
    Separated(SeparatingAxis),
}

impl SatTest {
    pub fn is_separated(self) -> bool {
        matches!(self, SatTest::Separated(_))
    }
}

/// Six planes, of which a degenerate one (the far plane of an infinite projection) is absent.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frustum {
    planes: [Option<Plane>; 6],
}

/// Relative tolerance of the plane test: a plane rejects only when the volume is outside by
/// more than this fraction of the magnitudes involved, so f64 rounding never rejects a volume
/// that touches the plane.
const PLANE_TEST_REL_TOL: f64 = 1e-9;
/// Relative tolerance of the SAT interval comparisons (corners come from plane intersections,
/// whose f64 error is far below this).
const SAT_REL_TOL: f64 = 1e-11;

/// A combination of two matrix rows is treated as "no plane" when its normal is below the
/// rounding noise of f32 entries it was formed from (8 ulps of the inputs). Exact cancellation
/// is what an infinite far plane produces; noise that survives cancellation would otherwise
/// become a plane in a random direction.
const DEGENERATE_REL: f64 = 8.0 * f32::EPSILON as f64;

fn row(m: &DMat4, i: usize) -> DVec4 {
    m.row(i)
}

fn plane_from_rows(a: DVec4, b: DVec4, sign: f64) -> Option<Plane> {
    let p = a + b * sign;
    let n = p.truncate();
    let len = n.length();
    let noise = DEGENERATE_REL * (a.truncate().length() + b.truncate().length() * sign.abs());
    if len == 0.0 || len <= noise || !len.is_finite() {
        return None;
    }
    Some(Plane {
        normal: n / len,
        d: p.w / len,
    })
}

/// The point where three planes meet, or None when they do not meet in one point.
fn intersect3(a: &Plane, b: &Plane, c: &Plane) -> Option<DVec3> {
    let bc = b.normal.cross(c.normal);
    let det = a.normal.dot(bc);
    if det.abs() < 1e-12 {
        return None;
    }
    let p = (bc * -a.d + c.normal.cross(a.normal) * -b.d + a.normal.cross(b.normal) * -c.d) / det;
    p.is_finite().then_some(p)
}

/// Frustum corners, index = (x side: 0 left / 1 right) + 2 * (0 top / 1 bottom) + 4 * (0 near /
/// 1 far), and the 12 edges as corner index pairs.
const EDGES: [(usize, usize); 12] = [
    // near face
    (0, 1),
    (2, 3),
    (0, 2),
    (1, 3),
    // far face
    (4, 5),
    (6, 7),
    (4, 6),
    (5, 7),
    // sides
    (0, 4),
    (1, 5),
    (2, 6),
    (3, 7),
];

impl Frustum {
    /// Gribb-Hartmann extraction from `clip_from_world` (= projection * view), Vulkan clip
    /// space: -w <= x <= w, -w <= y <= w, 0 <= z <= w. With rows r0..r3 of the matrix:
    /// left = r3 + r0, right = r3 - r0, top (y >= -w) = r3 + r1, bottom = r3 - r1,
    /// z >= 0 is r2 and z <= w is r3 - r2; `depth` says which of those two is near (Standard:
    /// z >= 0; Reverse: z <= w). An infinite far plane comes out with a zero normal (exact
    /// cancellation) and is left absent instead of being normalized into NaN.
    pub fn from_clip_from_world(
        clip_from_world: &Mat4,
        depth: DepthConvention,
    ) -> Result<Self, CullError> {
        finite_mat4("frustum matrix", clip_from_world)?;
        let m = clip_from_world.as_dmat4();
        let (r0, r1, r2, r3) = (row(&m, 0), row(&m, 1), row(&m, 2), row(&m, 3));
        let z_ge_0 = plane_from_rows(r2, DVec4::ZERO, 0.0);
        let z_le_w = plane_from_rows(r3, r2, -1.0);
        let (near, far) = match depth {
            DepthConvention::Standard => (z_ge_0, z_le_w),
            DepthConvention::Reverse => (z_le_w, z_ge_0),
        };
        let planes = [
            plane_from_rows(r3, r0, 1.0),
            plane_from_rows(r3, r0, -1.0),
            plane_from_rows(r3, r1, 1.0),
            plane_from_rows(r3, r1, -1.0),
            near,
            far,
        ];
        Ok(Frustum { planes })
    }

    pub fn plane(&self, which: FrustumPlane) -> Option<&Plane> {
        self.planes[which.index()].as_ref()
    }

    /// The planes for a shader: absent planes become (0, 0, 0, 1), which every point passes,
    /// so a GPU loop needs no branch for the infinite far plane.
    pub fn gpu_planes(&self) -> [Vec4; 6] {
        std::array::from_fn(|i| {
            self.planes[i].map_or(Vec4::new(0.0, 0.0, 0.0, 1.0), |p| p.to_vec4())
        })
    }

    fn present(&self) -> impl Iterator<Item = (FrustumPlane, &Plane)> {
        FrustumPlane::ALL
            .into_iter()
            .zip(self.planes.iter())
            .filter_map(|(w, p)| p.as_ref().map(|p| (w, p)))
    }

    /// Closed point containment (every present plane, within the plane-test tolerance).
    pub fn contains_point(&self, p: DVec3) -> bool {
        self.present().all(|(_, pl)| {
            let s = pl.signed_distance(p);
            s >= -PLANE_TEST_REL_TOL * (pl.normal.dot(p).abs() + pl.d.abs())
        })
    }

    /// Plane test of a sphere: outside when the centre is farther than the radius behind any
    /// plane. Conservative: a sphere near a frustum edge can be outside yet pass every plane.
    pub fn test_sphere(&self, sphere: &Sphere) -> Result<PlaneTest, CullError> {
        sphere.validate("sphere")?;
        let c = sphere.center.as_dvec3();
        let r = f64::from(sphere.radius);
        let mut all_inside = true;
        for (which, pl) in self.present() {
            let s = pl.signed_distance(c);
            let tol = PLANE_TEST_REL_TOL * (pl.normal.dot(c).abs() + pl.d.abs() + r);
            if s < -r - tol {
                return Ok(PlaneTest::Outside(which));
            }
            if s < r {
                all_inside = false;
            }
        }
        Ok(if all_inside {
            PlaneTest::Inside
        } else {
            PlaneTest::Intersecting
        })
    }

    /// Plane test of an AABB (centre/extent form of the p-vertex test): outside when even the
    /// corner farthest along a plane's normal is behind it.
    pub fn test_aabb(&self, aabb: &Aabb) -> Result<PlaneTest, CullError> {
        aabb.validate("aabb")?;
        let c = (aabb.min.as_dvec3() + aabb.max.as_dvec3()) * 0.5;
        let e = (aabb.max.as_dvec3() - aabb.min.as_dvec3()) * 0.5;
        Ok(self.test_box_planes(c, [DVec3::X * e.x, DVec3::Y * e.y, DVec3::Z * e.z]))
    }

    /// Plane test of an oriented box (parallelepiped).
    pub fn test_obb(&self, obb: &Obb) -> Result<PlaneTest, CullError> {
        obb.validate("obb")?;
        Ok(self.test_box_planes(obb.center_f64(), obb.half_edges_f64()))
    }

    /// The plane test of an axis-aligned box by its centre (relative to the frustum's origin)
    /// and half extents, in f64: [`Frustum::test_aabb`] without the f32 box, for callers whose
    /// values are finite by construction (a scene's bounds, checked when they were set) and who
    /// test many boxes a frame.
    pub fn test_box(&self, center: DVec3, half: DVec3) -> PlaneTest {
        self.test_box_planes(
            center,
            [DVec3::X * half.x, DVec3::Y * half.y, DVec3::Z * half.z],
        )
    }

    fn test_box_planes(&self, c: DVec3, half_edges: [DVec3; 3]) -> PlaneTest {
        let mut all_inside = true;
        for (which, pl) in self.present() {
            let center = pl.signed_distance(c);
            let radius: f64 = half_edges.iter().map(|e| pl.normal.dot(*e).abs()).sum();
            let tol = PLANE_TEST_REL_TOL * (pl.normal.dot(c).abs() + pl.d.abs() + radius);
            if center + radius < -tol {
                return PlaneTest::Outside(which);
            }
            if center - radius < 0.0 {
                all_inside = false;
            }
        }
        if all_inside {
            PlaneTest::Inside
        } else {
            PlaneTest::Intersecting
        }
    }

    /// Exact separating-axis test of an AABB; see [`Frustum::sat_obb`].
    pub fn sat_aabb(&self, aabb: &Aabb) -> Result<SatTest, CullError> {
        self.sat_obb(&Obb::from(*aabb))
    }

    /// Exact separating-axis test of the closed frustum against a closed oriented box.
    ///
    /// Both are convex polyhedra, so they are disjoint iff one of these axes separates their
    /// projections: the frustum's face normals, the box's face normals, and every cross product
    /// of a box edge direction with a frustum edge direction (3 x 12). Degenerate boxes (zero
    /// extent on some axes) keep their non-zero edges and faces; zero-length axes are skipped,
    /// which leaves exactly the candidate set of the lower-dimensional shape.
    ///
    /// The frustum polyhedron is built from its 8 corners (intersections of plane triples).
    /// When the far plane is absent (infinite projection), it is closed by a plane parallel to
    /// the near plane placed just beyond the box's farthest corner: the box lies entirely on the
    /// near side of that plane, so cutting the frustum there removes nothing the box could
    /// touch, and the answer is exact for an infinite frustum.
    ///
    /// The plane test runs first with its own tolerance, so anything the plane test rejects the
    /// SAT rejects too (by construction, not by luck of rounding).
    pub fn sat_obb(&self, obb: &Obb) -> Result<SatTest, CullError> {
        obb.validate("obb")?;
        let center = obb.center_f64();
        let half_edges = obb.half_edges_f64();
        if let PlaneTest::Outside(which) = self.test_box_planes(center, half_edges) {
            return Ok(SatTest::Separated(SeparatingAxis::FrustumFace(which)));
        }

        let near = self
            .plane(FrustumPlane::Near)
            .ok_or(CullError::DegenerateFrustum {
                reason: "the near plane is absent",
            })?;
        let (far, far_is_clamp) = match self.plane(FrustumPlane::Far) {
            Some(f) => (*f, false),
            None => {
                // Farthest extent of the box along the view direction (= near normal).
                let box_far = near.normal.dot(center)
                    + half_edges
                        .iter()
                        .map(|e| near.normal.dot(*e).abs())
                        .sum::<f64>();
                let near_at = -near.d;
                let reach = box_far.max(near_at);
                let beyond = reach + 1.0 + reach.abs() * 1e-6;
                (
                    Plane {
                        normal: -near.normal,
                        d: beyond,
                    },
                    true,
                )
            }
        };
        let side = |w: FrustumPlane| {
            self.plane(w).copied().ok_or(CullError::DegenerateFrustum {
                reason: "a side plane is absent",
            })
        };
        let (left, right, top, bottom) = (
            side(FrustumPlane::Left)?,
            side(FrustumPlane::Right)?,
            side(FrustumPlane::Top)?,
            side(FrustumPlane::Bottom)?,
        );
        let mut corners = [DVec3::ZERO; 8];
        for (i, corner) in corners.iter_mut().enumerate() {
            let x = if i & 1 == 0 { &left } else { &right };
            let y = if i & 2 == 0 { &top } else { &bottom };
            let z = if i & 4 == 0 { near } else { &far };
            *corner = intersect3(x, y, z).ok_or(CullError::DegenerateFrustum {
                reason: "three frustum planes do not meet in a corner",
            })?;
        }

        let box_interval = |axis: DVec3| {
            let c = axis.dot(center);
            let r: f64 = half_edges.iter().map(|e| axis.dot(*e).abs()).sum();
            (c - r, c + r, c.abs() + r)
        };
        let frustum_interval = |axis: DVec3| {
            let mut lo = f64::INFINITY;
            let mut hi = f64::NEG_INFINITY;
            for c in &corners {
                let v = axis.dot(*c);
                lo = lo.min(v);
                hi = hi.max(v);
            }
            (lo, hi)
        };
        let separated = |axis: DVec3| {
            let (b_lo, b_hi, b_mag) = box_interval(axis);
            let (f_lo, f_hi) = frustum_interval(axis);
            let tol_lo = SAT_REL_TOL * (b_mag + f_lo.abs());
            let tol_hi = SAT_REL_TOL * (b_mag + f_hi.abs());
            b_hi < f_lo - tol_lo || b_lo > f_hi + tol_hi
        };

        if far_is_clamp && separated(far.normal) {
            return Ok(SatTest::Separated(SeparatingAxis::ClampedFarFace));
        }
        for (which, pl) in self.present() {
            if separated(pl.normal) {
                return Ok(SatTest::Separated(SeparatingAxis::FrustumFace(which)));
            }
        }

        // Box face normals: for a parallelepiped, the cross products of edge pairs.
        let box_faces = [
            half_edges[1].cross(half_edges[2]),
            half_edges[2].cross(half_edges[0]),
            half_edges[0].cross(half_edges[1]),
        ];
        // Edge directions of the box: a zero half-edge still has a direction (the box's local
        // axis); using it keeps the cross-product axes of flat boxes.
        let box_edge_dirs = {
            let cols = [
                obb.world_from_local.matrix3.x_axis,
                obb.world_from_local.matrix3.y_axis,
                obb.world_from_local.matrix3.z_axis,
            ];
            cols.map(|c| c.as_dvec3())
        };
        for (i, n) in box_faces.iter().enumerate() {
            if is_usable_axis(*n, 1.0) && separated(*n) {
                return Ok(SatTest::Separated(SeparatingAxis::BoxFace(i as u8)));
            }
        }
        for (bi, be) in box_edge_dirs.iter().enumerate() {
            for (fi, (a, b)) in EDGES.iter().enumerate() {
                let fe = corners[*b] - corners[*a];
                let axis = be.cross(fe);
                if is_usable_axis(axis, be.length() * fe.length()) && separated(axis) {
                    return Ok(SatTest::Separated(SeparatingAxis::EdgeCross {
                        box_edge: bi as u8,
                        frustum_edge: fi as u8,
                    }));
                }
            }
        }
        Ok(SatTest::Overlapping)
    }
}

/// A cross product is usable as an axis unless its inputs were (nearly) parallel or zero;
/// parallel edges contribute no face to the Minkowski difference, so skipping them loses
/// nothing.
fn is_usable_axis(axis: DVec3, input_scale: f64) -> bool {
    let len = axis.length();
    len.is_finite() && len > 1e-12 * input_scale && len > 0.0
}

/// How often the plane test keeps a box that the exact test separates.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct PlaneTestAccuracy {
    pub boxes: u32,
    /// Boxes the plane test rejects.
    pub plane_outside: u32,
    /// Boxes the SAT separates.
    pub sat_outside: u32,
    /// Kept by the plane test, separated by the SAT: work a plane-test culler draws for nothing.
    pub plane_false_positives: u32,
    /// Rejected by the plane test yet overlapping per SAT. Must be 0; counted, not assumed.
    pub plane_wrongly_rejected: u32,
    /// `plane_false_positives / (boxes - plane_outside)`: share of the kept boxes that are
    /// actually outside (0 when nothing was kept).
    pub false_positive_share_of_kept: f64,
}

/// Runs both tests over `boxes` and counts where they disagree.
pub fn measure_plane_test_false_positives(
    frustum: &Frustum,
    boxes: &[Aabb],
) -> Result<PlaneTestAccuracy, CullError> {
    let mut acc = PlaneTestAccuracy {
        boxes: boxes.len() as u32,
        ..PlaneTestAccuracy::default()
    };
    for b in boxes {
        let plane = frustum.test_aabb(b)?.is_outside();
        let sat = frustum.sat_aabb(b)?.is_separated();
        acc.plane_outside += u32::from(plane);
        acc.sat_outside += u32::from(sat);
        acc.plane_false_positives += u32::from(!plane && sat);
        acc.plane_wrongly_rejected += u32::from(plane && !sat);
    }
    let kept = acc.boxes - acc.plane_outside;
    acc.false_positive_share_of_kept = if kept == 0 {
        0.0
    } else {
        f64::from(acc.plane_false_positives) / f64::from(kept)
    };
    Ok(acc)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::Projection;
    use glam::{Affine3A, Quat, Vec3};

    /// A square viewport, looking down -z from the origin.
    fn camera(p: &Projection) -> (Mat4, Frustum) {
        let view = Mat4::look_at_rh(Vec3::new(0.0, 0.0, 0.0), Vec3::new(0.0, 0.0, -1.0), Vec3::Y);
        let m = p.matrix(1.0) * view;
        (
            m,
            Frustum::from_clip_from_world(&m, p.depth_convention()).unwrap(),
        )
    }

    #[test]
    fn infinite_far_plane_is_absent_not_nan() {
        for depth in [DepthConvention::Reverse, DepthConvention::Standard] {
            let p = Projection::Perspective {
                fov_y_rad: 1.0,
                near: 0.1,
                far: None,
                depth,
            };
            let (_, f) = camera(&p);
            assert!(f.plane(FrustumPlane::Far).is_none(), "{depth:?}");
            for w in [
                FrustumPlane::Left,
                FrustumPlane::Right,
                FrustumPlane::Top,
                FrustumPlane::Bottom,
                FrustumPlane::Near,
            ] {
                let pl = f.plane(w).unwrap();
                assert!(pl.normal.is_finite() && pl.d.is_finite());
            }
            assert_eq!(f.gpu_planes()[5], Vec4::new(0.0, 0.0, 0.0, 1.0));
            let near = f.plane(FrustumPlane::Near).unwrap();
            assert!((near.normal - DVec3::new(0.0, 0.0, -1.0)).length() < 1e-9);
            assert!((near.d - -0.1).abs() < 1e-7);
        }
    }

    #[test]
    fn finite_far_plane_is_where_it_should_be() {
        for depth in [DepthConvention::Reverse, DepthConvention::Standard] {
            let p = Projection::Perspective {
                fov_y_rad: 1.0,
                near: 0.1,
                far: Some(250.0),
                depth,
            };
            let (_, f) = camera(&p);
            let far = f.plane(FrustumPlane::Far).unwrap();
            assert!((far.normal - DVec3::Z).length() < 1e-6, "{depth:?} {far:?}");
            // The plane is the f32 matrix's own clip plane, extracted exactly. Standard depth
            // forms it as r3 - r2 with r2.z = -f/(f-n) ~ -1.0004: the f32 rounding of that entry
            // moves the plane by ~250 * 2^-24 / 4e-4 ~ 0.04 m, and the GPU clips there too.
            // Reverse depth forms it from r2 alone and is accurate to f32 resolution.
            let tol = match depth {
                DepthConvention::Standard => 0.05,
                DepthConvention::Reverse => 1e-3,
            };
            assert!((far.d - 250.0).abs() < tol, "{depth:?} {far:?}");
        }
    }

    #[test]
    fn top_plane_is_view_up() {
        let p = Projection::tilegraph_default(1.0, 0.1);
        let (_, f) = camera(&p);
        let top = f.plane(FrustumPlane::Top).unwrap();
        // The top plane faces down (into the frustum), i.e. it bounds +y.
        assert!(top.normal.y < 0.0);
    }

    #[test]
    fn rejects_nan_matrix() {
        let mut m = Mat4::IDENTITY;
        m.z_axis.y = f32::NAN;
        assert!(matches!(
            Frustum::from_clip_from_world(&m, DepthConvention::Reverse),
            Err(CullError::NonFiniteMatrix {
                column: 2,
                row: 1,
                ..
            })
        ));
    }

    /// The camera rolled 45 degrees: the frustum's cross-section is a diamond in world x/y.
    fn rolled_camera(p: &Projection) -> Frustum {
        let view = Mat4::look_at_rh(
            Vec3::ZERO,
            Vec3::new(0.0, 0.0, -1.0),
            Vec3::new(1.0, 1.0, 0.0).normalize(),
        );
        Frustum::from_clip_from_world(&(p.matrix(1.0) * view), p.depth_convention()).unwrap()
    }

    #[test]
    fn box_beside_a_rolled_frustum_is_a_plane_test_false_positive_that_sat_separates() {
        let p = Projection::Perspective {
            fov_y_rad: 1.2,
            near: 0.1,
            far: Some(100.0),
            depth: DepthConvention::Reverse,
        };
        let f = rolled_camera(&p);
        // At depth <= 12 every frustum point has |x| <= 12 tan(0.6) sqrt(2) (the diamond's
        // vertex). A box within depths 8..12 entirely beyond that in x but tall in y straddles
        // every side plane of the diamond: no plane alone rejects it. The frustum itself reaches
        // larger x farther away, so what separates them is an axis mixing the box's y edge
        // with a frustum side edge, never a frustum face.
        let vertex_x = 12.0 * 0.6f32.tan() * std::f32::consts::SQRT_2;
        let b = Aabb::try_new(
            Vec3::new(vertex_x * 1.1, -3.0 * vertex_x, -12.0),
            Vec3::new(vertex_x * 3.0, 3.0 * vertex_x, -8.0),
        )
        .unwrap();
        assert_eq!(f.test_aabb(&b).unwrap(), PlaneTest::Intersecting);
        let sat = f.sat_aabb(&b).unwrap();
        assert!(
            matches!(
                sat,
                SatTest::Separated(SeparatingAxis::EdgeCross { box_edge: 1, .. })
            ),
            "{sat:?}"
        );
        // The same box moved to straddle the diamond's vertex overlaps.
        let b2 = Aabb::try_new(
            Vec3::new(vertex_x * 0.9, -3.0 * vertex_x, -12.0),
            Vec3::new(vertex_x * 3.0, 3.0 * vertex_x, -8.0),
        )
        .unwrap();
        assert_eq!(f.sat_aabb(&b2).unwrap(), SatTest::Overlapping);
    }

    #[test]
    fn sat_handles_infinite_far_exactly() {
        let p = Projection::tilegraph_default(1.0, 0.1);
        let (_, f) = camera(&p);
        // Far away, straight ahead: inside an infinite frustum.
        let far_box =
            Aabb::from_center_half_extents(Vec3::new(0.0, 0.0, -1e7), Vec3::splat(1.0)).unwrap();
        assert_eq!(f.sat_aabb(&far_box).unwrap(), SatTest::Overlapping);
        assert_eq!(f.test_aabb(&far_box).unwrap(), PlaneTest::Inside);
        // Behind the camera.
        let behind =
            Aabb::from_center_half_extents(Vec3::new(0.0, 0.0, 5.0), Vec3::splat(1.0)).unwrap();
        assert!(f.sat_aabb(&behind).unwrap().is_separated());
        assert!(f.test_aabb(&behind).unwrap().is_outside());
    }

    #[test]
    fn sat_obb_rotated_and_degenerate() {
        let p = Projection::Perspective {
            fov_y_rad: 1.0,
            near: 0.1,
            far: Some(100.0),
            depth: DepthConvention::Standard,
        };
        let (_, f) = camera(&p);
        let local = Aabb::try_new(Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, 1.0, 0.0)).unwrap();
        let inside = Obb::new(
            local,
            Affine3A::from_rotation_translation(
                Quat::from_rotation_x(0.7),
                Vec3::new(0.0, 0.0, -5.0),
            ),
        )
        .unwrap();
        assert_eq!(f.sat_obb(&inside).unwrap(), SatTest::Overlapping);
        let outside = Obb::new(
            local,
            Affine3A::from_rotation_translation(
                Quat::from_rotation_x(0.7),
                Vec3::new(50.0, 0.0, -5.0),
            ),
        )
        .unwrap();
        assert!(f.sat_obb(&outside).unwrap().is_separated());
        let point = Aabb::try_new(Vec3::new(0.0, 0.0, -5.0), Vec3::new(0.0, 0.0, -5.0)).unwrap();
        assert_eq!(f.sat_aabb(&point).unwrap(), SatTest::Overlapping);
    }

    #[test]
    fn accuracy_counts_are_consistent() {
        let p = Projection::Perspective {
            fov_y_rad: 1.2,
            near: 0.1,
            far: Some(100.0),
            depth: DepthConvention::Reverse,
        };
        let f = rolled_camera(&p);
        let mut boxes = Vec::new();
        for i in 0..20 {
            for j in 0..20 {
                for k in 0..4 {
                    let c = Vec3::new(
                        i as f32 * 2.0 - 20.0,
                        j as f32 * 2.0 - 20.0,
                        -4.0 - 4.0 * k as f32,
                    );
                    boxes
                        .push(Aabb::from_center_half_extents(c, Vec3::new(0.9, 1.7, 1.5)).unwrap());
                }
            }
        }
        let acc = measure_plane_test_false_positives(&f, &boxes).unwrap();
        assert_eq!(acc.boxes, 1600);
        assert_eq!(acc.plane_wrongly_rejected, 0);
        assert!(
            acc.plane_false_positives > 0,
            "the corner regions must produce some: {acc:?}"
        );
        assert_eq!(
            acc.sat_outside,
            acc.plane_outside + acc.plane_false_positives
        );
    }
}
