//! glTF 2.0 loading: .gltf (external or data-URI buffers) and .glb, flattened into a [`Scene`].
//!
//! The pipeline, one phase per function, each checking what the next relies on:
//!
//! ```text
//! container (glb::parse) -> document (doc::parse) -> buffers (data::resolve_buffers)
//!   -> buffer views (data::check_views) -> accessors (data::check_accessors)
//!   -> materials -> meshes (check_meshes) -> node hierarchy (nodes::check_hierarchy)
//!   -> scene roots -> flatten (flatten.rs: instances; mesh data read on first use)
//! ```
//!
//! Nothing is read from a buffer before the range has been checked against its buffer view and
//! the view against its buffer, so no input can make the loader index out of bounds. Any error
//! aborts the load: there are no partial scenes.

mod data;
mod doc;
mod flatten;
pub(crate) mod glb;
mod images;
mod nodes;

use std::borrow::Cow;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

use gltf::json;
use gltf::json::accessor::{ComponentType, Type};
use gltf::json::mesh::{Mode, Semantic};
use gltf::json::validation::Checked;

use crate::error::SceneError;
use crate::scene::{GltfCounts, Material, MaterialClass, Scene, SceneBuilder, SceneSource};
use data::{lookup, Reader, Slot};
use doc::Doc;
use flatten::Flatten;
use nodes::{check_hierarchy, scene_roots};

/// Where a .gltf's external files (buffers) come from.
pub trait ResourceResolver {
    /// The bytes of `path`, a relative URI already percent-decoded.
    fn read(&self, path: &str) -> std::io::Result<Cow<'_, [u8]>>;

    /// At most the first `max_bytes` bytes of `path` (a buffer needs only its `byteLength`):
    /// a resolver over real files must not read an endless or huge file whole.
    fn read_prefix(&self, path: &str, max_bytes: u64) -> std::io::Result<Cow<'_, [u8]>> {
        let _ = max_bytes;
        self.read(path)
    }
}

/// Reads external files relative to a directory (the .gltf's own).
#[derive(Clone, Debug)]
pub struct FileResolver {
    pub base: PathBuf,
}

impl ResourceResolver for FileResolver {
    fn read(&self, path: &str) -> std::io::Result<Cow<'_, [u8]>> {
        self.read_prefix(path, u64::MAX)
    }

    /// Reads only regular files (not a device or a pipe that never ends) inside `base` once
    /// symbolic links are resolved (a link shipped with an asset must not reach another file),
    /// and at most `max_bytes` of them.
    fn read_prefix(&self, path: &str, max_bytes: u64) -> std::io::Result<Cow<'_, [u8]>> {
        use std::io::Read as _;
        // A .gltf opened by a bare file name has an empty base: the working directory.
        let base = if self.base.as_os_str().is_empty() {
            std::fs::canonicalize(".")?
        } else {
            std::fs::canonicalize(&self.base)?
        };
        let real = std::fs::canonicalize(base.join(path))?;
        if !real.starts_with(&base) {
            return Err(std::io::Error::new(
                std::io::ErrorKind::PermissionDenied,
                format!("`{path}` resolves outside {}", base.display()),
            ));
        }
        let file = std::fs::File::open(&real)?;
        let meta = file.metadata()?;
        if !meta.is_file() {
            return Err(std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                "not a regular file",
            ));
        }
        let mut bytes = Vec::with_capacity(meta.len().min(max_bytes).min(1 << 30) as usize);
        file.take(max_bytes).read_to_end(&mut bytes)?;
        Ok(Cow::Owned(bytes))
    }
}

/// Resolves nothing: every external reference is an error. For bytes that must be
/// self-contained (GLB, data URIs), such as fuzz input.
#[derive(Clone, Copy, Debug, Default)]
pub struct NoResources;

impl ResourceResolver for NoResources {
    fn read(&self, path: &str) -> std::io::Result<Cow<'_, [u8]>> {
        Err(std::io::Error::new(
            std::io::ErrorKind::NotFound,
            format!("external file `{path}` requested, but no resolver was given"),
        ))
    }
}

