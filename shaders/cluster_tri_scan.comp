#version 450
// Per-triangle culling, second step (common/triangles.glsl): one workgroup places each
// command's surviving triangles in the tail of the index buffer, in list and command order
// (an exclusive prefix sum over the counts). A command whose triangles would run past the
// tail's end keeps its cluster range (0xFFFFFFFF): drawn whole, still in its place.
#include "scene.glsl"
#include "cull.glsl"
#include "triangles.glsl"

layout(local_size_x = 256) in;

shared uint sums[256];

void main() {
    uint t = gl_LocalInvocationID.x;
    uint total = tri_commands();
    uint per = (total + 255u) / 256u;
    uint from = min(t * per, total);
    uint to = min(from + per, total);
    // Each thread sums a run of consecutive commands, the runs' sums are scanned, then each
    // thread walks its run again from its run's start.
    uint mine = 0u;
    for (uint c = from; c < to; ++c) {
        mine += 3u * tri[tri_command(c).x];
    }
    sums[t] = mine;
    barrier();
    for (uint d = 1u; d < 256u; d <<= 1u) {
        uint add = t >= d ? sums[t - d] : 0u;
        barrier();
        sums[t] += add;
        barrier();
    }
    uint at = sums[t] - mine;
    uint capacity = cull.triangles.y;
    for (uint c = from; c < to; ++c) {
        uint cmd = tri_command(c).x;
        uint n = 3u * tri[cmd];
        tri[tri_offset_slot(cmd)] = at + n <= capacity ? at : 0xFFFFFFFFu;
        at += n;
    }
}
