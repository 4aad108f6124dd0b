//! Hierarchical-Z pyramid and occlusion test.
//!
//! # Pyramid
//!
//! Level 0 is the depth buffer itself (a copy, texel for texel). Levels 1.. are reductions; a
//! GPU that keeps them in one image stores level `k` in mip `k - 1` (or keeps a copy of the
//! depth in mip 0 and level `k` in mip `k`: the values are the same). Every texel value is the
//! *farthest* (`max` Standard / `min` Reverse) of the texels it reads: pure min/max, no filtering
//! arithmetic, so a shader reproduces the pyramid bit for bit (up to the sign of zero).
//!
//! Per axis (x shown; y is identical with heights), with `S_k` the extent of level k and `w` the
//! extent of level 0, texel `t` of level `k` reads:
//!
//! - [`NpotMode::EdgeAware`], `S_k = max(1, S_{k-1} / 2)` (integer division, the Vulkan mip
//!   chain): level k-1 texels `2t ..= (t == S_k - 1 ? S_{k-1} - 1 : 2t + 1)`. The last texel
//!   also takes the odd leftover column, so it reads up to 3 (3x3 at a corner).
//! - [`NpotMode::PadToPow2`]: level 1 has `P = ` the largest power of two strictly below `w`
//!   (1 when `w = 1`); its texel `t` reads level-0 pixels `floor(t*w/P) ..= ceil((t+1)*w/P) - 1`
//!   (1 to 3 pixels: `w/P` is in (1, 2]). Levels k >= 2 halve cleanly:
//!   `S_k = max(1, S_{k-1} / 2)` and texel `t` reads `2t ..= min(2t + 1, S_{k-1} - 1)`.
//! - [`NpotMode::NaiveBuggy`]: the Vulkan chain with a plain clamped 2x2: `2t ..= min(2t + 1,
//!   S_{k-1} - 1)`. At odd sizes the last column of level k-1 is read by nobody (seed 000:
//!   27 -> 13 drops column 26). Only for the test that shows the bug.
//!
//! The chain ends at the first level that is 1x1.
//!
//! # Level-0 pixel -> texel mapping
//!
//! Each level has a per-axis rational scale `texels / pixels`; level-0 pixel `p` maps to texel
//! `min(p * texels / pixels, S_k - 1)` (integer division). EdgeAware and NaiveBuggy:
//! `texels = 1, pixels = 2^k`. PadToPow2: level 0 `1/1`, level k >= 1 `P / (w * 2^(k-1))`.
//! All products stay below 2^32 for extents up to [`crate::MAX_EXTENT_PX`], so `uint` suffices
//! in GLSL. For EdgeAware and PadToPow2 the texel a pixel maps to always covers that pixel (its
//! footprint, see [`HizPyramid::footprint`], contains it), which is what makes the test
//! conservative; NaiveBuggy's does not at odd sizes.
//!
//! # Test
//!
//! See [`HizPyramid::test_rect`].

use glam::UVec2;
use serde::{Deserialize, Serialize};

use crate::depth::{DepthConvention, DepthFormat};
use crate::project::ScreenProjection;
use crate::screen::{ClampedRect, Extent2d, ExtentExt, PixelRect};
use crate::CullError;

/// How odd (non-power-of-two) sizes are reduced.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum NpotMode {
    /// Vulkan mip chain; the last texel of a level reads the leftover odd row/column.
    EdgeAware,
    /// Reduce once to the power of two below the size, then halve cleanly.
    PadToPow2,
    /// Plain 2x2 on the Vulkan chain: loses data at odd sizes. Demonstrates the bug.
    NaiveBuggy,
}

/// Per-axis mapping `texel = min(pixel * texels / pixels, extent - 1)`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct AxisScale {
    pub texels: u32,
    pub pixels: u32,
}

impl AxisScale {
    /// Level-0 pixels per texel, for display.
    pub fn pixels_per_texel(&self) -> f64 {
        f64::from(self.pixels) / f64::from(self.texels)
    }
}

