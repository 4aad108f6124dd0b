//! Textures: images decoded (PNG, JPEG) into RGBA8 with their sRGB colour, mipmapped on the CPU
//! once at load, ready to upload as they are.
//!
//! Mip levels are box-filtered in linear light (sRGB decoded, averaged, encoded again), alpha
//! averaged as it is: averaging sRGB bytes would darken every minified texture. A level is half
//! its parent, rounded down, at least 1; an odd row or column of the parent is folded into the
//! last texel rather than dropped.

use std::sync::OnceLock;

use serde::Serialize;

/// Index of a [`Texture`] in [`crate::Scene::textures`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
pub struct TextureId(pub u32);

impl TextureId {
    pub fn index(self) -> usize {
        self.0 as usize
    }
}

/// How texture coordinates outside [0, 1] wrap (glTF sampler wrapS / wrapT).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
pub enum Wrap {
    Repeat,
    MirroredRepeat,
    ClampToEdge,
}

/// How a texture is filtered and wrapped (a glTF sampler). glTF leaves filters it does not give
/// to the renderer: trilinear.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
pub struct Sampler {
    pub wrap_u: Wrap,
    pub wrap_v: Wrap,
    pub mag_linear: bool,
    pub min_linear: bool,
    /// Linear between mip levels (else the nearest level).
    pub mip_linear: bool,
}

impl Default for Sampler {
    fn default() -> Self {
        Sampler {
            wrap_u: Wrap::Repeat,
            wrap_v: Wrap::Repeat,
            mag_linear: true,
            min_linear: true,
            mip_linear: true,
        }
    }
}

/// One mip level: its size and where its texels start in [`Texture::pixels`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct MipLevel {
    pub width: u32,
    pub height: u32,
    /// Byte offset of the level's first texel.
    pub offset: usize,
}

impl MipLevel {
    pub fn byte_size(&self) -> usize {
        self.width as usize * self.height as usize * 4
    }
}

/// A decoded RGBA8 texture (colour in sRGB, alpha linear) with its whole mip chain.
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    pub name: String,
    levels: Vec<MipLevel>,
    pixels: Vec<u8>,
    pub sampler: Sampler,
}

/// Why an image could not become a texture.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum TextureError {
    #[error("{width}x{height} with {bytes} bytes of RGBA8 (needs {needed})")]
    Size {
        width: u32,
        height: u32,
        bytes: usize,
        needed: usize,
    },
    #[error("{width}x{height} is over the limit of {max_pixels} pixels")]
    TooLarge {
        width: u64,
        height: u64,
        max_pixels: u64,
    },
    #[error("{0}")]
    Decode(String),
}

impl Texture {
    /// A texture from level 0 in RGBA8 (`width * height * 4` bytes); the mip chain is built here.
    pub fn from_rgba8(
        name: impl Into<String>,
        width: u32,
        height: u32,
        rgba: Vec<u8>,
        sampler: Sampler,
    ) -> Result<Self, TextureError> {
        let needed = width as usize * height as usize * 4;
        if width == 0 || height == 0 || rgba.len() != needed {
            return Err(TextureError::Size {
                width,
                height,
                bytes: rgba.len(),
                needed,
            });
        }
        let mut levels = vec![MipLevel {
            width,
            height,
            offset: 0,
        }];
        let mut pixels = rgba;
        while let Some(&last) = levels.last().filter(|l| l.width > 1 || l.height > 1) {
            let next = MipLevel {
                width: (last.width / 2).max(1),
                height: (last.height / 2).max(1),
                offset: pixels.len(),
            };
            let half = downsample(&pixels[last.offset..], last, next);
            pixels.extend_from_slice(&half);
            levels.push(next);
        }
        Ok(Texture {
            name: name.into(),
            levels,
            pixels,
            sampler,
        })
    }

    pub fn width(&self) -> u32 {
        self.levels[0].width
    }
    pub fn height(&self) -> u32 {
        self.levels[0].height
    }
    /// Level 0 first, down to 1x1.
    pub fn levels(&self) -> &[MipLevel] {
        &self.levels
    }
    /// Every level's texels, level after level (offsets in [`MipLevel::offset`]).
    pub fn pixels(&self) -> &[u8] {
        &self.pixels
    }
    /// The texels of level `i`.
    pub fn level_pixels(&self, i: usize) -> Option<&[u8]> {
        let l = self.levels.get(i)?;
        self.pixels.get(l.offset..l.offset + l.byte_size())
    }
    /// Bytes of every level: what the GPU copy holds.
    pub fn byte_size(&self) -> usize {
        self.pixels.len()
    }

