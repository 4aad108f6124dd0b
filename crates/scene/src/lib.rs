//! tilegraph-scene: scenes as flat, GPU-ready arrays. Pure Rust, no Vulkan.
//!
//! - **glTF 2.0** (.gltf with external or data-URI buffers, .glb) flattened into instances over
//!   one shared vertex buffer ([`Vertex`], 32 bytes) and one shared `u32` index buffer. A glTF
//!   primitive is a tilegraph [`Mesh`]; a node instancing a glTF mesh of k primitives becomes k
//!   [`Instance`]s. Bad input is a typed [`SceneError`] naming the file and the JSON pointer of
//!   the element (`/accessors/3`, `/meshes/0/primitives/1/indices`), never a panic and never a
//!   partial scene.
//! - **Procedural worlds** ([`ProceduralKind`]): `city`, `forest`, `field`, `interior`,
//!   deterministic from a seed, a few hundred to millions of instances, each with a default test
//!   [`CameraPath`].
//! - **Cameras** ([`Camera`], [`Projection`], [`CameraPath`]): Vulkan clip space with the y flip,
//!   reverse-Z with an infinite far plane by default ([`DepthConvention`]), fly-through splines,
//!   orbits, JSON camera paths, previous-frame matrices for reprojection.
//! - **Large worlds**: instance translations are f64; an instance's GPU record
//!   ([`GpuInstance`]) holds them split into two f32 ([`SplitPoint`]), and the shaders subtract
//!   the split eye to place it camera-relative ([`GpuInstance::relative`] on the CPU), to pair
//!   with [`Camera::view_relative`] (eye at the origin).
//! - **Changes by handle** ([`InstanceHandle`], [`MeshHandle`]): instances added, removed,
//!   moved in batches and hidden, meshes streamed in and out, each written to a journal a
//!   renderer follows to upload only what changed ([`Scene::changes_since`]); draw buckets
//!   ([`DrawBuckets`]) and loose grids ([`LooseGrid`]) kept from change to change.
//!
//! # Loading by spec (what the CLI calls)
//!
//! ```no_run
//! # fn main() -> Result<(), tilegraph_scene::SceneError> {
//! let helmet = tilegraph_scene::load("scenes/FlightHelmet/FlightHelmet.gltf")?;
//! let city = tilegraph_scene::load("city:1M:42")?; // kind[:size[:seed]]
//! let demo = tilegraph_scene::default_scene()?;    // small embedded city, no file needed
//! println!("{}", city.info());                      // a table; serde_json gives the JSON
//! # Ok(()) }
//! ```
//!
//! A spec is a path to a `.gltf` / `.glb` file (or any existing file), or
//! `city|forest|field|interior|maze[:size[:seed]]` where size is an instance count with an optional
//! `k` (thousand) or `M` (million) suffix (default 10k) and seed is a u64 (default 1), or
//! `default` for [`default_scene`]. See docs/SCENES.md for the formats and conventions.

mod bounds;
mod camera;
pub mod clusters;
pub mod cone;
mod error;
pub mod export;
mod gltf_load;
pub mod motion;
pub mod procedural;
mod scene;
pub mod test_data;
pub mod texture;

use std::path::Path;

use glam::DVec3;

pub use bounds::{Aabb, DAabb, DSphere};
pub use camera::{Camera, CameraFrame, CameraPath, FrameMatrices, PathKey, Waypoint};
pub use error::SceneError;
pub use gltf_load::{
    load_gltf, load_gltf_bytes, FileResolver, Limits, MemoryResources, NoResources,
    ResourceResolver,
};
pub use motion::{Motion, MotionParams};
pub use procedural::seed_grid;
pub use procedural::{generate, ProceduralKind, ProceduralParams};
pub use scene::{
    BoundsInfo, CellRun, Change, ClassCounts, Degenerate, DrawBuckets, DrawGroup, GltfCounts,
    GpuInstance, GpuLod, GpuMaterial, GpuMesh, GridMember, Instance, InstanceBounds, InstanceFlags,
    InstanceHandle, InstanceId, LooseGrid, Material, MaterialClass, MaterialId, Mesh, MeshHandle,
    MeshId, Overlap, RelativeInstance, Scene, SceneBuilder, SceneCursor, SceneInfo, SceneSource,
    SplitPoint, Transform, Vertex, DRAW_LISTS, MAX_LODS,
};
pub use texture::{Texture, TextureId};
/// Shared with the culling references and the passes (tilegraph-types); re-exported so scene
/// users name them from here as before.
pub use tilegraph_types::{DepthConvention, Projection};

/// Size and seed of the embedded default scene.
pub const DEFAULT_SCENE: ProceduralParams = ProceduralParams {
    size: 2_000,
    seed: 1,
};

/// Options for [`load_with`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LoadOptions {
    /// Caps on what a glTF file may make the loader allocate.
    pub limits: Limits,
    /// Size and seed of a procedural spec that gives none.
    pub procedural: ProceduralParams,
    /// Where the scene's origin goes in the world: the whole scene (and its camera path) is
    /// moved by this offset, in f64. `DVec3::new(1e6, 0.0, 0.0)` puts it 10^6 m out.
    pub origin: DVec3,
}

