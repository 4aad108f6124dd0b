//! glTF 2.0 loading: .gltf (external or data-URI buffers) and .glb, flattened into a [`Scene`].
//!
//! The pipeline, one phase per function, each checking what the next relies on:
//!
//! ```text
//! container (glb::parse) -> document (doc::parse) -> buffers (data::resolve_buffers)
//!   -> buffer views (data::check_views) -> accessors (data::check_accessors)
//!   -> materials -> meshes (check_meshes) -> node hierarchy (check_hierarchy)
//!   -> scene roots -> flatten (instances; mesh data read on first use)
//! ```
//!
//! Nothing is read from a buffer before the range has been checked against its buffer view and
//! the view against its buffer, so no input can make the loader index out of bounds. Any error
//! aborts the load: there are no partial scenes.

mod data;
mod doc;
pub(crate) mod glb;

use std::borrow::Cow;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

use glam::{DAffine3, DQuat, Vec3};
use gltf::json;
use gltf::json::accessor::{ComponentType, Type};
use gltf::json::mesh::{Mode, Semantic};
use gltf::json::validation::Checked;

use crate::error::SceneError;
use crate::scene::{
    GltfCounts, Material, MaterialClass, MaterialId, MeshId, Scene, SceneBuilder, SceneSource,
    Transform, Vertex,
};
use data::{lookup, Reader, Slot};
use doc::Doc;

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
}

