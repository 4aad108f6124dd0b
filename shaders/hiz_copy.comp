#version 460
// HiZ level 0: the depth buffer as the CPU reference sees it, texel for texel (no arithmetic on
// D32; D16 values are re-derived exactly, see hiz_d16_exact in hiz.glsl).
#extension GL_EXT_samplerless_texture_functions : require
#define HIZ_BUILD
#include "hiz.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// The depth view (DEPTH aspect only, one mip), read with texelFetch: no sampler, no filtering.
layout(set = 0, binding = 0) uniform texture2D depth_image;

void main() {
    uvec2 t = gl_GlobalInvocationID.xy;
    if (any(greaterThanEqual(t, pc.dst_extent))) {
        return;
    }
    float d = texelFetch(depth_image, ivec2(t), 0).r;
    if (pc.rule == HIZ_COPY_D16) {
        // Any conversion within half a code of k / 65535 gives back k.
        uint k = min(uint(round(clamp(d, 0.0, 1.0) * 65535.0)), 65535u);
        d = hiz_d16_exact(k);
    }
    pyramid.texels[pc.dst_offset + t.y * pc.dst_extent.x + t.x] = d;
}