/// One pyramid level.
#[derive(Debug, Clone, PartialEq)]
pub struct HizLevel {
    extent: Extent2d,
    scale_x: AxisScale,
    scale_y: AxisScale,
    texels: Vec<f32>,
}

impl HizLevel {
    pub fn extent(&self) -> Extent2d {
        self.extent
    }

    /// Row-major texels, row 0 = top.
    pub fn texels(&self) -> &[f32] {
        &self.texels
    }

    pub fn scale(&self) -> (AxisScale, AxisScale) {
        (self.scale_x, self.scale_y)
    }

    /// The texel that level-0 pixel `px` maps to.
    pub fn texel_of_pixel(&self, px: UVec2) -> UVec2 {
        UVec2::new(
            map_axis(px.x, self.scale_x, self.extent.width_px),
            map_axis(px.y, self.scale_y, self.extent.height_px),
        )
    }

    fn at(&self, x: u32, y: u32) -> f32 {
        self.texels[y as usize * self.extent.width_px as usize + x as usize]
    }
}

fn map_axis(px: u32, s: AxisScale, extent: u32) -> u32 {
    // u64 here; the documented bounds keep the GPU's u32 version exact too.
    let t = u64::from(px) * u64::from(s.texels) / u64::from(s.pixels);
    t.min(u64::from(extent - 1)) as u32
}

/// Largest power of two strictly below `n` (1 for n <= 2).
fn pow2_below(n: u32) -> u32 {
    if n <= 2 {
        1
    } else {
        1 << (31 - (n - 1).leading_zeros())
    }
}

/// The extents of every level for a depth buffer of `extent`, as a GPU allocates them.
pub fn level_extents(extent: Extent2d, mode: NpotMode) -> Vec<Extent2d> {
    let mut out = vec![extent];
    let (mut w, mut h) = (extent.width_px, extent.height_px);
    let mut first = true;
    while w > 1 || h > 1 {
        (w, h) = match (mode, first) {
            (NpotMode::PadToPow2, true) => (pow2_below(w), pow2_below(h)),
            _ => ((w / 2).max(1), (h / 2).max(1)),
        };
        first = false;
        out.push(Extent2d::new(w, h));
    }
    out
}

fn axis_scale(mode: NpotMode, level: u32, level0_px: u32, pow2_px: u32) -> AxisScale {
    match (mode, level) {
        (_, 0) => AxisScale {
            texels: 1,
            pixels: 1,
        },
        (NpotMode::PadToPow2, k) => AxisScale {
            texels: pow2_px,
            pixels: level0_px << (k - 1),
        },
        (NpotMode::EdgeAware | NpotMode::NaiveBuggy, k) => AxisScale {
            texels: 1,
            pixels: 1 << k,
        },
    }
}

/// The level k-1 (or level 0) index range that texel `t` of level k reads, per axis.
fn source_range(
    mode: NpotMode,
    level: u32,
    t: u32,
    dst_extent: u32,
    src_extent: u32,
) -> (u32, u32) {
    match (mode, level) {
        (NpotMode::PadToPow2, 1) => {
            // src is level 0 (w), dst is P.
            let (w, p) = (u64::from(src_extent), u64::from(dst_extent));
            let t = u64::from(t);
            let lo = t * w / p;
            let hi = ((t + 1) * w).div_ceil(p) - 1;
            (lo as u32, hi as u32)
        }
        (NpotMode::EdgeAware, _) => {
            let hi = if t == dst_extent - 1 {
                src_extent - 1
            } else {
                2 * t + 1
            };
            (2 * t, hi)
        }
        (NpotMode::PadToPow2 | NpotMode::NaiveBuggy, _) => (2 * t, (2 * t + 1).min(src_extent - 1)),
    }
}

/// Where a probe read: a level and an inclusive texel rect of that level.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct TexelRect {
    pub min_x: u32,
    pub min_y: u32,
    pub max_x: u32,
    pub max_y: u32,
}

