#version 450
// Per-triangle culling, last step (common/triangles.glsl): a workgroup per command of the
// phase's lists (striding over them) tests its triangles again, 64 at a time, copies the
// indices of those that may be drawn to the command's place in the tail, in their order, and
// points the command at them.
#define TRI_WRITE
#include "scene.glsl"
#include "cull.glsl"
#include "triangles.glsl"

layout(local_size_x = 64) in;

shared uint scan[64];

void main() {
    uint t = gl_LocalInvocationID.x;
    uint total = tri_commands();
    for (uint c = gl_WorkGroupID.x; c < total; c += gl_NumWorkGroups.x) {
        uvec2 at = tri_command(c);
        uint cmd = at.x;
        uint place = tri[tri_offset_slot(cmd)];
        if (place == 0xFFFFFFFFu) {
            continue; // uniform: the tail is full, the command keeps its range
        }
        uint n = commands[5u * cmd] / 3u;
        uint first = commands[5u * cmd + 2u];
        Instance inst = instance_at(draw_ids[commands[5u * cmd + 4u]]);
        bool back = tri_single_sided(at.y);
        uint dst = cull.triangles.x + place;
        uint written = 0u;
        for (uint base = 0u; base < n; base += 64u) {
            uint k = base + t;
            bool keep = k < n && command_triangle_visible(cmd, inst, k, back);
            scan[t] = keep ? 1u : 0u;
            barrier();
            for (uint d = 1u; d < 64u; d <<= 1u) {
                uint add = t >= d ? scan[t - d] : 0u;
                barrier();
                scan[t] += add;
                barrier();
            }
            if (keep) {
                uint o = dst + 3u * (written + scan[t] - 1u);
                uint s = first + 3u * k;
                index_data[o] = index_data[s];
                index_data[o + 1u] = index_data[s + 1u];
                index_data[o + 2u] = index_data[s + 2u];
            }
            written += scan[63];
            barrier(); // scan[63] read by all before the next batch overwrites it
        }
        barrier(); // every thread has read the command; one rewrites it
        if (t == 0u) {
            commands[5u * cmd] = 3u * written;
            commands[5u * cmd + 2u] = dst;
        }
        barrier();
    }
}
