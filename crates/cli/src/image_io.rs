//! PNG output.

use std::path::Path;

use tilegraph_vk::readback::RgbaImage;

use crate::CliError;

/// `path` must name a PNG (`.png`): the bytes written are PNG, whatever the name says.
pub fn check_png_path(path: &Path) -> Result<(), CliError> {
    let png = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("png"));
    if png {
        Ok(())
    } else {
        Err(CliError::Usage(format!(
            "--out {}: tilegraph writes PNG images; name the file .png",
            path.display()
        )))
    }
}

pub fn write_png(path: &Path, img: &RgbaImage) -> Result<(), CliError> {
    let err = |reason: String| CliError::Write {
        path: path.to_path_buf(),
        reason,
    };
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| err(e.to_string()))?;
    }
    let file = std::fs::File::create(path).map_err(|e| err(e.to_string()))?;
    let mut enc = png::Encoder::new(std::io::BufWriter::new(file), img.width, img.height);
    enc.set_color(png::ColorType::Rgba);
    enc.set_depth(png::BitDepth::Eight);
    let mut writer = enc.write_header().map_err(|e| err(e.to_string()))?;
    writer
        .write_image_data(&img.pixels)
        .map_err(|e| err(e.to_string()))?;
    writer.finish().map_err(|e| err(e.to_string()))
}

/// Reads an 8-bit RGBA PNG (a golden image).
pub fn read_png(path: &Path) -> Result<RgbaImage, CliError> {
    let bad = |reason: String| CliError::Usage(format!("{}: {reason}", path.display()));
    let file = std::fs::File::open(path).map_err(|e| bad(e.to_string()))?;
    let mut reader = png::Decoder::new(std::io::BufReader::new(file))
        .read_info()
        .map_err(|e| bad(e.to_string()))?;
    let mut pixels = vec![0; reader.output_buffer_size()];
    let info = reader
        .next_frame(&mut pixels)
        .map_err(|e| bad(e.to_string()))?;
    if info.color_type != png::ColorType::Rgba || info.bit_depth != png::BitDepth::Eight {
        return Err(bad(format!(
            "{:?} {:?}, not 8-bit RGBA",
            info.color_type, info.bit_depth
        )));
    }
    pixels.truncate(info.buffer_size());
    Ok(RgbaImage {
        width: info.width,
        height: info.height,
        pixels,
    })
}
