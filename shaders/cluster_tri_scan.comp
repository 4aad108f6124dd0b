#version 450
// Per-triangle culling, second step (common/triangles.glsl): one workgroup places each
// command's kept triangles in the tail of the index buffer, in list and command order (an
// exclusive prefix sum), and keeps each command's range as the emit wrote it for the write
// step. A command whose triangles would run past the tail's end, or that has more slices than
// were counted, keeps its cluster range (0xFFFFFFFF): drawn whole, still in its place.
#include "scene.glsl"
#include "cull.glsl"
#include "triangles.glsl"

layout(local_size_x = 256) in;

shared uint sums[256];

// The indices command slot `cmd` keeps; 0 for one it draws whole (too long to have been
// counted).
uint kept_indices(uint cmd) {
    uint n = commands[5u * cmd] / 3u;
    if (n > TRI_SLICE * TRI_SLICES) {
        return 0u;
    }
    uint kept = 0u;
    for (uint s = 0u; s * TRI_SLICE < n; ++s) {
        kept += tri[tri_slice_slot(cmd, s)];
    }
    return 3u * kept;
}

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
        mine += kept_indices(tri_command(c).x);
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
        uint count = commands[5u * cmd];
        uint n = kept_indices(cmd);
        bool counted = count / 3u <= TRI_SLICE * TRI_SLICES;
        tri[tri_place_slot(cmd)] = counted && at + n <= capacity ? at : 0xFFFFFFFFu;
        tri[tri_source_slot(cmd)] = count;
        tri[tri_source_slot(cmd) + 1u] = commands[5u * cmd + 2u];
        at += n;
    }
}