impl TexelRect {
    pub fn texel_count(&self) -> u32 {
        (self.max_x - self.min_x + 1) * (self.max_y - self.min_y + 1)
    }
}

/// What the test read and compared, for debugging and for matching a GPU run.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct HizProbe {
    pub level: u32,
    pub texels: TexelRect,
    /// Farthest value of the texels read.
    pub farthest_depth: f32,
    /// The object's nearest depth after [`DepthFormat::toward_near`].
    pub compared_depth: f32,
}

/// Result of the HiZ test.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum HizOutcome {
    /// The object's nearest depth is strictly behind every texel it covers.
    Occluded(HizProbe),
    /// Some covered texel is at or behind the object's nearest depth.
    Visible(HizProbe),
    /// The rect has no pixel on screen. Not this test's business: frustum culling rejects such
    /// objects; a caller that skipped it must draw them. Not culled.
    OffScreen,
    /// The volume touches the near plane, contains the eye, or lies before the near plane:
    /// no rect, not culled (see [`ScreenProjection`]).
    NotProjectable,
}

impl HizOutcome {
    /// Only `Occluded` culls.
    pub fn is_culled(&self) -> bool {
        matches!(self, HizOutcome::Occluded(_))
    }
}

/// A texel where two pyramids differ (see [`HizPyramid::first_mismatch`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TexelMismatch {
    pub texel: UVec2,
    pub expected: f32,
    pub actual: f32,
}

/// A max/min depth pyramid built on the CPU.
#[derive(Debug, Clone, PartialEq)]
pub struct HizPyramid {
    convention: DepthConvention,
    format: DepthFormat,
    mode: NpotMode,
    levels: Vec<HizLevel>,
}

impl HizPyramid {
    /// Builds the pyramid from a row-major depth buffer (row 0 = top). Rejects an extent
    /// outside 1..=[`crate::MAX_EXTENT_PX`], a buffer whose length does not match, non-finite
    /// depths, and (for D16) values that are not `k/65535`.
    pub fn build(
        depth: &[f32],
        extent: Extent2d,
        convention: DepthConvention,
        format: DepthFormat,
        mode: NpotMode,
    ) -> Result<Self, CullError> {
        extent.validate("depth extent")?;
        extent.check_len("depth buffer", depth.len())?;
        let w = extent.width_px;
        // One pass for the common (valid) case; the pixel position is only worked out for the
        // error.
        if let Some(i) = depth.iter().position(|&d| !format.is_representable(d)) {
            let (x_px, y_px, value) = (i as u32 % w, i as u32 / w, depth[i]);
            return Err(if value.is_finite() {
                CullError::NotD16Quantized {
                    what: "depth buffer",
                    x_px,
                    y_px,
                    value,
                }
            } else {
                CullError::NonFiniteDepth {
                    what: "depth buffer",
                    x_px,
                    y_px,
                    value,
                }
            });
        }

        let extents = level_extents(extent, mode);
        let pow2 = extents.get(1).copied().unwrap_or(extent);
        let mut levels: Vec<HizLevel> = Vec::with_capacity(extents.len());
        levels.push(HizLevel {
            extent,
            scale_x: axis_scale(mode, 0, extent.width_px, pow2.width_px),
            scale_y: axis_scale(mode, 0, extent.height_px, pow2.height_px),
            texels: depth.to_vec(),
        });
        for (k, &dst) in extents.iter().enumerate().skip(1) {
            let level = k as u32;
            let src = &levels[k - 1];
            let texels = reduce(src, dst, level, mode, convention);
            levels.push(HizLevel {
                extent: dst,
                scale_x: axis_scale(mode, level, extent.width_px, pow2.width_px),
                scale_y: axis_scale(mode, level, extent.height_px, pow2.height_px),
                texels,
            });
        }
        Ok(HizPyramid {
            convention,
            format,
            mode,
            levels,
        })
    }

