//! Buffers, buffer views and accessors: resolving bytes, checking every range before it is
//! read, and converting accessor elements to f32 / u32.

use std::borrow::Cow;

use base64::Engine as _;
use gltf::json;
use gltf::json::accessor::{ComponentType, Type};
use gltf::json::validation::Checked;

use super::doc::Doc;
use super::{Ctx, ResourceResolver};
use crate::error::SceneError;

/// A buffer's bytes, or why there are none. Missing bytes are an error only when read: a
/// placeholder buffer (no URI, not the GLB one) or a remote URI is fine if nothing uses it.
pub(crate) enum BufferData<'a> {
    Bytes(Cow<'a, [u8]>),
    Unavailable(String),
}

/// `true` for a URI with a scheme (`http:`, `file:`), which this loader does not fetch.
pub(super) fn has_scheme(uri: &str) -> Result<bool, String> {
    let Some(colon) = uri.find(':') else {
        return Ok(false);
    };
    // A colon after the first '/', '?' or '#' belongs to a relative path, not a scheme.
    if uri[..colon].contains(['/', '?', '#']) {
        return Ok(false);
    }
    let scheme = &uri[..colon];
    let valid = scheme.starts_with(|c: char| c.is_ascii_alphabetic())
        && scheme
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '+' | '-' | '.'));
    if valid {
        Ok(true)
    } else {
        Err(format!("invalid URI `{uri}`: malformed scheme before ':'"))
    }
}

fn percent_decode(s: &str) -> Result<String, String> {
    String::from_utf8(percent_decode_bytes(s)?)
        .map_err(|_| format!("`{s}` does not decode to UTF-8"))
}

fn percent_decode_bytes(s: &str) -> Result<Vec<u8>, String> {
    let bytes = s.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = bytes
                .get(i + 1..i + 3)
                .and_then(|h| std::str::from_utf8(h).ok())
                .and_then(|h| u8::from_str_radix(h, 16).ok())
                .ok_or_else(|| format!("invalid percent-encoding in `{s}`"))?;
            out.push(hex);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    Ok(out)
}

/// A relative URI reference, percent-decoded, that stays in the glTF's directory tree: no
/// absolute path, no `..` (a file must not make the loader read /dev/zero or ~/.ssh).
pub(super) fn relative_path(uri: &str) -> Result<String, String> {
    let path = percent_decode(uri)?;
    let escapes = path.starts_with(['/', '\\'])
        || std::path::Path::new(&path).is_absolute()
        || path.split(['/', '\\']).any(|part| part == "..");
    if escapes {
        return Err(format!(
            "`{path}` is not a relative path inside the file's directory"
        ));
    }
    Ok(path)
}

/// Decodes a buffer's `data:[<media type>][;base64],<data>`.
pub(super) fn decode_data_uri(uri: &str) -> Result<Vec<u8>, String> {
    decode_data_uri_of(
        uri,
        &["application/octet-stream", "application/gltf-buffer"],
    )
}

/// Decodes `data:[<media type>][;base64],<data>` whose media type is one of `media_types`.
pub(super) fn decode_data_uri_of(uri: &str, media_types: &[&str]) -> Result<Vec<u8>, String> {
    let rest = &uri["data:".len()..];
    let Some((header, payload)) = rest.split_once(',') else {
        return Err("data URI without ','".into());
    };
    let (media, base64) = match header.strip_suffix(";base64") {
        Some(m) => (m, true),
        None => (header, false),
    };
    if media.contains(';') && !media.contains('=') {
        return Err(format!("invalid data URI parameters `{header}`"));
    }
    // Parameters such as `;charset=...` do not change the bytes.
    let media = media.split(';').next().unwrap_or_default();
    // Media types compare case-insensitively (RFC 2045); glTF allows these two for buffers.
    let media = media.to_ascii_lowercase();
    if !media_types.contains(&media.as_str()) {
        return Err(format!(
            "data URI media type `{media}` must be {}",
            media_types.join(" or ")
        ));
    }
    if base64 {
        base64::engine::general_purpose::STANDARD
            .decode(payload)
            .map_err(|e| format!("invalid base64 in data URI: {e}"))
    } else {
        // Plain data URIs carry percent-encoded bytes (RFC 2397).
        percent_decode_bytes(payload)
    }
}