impl Default for Limits {
    /// 2^26 vertices (2 GiB of vertex data), 2^28 indices (1 GiB), 2^24 instances (about
    /// 2 GiB of instances: a 1 MB file can instance a 10k-primitive mesh from 10k nodes).
    fn default() -> Self {
        Limits {
            max_vertices: 1 << 26,
            max_indices: 1 << 28,
            max_instances: 1 << 24,
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
    add_materials(&doc, &mut builder, &ctx)?;
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
        mirrored: HashMap::new(),
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

fn add_materials(doc: &Doc, builder: &mut SceneBuilder, ctx: &Ctx) -> Result<(), SceneError> {
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
        builder.add_material(Material {
            base_color: color,
            class,
            double_sided: m.double_sided,
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
                    Checked::Valid(Semantic::TexCoords(0)) => {
                        let ok = float_or(a, true, &[ComponentType::U8, ComponentType::U16], true);
                        if a.ty != Type::Vec2 || !ok {
                            return Err(ctx.invalid(
                                ap,
                                "TEXCOORD_0 must be a VEC2 of floats or normalized unsigned bytes/shorts".into(),
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

/// Checks node references and that the hierarchy is a forest; returns each node's parent.
fn check_hierarchy(doc: &Doc, ctx: &Ctx) -> Result<Vec<Option<usize>>, SceneError> {
    let n = doc.nodes.len();
    let mut parent: Vec<Option<usize>> = vec![None; n];
    for (i, node) in doc.nodes.iter().enumerate() {
        if let Some(m) = node.mesh {
            if m.value() >= doc.meshes.len() {
                return Err(ctx.unresolved(
                    format!("/nodes/{i}/mesh"),
                    "/meshes",
                    m.value(),
                    doc.meshes.len(),
                ));
            }
        }
        for (j, c) in node.children.iter().flatten().enumerate() {
            let c = c.value();
            let p = format!("/nodes/{i}/children/{j}");
            if c >= n {
                return Err(ctx.unresolved(p, "/nodes", c, n));
            }
            if let Some(other) = parent[c] {
                return Err(ctx.hierarchy(p, format!("node {c} already has parent {other}")));
            }
            parent[c] = Some(i);
        }
    }
    // With at most one parent each, a loop is a parent chain that comes back to itself.
    // 0 = unvisited, 1 = on the current chain, 2 = known to reach a root.
    let mut state = vec![0u8; n];
    let mut chain = Vec::new();
    for start in 0..n {
        let mut cur = Some(start);
        while let Some(i) = cur {
            match state[i] {
                2 => break,
                1 => {
                    return Err(ctx.hierarchy(
                        format!("/nodes/{i}"),
                        "the node is its own ancestor (a loop)".into(),
                    ))
                }
                _ => {
                    state[i] = 1;
                    chain.push(i);
                    cur = parent[i];
                }
            }
        }
        for i in chain.drain(..) {
            state[i] = 2;
        }
    }
    Ok(parent)
}

/// The root nodes to draw: the default scene's, scene 0's, or every root node if there is no
/// scene at all (glTF leaves that case to the application).
fn scene_roots(doc: &Doc, parent: &[Option<usize>], ctx: &Ctx) -> Result<Vec<usize>, SceneError> {
    for (s, scene) in doc.scenes.iter().enumerate() {
        let Some(nodes) = &scene.nodes else { continue };
        if nodes.is_empty() {
            return Err(ctx.invalid(format!("/scenes/{s}/nodes"), "empty array".into()));
        }
        let mut listed = vec![false; doc.nodes.len()];
        for (j, &node) in nodes.iter().enumerate() {
            let i = node as usize;
            let p = format!("/scenes/{s}/nodes/{j}");
            if i >= doc.nodes.len() {
                return Err(ctx.unresolved(p, "/nodes", i, doc.nodes.len()));
            }
            // A root listed twice would be drawn twice (and a long list of one big subtree
            // would multiply the instance count): the schema's uniqueItems.
            if std::mem::replace(&mut listed[i], true) {
                return Err(ctx.invalid(p, format!("node {i} is listed twice")));
            }
            if let Some(par) = parent[i] {
                return Err(ctx.invalid(
                    p,
                    format!("node {i} is not a root node (its parent is {par})"),
                ));
            }
        }
    }
    let selected = match doc.scene {
        Some(s) => {
            let s = usize::try_from(s).unwrap_or(usize::MAX);
            if s >= doc.scenes.len() {
                return Err(ctx.unresolved("/scene".into(), "/scenes", s, doc.scenes.len()));
            }
            Some(s)
        }
        None if !doc.scenes.is_empty() => Some(0),
        None => None,
    };
    Ok(match selected {
        Some(s) => doc.scenes[s]
            .nodes
            .iter()
            .flatten()
            .map(|&n| n as usize)
            .collect(),
        None => {
            log::info!("{}: no scene defined; drawing every root node", ctx.file);
            (0..doc.nodes.len())
                .filter(|&i| parent[i].is_none())
                .collect()
        }
    })
}

fn local_transform(node: &json::Node, i: usize, ctx: &Ctx) -> Result<DAffine3, SceneError> {
    let p = format!("/nodes/{i}");
    let has_trs = node.translation.is_some() || node.rotation.is_some() || node.scale.is_some();
    if let Some(m) = node.matrix {
        if has_trs {
            return Err(ctx.invalid(
                format!("{p}/matrix"),
                "both a matrix and translation/rotation/scale".into(),
            ));
        }
        if !m.iter().all(|x| x.is_finite()) {
            return Err(ctx.non_finite(format!("{p}/matrix"), format!("{m:?}")));
        }
        // Column-major; the bottom row must be (0, 0, 0, 1) for an affine transform.
        if m[3] != 0.0 || m[7] != 0.0 || m[11] != 0.0 || m[15] != 1.0 {
            return Err(ctx.invalid(
                format!("{p}/matrix"),
                "not an affine transform (bottom row is not 0, 0, 0, 1)".into(),
            ));
        }
        let d = |k: usize| f64::from(m[k]);
        return Ok(DAffine3::from_cols_array(&[
            d(0),
            d(1),
            d(2),
            d(4),
            d(5),
            d(6),
            d(8),
            d(9),
            d(10),
            d(12),
            d(13),
            d(14),
        ]));
    }
    let t = node.translation.unwrap_or([0.0; 3]);
    if !t.iter().all(|x| x.is_finite()) {
        return Err(ctx.non_finite(format!("{p}/translation"), format!("{t:?}")));
    }
    let s = node.scale.unwrap_or([1.0; 3]);
    if !s.iter().all(|x| x.is_finite()) {
        return Err(ctx.non_finite(format!("{p}/scale"), format!("{s:?}")));
    }
    let r = node.rotation.map_or([0.0, 0.0, 0.0, 1.0], |q| q.0);
    if !r.iter().all(|x| x.is_finite()) {
        return Err(ctx.non_finite(format!("{p}/rotation"), format!("{r:?}")));
    }
    let q = DQuat::from_xyzw(
        f64::from(r[0]),
        f64::from(r[1]),
        f64::from(r[2]),
        f64::from(r[3]),
    );
    let len = q.length();
    // Exporters write quaternions rounded to f32 text; accept those, renormalised.
    if (len - 1.0).abs() > 1e-3 {
        return Err(ctx.invalid(
            format!("{p}/rotation"),
            format!("not a unit quaternion (length {len})"),
        ));
    }
    Ok(DAffine3::from_scale_rotation_translation(
        Vec3::from_array(s).as_dvec3(),
        q / len,
        Vec3::from_array(t).as_dvec3(),
    ))
}

/// Flattening state: the builder, and glTF meshes converted on first use.
struct Flatten<'x, 'd, 'a> {
    doc: &'x Doc,
    reader: &'x Reader<'d, 'a>,
    prims: &'x [Vec<Prim>],
    limits: &'x Limits,
    ctx: &'x Ctx,
    builder: SceneBuilder,
    mesh_cache: Vec<Option<Vec<MeshId>>>,
    /// Mesh -> its copy with reversed winding, for mirroring nodes (made on first use).
    mirrored: HashMap<MeshId, MeshId>,
    /// (POSITION, NORMAL, TEXCOORD_0) accessors -> (vertex offset, count): primitives that share
    /// vertex accessors share vertices.
    vertex_cache: HashMap<(usize, usize, Option<usize>), (u32, u32)>,
    /// (POSITION, TEXCOORD_0) accessors -> their vertices, for primitives without normals (each
    /// is de-indexed into flat-shaded corners; the source is read once however many share it).
    flat_source_cache: HashMap<(usize, Option<usize>), std::rc::Rc<Vec<Vertex>>>,
    /// Vertices read from accessors so far: bounded like the vertices kept, so a small file
    /// cannot make the loader read (or zero-fill) far more than it keeps.
    vertices_read: usize,
    default_material: Option<MaterialId>,
    material_count: usize,
}

impl Flatten<'_, '_, '_> {
    fn flatten(&mut self, roots: &[usize]) -> Result<usize, SceneError> {
        let mut stack: Vec<(usize, DAffine3)> = roots
            .iter()
            .rev()
            .map(|&r| (r, DAffine3::IDENTITY))
            .collect();
        let mut visited = 0usize;
        while let Some((i, parent_world)) = stack.pop() {
            visited += 1;
            let Some(node) = self.doc.nodes.get(i) else {
                return Err(self.ctx.unresolved(
                    format!("/nodes/{i}"),
                    "/nodes",
                    i,
                    self.doc.nodes.len(),
                ));
            };
            let world = parent_world * local_transform(node, i, self.ctx)?;
            if !(world.matrix3.is_finite() && world.translation.is_finite()) {
                return Err(self
                    .ctx
                    .non_finite(format!("/nodes/{i}"), "world transform overflows".into()));
            }
            if let Some(m) = node.mesh {
                let mut ids = self.mesh(m.value())?;
                // glTF: a mirroring transform (negative determinant) makes front faces
                // clockwise; its instances draw a copy with the winding reversed.
                if world.matrix3.determinant() < 0.0 {
                    ids = self.mirrored_meshes(&ids, &format!("/nodes/{i}"))?;
                }
                let transform = Transform::from_daffine(&world);
                for id in ids {
                    if self.builder.instance_count() >= self.limits.max_instances {
                        return Err(self.ctx.limit(
                            format!("/nodes/{i}"),
                            "instances",
                            self.builder.instance_count() + 1,
                            self.limits.max_instances,
                        ));
                    }
                    self.builder
                        .add_instance(transform, id)
                        .map_err(|e| match e {
                            SceneError::NonFinite { what, .. } => self.ctx.non_finite(
                                format!("/nodes/{i}"),
                                format!("instance of mesh {}: {what}", m.value()),
                            ),
                            other => other,
                        })?;
                }
            }
            if node.skin.is_some() {
                log::debug!(
                    "{}: /nodes/{i}: skin ignored (bind pose drawn)",
                    self.ctx.file
                );
            }
            for c in node.children.iter().flatten().rev() {
                stack.push((c.value(), world));
            }
        }
        Ok(visited)
    }

    /// The mirrored copies of `ids` (made once per mesh; they count against the index limit).
    fn mirrored_meshes(
        &mut self,
        ids: &[MeshId],
        pointer: &str,
    ) -> Result<Vec<MeshId>, SceneError> {
        let mut out = Vec::with_capacity(ids.len());
        for &id in ids {
            if let Some(&m) = self.mirrored.get(&id) {
                out.push(m);
                continue;
            }
            let count = self.builder.mesh_index_count(id).unwrap_or(0) as usize;
            self.check_limit(
                pointer,
                "indices",
                self.builder.index_count(),
                count,
                self.index_limit(),
            )?;
            let Some(m) = self.builder.mirrored_mesh(id) else {
                return Err(self
                    .ctx
                    .invalid(pointer.to_string(), format!("mesh {} is missing", id.0)));
            };
            self.mirrored.insert(id, m);
            out.push(m);
        }
        Ok(out)
    }

    /// The tilegraph meshes of glTF mesh `m`, converting it on first use.
    fn mesh(&mut self, m: usize) -> Result<Vec<MeshId>, SceneError> {
        if let Some(Some(ids)) = self.mesh_cache.get(m) {
            return Ok(ids.clone());
        }
        let prims = self.prims.get(m).cloned().unwrap_or_default();
        let mut ids = Vec::with_capacity(prims.len());
        for (pi, prim) in prims.iter().enumerate() {
            if let Some(id) = self.primitive(m, pi, prim)? {
                ids.push(id);
            }
        }
        if let Some(slot) = self.mesh_cache.get_mut(m) {
            *slot = Some(ids.clone());
        }
        Ok(ids)
    }

    fn material(&mut self, index: Option<usize>) -> MaterialId {
        match index {
            Some(i) if i < self.material_count => MaterialId(i as u32),
            _ => *self.default_material.get_or_insert_with(|| {
                // glTF's default material: white, opaque, single-sided.
                self.builder.add_material(Material::opaque([1.0; 4]))
            }),
        }
    }

    fn check_finite(
        &self,
        values: &[f32],
        comps: usize,
        accessor: usize,
        what: &str,
        pp: &str,
    ) -> Result<(), SceneError> {
        match values.iter().position(|v| !v.is_finite()) {
            None => Ok(()),
            Some(k) => Err(self.ctx.non_finite(
                format!("/accessors/{accessor}"),
                format!(
                    "{what} element {} (used by {pp}) is {}",
                    k / comps,
                    values[k]
                ),
            )),
        }
    }

    fn primitive(
        &mut self,
        m: usize,
        pi: usize,
        prim: &Prim,
    ) -> Result<Option<MeshId>, SceneError> {
        let pp = format!("/meshes/{m}/primitives/{pi}");
        if matches!(
            prim.mode,
            Mode::Points | Mode::Lines | Mode::LineLoop | Mode::LineStrip
        ) {
            log::warn!(
                "{}: {pp}: mode {:?} is not triangles; skipped",
                self.ctx.file,
                prim.mode
            );
            return Ok(None);
        }
        let Some(pos) = prim.position else {
            log::warn!("{}: {pp}: no POSITION; skipped", self.ctx.file);
            return Ok(None);
        };
        let n = self.reader.accessor(pos).map_or(0, |a| a.count);
        let raw = match prim.indices {
            Some(ii) => {
                let count = self.reader.accessor(ii).map_or(0, |a| a.count);
                // Strips and fans triple their indices: the limit applies to what they expand
                // to, checked before anything is read.
                self.check_limit(
                    &pp,
                    "indices",
                    self.builder.index_count(),
                    count.max(triangle_index_count(count, prim.mode)),
                    self.index_limit(),
                )?;
                let raw = self.reader.read_indices(ii)?;
                if let Some((position, &index)) =
                    raw.iter().enumerate().find(|(_, &i)| i as usize >= n)
                {
                    return Err(SceneError::IndexOutOfRange {
                        file: self.ctx.file.clone(),
                        pointer: format!("{pp}/indices"),
                        index: u64::from(index),
                        position,
                        vertex_count: n,
                    });
                }
                raw
            }
            None => {
                self.check_limit(
                    &pp,
                    "indices",
                    self.builder.index_count(),
                    n.max(triangle_index_count(n, prim.mode)),
                    self.index_limit(),
                )?;
                (0..n as u32).collect()
            }
        };
        let tris = triangles(&raw, prim.mode);
        if raw.len() > tris.len() && prim.mode == Mode::Triangles {
            log::warn!(
                "{}: {pp}: {} trailing indices do not form a triangle; dropped",
                self.ctx.file,
                raw.len() - tris.len()
            );
        }
        if tris.is_empty() {
            log::warn!("{}: {pp}: no triangle; skipped", self.ctx.file);
            return Ok(None);
        }
        let material = self.material(prim.material);

        match prim.normal {
            Some(normal) => {
                let key = (pos, normal, prim.uv);
                let (offset, count) = match self.vertex_cache.get(&key) {
                    Some(&range) => range,
                    None => {
                        let vertices = self.read_vertices(pos, Some(normal), prim.uv, &pp)?;
                        let range = self.push_vertices(&vertices, &pp)?;
                        self.vertex_cache.insert(key, range);
                        range
                    }
                };
                Ok(Some(
                    self.builder.push_mesh_range(offset, count, &tris, material),
                ))
            }
            None => {
                // glTF: without normals, flat normals. Flat shading needs a vertex per corner:
                // check that many against the vertex limit before building them.
                let limit = self.limits.max_vertices.min(i32::MAX as usize);
                self.check_limit(
                    &pp,
                    "vertices",
                    self.builder.vertex_count(),
                    tris.len(),
                    limit,
                )?;
                let shared = match self.flat_source_cache.get(&(pos, prim.uv)) {
                    Some(v) => v.clone(),
                    None => {
                        let v = std::rc::Rc::new(self.read_vertices(pos, None, prim.uv, &pp)?);
                        self.flat_source_cache.insert((pos, prim.uv), v.clone());
                        v
                    }
                };
                let mut vertices = Vec::with_capacity(tris.len());
                for t in tris.chunks_exact(3) {
                    let p = |k: usize| Vec3::from_array(shared[t[k] as usize].position);
                    let normal = (p(1) - p(0))
                        .cross(p(2) - p(0))
                        .normalize_or(Vec3::Y)
                        .to_array();
                    for &k in t {
                        vertices.push(Vertex {
                            normal,
                            ..shared[k as usize]
                        });
                    }
                }
                let (offset, count) = self.push_vertices(&vertices, &pp)?;
                let seq: Vec<u32> = (0..count).collect();
                Ok(Some(
                    self.builder.push_mesh_range(offset, count, &seq, material),
                ))
            }
        }
    }

    fn check_limit(
        &self,
        pp: &str,
        what: &'static str,
        have: usize,
        add: usize,
        limit: usize,
    ) -> Result<(), SceneError> {
        let total = have.saturating_add(add);
        if total > limit {
            return Err(self.ctx.limit(pp.to_string(), what, total, limit));
        }
        Ok(())
    }

    /// Mesh ranges are u32 (`first_index`, `index_count`), whatever the caller's limit.
    fn index_limit(&self) -> usize {
        self.limits.max_indices.min(u32::MAX as usize)
    }

    fn push_vertices(&mut self, vertices: &[Vertex], pp: &str) -> Result<(u32, u32), SceneError> {
        // Mesh offsets are i32 (VkDrawIndexedIndirectCommand::vertexOffset).
        let limit = self.limits.max_vertices.min(i32::MAX as usize);
        self.check_limit(
            pp,
            "vertices",
            self.builder.vertex_count(),
            vertices.len(),
            limit,
        )?;
        Ok((self.builder.push_vertices(vertices), vertices.len() as u32))
    }

    fn read_vertices(
        &mut self,
        pos: usize,
        normal: Option<usize>,
        uv: Option<usize>,
        pp: &str,
    ) -> Result<Vec<Vertex>, SceneError> {
        let n = self.reader.accessor(pos).map_or(0, |a| a.count);
        let limit = self.limits.max_vertices.min(i32::MAX as usize);
        self.check_limit(pp, "vertices", self.builder.vertex_count(), n, limit)?;
        self.check_limit(pp, "vertices read", self.vertices_read, n, limit)?;
        self.vertices_read += n;
        let positions = self.reader.read_f32(pos, 3)?;
        self.check_finite(&positions, 3, pos, "POSITION", pp)?;
        let normals = match normal {
            Some(a) => {
                let v = self.reader.read_f32(a, 3)?;
                self.check_finite(&v, 3, a, "NORMAL", pp)?;
                Some(v)
            }
            None => None,
        };
        let uvs = match uv {
            Some(a) => {
                let v = self.reader.read_f32(a, 2)?;
                self.check_finite(&v, 2, a, "TEXCOORD_0", pp)?;
                Some(v)
            }
            None => None,
        };
        Ok((0..n)
            .map(|i| Vertex {
                position: [positions[3 * i], positions[3 * i + 1], positions[3 * i + 2]],
                normal: normals
                    .as_ref()
                    .map_or([0.0; 3], |v| [v[3 * i], v[3 * i + 1], v[3 * i + 2]]),
                uv: uvs.as_ref().map_or([0.0; 2], |v| [v[2 * i], v[2 * i + 1]]),
            })
            .collect())
    }
}

/// Triangle list from indices in `mode` (triangles, strip or fan). Caller skips other modes.
/// How many indices [`triangles`] makes of `len` indices.
fn triangle_index_count(len: usize, mode: Mode) -> usize {
    match mode {
        Mode::TriangleStrip | Mode::TriangleFan => len.saturating_sub(2).saturating_mul(3),
        _ => len / 3 * 3,
    }
}

fn triangles(raw: &[u32], mode: Mode) -> Vec<u32> {
    match mode {
        Mode::TriangleStrip => {
            let mut out = Vec::with_capacity(raw.len().saturating_sub(2) * 3);
            for i in 0..raw.len().saturating_sub(2) {
                // glTF: triangle i is (v[i], v[i + 1 + i % 2], v[i + 2 - i % 2]), which keeps
                // every triangle's winding the same as the first's.
                if i % 2 == 0 {
                    out.extend_from_slice(&[raw[i], raw[i + 1], raw[i + 2]]);
                } else {
                    out.extend_from_slice(&[raw[i], raw[i + 2], raw[i + 1]]);
                }
            }
            out
        }
        Mode::TriangleFan => {
            let mut out = Vec::with_capacity(raw.len().saturating_sub(2) * 3);
            for i in 1..raw.len().saturating_sub(1) {
                out.extend_from_slice(&[raw[i], raw[i + 1], raw[0]]);
            }
            out
        }
        _ => raw[..raw.len() / 3 * 3].to_vec(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn strips_and_fans_become_lists_with_the_spec_winding() {
        assert_eq!(
            triangles(&[0, 1, 2, 3], Mode::TriangleStrip),
            vec![0, 1, 2, 1, 3, 2]
        );
        assert_eq!(
            triangles(&[0, 1, 2, 3], Mode::TriangleFan),
            vec![1, 2, 0, 2, 3, 0]
        );
        assert_eq!(triangles(&[0, 1, 2, 3], Mode::Triangles), vec![0, 1, 2]);
        assert!(triangles(&[0, 1], Mode::TriangleStrip).is_empty());
        assert!(triangles(&[0], Mode::TriangleFan).is_empty());
    }
}