    pub fn convention(&self) -> DepthConvention {
        self.convention
    }

    pub fn format(&self) -> DepthFormat {
        self.format
    }

    pub fn mode(&self) -> NpotMode {
        self.mode
    }

    pub fn levels(&self) -> &[HizLevel] {
        &self.levels
    }

    pub fn level_count(&self) -> u32 {
        self.levels.len() as u32
    }

    pub fn level(&self, level: u32) -> Result<&HizLevel, CullError> {
        self.levels
            .get(level as usize)
            .ok_or(CullError::LevelOutOfRange {
                level,
                level_count: self.level_count(),
            })
    }

    /// The level-0 extent.
    pub fn extent(&self) -> Extent2d {
        self.levels[0].extent
    }

    /// The inclusive level-0 pixel rect texel `texel` of `level` was reduced from, by the
    /// mode's build rule (for NaiveBuggy, the rect it *should* cover; its value may miss part
    /// of it). Pure function of the sizes, independent of the stored values.
    pub fn footprint(&self, level: u32, texel: UVec2) -> Result<TexelRect, CullError> {
        let _ = self.level(level)?;
        let x = self.footprint_axis(level, texel.x, |e| e.width_px);
        let y = self.footprint_axis(level, texel.y, |e| e.height_px);
        Ok(TexelRect {
            min_x: x.0,
            min_y: y.0,
            max_x: x.1,
            max_y: y.1,
        })
    }

    fn footprint_axis(&self, level: u32, t: u32, side: impl Fn(&Extent2d) -> u32) -> (u32, u32) {
        // Walk down the chain applying each level's source range; the ranges are contiguous,
        // so the footprint is [lo of the lowest, hi of the highest].
        let (mut lo, mut hi) = (t, t);
        for k in (1..=level).rev() {
            let dst = side(&self.levels[k as usize].extent);
            let src = side(&self.levels[k as usize - 1].extent);
            let mode = if self.mode == NpotMode::NaiveBuggy {
                NpotMode::EdgeAware
            } else {
                self.mode
            };
            lo = source_range(mode, k, lo, dst, src).0;
            hi = source_range(mode, k, hi, dst, src).1;
        }
        (lo, hi)
    }

    /// The HiZ occlusion test of an object covering (at most) the level-0 pixels of `rect`,
    /// whose nearest depth is `nearest_depth`.
    ///
    /// 1. Clamp `rect` to the screen; no pixel left -> `OffScreen`.
    /// 2. Compare depth `c = format.toward_near(convention, nearest_depth)`: for D16 the code on
    ///    the near side, because the attachment holds the object's fragments at a rounded code
    ///    that can be up to one step nearer than the float depth.
    /// 3. Level choice: the smallest level k at which the mapped texel rect
    ///    `[map(min) ..= map(max)]` is at most 2x2 (seed 004: the screen AABB's size picks the
    ///    level; iterating makes it exact for NPOT scales). The top level is 1x1, so one exists.
    /// 4. Read every texel of that rect, take the farthest `f`.
    /// 5. `Occluded` iff `c` is strictly behind `f`; otherwise `Visible`.
    ///
    /// Conservative for EdgeAware and PadToPow2: every pixel of the rect maps to a read texel
    /// whose footprint contains it, so `f` is at least as far as every covered pixel; `c`
    /// strictly behind `f` means behind every pixel, where any fragment fails LESS (or GREATER)
    /// and LESS_OR_EQUAL (GREATER_OR_EQUAL) alike.
    pub fn test_rect(&self, rect: PixelRect, nearest_depth: f32) -> Result<HizOutcome, CullError> {
        rect.validate()?;
        crate::check::finite_f32("hiz test", "nearest_depth", nearest_depth)?;
        let ClampedRect::OnScreen {
            min_x,
            min_y,
            max_x,
            max_y,
        } = rect.clamp_to(self.extent())
        else {
            return Ok(HizOutcome::OffScreen);
        };
        let compared_depth = self.format.toward_near(self.convention, nearest_depth);
        let (min, max) = (UVec2::new(min_x, min_y), UVec2::new(max_x, max_y));
        let (level_index, lvl) = self
            .levels
            .iter()
            .enumerate()
            .find(|(_, l)| {
                let (a, b) = (l.texel_of_pixel(min), l.texel_of_pixel(max));
                b.x - a.x <= 1 && b.y - a.y <= 1
            })
            // The chain ends at 1x1, which always qualifies; fall back to it regardless.
            .unwrap_or((self.levels.len() - 1, &self.levels[self.levels.len() - 1]));
        let (a, b) = (lvl.texel_of_pixel(min), lvl.texel_of_pixel(max));
        let mut farthest = lvl.at(a.x, a.y);
        for y in a.y..=b.y {
            for x in a.x..=b.x {
                farthest = self.convention.farther(farthest, lvl.at(x, y));
            }
        }
        let probe = HizProbe {
            level: level_index as u32,
            texels: TexelRect {
                min_x: a.x,
                min_y: a.y,
                max_x: b.x,
                max_y: b.y,
            },
            farthest_depth: farthest,
            compared_depth,
        };
        Ok(
            if self.convention.is_strictly_behind(compared_depth, farthest) {
                HizOutcome::Occluded(probe)
            } else {
                HizOutcome::Visible(probe)
            },
        )
    }

