//! Screen-space rectangles and the NDC -> pixel mapping.
//!
//! Pixel (px, py) spans the square [px, px+1) x [py, py+1) in pixel coordinates and has its
//! centre at NDC x = (px + 0.5) / w * 2 - 1, y = (py + 0.5) / h * 2 - 1; pixel (0, 0) is the
//! top-left one (NDC y = -1 is the top row, the projection carries the y flip).

use glam::Vec2;

use crate::CullError;

/// Largest width or height accepted. Keeps every product in the pyramid's texel mapping
/// below 2^32 so a shader can do it in `uint` (see `hiz`), and covers Vulkan's common
/// `maxImageDimension2D`.
pub const MAX_EXTENT_PX: u32 = 16384;

pub use tilegraph_types::Extent2d;

/// The culling references' checks on the shared [`Extent2d`], which any pair of sides can
/// build: every entry point that takes an extent validates it (both sides in
/// 1..=[`MAX_EXTENT_PX`]) with [`ExtentExt::validate`], and the constructors here validate
/// at once. A trait because the type lives in tilegraph-types, which knows no [`CullError`].
pub trait ExtentExt: Sized {
    /// A validated extent, reported as `"extent"` in errors.
    fn try_new(width_px: u32, height_px: u32) -> Result<Self, CullError>;

    /// Like [`ExtentExt::try_new`], with the name errors report.
    fn named(what: &'static str, width_px: u32, height_px: u32) -> Result<Self, CullError>;

    /// Both sides in 1..=[`MAX_EXTENT_PX`]; `what` names the extent in the error.
    fn validate(&self, what: &'static str) -> Result<(), CullError>;

    /// The length of a row-major buffer of one value per pixel.
    fn buffer_len(&self) -> usize;

    /// Checks that a row-major buffer matches this extent.
    fn check_len(&self, what: &'static str, len: usize) -> Result<(), CullError>;
}

impl ExtentExt for Extent2d {
    fn try_new(width_px: u32, height_px: u32) -> Result<Self, CullError> {
        Extent2d::named("extent", width_px, height_px)
    }

    fn named(what: &'static str, width_px: u32, height_px: u32) -> Result<Self, CullError> {
        let extent = Extent2d::new(width_px, height_px);
        extent.validate(what)?;
        Ok(extent)
    }

    fn validate(&self, what: &'static str) -> Result<(), CullError> {
        let (width_px, height_px) = (self.width_px, self.height_px);
        if width_px == 0 || height_px == 0 {
            return Err(CullError::ZeroExtent {
                what,
                width_px,
                height_px,
            });
        }
        if width_px > MAX_EXTENT_PX || height_px > MAX_EXTENT_PX {
            return Err(CullError::ExtentTooLarge {
                what,
                width_px,
                height_px,
                max_px: MAX_EXTENT_PX,
            });
        }
        Ok(())
    }

    fn buffer_len(&self) -> usize {
        self.width_px as usize * self.height_px as usize
    }

    fn check_len(&self, what: &'static str, len: usize) -> Result<(), CullError> {
        if len == self.buffer_len() {
            Ok(())
        } else {
            Err(CullError::BufferSizeMismatch {
                what,
                expected_len: self.buffer_len(),
                actual_len: len,
            })
        }
    }
}

/// A rectangle in NDC (x right, y down: -1 is the top row). `min <= max`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NdcRect {
    pub min: Vec2,
    pub max: Vec2,
}

/// An inclusive rectangle of level-0 pixels, possibly reaching past the screen (signed).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct PixelRect {
    pub min_x: i32,
    pub min_y: i32,
    pub max_x: i32,
    pub max_y: i32,
}

/// Converts an NDC coordinate to pixel coordinates (f64, not rounded).
fn ndc_to_px(ndc: f32, size_px: u32) -> f64 {
    (f64::from(ndc) + 1.0) * 0.5 * f64::from(size_px)
}

/// Floors to i32, saturating: rects of objects just past the near plane reach far off-screen.
fn floor_to_i32(x: f64) -> i32 {
    // `as` saturates for out-of-range floats; NaN cannot reach here (inputs are validated).
    x.floor() as i32
}

impl NdcRect {
    /// Every pixel whose square [px, px+1) overlaps the closed rect. This is wider than "pixels
    /// whose centre is inside" by up to one pixel per side, which absorbs the rasterizer's
    /// sub-pixel vertex snapping and any rounding in the rect itself: an object can only cover
    /// pixels whose centres lie inside its projected silhouette, and those are all included.
    pub fn to_pixel_rect(&self, extent: Extent2d) -> Result<PixelRect, CullError> {
        extent.validate("screen extent")?;
        for (field, v) in [("rect_ndc.min", self.min), ("rect_ndc.max", self.max)] {
            for c in v.to_array() {
                crate::check::finite_f32("ndc rect", field, c)?;
            }
        }
        for (axis, lo, hi) in [('x', self.min.x, self.max.x), ('y', self.min.y, self.max.y)] {
            if lo > hi {
                return Err(CullError::InvertedBounds {
                    what: "ndc rect",
                    axis,
                    min: lo,
                    max: hi,
                });
            }
        }
        Ok(PixelRect {
            min_x: floor_to_i32(ndc_to_px(self.min.x, extent.width_px)),
            min_y: floor_to_i32(ndc_to_px(self.min.y, extent.height_px)),
            max_x: floor_to_i32(ndc_to_px(self.max.x, extent.width_px)),
            max_y: floor_to_i32(ndc_to_px(self.max.y, extent.height_px)),
        })
    }
}

/// A pixel rectangle after clamping to the screen.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ClampedRect {
    /// Inclusive, inside the screen: `min_* <= max_* < extent`.
    OnScreen {
        min_x: u32,
        min_y: u32,
        max_x: u32,
        max_y: u32,
    },
    /// Entirely left of, right of, above or below the screen.
    OffScreen,
}

