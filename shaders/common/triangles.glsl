// Per-triangle culling (knob triangle_culling; seed 000, after Wihlidal 2016), shared by
// cluster_tri_count.comp, cluster_tri_scan.comp and cluster_tri_write.comp: after a phase's
// cluster commands are written (cluster_emit.comp), every triangle of every command is tested —
// frustum, back-facing, zero-area, no sample covered, and in two-phase culling's late phase the
// pyramid — and the survivors' indices are packed, in their order, into the tail of the scene's
// index buffer, which the command then draws instead of its cluster range. Needs scene.glsl and
// cull.glsl first.
//
// Exact: a triangle is dropped only where the rasterizer would make no fragment of it, or every
// fragment would fail the depth test. Each test keeps a margin for what the rasterizer's
// sub-pixel snapping and the vertex shader's own rounding can move a vertex by; a triangle it
// cannot decide is kept. Count and write run the same test on the same data, so they agree.
#ifndef TILEGRAPH_TRIANGLES_GLSL
#define TILEGRAPH_TRIANGLES_GLSL

#include "cull_tests.glsl"

// The write step rewrites commands and writes the index buffer's tail; the count and scan
// steps only read them (a binding without NonWritable counts as a write to synchronization
// validation).
#ifdef TRI_WRITE
#define TRI_WRITES
#else
#define TRI_WRITES readonly
#endif

layout(set = 0, binding = 5, std430) readonly buffer Vertices { float vertex_data[]; }; // 8 floats each
layout(set = 0, binding = 6, std430) TRI_WRITES buffer Indices { uint index_data[]; };

// VkDrawIndexedIndirectCommand, 5 uints each (cluster_emit.comp's).
layout(set = 1, binding = 1, std430) TRI_WRITES buffer Commands { uint commands[]; };
// Per list (0-7): its draw count (cluster_place.comp's).
layout(set = 1, binding = 2, std430) readonly buffer Counts { uint counts[]; };
layout(set = 1, binding = 3, std430) readonly buffer DrawIds { uint draw_ids[]; };
// A command's triangles are tested in slices of TRI_SLICE, a workgroup each (a run of 64
// clusters is up to 7,936 triangles: one workgroup per command would leave a few long commands
// to a few cores). Per command slot (w = cull.triangles.w slots): its slices' kept triangles
// (count step), then its first index in the tail (scan step; 0xFFFFFFFF: the tail is full or
// the command is longer than TRI_SLICES slices: it keeps its cluster range), then its index
// count and first index as the emit wrote them (the write step rewrites the command).
const uint TRI_SLICE = 1024u;
const uint TRI_SLICES = 8u;
const uint TRI_GROUP = 256u; // threads of the count and write workgroups
layout(set = 1, binding = 4, std430) buffer Triangles { uint tri[]; };
// The cluster stage's places (common/cluster.glsl's Offsets): with fixed places (engine
// materials), per draw group and region its first command (kind 0) and the runs of its list's
// groups before it (kind 1).
layout(set = 1, binding = 7, std430) readonly buffer Places { uint places[]; };

uint tri_slice_slot(uint cmd, uint s) { return cmd * TRI_SLICES + s; }
uint tri_place_slot(uint cmd) { return TRI_SLICES * cull.triangles.w + cmd; }
uint tri_source_slot(uint cmd) { return (TRI_SLICES + 1u) * cull.triangles.w + 2u * cmd; }

// The lists a phase's triangle stage packs: the early (or only) phase's 0-3; the late phase
// rewrote the union's (0-3) and wrote its own (4-7).
uint tri_lists() {
    return cull.info.y == 3u ? 8u : 4u;
}

// common/cluster.glsl's group_slot (the places of kind `kind` of group g in region r).
uint tri_group_slot(uint kind, uint r, uint g) {
    return 12u * cull.screen.z + (2u * kind + r) * cull.groups.x + g;
}

