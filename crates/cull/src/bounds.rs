//! Bounding volumes and their transforms. Every transform here rounds outward (computes in f64,
//! then rounds the result away from the volume), so a transformed volume always contains the
//! transformed original: the culling tests downstream are only as conservative as their bounds.

use glam::{Affine3A, DVec3, Vec3};
use tilegraph_types::round::{f64_to_f32_round_down, f64_to_f32_round_up};

use crate::check::{finite_affine, finite_f32, finite_vec3};
use crate::CullError;

pub use tilegraph_types::Aabb;

/// Sphere, metres. Radius 0 is allowed (a point).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sphere {
    pub center: Vec3,
    pub radius: f32,
}

/// Oriented box: a local AABB placed by an affine transform (rotation, scale, shear,
/// translation). Under shear or non-uniform scale the world shape is a parallelepiped; every
/// function here handles that general case.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Obb {
    pub local: Aabb,
    pub world_from_local: Affine3A,
}

fn dvec(v: Vec3) -> DVec3 {
    v.as_dvec3()
}

fn round_down_vec(v: DVec3) -> Vec3 {
    Vec3::new(
        f64_to_f32_round_down(v.x),
        f64_to_f32_round_down(v.y),
        f64_to_f32_round_down(v.z),
    )
}

fn round_up_vec(v: DVec3) -> Vec3 {
    Vec3::new(
        f64_to_f32_round_up(v.x),
        f64_to_f32_round_up(v.y),
        f64_to_f32_round_up(v.z),
    )
}

/// The linear part of an affine transform as f64 columns.
fn linear_columns_f64(m: &Affine3A) -> [DVec3; 3] {
    [
        dvec(m.matrix3.x_axis.into()),
        dvec(m.matrix3.y_axis.into()),
        dvec(m.matrix3.z_axis.into()),
    ]
}

fn transform_point_f64(m: &Affine3A, p: DVec3) -> DVec3 {
    let [cx, cy, cz] = linear_columns_f64(m);
    cx * p.x + cy * p.y + cz * p.z + dvec(m.translation.into())
}

/// A relative widening for results computed in f64 from f32 inputs: f64 sums of a handful of
/// exact f32 products err by far less than this, so rounding `x -/+ |x| * SLACK` outward to
/// f32 cannot land inside the exact value.
const F64_SLACK: f64 = 8.0 * f64::EPSILON;

fn widen_down(x: DVec3) -> DVec3 {
    x - x.abs() * F64_SLACK
}

fn widen_up(x: DVec3) -> DVec3 {
    x + x.abs() * F64_SLACK
}

/// The culling references' checked and outward-rounded operations on the shared [`Aabb`]:
/// validation with [`CullError`], constructors that reject bad input, and transforms that
/// round away from the box. A trait because the box lives in tilegraph-types, which knows
/// neither [`CullError`] nor this crate's [`Sphere`]. Public fields make it possible to build a
/// box without the checks, so every entry point here that takes a box validates it.
pub trait AabbExt: Sized {
    /// A validated box: all components finite and `min <= max` per axis.
    fn try_new(min: Vec3, max: Vec3) -> Result<Self, CullError>;

    /// A box from its centre and half extents (each >= 0).
    fn from_center_half_extents(center: Vec3, half_extents_m: Vec3) -> Result<Self, CullError>;

    /// The smallest box holding every point (error when `points` is empty or holds NaN).
    fn try_from_points(points: &[Vec3]) -> Result<Self, CullError>;

    /// A box given in f64 world coordinates, made camera-relative: `(world - eye)` is formed
    /// in f64 and rounded outward to f32. At 10^6 m an f32 world coordinate has a 6 cm step;
    /// relative to the eye the step shrinks with the distance to the eye instead.
    fn from_world_f64(
        min_world: DVec3,
        max_world: DVec3,
        eye_world: DVec3,
    ) -> Result<Self, CullError>;

    /// Checks the invariants [`AabbExt::try_new`] establishes.
    fn validate(&self, what: &'static str) -> Result<(), CullError>;

    /// The world AABB of this box under `m` (Arvo 1990: centre transformed, half extents through
    /// the absolute matrix), computed in f64 and rounded outward.
    fn transformed(&self, m: &Affine3A) -> Result<Self, CullError>;

    /// The sphere through the corners (centre at the box centre).
    fn bounding_sphere(&self) -> Sphere;
}

impl AabbExt for Aabb {
    fn try_new(min: Vec3, max: Vec3) -> Result<Self, CullError> {
        let b = Aabb { min, max };
        b.validate("aabb")?;
        Ok(b)
    }

