//! Axis-aligned boxes and spheres: f32 [`Aabb`] (mesh-local, from tilegraph-types) and f64
//! [`DAabb`], [`DSphere`] (world).

use glam::{DVec3, Mat3, Mat3A, Vec3, Vec3A};
use serde::Serialize;

/// The f32 box (mesh-local bounds) is shared with the culling references, so it lives in
/// tilegraph-types; the f64 world types below are the scene's own.
pub use tilegraph_types::Aabb;

/// An axis-aligned box in f64, used for world bounds (coordinates may be large).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct DAabb {
    pub min: DVec3,
    pub max: DVec3,
}

impl DAabb {
    pub const EMPTY: DAabb = DAabb {
        min: DVec3::splat(f64::INFINITY),
        max: DVec3::splat(f64::NEG_INFINITY),
    };

    pub fn new(min: DVec3, max: DVec3) -> Self {
        DAabb { min, max }
    }

    #[must_use]
    pub fn union(self, other: DAabb) -> Self {
        DAabb {
            min: self.min.min(other.min),
            max: self.max.max(other.max),
        }
    }

    #[must_use]
    pub fn including(self, p: DVec3) -> Self {
        DAabb {
            min: self.min.min(p),
            max: self.max.max(p),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.min.cmpgt(self.max).any()
    }

    pub fn center(&self) -> DVec3 {
        (self.min + self.max) * 0.5
    }

    pub fn half_extents(&self) -> DVec3 {
        (self.max - self.min) * 0.5
    }

    pub fn contains(&self, p: DVec3) -> bool {
        p.cmpge(self.min).all() && p.cmple(self.max).all()
    }

    /// Whether `other` lies inside this box, with `slack` of tolerance on every side.
    pub fn contains_box(&self, other: &DAabb, slack: f64) -> bool {
        other.min.cmpge(self.min - slack).all() && other.max.cmple(self.max + slack).all()
    }
}

/// A sphere in world space (f64 centre so it survives large coordinates).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct DSphere {
    pub center: DVec3,
    pub radius: f64,
}

/// World bounds of one transformed local box, sharing one centre between the AABB and the sphere.
///
/// The centre is the transformed centre of the local box, kept in f64. The AABB half extents are
/// `|M| * e` (Arvo's method: exact for the transformed box). The sphere radius is the distance from
/// that centre to the farthest transformed corner, which is exact for the box (a parallelepiped's
/// farthest point from its centre is a corner) and never larger than the AABB's half diagonal.
pub(crate) fn transformed_bounds(
    linear: Mat3,
    translation: DVec3,
    local: &Aabb,
) -> (DVec3, Vec3, f32) {
    // The same f32 operations as on Vec3, in SIMD lanes (a move of an instance pays this).
    let l = Mat3A::from(linear);
    let c = Vec3A::from(local.center());
    let e = Vec3A::from(local.half_extents());
    let center = translation + Vec3::from(l * c).as_dvec3();
    let abs = Mat3A::from_cols(l.x_axis.abs(), l.y_axis.abs(), l.z_axis.abs());
    // Everything above is f32 arithmetic on local coordinates, and the GPU's own transform
    // (L * p) rounds too: each step is off by at most an ulp of |L| * |p|. Grow the bounds by a
    // few of those so they always enclose the drawn vertices, even for a mesh whose coordinates
    // sit far from its origin (10^4 m out, a box 0.25 m wide lost half a millimetre).
    let reach = Vec3A::from(local.min.abs().max(local.max.abs()));
    let pad = (abs * reach) * (8.0 * f32::EPSILON / 2.0);
    let half = Vec3::from(abs * e + pad);
    // |L k|^2 for the corners k = (±ex, ±ey, ±ez) is k' G k with G = L'L: a diagonal part
    // every corner shares and cross terms whose signs are the corner's (four corners cover the
    // eight: k and -k are as far). Cheaper than four transforms.
    let (x, y, z) = (l.x_axis, l.y_axis, l.z_axis);
    let diagonal = x.length_squared() * e.x * e.x
        + y.length_squared() * e.y * e.y
        + z.length_squared() * e.z * e.z;
    let (a, b, c2) = (
        2.0 * x.dot(y) * e.x * e.y,
        2.0 * x.dot(z) * e.x * e.z,
        2.0 * y.dot(z) * e.y * e.z,
    );
    let cross = (a + b + c2)
        .max(-a - b + c2)
        .max(-a + b - c2)
        .max(a - b - c2);
    // Rounding can leave the sum an ulp or two below the exact farthest corner: the pad, a few
    // ulps of |L| * reach, covers more than that.
    // The pad's components summed: at least its length, and no second square root.
    let radius =
        (diagonal + cross).max(0.0).sqrt() * (1.0 + 4.0 * f32::EPSILON) + (pad.x + pad.y + pad.z);
    (center, half, radius)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Quat;

    #[test]
    fn transformed_bounds_contain_every_transformed_corner() {
        let local = Aabb::new(Vec3::new(-1.0, 0.0, -2.0), Vec3::new(3.0, 5.0, 1.0));
        let linear = Mat3::from_quat(Quat::from_euler(glam::EulerRot::YXZ, 0.7, 0.3, -1.1))
            * Mat3::from_diagonal(Vec3::new(2.0, 0.5, 3.0));
        let t = DVec3::new(1e6, -3.0, 7.0);
        let (c, half, r) = transformed_bounds(linear, t, &local);
        for i in 0..8 {
            let p = Vec3::new(
                if i & 1 == 0 { local.min.x } else { local.max.x },
                if i & 2 == 0 { local.min.y } else { local.max.y },
                if i & 4 == 0 { local.min.z } else { local.max.z },
            );
            let w = t + (linear * p).as_dvec3();
            let d = w - c;
            assert!(
                d.abs().cmple(half.as_dvec3() + 1e-4).all(),
                "corner {i} outside AABB"
            );
            assert!(
                d.length() <= f64::from(r) + 1e-4,
                "corner {i} outside sphere"
            );
        }
        assert!(f64::from(r) <= half.as_dvec3().length() + 1e-4);
    }
}
