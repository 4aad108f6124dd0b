//! Depth formats and the D16 rounding rules that keep comparisons conservative. The depth
//! convention (which end of [0, 1] is near) is tilegraph-types' [`DepthConvention`], re-exported
//! here.

use serde::{Deserialize, Serialize};

pub use tilegraph_types::DepthConvention;

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
}
