//! Golden-image comparison: PNG in, a per-channel tolerance, and a diff image written beside the
//! golden when they differ (red where a channel is off by more than the tolerance).

use std::path::{Path, PathBuf};

use tilegraph_vk::readback::RgbaImage;

pub fn write_png(path: &Path, img: &RgbaImage) -> Result<(), String> {
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    }
    let file = std::fs::File::create(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut enc = png::Encoder::new(std::io::BufWriter::new(file), img.width, img.height);
    enc.set_color(png::ColorType::Rgba);
    enc.set_depth(png::BitDepth::Eight);
    let mut w = enc.write_header().map_err(|e| e.to_string())?;
    w.write_image_data(&img.pixels)
        .map_err(|e| format!("{}: {e}", path.display()))?;
    // The end chunk and the buffered bytes go out here: an error must not be lost in Drop.
    w.finish().map_err(|e| format!("{}: {e}", path.display()))
}

pub fn read_png(path: &Path) -> Result<RgbaImage, String> {
    let file = std::fs::File::open(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let decoder = png::Decoder::new(std::io::BufReader::new(file));
    let mut reader = decoder
        .read_info()
        .map_err(|e| format!("{}: {e}", path.display()))?;
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader
        .next_frame(&mut buf)
        .map_err(|e| format!("{}: {e}", path.display()))?;
    if info.color_type != png::ColorType::Rgba || info.bit_depth != png::BitDepth::Eight {
        return Err(format!("{}: expected 8-bit RGBA", path.display()));
    }
    buf.truncate(info.buffer_size());
    Ok(RgbaImage {
        width: info.width,
        height: info.height,
        pixels: buf,
    })
}

/// Where the diff image of `golden` goes.
pub fn diff_path(golden: &Path) -> PathBuf {
    golden.with_extension("diff.png")
}

/// Compares `img` with the golden PNG; on failure writes the diff image and says how many
/// pixels differ by more than `tolerance` in some channel.
pub fn compare(golden: &Path, img: &RgbaImage, tolerance: u8) -> Result<(), String> {
    let want = read_png(golden)?;
    if (want.width, want.height) != (img.width, img.height) {
        return Err(format!(
            "size {}x{} != golden {}x{}",
            img.width, img.height, want.width, want.height
        ));
    }
    let mut diff = img.clone();
    let mut bad = 0usize;
    let mut worst = 0u8;
    for (d, (a, b)) in diff
        .pixels
        .chunks_exact_mut(4)
        .zip(img.pixels.chunks_exact(4).zip(want.pixels.chunks_exact(4)))
    {
        let m = (0..4).map(|c| a[c].abs_diff(b[c])).max().unwrap_or(0);
        worst = worst.max(m);
        if m > tolerance {
            bad += 1;
            d.copy_from_slice(&[255, 0, 0, 255]);
        } else {
            d.copy_from_slice(&[a[0] / 3, a[1] / 3, a[2] / 3, 255]);
        }
    }
    if bad == 0 {
        return Ok(());
    }
    let dp = diff_path(golden);
    write_png(&dp, &diff)?;
    Err(format!(
        "{bad} pixels differ by more than {tolerance} (worst {worst}); diff image: {}",
        dp.display()
    ))
}
