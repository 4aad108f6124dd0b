#version 450
// Cluster culling, third step: one workgroup per list turns its groups' runs (cluster_place.comp)
// into each group's first command among the list's (an exclusive prefix sum in the frame's group
// order, in place) and writes the list's draw count and the instances its commands draw. List w
// draws region w / 4: the early (or only) dispatch runs lists 0-3 and empties the late lists'
// counts, the late one 0-7.
#include "cull.glsl"
#include "cluster.glsl"

layout(local_size_x = 64) in;

// Per list: the draw count (0-7), then the instances its commands draw (8-15).
layout(set = 1, binding = 2, std430) writeonly buffer Counts { uint counts[]; };

// Each thread owns PER_THREAD consecutive groups of a chunk (as cull_commands.comp).
const uint PER_THREAD = 8u;
const uint CHUNK = 64u * PER_THREAD;

shared uint scan[64];
shared uint instances;

void main() {
    uint list = gl_WorkGroupID.x;
    uint r = list / 4u;
    uint start = cull.group_start[list % 4u];
    uint n = cull.group_count[list % 4u];
    uint t = gl_LocalInvocationID.x;
    if (t == 0u) {
        instances = 0u;
    }
    barrier();
    uint placed = 0u;
    for (uint chunk = 0u; chunk < n; chunk += CHUNK) {
        uint first = chunk + t * PER_THREAD;
        uint last = min(first + PER_THREAD, n);
        uint mine = 0u;
        uint drawn = 0u;
        for (uint j = first; j < last; ++j) {
            mine += offsets[group_slot(0u, r, start + j)];
            drawn += offsets[group_slot(1u, r, start + j)];
        }
        scan[t] = mine;
        barrier();
        for (uint d = 1u; d < 64u; d <<= 1u) {
            uint add = t >= d ? scan[t - d] : 0u;
            barrier();
            scan[t] += add;
            barrier();
        }
        uint at = placed + scan[t] - mine;
        for (uint j = first; j < last; ++j) {
            uint slot = group_slot(0u, r, start + j);
            uint runs_of_group = offsets[slot];
            offsets[slot] = at;
            at += runs_of_group;
        }
        if (drawn != 0u) {
            atomicAdd(instances, drawn);
        }
        placed += scan[63];
        barrier();
    }
    if (t == 0u) {
        counts[list] = placed;
        counts[8u + list] = instances;
        if (gl_NumWorkGroups.x == 4u) {
            counts[list + 4u] = 0u;
            counts[8u + list + 4u] = 0u;
        }
    }
}