pub(crate) fn resolve_buffers<'a>(
    doc: &Doc,
    glb_bin: Option<&'a [u8]>,
    is_glb: bool,
    resolver: &'a dyn ResourceResolver,
    ctx: &Ctx,
) -> Result<Vec<BufferData<'a>>, SceneError> {
    let mut out = Vec::with_capacity(doc.buffers.len());
    for (i, buffer) in doc.buffers.iter().enumerate() {
        let pointer = format!("/buffers/{i}");
        let declared = buffer.byte_length.0;
        if declared == 0 {
            return Err(ctx.invalid(format!("{pointer}/byteLength"), "must be at least 1".into()));
        }
        let bytes: Cow<'a, [u8]> = match &buffer.uri {
            Some(uri) if uri.starts_with("data:") => Cow::Owned(
                decode_data_uri(uri)
                    .map_err(|reason| ctx.buffer(format!("{pointer}/uri"), reason))?,
            ),
            Some(uri) => {
                if has_scheme(uri).map_err(|r| ctx.buffer(format!("{pointer}/uri"), r))? {
                    log::warn!("{}: {pointer}: remote URI `{uri}` not fetched", ctx.file);
                    out.push(BufferData::Unavailable(format!(
                        "non-relative URI `{uri}` is not fetched by this loader"
                    )));
                    continue;
                }
                let path =
                    relative_path(uri).map_err(|r| ctx.buffer(format!("{pointer}/uri"), r))?;
                resolver.read_prefix(&path, declared).map_err(|e| {
                    ctx.buffer(
                        format!("{pointer}/uri"),
                        format!("cannot read `{path}`: {e}"),
                    )
                })?
            }
            None if i == 0 && is_glb => match glb_bin {
                Some(bin) => Cow::Borrowed(bin),
                None => {
                    return Err(ctx.buffer(
                        pointer,
                        "refers to the GLB BIN chunk, but the file has none".into(),
                    ))
                }
            },
            None => {
                out.push(BufferData::Unavailable(
                    "no URI and not the GLB BIN buffer (a placeholder)".into(),
                ));
                continue;
            }
        };
        let Ok(declared) = usize::try_from(declared) else {
            return Err(ctx.invalid(format!("{pointer}/byteLength"), "too large".into()));
        };
        if bytes.len() < declared {
            return Err(ctx.buffer(
                pointer,
                format!(
                    "has {} bytes, fewer than its byteLength {declared}",
                    bytes.len()
                ),
            ));
        }
        // Longer is allowed (GLB padding); keep exactly the declared bytes.
        let bytes = match bytes {
            Cow::Borrowed(b) => Cow::Borrowed(&b[..declared]),
            Cow::Owned(mut v) => {
                v.truncate(declared);
                Cow::Owned(v)
            }
        };
        out.push(BufferData::Bytes(bytes));
    }
    Ok(out)
}

pub(crate) fn component_size(c: ComponentType) -> usize {
    match c {
        ComponentType::I8 | ComponentType::U8 => 1,
        ComponentType::I16 | ComponentType::U16 => 2,
        ComponentType::U32 | ComponentType::F32 => 4,
    }
}

pub(crate) fn component_count(t: Type) -> usize {
    match t {
        Type::Scalar => 1,
        Type::Vec2 => 2,
        Type::Vec3 => 3,
        Type::Vec4 | Type::Mat2 => 4,
        Type::Mat3 => 9,
        Type::Mat4 => 16,
    }
}