impl PixelRect {
    /// A validated rect (`min <= max` per axis).
    pub fn new(min_x: i32, min_y: i32, max_x: i32, max_y: i32) -> Result<Self, CullError> {
        let r = PixelRect {
            min_x,
            min_y,
            max_x,
            max_y,
        };
        r.validate()?;
        Ok(r)
    }

    pub fn validate(&self) -> Result<(), CullError> {
        for (axis, lo, hi) in [('x', self.min_x, self.max_x), ('y', self.min_y, self.max_y)] {
            if lo > hi {
                return Err(CullError::InvertedBounds {
                    what: "pixel rect",
                    axis,
                    min: lo as f32,
                    max: hi as f32,
                });
            }
        }
        Ok(())
    }

    /// Clamps to `[0, extent - 1]`; a rect with no pixel on screen is `OffScreen` (so is every
    /// rect on a screen with no pixel: an empty extent has no `extent - 1` to clamp to).
    pub fn clamp_to(&self, extent: Extent2d) -> ClampedRect {
        let (w, h) = (i64::from(extent.width_px), i64::from(extent.height_px));
        let (x0, x1) = (i64::from(self.min_x), i64::from(self.max_x));
        let (y0, y1) = (i64::from(self.min_y), i64::from(self.max_y));
        if w == 0 || h == 0 || x1 < 0 || y1 < 0 || x0 >= w || y0 >= h {
            return ClampedRect::OffScreen;
        }
        // Each value is in [0, w-1] or [0, h-1] after the clamp, so it fits u32.
        ClampedRect::OnScreen {
            min_x: x0.clamp(0, w - 1) as u32,
            min_y: y0.clamp(0, h - 1) as u32,
            max_x: x1.clamp(0, w - 1) as u32,
            max_y: y1.clamp(0, h - 1) as u32,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn extent_validation() {
        assert!(matches!(
            Extent2d::try_new(0, 5),
            Err(CullError::ZeroExtent { .. })
        ));
        assert!(matches!(
            Extent2d::try_new(5, 0),
            Err(CullError::ZeroExtent { .. })
        ));
        assert!(matches!(
            Extent2d::try_new(MAX_EXTENT_PX + 1, 1),
            Err(CullError::ExtentTooLarge { .. })
        ));
        let e = Extent2d::try_new(27, 13).unwrap();
        assert!(e.check_len("d", 27 * 13).is_ok());
        assert!(matches!(
            e.check_len("d", 27 * 13 - 1),
            Err(CullError::BufferSizeMismatch {
                expected_len: 351,
                actual_len: 350,
                ..
            })
        ));
    }

    #[test]
    fn pixel_centres_map_back_to_their_pixel() {
        let e = Extent2d::try_new(27, 13).unwrap();
        for py in 0..13u32 {
            for px in 0..27u32 {
                let ndc = Vec2::new(
                    (px as f32 + 0.5) / 27.0 * 2.0 - 1.0,
                    (py as f32 + 0.5) / 13.0 * 2.0 - 1.0,
                );
                let r = NdcRect { min: ndc, max: ndc }.to_pixel_rect(e).unwrap();
                assert_eq!(
                    (r.min_x, r.min_y, r.max_x, r.max_y),
                    (px as i32, py as i32, px as i32, py as i32)
                );
            }
        }
    }

    #[test]
    fn full_screen_and_off_screen_rects() {
        let e = Extent2d::try_new(4, 3).unwrap();
        let full = NdcRect {
            min: Vec2::splat(-1.0),
            max: Vec2::splat(1.0),
        };
        let r = full.to_pixel_rect(e).unwrap();
        assert_eq!(
            r.clamp_to(e),
            ClampedRect::OnScreen {
                min_x: 0,
                min_y: 0,
                max_x: 3,
                max_y: 2
            }
        );
        let right = NdcRect {
            min: Vec2::new(1.0, -0.5),
            max: Vec2::new(3.0, 0.5),
        };
        assert_eq!(
            right.to_pixel_rect(e).unwrap().clamp_to(e),
            ClampedRect::OffScreen
        );
        let huge = NdcRect {
            min: Vec2::splat(-1e30),
            max: Vec2::splat(1e30),
        };
        assert!(matches!(
            huge.to_pixel_rect(e).unwrap().clamp_to(e),
            ClampedRect::OnScreen {
                min_x: 0,
                max_x: 3,
                ..
            }
        ));
        assert!(NdcRect {
            min: Vec2::ONE,
            max: Vec2::ZERO
        }
        .to_pixel_rect(e)
        .is_err());
    }
}