    /// Projects-then-tests: non-rect projections are `NotProjectable` (kept); a rect is mapped
    /// to level-0 pixels ([`crate::NdcRect::to_pixel_rect`]) and tested.
    pub fn test_projection(&self, projection: &ScreenProjection) -> Result<HizOutcome, CullError> {
        match projection {
            ScreenProjection::Projected(b) => {
                let rect = b.rect_ndc.to_pixel_rect(self.extent())?;
                self.test_rect(rect, b.nearest_depth)
            }
            ScreenProjection::TouchesNearPlane
            | ScreenProjection::CameraInside
            | ScreenProjection::BeforeNearPlane => Ok(HizOutcome::NotProjectable),
        }
    }

    /// Compares a level read back from a GPU with this one. Values compare with `==`, so +0
    /// and -0 match (GLSL `min`/`max` may return either for equal zeros); everything else must
    /// be bit-identical, which for values that are all copies of inputs is the same thing.
    pub fn first_mismatch(
        &self,
        level: u32,
        actual: &[f32],
    ) -> Result<Option<TexelMismatch>, CullError> {
        let l = self.level(level)?;
        l.extent.check_len("gpu hiz level", actual.len())?;
        let w = l.extent.width_px;
        Ok(l.texels
            .iter()
            .zip(actual)
            .enumerate()
            .find_map(|(i, (&e, &a))| {
                (e != a).then_some(TexelMismatch {
                    texel: UVec2::new(i as u32 % w, i as u32 / w),
                    expected: e,
                    actual: a,
                })
            }))
    }
}

fn reduce(
    src: &HizLevel,
    dst: Extent2d,
    level: u32,
    mode: NpotMode,
    convention: DepthConvention,
) -> Vec<f32> {
    // Pick the reduction once so the inner loop is a plain min or max.
    match convention {
        DepthConvention::Standard => reduce_with(src, dst, level, mode, f32::max),
        DepthConvention::Reverse => reduce_with(src, dst, level, mode, f32::min),
    }
}

