#version 450
// Per-triangle culling, first step (common/triangles.glsl): a workgroup per command of the
// phase's lists (striding over them) tests the command's triangles, 64 at a time, and stores
// how many may be drawn.
#include "scene.glsl"
#include "cull.glsl"
#include "triangles.glsl"

layout(local_size_x = 64) in;

shared uint kept;

void main() {
    uint t = gl_LocalInvocationID.x;
    uint total = tri_commands();
    for (uint c = gl_WorkGroupID.x; c < total; c += gl_NumWorkGroups.x) {
        uvec2 at = tri_command(c);
        uint cmd = at.x;
        if (t == 0u) {
            kept = 0u;
        }
        barrier();
        uint n = commands[5u * cmd] / 3u;
        Instance inst = instance_at(draw_ids[commands[5u * cmd + 4u]]);
        bool back = tri_single_sided(at.y);
        uint mine = 0u;
        for (uint k = t; k < n; k += 64u) {
            mine += command_triangle_visible(cmd, inst, k, back) ? 1u : 0u;
        }
        if (mine != 0u) {
            atomicAdd(kept, mine);
        }
        barrier();
        if (t == 0u) {
            tri[cmd] = kept;
        }
        barrier(); // `kept` starts afresh for the next command
    }
}
