//! Clusters (meshlets): each mesh split into runs of at most [`MAX_TRIANGLES`] triangles with a
//! local bounding box and a back-facing normal cone, for culling below the instance (issue 22,
//! seed 000's cone/cluster culling).
//!
//! A cluster is a contiguous range of its mesh's indices: attaching clusters to a scene
//! ([`Scene::attach_clusters`]) rewrites its index buffer into cluster order, so that every
//! technique, the unculled reference included, draws the same triangles in the same order and a
//! culled frame that draws the surviving ranges in order stays bit-equal to the reference.
//!
//! Building clusters is an asset step ([`build`], behind the `meshopt` feature: meshoptimizer is
//! C++, and the Android builds compile without it). The runtime only consumes [`ClusterData`]:
//! built here, read from a file written on the desktop ([`ClusterData::write`],
//! [`ClusterData::read`]), or handed over by an engine's own pipeline.

use std::path::Path;

use bytemuck::Pod;

use crate::error::SceneError;
#[cfg(feature = "meshopt")]
use crate::scene::Scene;
pub use crate::scene::{
    ClusterData, Clusters, GpuCluster, GpuLod, MAX_LODS, MAX_TRIANGLES, MAX_VERTICES,
};

const CLUSTER_BYTES: usize = std::mem::size_of::<GpuCluster>();
const LOD_BYTES: usize = std::mem::size_of::<GpuLod>();
const HEADER_BYTES: usize = 48;

/// Version 7: 80-byte clusters with the snapping-safe cone (`crate::cone`), each cluster's
/// triangles in vertex-cache order, each mesh's clusters outermost first, then the meshes'
/// levels of detail (an older file is rebuilt).
const MAGIC: &[u8; 8] = b"TGCLUST7";

impl ClusterData {
    /// Writes the data to `path` (little-endian: magic, fingerprint, counts, then the arrays).
    pub fn write(&self, path: &Path) -> Result<(), SceneError> {
        let mut out = Vec::with_capacity(
            HEADER_BYTES
                + self.indices.len() * 4
                + self.clusters.len() * CLUSTER_BYTES
                + self.mesh_clusters.len() * 8
                + self.lods.len() * LOD_BYTES,
        );
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&self.fingerprint.to_le_bytes());
        for n in [
            self.indices.len(),
            self.clusters.len(),
            self.mesh_clusters.len(),
            self.lods.len(),
        ] {
            out.extend_from_slice(&(n as u64).to_le_bytes());
        }
        out.extend_from_slice(bytemuck::cast_slice(&self.indices));
        out.extend_from_slice(bytemuck::cast_slice(&self.clusters));
        out.extend_from_slice(bytemuck::cast_slice(&self.mesh_clusters));
        out.extend_from_slice(bytemuck::cast_slice(&self.lods));
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).map_err(|source| io(path, source))?;
        }
        // Written whole under a name no other writer uses, then renamed: a reader in another
        // thread or process (tests run in parallel) sees the old file, none, or all of the new.
        static WRITES: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
        let n = WRITES.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let tmp = path.with_extension(format!("tmp{}-{n}", std::process::id()));
        std::fs::write(&tmp, out).map_err(|source| io(&tmp, source))?;
        std::fs::rename(&tmp, path).map_err(|source| io(path, source))
    }

    /// The data without its levels of detail: the scene's indices only, no level table (a
    /// renderer that never draws levels keeps the index buffer it had before they existed:
    /// the levels add about as many indices again).
    pub fn without_lods(mut self) -> ClusterData {
        let tail = (self.lods.iter())
            .filter(|l| l.index_count > 0)
            .map(|l| l.first_index as usize)
            .min();
        if let Some(start) = tail {
            self.indices.truncate(start);
        }
        self.lods.clear();
        self
    }

    /// Reads data [`ClusterData::write`] wrote; a wrong magic or a short file is an error naming
    /// the file. (Whether it fits a scene is [`Scene::attach_clusters`]'s check.)
    pub fn read(path: &Path) -> Result<ClusterData, SceneError> {
        let bytes = std::fs::read(path).map_err(|source| io(path, source))?;
        let bad = |reason: String| SceneError::Clusters {
            what: path.display().to_string(),
            reason,
        };
        if bytes.get(..8) != Some(MAGIC.as_slice()) {
            return Err(bad("not a tilegraph cluster file (magic)".into()));
        }
        let word = |i: usize| {
            bytes
                .get(8 + 8 * i..16 + 8 * i)
                .and_then(|b| b.try_into().ok())
                .map(u64::from_le_bytes)
        };
        let header = (word(0), word(1), word(2), word(3), word(4));
        let (Some(fingerprint), Some(ni), Some(nc), Some(nm), Some(nl)) = header else {
            return Err(bad("header cut short".into()));
        };
        let sizes = [
            ni.checked_mul(4),
            nc.checked_mul(CLUSTER_BYTES as u64),
            nm.checked_mul(8),
            nl.checked_mul(LOD_BYTES as u64),
        ];
        let [Some(si), Some(sc), Some(sm), Some(sl)] =
            sizes.map(|s| s.and_then(|s| usize::try_from(s).ok()))
        else {
            return Err(bad("counts overflow".into()));
        };
        let start = HEADER_BYTES;
        let expected = start
            .checked_add(si)
            .and_then(|n| n.checked_add(sc))
            .and_then(|n| n.checked_add(sm))
            .and_then(|n| n.checked_add(sl));
        if expected != Some(bytes.len()) {
            return Err(bad(format!(
                "{} bytes, the header's counts need {}",
                bytes.len(),
                expected.map_or("more than memory holds".into(), |n| n.to_string())
            )));
        }
        let (a, rest) = bytes[start..].split_at(si);
        let (b, rest) = rest.split_at(sc);
        let (c, d) = rest.split_at(sm);
        Ok(ClusterData {
            fingerprint,
            indices: read_pods(a),
            clusters: read_pods(b),
            mesh_clusters: read_pods(c),
            lods: read_pods(d),
        })
    }
}

