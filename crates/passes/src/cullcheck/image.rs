//! The images of a check compared: how far the technique's is from the reference (exact
//! techniques: not at all; levels of detail: the image error they trade for triangles), and
//! the diff image of a failed frame.

use serde::Serialize;

use tilegraph_vk::readback::RgbaImage;

/// How far a frame's image lies from the reference's, over the RGB channels (0-255).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct ImageError {
    /// The largest difference of one channel of one pixel.
    pub max_channel_diff: u8,
    /// Mean squared difference per channel.
    pub mse: f64,
    /// Peak signal-to-noise ratio, 10 log10(255^2 / mse) dB; `None` where the images are equal.
    pub psnr_db: Option<f64>,
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
        }
    }

    /// Frames of one size together: their mean squared error, the largest difference.
    pub fn over<'a>(frames: impl Iterator<Item = &'a ImageError>) -> Self {
        let (mut n, mut sum, mut max) = (0usize, 0.0, 0u8);
        for f in frames {
            n += 1;
            sum += f.mse;
            max = max.max(f.max_channel_diff);
        }
        let mse = if n == 0 { 0.0 } else { sum / n as f64 };
        ImageError {
            max_channel_diff: max,
            mse,
            psnr_db: psnr(mse),
        }
    }
}

fn psnr(mse: f64) -> Option<f64> {
    (mse > 0.0).then(|| 10.0 * (255.0 * 255.0 / mse).log10())
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