/// Element size in bytes, with the column padding glTF requires for small matrices.
fn element_size(c: ComponentType, t: Type) -> usize {
    let s = component_size(c);
    match (t, s) {
        (Type::Mat2, 1) => 8,
        (Type::Mat3, 1) => 12,
        (Type::Mat3, 2) => 24,
        _ => s * component_count(t),
    }
}

/// A checked accessor: every range below fits its buffer view and buffer.
#[derive(Clone, Debug)]
pub(crate) struct Accessor {
    pub component: ComponentType,
    pub ty: Type,
    pub normalized: bool,
    pub count: usize,
    /// `(buffer, byte offset in the buffer, stride)`; `None`: all zeros (no bufferView).
    pub source: Option<(usize, usize, usize)>,
    pub sparse: Option<Sparse>,
}

#[derive(Clone, Debug)]
pub(crate) struct Sparse {
    pub count: usize,
    pub index_component: ComponentType,
    /// `(buffer, byte offset)` of the indices and of the values (tightly packed).
    pub indices: (usize, usize),
    pub values: (usize, usize),
}

/// A checked buffer view: `(buffer, offset, length, stride)`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct View {
    pub buffer: usize,
    pub offset: usize,
    pub length: usize,
    pub stride: Option<usize>,
}

fn to_usize(v: u64, pointer: &str, ctx: &Ctx) -> Result<usize, SceneError> {
    usize::try_from(v).map_err(|_| ctx.invalid(pointer.to_string(), format!("{v} is too large")))
}

pub(crate) fn check_views(doc: &Doc, ctx: &Ctx) -> Result<Vec<View>, SceneError> {
    doc.views
        .iter()
        .enumerate()
        .map(|(i, v)| {
            let p = format!("/bufferViews/{i}");
            let b = v.buffer.value();
            let buffer = doc.buffers.get(b).ok_or_else(|| {
                ctx.unresolved(format!("{p}/buffer"), "/buffers", b, doc.buffers.len())
            })?;
            let length = to_usize(v.byte_length.0, &format!("{p}/byteLength"), ctx)?;
            let offset = to_usize(v.byte_offset.map_or(0, |o| o.0), &format!("{p}/byteOffset"), ctx)?;
            if length == 0 {
                return Err(ctx.invalid(format!("{p}/byteLength"), "must be at least 1".into()));
            }
            let buffer_len = to_usize(buffer.byte_length.0, &format!("/buffers/{b}/byteLength"), ctx)?;
            if offset >= buffer_len {
                return Err(ctx.out_of_bounds(
                    format!("{p}/byteOffset"),
                    format!("offset {offset} is past the end of buffer {b} ({buffer_len} bytes)"),
                ));
            }
            if !matches!(offset.checked_add(length), Some(end) if end <= buffer_len) {
                return Err(ctx.out_of_bounds(
                    format!("{p}/byteLength"),
                    format!("{offset} + {length} bytes exceed buffer {b} ({buffer_len} bytes)"),
                ));
            }
            let stride = v.byte_stride.map(|s| s.0);
            if let Some(s) = stride {
                if !(4..=252).contains(&s) || s % 4 != 0 {
                    return Err(ctx.invalid(
                        format!("{p}/byteStride"),
                        format!("{s} must be a multiple of 4 in [4, 252]"),
                    ));
                }
                if s > length {
                    return Err(ctx.invalid(
                        format!("{p}/byteStride"),
                        format!("{s} is larger than the view's byteLength {length}"),
                    ));
                }
            }
            match v.target {
                Some(Checked::Invalid) => {
                    return Err(ctx.invalid(format!("{p}/target"), "unknown target".into()))
                }
                Some(Checked::Valid(json::buffer::Target::ElementArrayBuffer)) if stride.is_some() => {
                    return Err(ctx.invalid(
                        format!("{p}/byteStride"),
                        "an index buffer view (target ELEMENT_ARRAY_BUFFER) cannot have a byteStride".into(),
                    ))
                }
                _ => {}
            }
            Ok(View {
                buffer: b,
                offset,
                length,
                stride,
            })
        })
        .collect()
}