/// External files held in memory, by relative URI (tests, fuzzing, embedding).
#[derive(Clone, Debug, Default)]
pub struct MemoryResources {
    pub files: HashMap<String, Vec<u8>>,
}

impl ResourceResolver for MemoryResources {
    fn read(&self, path: &str) -> std::io::Result<Cow<'_, [u8]>> {
        self.files
            .get(path)
            .map(|b| Cow::Borrowed(b.as_slice()))
            .ok_or_else(|| std::io::Error::new(std::io::ErrorKind::NotFound, path.to_string()))
    }
}

/// Caps on what a file may make the loader allocate; a corrupted count in a small file must not
/// exhaust memory. Exceeding one is [`SceneError::LimitExceeded`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Limits {
    pub max_vertices: usize,
    pub max_indices: usize,
    pub max_instances: usize,
    /// Pixels of one texture image (checked from its header, before decoding).
    pub max_texture_pixels: usize,
    /// Pixels of all the texture images together (each checked before it is decoded): many
    /// small image entries can name one large image's bytes.
    pub max_texture_pixels_total: usize,
}

impl Default for Limits {
    /// 2^26 vertices (2 GiB of vertex data), 2^28 indices (1 GiB), 2^24 instances (about
    /// 2 GiB of instances: a 1 MB file can instance a 10k-primitive mesh from 10k nodes),
    /// 2^26 pixels per texture (8192 x 8192, 341 MiB with mips), 2^30 pixels of textures in
    /// all (5.3 GiB with mips).
    fn default() -> Self {
        Limits {
            max_vertices: 1 << 26,
            max_indices: 1 << 28,
            max_instances: 1 << 24,
            max_texture_pixels: 1 << 26,
            max_texture_pixels_total: 1 << 30,
        }
    }
}

/// Error constructors that carry the file name.
pub(crate) struct Ctx {
    pub file: String,
}

impl Ctx {
    pub fn invalid(&self, pointer: String, reason: String) -> SceneError {
        SceneError::Invalid {
            file: self.file.clone(),
            pointer,
            reason,
        }
    }
    pub fn image(&self, pointer: String, reason: String) -> SceneError {
        SceneError::Image {
            file: self.file.clone(),
            pointer,
            reason,
        }
    }
    pub fn buffer(&self, pointer: String, reason: String) -> SceneError {
        SceneError::Buffer {
            file: self.file.clone(),
            pointer,
            reason,
        }
    }
    pub fn out_of_bounds(&self, pointer: String, reason: String) -> SceneError {
        SceneError::OutOfBounds {
            file: self.file.clone(),
            pointer,
            reason,
        }
    }
    pub fn unresolved(
        &self,
        pointer: String,
        target: &'static str,
        index: usize,
        len: usize,
    ) -> SceneError {
        SceneError::UnresolvedReference {
            file: self.file.clone(),
            pointer,
            target,
            index: index as u64,
            len,
        }
    }
    fn non_finite(&self, pointer: String, what: String) -> SceneError {
        SceneError::NonFinite {
            file: self.file.clone(),
            pointer,
            what,
        }
    }
    fn hierarchy(&self, pointer: String, reason: String) -> SceneError {
        SceneError::Hierarchy {
            file: self.file.clone(),
            pointer,
            reason,
        }
    }
    fn limit(
        &self,
        pointer: String,
        what: &'static str,
        requested: usize,
        limit: usize,
    ) -> SceneError {
        SceneError::LimitExceeded {
            file: self.file.clone(),
            pointer,
            what,
            requested: requested as u64,
            limit: limit as u64,
        }
    }
}

/// Loads a .gltf or .glb file; external buffers are read relative to its directory.
pub fn load_gltf(path: &Path, limits: &Limits) -> Result<Scene, SceneError> {
    let file = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|source| SceneError::Io {
        file: file.clone(),
        source,
    })?;
    let resolver = FileResolver {
        base: path.parent().map(Path::to_path_buf).unwrap_or_default(),
    };
    load_gltf_bytes(&bytes, &file, &resolver, limits)
}

