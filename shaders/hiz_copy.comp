#version 460
// HiZ level 0: the depth buffer as the CPU reference sees it, texel for texel (no arithmetic on
// D32; D16 values are re-derived exactly, see d16_exact).
#extension GL_EXT_samplerless_texture_functions : require
#include "hiz.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// The depth view (DEPTH aspect only, one mip), read with texelFetch: no sampler, no filtering.
layout(set = 0, binding = 0) uniform texture2D depth_image;

// The f32 nearest to k / 65535, exactly, in integer arithmetic: the UNORM -> float conversion of
// a D16 texel, like GLSL division, need not be correctly rounded (lavapipe's is one ulp off for
// 512 of the 65536 codes); the CPU reference holds exactly this value.
// For 0 < k < 65535, k / (2^16 - 1) in binary is k's 16 bits repeated forever: 0.kkkk... . With
// k' = k rotated (16 bits) so that its leading one is on top, the significand is the first 24
// bits of k'k'k'..., and the rest is never exactly a half (it repeats a non-zero pattern), so
// round to nearest is "add the 25th bit", k' bit 7.
float d16_exact(uint k) {
    if (k == 0u) {
        return 0.0;
    }
    if (k >= 65535u) {
        return 1.0;
    }
    int m = findMSB(k); // k / 65535 lies in [2^(m-16), 2^(m-15))
    uint p = uint(15 - m);
    uint kr = ((k << p) | (k >> (16u - p))) & 0xFFFFu;
    uint q = ((kr << 8) | (kr >> 8)) + ((kr >> 7) & 1u);
    // q < 2^24: it would need k' = 0xFFFF, i.e. k = 65535.
    return uintBitsToFloat((uint(m - 16 + 127) << 23) | (q & 0x7FFFFFu));
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
