// The body of cull_commands.comp and cull_commands_lod.comp (LOD_LEVELS).
#include "scene.glsl"
#include "cull.glsl"

layout(local_size_x = 64) in;

layout(set = 1, binding = 1, std430) writeonly buffer Commands { uint commands[]; }; // 5 uints each
// Per list: the draw count (0-7), then the instances its commands draw (8-15).
layout(set = 1, binding = 2, std430) writeonly buffer Counts { uint counts[]; };
layout(set = 1, binding = 9, std430) readonly buffer Groups { Group groups[]; };
layout(set = 1, binding = 10, std430) readonly buffer Survivors { uint survivors[]; };
layout(set = 1, binding = 13, std430) readonly buffer Lods { Lod lods[]; };

// Each thread owns PER_THREAD consecutive groups of a chunk (as cull_compact.comp).
const uint PER_THREAD = 8u;
// Levels per group, fixed per variant (as cull_compact_body.glsl): 1 in cull_commands.comp,
// the mesh and its coarser levels in cull_commands_lod.comp.
#ifndef LOD_LEVELS
#define LOD_LEVELS 1u
#endif
const uint CHUNK = 64u * PER_THREAD;

shared uint scan[64];
shared uint drawn_total;

void main() {
    uint list = gl_WorkGroupID.x;
    uint local_list = list % 4u;
    uint phase = list / 4u;
    uint start = cull.group_start[local_list];
    uint n = cull.group_count[local_list];
    bool keep_empty = cull.groups.y == 1u;
    // A command per group and level of detail (1 level: none), survivors counted likewise.
    const uint levels = LOD_LEVELS;
    uint t = gl_LocalInvocationID.x;
    if (t == 0u) {
        drawn_total = 0u;
    }
    barrier();
    uint written = 0u;
    for (uint chunk = 0u; chunk < n; chunk += CHUNK) {
        uint first = chunk + t * PER_THREAD;
        uint last = min(first + PER_THREAD, n);
        uint kept = 0u;
        for (uint j = first; j < last; ++j) {
            for (uint level = 0u; level < levels; ++level) {
                uint count = survivors[(phase * cull.groups.x + start + j) * levels + level];
                kept += keep_empty || count != 0u ? 1u : 0u;
            }
        }
        scan[t] = kept;
        barrier();
        for (uint d = 1u; d < 64u; d <<= 1u) {
            uint add = t >= d ? scan[t - d] : 0u;
            barrier();
            scan[t] += add;
            barrier();
        }
        uint k = written + scan[t] - kept;
        uint drawn = 0u;
        for (uint j = first; j < last; ++j) {
            uint g = start + j;
            Group group = groups[g];
            Mesh m = meshes[group.mesh];
            uint offset = 0u; // the group's survivors of the levels before
            for (uint level = 0u; level < levels; ++level) {
                uint count = survivors[(phase * cull.groups.x + g) * levels + level];
                drawn += count;
                if (count == 0u && !keep_empty) {
                    continue;
                }
                uint first_index = m.first_index;
                uint index_count = m.index_count;
                if (level > 0u) {
                    Lod l = lods[group.mesh * MAX_LODS + level - 1u];
                    first_index = l.first_index;
                    index_count = l.index_count;
                }
                uint at = list * cull.commands.x + k;
                commands[5u * at + 0u] = index_count;
                commands[5u * at + 1u] = count;
                commands[5u * at + 2u] = first_index;
                commands[5u * at + 3u] = uint(m.vertex_offset);
                commands[5u * at + 4u] = list * cull.screen.z + group.position + offset; // firstInstance
                offset += count;
                k += 1u;
            }
        }
        if (drawn != 0u) {
            atomicAdd(drawn_total, drawn);
        }
        written += scan[63];
        barrier();
    }
    if (t == 0u) {
        counts[list] = written;
        counts[8u + list] = drawn_total;
        if (gl_NumWorkGroups.x == 4u) {
            // The early (or only) phase empties the late lists; a late phase refills them.
            counts[list + 4u] = 0u;
            counts[8u + list + 4u] = 0u;
        }
    }
}
