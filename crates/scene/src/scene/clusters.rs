//! The cluster records a scene carries (`crate::clusters` builds, reads and writes them).

use bytemuck::{Pod, Zeroable};

use super::Scene;
use crate::error::SceneError;

/// Most triangles in a cluster (meshoptimizer's limit is 512; 124 is niagara's and NVIDIA's
/// mesh-shader choice, and a multiple of 4 as meshoptimizer asks).
pub const MAX_TRIANGLES: usize = 124;
/// Most distinct vertices in a cluster.
pub const MAX_VERTICES: usize = 64;

/// One cluster as the culling shader reads it (`Cluster` of shaders/common/cluster.glsl; 80
/// bytes). Bounds and cone are in the mesh's local space.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuCluster {
    /// Centre of the local bounding box of the cluster's vertices.
    pub center: [f32; 3],
    /// Its first index in the scene's (cluster-ordered) index buffer.
    pub first_index: u32,
    pub half_extents: [f32; 3],
    pub index_count: u32,
    /// Back-facing cone ([`crate::cone::Cone`]): apex behind every triangle's plane, axis, and
    /// cutoff = sin of the half-angle holding every normal; a cutoff of 1 or more never rejects.
    pub cone_apex: [f32; 3],
    pub cone_cutoff: f32,
    pub cone_axis: [f32; 3],
    /// The farthest vertex from the apex.
    pub cone_reach: f32,
    /// The largest perimeter / area of the cluster's triangles: how far snapping can turn one.
    pub cone_thinness: f32,
    pub _pad: [u32; 3],
}

impl GpuCluster {
    /// The cluster's cone as [`crate::cone::back_facing`] tests it.
    pub fn cone(&self) -> crate::cone::Cone {
        crate::cone::Cone {
            apex: self.cone_apex,
            axis: self.cone_axis,
            cutoff: self.cone_cutoff,
            reach: self.cone_reach,
            thinness: self.cone_thinness,
        }
    }
}

/// Coarser levels of detail kept per mesh (each about half the triangles of the one before).
pub const MAX_LODS: usize = 6;

/// One simplified level of a mesh (`Lod` of shaders/common/cull.glsl; 16 bytes): a range of
/// the scene's index buffer over the mesh's own vertices, and how far its surface may lie from
/// the full mesh's, in the mesh's local units (meshoptimizer's error estimate).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuLod {
    pub first_index: u32,
    /// 0: no such level.
    pub index_count: u32,
    pub error: f32,
    pub _pad: u32,
}

/// A scene's clusters: the index buffer in cluster order, the clusters, and each mesh's range
/// of them; then each mesh's levels of detail, whose indices follow the scene's. `fingerprint`
/// is [`Scene::geometry_fingerprint`] of the scene they were built from.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ClusterData {
    pub fingerprint: u64,
    /// The scene's indices in cluster order, then the levels of detail's.
    pub indices: Vec<u32>,
    pub clusters: Vec<GpuCluster>,
    /// Per mesh: first cluster, cluster count.
    pub mesh_clusters: Vec<[u32; 2]>,
    /// Per mesh, [`MAX_LODS`] levels, coarser and coarser (error never decreasing); unused ones
    /// have no indices. Empty: no levels ([`ClusterData::without_lods`]).
    pub lods: Vec<GpuLod>,
}

/// The clusters a scene carries once attached (its index buffer is then in cluster order).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Clusters {
    pub clusters: Vec<GpuCluster>,
    pub mesh_clusters: Vec<[u32; 2]>,
    /// Per mesh, [`MAX_LODS`] levels of detail ([`ClusterData::lods`]).
    pub lods: Vec<GpuLod>,
}

impl Clusters {
    /// Bytes the cluster records, mesh ranges and level table take (GPU and CPU alike).
    pub fn bytes(&self) -> u64 {
        (self.clusters.len() * std::mem::size_of::<GpuCluster>()
            + self.mesh_clusters.len() * 8
            + self.lods.len() * std::mem::size_of::<GpuLod>()) as u64
    }

    /// The levels of detail of mesh `mesh` that exist, coarser and coarser (empty for an
    /// unknown mesh or one that does not simplify).
    pub fn lods_of(&self, mesh: u32) -> &[GpuLod] {
        let first = mesh as usize * MAX_LODS;
        let levels = self.lods.get(first..first + MAX_LODS).unwrap_or(&[]);
        let n = levels.iter().take_while(|l| l.index_count > 0).count();
        &levels[..n]
    }

    /// Whether any mesh has a level of detail.
    pub fn has_lods(&self) -> bool {
        self.lods.iter().any(|l| l.index_count > 0)
    }

    /// Clusters of mesh `mesh` (empty for an unknown mesh).
    pub fn of_mesh(&self, mesh: u32) -> &[GpuCluster] {
        self.mesh_clusters
            .get(mesh as usize)
            .and_then(|&[first, count]| {
                self.clusters
                    .get(first as usize..first as usize + count as usize)
            })
            .unwrap_or(&[])
    }
}