impl Default for LoadOptions {
    fn default() -> Self {
        LoadOptions {
            limits: Limits::default(),
            procedural: ProceduralParams::default(),
            origin: DVec3::ZERO,
        }
    }
}

/// The embedded default scene: a small `city` that needs no file (the demo's scene).
pub fn default_scene() -> Result<Scene, SceneError> {
    generate(ProceduralKind::City, DEFAULT_SCENE)
}

/// Loads a scene from a spec with default options. See the crate docs for the spec grammar.
pub fn load(spec: &str) -> Result<Scene, SceneError> {
    load_with(spec, &LoadOptions::default())
}

/// The most materials `@materials:N` spreads a scene over.
pub const MAX_SPREAD_MATERIALS: u32 = 4096;

/// Loads a scene from a spec: a glTF path, `kind[:size[:seed]]`, or `default`; with `@one-mesh`
/// after it, baked into one mesh per material ([`Scene::one_mesh_per_material`]: a level as
/// many engines export it); with `@materials:N`, its opaque instances spread over `N` materials
/// ([`Scene::with_spread_materials`]: what material classification is measured on); with
/// `@dense:L`, every triangle split into `4^L` ([`Scene::densified`]); with `@draws`, a mesh per
/// instance ([`Scene::mesh_per_instance`]) — the bottleneck finder's constructed cases.
pub fn load_with(spec: &str, options: &LoadOptions) -> Result<Scene, SceneError> {
    load_variant(spec, options, 0)
}

/// The most suffixes one spec chains (each makes a whole new scene from the one before).
pub const MAX_SPEC_SUFFIXES: usize = 8;

/// [`load_with`] after `depth` suffixes were taken off `spec`.
fn load_variant(spec: &str, options: &LoadOptions, depth: usize) -> Result<Scene, SceneError> {
    let load_with = |base: &str, options: &LoadOptions| {
        if depth >= MAX_SPEC_SUFFIXES {
            return Err(SceneError::BadSpec {
                spec: spec.to_string(),
                reason: format!("more than {MAX_SPEC_SUFFIXES} @ suffixes"),
            });
        }
        load_variant(base, options, depth + 1)
    };
    if let Some(level) = spec.strip_suffix("@one-mesh") {
        return load_with(level, options)?.one_mesh_per_material();
    }
    if let Some(rest) = spec.strip_prefix("seed-grid") {
        return seed_grid_spec(spec, rest);
    }
    if let Some(base) = spec.strip_suffix("@draws") {
        return load_with(base, options)?.mesh_per_instance();
    }
    if let Some((base, level)) = spec.rsplit_once("@dense:") {
        let level = level
            .parse::<u32>()
            .ok()
            .filter(|l| (1..=5).contains(l))
            .ok_or_else(|| SceneError::BadSpec {
                spec: spec.to_string(),
                reason: format!("@dense:{level}: a subdivision level from 1 to 5"),
            })?;
        return load_with(base, options)?.densified(level);
    }
    if let Some((base, n)) = spec.rsplit_once("@materials:") {
        let count = n
            .parse::<u32>()
            .ok()
            .filter(|c| (1..=MAX_SPREAD_MATERIALS).contains(c))
            .ok_or_else(|| SceneError::BadSpec {
                spec: spec.to_string(),
                reason: format!(
                    "@materials:{n}: a material count from 1 to {MAX_SPREAD_MATERIALS}"
                ),
            })?;
        return load_with(base, options)?.with_spread_materials(count);
    }
    let mut scene = match parse_spec(spec, options)? {
        Spec::File(path) => load_gltf(Path::new(path), &options.limits)?,
        Spec::Procedural(kind, params) => generate(kind, params)?,
    };
    if options.origin != DVec3::ZERO {
        scene.translate(options.origin);
    }
    Ok(scene)
}

/// `seed-grid[:N[:DETAIL]]` ([`seed_grid::generate`]; `rest` is what follows `seed-grid`).
fn seed_grid_spec(spec: &str, rest: &str) -> Result<Scene, SceneError> {
    let bad = || SceneError::BadSpec {
        spec: spec.to_string(),
        reason: "seed-grid[:N[:DETAIL]]: whole numbers".into(),
    };
    let mut grid = seed_grid::SeedGrid::default();
    if !rest.is_empty() {
        let mut parts = rest.strip_prefix(':').ok_or_else(bad)?.split(':');
        if let Some(n) = parts.next() {
            grid.n = n.parse().map_err(|_| bad())?;
        }
        if let Some(d) = parts.next() {
            grid.detail = d.parse().map_err(|_| bad())?;
        }
        if parts.next().is_some() {
            return Err(bad());
        }
    }
    seed_grid::generate(grid, 1)
}

#[derive(Debug, PartialEq)]
enum Spec<'a> {
    File(&'a str),
    Procedural(ProceduralKind, ProceduralParams),
}

