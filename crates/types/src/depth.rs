//! Depth conventions: which end of [0, 1] is near, and the compares, clears and conservative
//! roundings that follow from it.

use serde::{Deserialize, Serialize};

use crate::round::{f64_to_f32_round_down, f64_to_f32_round_up, next_f32_down, next_f32_up};

/// Which end of [0, 1] is near, so that depth tests, clears and HiZ reductions pick the right
/// compare.
///
/// - `Standard`: near -> 0, far -> 1, nearer = smaller, depth compare LESS, HiZ keeps the MAX.
/// - `Reverse`: near -> 1, far (or infinity) -> 0, nearer = larger, compare GREATER, HiZ keeps
///   the MIN. tilegraph's default (with an infinite far plane): floating-point density near 0
///   matches the 1/z distribution, so precision is nearly uniform in log-distance.
///
/// Serialized in snake_case (`"standard"`, `"reverse"`): camera-path JSON stores it per frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DepthConvention {
    /// near -> 0, far -> 1; depth test LESS, clear to 1, HiZ keeps the max.
    Standard,
    /// near -> 1, far (or infinity) -> 0; depth test GREATER, clear to 0, HiZ keeps the min.
    #[default]
    Reverse,
}

impl DepthConvention {
    /// The depth-buffer clear value: the farthest representable depth.
    pub fn far_depth(self) -> f32 {
        match self {
            DepthConvention::Standard => 1.0,
            DepthConvention::Reverse => 0.0,
        }
    }

    /// The depth of the near plane.
    pub fn near_depth(self) -> f32 {
        match self {
            DepthConvention::Standard => 0.0,
            DepthConvention::Reverse => 1.0,
        }
    }

    /// Whether depth `a` is strictly closer to the camera than depth `b`: the converse of
    /// [`DepthConvention::is_strictly_behind`], for callers that ask from the near side.
    pub fn is_closer(self, a: f32, b: f32) -> bool {
        self.is_strictly_behind(b, a)
    }

    /// The farther of two depths: `max` for Standard, `min` for Reverse. This is the only
    /// arithmetic the HiZ pyramid performs, so a GPU reproduces it bit for bit.
    #[inline]
    pub fn farther(self, a: f32, b: f32) -> f32 {
        match self {
            DepthConvention::Standard => a.max(b),
            DepthConvention::Reverse => a.min(b),
        }
    }

    /// The nearer of two depths.
    #[inline]
    pub fn nearer(self, a: f32, b: f32) -> f32 {
        match self {
            DepthConvention::Standard => a.min(b),
            DepthConvention::Reverse => a.max(b),
        }
    }

    /// True when `depth` lies strictly behind `reference` (farther from the camera). Equal depths
    /// are never "behind": a fragment at the same depth may still pass LESS_OR_EQUAL.
    #[inline]
    pub fn is_strictly_behind(self, depth: f32, reference: f32) -> bool {
        match self {
            DepthConvention::Standard => depth > reference,
            DepthConvention::Reverse => depth < reference,
        }
    }

    /// Rounds an exact (f64) depth to f32 in the direction of the camera, so the result is
    /// never farther than the exact value.
    pub fn round_toward_near(self, depth: f64) -> f32 {
        match self {
            DepthConvention::Standard => f64_to_f32_round_down(depth),
            DepthConvention::Reverse => f64_to_f32_round_up(depth),
        }
    }

    /// Moves `depth` `ulps` representable f32 steps toward the camera.
    pub fn nudge_toward_near(self, depth: f32, ulps: u32) -> f32 {
        let mut d = depth;
        for _ in 0..ulps {
            d = match self {
                DepthConvention::Standard => next_f32_down(d),
                DepthConvention::Reverse => next_f32_up(d),
            };
        }
        d
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn farther_and_behind_follow_the_convention() {
        let s = DepthConvention::Standard;
        let r = DepthConvention::Reverse;
        assert_eq!(s.farther(0.2, 0.7), 0.7);
        assert_eq!(r.farther(0.2, 0.7), 0.2);
        assert!(s.is_strictly_behind(0.7, 0.2));
        assert!(r.is_strictly_behind(0.2, 0.7));
        assert!(!s.is_strictly_behind(0.5, 0.5));
        assert!(!r.is_strictly_behind(0.5, 0.5));
        assert_eq!(s.nudge_toward_near(0.5, 1), next_f32_down(0.5));
        assert_eq!(r.nudge_toward_near(0.5, 1), next_f32_up(0.5));
    }
}