// Where the c-th command of list l sits among the list's: packed, the c-th; with fixed places
// (cull.clusters.y bit 2) in the group whose runs cover c — the last whose runs before it are
// at most c (a binary search: the runs before the groups only grow) — after that group's
// first command.
uint tri_place(uint l, uint c) {
    if ((cull.clusters.y & 4u) == 0u) {
        return c;
    }
    uint r = l / 4u;
    uint lo = cull.group_start[l % 4u];
    uint hi = lo + cull.group_count[l % 4u]; // c lies in one of lo..hi
    while (hi - lo > 1u) {
        uint mid = (lo + hi) / 2u;
        if (places[tri_group_slot(1u, r, mid)] <= c) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    return places[tri_group_slot(0u, r, lo)] + c - places[tri_group_slot(1u, r, lo)];
}

// The c-th command of the phase's lists (in list order): its slot and list; x = 0xFFFFFFFF
// past the last.
uvec2 tri_command(uint c) {
    uint lists = tri_lists();
    for (uint l = 0u; l < lists; ++l) {
        uint n = counts[l];
        if (c < n) {
            return uvec2(cull.cmd_base[l / 4u][l % 4u] + tri_place(l, c), l);
        }
        c -= n;
    }
    return uvec2(0xFFFFFFFFu, 0u);
}

// Commands of the phase's lists.
uint tri_commands() {
    uint total = 0u;
    for (uint l = 0u; l < tri_lists(); ++l) {
        total += counts[l];
    }
    return total;
}

// Whether the pipelines drawing list l cull back faces: the single-sided lists (cull.glsl's
// order: opaque, opaque double-sided, alpha-tested, alpha-tested double-sided, per phase).
bool tri_single_sided(uint l) {
    return (l & 1u) == 0u;
}

vec3 tri_position(uint v) {
    uint b = v * 8u;
    return vec3(vertex_data[b], vertex_data[b + 1u], vertex_data[b + 2u]);
}

// How far (in pixels) a vertex may land from where this shader computes it: the rasterizer
// snaps to 2^-sub_pixel_bits (cull.triangles.z, f32 bits) and the vertex shader rounds its own
// product (a few ulps of coordinates up to the guard band).
float tri_slack() {
    return uintBitsToFloat(cull.triangles.z) + 1.0 / 256.0;
}

// Whether the triangle of (local-space) vertices a, b, c of `inst` may make a fragment that
// passes the depth test. `cull_back`: the pipeline culls back faces (front: counter-clockwise
// in framebuffer coordinates, y down; VkViewport of positive height).
bool triangle_visible(Instance inst, vec3 a, vec3 b, vec3 c, bool cull_back) {
    if (a == b || b == c || c == a) {
        return false; // two equal vertices: zero area however it is snapped
    }
    vec3 pa = instance_transform(inst, a);
    vec3 pb = instance_transform(inst, b);
    vec3 pc = instance_transform(inst, c);
    vec4 h[3];
    h[0] = frame.view_proj * vec4(pa, 1.0);
    h[1] = frame.view_proj * vec4(pb, 1.0);
    h[2] = frame.view_proj * vec4(pc, 1.0);
    // Clip volume: all three beyond one plane (any w: the triangle is their convex
    // combination in clip space). A relative margin for the vertex shader's rounding.
    const float m = 1e-5;
    // Per plane (x > w, x < -w, y > w, y < -w, z < 0, z > w): how many vertices lie beyond it.
    uint beyond[6] = uint[6](0u, 0u, 0u, 0u, 0u, 0u);
    for (uint i = 0u; i < 3u; ++i) {
        vec4 v = h[i];
        float e = m * (abs(v.x) + abs(v.y) + abs(v.z) + abs(v.w));
        beyond[0] += v.x > v.w + e ? 1u : 0u;
        beyond[1] += v.x < -v.w - e ? 1u : 0u;
        beyond[2] += v.y > v.w + e ? 1u : 0u;
        beyond[3] += v.y < -v.w - e ? 1u : 0u;
        beyond[4] += v.z < -e ? 1u : 0u;
        beyond[5] += v.z > v.w + e ? 1u : 0u;
    }
    for (uint k = 0u; k < 6u; ++k) {
        if (beyond[k] == 3u) {
            return false;
        }
    }
    // Screen-space tests need every vertex in front of the eye; a triangle through the eye's
    // plane is kept (clipping makes of it what projection cannot say here).
    float min_w = min(h[0].w, min(h[1].w, h[2].w));
    float max_abs_w = max(abs(h[0].w), max(abs(h[1].w), abs(h[2].w)));
    if (!(min_w > 1e-4 * max_abs_w) || min_w <= 0.0) {
        return true;
    }
    vec2 size = frame.viewport.xy;
    vec2 s0 = (h[0].xy / h[0].w * 0.5 + 0.5) * size;
    vec2 s1 = (h[1].xy / h[1].w * 0.5 + 0.5) * size;
    vec2 s2 = (h[2].xy / h[2].w * 0.5 + 0.5) * size;
    // The vertex shader's clip position may differ from this one by a few ulps of its terms;
    // after the division that is a few ulps of the vertex's distance from the screen's centre
    // in units of w, which for a vertex far off screen (near the eye's plane) is more than the
    // snapping step.
    float reach = 0.0;
    for (uint i = 0u; i < 3u; ++i) {
        reach = max(reach, (abs(h[i].x) + abs(h[i].y) + abs(h[i].z) + abs(h[i].w)) / h[i].w);
    }
    float slack = tri_slack() + 4e-6 * reach * max(size.x, size.y);
    vec2 lo = min(s0, min(s1, s2)) - slack;
    vec2 hi = max(s0, max(s1, s2)) + slack;
    // No sample: no pixel centre k + 0.5 inside the box on one axis, or none on screen.
    vec2 first = max(ceil(lo - 0.5), vec2(0.0));
    vec2 last = min(floor(hi - 0.5), size - 1.0);
    if (any(greaterThan(first, last))) {
        return false;
    }
    if (cull_back) {
        // Vulkan's signed area (framebuffer y down): a = -1/2 sum(x_i y_(i+1) - x_(i+1) y_i),
        // front-facing when positive (counter-clockwise). Snapping moves each vertex by at most
        // `slack`, which changes twice the area by at most slack * (sum of the edges' |dx|+|dy|)
        // * 2, plus the rounding of these products.
        vec2 e1 = s1 - s0;
        vec2 e2 = s2 - s0;
        float twice = -(e1.x * e2.y - e1.y * e2.x);
        vec2 e3 = s2 - s1;
        float perimeter = abs(e1.x) + abs(e1.y) + abs(e2.x) + abs(e2.y) + abs(e3.x) + abs(e3.y);
        float margin = 2.0 * slack * perimeter + 8.0 * slack * slack
            + 1e-6 * (abs(e1.x * e2.y) + abs(e1.y * e2.x));
        if (twice < -margin) {
            return false;
        }
    }
    // Occlusion: the pyramid of this frame's early depth (late phase only).
    if (cull.info.y == 3u && cull.info.z != 0u) {
        vec4 q[3];
        q[0] = cull.hiz_view_proj * vec4(pa, 1.0);
        q[1] = cull.hiz_view_proj * vec4(pb, 1.0);
        q[2] = cull.hiz_view_proj * vec4(pc, 1.0);
        Projected p;
        bool reverse = cull.info.w == 1u;
        p.lo = vec2(1e30);
        p.hi = vec2(-1e30);
        p.nearest = reverse ? 0.0 : 1.0;
        float farthest = reverse ? 1.0 : 0.0;
        vec2 px[3];
        vec2 screen = vec2(cull.screen.xy);
        for (uint i = 0u; i < 3u; ++i) {
            if (q[i].w <= 1e-6) {
                return true;
            }
            vec3 ndc = q[i].xyz / q[i].w;
            if (reverse ? ndc.z >= 1.0 : ndc.z <= 0.0) {
                return true;
            }
            p.lo = min(p.lo, ndc.xy);
            p.hi = max(p.hi, ndc.xy);
            p.nearest = reverse ? max(p.nearest, ndc.z) : min(p.nearest, ndc.z);
            farthest = reverse ? min(farthest, ndc.z) : max(farthest, ndc.z);
            px[i] = (ndc.xy * 0.5 + 0.5) * screen;
        }
        // A sample inside the snapped triangle but outside this one takes its depth from the
        // triangle's plane, extrapolated: nearer than every vertex by up to the depth's slope
        // times the slack. The slope is at most the depth range over the triangle's least
        // height (twice its area over its longest edge); a sliver too thin to bound is kept.
        vec2 e1 = px[1] - px[0];
        vec2 e2 = px[2] - px[0];
        vec2 e3 = px[2] - px[1];
        float twice = abs(e1.x * e2.y - e1.y * e2.x);
        float longest = max(length(e1), max(length(e2), length(e3)));
        float height = twice / max(longest, 1e-30);
        if (!(height > 4.0 * slack)) {
            return true;
        }
        float reach = abs(farthest - p.nearest) * (2.0 * slack / height) * 1.001;
        p.nearest = reverse ? p.nearest + reach : p.nearest - reach;
        // The rect grown by the slack too.
        vec2 grow = 2.0 * slack / screen;
        p.lo -= grow;
        p.hi += grow;
        return hiz_rect_visible(p, 8u);
    }
    return true;
}

// Whether triangle t (0-based) of the range from index `first`, vertex offset `base`, may be
// drawn.
bool range_triangle_visible(uint first, uint base, Instance inst, uint t, bool cull_back) {
    uint i = first + 3u * t;
    vec3 a = tri_position(index_data[i] + base);
    vec3 b = tri_position(index_data[i + 1u] + base);
    vec3 c = tri_position(index_data[i + 2u] + base);
    return triangle_visible(inst, a, b, c, cull_back);
}

#endif