fn parse_count(s: &str) -> Option<u64> {
    let s = s.replace('_', "");
    let (digits, mult) = match s.as_bytes().last()? {
        b'k' | b'K' => (&s[..s.len() - 1], 1_000),
        b'm' | b'M' => (&s[..s.len() - 1], 1_000_000),
        _ => (&s[..], 1),
    };
    digits.parse::<u64>().ok()?.checked_mul(mult)
}

fn parse_spec<'a>(spec: &'a str, options: &LoadOptions) -> Result<Spec<'a>, SceneError> {
    let lower = spec.to_ascii_lowercase();
    if lower.ends_with(".gltf") || lower.ends_with(".glb") || Path::new(spec).is_file() {
        return Ok(Spec::File(spec));
    }
    let bad = |reason: String| SceneError::BadSpec {
        spec: spec.to_string(),
        reason,
    };
    if spec == "default" {
        return Ok(Spec::Procedural(ProceduralKind::City, DEFAULT_SCENE));
    }
    if Path::new(spec).is_dir() {
        let mut found: Vec<String> = std::fs::read_dir(spec)
            .map(|entries| {
                entries
                    .filter_map(Result::ok)
                    .map(|e| e.file_name().to_string_lossy().into_owned())
                    .filter(|n| {
                        let n = n.to_ascii_lowercase();
                        n.ends_with(".gltf") || n.ends_with(".glb")
                    })
                    .collect()
            })
            .unwrap_or_default();
        found.sort();
        return Err(bad(if found.is_empty() {
            "is a directory, and holds no .gltf or .glb file".into()
        } else {
            format!("is a directory; the glTF files in it: {}", found.join(", "))
        }));
    }
    let mut parts = spec.split(':');
    let name = parts.next().unwrap_or_default();
    let Ok(kind) = name.parse::<ProceduralKind>() else {
        return Err(bad(
            "not a .gltf/.glb file, an existing file, `default`, or one of \
             city|forest|field|interior|maze[:size[:seed]]"
                .into(),
        ));
    };
    let mut params = options.procedural;
    if let Some(size) = parts.next() {
        let n = parse_count(size)
            .ok_or_else(|| bad(format!("size `{size}` is not a count (e.g. 5000, 50k, 1M)")))?;
        if n == 0 {
            return Err(bad(format!(
                "size `{size}`: a scene needs at least one instance"
            )));
        }
        params.size = usize::try_from(n).map_err(|_| bad(format!("size {n} is too large")))?;
    }
    if let Some(seed) = parts.next() {
        params.seed = seed
            .parse()
            .map_err(|_| bad(format!("seed `{seed}` is not an unsigned integer")))?;
    }
    if let Some(extra) = parts.next() {
        return Err(bad(format!("unexpected `:{extra}` after the seed")));
    }
    Ok(Spec::Procedural(kind, params))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn specs_parse() {
        let o = LoadOptions::default();
        assert_eq!(parse_spec("a/b.GLB", &o).unwrap(), Spec::File("a/b.GLB"));
        assert_eq!(
            parse_spec("city:1M:42", &o).unwrap(),
            Spec::Procedural(
                ProceduralKind::City,
                ProceduralParams {
                    size: 1_000_000,
                    seed: 42
                }
            )
        );
        assert_eq!(
            parse_spec("forest:50k", &o).unwrap(),
            Spec::Procedural(
                ProceduralKind::Forest,
                ProceduralParams {
                    size: 50_000,
                    seed: 1
                }
            )
        );
        assert_eq!(
            parse_spec("interior", &o).unwrap(),
            Spec::Procedural(ProceduralKind::Interior, o.procedural)
        );
        for bad in [
            "town",
            "city:abc",
            "city:10:x",
            "city:10:1:2",
            "city:99999999999999999999M",
            "city:0",
            "",
        ] {
            assert!(
                matches!(parse_spec(bad, &o), Err(SceneError::BadSpec { .. })),
                "{bad}"
            );
        }
    }

    #[test]
    fn a_directory_names_the_gltf_files_inside() {
        let dir = std::env::temp_dir().join(format!("tilegraph-spec-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("b.glb"), b"").unwrap();
        std::fs::write(dir.join("a.gltf"), b"").unwrap();
        std::fs::write(dir.join("notes.txt"), b"").unwrap();
        let spec = dir.to_string_lossy().into_owned();
        let e = parse_spec(&spec, &LoadOptions::default()).unwrap_err();
        std::fs::remove_dir_all(&dir).unwrap();
        assert!(
            e.to_string()
                .ends_with("is a directory; the glTF files in it: a.gltf, b.glb"),
            "{e}"
        );
    }

    #[test]
    fn missing_gltf_file_is_an_io_error_naming_it() {
        match load("does/not/exist.gltf") {
            Err(SceneError::Io { file, .. }) => assert_eq!(file, "does/not/exist.gltf"),
            other => panic!("expected Io, got {other:?}"),
        }
    }
}