/// Loads glTF from bytes: GLB if they start with the GLB magic (or `name` ends in `.glb`),
/// JSON otherwise. `name` is used in errors; `resolver` supplies external files.
pub fn load_gltf_bytes(
    bytes: &[u8],
    name: &str,
    resolver: &dyn ResourceResolver,
    limits: &Limits,
) -> Result<Scene, SceneError> {
    let ctx = Ctx {
        file: name.to_string(),
    };
    let is_glb = glb::is_glb(bytes) || name.to_ascii_lowercase().ends_with(".glb");
    let (json_bytes, bin) = if is_glb {
        let g = glb::parse(bytes, name)?;
        (g.json, g.bin)
    } else {
        (bytes, None)
    };
    let doc = doc::parse(json_bytes, &ctx)?;
    let buffers = data::resolve_buffers(&doc, bin, is_glb, resolver, &ctx)?;
    let views = data::check_views(&doc, &ctx)?;
    let accessors = data::check_accessors(&doc, &views, &ctx)?;
    let reader = Reader {
        accessors: &accessors,
        buffers: &buffers,
        ctx: &ctx,
    };

    // The scene is named after the file; errors (ctx) keep the whole path.
    let short = Path::new(name)
        .file_name()
        .map_or(name.into(), |f| f.to_string_lossy());
    let mut builder = SceneBuilder::new(short);
    builder.set_source(SceneSource::Gltf {
        path: name.to_string(),
    });
    let mut images = images::Images::new(&doc, &views, &reader, resolver, limits, &ctx);
    add_materials(&doc, &mut images, &mut builder, &ctx)?;
    let prims = check_meshes(&doc, &accessors, &ctx)?;
    let parents = check_hierarchy(&doc, &ctx)?;
    let roots = scene_roots(&doc, &parents, &ctx)?;

    let mut f = Flatten {
        doc: &doc,
        reader: &reader,
        prims: &prims,
        limits,
        ctx: &ctx,
        builder,
        mesh_cache: vec![None; doc.meshes.len()],
        vertex_cache: HashMap::new(),
        flat_source_cache: HashMap::new(),
        vertices_read: 0,
        default_material: None,
        material_count: doc.materials.len(),
    };
    let visited = f.flatten(&roots)?;
    let counts = GltfCounts {
        nodes: doc.nodes.len(),
        meshes: doc.meshes.len(),
        primitives: doc.meshes.iter().map(|m| m.primitives.len()).sum(),
        nodes_in_scene: visited,
    };
    let mut builder = f.builder;
    builder.set_gltf_counts(counts);
    if builder.instance_count() == 0 {
        return Err(SceneError::EmptyScene {
            file: ctx.file,
            reason: format!(
                "{} root node(s), {visited} node(s) reached, none instancing a triangle mesh \
                 ({} nodes and {} meshes in the document)",
                roots.len(),
                doc.nodes.len(),
                doc.meshes.len()
            ),
        });
    }
    builder.build(None)
}