/// `bytes` (a multiple of `T`'s size) as `T`s, whatever their alignment.
fn read_pods<T: Pod>(bytes: &[u8]) -> Vec<T> {
    bytes
        .chunks_exact(std::mem::size_of::<T>())
        .map(bytemuck::pod_read_unaligned)
        .collect()
}

fn io(path: &Path, source: std::io::Error) -> SceneError {
    SceneError::Io {
        file: path.display().to_string(),
        source,
    }
}

/// What [`build`] took: time and how many clusters.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BuildStats {
    pub milliseconds: f64,
    pub clusters: u64,
}

/// Splits every mesh of `scene` into clusters with meshoptimizer (`meshopt_buildMeshlets`, cone
/// weight 0.25) and computes each cluster's box and its back-facing cone ([`crate::cone::Cone`],
/// tilegraph's own: safe against snapping, none where a triangle is degenerate). Each mesh is built once,
/// whatever number of instances draw it.
#[cfg(feature = "meshopt")]
pub fn build(scene: &Scene) -> Result<(ClusterData, BuildStats), SceneError> {
    let start = std::time::Instant::now();
    let vertices = scene.vertices();
    let mut data = ClusterData {
        fingerprint: scene.geometry_fingerprint(),
        indices: scene.indices().to_vec(),
        clusters: Vec::new(),
        mesh_clusters: Vec::with_capacity(scene.meshes().len()),
        lods: Vec::with_capacity(scene.meshes().len() * MAX_LODS),
    };
    for (m, mesh) in scene.meshes().iter().enumerate() {
        let bad = |reason: String| SceneError::Clusters {
            what: format!("{} mesh {m}", scene.name()),
            reason,
        };
        let first = mesh.first_index as usize;
        let range = first..first + mesh.index_count as usize;
        let vrange = mesh.vertex_offset.max(0) as usize
            ..mesh.vertex_offset.max(0) as usize + mesh.vertex_count as usize;
        let (Some(indices), Some(verts)) =
            (scene.indices().get(range.clone()), vertices.get(vrange))
        else {
            return Err(bad(
                "index or vertex range outside the scene's buffers".into()
            ));
        };
        let first_cluster = data.clusters.len() as u32;
        if indices.len() >= 3 {
            let adapter = meshopt::VertexDataAdapter::new(
                bytemuck::cast_slice(verts),
                std::mem::size_of::<crate::Vertex>(),
                0,
            )
            .map_err(|e| bad(e.to_string()))?;
            let meshlets =
                meshopt::build_meshlets(indices, &adapter, MAX_VERTICES, MAX_TRIANGLES, 0.25);
            let mut at = first;
            for meshlet in overdraw_order(&meshlets, verts) {
                let begin = at;
                let mut corners = Vec::with_capacity(meshlet.triangles.len());
                let (mut lo, mut hi) = ([f32::MAX; 3], [f32::MIN; 3]);
                for &local in meshlet.triangles {
                    let Some(&v) = meshlet.vertices.get(usize::from(local)) else {
                        return Err(bad("meshlet refers past its vertices".into()));
                    };
                    let Some(p) = verts.get(v as usize).map(|v| v.position) else {
                        return Err(bad(format!("vertex {v} past the mesh's")));
                    };
                    for a in 0..3 {
                        lo[a] = lo[a].min(p[a]);
                        hi[a] = hi[a].max(p[a]);
                    }
                    if let Some(slot) = data.indices.get_mut(at) {
                        *slot = v;
                    }
                    corners.push(p);
                    at += 1;
                }
                let triangles: Vec<[[f32; 3]; 3]> = corners
                    .chunks_exact(3)
                    .map(|t| [t[0], t[1], t[2]])
                    .collect();
                let cone = crate::cone::Cone::of_triangles(&triangles);
                let center = std::array::from_fn(|a| 0.5 * (lo[a] + hi[a]));
                let half = std::array::from_fn(|a| 0.5 * (hi[a] - lo[a]));
                data.clusters.push(GpuCluster {
                    center,
                    first_index: begin as u32,
                    half_extents: half,
                    index_count: (at - begin) as u32,
                    cone_apex: cone.apex,
                    cone_cutoff: cone.cutoff,
                    cone_axis: cone.axis,
                    cone_reach: cone.reach,
                    cone_thinness: cone.thinness,
                    _pad: [0; 3],
                });
            }
            // Each cluster's triangles in vertex-cache order (meshoptimizer's): the meshlet
            // builder's order is the cluster's growth, whose vertex reuse is poorer than the
            // mesh's own; a cluster's set of triangles, hence its box and cone, stays.
            for c in &data.clusters[first_cluster as usize..] {
                let r = c.first_index as usize..(c.first_index + c.index_count) as usize;
                if let Some(tri) = data.indices.get_mut(r) {
                    meshopt::optimize_vertex_cache_in_place(tri, verts.len());
                }
            }
            if at != range.end {
                return Err(bad(format!(
                    "meshlets hold {} indices of {}",
                    at - first,
                    indices.len()
                )));
            }
        }
        data.mesh_clusters
            .push([first_cluster, data.clusters.len() as u32 - first_cluster]);
    }
    // The levels of detail, each from the full mesh (its error is the full mesh's distance),
    // their indices after the scene's.
    for mesh in scene.meshes() {
        let range = mesh.first_index as usize..(mesh.first_index + mesh.index_count) as usize;
        let vrange = mesh.vertex_offset.max(0) as usize
            ..mesh.vertex_offset.max(0) as usize + mesh.vertex_count as usize;
        let levels = match (data.indices.get(range), vertices.get(vrange)) {
            (Some(indices), Some(verts)) => simplified_levels(indices, verts),
            _ => Vec::new(),
        };
        let mut slots = [GpuLod::default(); MAX_LODS];
        for (slot, (indices, error)) in slots.iter_mut().zip(levels) {
            *slot = GpuLod {
                first_index: data.indices.len() as u32,
                index_count: indices.len() as u32,
                error,
                _pad: 0,
            };
            data.indices.extend_from_slice(&indices);
        }
        data.lods.extend_from_slice(&slots);
    }
    let stats = BuildStats {
        milliseconds: start.elapsed().as_secs_f64() * 1e3,
        clusters: data.clusters.len() as u64,
    };
    Ok((data, stats))
}