    fn from_center_half_extents(center: Vec3, half_extents_m: Vec3) -> Result<Self, CullError> {
        finite_vec3("aabb", "center", center)?;
        finite_vec3("aabb", "half_extents_m", half_extents_m)?;
        let lo = dvec(center) - dvec(half_extents_m);
        let hi = dvec(center) + dvec(half_extents_m);
        Aabb::try_new(round_down_vec(widen_down(lo)), round_up_vec(widen_up(hi)))
    }

    fn try_from_points(points: &[Vec3]) -> Result<Self, CullError> {
        let Some(first) = points.first() else {
            return Err(CullError::BufferSizeMismatch {
                what: "aabb points",
                expected_len: 1,
                actual_len: 0,
            });
        };
        let mut min = *first;
        let mut max = *first;
        for &p in points {
            finite_vec3("aabb points", "point", p)?;
            min = min.min(p);
            max = max.max(p);
        }
        Aabb::try_new(min, max)
    }

    fn from_world_f64(
        min_world: DVec3,
        max_world: DVec3,
        eye_world: DVec3,
    ) -> Result<Self, CullError> {
        for (field, v) in [
            ("min_world", min_world),
            ("max_world", max_world),
            ("eye_world", eye_world),
        ] {
            for c in v.to_array() {
                if !c.is_finite() {
                    return Err(CullError::NonFiniteValue {
                        what: "aabb",
                        field,
                        value: c as f32,
                    });
                }
            }
        }
        Aabb::try_new(
            round_down_vec(widen_down(min_world - eye_world)),
            round_up_vec(widen_up(max_world - eye_world)),
        )
    }

    fn validate(&self, what: &'static str) -> Result<(), CullError> {
        finite_vec3(what, "min", self.min)?;
        finite_vec3(what, "max", self.max)?;
        for (axis, (lo, hi)) in ['x', 'y', 'z']
            .into_iter()
            .zip(self.min.to_array().into_iter().zip(self.max.to_array()))
        {
            if lo > hi {
                return Err(CullError::InvertedBounds {
                    what,
                    axis,
                    min: lo,
                    max: hi,
                });
            }
        }
        Ok(())
    }

    fn transformed(&self, m: &Affine3A) -> Result<Self, CullError> {
        self.validate("aabb")?;
        finite_affine("aabb transform", m)?;
        let cols = linear_columns_f64(m);
        let c = transform_point_f64(m, (dvec(self.min) + dvec(self.max)) * 0.5);
        let e = (dvec(self.max) - dvec(self.min)) * 0.5;
        let ext = cols[0].abs() * e.x + cols[1].abs() * e.y + cols[2].abs() * e.z;
        Aabb::try_new(
            round_down_vec(widen_down(c - ext)),
            round_up_vec(widen_up(c + ext)),
        )
    }

    fn bounding_sphere(&self) -> Sphere {
        let c = (dvec(self.min) + dvec(self.max)) * 0.5;
        let r = ((dvec(self.max) - dvec(self.min)) * 0.5).length();
        let center = c.as_vec3();
        // The centre rounds to nearest, so the radius absorbs that error too.
        let radius = f64_to_f32_round_up((r + (dvec(center) - c).length()) * (1.0 + F64_SLACK));
        Sphere { center, radius }
    }
}

impl Sphere {
    /// A validated sphere: finite centre, finite radius >= 0.
    pub fn new(center: Vec3, radius_m: f32) -> Result<Self, CullError> {
        let s = Sphere {
            center,
            radius: radius_m,
        };
        s.validate("sphere")?;
        Ok(s)
    }

    /// A sphere given in f64 world coordinates, made camera-relative (see
    /// [`Aabb::from_world_f64`]); the radius grows by the rounding error of the centre.
    pub fn from_world_f64(
        center_world: DVec3,
        radius_m: f64,
        eye_world: DVec3,
    ) -> Result<Self, CullError> {
        for (field, v) in [("center_world", center_world), ("eye_world", eye_world)] {
            for c in v.to_array() {
                if !c.is_finite() {
                    return Err(CullError::NonFiniteValue {
                        what: "sphere",
                        field,
                        value: c as f32,
                    });
                }
            }
        }
        if !radius_m.is_finite() {
            return Err(CullError::NonFiniteValue {
                what: "sphere",
                field: "radius_m",
                value: radius_m as f32,
            });
        }
        if radius_m < 0.0 {
            return Err(CullError::NegativeRadius {
                what: "sphere",
                radius_m: radius_m as f32,
            });
        }
        let rel = center_world - eye_world;
        let center = rel.as_vec3();
        let err = (dvec(center) - rel).length() + rel.length() * F64_SLACK;
        Sphere::new(center, f64_to_f32_round_up(radius_m + err))
    }

