#version 450
// Ordered compaction, first half: one workgroup per draw group (a mesh's run of consecutive
// entries, common/cull.glsl) packs the ids of the group's surviving entries to the front of the
// group's range of the draw list, in entry order, and writes how many survived. Workgroup w
// handles group w % groups of phase w / groups: the early (or only) dispatch runs one phase,
// the late dispatch both (the early lists again, now the union of both phases, then the late).
// With levels of detail (cull.lod_info.x levels), survivors are counted per group and level.
#include "cull.glsl"

layout(local_size_x = 64) in;

layout(set = 1, binding = 3, std430) writeonly buffer DrawIds { uint draw_ids[]; };
layout(set = 1, binding = 8, std430) readonly buffer Entries { uint entries[]; };
layout(set = 1, binding = 9, std430) readonly buffer Groups { Group groups[]; };
layout(set = 1, binding = 10, std430) writeonly buffer Survivors { uint survivors[]; };

// Each thread owns PER_THREAD consecutive entries of a chunk: a group of up to 1,024 entries is
// one pass of loads, one 64-wide scan and one pass of stores (the scan's barriers are the
// latency; few groups run at once when a scene has few meshes).
const uint PER_THREAD = 16u;
const uint CHUNK = 64u * PER_THREAD;

shared uint scan[64];

void main() {
    uint g = gl_WorkGroupID.x % cull.groups.x;
    uint phase = gl_WorkGroupID.x / cull.groups.x;
    Group group = groups[g];
    uint base = (4u * phase + group.list) * cull.screen.z + group.position;
    uint t = gl_LocalInvocationID.x;
    // With levels of detail, the group's survivors are packed level by level (each level its
    // own command, in entry order within it); without, one level holds them all.
    uint levels = max(cull.lod_info.x, 1u);
    uint packed = 0u;
    for (uint level = 0u; level < levels; ++level) {
        uint level_packed = 0u;
        for (uint chunk = 0u; chunk < group.len; chunk += CHUNK) {
            uint first = chunk + t * PER_THREAD;
            uint last = min(first + PER_THREAD, group.len);
            uint kept = 0u;
            for (uint i = first; i < last; ++i) {
                uint e = entries[base + i];
                kept += e != 0u && (e >> ENTRY_LEVEL_SHIFT) == level ? 1u : 0u;
            }
            // Inclusive scan of the threads' counts (Hillis-Steele in shared memory: portable,
            // no subgroup size assumptions).
            scan[t] = kept;
            barrier();
            for (uint d = 1u; d < 64u; d <<= 1u) {
                uint add = t >= d ? scan[t - d] : 0u;
                barrier();
                scan[t] += add;
                barrier();
            }
            uint at = base + packed + level_packed + scan[t] - kept;
            for (uint i = first; i < last; ++i) {
                uint e = entries[base + i];
                if (e != 0u && (e >> ENTRY_LEVEL_SHIFT) == level) {
                    draw_ids[at] = (e & ENTRY_ID_MASK) - 1u;
                    at += 1u;
                }
            }
            level_packed += scan[63];
            barrier(); // every thread read scan[63] before the next chunk overwrites it
        }
        if (t == 0u) {
            survivors[gl_WorkGroupID.x * levels + level] = level_packed;
        }
        packed += level_packed;
    }
}
