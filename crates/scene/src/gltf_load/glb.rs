//! The GLB container: a 12-byte header, a JSON chunk, an optional BIN chunk.
//!
//! Parsed here rather than with `gltf::Glb::from_slice`, which subtracts the header size from
//! the declared length without checking it (a GLB declaring a length below 12 overflows), and
//! which does not tell the container errors apart the way the glTF-Validator does (length
//! mismatch, unaligned chunk, duplicate chunk, BIN chunk out of place).

use crate::error::SceneError;

const MAGIC: &[u8; 4] = b"glTF";
const JSON: u32 = 0x4E4F_534A;
const BIN: u32 = 0x004E_4942;
const HEADER: usize = 12;
const CHUNK_HEADER: usize = 8;

/// The chunks of a GLB file, borrowed from its bytes.
#[derive(Debug)]
pub(crate) struct Glb<'a> {
    pub json: &'a [u8],
    pub bin: Option<&'a [u8]>,
}

pub(crate) fn is_glb(bytes: &[u8]) -> bool {
    bytes.starts_with(MAGIC)
}

fn u32_at(bytes: &[u8], at: usize) -> Option<u32> {
    let b = bytes.get(at..at.checked_add(4)?)?;
    Some(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
}

pub(crate) fn parse<'a>(bytes: &'a [u8], file: &str) -> Result<Glb<'a>, SceneError> {
    let err = |offset: usize, reason: String| SceneError::Glb {
        file: file.to_string(),
        offset,
        reason,
    };
    if bytes.len() < HEADER {
        return Err(err(
            bytes.len(),
            format!(
                "unexpected end of header: {} bytes, the header needs 12",
                bytes.len()
            ),
        ));
    }
    if !is_glb(bytes) {
        return Err(err(
            0,
            format!("invalid magic {:02x?}, expected \"glTF\"", &bytes[..4]),
        ));
    }
    let version = u32_at(bytes, 4).unwrap_or(0);
    if version != 2 {
        return Err(err(
            4,
            format!("unsupported GLB version {version}, expected 2"),
        ));
    }
    let declared = u32_at(bytes, 8).unwrap_or(0) as usize;
    if declared < HEADER + CHUNK_HEADER {
        return Err(err(
            8,
            format!("declared length {declared} is too small for a header and a JSON chunk"),
        ));
    }
    if declared > bytes.len() {
        return Err(err(
            bytes.len(),
            format!(
                "declared length {declared} but the file has {} bytes",
                bytes.len()
            ),
        ));
    }
    if declared < bytes.len() {
        // The validator only warns about bytes after the declared end; so do we.
        log::warn!(
            "{file}: {} bytes after the declared end of the GLB are ignored",
            bytes.len() - declared
        );
    }
    let data = &bytes[..declared];

    let mut json: Option<&[u8]> = None;
    let mut bin: Option<&[u8]> = None;
    let mut offset = HEADER;
    let mut index = 0usize;
    while offset < data.len() {
        let (Some(len), Some(ty)) = (u32_at(data, offset), u32_at(data, offset + 4)) else {
            return Err(err(offset, "unexpected end of chunk header".into()));
        };
        let len = len as usize;
        if !len.is_multiple_of(4) {
            return Err(err(
                offset,
                format!("chunk length {len} is not a multiple of 4"),
            ));
        }
        let start = offset + CHUNK_HEADER;
        let Some(body) = start.checked_add(len).and_then(|end| data.get(start..end)) else {
            return Err(err(
                offset,
                format!(
                    "chunk of {len} bytes does not fit: {} bytes left",
                    data.len().saturating_sub(start)
                ),
            ));
        };
        match ty {
            JSON if index == 0 => {
                if len == 0 {
                    return Err(err(offset, "empty JSON chunk".into()));
                }
                json = Some(body);
            }
            JSON => return Err(err(offset, "a second JSON chunk".into())),
            _ if index == 0 => {
                return Err(err(
                    offset,
                    format!("first chunk must be JSON, found type 0x{ty:08x}"),
                ))
            }
            BIN if bin.is_some() => return Err(err(offset, "a second BIN chunk".into())),
            BIN if index != 1 => {
                return Err(err(offset, "the BIN chunk must be the second chunk".into()))
            }
            BIN => bin = Some(body),
            other => {
                // The spec: chunks of unknown types must be ignored.
                log::debug!("{file}: ignoring GLB chunk of unknown type 0x{other:08x}");
            }
        }
        offset = start + len;
        index += 1;
    }
    match json {
        Some(json) => Ok(Glb { json, bin }),
        None => Err(err(HEADER, "no JSON chunk".into())),
    }
}

/// Writes a GLB container (used by the exporter and by tests that build small files).
pub(crate) fn write(json: &[u8], bin: Option<&[u8]>) -> Vec<u8> {
    let pad = |n: usize| (4 - n % 4) % 4;
    let json_len = json.len() + pad(json.len());
    let bin_len = bin.map_or(0, |b| b.len() + pad(b.len()));
    let total = HEADER + CHUNK_HEADER + json_len + bin.map_or(0, |_| CHUNK_HEADER + bin_len);
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json_len as u32).to_le_bytes());
    out.extend_from_slice(&JSON.to_le_bytes());
    out.extend_from_slice(json);
    out.resize(out.len() + pad(json.len()), b' ');
    if let Some(b) = bin {
        out.extend_from_slice(&(bin_len as u32).to_le_bytes());
        out.extend_from_slice(&BIN.to_le_bytes());
        out.extend_from_slice(b);
        out.resize(out.len() + pad(b.len()), 0);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_and_rejects_every_truncation() {
        let glb = write(br#"{"asset":{"version":"2.0"}}"#, Some(&[1, 2, 3, 4, 5]));
        let parsed = parse(&glb, "t.glb").unwrap();
        assert_eq!(parsed.bin.map(|b| b.len()), Some(8));
        assert!(parsed.json.starts_with(b"{"));
        for n in 0..glb.len() {
            assert!(
                matches!(parse(&glb[..n], "t.glb"), Err(SceneError::Glb { .. })),
                "truncated to {n} bytes"
            );
        }
    }

    #[test]
    fn rejects_declared_length_below_the_header() {
        let mut glb = write(b"{}  ", None);
        glb[8..12].copy_from_slice(&4u32.to_le_bytes());
        assert!(matches!(
            parse(&glb, "t.glb"),
            Err(SceneError::Glb { offset: 8, .. })
        ));
    }
}