/// An accessor the loader can read, or `(pointer, reason)` why not. An unknown `type` or
/// `componentType` is an error only when something uses the accessor: the validator only warns
/// about unknown enum values in an unused accessor.
pub(crate) type Slot = Result<Accessor, (String, String)>;

/// The accessor at `index`, for `user` (a JSON pointer); an error if it does not exist or
/// cannot be read.
pub(crate) fn lookup<'s>(
    slots: &'s [Slot],
    index: usize,
    user: &str,
    ctx: &Ctx,
) -> Result<&'s Accessor, SceneError> {
    match slots.get(index) {
        None => Err(ctx.unresolved(user.to_string(), "/accessors", index, slots.len())),
        Some(Ok(a)) => Ok(a),
        Some(Err((pointer, reason))) => {
            Err(ctx.invalid(pointer.clone(), format!("{reason}; used by {user}")))
        }
    }
}

pub(crate) fn check_accessors(
    doc: &Doc,
    views: &[View],
    ctx: &Ctx,
) -> Result<Vec<Slot>, SceneError> {
    doc.accessors
        .iter()
        .enumerate()
        .map(|(i, a)| check_accessor(i, a, views, ctx))
        .collect()
}

fn check_accessor(
    i: usize,
    a: &json::Accessor,
    views: &[View],
    ctx: &Ctx,
) -> Result<Slot, SceneError> {
    let p = format!("/accessors/{i}");
    let Checked::Valid(json::accessor::GenericComponentType(component)) = a.component_type else {
        return Ok(Err((
            format!("{p}/componentType"),
            "unknown component type".into(),
        )));
    };
    let Checked::Valid(ty) = a.type_ else {
        return Ok(Err((format!("{p}/type"), "unknown accessor type".into())));
    };
    if a.normalized && matches!(component, ComponentType::F32 | ComponentType::U32) {
        return Err(ctx.invalid(
            format!("{p}/normalized"),
            "only 8- and 16-bit integer accessors can be normalized".into(),
        ));
    }
    let count = to_usize(a.count.0, &format!("{p}/count"), ctx)?;
    if count == 0 {
        return Err(ctx.invalid(format!("{p}/count"), "must be at least 1".into()));
    }
    let csize = component_size(component);
    let esize = element_size(component, ty);
    let byte_offset = to_usize(
        a.byte_offset.map_or(0, |o| o.0),
        &format!("{p}/byteOffset"),
        ctx,
    )?;
    let source = match a.buffer_view {
        None => {
            if a.byte_offset.is_some() {
                return Err(ctx.invalid(
                    format!("{p}/byteOffset"),
                    "byteOffset without a bufferView".into(),
                ));
            }
            None
        }
        Some(vi) => {
            let vi = vi.value();
            let view = views.get(vi).ok_or_else(|| {
                ctx.unresolved(format!("{p}/bufferView"), "/bufferViews", vi, views.len())
            })?;
            if byte_offset % csize != 0 {
                return Err(ctx.invalid(
                    format!("{p}/byteOffset"),
                    format!("{byte_offset} is not a multiple of the component size {csize}"),
                ));
            }
            if matches!(ty, Type::Mat2 | Type::Mat3 | Type::Mat4) && byte_offset % 4 != 0 {
                return Err(ctx.invalid(
                    format!("{p}/byteOffset"),
                    "matrix accessors must start on a 4-byte boundary".into(),
                ));
            }
            // Checked: a placeholder buffer's byteLength is never compared with real bytes, so
            // a view offset near u64::MAX can reach here.
            let Some(total) = view.offset.checked_add(byte_offset) else {
                return Err(ctx.out_of_bounds(
                    format!("{p}/byteOffset"),
                    format!("{byte_offset} past bufferView {vi} overflows"),
                ));
            };
            if total % csize != 0 {
                return Err(ctx.invalid(
                    p,
                    format!("total offset {total} is not a multiple of the component size {csize}"),
                ));
            }
            let stride = view.stride.unwrap_or(esize);
            if stride < esize {
                return Err(ctx.invalid(
                    p,
                    format!(
                        "bufferView byteStride {stride} is smaller than the element size {esize}"
                    ),
                ));
            }
            let needed = (count - 1)
                .checked_mul(stride)
                .and_then(|n| n.checked_add(esize))
                .and_then(|n| n.checked_add(byte_offset));
            if !matches!(needed, Some(n) if n <= view.length) {
                return Err(ctx.out_of_bounds(
                    p,
                    format!(
                        "{count} elements of {esize} bytes (stride {stride}) from offset {byte_offset} \
                         do not fit bufferView {vi} ({} bytes)",
                        view.length
                    ),
                ));
            }
            Some((view.buffer, total, stride))
        }
    };
    let sparse = match &a.sparse {
        None => None,
        Some(s) => Some(check_sparse(&p, s, count, esize, views, ctx)?),
    };
    Ok(Ok(Accessor {
        component,
        ty,
        normalized: a.normalized,
        count,
        source,
        sparse,
    }))
}