/// 64-bit FNV-1a: stable across builds and platforms (the cluster cache's key).
pub(crate) fn fnv1a(hash: u64, bytes: &[u8]) -> u64 {
    bytes.iter().fold(hash, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

pub(crate) const FNV_OFFSET: u64 = 0xcbf2_9ce4_8422_2325;

/// Checks `data` against `scene` (each mesh's clusters tile its index range in order, every
/// index stays inside the mesh's vertices) before [`Scene::attach_clusters`] swaps it in.
pub(super) fn validate(scene: &Scene, data: &ClusterData) -> Result<(), SceneError> {
    let bad = |reason: String| SceneError::Clusters {
        what: scene.name().to_string(),
        reason,
    };
    if data.indices.len() < scene.indices().len() {
        return Err(bad(format!(
            "{} indices for a scene of {}",
            data.indices.len(),
            scene.indices().len()
        )));
    }
    if data.mesh_clusters.len() != scene.meshes().len() {
        return Err(bad(format!(
            "cluster ranges for {} meshes, the scene has {}",
            data.mesh_clusters.len(),
            scene.meshes().len()
        )));
    }
    for (m, (mesh, &[first, count])) in scene.meshes().iter().zip(&data.mesh_clusters).enumerate() {
        let Some(clusters) = data
            .clusters
            .get(first as usize..first as usize + count as usize)
        else {
            return Err(bad(format!(
                "mesh {m}: clusters {first}+{count} past the end"
            )));
        };
        // In u64: a file's counts must not wrap round to a mesh's end.
        let mut at = u64::from(mesh.first_index);
        let end = at + u64::from(mesh.index_count);
        for (k, c) in clusters.iter().enumerate() {
            if u64::from(c.first_index) != at || c.index_count % 3 != 0 {
                return Err(bad(format!(
                    "mesh {m} cluster {k}: indices {}+{} do not follow on from {at}",
                    c.first_index, c.index_count
                )));
            }
            at += u64::from(c.index_count);
            if at > end {
                return Err(bad(format!(
                    "mesh {m} cluster {k}: indices {}+{} past the mesh's end {end}",
                    c.first_index, c.index_count
                )));
            }
        }
        if at != end {
            return Err(bad(format!(
                "mesh {m}: clusters cover {} of its {} indices",
                at - u64::from(mesh.first_index),
                mesh.index_count
            )));
        }
        let range = mesh.first_index as usize..(mesh.first_index + mesh.index_count) as usize;
        if let Some(i) = data
            .indices
            .get(range)
            .and_then(|ix| ix.iter().find(|&&i| i >= mesh.vertex_count))
        {
            return Err(bad(format!(
                "mesh {m}: index {i} past its {} vertices",
                mesh.vertex_count
            )));
        }
    }
    validate_lods(scene, data).map_err(bad)
}

/// Checks the levels of detail of `data`: [`MAX_LODS`] per mesh, each a range of whole
/// triangles after the scene's indices over the mesh's vertices, errors finite and never
/// decreasing.
fn validate_lods(scene: &Scene, data: &ClusterData) -> Result<(), String> {
    // Without levels (`ClusterData::without_lods`): the scene's indices only.
    if data.lods.is_empty() {
        return match data.indices.len() == scene.indices().len() {
            true => Ok(()),
            false => Err(format!(
                "{} indices and no levels of detail for a scene of {}",
                data.indices.len(),
                scene.indices().len()
            )),
        };
    }
    if data.lods.len() != scene.meshes().len() * MAX_LODS {
        return Err(format!(
            "{} levels of detail for {} meshes ({MAX_LODS} each)",
            data.lods.len(),
            scene.meshes().len()
        ));
    }
    let tail = scene.indices().len() as u64..data.indices.len() as u64;
    for (m, (mesh, levels)) in scene
        .meshes()
        .iter()
        .zip(data.lods.chunks_exact(MAX_LODS))
        .enumerate()
    {
        let mut error = 0.0f32;
        for (k, l) in levels.iter().enumerate() {
            if l.index_count == 0 {
                continue;
            }
            let start = u64::from(l.first_index);
            let end = start + u64::from(l.index_count);
            if l.index_count % 3 != 0 || !tail.contains(&start) || end > tail.end {
                return Err(format!(
                    "mesh {m} level {}: indices {start}+{} outside the level tail {tail:?}",
                    k + 1,
                    l.index_count
                ));
            }
            if !(l.error.is_finite() && l.error >= error) {
                return Err(format!(
                    "mesh {m} level {}: error {} after {error}",
                    k + 1,
                    l.error
                ));
            }
            error = l.error;
            let indices = &data.indices[start as usize..end as usize];
            if let Some(i) = indices.iter().find(|&&i| i >= mesh.vertex_count) {
                return Err(format!(
                    "mesh {m} level {}: index {i} past its {} vertices",
                    k + 1,
                    mesh.vertex_count
                ));
            }
        }
    }
    Ok(())
}
