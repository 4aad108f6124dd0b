//! The JSON document, parsed element by element into the `gltf` crate's JSON types.
//!
//! Why not `gltf::json::Root::from_slice` for the whole file: one bad element anywhere (an image,
//! a sampler) would fail the whole document, and serde's message would not say which element.
//! Deserializing each element of the collections the loader uses on its own gives an error
//! pointing at `/accessors/3`, and leaves the collections it does not use (cameras, animations,
//! skins) unread. Textures, images and samplers are kept as JSON and read element by element
//! only where a material's base colour reaches them (`images.rs`).

use gltf::json;
use serde::de::DeserializeOwned;
use serde_json::{Map, Value};

use super::Ctx;
use crate::error::SceneError;

/// Required extensions this loader can honour: they change nothing it reads, or (mesh
/// quantization) only allow component types its accessor reader already converts.
const SUPPORTED_REQUIRED: &[&str] = &[
    "KHR_mesh_quantization",
    "KHR_materials_unlit",
    "KHR_materials_emissive_strength",
    "KHR_materials_ior",
    "KHR_materials_specular",
    "KHR_materials_transmission",
    "KHR_materials_volume",
    "KHR_materials_clearcoat",
    "KHR_materials_sheen",
    "KHR_materials_iridescence",
    "KHR_materials_anisotropy",
    "KHR_materials_dispersion",
    "KHR_texture_transform",
    "KHR_texture_basisu",
    "EXT_texture_webp",
    "EXT_texture_avif",
    "KHR_lights_punctual",
];

/// The parts of the document the loader uses.
pub(crate) struct Doc {
    pub buffers: Vec<json::Buffer>,
    pub views: Vec<json::buffer::View>,
    pub accessors: Vec<json::Accessor>,
    pub meshes: Vec<json::Mesh>,
    pub materials: Vec<json::Material>,
    pub nodes: Vec<json::Node>,
    pub scenes: Vec<SceneDef>,
    pub scene: Option<u64>,
    pub quantized: bool,
    /// Raw `textures`, `images` and `samplers`: read element by element, only those a
    /// material's base colour reaches ([`element`]).
    pub textures: Vec<Value>,
    pub images: Vec<Value>,
    pub samplers: Vec<Value>,
    /// Per material: `KHR_materials_transmission` with a factor above 0 (glass). Read before
    /// the extensions are dropped: light passes through it, so it must not hide what is behind.
    pub transmissive: Vec<bool>,
}

/// A scene. Not `gltf::json::Scene`, which requires `nodes` where glTF 2.0 makes it optional.
#[derive(Debug, serde::Deserialize)]
pub(crate) struct SceneDef {
    #[serde(default)]
    pub nodes: Option<Vec<u32>>,
}

/// Turns integral floats (`1e0`, `2.0`) into integers and drops `extras` and `extensions`.
///
/// glTF allows integers written as floats (the validator accepts them); serde does not
/// deserialize `1.0` into a `u32`. Integral values deserialize into floats unchanged, so the
/// rewrite is safe for every field. `extras` are application data that may be any JSON value
/// (the `gltf` crate's non-`extras` build expects an object), and element-level extensions are
/// either unsupported (and then required, rejected above) or ignorable.
fn normalize(v: &mut Value) {
    match v {
        Value::Object(map) => {
            map.remove("extras");
            map.remove("extensions");
            map.values_mut().for_each(normalize);
        }
        Value::Array(items) => items.iter_mut().for_each(normalize),
        Value::Number(n) => {
            if let Some(f) = n.as_f64().filter(|_| !n.is_i64() && !n.is_u64()) {
                // 2^53: beyond it f64 no longer holds every integer exactly.
                if f.fract() == 0.0 && f.abs() <= 9_007_199_254_740_992.0 {
                    *v = if f < 0.0 {
                        Value::from(f as i64)
                    } else {
                        Value::from(f as u64)
                    };
                }
            }
        }
        _ => {}
    }
}

/// One element of a raw collection (at `pointer`), normalized and deserialized.
pub(crate) fn element<T: DeserializeOwned>(
    raw: &Value,
    pointer: &str,
    ctx: &Ctx,
) -> Result<T, SceneError> {
    if !raw.is_object() {
        return Err(ctx.invalid(pointer.to_string(), "must be a JSON object".into()));
    }
    let mut item = raw.clone();
    normalize(&mut item);
    serde_json::from_value(item).map_err(|e| ctx.invalid(pointer.to_string(), e.to_string()))
}

