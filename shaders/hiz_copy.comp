#version 460
// HiZ level 0: the depth buffer as the CPU reference sees it, texel for texel (no arithmetic on
// D32; D16 values are re-derived exactly, see d16_exact).
#extension GL_EXT_samplerless_texture_functions : require
#include "hiz.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// The depth view (DEPTH aspect only, one mip), read with texelFetch: no sampler, no filtering.
layout(set = 0, binding = 0) uniform texture2D depth_image;

// The f32 nearest to k / 65535 (ties cannot occur: 65535 is odd), in integer arithmetic. The
// UNORM -> float conversion of a D16 texel, like GLSL division, need not be correctly rounded
// (lavapipe's is off by one ulp for some codes); the CPU reference holds exactly this value.
float d16_exact(uint k) {
    if (k == 0u) {
        return 0.0;
    }
    if (k >= 65535u) {
        return 1.0;
    }
    // k in [2^m, 2^(m+1)) and k < 65535, so k / 65535 lies in [2^(m-16), 2^(m-15)).
    int m = findMSB(k);
    // The 24-bit significand floor(k * 2^(39-m) / 65535) by long division; q stays below 2^24.
    uint q = 0u;
    uint r = k;
    for (int i = 0; i < 39 - m; ++i) {
        r <<= 1;
        q <<= 1;
        if (r >= 65535u) {
            r -= 65535u;
            q |= 1u;
        }
    }
    if (2u * r > 65535u) {
        q += 1u;
    }
    int e = m - 16;
    if (q == (1u << 24)) {
        q >>= 1;
        e += 1;
    }
    return uintBitsToFloat((uint(e + 127) << 23) | (q & 0x7FFFFFu));
}

void main() {
    uvec2 t = gl_GlobalInvocationID.xy;
    if (any(greaterThanEqual(t, pc.dst_extent))) {
        return;
    }
    float d = texelFetch(depth_image, ivec2(t), 0).r;
    if (pc.rule == HIZ_COPY_D16) {
        // Any conversion within half a code of k / 65535 gives back k.
        uint k = min(uint(round(clamp(d, 0.0, 1.0) * 65535.0)), 65535u);
        d = d16_exact(k);
    }
    pyramid.texels[pc.dst_offset + t.y * pc.dst_extent.x + t.x] = d;
}
