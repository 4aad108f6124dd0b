//! Base-colour textures: the textures, images and samplers that a material's
//! `pbrMetallicRoughness.baseColorTexture` reaches, decoded (PNG, JPEG) and mipmapped. Nothing
//! else in those collections is read: a broken normal map or an unused image does not fail a
//! load that never samples it.

use std::collections::HashMap;

use gltf::json;
use gltf::json::validation::Checked;
use serde_json::Value;

use super::data::{decode_data_uri_of, has_scheme, relative_path, Reader, View};
use super::doc::{element, Doc};
use super::{Ctx, Limits, ResourceResolver};
use crate::error::SceneError;
use crate::scene::SceneBuilder;
use crate::texture::{decode_image, ImageFormat, Sampler, Texture, TextureId, Wrap};

/// What the material loop needs: where to find image bytes and where to put textures.
pub(super) struct Images<'a, 'd> {
    pub doc: &'d Doc,
    pub views: &'d [View],
    pub reader: &'d Reader<'d, 'a>,
    pub resolver: &'d dyn ResourceResolver,
    pub limits: &'d Limits,
    pub ctx: &'d Ctx,
    /// (image, sampler) -> texture already made.
    made: HashMap<(usize, Option<usize>), TextureId>,
    /// Pixels decoded so far (`Limits::max_texture_pixels_total`).
    pixels: u64,
}

impl<'a, 'd> Images<'a, 'd> {
    pub fn new(
        doc: &'d Doc,
        views: &'d [View],
        reader: &'d Reader<'d, 'a>,
        resolver: &'d dyn ResourceResolver,
        limits: &'d Limits,
        ctx: &'d Ctx,
    ) -> Self {
        Images {
            doc,
            views,
            reader,
            resolver,
            limits,
            ctx,
            made: HashMap::new(),
            pixels: 0,
        }
    }

    /// The texture of material `m`'s base colour (`info`, at `pointer`), decoded once per
    /// (image, sampler). `None` (with a warning) for a texture whose image is only in an
    /// extension this loader does not decode (KTX2/Basis, WebP, AVIF).
    pub fn base_color(
        &mut self,
        info: &json::texture::Info,
        pointer: &str,
        builder: &mut SceneBuilder,
    ) -> Result<Option<TextureId>, SceneError> {
        let ctx = self.ctx;
        let t = info.index.value();
        let tp = format!("/textures/{t}");
        let raw = self.doc.textures.get(t).ok_or_else(|| {
            ctx.unresolved(
                format!("{pointer}/index"),
                "/textures",
                t,
                self.doc.textures.len(),
            )
        })?;
        if raw.get("source").is_none() {
            log::warn!(
                "{}: {tp}: no `source` image (only an extension's, not decoded here): \
                 drawn untextured",
                ctx.file
            );
            return Ok(None);
        }
        let texture: json::Texture = element(raw, &tp, ctx)?;
        let image = texture.source.value();
        let sampler = texture.sampler.map(|s| s.value());
        if let Some(&id) = self.made.get(&(image, sampler)) {
            return Ok(Some(id));
        }
        let sampler_desc = match sampler {
            None => Sampler::default(),
            Some(s) => self.sampler(s, &format!("{tp}/sampler"))?,
        };
        let ip = format!("/images/{image}");
        let raw = self.doc.images.get(image).ok_or_else(|| {
            ctx.unresolved(
                format!("{tp}/source"),
                "/images",
                image,
                self.doc.images.len(),
            )
        })?;
        let img: json::Image = element(raw, &ip, ctx)?;
        let (bytes, declared) = self.image_bytes(&img, &ip)?;
        let format = match declared {
            Some(f) => f,
            None => ImageFormat::sniff(&bytes).ok_or_else(|| {
                ctx.image(ip.clone(), "neither PNG nor JPEG (no mimeType)".into())
            })?,
        };
        // Within the limit per image and what is left of the one over all of them.
        let left = (self.limits.max_texture_pixels_total as u64).saturating_sub(self.pixels);
        let max_pixels = (self.limits.max_texture_pixels as u64).min(left);
        let (w, h, rgba) = decode_image(&bytes, format, max_pixels).map_err(|e| {
            let total = match left < self.limits.max_texture_pixels as u64 {
                true => format!(
                    " ({} pixels of textures decoded before it, of {} in all)",
                    self.pixels, self.limits.max_texture_pixels_total
                ),
                false => String::new(),
            };
            ctx.image(ip.clone(), format!("{e}{total}"))
        })?;
        self.pixels += u64::from(w) * u64::from(h);
        let name = img
            .name
            .clone()
            .or(texture.name.clone())
            .unwrap_or_else(|| ip.clone());
        let tex = Texture::from_rgba8(name, w, h, rgba, sampler_desc)
            .map_err(|e| ctx.image(ip.clone(), e.to_string()))?;
        let id = builder.add_texture(tex);
        self.made.insert((image, sampler), id);
        Ok(Some(id))
    }