/// A top-level array kept as JSON values. Anything else counts as empty (with a warning): it
/// is an error only if a material reaches into it, and then the reference is unresolved.
fn raw_collection(root: &mut Map<String, Value>, name: &str, ctx: &Ctx) -> Vec<Value> {
    match root.remove(name) {
        None => Vec::new(),
        Some(Value::Array(items)) => items,
        Some(_) => {
            log::warn!("{}: /{name} is not an array: read as empty", ctx.file);
            Vec::new()
        }
    }
}

fn collection<T: DeserializeOwned>(
    root: &mut Map<String, Value>,
    name: &str,
    ctx: &Ctx,
) -> Result<Vec<T>, SceneError> {
    let Some(value) = root.remove(name) else {
        return Ok(Vec::new());
    };
    let pointer = format!("/{name}");
    let Value::Array(items) = value else {
        return Err(ctx.invalid(pointer, format!("`{name}` must be an array")));
    };
    if items.is_empty() {
        // The schema's minItems: 1 for every top-level array.
        return Err(ctx.invalid(pointer, "empty array: omit the property instead".into()));
    }
    items
        .into_iter()
        .enumerate()
        .map(|(i, mut item)| {
            if !item.is_object() {
                return Err(ctx.invalid(format!("{pointer}/{i}"), "must be a JSON object".into()));
            }
            normalize(&mut item);
            serde_json::from_value(item)
                .map_err(|e| ctx.invalid(format!("{pointer}/{i}"), e.to_string()))
        })
        .collect()
}

/// `"2.0"` -> (2, 0); the validator's pattern `^([0-9]+)\.([0-9]+)$`.
fn parse_version(s: &str) -> Option<(u64, u64)> {
    let (major, minor) = s.split_once('.')?;
    let digits = |t: &str| !t.is_empty() && t.bytes().all(|b| b.is_ascii_digit());
    if !digits(major) || !digits(minor) {
        return None;
    }
    Some((major.parse().ok()?, minor.parse().ok()?))
}

fn check_asset(root: &Map<String, Value>, ctx: &Ctx) -> Result<(), SceneError> {
    let Some(asset) = root.get("asset") else {
        return Err(ctx.invalid(String::new(), "missing required property `asset`".into()));
    };
    let Value::Object(asset) = asset else {
        return Err(ctx.invalid("/asset".into(), "must be a JSON object".into()));
    };
    let version = match asset.get("version") {
        Some(Value::String(s)) => s,
        Some(_) => return Err(ctx.invalid("/asset/version".into(), "must be a string".into())),
        None => {
            return Err(ctx.invalid(
                "/asset".into(),
                "missing required property `version`".into(),
            ))
        }
    };
    let Some((major, minor)) = parse_version(version) else {
        return Err(ctx.invalid(
            "/asset/version".into(),
            format!("`{version}` is not of the form <major>.<minor>"),
        ));
    };
    if major != 2 {
        return Err(ctx.invalid(
            "/asset/version".into(),
            format!("glTF {version}: this loader reads glTF 2.x"),
        ));
    }
    match asset.get("minVersion") {
        None => {}
        Some(Value::String(min)) => {
            let Some(min_v) = parse_version(min) else {
                return Err(ctx.invalid(
                    "/asset/minVersion".into(),
                    format!("`{min}` is not of the form <major>.<minor>"),
                ));
            };
            if min_v > (major, minor) {
                return Err(ctx.invalid(
                    "/asset/minVersion".into(),
                    format!("minVersion {min} is greater than version {version}"),
                ));
            }
            // minVersion is the version a loader must implement to read the file at all.
            if min_v > (2, 0) {
                return Err(ctx.invalid(
                    "/asset/minVersion".into(),
                    format!("requires glTF {min}; this loader implements 2.0"),
                ));
            }
        }
        Some(_) => return Err(ctx.invalid("/asset/minVersion".into(), "must be a string".into())),
    }
    if minor > 0 {
        log::info!("{}: glTF {version}, read as 2.0", ctx.file);
    }
    Ok(())
}

