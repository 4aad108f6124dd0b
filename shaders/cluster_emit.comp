#version 450
// Cluster culling, last step: a workgroup per chunk of 64 clusters of an instance (the phase's
// chunk list, as cluster_cull.comp's) writes one
// indexed indirect command per run of consecutive drawn clusters of each region the chunk has
// runs in (a run ends at the chunk's end), at its entry's place — its group's first command
// (placed by cluster_place.comp's last workgroup of its list), then its place in the group
// (cluster_place.comp) — after the runs of the instance's chunks before it, in cluster order:
// the frame draws the surviving index ranges in the unculled order (instance by instance, as
// the unculled instanced draw). Each command
// draws one instance whose id it stores in the draw list (firstInstance points at it).
#include "scene.glsl"
#include "cull.glsl"
#include "cluster.glsl"

layout(local_size_x = 64) in;

// VkDrawIndexedIndirectCommand, 5 uints each. Coherent: a run's start and end may be found by
// different threads, and the end's index count is fixed up after a barrier.
layout(set = 1, binding = 1, std430) coherent buffer Commands { uint commands[]; };
layout(set = 1, binding = 3, std430) writeonly buffer DrawIds { uint draw_ids[]; };
// Per command (from draw id cull.clusters.x on, which word 0 holds): the mesh's triangle its run
// starts at (visbuf.vert's DrawRuns: the visibility buffer's ids count from it).
layout(set = 1, binding = 18, std430) buffer RunTriangles {
    uint run_base;
    uint run_first_triangle[];
};
layout(set = 1, binding = 7, std430) readonly buffer Order { uint order[]; };

shared uint scan[64];

// The runs of region r in the chunks of the instance before chunk w (from its first, `from`).
uint runs_before(uint r, uint from, uint w) {
    if (w == from) {
        return 0u; // the instance's first chunk (most instances' only one)
    }
    uint t = gl_LocalInvocationID.x;
    uint mine = 0u;
    for (uint k = from + t; k < w; k += 64u) {
        mine += runs[chunk_slot(r, k)];
    }
    scan[t] = mine;
    barrier();
    for (uint d = 32u; d > 0u; d >>= 1u) {
        if (t < d) {
            scan[t] += scan[t + d];
        }
        barrier();
    }
    uint total = scan[0];
    barrier();
    return total;
}

// Flag of cluster c of the chunk [first, end) in region r of an instance whose first cluster
// instance is `base`; 0 outside the chunk.
uint flag(uint r, uint base, uint c, uint first, uint end) {
    return c >= first && c < end ? flags[r * cull.clusters.z + base + c] : 0u;
}

void emit(uint r, uint w, uint id, uint e, uint g, Instance inst, uvec2 range, uint base, uint first) {
    uint t = gl_LocalInvocationID.x;
    uint n = runs[chunk_slot(r, w)];
    if (n == 0u) {
        return;
    }
    uint list = 4u * r + e / cull.screen.z;
    uint before = runs_before(r, chunk_first(id), w);
    uint first_cmd = cull.cmd_base[list / 4u][list % 4u] + offsets[group_slot(0u, r, g)]
        + offsets[r * 4u * cull.screen.z + e] + before;
    Mesh m = meshes[inst.mesh];
    uint end = min(first + 64u, range.y);
    uint c = first + t;
    uint f = flag(r, base, c, first, end);
    bool start = f == 1u && flag(r, base, c - 1u, first, end) == 0u;
    bool last = f == 1u && flag(r, base, c + 1u, first, end) == 0u;
    scan[t] = start ? 1u : 0u;
    barrier();
    for (uint d = 1u; d < 64u; d <<= 1u) {
        uint add = t >= d ? scan[t - d] : 0u;
        barrier();
        scan[t] += add;
        barrier();
    }
    if (f == 1u) {
        // Runs begun up to this cluster (inclusive): the run it starts or belongs to is the
        // last of them.
        uint cmd = first_cmd + scan[t] - 1u;
        Cluster cl = clusters[range.x + c];
        if (start) {
            commands[5u * cmd + 1u] = 1u;
            commands[5u * cmd + 2u] = cl.first_index;
            commands[5u * cmd + 3u] = uint(m.vertex_offset);
            commands[5u * cmd + 4u] = cull.clusters.x + cmd;
            draw_ids[cull.clusters.x + cmd] = id;
            run_first_triangle[cmd] = (cl.first_index - m.first_index) / 3u;
        }
        if (last) {
            // The end of the run's indices for now; the count once every start is written.
            commands[5u * cmd + 0u] = cl.first_index + cl.index_count;
        }
    }
    memoryBarrierBuffer();
    barrier();
    if (t < n) {
        uint cmd = first_cmd + t;
        commands[5u * cmd + 0u] -= commands[5u * cmd + 2u];
    }
    barrier();
}

// Writes the commands of chunk w (uniform over the workgroup: every return is).
void emit_chunk(uint w) {
    uint id = chunk_instance(w);
    if (id >= cull.info.x || order[id] == 0xFFFFFFFFu) {
        return;
    }
    uint e = order[id];
    Instance inst = instance_at(id);
    uvec2 range = mesh_clusters[inst.mesh];
    uint base = cluster_base[id];
    uint first = (w - chunk_first(id)) * 64u;
    // The entry's runs are placed (cluster_place.comp read them): zero them for the next culling to add
    // to (by the first chunk's workgroup; only this phase's regions were added to).
    if (gl_LocalInvocationID.x == 0u && first == 0u) {
        runs[e] = 0u;
        if (cull.info.y == 3u) {
            runs[4u * cull.screen.z + e] = 0u;
        }
    }
    uint g = offsets[group_of_entry(e)];
    emit(0u, w, id, e, g, inst, range, base, first);
    if (cull.info.y == 3u) {
        emit(1u, w, id, e, g, inst, range, base, first);
    }
}

void main() {
    uint r = work_region();
    uint n = work_count(r);
    for (uint i = gl_WorkGroupID.x; i < n; i += gl_NumWorkGroups.x) {
        emit_chunk(work_chunk(r, i));
        barrier(); // the next chunk's scans start afresh
    }
}
