#version 450
// Cluster culling, second step: one workgroup per draw group and region places the runs of the
// group's entries (an exclusive prefix sum in entry order, relative to the group's first
// command) and writes the group's runs and how many of its entries have any (cluster.glsl's
// group_slot), and, in region 0, each entry's group (cluster_emit.comp's lookup). The entries' runs are their chunks' (cluster_cull.comp adds them;
// cluster_emit.comp zeroes them for the next culling to add to). An entry whose instance is
// culled has none: the group's entries need no test, and the instance compaction does not run.
// Workgroup w is group w % groups of region w / groups: the early (or only) dispatch runs
// region 0, the late one both (the colour pass's union, then the late depth pass's).
#include "cull.glsl"
#include "cluster.glsl"

layout(local_size_x = 64) in;

// Each thread owns PER_THREAD consecutive entries of a chunk (as cull_compact.comp): a group of
// up to 1,024 entries is one pass of loads, one 64-wide scan and one pass of stores.
const uint PER_THREAD = 16u;
const uint CHUNK = 64u * PER_THREAD;

// Per thread: its entries' runs (x) and how many of them have any (y).
shared uvec2 scan[64];

void main() {
    uint g = gl_WorkGroupID.x % cull.groups.x;
    uint r = gl_WorkGroupID.x / cull.groups.x;
    Group group = cluster_groups[g];
    uint base = r * 4u * cull.screen.z + group.list * cull.screen.z + group.position;
    uint t = gl_LocalInvocationID.x;
    uvec2 placed = uvec2(0u);
    for (uint chunk = 0u; chunk < group.len; chunk += CHUNK) {
        uint first = chunk + t * PER_THREAD;
        uint last = min(first + PER_THREAD, group.len);
        uvec2 mine = uvec2(0u);
        for (uint i = first; i < last; ++i) {
            uint n = runs[base + i];
            mine += uvec2(n, n != 0u ? 1u : 0u);
        }
        // Inclusive scan of the threads' sums (Hillis-Steele in shared memory: portable, no
        // subgroup size assumptions).
        scan[t] = mine;
        barrier();
        for (uint d = 1u; d < 64u; d <<= 1u) {
            uvec2 add = t >= d ? scan[t - d] : uvec2(0u);
            barrier();
            scan[t] += add;
            barrier();
        }
        uint at = placed.x + scan[t].x - mine.x;
        for (uint i = first; i < last; ++i) {
            offsets[base + i] = at;
            at += runs[base + i];
            if (r == 0u) {
                offsets[group_of_entry(base + i)] = g;
            }
        }
        placed += scan[63];
        barrier(); // every thread read scan[63] before the next chunk overwrites it
    }
    if (t == 0u) {
        offsets[group_slot(0u, r, g)] = placed.x;
        offsets[group_slot(1u, r, g)] = placed.y;
    }
}
