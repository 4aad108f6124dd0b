//! The images of a check compared: how far the technique's is from the reference (exact
//! techniques: not at all; levels of detail: the image error they trade for triangles), and
//! the diff image of a failed frame.

use serde::Serialize;
use tilegraph_scene::{DepthConvention, FrameMatrices};

use tilegraph_vk::readback::RgbaImage;

use super::stray::OracleFrame;

/// How far a frame's image lies from the reference's, over the RGB channels (0-255).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct ImageError {
    /// The largest difference of one channel of one pixel.
    pub max_channel_diff: u8,
    /// Mean squared difference per channel.
    pub mse: f64,
    /// Peak signal-to-noise ratio, 10 log10(255^2 / mse) dB; `None` where the images are equal.
    pub psnr_db: Option<f64>,
    /// Where both frames' depth was kept (every `cull-check` frame): the largest difference of the
    /// distance along the view axis at a pixel both cover, relative to the reference's (a
    /// pixel one covers and the other does not shows in the colours).
    pub max_depth_rel_diff: Option<f64>,
}

impl ImageError {
    /// `got` against `want` (same size).
    pub fn between(got: &RgbaImage, want: &RgbaImage) -> Self {
        let mut max = 0u8;
        let mut sum = 0u64;
        let mut samples = 0u64;
        for (a, b) in got.pixels.chunks_exact(4).zip(want.pixels.chunks_exact(4)) {
            for c in 0..3 {
                let d = a[c].abs_diff(b[c]);
                max = max.max(d);
                sum += u64::from(d) * u64::from(d);
                samples += 1;
            }
        }
        let mse = if samples == 0 {
            0.0
        } else {
            sum as f64 / samples as f64
        };
        ImageError {
            max_channel_diff: max,
            mse,
            psnr_db: psnr(mse),
            max_depth_rel_diff: None,
        }
    }

    /// With the depth of both frames (values in [0, 1] a pixel) and the frame's matrices.
    pub fn with_depth(self, got: &[f32], want: &[f32], m: &FrameMatrices) -> Self {
        ImageError {
            max_depth_rel_diff: Some(depth_difference(got, want, m)),
            ..self
        }
    }

    /// Frames of one size together: their mean squared error, the largest difference.
    pub fn over<'a>(frames: impl Iterator<Item = &'a ImageError>) -> Self {
        let (mut n, mut sum, mut max) = (0usize, 0.0, 0u8);
        let mut depth: Option<f64> = None;
        for f in frames {
            n += 1;
            sum += f.mse;
            max = max.max(f.max_channel_diff);
            if let Some(d) = f.max_depth_rel_diff {
                depth = Some(depth.map_or(d, |m| m.max(d)));
            }
        }
        let mse = if n == 0 { 0.0 } else { sum / n as f64 };
        ImageError {
            max_channel_diff: max,
            mse,
            psnr_db: psnr(mse),
            max_depth_rel_diff: depth,
        }
    }
}

/// The largest relative difference of view-axis distance between two depth images at the
/// pixels both cover (the clear value, the far plane, marks a pixel neither drew).
fn depth_difference(got: &[f32], want: &[f32], m: &FrameMatrices) -> f64 {
    let background = match m.depth {
        DepthConvention::Reverse => 0.0,
        DepthConvention::Standard => 1.0,
    };
    let inverse = m.projection.inverse();
    let distance = |d: f32| {
        let p = inverse * glam::Vec4::new(0.0, 0.0, d, 1.0);
        f64::from((p.z / p.w).abs())
    };
    got.iter()
        .zip(want)
        .filter(|(&a, &b)| a != background && b != background && a != b)
        .map(|(&a, &b)| {
            let (da, db) = (distance(a), distance(b));
            if db > 0.0 && da.is_finite() && db.is_finite() {
                (da - db).abs() / db
            } else {
                0.0
            }
        })
        .fold(0.0, f64::max)
}

fn psnr(mse: f64) -> Option<f64> {
    (mse > 0.0).then(|| 10.0 * (255.0 * 255.0 / mse).log10())
}

/// The pixels where a technique's image differs from the reference's, and of them those
/// whose owner (`ids`, the oracle's) the technique drew, and those where both depths are the
/// same bit for bit, and those whose owner in the oracle is stray (`FrameCheck`'s
/// `image_diff_pixels*`).
#[derive(Debug, Default, Clone, Copy)]
pub(super) struct PixelDiff {
    pub pixels: usize,
    pub owner_drawn: usize,
    pub depth_tie: usize,
    pub stray: usize,
    /// Neither a tie nor stray.
    pub unexplained: usize,
}