fn check_sparse(
    p: &str,
    s: &json::accessor::sparse::Sparse,
    count: usize,
    esize: usize,
    views: &[View],
    ctx: &Ctx,
) -> Result<Sparse, SceneError> {
    let n = to_usize(s.count.0, &format!("{p}/sparse/count"), ctx)?;
    if n == 0 || n > count {
        return Err(ctx.invalid(
            format!("{p}/sparse/count"),
            format!("{n} must be in [1, accessor count {count}]"),
        ));
    }
    let Checked::Valid(ic) = s.indices.component_type else {
        return Err(ctx.invalid(
            format!("{p}/sparse/indices/componentType"),
            "must be UNSIGNED_BYTE, UNSIGNED_SHORT or UNSIGNED_INT".into(),
        ));
    };
    let ic = ic.0;
    let place = |part: &str,
                 view_index: usize,
                 offset: u64,
                 elem: usize|
     -> Result<(usize, usize), SceneError> {
        let vp = format!("{p}/sparse/{part}/bufferView");
        let view = views
            .get(view_index)
            .ok_or_else(|| ctx.unresolved(vp.clone(), "/bufferViews", view_index, views.len()))?;
        if view.stride.is_some() {
            return Err(ctx.invalid(
                vp,
                "sparse data cannot use a bufferView with byteStride".into(),
            ));
        }
        let offset = to_usize(offset, &format!("{p}/sparse/{part}/byteOffset"), ctx)?;
        let end = n.checked_mul(elem).and_then(|b| b.checked_add(offset));
        if !matches!(end, Some(e) if e <= view.length) {
            return Err(ctx.out_of_bounds(
                format!("{p}/sparse/{part}"),
                format!(
                    "{n} elements of {elem} bytes from {offset} exceed bufferView {view_index}"
                ),
            ));
        }
        Ok((view.buffer, view.offset + offset))
    };
    let indices = place(
        "indices",
        s.indices.buffer_view.value(),
        s.indices.byte_offset.0,
        component_size(ic),
    )?;
    let values = place(
        "values",
        s.values.buffer_view.value(),
        s.values.byte_offset.0,
        esize,
    )?;
    Ok(Sparse {
        count: n,
        index_component: ic,
        indices,
        values,
    })
}

/// Reads accessors out of resolved buffers.
pub(crate) struct Reader<'d, 'a> {
    pub accessors: &'d [Slot],
    pub buffers: &'d [BufferData<'a>],
    pub ctx: &'d Ctx,
}

