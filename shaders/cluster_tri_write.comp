#version 450
// Per-triangle culling, last step (common/triangles.glsl): a workgroup per slice of a command
// of the phase's lists (x strides over the commands, y is the slice) tests the slice's
// triangles again, copies the indices of those that may be drawn to the slice's place in the
// tail, in their order, and the first slice's workgroup points the command at its packed range.
#define TRI_WRITE
#include "scene.glsl"
#include "cull.glsl"
#include "triangles.glsl"

layout(local_size_x = 256) in;

shared uint scan[256];

void main() {
    uint t = gl_LocalInvocationID.x;
    uint s = gl_WorkGroupID.y;
    uint total = tri_commands();
    for (uint c = gl_WorkGroupID.x; c < total; c += gl_NumWorkGroups.x) {
        uvec2 at = tri_command(c);
        uint cmd = at.x;
        uint place = tri[tri_place_slot(cmd)];
        // The command's range as the emit wrote it (the first slice rewrites the command).
        uint n = tri[tri_source_slot(cmd)] / 3u;
        uint first = tri[tri_source_slot(cmd) + 1u];
        uint from = s * TRI_SLICE;
        if (place == 0xFFFFFFFFu || (from >= n && s != 0u)) {
            continue; // uniform: the command keeps its range, or has no such slice
        }
        uint slices = (n + TRI_SLICE - 1u) / TRI_SLICE;
        uint before = 0u;
        uint kept = 0u;
        for (uint q = 0u; q < slices; ++q) {
            uint k = tri[tri_slice_slot(cmd, q)];
            before += q < s ? k : 0u;
            kept += k;
        }
        uint base = commands[5u * cmd + 3u];
        Instance inst = instance_at(draw_ids[commands[5u * cmd + 4u]]);
        bool back = tri_single_sided(at.y);
        uint dst = cull.triangles.x + place + 3u * before;
        uint to = min(from + TRI_SLICE, n);
        uint written = 0u;
        for (uint b = from; b < to; b += TRI_GROUP) {
            uint k = b + t;
            bool keep = k < to && range_triangle_visible(first, base, inst, k, back);
            scan[t] = keep ? 1u : 0u;
            barrier();
            for (uint d = 1u; d < TRI_GROUP; d <<= 1u) {
                uint add = t >= d ? scan[t - d] : 0u;
                barrier();
                scan[t] += add;
                barrier();
            }
            if (keep) {
                uint o = dst + 3u * (written + scan[t] - 1u);
                uint i = first + 3u * k;
                index_data[o] = index_data[i];
                index_data[o + 1u] = index_data[i + 1u];
                index_data[o + 2u] = index_data[i + 2u];
            }
            written += scan[TRI_GROUP - 1u];
            barrier(); // the last sum read by all before the next batch overwrites it
        }
        if (s == 0u && t == 0u) {
            commands[5u * cmd] = 3u * kept;
            commands[5u * cmd + 2u] = cull.triangles.x + place;
        }
    }
}