fn reduce_with(
    src: &HizLevel,
    dst: Extent2d,
    level: u32,
    mode: NpotMode,
    farther: impl Fn(f32, f32) -> f32,
) -> Vec<f32> {
    let (sw, sh) = (src.extent.width_px, src.extent.height_px);
    let (dw, dh) = (dst.width_px, dst.height_px);
    let xs: Vec<(usize, usize)> = (0..dw)
        .map(|t| {
            let (lo, hi) = source_range(mode, level, t, dw, sw);
            (lo as usize, hi as usize)
        })
        .collect();
    let mut out = Vec::with_capacity(dst.buffer_len());
    for ty in 0..dh {
        let (y0, y1) = source_range(mode, level, ty, dh, sh);
        let rows: Vec<&[f32]> = (y0..=y1)
            .map(|y| &src.texels[y as usize * sw as usize..(y as usize + 1) * sw as usize])
            .collect();
        for &(x0, x1) in &xs {
            let mut v = rows[0][x0];
            for row in &rows {
                for &d in &row[x0..=x1] {
                    v = farther(v, d);
                }
            }
            out.push(v);
        }
    }
    out
}

/// The exact answer the HiZ test approximates: occluded iff the compared depth (see
/// [`HizPyramid::test_rect`], step 2) is strictly behind every on-screen pixel of `rect`.
/// `None` when the rect is off-screen. Brute force over level-0 pixels.
pub fn exact_is_occluded(
    depth: &[f32],
    extent: Extent2d,
    convention: DepthConvention,
    format: DepthFormat,
    rect: PixelRect,
    nearest_depth: f32,
) -> Result<Option<bool>, CullError> {
    extent.validate("depth extent")?;
    extent.check_len("depth buffer", depth.len())?;
    rect.validate()?;
    crate::check::finite_f32("exact occlusion", "nearest_depth", nearest_depth)?;
    let ClampedRect::OnScreen {
        min_x,
        min_y,
        max_x,
        max_y,
    } = rect.clamp_to(extent)
    else {
        return Ok(None);
    };
    let c = format.toward_near(convention, nearest_depth);
    let w = extent.width_px as usize;
    for y in min_y..=max_y {
        let row = &depth[y as usize * w..(y as usize + 1) * w];
        if !row[min_x as usize..=max_x as usize]
            .iter()
            .all(|&d| convention.is_strictly_behind(c, d))
        {
            return Ok(Some(false));
        }
    }
    Ok(Some(true))
}

#[cfg(test)]
mod tests {
    use super::*;

    const MODES: [NpotMode; 2] = [NpotMode::EdgeAware, NpotMode::PadToPow2];

    fn extent(w: u32, h: u32) -> Extent2d {
        Extent2d::try_new(w, h).unwrap()
    }

    #[test]
    fn chain_27x13_matches_the_seed() {
        let widths: Vec<u32> = level_extents(extent(27, 13), NpotMode::EdgeAware)
            .iter()
            .map(|e| e.width_px)
            .collect();
        assert_eq!(widths, vec![27, 13, 6, 3, 1]);
        let heights: Vec<u32> = level_extents(extent(27, 13), NpotMode::EdgeAware)
            .iter()
            .map(|e| e.height_px)
            .collect();
        assert_eq!(heights, vec![13, 6, 3, 1, 1]);
        let pad: Vec<(u32, u32)> = level_extents(extent(27, 13), NpotMode::PadToPow2)
            .iter()
            .map(|e| (e.width_px, e.height_px))
            .collect();
        assert_eq!(pad, vec![(27, 13), (16, 8), (8, 4), (4, 2), (2, 1), (1, 1)]);
        assert_eq!(level_extents(extent(1, 1), NpotMode::EdgeAware).len(), 1);
        assert_eq!(
            level_extents(extent(4096, 1), NpotMode::PadToPow2)
                .last()
                .unwrap()
                .width_px,
            1
        );
        assert_eq!(pow2_below(16), 8);
        assert_eq!(pow2_below(17), 16);
        assert_eq!(pow2_below(3), 2);
        assert_eq!(pow2_below(1), 1);
    }