fn add_materials(
    doc: &Doc,
    images: &mut images::Images<'_, '_>,
    builder: &mut SceneBuilder,
    ctx: &Ctx,
) -> Result<(), SceneError> {
    for (i, m) in doc.materials.iter().enumerate() {
        let p = format!("/materials/{i}");
        let color = m.pbr_metallic_roughness.base_color_factor.0;
        if !color.iter().all(|c| (0.0..=1.0).contains(c)) {
            return Err(ctx.invalid(
                format!("{p}/pbrMetallicRoughness/baseColorFactor"),
                format!("{color:?}: components must be in [0, 1]"),
            ));
        }
        let class = match m.alpha_mode {
            Checked::Valid(json::material::AlphaMode::Opaque) => MaterialClass::Opaque,
            Checked::Valid(json::material::AlphaMode::Mask) => {
                let cutoff = m.alpha_cutoff.map_or(0.5, |c| c.0);
                if !(cutoff.is_finite() && cutoff >= 0.0) {
                    return Err(
                        ctx.invalid(format!("{p}/alphaCutoff"), format!("{cutoff} must be >= 0"))
                    );
                }
                MaterialClass::AlphaTested { cutoff }
            }
            Checked::Valid(json::material::AlphaMode::Blend) => MaterialClass::Blended,
            Checked::Invalid => {
                return Err(ctx.invalid(
                    format!("{p}/alphaMode"),
                    "must be OPAQUE, MASK or BLEND".into(),
                ))
            }
        };
        // Transmissive (glass) lets the scene behind show through, so it must not occlude:
        // an OPAQUE one is drawn as blended with its alpha at 1 (glTF ignores alpha there, so it
        // looks the same), a BLEND one already is. A MASK one keeps its cut-out (alpha-tested
        // geometry still occludes where it is not cut out: a known limit).
        let transmissive = doc.transmissive.get(i).copied().unwrap_or(false);
        let (class, color) = match class {
            MaterialClass::Opaque if transmissive => {
                (MaterialClass::Blended, [color[0], color[1], color[2], 1.0])
            }
            other => (other, color),
        };
        let base_color_texture = match &m.pbr_metallic_roughness.base_color_texture {
            Some(info) => images.base_color(
                info,
                &format!("{p}/pbrMetallicRoughness/baseColorTexture"),
                builder,
            )?,
            None => None,
        };
        builder.add_material(Material {
            base_color: color,
            class,
            double_sided: m.double_sided,
            base_color_texture,
            engine_material: None,
        });
    }
    Ok(())
}

/// A checked primitive: accessor indices that resolve and have usable types.
#[derive(Clone, Copy, Debug)]
struct Prim {
    position: Option<usize>,
    normal: Option<usize>,
    uv: Option<usize>,
    indices: Option<usize>,
    material: Option<usize>,
    mode: Mode,
}