    /// The same image resampled to `width` x `height` (bilinear in linear light from the
    /// smallest level at least that large), with its own mip chain: what a layer of a texture
    /// array of one size holds.
    pub fn resized(&self, width: u32, height: u32) -> Result<Texture, TextureError> {
        if width == self.width() && height == self.height() {
            return Ok(self.clone());
        }
        // The smallest level still covering the target in both axes keeps the filter from
        // skipping texels when minifying by more than 2.
        let src = self
            .levels
            .iter()
            .rev()
            .find(|l| l.width >= width && l.height >= height)
            .copied()
            .unwrap_or(self.levels[0]);
        let texels = &self.pixels[src.offset..src.offset + src.byte_size()];
        let lut = srgb_to_linear_table();
        let at = |x: u32, y: u32, c: usize| -> f32 {
            let v = texels[(y as usize * src.width as usize + x as usize) * 4 + c];
            if c == 3 {
                f32::from(v) / 255.0
            } else {
                lut[v as usize]
            }
        };
        let mut out = Vec::with_capacity(width as usize * height as usize * 4);
        for y in 0..height {
            let fy = ((y as f32 + 0.5) * src.height as f32 / height as f32 - 0.5).max(0.0);
            let y0 = (fy as u32).min(src.height - 1);
            let y1 = (y0 + 1).min(src.height - 1);
            let ty = fy - y0 as f32;
            for x in 0..width {
                let fx = ((x as f32 + 0.5) * src.width as f32 / width as f32 - 0.5).max(0.0);
                let x0 = (fx as u32).min(src.width - 1);
                let x1 = (x0 + 1).min(src.width - 1);
                let tx = fx - x0 as f32;
                for c in 0..4 {
                    let top = at(x0, y0, c) * (1.0 - tx) + at(x1, y0, c) * tx;
                    let bottom = at(x0, y1, c) * (1.0 - tx) + at(x1, y1, c) * tx;
                    out.push(encode(top * (1.0 - ty) + bottom * ty, c));
                }
            }
        }
        Texture::from_rgba8(self.name.clone(), width, height, out, self.sampler)
    }
}

/// sRGB byte -> linear value, the exact transfer function, tabulated once.
fn srgb_to_linear_table() -> &'static [f32; 256] {
    static TABLE: OnceLock<[f32; 256]> = OnceLock::new();
    TABLE.get_or_init(|| {
        let mut t = [0.0f32; 256];
        for (i, v) in t.iter_mut().enumerate() {
            let c = i as f32 / 255.0;
            *v = if c <= 0.04045 {
                c / 12.92
            } else {
                ((c + 0.055) / 1.055).powf(2.4)
            };
        }
        t
    })
}

fn linear_to_srgb(l: f32) -> f32 {
    let l = l.clamp(0.0, 1.0);
    if l <= 0.003_130_8 {
        l * 12.92
    } else {
        1.055 * l.powf(1.0 / 2.4) - 0.055
    }
}

/// Channel `c` (3 = alpha, stored linear) of a linear value as a byte.
fn encode(v: f32, c: usize) -> u8 {
    let s = if c == 3 {
        v.clamp(0.0, 1.0)
    } else {
        linear_to_srgb(v)
    };
    (s * 255.0 + 0.5) as u8
}

/// Level `to` from its parent `from` (texels at the start of `src`): each texel averages the
/// parent texels it covers, 2x2, or 3 wide / tall where the parent's size is odd.
fn downsample(src: &[u8], from: MipLevel, to: MipLevel) -> Vec<u8> {
    let lut = srgb_to_linear_table();
    let span = |i: u32, parent: u32, child: u32| -> (u32, u32) {
        if parent == 1 {
            return (0, 1);
        }
        let first = 2 * i;
        // The last texel of an odd parent folds into the child's last texel.
        let n = if i + 1 == child && parent % 2 == 1 {
            3
        } else {
            2
        };
        (first, n)
    };
    let mut out = Vec::with_capacity(to.byte_size());
    for y in 0..to.height {
        let (y0, ny) = span(y, from.height, to.height);
        for x in 0..to.width {
            let (x0, nx) = span(x, from.width, to.width);
            let mut acc = [0.0f32; 4];
            for sy in y0..y0 + ny {
                for sx in x0..x0 + nx {
                    let t = (sy as usize * from.width as usize + sx as usize) * 4;
                    for (c, a) in acc.iter_mut().enumerate() {
                        let v = src[t + c];
                        *a += if c == 3 {
                            f32::from(v) / 255.0
                        } else {
                            lut[v as usize]
                        };
                    }
                }
            }
            let n = (nx * ny) as f32;
            for (c, a) in acc.iter().enumerate() {
                out.push(encode(a / n, c));
            }
        }
    }
    out
}

/// Which decoder an image needs: from its declared MIME type, else from its first bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImageFormat {
    Png,
    Jpeg,
}