    #[test]
    fn naive_reduction_loses_the_last_column_of_27x13() {
        // Everything near except the last column, which is far (standard: 1.0).
        let e = extent(27, 13);
        let mut depth = vec![0.25f32; e.buffer_len()];
        for y in 0..13 {
            depth[y * 27 + 26] = 1.0;
        }
        let naive = HizPyramid::build(
            &depth,
            e,
            DepthConvention::Standard,
            DepthFormat::D32Float,
            NpotMode::NaiveBuggy,
        )
        .unwrap();
        // Level 1 is 13 wide: texel 12 read columns 24 and 25; column 26 went nowhere.
        assert!(naive.levels()[1].texels().iter().all(|&d| d == 0.25));
        // So an object at depth 0.5 covering column 26 only is wrongly culled: it is visible
        // there (0.5 < 1.0) ...
        let rect = PixelRect::new(20, 0, 26, 12).unwrap();
        assert_eq!(
            exact_is_occluded(
                &depth,
                e,
                DepthConvention::Standard,
                DepthFormat::D32Float,
                rect,
                0.5
            )
            .unwrap(),
            Some(false)
        );
        assert!(
            naive.test_rect(rect, 0.5).unwrap().is_culled(),
            "the naive pyramid must show the bug"
        );
        // ... and both fixes keep it.
        for mode in MODES {
            let p = HizPyramid::build(
                &depth,
                e,
                DepthConvention::Standard,
                DepthFormat::D32Float,
                mode,
            )
            .unwrap();
            assert!(!p.test_rect(rect, 0.5).unwrap().is_culled(), "{mode:?}");
            assert!(
                p.levels().iter().all(|l| l.texels().contains(&1.0)),
                "{mode:?} lost the far column"
            );
        }
    }