/// How much a unit of normal change weighs in a level's error, as a share of the mesh's extent.
#[cfg(feature = "meshopt")]
const NORMAL_WEIGHT: f32 = 0.25;

/// A level is kept only if it has at most this share of the previous level's triangles.
#[cfg(feature = "meshopt")]
const LOD_STEP: f64 = 0.75;

/// Up to [`MAX_LODS`] simplified versions of a mesh's `indices` (meshoptimizer's
/// `meshopt_simplify`, border vertices locked so that meshes that meet stay closed), each aiming
/// at half the triangles of the one before, with its error in the mesh's units; a level that
/// does not get below [`LOD_STEP`] of the one before ends the list. Each is in vertex-cache
/// order, errors never decrease.
#[cfg(feature = "meshopt")]
fn simplified_levels(indices: &[u32], verts: &[crate::Vertex]) -> Vec<(Vec<u32>, f32)> {
    let mut levels = Vec::new();
    let Ok(adapter) = meshopt::VertexDataAdapter::new(
        bytemuck::cast_slice(verts),
        std::mem::size_of::<crate::Vertex>(),
        0,
    ) else {
        return levels;
    };
    // No error limit: the triangle count decides, the error is what it costs.
    let limit = f32::MAX;
    let options = meshopt::SimplifyOptions::ErrorAbsolute | meshopt::SimplifyOptions::LockBorder;
    // Normals weigh in the error as lengths (a unit of normal change is NORMAL_WEIGHT of the
    // mesh's extent): a level that bends the shading counts as far off as one that moves the
    // surface by that much, so it is chosen only where that is small on screen.
    let floats: &[f32] = bytemuck::cast_slice(verts);
    let normals = floats.get(3..).unwrap_or(&[]);
    let weight = NORMAL_WEIGHT * meshopt::simplify_scale(&adapter);
    let weights = [weight; 3];
    let locks = vec![false; verts.len()];
    let mut previous = indices.len();
    let mut error_floor = 0.0f32;
    while levels.len() < MAX_LODS && previous >= 6 {
        let target = (previous / 2) / 3 * 3;
        let mut error = 0.0f32;
        let mut level = meshopt::simplify_with_attributes_and_locks(
            indices,
            &adapter,
            normals,
            &weights,
            std::mem::size_of::<crate::Vertex>(),
            &locks,
            target,
            limit,
            options,
            Some(&mut error),
        );
        if level.is_empty() || level.len() as f64 > LOD_STEP * previous as f64 || !error.is_finite()
        {
            break;
        }
        meshopt::optimize_vertex_cache_in_place(&mut level, verts.len());
        error_floor = error_floor.max(error);
        previous = level.len();
        levels.push((level, error_floor));
    }
    levels
}