impl ImageFormat {
    /// By signature (glTF allows only PNG and JPEG in core).
    pub fn sniff(bytes: &[u8]) -> Option<Self> {
        if bytes.starts_with(&[0x89, b'P', b'N', b'G', 0x0D, 0x0A, 0x1A, 0x0A]) {
            Some(ImageFormat::Png)
        } else if bytes.starts_with(&[0xFF, 0xD8, 0xFF]) {
            Some(ImageFormat::Jpeg)
        } else {
            None
        }
    }

    pub fn from_mime(mime: &str) -> Option<Self> {
        match mime {
            "image/png" => Some(ImageFormat::Png),
            "image/jpeg" => Some(ImageFormat::Jpeg),
            _ => None,
        }
    }
}

/// Decodes a PNG or JPEG into (width, height, RGBA8). Refuses images over `max_pixels` before
/// decoding them (the size is read from the header).
pub fn decode_image(
    bytes: &[u8],
    format: ImageFormat,
    max_pixels: u64,
) -> Result<(u32, u32, Vec<u8>), TextureError> {
    let check = |width: u64, height: u64| {
        if width == 0 || height == 0 || width.saturating_mul(height) > max_pixels {
            Err(TextureError::TooLarge {
                width,
                height,
                max_pixels,
            })
        } else {
            Ok(())
        }
    };
    match format {
        ImageFormat::Png => decode_png(bytes, &check),
        ImageFormat::Jpeg => decode_jpeg(bytes, &check),
    }
}

type SizeCheck<'a> = &'a dyn Fn(u64, u64) -> Result<(), TextureError>;

fn decode_png(bytes: &[u8], check: SizeCheck<'_>) -> Result<(u32, u32, Vec<u8>), TextureError> {
    let err = |e: png::DecodingError| TextureError::Decode(format!("PNG: {e}"));
    let mut decoder = png::Decoder::new(bytes);
    // Palette to RGB, 16 bits to 8, sub-byte grey to 8 bits.
    decoder.set_transformations(png::Transformations::normalize_to_color8());
    let mut reader = decoder.read_info().map_err(err)?;
    let (width, height) = {
        let info = reader.info();
        (info.width, info.height)
    };
    check(u64::from(width), u64::from(height))?;
    let mut buf = vec![0; reader.output_buffer_size()];
    let frame = reader.next_frame(&mut buf).map_err(err)?;
    let data = buf.get(..frame.buffer_size()).unwrap_or(&buf);
    let texels = width as usize * height as usize;
    let rgba: Vec<u8> = match frame.color_type {
        png::ColorType::Rgba => data.to_vec(),
        png::ColorType::Rgb => data
            .chunks_exact(3)
            .flat_map(|p| [p[0], p[1], p[2], 255])
            .collect(),
        png::ColorType::GrayscaleAlpha => data
            .chunks_exact(2)
            .flat_map(|p| [p[0], p[0], p[0], p[1]])
            .collect(),
        png::ColorType::Grayscale => data.iter().flat_map(|&g| [g, g, g, 255]).collect(),
        png::ColorType::Indexed => {
            return Err(TextureError::Decode("PNG: palette left unexpanded".into()))
        }
    };
    if rgba.len() != texels * 4 {
        return Err(TextureError::Decode(format!(
            "PNG: {} bytes of RGBA for {width}x{height}",
            rgba.len()
        )));
    }
    Ok((width, height, rgba))
}

