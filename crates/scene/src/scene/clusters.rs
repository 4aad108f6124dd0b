//! The cluster records a scene carries (`crate::clusters` builds, reads and writes them).

use bytemuck::{Pod, Zeroable};

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