#[inline]
fn component_f32(c: ComponentType, normalized: bool, b: &[u8]) -> f32 {
    match c {
        ComponentType::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]),
        ComponentType::U8 if normalized => f32::from(b[0]) / 255.0,
        ComponentType::U8 => f32::from(b[0]),
        ComponentType::I8 if normalized => (f32::from(b[0] as i8) / 127.0).max(-1.0),
        ComponentType::I8 => f32::from(b[0] as i8),
        ComponentType::U16 if normalized => f32::from(u16::from_le_bytes([b[0], b[1]])) / 65535.0,
        ComponentType::U16 => f32::from(u16::from_le_bytes([b[0], b[1]])),
        ComponentType::I16 if normalized => {
            (f32::from(i16::from_le_bytes([b[0], b[1]])) / 32767.0).max(-1.0)
        }
        ComponentType::I16 => f32::from(i16::from_le_bytes([b[0], b[1]])),
        ComponentType::U32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f32,
    }
}

#[inline]
fn component_u32(c: ComponentType, b: &[u8]) -> u32 {
    match c {
        ComponentType::U8 | ComponentType::I8 => u32::from(b[0]),
        ComponentType::U16 | ComponentType::I16 => u32::from(u16::from_le_bytes([b[0], b[1]])),
        ComponentType::U32 | ComponentType::F32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]),
    }
}

