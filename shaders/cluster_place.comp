#version 450
// Cluster culling, second step: one workgroup per draw group and region places the runs of the
// group's entries (an exclusive prefix sum in entry order, relative to the group's first
// command) and writes the group's runs and how many of its entries have any (cluster.glsl's
// group_slot), and, in region 0, each entry's group (cluster_emit.comp's lookup). The entries'
// runs are their chunks' (cluster_cull.comp adds them; cluster_emit.comp zeroes them for the
// next culling to add to). An entry whose instance is culled has none: the group's entries
// need no test, and the instance compaction does not run.
//
// The last workgroup to finish a list's groups (a counter per phase and list in the work
// buffer, which a transfer zeroes every frame) then places the list's groups: each group's
// first command among the list's (an exclusive prefix sum in the frame's group order, in
// place), and writes the list's draw count and the instances its commands draw. One dispatch
// instead of two: which workgroup finishes last does not matter, only that every group's
// places are written and visible before it reads them (coherent writes, a buffer memory
// barrier, then the counter's atomic; the reader orders its reads after the atomic the same
// way), the pattern of single-pass reductions that needs no forward progress between
// workgroups.
//
// Workgroup w is group w % groups of region w / groups: the early (or only) dispatch runs
// region 0 (lists 0-3) and empties the late lists' counts, the late one both regions (lists
// 0-7: the colour pass's union, then the late depth pass's).
#define CLUSTER_WORK_COUNTERS
#include "cull.glsl"
#include "cluster.glsl"

layout(local_size_x = 64) in;

// Per list: the draw count (0-7), then the instances its commands draw (8-15).
layout(set = 1, binding = 2, std430) writeonly buffer Counts { uint counts[]; };

// Each thread owns PER_THREAD consecutive entries of a chunk (as cull_compact.comp): a group of
// up to 1,024 entries is one pass of loads, one 64-wide scan and one pass of stores.
const uint PER_THREAD = 16u;
const uint CHUNK = 64u * PER_THREAD;
// Groups a thread owns in a chunk of the list's groups (as cull_commands.comp).
const uint GROUPS_PER_THREAD = 8u;
const uint GROUP_CHUNK = 64u * GROUPS_PER_THREAD;

// Per thread: its entries' runs (x) and how many of them have any (y).
shared uvec2 scan[64];
shared bool last_of_list;
shared uint instances;

// Inclusive scan of the threads' values in `scan` (Hillis-Steele in shared memory: portable, no
// subgroup size assumptions).
void scan_threads() {
    uint t = gl_LocalInvocationID.x;
    barrier();
    for (uint d = 1u; d < 64u; d <<= 1u) {
        uvec2 add = t >= d ? scan[t - d] : uvec2(0u);
        barrier();
        scan[t] += add;
        barrier();
    }
}

// Places the runs of group g's entries in region r; returns the group's runs and entries with
// runs (thread 0's is the one that counts).
uvec2 place_group(uint r, uint g) {
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
        scan[t] = mine;
        scan_threads();
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
    return placed;
}

// Turns the runs of list `list`'s groups into their first commands and writes its counts. With
// fixed places (cluster.glsl) a group's first command is the rooms of the groups before it, and
// its runs are kept as its draw count.
void place_list(uint list) {
    uint r = list / 4u;
    uint start = cull.group_start[list % 4u];
    uint n = cull.group_count[list % 4u];
    uint t = gl_LocalInvocationID.x;
    bool pinned = fixed_places();
    uvec2 placed = uvec2(0u); // commands placed (rooms with fixed places), runs
    for (uint chunk = 0u; chunk < n; chunk += GROUP_CHUNK) {
        uint first = chunk + t * GROUPS_PER_THREAD;
        uint last = min(first + GROUPS_PER_THREAD, n);
        uvec2 mine = uvec2(0u);
        uint drawn = 0u;
        for (uint j = first; j < last; ++j) {
            uint runs_of_group = offsets[group_slot(0u, r, start + j)];
            mine += uvec2(pinned ? group_room(start + j) : runs_of_group, runs_of_group);
            drawn += offsets[group_slot(1u, r, start + j)];
        }
        scan[t] = mine;
        scan_threads();
        uint at = placed.x + scan[t].x - mine.x;
        uint runs_before = placed.y + scan[t].y - mine.y;
        for (uint j = first; j < last; ++j) {
            uint slot = group_slot(0u, r, start + j);
            uint runs_of_group = offsets[slot];
            offsets[slot] = at;
            if (pinned) {
                // The group's draw count, and the runs of the list's groups before it (its
                // entries with runs are summed above: per-triangle culling finds a command's
                // group by them, common/triangles.glsl).
                offsets[group_slot(2u, r, start + j)] = runs_of_group;
                offsets[group_slot(1u, r, start + j)] = runs_before;
                at += group_room(start + j);
            } else {
                at += runs_of_group;
            }
            runs_before += runs_of_group;
        }
        if (drawn != 0u) {
            atomicAdd(instances, drawn);
        }
        placed += scan[63];
        barrier();
    }
    if (t == 0u) {
        counts[list] = placed.y;
        counts[8u + list] = instances;
    }
}

void main() {
    uint t = gl_LocalInvocationID.x;
    uint phase = work_region();
    uint regions = phase + 1u; // the late phase places the union's runs again
    // Lists no group of the frame belongs to have no last workgroup: the dispatch's first
    // empties them (and the early dispatch the late lists, which only the late one fills).
    if (gl_WorkGroupID.x == 0u && t < 8u) {
        if (t >= 4u * regions || cull.group_count[t % 4u] == 0u) {
            counts[t] = 0u;
            counts[8u + t] = 0u;
        }
    }
    if (cull.groups.x == 0u) {
        return;
    }
    uint g = gl_WorkGroupID.x % cull.groups.x;
    uint r = gl_WorkGroupID.x / cull.groups.x;
    uvec2 placed = place_group(r, g);
    uint list = 4u * r + cluster_groups[g].list;
    if (t == 0u) {
        offsets[group_slot(0u, r, g)] = placed.x;
        offsets[group_slot(1u, r, g)] = placed.y;
        instances = 0u;
    }
    // Every place this workgroup wrote is visible before the counter says so.
    memoryBarrierBuffer();
    barrier();
    if (t == 0u) {
        uint done = atomicAdd(work[8u + 8u * phase + list], 1u);
        last_of_list = done + 1u == cull.group_count[list % 4u];
    }
    barrier();
    if (last_of_list) {
        memoryBarrierBuffer();
        place_list(list);
    }
}
