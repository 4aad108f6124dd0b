//! Axis-aligned boxes in f32.

use glam::Vec3;
use serde::Serialize;

/// An axis-aligned box in f32, metres: mesh-local bounds in a scene (small coordinates), and
/// camera-relative bounds in the culling references. `min == max` on an axis is a flat or point
/// box; [`Aabb::EMPTY`] (min above max) holds nothing and grows to the first point added.
///
/// Nothing here checks the fields, so every box is representable; a crate that needs a finite,
/// non-inverted box checks it with its own error type (tilegraph-cull's `AabbExt::validate`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Aabb {
    pub min: Vec3,
    pub max: Vec3,
}

impl Aabb {
    /// The empty box: min = +inf, max = -inf, so that any point extends it.
    pub const EMPTY: Aabb = Aabb {
        min: Vec3::splat(f32::INFINITY),
        max: Vec3::splat(f32::NEG_INFINITY),
    };

    pub fn new(min: Vec3, max: Vec3) -> Self {
        Aabb { min, max }
    }

    /// The smallest box holding every point; [`Aabb::EMPTY`] when there is none.
    pub fn from_points(points: impl IntoIterator<Item = Vec3>) -> Self {
        points.into_iter().fold(Aabb::EMPTY, |b, p| b.including(p))
    }

    #[must_use]
    pub fn including(self, p: Vec3) -> Self {
        Aabb {
            min: self.min.min(p),
            max: self.max.max(p),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.min.cmpgt(self.max).any()
    }

    pub fn center(&self) -> Vec3 {
        (self.min + self.max) * 0.5
    }

    pub fn half_extents(&self) -> Vec3 {
        (self.max - self.min) * 0.5
    }

    /// The 8 corners; bit 0 of the index selects max x, bit 1 max y, bit 2 max z.
    pub fn corners(&self) -> [Vec3; 8] {
        std::array::from_fn(|i| {
            Vec3::new(
                if i & 1 == 0 { self.min.x } else { self.max.x },
                if i & 2 == 0 { self.min.y } else { self.max.y },
                if i & 4 == 0 { self.min.z } else { self.max.z },
            )
        })
    }

    /// Closed containment test.
    pub fn contains_point(&self, p: Vec3) -> bool {
        p.cmpge(self.min).all() && p.cmple(self.max).all()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn empty_box_grows_to_points() {
        let b = Aabb::from_points([Vec3::ONE, -Vec3::ONE]);
        assert!(!b.is_empty());
        assert!(Aabb::EMPTY.is_empty());
        assert_eq!(b.center(), Vec3::ZERO);
    }
}
