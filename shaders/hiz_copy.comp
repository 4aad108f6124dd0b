#version 460
// The pyramid's base level from the depth image. At level 0 (full resolution) a copy, texel for
// texel: the depth buffer as the CPU reference sees it (no arithmetic on D32; D16 values are
// re-derived exactly, see hiz_d16_exact in hiz.glsl). At level b > 0 (knob hiz_resolution: half,
// quarter) each texel is the farthest depth of its level-0 footprint, which is what b levels of
// reductions give: max and min are exact, so the order they are taken in does not matter and the
// level is bit-identical to the CPU reference's level b (docs/CULLING.md).
#extension GL_EXT_samplerless_texture_functions : require
#define HIZ_BUILD
#include "hiz.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// The depth view (DEPTH aspect only, one mip), read with texelFetch: no sampler, no filtering.
layout(set = 0, binding = 0) uniform texture2D depth_image;

float depth_at(uvec2 p) {
    float d = texelFetch(depth_image, ivec2(p), 0).r;
    if (pc.rule == HIZ_COPY_D16) {
        // Any conversion within half a code of k / 65535 gives back k.
        uint k = min(uint(round(clamp(d, 0.0, 1.0) * 65535.0)), 65535u);
        d = hiz_d16_exact(k);
    }
    return d;
}

void main() {
    uvec2 t = gl_GlobalInvocationID.xy;
    if (any(greaterThanEqual(t, pc.dst_extent))) {
        return;
    }
    uint b = pc.base_level;
    uvec2 lo = t;
    uvec2 hi = t;
    if (b > 0u && pc.npot == HIZ_NPOT_PAD) {
        // Level-1 texels [t 2^(b-1), (t+1) 2^(b-1) - 1] (clamped to P), each reading level 0's
        // [u w / P, ceil((u + 1) w / P) - 1].
        uvec2 w = pc.src_extent;
        uvec2 p = pc.pow2_extent;
        uvec2 first = t << (b - 1u);
        uvec2 last = min(((t + 1u) << (b - 1u)) - 1u, p - 1u);
        lo = (first * w) / p;
        hi = ((last + 1u) * w + p - 1u) / p - 1u;
    } else if (b > 0u) {
        // EdgeAware: 2^b pixels per texel; the last texel of a level also takes what the odd
        // sizes left over below it, down to the depth image's last row and column.
        lo = t << b;
        hi = mix(((t + 1u) << b) - 1u, pc.src_extent - 1u, equal(t, pc.dst_extent - 1u));
    }
    float v = depth_at(lo);
    for (uint y = lo.y; y <= hi.y; ++y) {
        for (uint x = lo.x; x <= hi.x; ++x) {
            float d = depth_at(uvec2(x, y));
            v = pc.convention == HIZ_STANDARD_MAX ? max(v, d) : min(v, d);
        }
    }
    pyramid.texels[pc.dst_offset + t.y * pc.dst_extent.x + t.x] = v;
}