/// The mesh's meshlets in the order that draws its outer surface first (view-independent
/// overdraw reduction, Sander, Nehab and Barczak 2007, as meshoptimizer's overdraw optimizer
/// sorts its patches): by how far each meshlet's centroid lies from the mesh's along the
/// meshlet's area-weighted normal, outermost first; ties keep the builder's order.
#[cfg(feature = "meshopt")]
fn overdraw_order<'m>(
    meshlets: &'m meshopt::Meshlets,
    verts: &[crate::Vertex],
) -> impl Iterator<Item = meshopt::Meshlet<'m>> {
    let position = |m: &meshopt::Meshlet<'_>, local: u8| {
        m.vertices
            .get(usize::from(local))
            .and_then(|&v| verts.get(v as usize))
            .map(|v| glam::Vec3::from(v.position))
    };
    // Per meshlet: area-weighted centroid sum, area sum and normal sum.
    let sums: Vec<(glam::Vec3, f32, glam::Vec3)> = meshlets
        .iter()
        .map(|m| {
            let mut acc = (glam::Vec3::ZERO, 0.0, glam::Vec3::ZERO);
            for t in m.triangles.chunks_exact(3) {
                let (Some(a), Some(b), Some(c)) =
                    (position(&m, t[0]), position(&m, t[1]), position(&m, t[2]))
                else {
                    continue;
                };
                let n = (b - a).cross(c - a);
                let area = 0.5 * n.length();
                acc.0 += area * (a + b + c) / 3.0;
                acc.1 += area;
                acc.2 += n;
            }
            acc
        })
        .collect();
    let total: f32 = sums.iter().map(|s| s.1).sum();
    let mesh_centroid = if total > 0.0 {
        sums.iter().map(|s| s.0).sum::<glam::Vec3>() / total
    } else {
        glam::Vec3::ZERO
    };
    let mut keyed: Vec<(f32, usize)> = sums
        .iter()
        .enumerate()
        .map(|(k, &(weighted, area, normal))| {
            let centroid = if area > 0.0 {
                weighted / area
            } else {
                mesh_centroid
            };
            let key = (centroid - mesh_centroid).dot(normal.normalize_or_zero());
            (if key.is_finite() { key } else { 0.0 }, k)
        })
        .collect();
    keyed.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
    keyed.into_iter().map(move |(_, k)| meshlets.get(k))
}

