// Shared declarations of the cluster culling shaders (cluster_cull.comp, cluster_place.comp,
// cluster_emit.comp): a second stage after instance culling that tests the clusters of every
// drawn instance and writes one indirect command per run of consecutive surviving clusters
// (docs/CULLING.md, "Clusters"). Needs scene.glsl and cull.glsl first.
//
// A cluster instance k = base[instance] + c (cluster c of the instance's mesh) has one flag
// per region: region 0 the early (or only) phase's draws, which the late phase turns into the
// union of both phases; region 1 the late phase's. Per list entry e (cull.glsl's entries), the
// runs of its flags and their place among the list's commands.
//
// An instance's clusters come in chunks of 64, each culled and emitted by a workgroup of its
// own (a run never crosses a chunk's end): per chunk and region, its runs, after the entries'
// in the same buffer.
#ifndef TILEGRAPH_CLUSTER_GLSL
#define TILEGRAPH_CLUSTER_GLSL

// tilegraph_scene::clusters::GpuCluster (80 bytes): local-space box, index range, back-facing
// cone (tilegraph_scene::cone: apex, axis, sin of its half-angle, the farthest vertex from the
// apex, the largest perimeter / area of its triangles).
struct Cluster {
    vec3 center;
    uint first_index;
    vec3 half_extents;
    uint index_count;
    vec3 cone_apex;
    float cone_cutoff;
    vec3 cone_axis;
    float cone_reach;
    float cone_thinness;
    uint pad0;
    uint pad1;
    uint pad2;
};

layout(set = 1, binding = 9, std430) readonly buffer Clusters { Cluster clusters[]; };
// Per mesh: first cluster, cluster count.
layout(set = 1, binding = 10, std430) readonly buffer MeshClusters { uvec2 mesh_clusters[]; };
// Per instance: its first cluster instance.
layout(set = 1, binding = 11, std430) readonly buffer ClusterBase { uint cluster_base[]; };
// Per region and cluster instance: 1 drawn (region r at r * cull.clusters.z).
layout(set = 1, binding = 12, std430) buffer Flags { uint flags[]; };
// Per list entry (0-7 lists of `stride`): runs of drawn clusters, and the first command's place
// among its group's; after the entries' places, each entry's draw group (group_of_entry), then
// per draw group and region its runs (then its first command among its list's) and its entries
// with runs (group_slot).
layout(set = 1, binding = 14, std430) buffer Runs { uint runs[]; };
// Coherent: cluster_place.comp's last workgroup of a list reads the places the others wrote.
layout(set = 1, binding = 15, std430) coherent buffer Offsets { uint offsets[]; };
// The frame's draw groups (cull.glsl), in draw order.
layout(set = 1, binding = 16, std430) readonly buffer ClusterGroups { Group cluster_groups[]; };

// Per region (0 early or only, 1 late): the dispatch's workgroups (x, 1, 1) and its chunk
// count, then the lists' placed groups, then from WORK_CHUNKS the region's chunks
// (cull_clusters.comp appends the chunks of the instances whose clusters the phase tests; a
// reset pass empties both lists each frame; cull.glsl). Writable in cluster_place.comp only.
#ifdef CLUSTER_WORK_COUNTERS
layout(set = 1, binding = 17, std430) coherent buffer Work { uint work[]; };
#else
layout(set = 1, binding = 17, std430) readonly buffer Work { uint work[]; };
#endif

// The region whose chunk list the dispatch runs through: the late phase's, or the early (or
// only) phase's.
uint work_region() {
    return cull.info.y == 3u ? 1u : 0u;
}

// How many chunks region r's list holds, and its i-th.
uint work_count(uint r) {
    return work[4u * r + 3u];
}

uint work_chunk(uint r, uint i) {
    return work[WORK_CHUNKS + r * cull.commands.w + i];
}

// The chunks (cull.commands: y where the first chunk of each instance is kept in
// cluster_base's buffer, z where each chunk's instance is, w how many chunks there are).
uint chunk_count() {
    return cull.commands.w;
}

// Instance `id`'s first chunk (its chunks end where instance id + 1's begin).
uint chunk_first(uint id) {
    return cluster_base[cull.commands.y + id];
}

uint chunk_instance(uint w) {
    return cluster_base[cull.commands.z + w];
}

// Where group g's runs of region r (kind 0: cluster_place.comp writes them, then its list's
// last workgroup turns them into the group's first command), its entries with runs (kind 1)
// or, with fixed places, its runs again (kind 2: the group's draw count) are kept in Offsets,
// after the entries' places.
uint group_slot(uint kind, uint r, uint g) {
    return 12u * cull.screen.z + (2u * kind + r) * cull.groups.x + g;
}

// Fixed places (cull.clusters.y bit 2: engine materials draw the lists group by group, each
// with its pipeline): each group's commands start at a place the CPU knows — the rooms of the
// list's groups before it — instead of right after the runs of the groups before it, and each
// group's runs are its own draw count (group_slot kind 2). tilegraph_passes::cull::ClusterStage
// computes the same rooms.
bool fixed_places() {
    return (cull.clusters.y & 4u) != 0u;
}

// The most commands group g can need: one per cluster of each of its entries (a run holds a
// cluster at least; every entry of a group draws the group's mesh).
uint group_room(uint g) {
    Group group = cluster_groups[g];
    return group.len * mesh_clusters[group.mesh].y;
}

// Where the draw group of entry e (of lists 0-3) is kept in Offsets (cluster_place.comp
// writes it: a list's groups are in draw order, not in entry order).
uint group_of_entry(uint e) {
    return 8u * cull.screen.z + e;
}

// Where chunk w's runs of region r are kept (Runs).
uint chunk_slot(uint r, uint w) {
    return 8u * cull.screen.z + r * chunk_count() + w;
}

#endif
