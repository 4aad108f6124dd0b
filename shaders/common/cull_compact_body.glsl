// The body of cull_compact.comp and cull_compact_lod.comp (LOD_LEVELS).
#include "cull.glsl"

layout(local_size_x = 64) in;

layout(set = 1, binding = 3, std430) writeonly buffer DrawIds { uint draw_ids[]; };
layout(set = 1, binding = 8, std430) readonly buffer Entries { uint entries[]; };
layout(set = 1, binding = 9, std430) readonly buffer Groups { Group groups[]; };
layout(set = 1, binding = 10, std430) writeonly buffer Survivors { uint survivors[]; };

// Each thread owns PER_THREAD consecutive entries of a chunk: a group of up to 1,024 entries is
// one pass of loads, one 64-wide scan (of every level's counts at once) and one pass of stores
// (the scan's barriers are the latency; few groups run at once when a scene has few meshes).
const uint PER_THREAD = 16u;
const uint CHUNK = 64u * PER_THREAD;
// Levels per group, fixed per variant: 1 (cull_compact.comp: no levels of detail, one level
// holds the survivors) or the mesh itself and its coarser levels (cull_compact_lod.comp). A
// constant, so that the variant without levels keeps its counts in registers.
#ifndef LOD_LEVELS
#define LOD_LEVELS 1u
#endif
const uint MAX_LEVELS = LOD_LEVELS;

shared uint scan[64u * MAX_LEVELS];
// Per level, the group's survivors (where each level's run starts follows from them).
shared uint totals[MAX_LEVELS];

// Level `e`'s entry is drawn with (0 without levels of detail: the entry is the id + 1).
uint entry_level(uint e) {
    return e >> ENTRY_LEVEL_SHIFT;
}

void main() {
    uint g = gl_WorkGroupID.x % cull.groups.x;
    uint phase = gl_WorkGroupID.x / cull.groups.x;
    Group group = groups[g];
    uint base = (4u * phase + group.list) * cull.screen.z + group.position;
    uint t = gl_LocalInvocationID.x;
    // With levels of detail the group's survivors are packed level by level, each level a run
    // in entry order (its own command); without, one level holds them all.
    const uint levels = MAX_LEVELS;
    if (levels > 1u) {
        if (t < MAX_LEVELS) {
            totals[t] = 0u;
        }
        barrier();
    }
    // A group of several chunks counts its levels first: a level's run starts after every
    // survivor of the levels before it. (One chunk's scan gives the counts itself.)
    bool chunks = group.len > CHUNK;
    if (chunks && levels > 1u) {
        for (uint chunk = 0u; chunk < group.len; chunk += CHUNK) {
            uint first = chunk + t * PER_THREAD;
            uint last = min(first + PER_THREAD, group.len);
            for (uint i = first; i < last; ++i) {
                uint e = entries[base + i];
                if (e != 0u) {
                    atomicAdd(totals[entry_level(e)], 1u);
                }
            }
        }
        barrier();
    }
    uint done[MAX_LEVELS]; // per level, the survivors placed by the chunks before
    for (uint l = 0u; l < MAX_LEVELS; ++l) {
        done[l] = 0u;
    }
    for (uint chunk = 0u; chunk < group.len; chunk += CHUNK) {
        uint first = chunk + t * PER_THREAD;
        uint last = min(first + PER_THREAD, group.len);
        uint kept[MAX_LEVELS];
        for (uint l = 0u; l < MAX_LEVELS; ++l) {
            kept[l] = 0u;
        }
        for (uint i = first; i < last; ++i) {
            uint e = entries[base + i];
            if (e != 0u) {
                kept[min(entry_level(e), MAX_LEVELS - 1u)] += 1u;
            }
        }
        // Inclusive scan of the threads' counts, every level at once (Hillis-Steele in shared
        // memory: portable, no subgroup size assumptions).
        for (uint l = 0u; l < levels; ++l) {
            scan[l * 64u + t] = kept[l];
        }
        barrier();
        for (uint d = 1u; d < 64u; d <<= 1u) {
            uint add[MAX_LEVELS];
            for (uint l = 0u; l < levels; ++l) {
                add[l] = t >= d ? scan[l * 64u + t - d] : 0u;
            }
            barrier();
            for (uint l = 0u; l < levels; ++l) {
                scan[l * 64u + t] += add[l];
            }
            barrier();
        }
        // Where this thread's survivors of each level go: after the levels before, the chunks
        // before and the threads before.
        uint cursor[MAX_LEVELS];
        uint start = 0u;
        for (uint l = 0u; l < levels; ++l) {
            uint total = chunks ? totals[l] : scan[l * 64u + 63u];
            cursor[l] = base + start + done[l] + scan[l * 64u + t] - kept[l];
            start += total;
        }
        for (uint i = first; i < last; ++i) {
            uint e = entries[base + i];
            if (e != 0u) {
                uint l = min(entry_level(e), levels - 1u);
                draw_ids[cursor[l]] = (e & ENTRY_ID_MASK) - 1u;
                cursor[l] += 1u;
            }
        }
        for (uint l = 0u; l < levels; ++l) {
            done[l] += scan[l * 64u + 63u];
        }
        barrier(); // every thread read the scan before the next chunk overwrites it
    }
    if (t < levels) {
        survivors[gl_WorkGroupID.x * levels + t] = done[t];
    }
}