    /// The image's encoded bytes, and the format its mimeType declares.
    fn image_bytes(
        &self,
        img: &json::Image,
        ip: &str,
    ) -> Result<(Vec<u8>, Option<ImageFormat>), SceneError> {
        let ctx = self.ctx;
        let declared = match &img.mime_type {
            None => None,
            Some(m) => Some(ImageFormat::from_mime(&m.0).ok_or_else(|| {
                ctx.image(
                    format!("{ip}/mimeType"),
                    format!("`{}`: only image/png and image/jpeg are decoded", m.0),
                )
            })?),
        };
        match (&img.uri, img.buffer_view) {
            (Some(uri), None) if uri.starts_with("data:") => {
                let bytes = decode_data_uri_of(uri, &["image/png", "image/jpeg"])
                    .map_err(|r| ctx.image(format!("{ip}/uri"), r))?;
                Ok((bytes, declared))
            }
            (Some(uri), None) => {
                if has_scheme(uri).map_err(|r| ctx.image(format!("{ip}/uri"), r))? {
                    return Err(ctx.image(
                        format!("{ip}/uri"),
                        format!("non-relative URI `{uri}` is not fetched by this loader"),
                    ));
                }
                let path = relative_path(uri).map_err(|r| ctx.image(format!("{ip}/uri"), r))?;
                let bytes = self.resolver.read(&path).map_err(|e| {
                    ctx.image(format!("{ip}/uri"), format!("cannot read `{path}`: {e}"))
                })?;
                Ok((bytes.into_owned(), declared))
            }
            (None, Some(v)) => {
                let v = v.value();
                let view = self.views.get(v).ok_or_else(|| {
                    ctx.unresolved(
                        format!("{ip}/bufferView"),
                        "/bufferViews",
                        v,
                        self.views.len(),
                    )
                })?;
                if declared.is_none() {
                    return Err(
                        ctx.invalid(format!("{ip}/mimeType"), "required with bufferView".into())
                    );
                }
                let data = self.reader.bytes(view.buffer, ip)?;
                // The view was checked against its buffer.
                let bytes = data
                    .get(view.offset..view.offset + view.length)
                    .ok_or_else(|| {
                        ctx.out_of_bounds(format!("{ip}/bufferView"), "past its buffer".into())
                    })?;
                Ok((bytes.to_vec(), declared))
            }
            _ => Err(ctx.invalid(
                ip.to_string(),
                "exactly one of uri and bufferView must be given".into(),
            )),
        }
    }

    fn sampler(&self, s: usize, user: &str) -> Result<Sampler, SceneError> {
        let ctx = self.ctx;
        let sp = format!("/samplers/{s}");
        let raw: &Value = self.doc.samplers.get(s).ok_or_else(|| {
            ctx.unresolved(user.to_string(), "/samplers", s, self.doc.samplers.len())
        })?;
        let js: json::texture::Sampler = element(raw, &sp, ctx)?;
        let wrap = |w: Checked<json::texture::WrappingMode>, field: &str| match w {
            Checked::Valid(json::texture::WrappingMode::Repeat) => Ok(Wrap::Repeat),
            Checked::Valid(json::texture::WrappingMode::MirroredRepeat) => Ok(Wrap::MirroredRepeat),
            Checked::Valid(json::texture::WrappingMode::ClampToEdge) => Ok(Wrap::ClampToEdge),
            Checked::Invalid => {
                Err(ctx.invalid(format!("{sp}/{field}"), "unknown wrap mode".into()))
            }
        };
        use json::texture::{MagFilter, MinFilter};
        let mag_linear = !matches!(js.mag_filter, Some(Checked::Valid(MagFilter::Nearest)));
        let (min_linear, mip_linear) = match js.min_filter {
            Some(Checked::Valid(MinFilter::Nearest | MinFilter::NearestMipmapNearest)) => {
                (false, false)
            }
            Some(Checked::Valid(MinFilter::NearestMipmapLinear)) => (false, true),
            Some(Checked::Valid(MinFilter::LinearMipmapNearest)) => (true, false),
            _ => (true, true),
        };
        Ok(Sampler {
            wrap_u: wrap(js.wrap_s, "wrapS")?,
            wrap_v: wrap(js.wrap_t, "wrapT")?,
            mag_linear,
            min_linear,
            mip_linear,
        })
    }
}