/// Where [`cached`] keeps built clusters: `$TILEGRAPH_CACHE_DIR`, else
/// `$XDG_CACHE_HOME/tilegraph`, else `$HOME/.cache/tilegraph`.
pub fn cache_dir() -> Option<std::path::PathBuf> {
    let var = |k: &str| std::env::var_os(k).filter(|v| !v.is_empty());
    var("TILEGRAPH_CACHE_DIR")
        .map(std::path::PathBuf::from)
        .or_else(|| var("XDG_CACHE_HOME").map(|d| Path::new(&d).join("tilegraph")))
        .or_else(|| var("HOME").map(|h| Path::new(&h).join(".cache/tilegraph")))
}

/// How [`cached`] got the clusters.
#[derive(Clone, Debug, PartialEq)]
pub enum Provenance {
    /// Read from this cache file.
    Cache(std::path::PathBuf),
    /// Built now (and written to the cache file when there is one).
    Built(BuildStats),
}

/// The scene's clusters from the cache (keyed by [`Scene::geometry_fingerprint`]), else built
/// and written there. A cache that cannot be read or written is logged and skipped.
#[cfg(feature = "meshopt")]
pub fn cached(scene: &Scene) -> Result<(ClusterData, Provenance), SceneError> {
    let fingerprint = scene.geometry_fingerprint();
    let file = cache_dir().map(|d| d.join(format!("{fingerprint:016x}.tgclusters")));
    if let Some(path) = file.as_deref().filter(|p| p.is_file()) {
        match ClusterData::read(path) {
            Ok(d) if d.fingerprint == fingerprint => {
                return Ok((d, Provenance::Cache(path.to_path_buf())))
            }
            Ok(_) => log::warn!("{}: another scene's clusters; rebuilding", path.display()),
            Err(e) => log::warn!("{e}; rebuilding"),
        }
    }
    let (data, stats) = build(scene)?;
    if let Some(path) = &file {
        if let Err(e) = data.write(path) {
            log::warn!("cluster cache not written: {e}");
        }
    }
    Ok((data, Provenance::Built(stats)))
}

#[cfg(all(test, feature = "meshopt"))]
mod tests {
    use super::*;
    use crate::{generate, ProceduralKind, ProceduralParams};

    fn triangles(indices: &[u32]) -> Vec<[u32; 3]> {
        let mut t: Vec<[u32; 3]> = indices
            .chunks_exact(3)
            .map(|c| {
                // Rotate so the smallest comes first: same triangle, same winding.
                let k = (0..3).min_by_key(|&k| c[k]).unwrap_or(0);
                [c[k], c[(k + 1) % 3], c[(k + 2) % 3]]
            })
            .collect();
        t.sort_unstable();
        t
    }

