//! Two-dimensional extents in pixels.

use std::fmt;

/// Width and height of an image, render area or screen, in pixels.
///
/// Any pair of sides is representable (a render area of 0 x 0 is how an unset one prints), so
/// a crate that needs bounds checks them with its own error type: the graph validates the
/// extents it is given against the profile, the culling references against their own limits.
/// `Debug` prints the fields by name; the graph's plan digests depend on that text.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Extent2d {
    pub width_px: u32,
    pub height_px: u32,
}

impl Extent2d {
    pub const fn new(width_px: u32, height_px: u32) -> Self {
        Self {
            width_px,
            height_px,
        }
    }

    pub const fn pixel_count(self) -> u64 {
        self.width_px as u64 * self.height_px as u64
    }

    /// Extent of mip `level` (each side halves, rounding down, never below 1).
    pub const fn mip(self, level: u32) -> Self {
        let w = if level >= 32 {
            0
        } else {
            self.width_px >> level
        };
        let h = if level >= 32 {
            0
        } else {
            self.height_px >> level
        };
        Self {
            width_px: if w == 0 { 1 } else { w },
            height_px: if h == 0 { 1 } else { h },
        }
    }

    /// Length of the full mip chain down to 1x1.
    pub const fn full_mip_count(self) -> u32 {
        let max = if self.width_px > self.height_px {
            self.width_px
        } else {
            self.height_px
        };
        if max == 0 {
            0
        } else {
            32 - max.leading_zeros()
        }
    }
}

impl fmt::Display for Extent2d {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}x{}", self.width_px, self.height_px)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mips_round_down_and_stop_at_one() {
        let e = Extent2d::new(27, 13);
        assert_eq!(e.full_mip_count(), 5);
        assert_eq!(e.mip(1), Extent2d::new(13, 6));
        assert_eq!(e.mip(4), Extent2d::new(1, 1));
        assert_eq!(e.mip(40), Extent2d::new(1, 1));
        assert_eq!(Extent2d::new(1, 1).full_mip_count(), 1);
    }

    /// The graph's plan digests hash this text: it must stay the derived form.
    #[test]
    fn debug_and_display_text() {
        let e = Extent2d::new(1920, 1080);
        assert_eq!(
            format!("{e:?}"),
            "Extent2d { width_px: 1920, height_px: 1080 }"
        );
        assert_eq!(e.to_string(), "1920x1080");
    }
}