impl PixelDiff {
    pub fn between(
        got: &RgbaImage,
        want: &RgbaImage,
        ids: &[u32],
        drawn: &[bool],
        depths: Option<&(Vec<f32>, Vec<f32>)>,
        stray: Option<&OracleFrame<'_>>,
    ) -> Self {
        let mut diff = PixelDiff::default();
        let pairs = got.pixels.chunks_exact(4).zip(want.pixels.chunks_exact(4));
        for (p, _) in pairs.enumerate().filter(|(_, (a, b))| a != b) {
            diff.pixels += 1;
            let owner = ids.get(p).copied().unwrap_or(u32::MAX) as usize;
            diff.owner_drawn += usize::from(drawn.get(owner).copied().unwrap_or(false));
            let tie = depths.is_some_and(|(a, b)| {
                matches!((a.get(p), b.get(p)), (Some(x), Some(y)) if x.to_bits() == y.to_bits())
            });
            diff.depth_tie += usize::from(tie);
            let pair = depths.and_then(|(a, b)| Some((*a.get(p)?, *b.get(p)?)));
            let explained = stray
                .zip(pair)
                .is_some_and(|(s, d)| s.explains_difference(p, d, drawn));
            diff.stray += usize::from(explained);
            diff.unexplained += usize::from(!tie && !explained);
        }
        diff
    }
}

/// The diff image of a failed frame: the reference in dim grey, differing pixels red, pixels
/// owned (in the oracle) by a visible instance the technique did not draw magenta.
pub(super) fn diff_image(
    got: &RgbaImage,
    want: &RgbaImage,
    ids: &[u32],
    visible: &[bool],
    drawn: &[bool],
) -> RgbaImage {
    let mut pixels = Vec::with_capacity(want.pixels.len());
    for (p, (a, b)) in got
        .pixels
        .chunks_exact(4)
        .zip(want.pixels.chunks_exact(4))
        .enumerate()
    {
        let owner = ids.get(p).map(|&id| id as usize);
        let culled = owner.is_some_and(|o| {
            visible.get(o).copied().unwrap_or(false) && !drawn.get(o).copied().unwrap_or(true)
        });
        let rgba = if culled {
            [255, 0, 255, 255]
        } else if a != b {
            [255, 0, 0, 255]
        } else {
            let grey = ((u32::from(b[0]) + u32::from(b[1]) + u32::from(b[2])) / 6) as u8;
            [grey, grey, grey, 255]
        };
        pixels.extend_from_slice(&rgba);
    }
    RgbaImage {
        width: want.width,
        height: want.height,
        pixels,
    }
}

/// The sum of per-frame counts, `None` when a frame has none.
pub(super) fn summed(counts: impl Iterator<Item = Option<u32>>) -> Option<u64> {
    counts.map(|c| c.map(u64::from)).sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use tilegraph_scene::Projection;

    #[test]
    fn depth_difference_is_relative_view_distance_where_both_drew() {
        for depth in [DepthConvention::Reverse, DepthConvention::Standard] {
            let projection = Projection::Perspective {
                fov_y_rad: 1.0,
                near: 0.1,
                far: Some(100.0),
                depth,
            }
            .matrix(1.0);
            let m = FrameMatrices {
                eye: glam::DVec3::ZERO,
                view: glam::Mat4::IDENTITY,
                projection,
                view_projection: projection,
                depth,
            };
            // The stored depth of a point `z` in front of the eye.
            let at = |z: f32| {
                let c = projection * glam::Vec4::new(0.0, 0.0, -z, 1.0);
                c.z / c.w
            };
            let background = match depth {
                DepthConvention::Reverse => 0.0,
                DepthConvention::Standard => 1.0,
            };
            // 10 against 10.5: 5 %; a pixel only one drew does not count; equal pixels none.
            let got = [at(10.5), at(3.0), background, at(7.0)];
            let want = [at(10.0), background, at(2.0), at(7.0)];
            let d = depth_difference(&got, &want, &m);
            assert!((d - 0.05).abs() < 1e-3, "{depth:?}: {d}");
            assert_eq!(depth_difference(&want, &want, &m), 0.0);
        }
        // Over frames: the largest.
        let frames = [
            ImageError {
                max_depth_rel_diff: Some(0.01),
                ..ImageError::default()
            },
            ImageError {
                max_depth_rel_diff: Some(0.03),
                ..ImageError::default()
            },
        ];
        assert_eq!(
            ImageError::over(frames.iter()).max_depth_rel_diff,
            Some(0.03)
        );
        assert_eq!(
            ImageError::over([ImageError::default()].iter()).max_depth_rel_diff,
            None
        );
    }
}
