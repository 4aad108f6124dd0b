// The directional light's cascaded shadow maps (tilegraph_passes::shadow): one depth atlas of
// frame.shadow_info.y x .z cascades, each a square of frame.shadow_params.y texels, sampled
// with hardware depth compares (LESS_OR_EQUAL: 1 where the receiver is nearer the light than
// the stored caster), filtered over the (2r + 1)^2 texels around the lookup (PCF).
#ifndef TILEGRAPH_SHADOW_GLSL
#define TILEGRAPH_SHADOW_GLSL

#include "scene.glsl"

layout(set = 0, binding = 9) uniform sampler2DShadow shadow_atlas;

// How much of the light reaches camera-relative point `p` with normal `n` (facing the camera):
// 1 beyond the last cascade or without shadows. The cascade is the first whose far distance
// lies beyond the point's view distance; the lookup moves along the normal by a few texels of
// that cascade (normal offset: no self-shadowing on surfaces the light grazes).
float shadow_factor(vec3 p, vec3 n) {
    uint count = frame.shadow_info.x;
    if (count == 0u) {
        return 1.0;
    }
    float dist = dot(p, frame.view_forward.xyz);
    uint c = 0u;
    while (c < count && dist >= frame.shadow_far[c]) {
        c++;
    }
    if (c >= count) {
        return 1.0;
    }
    vec3 q = p + normalize(n) * (frame.shadow_params.x * frame.shadow_texel[c]);
    vec4 clip = frame.shadow_clip[c] * vec4(q, 1.0);
    vec2 uv = clip.xy * 0.5 + 0.5;
    uint cols = frame.shadow_info.y;
    vec2 cell = vec2(float(c % cols), float(c / cols));
    vec2 grid = vec2(float(cols), float(frame.shadow_info.z));
    // (2r)^2 bilinear compare taps half a texel off the texel grid: together they weigh the
    // (2r + 1)^2 texels around the lookup (4 taps for r = 1 instead of 9 point taps); r = 0 is
    // one bilinear tap at the lookup (its 2x2 texels).
    int r = int(frame.shadow_info.w);
    if (r == 0) {
        return texture(shadow_atlas, vec3((uv + cell) / grid, clip.z));
    }
    float sum = 0.0;
    for (int y = 0; y < 2 * r; ++y) {
        for (int x = 0; x < 2 * r; ++x) {
            vec2 offset = vec2(float(x - r) + 0.5, float(y - r) + 0.5);
            vec2 at = (uv + offset * frame.shadow_params.z + cell) / grid;
            sum += texture(shadow_atlas, vec3(at, clip.z));
        }
    }
    return sum / float(4 * r * r);
}

#endif
