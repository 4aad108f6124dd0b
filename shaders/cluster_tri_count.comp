#version 450
// Per-triangle culling, first step (common/triangles.glsl): a workgroup per slice of a command
// of the phase's lists (x strides over the commands, y is the slice) tests the slice's
// triangles and stores how many may be drawn.
#include "scene.glsl"
#include "cull.glsl"
#include "triangles.glsl"

layout(local_size_x = 256) in;

shared uint kept;

void main() {
    uint t = gl_LocalInvocationID.x;
    uint s = gl_WorkGroupID.y;
    uint total = tri_commands();
    for (uint c = gl_WorkGroupID.x; c < total; c += gl_NumWorkGroups.x) {
        uvec2 at = tri_command(c);
        uint cmd = at.x;
        uint n = commands[5u * cmd] / 3u;
        uint from = s * TRI_SLICE;
        if (from >= n) {
            continue; // uniform: the command has no such slice
        }
        if (t == 0u) {
            kept = 0u;
        }
        barrier();
        uint first = commands[5u * cmd + 2u];
        uint base = commands[5u * cmd + 3u];
        Instance inst = instance_at(draw_ids[commands[5u * cmd + 4u]]);
        bool back = tri_single_sided(at.y);
        uint to = min(from + TRI_SLICE, n);
        uint mine = 0u;
        for (uint k = from + t; k < to; k += TRI_GROUP) {
            mine += range_triangle_visible(first, base, inst, k, back) ? 1u : 0u;
        }
        if (mine != 0u) {
            atomicAdd(kept, mine);
        }
        barrier();
        if (t == 0u) {
            tri[tri_slice_slot(cmd, s)] = kept;
        }
        barrier(); // `kept` starts afresh for the next command
    }
}