    #[test]
    fn footprints_tile_level_zero_and_values_are_their_farthest() {
        for (w, h) in [
            (27u32, 13u32),
            (1, 1),
            (2, 1),
            (3, 3),
            (5, 7),
            (64, 1),
            (17, 33),
        ] {
            let e = extent(w, h);
            let depth: Vec<f32> = (0..e.buffer_len())
                .map(|i| ((i * 7919) % 1000) as f32 / 1000.0)
                .collect();
            for mode in MODES {
                for conv in [DepthConvention::Standard, DepthConvention::Reverse] {
                    let p =
                        HizPyramid::build(&depth, e, conv, DepthFormat::D32Float, mode).unwrap();
                    for (k, l) in p.levels().iter().enumerate() {
                        let k = k as u32;
                        for ty in 0..l.extent().height_px {
                            for tx in 0..l.extent().width_px {
                                let f = p.footprint(k, UVec2::new(tx, ty)).unwrap();
                                let mut far = depth[(f.min_y * w + f.min_x) as usize];
                                for y in f.min_y..=f.max_y {
                                    for x in f.min_x..=f.max_x {
                                        far = conv.farther(far, depth[(y * w + x) as usize]);
                                    }
                                }
                                assert_eq!(
                                    l.at(tx, ty),
                                    far,
                                    "{mode:?} {conv:?} {w}x{h} level {k} texel {tx},{ty}"
                                );
                            }
                        }
                        for py in 0..h {
                            for px in 0..w {
                                let t = l.texel_of_pixel(UVec2::new(px, py));
                                let f = p.footprint(k, t).unwrap();
                                assert!(
                                    f.min_x <= px
                                        && px <= f.max_x
                                        && f.min_y <= py
                                        && py <= f.max_y
                                );
                            }
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn test_reads_at_most_2x2_and_is_conservative_on_a_step() {
        let e = extent(27, 13);
        // Left half near (0.2), right half far (standard 0.9).
        let depth: Vec<f32> = (0..e.buffer_len())
            .map(|i| if i % 27 < 13 { 0.2 } else { 0.9 })
            .collect();
        for mode in MODES {
            let p = HizPyramid::build(
                &depth,
                e,
                DepthConvention::Standard,
                DepthFormat::D32Float,
                mode,
            )
            .unwrap();
            let left = PixelRect::new(0, 2, 5, 10).unwrap();
            match p.test_rect(left, 0.5).unwrap() {
                HizOutcome::Occluded(probe) => assert!(probe.texels.texel_count() <= 4),
                other => panic!("{mode:?}: left half at 0.5 is hidden behind 0.2, got {other:?}"),
            }
            let straddle = PixelRect::new(10, 2, 14, 10).unwrap();
            assert!(!p.test_rect(straddle, 0.5).unwrap().is_culled(), "{mode:?}");
            assert_eq!(
                p.test_rect(PixelRect::new(30, 0, 40, 5).unwrap(), 0.5)
                    .unwrap(),
                HizOutcome::OffScreen
            );
            // Equal depth is not behind.
            assert!(!p.test_rect(left, 0.2).unwrap().is_culled());
        }
    }

    #[test]
    fn d16_compares_the_near_side_code() {
        // Occluder at code 1000; an object whose float depth lies 0.3 codes behind it would be
        // stored at code 1000 too (round to nearest) and pass LESS_OR_EQUAL: it must stay.
        let e = extent(4, 4);
        let occ = dequantize(1000);
        let depth = vec![occ; 16];
        let p = HizPyramid::build(
            &depth,
            e,
            DepthConvention::Standard,
            DepthFormat::D16Unorm,
            NpotMode::EdgeAware,
        )
        .unwrap();
        let rect = PixelRect::new(0, 0, 3, 3).unwrap();
        let slightly_behind = ((1000.3f64) / 65535.0) as f32;
        assert!(!p.test_rect(rect, slightly_behind).unwrap().is_culled());
        let clearly_behind = ((1001.2f64) / 65535.0) as f32;
        assert!(p.test_rect(rect, clearly_behind).unwrap().is_culled());
        // Non-D16 values are rejected.
        assert!(matches!(
            HizPyramid::build(
                &[0.123_456_7; 16],
                e,
                DepthConvention::Standard,
                DepthFormat::D16Unorm,
                NpotMode::EdgeAware
            ),
            Err(CullError::NotD16Quantized { .. })
        ));
    }

    fn dequantize(code: u16) -> f32 {
        crate::depth::dequantize_d16(code)
    }

    #[test]
    fn invalid_inputs_are_typed_errors() {
        let e = extent(3, 2);
        assert!(matches!(
            HizPyramid::build(
                &[0.0; 5],
                e,
                DepthConvention::Reverse,
                DepthFormat::D32Float,
                NpotMode::EdgeAware
            ),
            Err(CullError::BufferSizeMismatch {
                expected_len: 6,
                actual_len: 5,
                ..
            })
        ));
        let mut d = [0.0f32; 6];
        d[4] = f32::NAN;
        assert!(matches!(
            HizPyramid::build(
                &d,
                e,
                DepthConvention::Reverse,
                DepthFormat::D32Float,
                NpotMode::EdgeAware
            ),
            Err(CullError::NonFiniteDepth {
                x_px: 1,
                y_px: 1,
                ..
            })
        ));
        let p = HizPyramid::build(
            &[0.0; 6],
            e,
            DepthConvention::Reverse,
            DepthFormat::D32Float,
            NpotMode::EdgeAware,
        )
        .unwrap();
        assert!(p
            .test_rect(PixelRect::new(0, 0, 1, 1).unwrap(), f32::NAN)
            .is_err());
        assert!(p
            .test_rect(
                PixelRect {
                    min_x: 2,
                    min_y: 0,
                    max_x: 1,
                    max_y: 0
                },
                0.5
            )
            .is_err());
        assert!(matches!(
            p.level(9),
            Err(CullError::LevelOutOfRange {
                level: 9,
                level_count: 2
            })
        ));
        assert!(p.first_mismatch(0, &[0.0; 6]).unwrap().is_none());
        let mut gpu = [0.0f32; 6];
        gpu[5] = 0.5;
        assert_eq!(
            p.first_mismatch(0, &gpu).unwrap().unwrap().texel,
            UVec2::new(2, 1)
        );
    }
}
