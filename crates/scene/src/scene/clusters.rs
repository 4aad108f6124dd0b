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

/// A scene's clusters: the index buffer in cluster order, the clusters, and each mesh's range
/// of them. `fingerprint` is [`Scene::geometry_fingerprint`] of the scene they were built from.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ClusterData {
    pub fingerprint: u64,
    pub indices: Vec<u32>,
    pub clusters: Vec<GpuCluster>,
    /// Per mesh: first cluster, cluster count.
    pub mesh_clusters: Vec<[u32; 2]>,
}

/// The clusters a scene carries once attached (its index buffer is then in cluster order).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Clusters {
    pub clusters: Vec<GpuCluster>,
    pub mesh_clusters: Vec<[u32; 2]>,
}

impl Clusters {
    /// Bytes the cluster records and mesh ranges take (GPU and CPU alike).
    pub fn bytes(&self) -> u64 {
        (self.clusters.len() * std::mem::size_of::<GpuCluster>() + self.mesh_clusters.len() * 8)
            as u64
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
