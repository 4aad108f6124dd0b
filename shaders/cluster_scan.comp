#version 450
// Cluster culling, second step: one workgroup per list places each entry's runs among the
// list's commands (an exclusive prefix sum over the entries in the unculled draw order: the
// list's groups in the frame's order, each group's entries in entry order) and writes the
// list's draw count. The entries' runs are their chunks' (cluster_cull.comp adds them;
// cluster_emit.comp zeroes them for the next culling to add to). Workgroup w is list w: the
// early (or only) dispatch runs lists 0-3 and empties the late lists' counts, the late one 0-7.
#include "cull.glsl"
#include "cluster.glsl"

// 256 threads: one list's entries are scanned by one workgroup, so its width sets how many
// sequential chunks a large scene takes (17,408 entries: 5 chunks; at 64 threads, 17 chunks
// cost 0.052 ms on an H100 per dispatch).
layout(local_size_x = 256) in;

// Per list: the draw count (0-7), then the cluster instances its commands draw (8-15, unused
// here: triangles are counted on readback).
layout(set = 1, binding = 2, std430) writeonly buffer Counts { uint counts[]; };

const uint THREADS = 256u;
const uint PER_THREAD = 16u;
const uint CHUNK = THREADS * PER_THREAD;

shared uint scan[THREADS];

// The group of the list holding the list's `i`-th entry in draw order (groups [g0, g0 + n)).
uint group_of(uint g0, uint n, uint i) {
    uint lo = g0;
    uint hi = g0 + n;
    while (hi - lo > 1u) {
        uint mid = (lo + hi) / 2u;
        if (cluster_groups[mid].first <= i) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    return lo;
}

// The entry (of list `list`) of the list's `i`-th entry in draw order, `g` its group.
uint entry_at(uint list, uint g, uint i) {
    Group group = cluster_groups[g];
    return list * cull.screen.z + group.position + (i - group.first);
}

void main() {
    uint list = gl_WorkGroupID.x;
    uint n = cull.list_len[list % 4u];
    uint g0 = cull.group_start[list % 4u];
    uint groups = cull.group_count[list % 4u];
    uint t = gl_LocalInvocationID.x;
    uint placed = 0u;
    for (uint chunk = 0u; chunk < n; chunk += CHUNK) {
        uint first = chunk + t * PER_THREAD;
        uint last = min(first + PER_THREAD, n);
        uint g = first < last ? group_of(g0, groups, first) : g0;
        uint mine = 0u;
        for (uint i = first; i < last; ++i) {
            while (i >= cluster_groups[g].first + cluster_groups[g].len) {
                g += 1u;
            }
            mine += runs[entry_at(list, g, i)];
        }
        scan[t] = mine;
        barrier();
        for (uint d = 1u; d < THREADS; d <<= 1u) {
            uint add = t >= d ? scan[t - d] : 0u;
            barrier();
            scan[t] += add;
            barrier();
        }
        uint at = placed + scan[t] - mine;
        g = first < last ? group_of(g0, groups, first) : g0;
        for (uint i = first; i < last; ++i) {
            while (i >= cluster_groups[g].first + cluster_groups[g].len) {
                g += 1u;
            }
            uint e = entry_at(list, g, i);
            offsets[e] = at;
            at += runs[e];
        }
        placed += scan[THREADS - 1u];
        barrier();
    }
    if (t == 0u) {
        counts[list] = placed;
        if (gl_NumWorkGroups.x == 4u) {
            counts[list + 4u] = 0u;
        }
    }
}