impl<'d, 'a> Reader<'d, 'a> {
    pub fn accessor(&self, index: usize) -> Option<&'d Accessor> {
        self.accessors.get(index).and_then(|s| s.as_ref().ok())
    }

    pub fn bytes(&self, buffer: usize, user: &str) -> Result<&[u8], SceneError> {
        match self.buffers.get(buffer) {
            Some(BufferData::Bytes(b)) => Ok(b),
            Some(BufferData::Unavailable(why)) => Err(self.ctx.buffer(
                format!("/buffers/{buffer}"),
                format!("{why}; needed by {user}"),
            )),
            None => {
                Err(self
                    .ctx
                    .unresolved(user.to_string(), "/buffers", buffer, self.buffers.len()))
            }
        }
    }

    /// Reads accessor `index` as `comps` f32 per element (flat). The caller has checked the type.
    pub fn read_f32(&self, index: usize, comps: usize) -> Result<Vec<f32>, SceneError> {
        let p = format!("/accessors/{index}");
        let a = lookup(self.accessors, index, &p, self.ctx)?;
        let csize = component_size(a.component);
        let mut out = vec![0f32; a.count * comps];
        if let Some((buffer, offset, stride)) = a.source {
            let data = self.bytes(buffer, &p)?;
            for (e, dst) in out.chunks_exact_mut(comps).enumerate() {
                let at = offset + e * stride;
                // Ranges were checked against the view and the view against the buffer.
                let Some(elem) = data.get(at..at + comps * csize) else {
                    return Err(self
                        .ctx
                        .out_of_bounds(p, format!("element {e} past the buffer end")));
                };
                for (k, d) in dst.iter_mut().enumerate() {
                    *d = component_f32(a.component, a.normalized, &elem[k * csize..]);
                }
            }
        }
        if let Some(s) = &a.sparse {
            let idx = self.sparse_indices(&p, a, s)?;
            let data = self.bytes(s.values.0, &p)?;
            let esize = comps * csize;
            for (k, &target) in idx.iter().enumerate() {
                let at = s.values.1 + k * esize;
                let Some(elem) = data.get(at..at + esize) else {
                    return Err(self.ctx.out_of_bounds(
                        format!("{p}/sparse/values"),
                        "past the buffer end".into(),
                    ));
                };
                for c in 0..comps {
                    out[target * comps + c] =
                        component_f32(a.component, a.normalized, &elem[c * csize..]);
                }
            }
        }
        Ok(out)
    }

    /// Sparse indices, checked strictly increasing and below the accessor count.
    fn sparse_indices(&self, p: &str, a: &Accessor, s: &Sparse) -> Result<Vec<usize>, SceneError> {
        let data = self.bytes(s.indices.0, p)?;
        let isize_ = component_size(s.index_component);
        let mut out = Vec::with_capacity(s.count);
        for k in 0..s.count {
            let at = s.indices.1 + k * isize_;
            let Some(b) = data.get(at..at + isize_) else {
                return Err(self
                    .ctx
                    .out_of_bounds(format!("{p}/sparse/indices"), "past the buffer end".into()));
            };
            let i = component_u32(s.index_component, b) as usize;
            if i >= a.count || out.last().is_some_and(|&last| i <= last) {
                return Err(self.ctx.invalid(
                    format!("{p}/sparse/indices"),
                    format!(
                        "index {i} at position {k} is not strictly increasing or not below {}",
                        a.count
                    ),
                ));
            }
            out.push(i);
        }
        Ok(out)
    }

    /// Reads an index accessor (SCALAR of u8/u16/u32, checked by the caller) as u32.
    pub fn read_indices(&self, index: usize) -> Result<Vec<u32>, SceneError> {
        let p = format!("/accessors/{index}");
        let a = lookup(self.accessors, index, &p, self.ctx)?;
        let csize = component_size(a.component);
        let mut out = vec![0u32; a.count];
        if let Some((buffer, offset, stride)) = a.source {
            let data = self.bytes(buffer, &p)?;
            for (e, dst) in out.iter_mut().enumerate() {
                let at = offset + e * stride;
                let Some(b) = data.get(at..at + csize) else {
                    return Err(self
                        .ctx
                        .out_of_bounds(p, format!("element {e} past the buffer end")));
                };
                *dst = component_u32(a.component, b);
            }
        }
        if let Some(s) = &a.sparse {
            let idx = self.sparse_indices(&p, a, s)?;
            let data = self.bytes(s.values.0, &p)?;
            for (k, &target) in idx.iter().enumerate() {
                let at = s.values.1 + k * csize;
                let Some(b) = data.get(at..at + csize) else {
                    return Err(self.ctx.out_of_bounds(
                        format!("{p}/sparse/values"),
                        "past the buffer end".into(),
                    ));
                };
                out[target] = component_u32(a.component, b);
            }
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn data_uris_and_schemes() {
        assert_eq!(
            decode_data_uri("data:application/octet-stream;base64,AAE=").unwrap(),
            vec![0, 1]
        );
        assert!(decode_data_uri("data:application/OCTET-STREAM;base64,AA==").is_ok());
        assert!(decode_data_uri("data:application/octet-stream2;base64,AA==").is_err());
        assert!(decode_data_uri("data:application/octet-stream;;base64,AA==").is_err());
        assert_eq!(
            decode_data_uri("data:application/gltf-buffer,0%01").unwrap(),
            vec![b'0', 1]
        );
        assert!(decode_data_uri("data:application/octet-stream;base64,A!==").is_err());
        assert_eq!(has_scheme("http://x/y.bin"), Ok(true));
        assert_eq!(has_scheme("dir/a:b.bin"), Ok(false));
        assert_eq!(has_scheme("model.bin"), Ok(false));
        assert!(has_scheme(":").is_err());
        assert_eq!(percent_decode("a%20b.bin").unwrap(), "a b.bin");
        assert!(percent_decode("a%2").is_err());
    }

    #[test]
    fn normalized_components_convert_per_the_spec() {
        assert_eq!(component_f32(ComponentType::U8, true, &[255]), 1.0);
        assert_eq!(component_f32(ComponentType::I8, true, &[0x80]), -1.0);
        assert_eq!(
            component_f32(ComponentType::I16, true, &0x8000u16.to_le_bytes()),
            -1.0
        );
        assert_eq!(
            component_f32(ComponentType::U16, false, &7u16.to_le_bytes()),
            7.0
        );
    }
}
