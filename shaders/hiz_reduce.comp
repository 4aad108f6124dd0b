#version 460
// HiZ level k from level k-1: each texel is the farthest (max Standard / min Reverse) of the
// source texels its rule picks (see hiz.glsl). Pure min/max, so the result is bit-identical to
// tilegraph_cull::HizPyramid::build.
#define HIZ_BUILD
#include "hiz.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

float src_at(uint x, uint y) {
    return pyramid.texels[pc.src_offset + y * pc.src_extent.x + x];
}

void main() {
    uvec2 t = gl_GlobalInvocationID.xy;
    if (any(greaterThanEqual(t, pc.dst_extent))) {
        return;
    }
    uvec2 lo;
    uvec2 hi;
    if (pc.rule == HIZ_RULE_PAD_FIRST) {
        // floor and ceil of the texel's exact interval [t src/dst, (t+1) src/dst); products stay
        // below 2^32 for extents up to 16384 (MAX_EXTENT_PX).
        lo = (t * pc.src_extent) / pc.dst_extent;
        hi = ((t + 1u) * pc.src_extent + pc.dst_extent - 1u) / pc.dst_extent - 1u;
    } else if (pc.rule == HIZ_RULE_EDGE_AWARE) {
        // The last texel also takes the odd leftover row/column (up to 3x3 at the corner).
        lo = 2u * t;
        hi = mix(2u * t + 1u, pc.src_extent - 1u, equal(t, pc.dst_extent - 1u));
    } else {
        lo = 2u * t;
        hi = min(2u * t + 1u, pc.src_extent - 1u);
    }
    float v = src_at(lo.x, lo.y);
    // The convention is uniform across the dispatch, so the branch is too.
    if (pc.convention == HIZ_STANDARD_MAX) {
        for (uint y = lo.y; y <= hi.y; ++y) {
            for (uint x = lo.x; x <= hi.x; ++x) {
                v = max(v, src_at(x, y));
            }
        }
    } else {
        for (uint y = lo.y; y <= hi.y; ++y) {
            for (uint x = lo.x; x <= hi.x; ++x) {
                v = min(v, src_at(x, y));
            }
        }
    }
    pyramid.texels[pc.dst_offset + t.y * pc.dst_extent.x + t.x] = v;
}