fn decode_jpeg(bytes: &[u8], check: SizeCheck<'_>) -> Result<(u32, u32, Vec<u8>), TextureError> {
    use zune_jpeg::zune_core::colorspace::ColorSpace;
    use zune_jpeg::zune_core::options::DecoderOptions;
    let err = |e: zune_jpeg::errors::DecodeErrors| TextureError::Decode(format!("JPEG: {e:?}"));
    let options = DecoderOptions::default().jpeg_set_out_colorspace(ColorSpace::RGBA);
    let mut decoder = zune_jpeg::JpegDecoder::new_with_options(bytes, options);
    decoder.decode_headers().map_err(err)?;
    let (width, height) = decoder
        .dimensions()
        .map(|(w, h)| (w as u32, h as u32))
        .ok_or_else(|| TextureError::Decode("JPEG: no frame header".into()))?;
    check(u64::from(width), u64::from(height))?;
    let size = decoder
        .output_buffer_size()
        .ok_or_else(|| TextureError::Decode("JPEG: output size overflows".into()))?;
    let mut rgba = vec![0; size];
    decoder.decode_into(&mut rgba).map_err(err)?;
    if rgba.len() != width as usize * height as usize * 4 {
        return Err(TextureError::Decode(format!(
            "JPEG: {} bytes of RGBA for {width}x{height}",
            rgba.len()
        )));
    }
    Ok((width, height, rgba))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn solid(w: u32, h: u32, texel: [u8; 4]) -> Vec<u8> {
        (0..w * h).flat_map(|_| texel).collect()
    }

    #[test]
    fn mip_chains_end_at_one_texel_and_keep_a_solid_colour() {
        let t = Texture::from_rgba8(
            "t",
            5,
            3,
            solid(5, 3, [200, 10, 90, 128]),
            Sampler::default(),
        )
        .unwrap();
        let sizes: Vec<_> = t.levels().iter().map(|l| (l.width, l.height)).collect();
        assert_eq!(sizes, [(5, 3), (2, 1), (1, 1)]);
        for i in 0..t.levels().len() {
            for p in t.level_pixels(i).unwrap().chunks_exact(4) {
                assert_eq!(p, [200, 10, 90, 128], "level {i}");
            }
        }
        let bytes: usize = t.levels().iter().map(MipLevel::byte_size).sum();
        assert_eq!(t.byte_size(), bytes);
    }

    /// Black and white texels average to linear mid-grey, which is sRGB 188, not 128.
    #[test]
    fn minification_averages_in_linear_light() {
        let rgba = [[0u8, 0, 0, 0], [255, 255, 255, 255]]
            .iter()
            .cycle()
            .take(4)
            .flatten()
            .copied()
            .collect();
        let t = Texture::from_rgba8("checker", 2, 2, rgba, Sampler::default()).unwrap();
        assert_eq!(t.level_pixels(1).unwrap(), [188, 188, 188, 128]);
    }

    /// An odd parent's last column is folded in, not dropped: a 3x1 of (0, 0, 255) gives one
    /// texel of a third of full intensity, not zero.
    #[test]
    fn odd_sizes_fold_their_last_texel_in() {
        let mut rgba = solid(3, 1, [0, 0, 0, 255]);
        rgba[8..12].copy_from_slice(&[255, 255, 255, 255]);
        let t = Texture::from_rgba8("odd", 3, 1, rgba, Sampler::default()).unwrap();
        let third = (linear_to_srgb(1.0 / 3.0) * 255.0 + 0.5) as u8;
        assert_eq!(t.level_pixels(1).unwrap(), [third, third, third, 255]);
    }

    #[test]
    fn wrong_sizes_are_refused() {
        assert!(matches!(
            Texture::from_rgba8("t", 2, 2, vec![0; 15], Sampler::default()),
            Err(TextureError::Size { needed: 16, .. })
        ));
        assert!(Texture::from_rgba8("t", 0, 2, Vec::new(), Sampler::default()).is_err());
    }

    #[test]
    fn resizing_keeps_a_solid_colour_and_builds_its_own_chain() {
        let t = Texture::from_rgba8(
            "t",
            37,
            9,
            solid(37, 9, [30, 160, 250, 77]),
            Sampler::default(),
        )
        .unwrap();
        let r = t.resized(16, 16).unwrap();
        assert_eq!((r.width(), r.height(), r.levels().len()), (16, 16, 5));
        assert!(r
            .level_pixels(0)
            .unwrap()
            .chunks_exact(4)
            .all(|p| p == [30, 160, 250, 77]));
    }

    fn encode_png(w: u32, h: u32, color: png::ColorType, data: &[u8]) -> Vec<u8> {
        let mut out = Vec::new();
        let mut enc = png::Encoder::new(&mut out, w, h);
        enc.set_color(color);
        enc.set_depth(png::BitDepth::Eight);
        let mut writer = enc.write_header().unwrap();
        writer.write_image_data(data).unwrap();
        drop(writer);
        out
    }

    #[test]
    fn pngs_of_every_colour_type_decode_to_rgba() {
        let rgb = encode_png(2, 1, png::ColorType::Rgb, &[1, 2, 3, 4, 5, 6]);
        assert_eq!(ImageFormat::sniff(&rgb), Some(ImageFormat::Png));
        let (w, h, px) = decode_image(&rgb, ImageFormat::Png, 16).unwrap();
        assert_eq!((w, h, px), (2, 1, vec![1, 2, 3, 255, 4, 5, 6, 255]));
        let grey_alpha = encode_png(1, 1, png::ColorType::GrayscaleAlpha, &[9, 77]);
        let (_, _, px) = decode_image(&grey_alpha, ImageFormat::Png, 16).unwrap();
        assert_eq!(px, vec![9, 9, 9, 77]);
    }

    #[test]
    fn images_over_the_pixel_limit_are_refused_before_decoding() {
        let png = encode_png(4, 4, png::ColorType::Rgba, &[0; 64]);
        assert!(matches!(
            decode_image(&png, ImageFormat::Png, 15),
            Err(TextureError::TooLarge {
                width: 4,
                height: 4,
                ..
            })
        ));
        assert!(decode_image(&png[..20], ImageFormat::Png, 1 << 20).is_err());
        assert!(decode_image(b"\xFF\xD8\xFF\xE0 not a jpeg", ImageFormat::Jpeg, 1 << 20).is_err());
    }
}