    pub fn validate(&self, what: &'static str) -> Result<(), CullError> {
        finite_vec3(what, "center", self.center)?;
        finite_f32(what, "radius", self.radius)?;
        if self.radius < 0.0 {
            return Err(CullError::NegativeRadius {
                what,
                radius_m: self.radius,
            });
        }
        Ok(())
    }

    /// Closed containment test.
    pub fn contains_point(&self, p: Vec3) -> bool {
        (dvec(p) - dvec(self.center)).length_squared()
            <= f64::from(self.radius) * f64::from(self.radius)
    }

    /// The sphere's AABB.
    pub fn aabb(&self) -> Aabb {
        let c = dvec(self.center);
        let r = DVec3::splat(f64::from(self.radius));
        Aabb {
            min: round_down_vec(widen_down(c - r)),
            max: round_up_vec(widen_up(c + r)),
        }
    }

    /// The image under `m`, enlarged to stay a sphere: the radius scales by an upper bound of
    /// the largest singular value of the linear part (exact for rotation x scale, whose columns
    /// are orthogonal; a safe over-estimate under shear).
    pub fn transformed(&self, m: &Affine3A) -> Result<Sphere, CullError> {
        self.validate("sphere")?;
        finite_affine("sphere transform", m)?;
        let c = transform_point_f64(m, dvec(self.center));
        let stretch = max_stretch_upper_bound(m);
        let center = c.as_vec3();
        let err = (dvec(center) - c).length() + c.length() * F64_SLACK;
        let radius =
            f64_to_f32_round_up((f64::from(self.radius) * stretch + err) * (1.0 + F64_SLACK));
        Sphere::new(center, radius)
    }
}

/// Upper bound of the spectral norm of the linear part: sqrt of the Gershgorin bound of the
/// largest eigenvalue of M^T M. For orthogonal columns M^T M is diagonal and the bound is the
/// longest column, i.e. exact.
fn max_stretch_upper_bound(m: &Affine3A) -> f64 {
    let cols = linear_columns_f64(m);
    let mut worst = 0.0f64;
    for i in 0..3 {
        let row_sum: f64 = (0..3).map(|j| cols[i].dot(cols[j]).abs()).sum();
        worst = worst.max(row_sum);
    }
    worst.sqrt()
}

impl Obb {
    pub fn new(local: Aabb, world_from_local: Affine3A) -> Result<Self, CullError> {
        let o = Obb {
            local,
            world_from_local,
        };
        o.validate("obb")?;
        Ok(o)
    }

    pub fn validate(&self, what: &'static str) -> Result<(), CullError> {
        self.local.validate(what)?;
        finite_affine(what, &self.world_from_local)
    }

    /// World-space centre (f64, exact up to f64 rounding).
    pub fn center_f64(&self) -> DVec3 {
        transform_point_f64(
            &self.world_from_local,
            (dvec(self.local.min) + dvec(self.local.max)) * 0.5,
        )
    }

    /// The three world-space half-edge vectors (local axes times local half extents), f64.
    pub fn half_edges_f64(&self) -> [DVec3; 3] {
        let cols = linear_columns_f64(&self.world_from_local);
        let e = (dvec(self.local.max) - dvec(self.local.min)) * 0.5;
        [cols[0] * e.x, cols[1] * e.y, cols[2] * e.z]
    }

    /// The 8 world corners in f64, indexed like [`Aabb::corners`].
    pub fn corners_f64(&self) -> [DVec3; 8] {
        let local = self.local.corners();
        std::array::from_fn(|i| transform_point_f64(&self.world_from_local, dvec(local[i])))
    }

    /// The world AABB enclosing the box.
    pub fn aabb(&self) -> Result<Aabb, CullError> {
        self.local.transformed(&self.world_from_local)
    }