    #[test]
    fn clusters_tile_each_mesh_with_the_same_triangles_and_windings() {
        let scene = generate(
            ProceduralKind::Interior,
            ProceduralParams { size: 200, seed: 3 },
        )
        .unwrap();
        let (data, stats) = build(&scene).unwrap();
        assert_eq!(stats.clusters, data.clusters.len() as u64);
        assert!(data.clusters.len() >= scene.meshes().len());
        scene.clone().attach_clusters(data.clone()).unwrap();
        for mesh in scene.meshes() {
            let r = mesh.first_index as usize..(mesh.first_index + mesh.index_count) as usize;
            assert_eq!(
                triangles(&scene.indices()[r.clone()]),
                triangles(&data.indices[r])
            );
        }
        for c in &data.clusters {
            assert!(c.index_count as usize <= 3 * MAX_TRIANGLES && c.index_count > 0);
            // Every vertex of the cluster lies in its box.
            let mesh = scene
                .meshes()
                .iter()
                .find(|m| {
                    c.first_index >= m.first_index && c.first_index < m.first_index + m.index_count
                })
                .unwrap();
            for &i in &data.indices[c.first_index as usize..][..c.index_count as usize] {
                let p = scene.vertices()[(mesh.vertex_offset as u32 + i) as usize].position;
                for (a, x) in p.into_iter().enumerate() {
                    assert!((x - c.center[a]).abs() <= c.half_extents[a] * (1.0 + 1e-6) + 1e-6);
                }
            }
        }
    }

