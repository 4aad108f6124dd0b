//! Depth conventions, depth formats and the rounding rules that keep comparisons conservative.

use serde::{Deserialize, Serialize};

/// Which end of [0, 1] is near.
///
/// - `Standard`: near -> 0, far -> 1, nearer = smaller, depth compare LESS, HiZ keeps the MAX.
/// - `Reverse`: near -> 1, far (or infinity) -> 0, nearer = larger, compare GREATER, HiZ keeps
///   the MIN. tilegraph's default (with an infinite far plane): floating-point density near 0
///   matches the 1/z distribution, so precision is nearly uniform in log-distance.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
pub enum DepthConvention {
    Standard,
    #[default]
    Reverse,
}

impl DepthConvention {
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

    /// The value a depth buffer is cleared to: the farthest representable depth.
    #[inline]
    pub fn far_clear_value(self) -> f32 {
        match self {
            DepthConvention::Standard => 1.0,
            DepthConvention::Reverse => 0.0,
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

/// The format of the depth attachment the pyramid is built from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
pub enum DepthFormat {
    /// `VK_FORMAT_D32_SFLOAT`: stores the fragment depth unchanged.
    #[default]
    D32Float,
    /// `VK_FORMAT_D16_UNORM`: stores `round(clamp(d, 0, 1) * 65535)`; buffers handed to this crate
    /// hold the dequantized values `k / 65535` (see [`dequantize_d16`]).
    D16Unorm,
}

/// Number of steps of a 16-bit UNORM depth.
pub const D16_MAX_CODE: u16 = u16::MAX;

/// Converts a depth to its D16 UNORM code as the Vulkan spec defines it ("Conversion from
/// Floating-Point to Normalized Fixed-Point"): clamp to [0, 1], multiply by 65535, round to
/// nearest. The product is formed in f64, where it is exact (24 + 16 bits), so no double
/// rounding occurs. Ties round away from zero; the spec lets an implementation pick either
/// neighbour, and nothing in the HiZ test depends on the tie rule (see [`DepthFormat::toward_near`]).
/// NaN maps to 0, as the spec's NaN rule for UNORM conversion says.
pub fn quantize_d16(depth: f32) -> u16 {
    if depth.is_nan() {
        return 0;
    }
    let clamped = f64::from(depth).clamp(0.0, 1.0);
    // In [0, 65535] after the clamp, so the cast is exact.
    (clamped * f64::from(D16_MAX_CODE)).round() as u16
}

/// The float a shader reads from a D16 UNORM texel holding `code`: `code / 65535`, correctly
/// rounded to f32 (the spec's UNORM -> float conversion).
#[inline]
pub fn dequantize_d16(code: u16) -> f32 {
    f32::from(code) / f32::from(D16_MAX_CODE)
}

impl DepthFormat {
    /// What the attachment holds after a fragment of depth `depth` is written: identity for
    /// D32F, quantize-then-dequantize for D16.
    pub fn store(self, depth: f32) -> f32 {
        match self {
            DepthFormat::D32Float => depth,
            DepthFormat::D16Unorm => dequantize_d16(quantize_d16(depth)),
        }
    }

    /// Applies [`DepthFormat::store`] to a whole buffer (e.g. to turn a float depth render into
    /// what a D16 attachment would hold).
    pub fn store_buffer(self, depths: &[f32]) -> Vec<f32> {
        depths.iter().map(|&d| self.store(d)).collect()
    }

    /// The nearest value the attachment could hold for any fragment whose depth is `depth` or
    /// farther: for D16 the code on the near side of `depth` (floor for Standard, ceil for
    /// Reverse), so the result holds whichever neighbour the implementation rounds to; for
    /// D32F the depth itself. The HiZ test compares this, not the raw depth, with the pyramid.
    pub fn toward_near(self, convention: DepthConvention, depth: f32) -> f32 {
        match self {
            DepthFormat::D32Float => depth,
            DepthFormat::D16Unorm => {
                let scaled = f64::from(depth).clamp(0.0, 1.0) * f64::from(D16_MAX_CODE);
                let code = match convention {
                    DepthConvention::Standard => scaled.floor(),
                    DepthConvention::Reverse => scaled.ceil(),
                };
                // In [0, 65535] after the clamp, so the cast is exact.
                dequantize_d16(code as u16)
            }
        }
    }

    /// True when `depth` is a value an attachment of this format can hold.
    pub fn is_representable(self, depth: f32) -> bool {
        match self {
            DepthFormat::D32Float => depth.is_finite(),
            DepthFormat::D16Unorm => depth.is_finite() && self.store(depth) == depth,
        }
    }
}

/// The next f32 toward +infinity (`f32::next_up`, stable only since Rust 1.86).
pub(crate) fn next_f32_up(x: f32) -> f32 {
    if x.is_nan() || x == f32::INFINITY {
        return x;
    }
    if x == 0.0 {
        return f32::from_bits(1);
    }
    let bits = x.to_bits();
    if x > 0.0 {
        f32::from_bits(bits + 1)
    } else {
        f32::from_bits(bits - 1)
    }
}

/// The next f32 toward -infinity.
pub(crate) fn next_f32_down(x: f32) -> f32 {
    -next_f32_up(-x)
}

/// Largest f32 not above `x`.
pub(crate) fn f64_to_f32_round_down(x: f64) -> f32 {
    let y = x as f32;
    if f64::from(y) > x {
        next_f32_down(y)
    } else {
        y
    }
}

/// Smallest f32 not below `x`.
pub(crate) fn f64_to_f32_round_up(x: f64) -> f32 {
    let y = x as f32;
    if f64::from(y) < x {
        next_f32_up(y)
    } else {
        y
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn d16_round_trip_is_exact_for_every_code() {
        for code in 0..=u16::MAX {
            assert_eq!(quantize_d16(dequantize_d16(code)), code, "code {code}");
            assert!(DepthFormat::D16Unorm.is_representable(dequantize_d16(code)));
        }
    }

    #[test]
    fn d16_quantize_rounds_to_nearest_and_clamps() {
        assert_eq!(quantize_d16(0.0), 0);
        assert_eq!(quantize_d16(1.0), 65535);
        assert_eq!(quantize_d16(-3.0), 0);
        assert_eq!(quantize_d16(7.0), 65535);
        assert_eq!(quantize_d16(f32::NAN), 0);
        // 0.4 and 0.6 of a step round down and up.
        assert_eq!(quantize_d16((100.4 / 65535.0) as f32), 100);
        assert_eq!(quantize_d16((100.6 / 65535.0) as f32), 101);
    }

    #[test]
    fn toward_near_never_lies_behind_the_depth() {
        for convention in [DepthConvention::Standard, DepthConvention::Reverse] {
            for i in 0..10_000u32 {
                let d = i as f32 / 9_999.0;
                let q = DepthFormat::D16Unorm.toward_near(convention, d);
                assert!(
                    !convention.is_strictly_behind(q, d),
                    "{convention:?} {d} -> {q}"
                );
                // And it is never nearer than whatever either rounding neighbour would store.
                let stored = DepthFormat::D16Unorm.store(d);
                assert!(!convention.is_strictly_behind(q, stored));
            }
        }
    }

    #[test]
    fn directed_rounding_brackets_the_exact_value() {
        for x in [1.0 / 3.0, 1e-30, -2.5e-7, 0.999_999_999_9, 1e7 + 0.1] {
            let down = f64_to_f32_round_down(x);
            let up = f64_to_f32_round_up(x);
            assert!(f64::from(down) <= x && x <= f64::from(up), "{x}");
            assert!(f64::from(up) - f64::from(down) <= f64::from(next_f32_up(up)) - f64::from(up));
        }
        assert_eq!(next_f32_up(0.0), f32::from_bits(1));
        assert_eq!(next_f32_down(0.0), -f32::from_bits(1));
        assert_eq!(next_f32_up(-f32::from_bits(1)), -0.0);
    }

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
