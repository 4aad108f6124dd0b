#version 450
// Cluster culling, last step: one workgroup per instance writes one indexed indirect command
// per run of consecutive drawn clusters of each region it has runs in, at the place
// cluster_scan.comp gave its entry, in cluster order: the frame draws the surviving index
// ranges in the unculled order (instance by instance, as the unculled instanced draw). Each
// command draws one instance whose id it stores in the draw list (firstInstance points at it).
#include "scene.glsl"
#include "cull.glsl"
#include "cluster.glsl"

layout(local_size_x = 64) in;

// VkDrawIndexedIndirectCommand, 5 uints each. Coherent: a run's start and end may be found by
// different threads, and the end's index count is fixed up after a barrier.
layout(set = 1, binding = 1, std430) coherent buffer Commands { uint commands[]; };
layout(set = 1, binding = 3, std430) writeonly buffer DrawIds { uint draw_ids[]; };
layout(set = 1, binding = 7, std430) readonly buffer Order { uint order[]; };

shared uint scan[64];
shared uint before;

// Flag of cluster c (of `count`) in region r of an instance whose first is `base`; 0 outside.
uint flag(uint r, uint base, uint c, uint count) {
    return c < count ? flags[r * cull.clusters.z + base + c] : 0u;
}

void emit(uint r, uint id, uint e, Instance inst, uvec2 range, uint base) {
    uint t = gl_LocalInvocationID.x;
    uint entry = r * 4u * cull.screen.z + e;
    uint n = runs[entry];
    if (n == 0u) {
        return;
    }
    uint list = 4u * r + e / cull.screen.z;
    uint first_cmd = cull.cmd_base[list / 4u][list % 4u] + offsets[entry];
    Mesh m = meshes[inst.mesh];
    if (t == 0u) {
        before = 0u;
    }
    barrier();
    for (uint chunk = 0u; chunk < range.y; chunk += 64u) {
        uint c = chunk + t;
        uint f = flag(r, base, c, range.y);
        bool start = f == 1u && (c == 0u || flag(r, base, c - 1u, range.y) == 0u);
        bool end = f == 1u && flag(r, base, c + 1u, range.y) == 0u;
        uint s = start ? 1u : 0u;
        scan[t] = s;
        barrier();
        for (uint d = 1u; d < 64u; d <<= 1u) {
            uint add = t >= d ? scan[t - d] : 0u;
            barrier();
            scan[t] += add;
            barrier();
        }
        // Runs begun before this cluster (inclusive): the run it starts or belongs to is the
        // last of them.
        uint run = before + scan[t] - 1u;
        if (f == 1u) {
            Cluster cl = clusters[range.x + c];
            uint cmd = first_cmd + run;
            if (start) {
                commands[5u * cmd + 1u] = 1u;
                commands[5u * cmd + 2u] = cl.first_index;
                commands[5u * cmd + 3u] = uint(m.vertex_offset);
                commands[5u * cmd + 4u] = cull.clusters.x + cmd;
                draw_ids[cull.clusters.x + cmd] = id;
            }
            if (end) {
                // The end of the run's indices for now; the count once every start is written.
                commands[5u * cmd + 0u] = cl.first_index + cl.index_count;
            }
        }
        barrier();
        if (t == 0u) {
            before += scan[63];
        }
        barrier();
    }
    memoryBarrierBuffer();
    barrier();
    for (uint j = t; j < n; j += 64u) {
        uint cmd = first_cmd + j;
        commands[5u * cmd + 0u] -= commands[5u * cmd + 2u];
    }
    barrier();
}

void main() {
    uint id = workgroup_instance();
    if (id >= cull.info.x || order[id] == 0xFFFFFFFFu) {
        return;
    }
    uint e = order[id];
    Instance inst = instance_at(id);
    uvec2 range = mesh_clusters[inst.mesh];
    uint base = cluster_base[id];
    emit(0u, id, e, inst, range, base);
    if (cull.info.y == 3u) {
        emit(1u, id, e, inst, range, base);
    }
}