fn check_meshes(doc: &Doc, accessors: &[Slot], ctx: &Ctx) -> Result<Vec<Vec<Prim>>, SceneError> {
    let float_or =
        |a: &data::Accessor, quantized_ok: bool, allowed: &[ComponentType], normalized: bool| {
            a.component == ComponentType::F32
                || (allowed.contains(&a.component) && a.normalized == normalized)
                || (quantized_ok && doc.quantized && a.component != ComponentType::U32)
        };
    let mut out = Vec::with_capacity(doc.meshes.len());
    for (m, mesh) in doc.meshes.iter().enumerate() {
        if mesh.primitives.is_empty() {
            return Err(ctx.invalid(format!("/meshes/{m}/primitives"), "empty array".into()));
        }
        let mut prims = Vec::with_capacity(mesh.primitives.len());
        for (pi, prim) in mesh.primitives.iter().enumerate() {
            let pp = format!("/meshes/{m}/primitives/{pi}");
            if prim.attributes.is_empty() {
                return Err(ctx.invalid(format!("{pp}/attributes"), "no attributes".into()));
            }
            // The UV set the material's base-colour texture names (the vertex keeps one).
            let uv_set = prim
                .material
                .and_then(|m| doc.materials.get(m.value()))
                .and_then(|m| m.pbr_metallic_roughness.base_color_texture.as_ref())
                .map_or(0, |t| t.tex_coord);
            let mut count: Option<(usize, String)> = None;
            let mut p = Prim {
                position: None,
                normal: None,
                uv: None,
                indices: None,
                material: None,
                mode: Mode::Triangles,
            };
            for (semantic, index) in &prim.attributes {
                let name = match semantic {
                    Checked::Valid(s) => s.to_string(),
                    Checked::Invalid => {
                        log::debug!(
                            "{}: {pp}: attribute with an unknown semantic ignored",
                            ctx.file
                        );
                        continue;
                    }
                };
                let ap = format!("{pp}/attributes/{name}");
                let ai = index.value();
                let a = lookup(accessors, ai, &ap, ctx)?;
                match &count {
                    None => count = Some((a.count, name.clone())),
                    Some((c, first)) if *c != a.count => {
                        return Err(ctx.invalid(
                            ap,
                            format!("accessor {ai} has {} elements, {first} has {c}", a.count),
                        ))
                    }
                    _ => {}
                }
                match semantic {
                    Checked::Valid(Semantic::Positions) => {
                        if a.ty != Type::Vec3 || !float_or(a, true, &[], false) {
                            return Err(
                                ctx.invalid(ap, "POSITION must be a float VEC3 accessor".into())
                            );
                        }
                        p.position = Some(ai);
                    }
                    Checked::Valid(Semantic::Normals) => {
                        // KHR_mesh_quantization allows normalized signed bytes and shorts for
                        // normals, nothing else: plain integers would be read as huge vectors.
                        let quantized = doc.quantized
                            && a.normalized
                            && matches!(a.component, ComponentType::I8 | ComponentType::I16);
                        if a.ty != Type::Vec3 || !(a.component == ComponentType::F32 || quantized) {
                            return Err(ctx.invalid(
                                ap,
                                "NORMAL must be a float VEC3 accessor (or normalized signed \
                                 bytes/shorts with KHR_mesh_quantization)"
                                    .into(),
                            ));
                        }
                        p.normal = Some(ai);
                    }
                    Checked::Valid(Semantic::TexCoords(n)) if *n == uv_set => {
                        let ok = float_or(a, true, &[ComponentType::U8, ComponentType::U16], true);
                        if a.ty != Type::Vec2 || !ok {
                            return Err(ctx.invalid(
                                ap,
                                format!("{name} must be a VEC2 of floats or normalized unsigned bytes/shorts"),
                            ));
                        }
                        p.uv = Some(ai);
                    }
                    _ => {}
                }
            }
            if let Some(ii) = prim.indices {
                let ip = format!("{pp}/indices");
                let ii = ii.value();
                let a = lookup(accessors, ii, &ip, ctx)?;
                let int = matches!(
                    a.component,
                    ComponentType::U8 | ComponentType::U16 | ComponentType::U32
                );
                if a.ty != Type::Scalar || !int || a.normalized {
                    return Err(ctx.invalid(
                        ip,
                        format!("accessor {ii} must be a SCALAR of unsigned byte, short or int"),
                    ));
                }
                if let Some((_, _, stride)) = a.source {
                    if stride != data::component_size(a.component) {
                        return Err(ctx.invalid(
                            ip,
                            format!("accessor {ii}: index data must be tightly packed"),
                        ));
                    }
                }
                p.indices = Some(ii);
            }
            if let Some(mi) = prim.material {
                let mi = mi.value();
                if mi >= doc.materials.len() {
                    return Err(ctx.unresolved(
                        format!("{pp}/material"),
                        "/materials",
                        mi,
                        doc.materials.len(),
                    ));
                }
                p.material = Some(mi);
            }
            p.mode = match prim.mode {
                Checked::Valid(mode) => mode,
                Checked::Invalid => {
                    return Err(ctx.invalid(format!("{pp}/mode"), "unknown mode".into()))
                }
            };
            for (t, target) in prim.targets.iter().flatten().enumerate() {
                for (name, idx) in [
                    ("POSITION", target.positions),
                    ("NORMAL", target.normals),
                    ("TANGENT", target.tangents),
                ] {
                    if let Some(i) = idx {
                        if i.value() >= accessors.len() {
                            return Err(ctx.unresolved(
                                format!("{pp}/targets/{t}/{name}"),
                                "/accessors",
                                i.value(),
                                accessors.len(),
                            ));
                        }
                    }
                }
            }
            prims.push(p);
        }
        out.push(prims);
    }
    Ok(out)
}