fn check_extensions(root: &Map<String, Value>, ctx: &Ctx) -> Result<bool, SceneError> {
    let list = |name: &str| -> Result<Vec<String>, SceneError> {
        match root.get(name) {
            None => Ok(Vec::new()),
            Some(Value::Array(items)) => items
                .iter()
                .enumerate()
                .map(|(i, v)| match v {
                    Value::String(s) => Ok(s.clone()),
                    _ => Err(ctx.invalid(format!("/{name}/{i}"), "must be a string".into())),
                })
                .collect(),
            Some(_) => Err(ctx.invalid(format!("/{name}"), "must be an array".into())),
        }
    };
    let used = list("extensionsUsed")?;
    let required = list("extensionsRequired")?;
    for (i, name) in required.iter().enumerate() {
        if !SUPPORTED_REQUIRED.contains(&name.as_str()) {
            return Err(SceneError::UnsupportedExtension {
                file: ctx.file.clone(),
                pointer: format!("/extensionsRequired/{i}"),
                name: name.clone(),
            });
        }
    }
    if used.iter().any(|n| n == "KHR_texture_transform") {
        log::warn!(
            "{}: KHR_texture_transform is not applied: textures are sampled with the UVs as stored",
            ctx.file
        );
    }
    for name in used.iter().filter(|n| !required.contains(n)) {
        log::debug!("{}: optional extension {name} ignored", ctx.file);
    }
    Ok(used.iter().any(|n| n == "KHR_mesh_quantization"))
}

pub(crate) fn parse(json_bytes: &[u8], ctx: &Ctx) -> Result<Doc, SceneError> {
    if json_bytes.starts_with(&[0xEF, 0xBB, 0xBF]) {
        return Err(SceneError::Json {
            file: ctx.file.clone(),
            line: 1,
            column: 1,
            reason: "starts with a UTF-8 byte order mark, which glTF JSON must not have".into(),
        });
    }
    let value: Value = serde_json::from_slice(json_bytes).map_err(|e| {
        let first = json_bytes.iter().find(|b| !b.is_ascii_whitespace());
        if e.is_syntax() && first != Some(&b'{') && first != Some(&b'[') {
            SceneError::NotGltf {
                file: ctx.file.clone(),
                reason: format!("neither a GLB container nor JSON ({e})"),
            }
        } else {
            SceneError::Json {
                file: ctx.file.clone(),
                line: e.line(),
                column: e.column(),
                reason: e.to_string(),
            }
        }
    })?;
    let Value::Object(mut root) = value else {
        return Err(ctx.invalid(String::new(), "the document must be a JSON object".into()));
    };
    check_asset(&root, ctx)?;
    let quantized = check_extensions(&root, ctx)?;
    let scene = match root.get("scene") {
        None => None,
        Some(v) => Some(
            v.as_u64()
                .or_else(|| {
                    v.as_f64()
                        .filter(|f| f.fract() == 0.0 && *f >= 0.0)
                        .map(|f| f as u64)
                })
                .ok_or_else(|| {
                    ctx.invalid("/scene".into(), "must be a non-negative integer".into())
                })?,
        ),
    };
    let transmissive = root
        .get("materials")
        .and_then(Value::as_array)
        .map(|materials| materials.iter().map(transmission_above_zero).collect())
        .unwrap_or_default();
    // Order matters only for which error is reported first: the data layer before its users.
    Ok(Doc {
        buffers: collection(&mut root, "buffers", ctx)?,
        views: collection(&mut root, "bufferViews", ctx)?,
        accessors: collection(&mut root, "accessors", ctx)?,
        materials: collection(&mut root, "materials", ctx)?,
        meshes: collection(&mut root, "meshes", ctx)?,
        nodes: collection(&mut root, "nodes", ctx)?,
        scenes: collection(&mut root, "scenes", ctx)?,
        textures: raw_collection(&mut root, "textures", ctx),
        images: raw_collection(&mut root, "images", ctx),
        samplers: raw_collection(&mut root, "samplers", ctx),
        scene,
        quantized,
        transmissive,
    })
}

/// `extensions.KHR_materials_transmission.transmissionFactor > 0` (the factor defaults to 0).
fn transmission_above_zero(material: &Value) -> bool {
    material
        .pointer("/extensions/KHR_materials_transmission/transmissionFactor")
        .and_then(Value::as_f64)
        .is_some_and(|f| f > 0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn versions_follow_the_validator_pattern() {
        assert_eq!(parse_version("2.0"), Some((2, 0)));
        assert_eq!(parse_version("2.10"), Some((2, 10)));
        assert_eq!(parse_version("1.0.1-dev"), None);
        assert_eq!(parse_version("2."), None);
        assert_eq!(parse_version("+2.0"), None);
    }

    #[test]
    fn integral_floats_become_integers() {
        let mut v: Value =
            serde_json::from_str(r#"{"a": 1e0, "b": [2.0, 0.5, -3.0], "extras": 5}"#).unwrap();
        normalize(&mut v);
        assert_eq!(v, serde_json::json!({"a": 1, "b": [2, 0.5, -3]}));
    }
}