    #[test]
    fn meshlets_are_drawn_outermost_first_each_once() {
        // A box seen from outside (normals out) and a room seen from inside (normals in): the
        // outer faces come first in the first, last in the second; every meshlet once.
        for inward in [false, true] {
            let mut vertices = Vec::new();
            let mut indices = Vec::new();
            for axis in 0..3 {
                for side in [-1.0f32, 1.0] {
                    // A 4x4 grid of quads on the face, wound to face out (or in).
                    let base = vertices.len() as u32;
                    for j in 0..5 {
                        for i in 0..5 {
                            let (u, v) = (i as f32 / 2.0 - 1.0, j as f32 / 2.0 - 1.0);
                            let mut p = [0.0; 3];
                            p[axis] = side;
                            p[(axis + 1) % 3] = u;
                            p[(axis + 2) % 3] = v;
                            vertices.push(crate::Vertex {
                                position: p,
                                normal: [0.0; 3],
                                uv: [0.0; 2],
                            });
                        }
                    }
                    for j in 0..4u32 {
                        for i in 0..4u32 {
                            let k = base + j * 5 + i;
                            let (a, b, c, d) = (k, k + 1, k + 6, k + 5);
                            let out = (side > 0.0) != inward;
                            if out {
                                indices.extend([a, b, c, a, c, d]);
                            } else {
                                indices.extend([a, c, b, a, d, c]);
                            }
                        }
                    }
                }
            }
            let adapter = meshopt::VertexDataAdapter::new(
                bytemuck::cast_slice(&vertices),
                std::mem::size_of::<crate::Vertex>(),
                0,
            )
            .unwrap();
            // Small meshlets: several per face.
            let meshlets = meshopt::build_meshlets(&indices, &adapter, 16, 8, 0.0);
            let ordered: Vec<_> = overdraw_order(&meshlets, &vertices).collect();
            assert_eq!(ordered.len(), meshlets.len());
            let mut seen: Vec<_> = ordered.iter().map(|m| m.triangles.as_ptr()).collect();
            seen.sort_unstable();
            seen.dedup();
            assert_eq!(seen.len(), meshlets.len(), "a meshlet twice");
            // The box is centred on the origin: a meshlet's key is its centroid along its
            // mean normal, +1 (out) or -1 (in) within one face, between for one that spans two.
            let key = |m: &meshopt::Meshlet<'_>| {
                let mut n = glam::Vec3::ZERO;
                let mut c = glam::Vec3::ZERO;
                for t in m.triangles.chunks_exact(3) {
                    let p = |k: u8| {
                        glam::Vec3::from(vertices[m.vertices[usize::from(k)] as usize].position)
                    };
                    let (a, b, d) = (p(t[0]), p(t[1]), p(t[2]));
                    n += (b - a).cross(d - a);
                    c += a + b + d;
                }
                (c / m.triangles.len() as f32).dot(n.normalize_or_zero())
            };
            let keys: Vec<f32> = ordered.iter().map(key).collect();
            assert!(keys.windows(2).all(|w| w[0] >= w[1] - 1e-3), "{keys:?}");
            let sign = if inward { -1.0 } else { 1.0 };
            assert!(keys.iter().all(|k| k * sign > 0.0), "{keys:?}");
        }
    }

    /// A `n` x `n` grid of quads over [-1, 1]^2 at height `height(x, y)`, facing +z.
    fn height_field(n: u32, height: impl Fn(f32, f32) -> f32) -> (Vec<crate::Vertex>, Vec<u32>) {
        let mut vertices = Vec::new();
        for j in 0..=n {
            for i in 0..=n {
                let (x, y) = (
                    2.0 * i as f32 / n as f32 - 1.0,
                    2.0 * j as f32 / n as f32 - 1.0,
                );
                vertices.push(crate::Vertex {
                    position: [x, y, height(x, y)],
                    normal: [0.0, 0.0, 1.0],
                    uv: [0.5 * x + 0.5, 0.5 * y + 0.5],
                });
            }
        }
        let mut indices = Vec::new();
        for j in 0..n {
            for i in 0..n {
                let k = j * (n + 1) + i;
                indices.extend([k, k + 1, k + n + 2, k, k + n + 2, k + n + 1]);
            }
        }
        (vertices, indices)
    }

    #[test]
    fn levels_of_detail_halve_triangles_with_growing_error_over_the_mesh_vertices() {
        let (vertices, indices) = height_field(32, |x, y| 0.2 * (3.0 * x).sin() * (2.0 * y).cos());
        let levels = simplified_levels(&indices, &vertices);
        assert!(levels.len() >= 3, "{} levels", levels.len());
        let mut previous = (indices.len(), 0.0f32);
        for (level, error) in &levels {
            assert!(level.len() % 3 == 0 && !level.is_empty());
            assert!(level.len() as f64 <= LOD_STEP * previous.0 as f64);
            assert!(*error >= previous.1 && error.is_finite());
            assert!(level.iter().all(|&i| (i as usize) < vertices.len()));
            previous = (level.len(), *error);
        }
        // Curved: the coarsest level moved the surface. Its border is locked: every border
        // vertex of the full mesh is still used.
        assert!(previous.1 > 1e-3, "error {}", previous.1);
        let coarsest = &levels[levels.len() - 1].0;
        for (k, v) in vertices.iter().enumerate() {
            let on_border = v.position[0].abs() == 1.0 || v.position[1].abs() == 1.0;
            let corner = v.position[0].abs() == 1.0 && v.position[1].abs() == 1.0;
            if on_border && corner {
                assert!(coarsest.contains(&(k as u32)), "corner {k} gone");
            }
        }
        // Flat: simplified with no error to speak of.
        let (vertices, indices) = height_field(16, |_, _| 0.0);
        let levels = simplified_levels(&indices, &vertices);
        assert!(!levels.is_empty());
        assert!(
            levels.iter().all(|(_, e)| *e < 1e-3),
            "{:?}",
            levels.iter().map(|l| l.1).collect::<Vec<_>>()
        );
        // Too small to simplify: none.
        assert!(simplified_levels(&indices[..3], &vertices).is_empty());
    }

    #[test]
    fn cluster_files_round_trip_and_bad_ones_are_named() {
        let mut scene =
            generate(ProceduralKind::City, ProceduralParams { size: 30, seed: 1 }).unwrap();
        let (data, _) = build(&scene).unwrap();
        let dir = std::env::temp_dir().join(format!("tilegraph-clusters-{}", std::process::id()));
        let path = dir.join("city.tgclusters");
        data.write(&path).unwrap();
        assert_eq!(ClusterData::read(&path).unwrap(), data);
        let bytes = std::fs::read(&path).unwrap();
        std::fs::write(&path, &bytes[..bytes.len() - 4]).unwrap();
        let e = ClusterData::read(&path).unwrap_err().to_string();
        assert!(
            e.contains("city.tgclusters") && e.contains("header's counts"),
            "{e}"
        );
        std::fs::write(&path, b"GLTF....").unwrap();
        assert!(ClusterData::read(&path)
            .unwrap_err()
            .to_string()
            .contains("magic"));
        std::fs::remove_dir_all(&dir).unwrap();
        // Another scene's data does not attach.
        let other = generate(
            ProceduralKind::Forest,
            ProceduralParams { size: 30, seed: 1 },
        )
        .unwrap();
        let (wrong, _) = build(&other).unwrap();
        assert!(scene.attach_clusters(wrong).is_err());
        scene.attach_clusters(data.clone()).unwrap();
        assert_eq!(
            scene.clusters().map(|c| c.clusters.len()),
            Some(data.clusters.len())
        );
        assert_eq!(scene.indices(), &data.indices[..]);
    }

    #[test]
    fn levels_of_detail_round_trip_and_bad_ones_are_refused() {
        let (vertices, indices) = height_field(24, |x, y| 0.3 * (2.0 * x).sin() * y.cos());
        let mut b = crate::SceneBuilder::new("hills");
        let m = b.add_material(crate::Material::opaque([0.5, 0.5, 0.5, 1.0]));
        let mesh = b.add_mesh(&vertices, &indices, m).unwrap();
        b.add_instance(crate::Transform::IDENTITY, mesh).unwrap();
        let scene = b.build(None).unwrap();
        let (data, _) = build(&scene).unwrap();
        assert_eq!(data.lods.len(), MAX_LODS);
        assert!(data.lods[1].index_count > 0 && data.lods[1].error >= data.lods[0].error);
        let level_indices: u32 = data.lods.iter().map(|l| l.index_count).sum();
        assert_eq!(data.indices.len(), indices.len() + level_indices as usize);
        let dir = std::env::temp_dir().join(format!("tilegraph-lods-{}", std::process::id()));
        let path = dir.join("hills.tgclusters");
        data.write(&path).unwrap();
        assert_eq!(ClusterData::read(&path).unwrap(), data);
        std::fs::remove_dir_all(&dir).unwrap();
        let mut attached = scene.clone();
        attached.attach_clusters(data.clone()).unwrap();
        let clusters = attached.clusters().unwrap();
        assert!(clusters.has_lods());
        let levels = data.lods.iter().filter(|l| l.index_count > 0).count();
        assert_eq!(clusters.lods_of(0).len(), levels);
        assert!(clusters.lods_of(7).is_empty());
        // Levels that reach into the scene's own indices, or shrink their error, are refused.
        let mut bad = data.clone();
        bad.lods[0].first_index = 0;
        let e = scene.clone().attach_clusters(bad).unwrap_err().to_string();
        assert!(e.contains("level tail"), "{e}");
        let mut bad = data.clone();
        bad.lods[1].error = -1.0;
        let e = scene.clone().attach_clusters(bad).unwrap_err().to_string();
        assert!(e.contains("error"), "{e}");
        let mut bad = data.clone();
        bad.lods.pop();
        assert!(scene.clone().attach_clusters(bad).is_err());
        // Without levels: the scene's indices only, as before levels existed.
        let mut plain = scene.clone();
        plain.attach_clusters(data.clone().without_lods()).unwrap();
        assert_eq!(plain.indices().len(), indices.len());
        assert!(!plain.clusters().unwrap().has_lods());
        let mut bad = data.without_lods();
        bad.indices.push(0);
        let e = scene.clone().attach_clusters(bad).unwrap_err().to_string();
        assert!(e.contains("no levels of detail"), "{e}");
    }
}