    /// This box placed by a further transform.
    pub fn transformed(&self, m: &Affine3A) -> Result<Obb, CullError> {
        finite_affine("obb transform", m)?;
        Obb::new(self.local, *m * self.world_from_local)
    }
}

impl From<Aabb> for Obb {
    fn from(b: Aabb) -> Self {
        Obb {
            local: b,
            world_from_local: Affine3A::IDENTITY,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Quat;

    #[test]
    fn rejects_invalid_boxes_and_spheres() {
        assert!(matches!(
            Aabb::try_new(Vec3::new(1.0, 0.0, 0.0), Vec3::ZERO),
            Err(CullError::InvertedBounds { axis: 'x', .. })
        ));
        assert!(matches!(
            Aabb::try_new(Vec3::new(f32::NAN, 0.0, 0.0), Vec3::ONE),
            Err(CullError::NonFiniteValue { field: "min", .. })
        ));
        assert!(matches!(
            Sphere::new(Vec3::ZERO, -1.0),
            Err(CullError::NegativeRadius { .. })
        ));
        assert!(
            Aabb::try_new(Vec3::ONE, Vec3::ONE).is_ok(),
            "zero extent is a valid point box"
        );
        assert!(matches!(
            Aabb::try_from_points(&[]),
            Err(CullError::BufferSizeMismatch { .. })
        ));
    }

    #[test]
    fn transformed_aabb_contains_transformed_corners() {
        let b = Aabb::try_new(Vec3::new(-1.0, 2.0, 0.5), Vec3::new(3.0, 2.5, 4.0)).unwrap();
        let m = Affine3A::from_scale_rotation_translation(
            Vec3::new(2.0, 0.5, 3.0),
            Quat::from_euler(glam::EulerRot::XYZ, 0.3, 1.1, -0.7),
            Vec3::new(1e3, -7.0, 0.25),
        );
        let t = b.transformed(&m).unwrap();
        let s = b.bounding_sphere().transformed(&m).unwrap();
        for c in b.corners() {
            // Exact (f64) image of the corner: the f32 transform would add its own rounding.
            let p = transform_point_f64(&m, dvec(c));
            assert!(dvec(t.min).cmple(p).all() && dvec(t.max).cmpge(p).all());
            assert!((p - dvec(s.center)).length() <= f64::from(s.radius));
        }
    }

    #[test]
    fn sphere_radius_bound_covers_shear() {
        // A shear stretches some direction by more than its longest column: (1 + sqrt 5) / 2
        // vs sqrt 2.
        let m = Affine3A::from_cols_array(&[
            1.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0,
        ]);
        let s = Sphere::new(Vec3::ZERO, 1.0)
            .unwrap()
            .transformed(&m)
            .unwrap();
        assert!(s.radius >= 1.618_034);
        for i in 0..360 {
            let a = (i as f32).to_radians();
            let p = Vec3::new(a.cos(), a.sin(), 0.0);
            assert!(s.contains_point(m.transform_point3(p)));
        }
    }

    #[test]
    fn camera_relative_conversion_rounds_outward() {
        let eye = DVec3::new(1e6 + 0.123_456_789, -2e6, 3e6);
        let min = DVec3::new(1e6 + 5.000_000_01, -2e6 - 1.0, 3e6 + 0.1);
        let max = min + DVec3::new(0.3, 0.2, 1e-9);
        let b = Aabb::from_world_f64(min, max, eye).unwrap();
        assert!(b.min.as_dvec3().cmple(min - eye).all());
        assert!(b.max.as_dvec3().cmpge(max - eye).all());
        let s = Sphere::from_world_f64(min, 0.5, eye).unwrap();
        assert!((s.center.as_dvec3() - (min - eye)).length() + 0.5 <= f64::from(s.radius));
    }

    #[test]
    fn obb_corners_and_aabb_agree() {
        let local = Aabb::try_new(Vec3::new(-1.0, -2.0, -0.5), Vec3::new(1.0, 2.0, 0.5)).unwrap();
        let m = Affine3A::from_rotation_translation(
            Quat::from_rotation_y(0.6),
            Vec3::new(4.0, 0.0, -9.0),
        );
        let o = Obb::new(local, m).unwrap();
        let aabb = o.aabb().unwrap();
        for c in o.corners_f64() {
            assert!(aabb.contains_point(c.as_vec3()));
        }
        let he = o.half_edges_f64();
        assert!((he[1].length() - 2.0).abs() < 1e-6);
        assert!((o.center_f64() - DVec3::new(4.0, 0.0, -9.0)).length() < 1e-6);
    }
}
